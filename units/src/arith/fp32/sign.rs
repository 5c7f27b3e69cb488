//! Sign-bit operations (IEEE 754-2008 §5.5.1 `abs`, `negate`): quiet, non-arithmetic, no
//! flags, and bit-exact on every input — a NaN keeps its payload and only its sign bit
//! changes, as RISC-V `fsgnjx.s`/`fsgnjn.s` do. They take no [`FpMode`](super::FpMode): a
//! subnormal is never flushed by a sign operation.

use super::SIGN;

/// `|a|`: clears the sign bit.
#[inline]
pub const fn abs(a: u32) -> u32 {
    a & !SIGN
}

/// `−a`: inverts the sign bit.
#[inline]
pub const fn neg(a: u32) -> u32 {
    a ^ SIGN
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sign_ops() {
        assert_eq!(abs(0xBF80_0000), 0x3F80_0000);
        assert_eq!(abs(0x7F80_0001), 0x7F80_0001);
        assert_eq!(abs(0xFFC0_1234), 0x7FC0_1234);
        assert_eq!(neg(0), 0x8000_0000);
        assert_eq!(neg(0x8000_0001), 1);
        assert_eq!(neg(0x7FC0_0000), 0xFFC0_0000);
    }
}
