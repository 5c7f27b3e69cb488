//! Bit-accurate value types.
//!
//! Narrow fields (exponents, indices, opcodes, counters) use `arbitrary-int` types such as
//! [`u5`] or [`u48`], whose arithmetic wraps when asked (`wrapping_add`) and whose
//! constructors reject values that do not fit. Wide packed words (VLIW microcode words,
//! switch buses) use [`WideWord`], a `bitvec` vector of a declared width.
//!
//! [`Bits`] is what a probe needs from a value: its declared width and its bits.

pub use arbitrary_int::prelude::*;
pub use arbitrary_int::{UInt, u1, u2, u3, u4, u5, u6, u7, u9, u10, u11, u12, u13, u14, u15};
pub use arbitrary_int::{u17, u18, u20, u23, u24, u25, u31, u33, u40, u48, u56, u63};
use bitvec::prelude::*;

/// A wide word of a fixed declared width, least significant bit first.
pub type WideWord = BitVec<u64, Lsb0>;

/// Makes a zeroed wide word of `width` bits.
pub fn wide_word(width: usize) -> WideWord {
    bitvec![u64, Lsb0; 0; width]
}

/// A value with a declared bit width, as carried by registers and probes (≤ 128 bits;
/// wider values are [`WideWord`]s).
pub trait Bits: Copy {
    /// Declared width in bits.
    const WIDTH: u32;
    /// The value's bits, zero-extended.
    fn to_u128(self) -> u128;
}

macro_rules! bits_for_uint {
    ($($t:ty),*) => {$(
        impl<const B: usize> Bits for UInt<$t, B> {
            const WIDTH: u32 = B as u32;
            #[inline]
            fn to_u128(self) -> u128 {
                self.value() as u128
            }
        }
        impl Bits for $t {
            const WIDTH: u32 = <$t>::BITS;
            #[inline]
            fn to_u128(self) -> u128 {
                self as u128
            }
        }
    )*};
}
bits_for_uint!(u8, u16, u32, u64, u128);

impl Bits for bool {
    const WIDTH: u32 = 1;
    #[inline]
    fn to_u128(self) -> u128 {
        self as u128
    }
}

/// Number of bits needed to count from 0 to `max` inclusive (at least 1).
pub const fn bits_for(max: u64) -> u32 {
    if max == 0 {
        1
    } else {
        64 - max.leading_zeros()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn widths_are_declared_widths() {
        assert_eq!(<u48 as Bits>::WIDTH, 48);
        assert_eq!(<u5 as Bits>::WIDTH, 5);
        assert_eq!(<u32 as Bits>::WIDTH, 32);
        assert_eq!(<bool as Bits>::WIDTH, 1);
        assert_eq!(
            u48::new(0xFFFF_FFFF_FFFF).wrapping_add(u48::new(2)).value(),
            1
        );
    }

    #[test]
    fn values_that_do_not_fit_are_rejected() {
        assert!(u5::try_new(32).is_err());
        assert!(u5::try_new(31).is_ok());
    }

    #[test]
    fn bits_for_counts() {
        assert_eq!(bits_for(0), 1);
        assert_eq!(bits_for(1), 1);
        assert_eq!(bits_for(16), 5);
        assert_eq!(bits_for(15), 4);
        assert_eq!(wide_word(300).len(), 300);
    }
}
