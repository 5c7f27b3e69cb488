//! proptest strategies for binary32 operands biased to the hard cases (feature `proptest`).
//!
//! Each class is its own strategy so properties can target it, and they shrink towards
//! simple members of the class (small fractions, `+` sign). [`any_f32`] and [`f32_pair`] mix
//! all classes with uniform bit patterns. The classes mirror [`super::testgen`], which drives
//! the SoftFloat cross-check and the vector generator without proptest.

use super::testgen::SPECIALS;
use super::{SIGN, exp_field};
use proptest::prelude::*;
use proptest::sample::select;

/// `0` or the sign bit.
pub fn sign() -> BoxedStrategy<u32> {
    prop_oneof![Just(0u32), Just(SIGN)].boxed()
}

/// Hand-picked specials and boundaries ([`SPECIALS`]).
pub fn special() -> BoxedStrategy<u32> {
    select(SPECIALS).boxed()
}

/// `±0`.
pub fn zero() -> BoxedStrategy<u32> {
    sign().boxed()
}

/// `±inf`.
pub fn infinity() -> BoxedStrategy<u32> {
    sign().prop_map(|s| s | 0x7F80_0000).boxed()
}

/// Quiet NaNs with any sign and payload.
pub fn qnan() -> BoxedStrategy<u32> {
    (sign(), 0u32..0x40_0000)
        .prop_map(|(s, p)| s | 0x7FC0_0000 | p)
        .boxed()
}

/// Signalling NaNs with any sign and non-zero payload.
pub fn snan() -> BoxedStrategy<u32> {
    (sign(), 1u32..0x40_0000)
        .prop_map(|(s, p)| s | 0x7F80_0000 | p)
        .boxed()
}

/// Any NaN.
pub fn nan() -> BoxedStrategy<u32> {
    prop_oneof![qnan(), snan()].boxed()
}

/// Subnormals (exponent field 0, non-zero fraction), weighted to tiny and to all-ones.
pub fn subnormal() -> BoxedStrategy<u32> {
    let frac = prop_oneof![
        1u32..0x80_0000,
        1u32..64,
        (0u32..23).prop_map(|k| 0x7F_FFFF >> k),
    ];
    (sign(), frac).prop_map(|(s, f)| s | f).boxed()
}

/// Normal numbers with the exponent in `lo..=hi` and any fraction.
pub fn normal_in(lo: u32, hi: u32) -> BoxedStrategy<u32> {
    (sign(), lo..=hi, 0u32..0x80_0000)
        .prop_map(|(s, e, f)| s | (e << 23) | f)
        .boxed()
}

/// Any normal number.
pub fn normal() -> BoxedStrategy<u32> {
    normal_in(1, 0xFE).boxed()
}

/// Around the subnormal/normal boundary: exponent field 0 (non-zero), 1 or 2.
pub fn boundary() -> BoxedStrategy<u32> {
    prop_oneof![subnormal(), normal_in(1, 2)].boxed()
}

/// Near overflow: exponent 0xFD or 0xFE.
pub fn near_overflow() -> BoxedStrategy<u32> {
    normal_in(0xFD, 0xFE).boxed()
}

/// Near one: exponent 0x7E..=0x80.
pub fn near_one() -> BoxedStrategy<u32> {
    normal_in(0x7E, 0x80).boxed()
}

/// Fractions of all ones, runs of ones, single bits: rounding carries and exact cases.
pub fn fraction_pattern() -> BoxedStrategy<u32> {
    prop_oneof![
        Just(0x7F_FFFFu32),
        (0u32..23).prop_map(|k| 1 << k),
        (0u32..23).prop_map(|k| 0x7F_FFFF & !(1 << k)),
        (0u32..24, 0u32..24).prop_map(|(a, b)| {
            let (lo, hi) = (a.min(b), a.max(b));
            ((1u32 << hi) - 1) & !((1u32 << lo) - 1)
        }),
    ]
    .boxed()
}

/// Finite numbers whose fraction is a [`fraction_pattern`].
pub fn patterned() -> BoxedStrategy<u32> {
    (sign(), 0u32..0xFF, fraction_pattern())
        .prop_map(|(s, e, f)| s | (e << 23) | f)
        .boxed()
}

/// Integers and half-integers in `[0.5, 2^32]` (conversion rounding and the ±2^31 edge).
pub fn integral() -> BoxedStrategy<u32> {
    (sign(), 0x7Eu32..=0x9F, 0u32..0x80_0000, 0u32..24)
        .prop_map(|(s, e, f, k)| s | (e << 23) | (f & !((1 << k) - 1)))
        .boxed()
}

/// Zeros, or normal numbers in `[2^-63, 2^64)` with at most 12 significant bits: the product
/// of two of them is always exact.
pub fn short_significand() -> BoxedStrategy<u32> {
    prop_oneof![
        9 => (sign(), 64u32..=190, 0u32..0x800).prop_map(|(s, e, f)| s | (e << 23) | (f << 12)),
        1 => zero(),
    ]
    .boxed()
}

/// Finite values (no NaN, no infinity) from every finite class.
pub fn finite() -> BoxedStrategy<u32> {
    prop_oneof![
        3 => normal(),
        1 => zero(),
        2 => boundary(),
        1 => near_overflow(),
        1 => near_one(),
        1 => patterned(),
        1 => integral(),
    ]
    .boxed()
}

/// Any bit pattern, biased: finite classes, specials, NaNs, infinities and uniform bits.
pub fn any_f32() -> BoxedStrategy<u32> {
    prop_oneof![
        6 => finite(),
        2 => special(),
        1 => nan(),
        1 => infinity(),
        2 => any::<u32>(),
    ]
    .boxed()
}

/// Cancellation pairs `(a, −a·(1 ± k ulp))`, `|k| ≤ 4`, for finite `a`.
pub fn cancellation_pair() -> BoxedStrategy<(u32, u32)> {
    (finite(), -4i32..=4)
        .prop_map(|(a, k)| {
            let m = (a & !SIGN) as i32 + k;
            let m = m.clamp(0, 0x7F7F_FFFF) as u32;
            (a, (a & SIGN) ^ SIGN | m)
        })
        .boxed()
}

/// Pairs whose exponents differ by 22..=27: the adder's halfway and sticky cases.
pub fn aligned_far_pair() -> BoxedStrategy<(u32, u32)> {
    (
        normal_in(28, 0xFE),
        22u32..=27,
        sign(),
        fraction_pattern(),
        any::<bool>(),
    )
        .prop_map(|(a, d, s, f, swap)| {
            let eb = exp_field(a) as u32 - d;
            let b = s | (eb << 23) | f;
            if swap { (b, a) } else { (a, b) }
        })
        .boxed()
}

/// Pairs with significands of at most 12..18 bits: many exact and exactly-halfway products
/// and quotients.
pub fn short_significand_pair() -> BoxedStrategy<(u32, u32)> {
    (finite(), finite(), 5u32..12)
        .prop_map(|(a, b, drop)| {
            let mask = !((1u32 << drop) - 1);
            (a & mask, b & mask)
        })
        .boxed()
}

/// Operand pairs for binary ops: independent biased operands, cancellation, far alignment,
/// short significands, and exponent sums near the overflow/underflow thresholds.
pub fn f32_pair() -> BoxedStrategy<(u32, u32)> {
    prop_oneof![
        4 => (any_f32(), any_f32()),
        1 => cancellation_pair(),
        1 => aligned_far_pair(),
        1 => short_significand_pair(),
        1 => (normal_in(1, 126), normal_in(1, 40)),    // mul underflow region
        1 => (normal_in(128, 0xFE), normal_in(100, 0xFE)), // mul overflow region
    ]
    .boxed()
}

/// i32 bit patterns biased to the i32→f32 rounding cases: small values, magnitudes above
/// 2^24, halfway patterns, extremes.
pub fn i32_bits() -> BoxedStrategy<u32> {
    prop_oneof![
        any::<u32>(),
        (-1000i32..1000).prop_map(|x| x as u32),
        (24u32..31, any::<u32>()).prop_map(|(k, r)| {
            // 25 significant bits ending in 1: exactly halfway between two floats.
            let base = (r | 1 << 31) >> (31 - k);
            (base & !((1 << (k - 23)) - 1)) | (1 << (k - 24))
        }),
        select(
            &[
                0u32,
                1,
                0x7FFF_FFFF,
                0x8000_0000,
                0x80FF_FFFF,
                0x00FF_FFFF,
                0x0100_0001
            ][..]
        ),
        (any::<bool>(), 0u32..32, 0u32..4).prop_map(|(neg, k, d)| {
            let v = (1u32 << k).wrapping_sub(d);
            if neg { v.wrapping_neg() } else { v }
        }),
    ]
    .boxed()
}
