//! The shared normalise-round-pack stage (IEEE 754-2008 §4.3.1 roundTiesToEven, §7.4/§7.5
//! overflow and underflow).
//!
//! Every arithmetic datapath ends in this block. Its input is an *unrounded* result in a fixed
//! internal format:
//!
//! * `sig`: a 31-bit significand with its leading one at bit 30 — 24 result bits (bits 30..7)
//!   followed by 7 guard bits (bits 6..0) whose lowest bit is a *sticky* bit: the OR of every
//!   bit of the exact result below it (Ercegovac & Lang §8.4.2). Bit 31 is kept clear so the
//!   rounding increment can carry out of the significand.
//! * `exp`: the biased exponent the result has when the leading one is at bit 30, i.e.
//!   value = `sig × 2^(exp − 127 − 30)`. It may lie outside `1..=254`; this block produces the
//!   overflow (±inf) and the subnormal/underflow results.
//!
//! Rounding is round-to-nearest-even on the 7 guard bits. The packing step *adds* the rounded
//! significand (hidden bit included) to `(exp − 1) << 23`, so a rounding carry that turns
//! `1.111…1` into `10.000…0` increments the exponent field for free, exactly as in a hardware
//! pack adder.
//!
//! Tininess is detected after rounding (the RISC-V choice in IEEE 754-2008 §7.5): the result is
//! tiny if, rounded to 24 bits with an unbounded exponent, its magnitude is below 2^-126.
//! Underflow is raised when the result is tiny *and* inexact.

use super::{FpMode, SIGN};
use crate::arith::flags::Flags;

/// Number of guard bits below the 24-bit result significand.
pub const GUARD_BITS: u32 = 7;
/// Position of the leading one of a normalised internal significand.
pub const LEAD_BIT: u32 = 30;

const HALF: u32 = 1 << (GUARD_BITS - 1);
const GUARD_MASK: u32 = (1 << GUARD_BITS) - 1;

/// Shift `x` right by `n` (any amount), ORing every bit shifted out into bit 0 (the sticky
/// "jamming" shifter of an alignment or denormalisation stage).
#[inline]
pub fn shift_right_jam32(x: u32, n: u32) -> u32 {
    if n < 32 {
        (x >> n) | ((x << ((32 - n) & 31) != 0 && n != 0) as u32)
    } else {
        (x != 0) as u32
    }
}

/// Shift `x` right by `n < 64`, jamming the shifted-out bits into bit 0.
#[inline]
pub fn shift_right_jam64(x: u64, n: u32) -> u64 {
    debug_assert!(n < 64);
    (x >> n) | ((x & ((1u64 << n) - 1)) != 0) as u64
}

/// Round to nearest even and pack.
///
/// `sign` is `0` or [`SIGN`]; `sig` must have its leading one at bit 30 (`2^30 <= sig < 2^31`);
/// see the module doc for `exp`. Returns the packed binary32 and the inexact / overflow /
/// underflow flags.
#[inline]
pub fn round_pack(sign: u32, exp: i32, sig: u32, mode: FpMode) -> (u32, Flags) {
    debug_assert!((1 << LEAD_BIT..1 << (LEAD_BIT + 1)).contains(&sig));
    debug_assert!(sign & !SIGN == 0);
    // Fast path: a normal result that cannot overflow even with a rounding carry.
    if !exp_in_normal_range(exp) {
        return round_pack_edge(sign, exp, sig, mode);
    }
    round_pack_normal(sign, exp, sig)
}

/// True when a result with unrounded exponent `exp` (as [`round_pack`] takes it) is normal
/// and finite whatever the rounding: `1 <= exp <= 253`, so a rounding carry (which can raise
/// the exponent by one) still stays below the overflow threshold `exp = 255`.
#[inline(always)]
pub const fn exp_in_normal_range(exp: i32) -> bool {
    ((exp - 1) as u32) < 0xFD
}

/// The round-and-pack stage for a result known to be normal and finite
/// ([`exp_in_normal_range`]): round to nearest even on the 7 guard bits, then the pack adder.
/// Raises only inexact. Same inputs as [`round_pack`].
///
/// Branch-free and total: the lane datapaths evaluate it on every lane and discard the lanes
/// whose result is out of range, so out-of-range inputs give meaningless bits but no panic.
#[inline(always)]
pub const fn round_pack_normal(sign: u32, exp: i32, sig: u32) -> (u32, Flags) {
    let guard = sig & GUARD_MASK;
    // Round to nearest, ties to even: adding half an ulp minus one, plus the result's lsb,
    // carries into the lsb exactly when the guard bits are above half, or are exactly half
    // and the lsb is odd.
    let lsb = (sig >> GUARD_BITS) & 1;
    let rounded = sig.wrapping_add(HALF - 1 + lsb) >> GUARD_BITS;
    // Pack: the hidden bit of `rounded` (or its rounding carry) adds to the exponent field,
    // hence `exp - 1`.
    let bits = sign | (((exp.wrapping_sub(1)) as u32) << 23).wrapping_add(rounded);
    (bits, Flags::when(guard != 0, Flags::INEXACT))
}

/// Round and pack where the result may overflow (`exp >= 254`) or be tiny (`exp <= 0`).
#[cold]
#[inline(never)]
fn round_pack_edge(sign: u32, exp: i32, sig: u32, mode: FpMode) -> (u32, Flags) {
    if exp >= 0xFE {
        // Overflow when the rounded magnitude reaches 2^128: rounding to nearest delivers inf.
        if exp > 0xFE || sig + HALF >= 1 << (LEAD_BIT + 1) {
            return (sign | super::POS_INF, Flags::OVERFLOW | Flags::INEXACT);
        }
        let guard = sig & GUARD_MASK;
        let tie = (guard == HALF) as u32;
        let rounded = ((sig + HALF) >> GUARD_BITS) & !tie;
        let bits = sign | ((((exp - 1) as u32) << 23) + rounded);
        return (bits, Flags::when(guard != 0, Flags::INEXACT));
    }
    // exp <= 0: below the normal range. Tiny after rounding unless exp == 0 and rounding to 24
    // bits carries up to 2^-126.
    let tiny = exp < 0 || sig + HALF < 1 << (LEAD_BIT + 1);
    // Denormalise: shift so that the exponent becomes 1 (the subnormal scale), jamming.
    let sig = shift_right_jam32(sig, (1 - exp) as u32);
    let guard = sig & GUARD_MASK;
    let tie = (guard == HALF) as u32;
    let rounded = ((sig + HALF) >> GUARD_BITS) & !tie;
    let inexact = guard != 0;
    if mode.flush_to_zero && rounded < super::HIDDEN {
        // Would be subnormal (or rounded to zero): flush to signed zero.
        return (sign, Flags::UNDERFLOW | Flags::INEXACT);
    }
    // Exponent field 0; a rounding carry into bit 23 yields the smallest normal.
    let flags =
        Flags::when(inexact, Flags::INEXACT) | Flags::when(inexact && tiny, Flags::UNDERFLOW);
    (sign | rounded, flags)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jam_shifts() {
        assert_eq!(shift_right_jam32(0b1000, 3), 1);
        assert_eq!(shift_right_jam32(0b1001, 3), 1);
        assert_eq!(shift_right_jam32(0b1100, 2), 0b11);
        assert_eq!(shift_right_jam32(0b1101, 2), 0b11);
        assert_eq!(shift_right_jam32(0b1110, 2), 0b11);
        assert_eq!(shift_right_jam32(0b1000, 2), 0b10);
        assert_eq!(shift_right_jam32(5, 0), 5);
        assert_eq!(shift_right_jam32(5, 40), 1);
        assert_eq!(shift_right_jam32(0, 40), 0);
        assert_eq!(shift_right_jam32(0x8000_0000, 31), 1);
        assert_eq!(shift_right_jam32(0x8000_0001, 31), 1);
        assert_eq!(shift_right_jam64(0x1_0000_0001, 32), 1 | 1);
        assert_eq!(shift_right_jam64(0x2_0000_0000, 32), 2);
        assert_eq!(shift_right_jam64(7, 0), 7);
    }

    #[test]
    fn rounding_ties_and_carries() {
        let one = 1u32 << 30;
        // 1.0 exact.
        assert_eq!(
            round_pack(0, 127, one, FpMode::IEEE),
            (0x3F80_0000, Flags::NONE)
        );
        // 1.0 + half an ulp: tie, rounds to even (down).
        assert_eq!(
            round_pack(0, 127, one | HALF, FpMode::IEEE),
            (0x3F80_0000, Flags::INEXACT)
        );
        // (1.0 + ulp) + half an ulp: tie, rounds to even (up).
        assert_eq!(
            round_pack(SIGN, 127, one | 0x80 | HALF, FpMode::IEEE),
            (0xBF80_0002, Flags::INEXACT)
        );
        // All ones + half ulp carries into the exponent.
        assert_eq!(
            round_pack(0, 127, 0x7FFF_FFC0, FpMode::IEEE),
            (0x4000_0000, Flags::INEXACT)
        );
        // Largest finite, and overflow by rounding carry.
        assert_eq!(
            round_pack(0, 254, 0x7FFF_FF80, FpMode::IEEE),
            (0x7F7F_FFFF, Flags::NONE)
        );
        assert_eq!(
            round_pack(0, 254, 0x7FFF_FFC0, FpMode::IEEE),
            (0x7F80_0000, Flags::OVERFLOW | Flags::INEXACT)
        );
        assert_eq!(
            round_pack(SIGN, 300, one, FpMode::IEEE),
            (0xFF80_0000, Flags::OVERFLOW | Flags::INEXACT)
        );
    }

    #[test]
    fn subnormal_and_tininess_after_rounding() {
        let one = 1u32 << 30;
        // 2^-127 exactly: subnormal 0x00400000, exact, no underflow.
        assert_eq!(
            round_pack(0, 0, one, FpMode::IEEE),
            (0x0040_0000, Flags::NONE)
        );
        // Just below 2^-126 but rounds (at 24 bits) to 2^-126: not tiny after rounding.
        assert_eq!(
            round_pack(0, 0, 0x7FFF_FFC0, FpMode::IEEE),
            (0x0080_0000, Flags::INEXACT)
        );
        // Rounds to 2^-126 only at subnormal precision: tiny, so underflow.
        assert_eq!(
            round_pack(0, 0, 0x7FFF_FF80 | 1, FpMode::IEEE),
            (0x0080_0000, Flags::INEXACT | Flags::UNDERFLOW)
        );
        // 2^-149 exactly: the smallest subnormal, exact.
        assert_eq!(round_pack(0, -22, one, FpMode::IEEE), (1, Flags::NONE));
        // 2^-150 exactly: tie between 0 and the smallest subnormal, rounds to even (0).
        assert_eq!(
            round_pack(SIGN, -23, one, FpMode::IEEE),
            (SIGN, Flags::INEXACT | Flags::UNDERFLOW)
        );
        // Far below: 0 with underflow.
        assert_eq!(
            round_pack(0, -200, one, FpMode::IEEE),
            (0, Flags::INEXACT | Flags::UNDERFLOW)
        );
        // FTZ: an exact subnormal is flushed with UF|NX; the smallest normal survives.
        assert_eq!(
            round_pack(SIGN, 0, one, FpMode::FTZ),
            (SIGN, Flags::INEXACT | Flags::UNDERFLOW)
        );
        assert_eq!(
            round_pack(0, 0, 0x7FFF_FFC0, FpMode::FTZ),
            (0x0080_0000, Flags::INEXACT)
        );
    }
}
