//! Floating-point multiplier (IEEE 754-2008 §5.4.1 multiplication).
//!
//! Datapath (Ercegovac & Lang §8.3): sign XOR; exponent adder `ea + eb − bias`; a 24×24-bit
//! significand multiplier array producing the exact 48-bit product (modelled as one `u64`
//! multiply); a 1-bit normaliser (the product of two significands in `[1, 2)` lies in
//! `[1, 4)`) that compresses the low product bits into a sticky bit; then the shared
//! [`round_pack`]. Subnormal operands are first normalised by a
//! leading-zero counter, so the array always sees a leading one at bit 23.
//!
//! # Fast path
//!
//! The model evaluates the common case — two normal operands and a normal, finite product —
//! without branching on the data (`mul_normal`): the same sign, exponent-adder, array and
//! 1-bit-normaliser stages, then round-to-nearest-even directly on the 24 product bits below
//! the result (the exact remainder, which decides the rounding and the inexact flag exactly
//! as the sticky-compressed guard bits of [`round_pack`] do). It computes an `ok` bit
//! alongside (operands normal, product normal and finite); where `ok` is clear the complete
//! datapath is used, so zeros, subnormals, inf/NaN, overflow, underflow and flush-to-zero are
//! all handled by the general code.
//!
//! [`mul_lanes`] (one op issued to the multipliers of all clusters) runs the fast path on
//! groups of lanes whose operands are all normal — branch-free, so the compiler evaluates
//! several lanes at a time in vector registers — and [`mul`] on the lanes whose `ok` is
//! clear and on groups with a non-normal operand, lane by lane.

use super::round::{exp_in_normal_range, round_pack};
use super::{EXP_MASK, FRAC_MASK, FpMode, HIDDEN, SIGN, flush_input, is_nan, is_normal, lane_loop};
use crate::arith::flags::Flags;

/// `a × b`, rounded to nearest even.
#[inline]
pub fn mul(a: u32, b: u32, mode: FpMode) -> (u32, Flags) {
    let (bits, flags, ok) = mul_normal(a, b);
    if ok {
        (bits, flags)
    } else {
        mul_general(a, b, mode)
    }
}

/// `out[i], flags[i] = mul(a[i], b[i])` for every lane `i < out.len()` (the op issued to one
/// multiplier in every cluster), by groups of lanes: see the module doc.
///
/// # Panics
/// If `a` or `b` is shorter than `out`, or `flags` is not as long as `out`.
#[inline(never)]
pub fn mul_lanes(a: &[u32], b: &[u32], mode: FpMode, out: &mut [u32], flags: &mut [Flags]) {
    lane_loop(a, b, out, flags, mul_normal, |a, b| mul(a, b, mode));
}

/// The fast path, branch-free: the product of two normal operands, its flags and `ok` (both
/// operands normal and the product normal and finite; see the module doc). Every value is
/// computed for every operand; the result is meaningful only when `ok` is set.
#[inline(always)]
fn mul_normal(a: u32, b: u32) -> (u32, Flags, bool) {
    // Operand class: one test per operand on the exponent field.
    let normal = is_normal(a) & is_normal(b);
    let sign = (a ^ b) & SIGN;
    // 24×24-bit significand array: the exact product, in [2^46, 2^48).
    let prod = ((a & FRAC_MASK) | HIDDEN) as u64 * ((b & FRAC_MASK) | HIDDEN) as u64;
    // 1-bit normaliser: a product below 2 (leading one at bit 46) is shifted left once
    // (added to itself), so the leading one is at bit 47 and the result bits are 47..24.
    let top = (prod >> 47) as u32;
    let prod = prod.wrapping_add(prod & (top as u64 ^ 1).wrapping_neg());
    // Exponent adder: ea + eb − bias, plus one for a product in [2, 4); this is the exponent
    // of the `round_pack` convention.
    let exp = ((a >> 23) & 0xFF) as i32 + ((b >> 23) & 0xFF) as i32 - 127 + top as i32;
    let ok = normal & exp_in_normal_range(exp);
    // Round to nearest, ties to even, on the 24 bits below the result: adding half an ulp
    // minus one, plus the result's lsb, carries into the lsb exactly when the remainder is
    // above half, or is half and the lsb is odd.
    let lsb = (prod >> 24) & 1;
    let rounded = (prod.wrapping_add((1 << 23) - 1 + lsb) >> 24) as u32;
    let inexact = prod & ((1 << 24) - 1) != 0;
    // Pack: the hidden bit (or a rounding carry out of the significand) adds to the exponent
    // field, hence `exp - 1`.
    let bits = sign | (((exp - 1) as u32) << 23).wrapping_add(rounded);
    (bits, Flags::when(inexact, Flags::INEXACT), ok)
}

/// `a × b` for every operand class (the complete multiplier; see the module doc).
#[cold]
#[inline(never)]
fn mul_general(a: u32, b: u32, mode: FpMode) -> (u32, Flags) {
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

    use crate::arith::fp32::testgen::{SplitMix64, biased_pair};

    /// Operand pairs for the fast path: the hard cases of `biased_pair`, and normal pairs
    /// whose product exponent lands anywhere from below the underflow threshold to above the
    /// overflow threshold.
    fn pairs(n: usize, seed: u64) -> impl Iterator<Item = (u32, u32)> {
        let mut rng = SplitMix64::new(seed);
        (0..n).map(move |i| {
            if i % 2 == 0 {
                return biased_pair(&mut rng);
            }
            let a = (rng.next_u32() & 0x807F_FFFF) | ((1 + rng.below(254)) << 23);
            let b = (rng.next_u32() & 0x807F_FFFF) | ((1 + rng.below(254)) << 23);
            (a, b)
        })
    }

    #[test]
    fn fast_path_matches_the_complete_multiplier() {
        let (mut fast, mut normal) = (0, 0);
        for (a, b) in pairs(400_000, 0x3A1) {
            let want = mul_general(a, b, M);
            let (bits, flags, ok) = mul_normal(a, b);
            if ok {
                assert_eq!((bits, flags), want, "mul_normal({a:08X}, {b:08X})");
                fast += 1;
            }
            normal += (want.0 & EXP_MASK != 0 && want.0 & EXP_MASK != EXP_MASK) as u32;
        }
        assert!(fast > normal * 9 / 10);
    }

    #[test]
    fn lanes_match_one_operation() {
        let mut ops = pairs(100_000, 0x5EED);
        for mode in [FpMode::IEEE, FpMode::FTZ] {
            for len in (0..=20).cycle().take(2000) {
                let (a, b): (Vec<u32>, Vec<u32>) = ops.by_ref().take(len).unzip();
                let (mut out, mut flags) = (vec![0; a.len()], vec![Flags::NONE; a.len()]);
                mul_lanes(&a, &b, mode, &mut out, &mut flags);
                for i in 0..a.len() {
                    assert_eq!(
                        (out[i], flags[i]),
                        mul(a[i], b[i], mode),
                        "lane {i} of {len}"
                    );
                }
            }
        }
    }
}
