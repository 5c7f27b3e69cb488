//! IEEE 754-2008 §7 exception flags, as a 5-bit sticky set.
//!
//! The bit encoding is the one Berkeley SoftFloat 3 uses for `softfloat_exceptionFlags` and
//! Berkeley TestFloat prints as two hex digits: inexact 1, underflow 2, overflow 4,
//! infinite (divide-by-zero) 8, invalid 16. Keeping the same encoding makes the flag byte of a
//! TestFloat vector directly comparable with [`Flags::bits`].

use core::fmt;
use core::ops::{BitOr, BitOrAssign};

/// A set of IEEE exception flags raised by one operation (or accumulated over many).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Flags(u8);

impl Flags {
    /// No exception.
    pub const NONE: Flags = Flags(0);
    /// Inexact: the rounded result differs from the exact result.
    pub const INEXACT: Flags = Flags(1);
    /// Underflow: tiny (detected after rounding) and inexact.
    pub const UNDERFLOW: Flags = Flags(2);
    /// Overflow: the rounded result's magnitude exceeds the largest finite number.
    pub const OVERFLOW: Flags = Flags(4);
    /// Divide-by-zero ("infinite" in SoftFloat): an exact infinity from finite operands.
    pub const INFINITE: Flags = Flags(8);
    /// Invalid operation: no usefully definable result (or a signalling NaN operand).
    pub const INVALID: Flags = Flags(16);
    /// All five flags.
    pub const ALL: Flags = Flags(31);

    /// Flags from the TestFloat/SoftFloat bit encoding; bits above 4 are dropped.
    #[inline]
    pub const fn from_bits(bits: u8) -> Flags {
        Flags(bits & 31)
    }

    /// The TestFloat/SoftFloat bit encoding.
    #[inline]
    pub const fn bits(self) -> u8 {
        self.0
    }

    /// True if every flag of `other` is set in `self`.
    #[inline]
    pub const fn contains(self, other: Flags) -> bool {
        self.0 & other.0 == other.0
    }

    /// True if no flag is set.
    #[inline]
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Union of two flag sets (a `const` form of `|`).
    #[inline]
    pub const fn union(self, other: Flags) -> Flags {
        Flags(self.0 | other.0)
    }

    /// `flag` if `cond`, else no flag (branch-free).
    #[inline]
    pub const fn when(cond: bool, flag: Flags) -> Flags {
        Flags(flag.0 & (cond as u8).wrapping_neg())
    }
}

impl BitOr for Flags {
    type Output = Flags;
    #[inline]
    fn bitor(self, rhs: Flags) -> Flags {
        Flags(self.0 | rhs.0)
    }
}

impl BitOrAssign for Flags {
    #[inline]
    fn bitor_assign(&mut self, rhs: Flags) {
        self.0 |= rhs.0;
    }
}

impl fmt::Debug for Flags {
    /// Prints e.g. `Flags(0x03 NX|UF)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Flags({:#04x}", self.0)?;
        let names = [(16, "NV"), (8, "DZ"), (4, "OF"), (2, "UF"), (1, "NX")];
        let mut first = true;
        for (bit, name) in names {
            if self.0 & bit != 0 {
                write!(f, "{}{}", if first { " " } else { "|" }, name)?;
                first = false;
            }
        }
        write!(f, ")")
    }
}

impl fmt::Display for Flags {
    /// The TestFloat form: two upper-case hex digits.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:02X}", self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encoding_matches_testfloat() {
        let all = [
            Flags::INEXACT,
            Flags::UNDERFLOW,
            Flags::OVERFLOW,
            Flags::INFINITE,
            Flags::INVALID,
        ];
        let mut acc = Flags::NONE;
        for (i, f) in all.iter().enumerate() {
            assert_eq!(f.bits(), 1 << i);
            acc |= *f;
        }
        assert_eq!(acc, Flags::ALL);
        assert_eq!(format!("{}", Flags::INEXACT | Flags::UNDERFLOW), "03");
        assert_eq!(
            format!("{:?}", Flags::INVALID | Flags::INEXACT),
            "Flags(0x11 NV|NX)"
        );
        assert_eq!(Flags::when(false, Flags::INVALID), Flags::NONE);
        assert_eq!(Flags::when(true, Flags::INVALID), Flags::INVALID);
        assert!((Flags::INVALID | Flags::INEXACT).contains(Flags::INEXACT));
        assert!(!Flags::INEXACT.contains(Flags::INVALID));
        assert_eq!(Flags::from_bits(0xFF), Flags::ALL);
    }
}
