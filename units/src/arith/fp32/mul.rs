//! Floating-point multiplier (IEEE 754-2008 §5.4.1 multiplication).
//!
//! Datapath (Ercegovac & Lang §8.3): sign XOR; exponent adder `ea + eb − bias`; a 24×24-bit
//! significand multiplier array producing the exact 48-bit product (modelled as one `u64`
//! multiply); a 1-bit normaliser (the product of two significands in `[1, 2)` lies in
//! `[1, 4)`) that compresses the low product bits into a sticky bit; then the shared
//! [`round_pack`]. Subnormal operands are first normalised by a
//! leading-zero counter, so the array always sees a leading one at bit 23.

use super::round::round_pack;
use super::{EXP_MASK, FRAC_MASK, FpMode, HIDDEN, SIGN, flush_input, is_nan};
use crate::arith::flags::Flags;

/// `a × b`, rounded to nearest even.
#[inline]
pub fn mul(a: u32, b: u32, mode: FpMode) -> (u32, Flags) {
    let a = flush_input(a, mode);
    let b = flush_input(b, mode);
    let sign = (a ^ b) & SIGN;
    let ea = ((a >> 23) & 0xFF) as i32;
    let eb = ((b >> 23) & 0xFF) as i32;
    // Common case first: both operands normal.
    let ((ea, ma), (eb, mb)) = if (ea - 1) as u32 >= 0xFE || (eb - 1) as u32 >= 0xFE {
        if a & EXP_MASK == EXP_MASK || b & EXP_MASK == EXP_MASK {
            return mul_special(a, b);
        }
        if a & !SIGN == 0 || b & !SIGN == 0 {
            return (sign, Flags::NONE);
        }
        (super::unpack_normalised(a), super::unpack_normalised(b))
    } else {
        (
            (ea, (a & FRAC_MASK) | HIDDEN),
            (eb, (b & FRAC_MASK) | HIDDEN),
        )
    };
    let prod = ma as u64 * mb as u64; // in [2^46, 2^48)
    // Normalise: leading one at bit 47 or 46; move it to bit 30 with the rest jammed.
    let top = (prod >> 47) as u32;
    let shift = 16 + top;
    let sticky = (prod & ((1u64 << shift) - 1) != 0) as u32;
    let sig = (prod >> shift) as u32 | sticky;
    round_pack(sign, ea + eb - 127 + top as i32, sig, mode)
}

/// NaN and infinity operands.
#[cold]
#[inline(never)]
fn mul_special(a: u32, b: u32) -> (u32, Flags) {
    if is_nan(a) || is_nan(b) {
        return super::propagate_nan(a, b);
    }
    // inf × 0 is invalid; inf × finite non-zero (or inf) is a signed inf.
    if a & !SIGN == 0 || b & !SIGN == 0 {
        return (super::CANONICAL_NAN, Flags::INVALID);
    }
    ((a ^ b) & SIGN | super::POS_INF, Flags::NONE)
}

#[cfg(test)]
mod tests {
    use super::*;
    const M: FpMode = FpMode::IEEE;

    #[test]
    fn products() {
        assert_eq!(mul(0x4000_0000, 0x4040_0000, M), (0x40C0_0000, Flags::NONE));
        assert_eq!(mul(0xBF80_0000, 0, M), (0x8000_0000, Flags::NONE));
        assert_eq!(mul(0x7F80_0000, 0, M), (0x7FC0_0000, Flags::INVALID));
        assert_eq!(mul(0x7F80_0000, 0x8000_0001, M), (0xFF80_0000, Flags::NONE));
        // 2^-126 * 2^-1 = 2^-127, exact subnormal.
        assert_eq!(mul(0x0080_0000, 0x3F00_0000, M), (0x0040_0000, Flags::NONE));
        // Subnormal * 2^23 = normal.
        assert_eq!(mul(1, 0x4B00_0000, M), (0x0080_0000, Flags::NONE));
        assert_eq!(
            mul(0x7F00_0000, 0x4000_0000, M),
            (0x7F80_0000, Flags::OVERFLOW | Flags::INEXACT)
        );
        assert_eq!(
            mul(1, 0x3F00_0000, M),
            (0, Flags::UNDERFLOW | Flags::INEXACT)
        );
    }
}
