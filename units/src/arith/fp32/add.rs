//! Floating-point adder/subtracter (IEEE 754-2008 §5.4.1 addition, subtraction; §6.3 sign of
//! an exact zero sum).
//!
//! Datapath (Ercegovac & Lang §8.2, single-path adder):
//!
//! 1. *swap*: order the operands by magnitude (an integer compare of the 31 low bits), so the
//!    larger operand's exponent is the result exponent and the subtraction never goes
//!    negative;
//! 2. *align*: shift the smaller significand right by the exponent difference through a
//!    jamming shifter (everything shifted out ORs into a sticky bit);
//! 3. *add/subtract* the significands, held with 6 guard bits (leading one at bit 29) so
//!    that a carry-out fits below bit 31;
//! 4. *normalise* with a leading-zero counter (massive cancellation shifts left, a carry-out
//!    needs none), then the shared [`round_pack`].
//!
//! Special operands (NaN, infinity) branch off before the significand path; an exact zero sum
//! of opposite-signed operands is `+0` (round-to-nearest).
//!
//! # Fast paths
//!
//! The model evaluates the common case — two normal operands and a normal, finite result —
//! through fast paths that leave out the special-operand and edge-of-range logic, and take
//! the complete datapath above for everything else (zeros, subnormals, inf/NaN, exact zero
//! sums, overflow, underflow, flush-to-zero). Each fast path produces exactly the bits and
//! flags of the complete datapath on the cases it accepts:
//!
//! * [`add`]/[`sub`] (one operation): a wide variant of the four stages (`add_normal`). The
//!   significands sit in 64 bits with 31 zero bits below the larger one, so the aligned
//!   smaller significand keeps every bit for shifts up to 31 and the sum is exact; the
//!   shifter saturates at 31, beyond which the smaller operand lies below a quarter ulp of the
//!   larger and only its being non-zero — the sticky bit's job — can affect the rounded sum.
//!   After the leading-zero normaliser, round-to-nearest-even looks at all 32 bits below the
//!   result. One branch rejects non-normal operands, one rejects the other cases.
//! * [`add_lanes`]/[`sub_lanes`] (one op issued to the adders of all clusters): the four
//!   stages exactly as above, but branch-free, computing an `ok` bit with each lane's result,
//!   and with the normaliser reduced to two 1-bit left shifters (`add_lane`). That covers every
//!   sum except one whose leading one lies two or more places below the larger significand's
//!   (a cancellation, which needs an effective subtraction of operands whose exponents differ
//!   by at most one). Without a leading-zero counter or any branch, the compiler evaluates
//!   several lanes at a time in vector registers. It runs on groups of lanes whose operands
//!   are all normal; the few lanes whose `ok` bit is clear, and groups with a non-normal
//!   operand, go through [`add`]/[`sub`] lane by lane.

use std::hint::select_unpredictable as select;
use std::num::NonZeroU64;

use super::round::{exp_in_normal_range, round_pack, round_pack_normal, shift_right_jam32};
use super::{EXP_MASK, FRAC_MASK, FpMode, HIDDEN, SIGN, exp_field, flush_input, is_nan, lane_loop};
use crate::arith::flags::Flags;

/// `a + b`, rounded to nearest even.
#[inline]
pub fn add(a: u32, b: u32, mode: FpMode) -> (u32, Flags) {
    match add_normal(a, b) {
        Some(r) => r,
        None => add_general(a, b, mode),
    }
}

/// `a − b`, rounded to nearest even (the adder with the sign of `b` inverted).
#[inline]
pub fn sub(a: u32, b: u32, mode: FpMode) -> (u32, Flags) {
    match add_normal(a, b ^ SIGN) {
        Some(r) => r,
        None => sub_general(a, b, mode),
    }
}

/// The one-operation fast path (see the module doc): `a + b` if both operands are normal and
/// the sum is normal and finite, else `None`.
#[inline(always)]
fn add_normal(a: u32, b: u32) -> Option<(u32, Flags)> {
    // 1. Swap: order by magnitude, so the larger operand sets the sign and exponent (selects,
    // not branches: the order of random operands is unpredictable).
    let (ma, mb) = (a & !SIGN, b & !SIGN);
    let swap = ma < mb;
    let (mbig, msmall) = (select(swap, mb, ma), select(swap, ma, mb));
    // Operand class: |big| below inf and |small| at least the smallest normal (the magnitudes
    // are ordered, so this is "both normal"); two sign tests of one OR.
    if ((mbig.wrapping_add(HIDDEN) | msmall.wrapping_sub(HIDDEN)) as i32) < 0 {
        return None;
    }
    let big = select(swap, b, a);
    let (eb, es) = (mbig >> 23, msmall >> 23);
    // 2. Align: significands with the hidden bit, the larger one's leading one at bit 54
    // (31 zero bits below it); the smaller one shifted 31 − d places left instead, d the
    // exponent difference saturated at 31.
    let d = (eb - es).min(31);
    let sb = (((mbig & FRAC_MASK) | HIDDEN) as u64) << 31;
    let ss = (((msmall & FRAC_MASK) | HIDDEN) as u64) << (31 - d);
    // 3. Add or subtract (signs equal or different); the sum is below 2^55 and exact.
    let sum = select((a ^ b) & SIGN == 0, sb + ss, sb - ss);
    // An exact zero sum (x − x) is left to the complete datapath.
    let sum = NonZeroU64::new(sum)?;
    // 4. Normalise: the leading-zero count brings the leading one to bit 55 (no shift after a
    // carry-out, lz = 8); the result exponent, in the `round_pack` convention, follows.
    let lz = sum.leading_zeros();
    let exp = eb as i32 + 9 - lz as i32;
    if !exp_in_normal_range(exp) {
        return None;
    }
    let sig = sum.get() << (lz - 8);
    // Round to nearest, ties to even, on the 32 bits below the 24 result bits (55..32):
    // adding half an ulp minus one, plus the result's lsb, carries into the lsb exactly when
    // the remainder is above half, or is half and the lsb is odd.
    let lsb = (sig >> 32) & 1;
    let rounded = ((sig + 0x7FFF_FFFF + lsb) >> 32) as u32;
    let inexact = sig as u32 != 0;
    // Pack: sign and exponent field of the larger operand, adjusted by the normalisation
    // shift; the hidden bit of `rounded` (or its rounding carry) adds one more, as `exp − 1`
    // = eb + 8 − lz in the `round_pack` convention.
    let bits = (big & (SIGN | EXP_MASK))
        .wrapping_add(8u32.wrapping_sub(lz) << 23)
        .wrapping_add(rounded);
    Some((bits, Flags::when(inexact, Flags::INEXACT)))
}

/// `out[i], flags[i] = add(a[i], b[i])` for every lane `i < out.len()` (the op issued to one
/// adder in every cluster), by groups of lanes: see the module doc.
///
/// # Panics
/// If `a` or `b` is shorter than `out`, or `flags` is not as long as `out`.
#[inline(never)]
pub fn add_lanes(a: &[u32], b: &[u32], mode: FpMode, out: &mut [u32], flags: &mut [Flags]) {
    lane_loop(a, b, out, flags, add_lane, |a, b| add(a, b, mode));
}

/// `out[i], flags[i] = sub(a[i], b[i])` for every lane `i < out.len()` (the lane fast path
/// with the sign of `b` inverted).
///
/// # Panics
/// If `a` or `b` is shorter than `out`, or `flags` is not as long as `out`.
#[inline(never)]
pub fn sub_lanes(a: &[u32], b: &[u32], mode: FpMode, out: &mut [u32], flags: &mut [Flags]) {
    lane_loop(
        a,
        b,
        out,
        flags,
        |a, b| add_lane(a, b ^ SIGN),
        |a, b| sub(a, b, mode),
    );
}

/// The lane fast path (see the module doc): `a + b`, its flags and `ok`, computed without a
/// branch for any operands; the result is meaningful only where `ok` is set (both operands
/// normal, the sum normal and finite, and within reach of the reduced normaliser).
#[inline(always)]
fn add_lane(a: u32, b: u32) -> (u32, Flags, bool) {
    // 1. Swap: order by magnitude, so the larger operand sets the sign and exponent; an
    // exchange through XOR under an all-ones mask (`ma < mb`; both are below 2^31).
    let (ma, mb) = (a & !SIGN, b & !SIGN);
    let swap = 0u32.wrapping_sub(((ma as i32) < (mb as i32)) as u32);
    let exchange = (ma ^ mb) & swap;
    let (mbig, msmall) = (ma ^ exchange, mb ^ exchange);
    let sign = (a ^ ((a ^ b) & swap)) & SIGN;
    // Operand class: both normal (as in `add_normal`).
    let normal = (mbig.wrapping_add(HIDDEN) | msmall.wrapping_sub(HIDDEN)) as i32 >= 0;
    let (eb, es) = (mbig >> 23, msmall >> 23);
    // Significands with the hidden bit and 6 guard bits (leading one at bit 29).
    let sb = ((mbig & FRAC_MASK) | HIDDEN) << 6;
    let ss = ((msmall & FRAC_MASK) | HIDDEN) << 6;
    // 2. Align: a 64-bit right shifter whose low half catches the bits shifted out of the
    // high half; they are ORed into the sticky bit (the jamming shifter of `add_core`). A
    // shift of 31 already moves all of `ss` (< 2^30) out, so larger differences saturate.
    let wide = ((ss as u64) << 32) >> ((eb - es) as i32).min(31);
    let ss = (wide >> 32) as u32 | (wide as u32 != 0) as u32;
    #[cfg(feature = "inject-bugs")]
    let ss = if imagine_hdl::inject::active(imagine_hdl::inject::Bug::FpAddDropsStickyBit) {
        (wide >> 32) as u32
    } else {
        ss
    };
    // 3. Significand adder: an effective subtraction (signs differ) inverts the B input and
    // sets the carry-in, i.e. adds the two's complement.
    let inv = 0u32.wrapping_sub((a ^ b) >> 31);
    let sum = sb.wrapping_add((ss ^ inv).wrapping_sub(inv));
    // 4. Normalise: two 1-bit left shifters (adding the value to itself), each enabled while
    // the leading one is below bit 30; each lowers the exponent by one (`m1`, `m2` are 0 or
    // −1). A sum with its leading one at bit 28 or above is normalised after them. Sums of
    // normal operands are below 2^31, so the compares are signed ones.
    let low = |x: u32| 0u32.wrapping_sub(((x as i32) < 1 << 30) as u32);
    let m1 = low(sum);
    let sum1 = sum.wrapping_add(sum & m1);
    let m2 = low(sum1);
    let sig = sum1.wrapping_add(sum1 & m2);
    let exp = eb as i32 + 1 + m1 as i32 + m2 as i32;
    let ok = normal & (sum as i32 >= 1 << 28) & exp_in_normal_range(exp);
    let (bits, flags) = round_pack_normal(sign, exp, sig);
    (bits, flags, ok)
}

/// `a + b` for every operand class (the complete adder; see the module doc).
#[cold]
#[inline(never)]
fn add_general(a: u32, b: u32, mode: FpMode) -> (u32, Flags) {
    add_core(flush_input(a, mode), flush_input(b, mode), mode)
}

/// `a − b` for every operand class.
#[cold]
#[inline(never)]
fn sub_general(a: u32, b: u32, mode: FpMode) -> (u32, Flags) {
    add_core(flush_input(a, mode), flush_input(b, mode) ^ SIGN, mode)
}

#[inline(always)]
fn add_core(a: u32, b: u32, mode: FpMode) -> (u32, Flags) {
    if a & EXP_MASK == EXP_MASK || b & EXP_MASK == EXP_MASK {
        return add_special(a, b);
    }
    // Swap so |big| >= |small| (finite values order like their magnitude bits).
    let (big, small) = if a & !SIGN >= b & !SIGN {
        (a, b)
    } else {
        (b, a)
    };
    let sign = big & SIGN;
    let subtract = (a ^ b) & SIGN != 0;
    let eb = exp_field(big);
    let es = exp_field(small);
    // Significands with the hidden bit; a subnormal uses exponent 1 and no hidden bit.
    let mb = ((big & FRAC_MASK) | if eb != 0 { HIDDEN } else { 0 }) << 6;
    let ms = ((small & FRAC_MASK) | if es != 0 { HIDDEN } else { 0 }) << 6;
    let eb = eb.max(1);
    let es = es.max(1);
    let ms = shift_right_jam32(ms, (eb - es) as u32);
    let sum = if subtract { mb - ms } else { mb + ms };
    if sum == 0 {
        // Exact zero: x + (-x) = +0; (±0) + (±0) of equal signs keeps the sign.
        return (if subtract { 0 } else { sign }, Flags::NONE);
    }
    // Normalise: bring the leading one to bit 30. `mb` has it at bit 29, so the exponent is
    // eb + 1 − (shift).
    let shift = sum.leading_zeros() - 1;
    round_pack(sign, eb + 1 - shift as i32, sum << shift, mode)
}

/// NaN and infinity operands.
#[cold]
#[inline(never)]
fn add_special(a: u32, b: u32) -> (u32, Flags) {
    if is_nan(a) || is_nan(b) {
        return super::propagate_nan(a, b);
    }
    if a & EXP_MASK == EXP_MASK && b & EXP_MASK == EXP_MASK {
        // inf + inf: same sign gives that inf; opposite signs are invalid.
        if (a ^ b) & SIGN != 0 {
            return (super::CANONICAL_NAN, Flags::INVALID);
        }
        return (a, Flags::NONE);
    }
    (if a & EXP_MASK == EXP_MASK { a } else { b }, Flags::NONE)
}

#[cfg(test)]
mod tests {
    use super::*;
    const M: FpMode = FpMode::IEEE;

    #[test]
    fn simple_sums() {
        assert_eq!(add(0x3F80_0000, 0x4000_0000, M), (0x4040_0000, Flags::NONE));
        assert_eq!(sub(0x3F80_0000, 0x4000_0000, M), (0xBF80_0000, Flags::NONE));
        assert_eq!(add(0x3F80_0000, 0xBF80_0000, M), (0, Flags::NONE));
        assert_eq!(add(0x8000_0000, 0x8000_0000, M), (0x8000_0000, Flags::NONE));
        assert_eq!(add(0x8000_0000, 0, M), (0, Flags::NONE));
        // 1 + 2^-24: tie, rounds to even (1.0).
        assert_eq!(
            add(0x3F80_0000, 0x3380_0000, M),
            (0x3F80_0000, Flags::INEXACT)
        );
        // Subnormal + subnormal, exact.
        assert_eq!(add(1, 1, M), (2, Flags::NONE));
        assert_eq!(add(0x007F_FFFF, 1, M), (0x0080_0000, Flags::NONE));
        // Overflow.
        assert_eq!(
            add(0x7F7F_FFFF, 0x7F7F_FFFF, M),
            (0x7F80_0000, Flags::OVERFLOW | Flags::INEXACT)
        );
        // inf - inf.
        assert_eq!(
            sub(0x7F80_0000, 0x7F80_0000, M),
            (0x7FC0_0000, Flags::INVALID)
        );
        assert_eq!(add(0x7F80_0001, 0, M), (0x7FC0_0000, Flags::INVALID));
        assert_eq!(add(0xFFC0_0001, 0, M), (0x7FC0_0000, Flags::NONE));
    }

    #[test]
    fn ftz() {
        // Subnormal inputs are zeros; 2^-126 - 2^-126*(1-2^-23)... would be subnormal.
        assert_eq!(add(1, 1, FpMode::FTZ), (0, Flags::NONE));
        assert_eq!(
            sub(0x0080_0001, 0x0080_0000, FpMode::FTZ),
            (0, Flags::UNDERFLOW | Flags::INEXACT)
        );
        assert_eq!(
            sub(0x0080_0001, 0x0080_0000, FpMode::IEEE),
            (1, Flags::NONE)
        );
    }

    use crate::arith::fp32::testgen::{SplitMix64, biased_pair};

    /// Operand pairs for the fast paths: the hard cases of `biased_pair`, and normal pairs
    /// with random signs, exponents across the whole range, and exponent differences
    /// concentrated where alignment, cancellation and the sticky bit matter (0..=40).
    fn pairs(n: usize, seed: u64) -> impl Iterator<Item = (u32, u32)> {
        let mut rng = SplitMix64::new(seed);
        (0..n).map(move |i| {
            if i % 2 == 0 {
                return biased_pair(&mut rng);
            }
            let a = rng.next_u32();
            let ea = (a >> 23) & 0xFF;
            let eb = ea.saturating_sub(rng.below(41)).clamp(1, 0xFE);
            let b = (rng.next_u32() & 0x807F_FFFF) | (eb << 23);
            if rng.below(2) == 0 { (a, b) } else { (b, a) }
        })
    }

    #[test]
    fn fast_paths_match_the_complete_adder() {
        let (mut scalar, mut lane, mut normal) = (0, 0, 0);
        for (a, b) in pairs(400_000, 0xADD) {
            for (x, y) in [(a, b), (a, b ^ SIGN)] {
                let want = add_core(x, y, M);
                if let Some(got) = add_normal(x, y) {
                    assert_eq!(got, want, "add_normal({x:08X}, {y:08X})");
                    scalar += 1;
                }
                let (bits, flags, ok) = add_lane(x, y);
                if ok {
                    assert_eq!((bits, flags), want, "add_lane({x:08X}, {y:08X})");
                    lane += 1;
                }
                normal += (want.0 & EXP_MASK != 0 && want.0 & EXP_MASK != EXP_MASK) as u32;
            }
        }
        // The fast paths take the common case (not a correctness property: a fast path
        // that declined everything would be slow, not wrong).
        assert!(scalar > normal * 8 / 10 && lane > normal * 3 / 4);
    }

    #[test]
    fn lanes_match_one_operation() {
        let mut rng = SplitMix64::new(0x1A4E5);
        let mut ops = pairs(200_000, 0x5EED);
        for mode in [FpMode::IEEE, FpMode::FTZ] {
            for len in (0..=20).cycle().take(2000) {
                let (a, b): (Vec<u32>, Vec<u32>) = ops.by_ref().take(len).unzip();
                // Mostly normal operands, so that most groups take no lane to the redo path.
                let b: Vec<u32> = if rng.below(2) == 0 {
                    b
                } else {
                    a.iter()
                        .map(|&x| x ^ (rng.next_u32() & 0x807F_FFFF))
                        .collect()
                };
                let (mut out, mut flags) = (vec![0; a.len()], vec![Flags::NONE; a.len()]);
                add_lanes(&a, &b, mode, &mut out, &mut flags);
                for i in 0..a.len() {
                    assert_eq!(
                        (out[i], flags[i]),
                        add(a[i], b[i], mode),
                        "lane {i} of {len}"
                    );
                }
                sub_lanes(&a, &b, mode, &mut out, &mut flags);
                for i in 0..a.len() {
                    assert_eq!(
                        (out[i], flags[i]),
                        sub(a[i], b[i], mode),
                        "lane {i} of {len}"
                    );
                }
            }
        }
    }
}
