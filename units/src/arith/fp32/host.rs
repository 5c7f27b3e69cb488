//! Host floating-point fast path for the fp32 adders, multipliers and divide/sqrt unit over
//! lanes.
//!
//! [`add_lanes`], [`sub_lanes`] and [`mul_lanes`] deliver exactly what the bit-level lane
//! datapaths of the same names ([`super::add::add_lanes`], [`super::add::sub_lanes`],
//! [`super::mul::mul_lanes`]) deliver — every result word and every flag — but compute the
//! common case with the host's own IEEE arithmetic (one `f32` add and two subtracts, or one
//! `f64` multiply and a conversion, per lane) instead of modelling the significand adder or
//! multiplier array bit by bit. They exist for the simulator's speed
//! ([`crate::ops::Op::eval_lanes_host`]); the bit-level datapath stays the model of record
//! (what the functional units and the waveforms show), and every lane the host cannot answer
//! provably goes to it.
//!
//! # Why the host's answer is exact
//!
//! On x86-64 (SSE/AVX, MXCSR at its default) and AArch64 (FPCR at its default) the host's
//! `f32`/`f64` `+`, `−`, `×` and the `f64 → f32` conversion (`as f32`) are the IEEE 754
//! operations, rounding to nearest even with gradual underflow (no flush-to-zero, no
//! denormals-are-zero); Rust never changes those modes and neither contracts (`a·b + c` to a
//! fused op) nor reassociates float expressions. On any other target ([`HOST_IS_IEEE`]) these
//! functions are the bit-level ones.
//!
//! **Add and subtract** (`a − b` is `a + (−b)`, the sign bit of `b` inverted). The host sum
//! `s = RN(x + y)` is the correctly rounded sum, as the bit-level adder's. A lane takes it
//! when `s` is normal and finite, or zero:
//!
//! * `s` finite: no overflow (rounding to nearest overflows exactly when it delivers ∞), and
//!   no infinite or NaN operand (either makes the sum ∞ or NaN), so no invalid.
//! * `s` normal: no underflow. Every finite binary32 is a multiple of 2^−149, so is an exact
//!   sum; one below 2^−126 in magnitude is a subnormal number and is delivered exactly. A
//!   normal `s` therefore comes from an exact sum of at least 2^−126: not tiny.
//! * `s` zero: by the same argument the exact sum was zero (a non-zero sum never rounds to
//!   zero), so no flag; its sign is IEEE 754 §6.3's, as the bit-level adder's: `+0` for
//!   `x + (−x)` under round-to-nearest, the common sign for `±0 + ±0`.
//! * Inexact, without computing the rounding error (the full TwoSum, Knuth TAOCP vol. 2
//!   §4.2.2): `s` is inexact exactly when `RN(s − x) ≠ y` or `RN(s − y) ≠ x`. If `s` is exact
//!   both differences are exact and equal the other operand. If not, for the operand of larger
//!   magnitude, say `x`, `s − x` is representable (Dekker's Fast2Sum lemma, which holds with
//!   gradual underflow: Boldo, Graillat and Muller, *On the robustness of the 2Sum and
//!   Fast2Sum algorithms*, ACM TOMS 2017), so `RN(s − x) = s − x ≠ y`.
//!
//! **Multiply.** The product of two binary32 significands has at most 48 bits and its
//! magnitude lies in `[2^−298, 2^256)`, so `p = x·y` in `f64` (53 bits, normal down to
//! 2^−1022) is exact, and `r = p as f32` is the correctly rounded product, rounded once. A
//! lane takes it when `|p| >= 2^−126` and `r` is finite (not tiny before rounding, so not
//! tiny after; no overflow; no NaN or infinite operand, which make `p` NaN or infinite), or
//! when `p` is zero (a zero operand times a finite one: an exact zero whose sign is the XOR of
//! the operands', no flag). Inexact is `f64(r) ≠ p`. Non-zero products below 2^−126 fall
//! back, among them those that round up to the smallest normal, whose underflow flag depends
//! on tininess after rounding.
//!
//! **Divide and square root.** The host's `f32` `/` and `sqrt` are IEEE's correctly rounded
//! operations, as the bit-level digit recurrence is. A lane takes the quotient `q = RN(x/y)`
//! when both operands are normal and `q` is finite with `|q| > 2^−126` (a quotient at the
//! smallest normal may have been tiny before rounding, whose underflow flag depends on
//! tininess after rounding: it falls back), and the root `r = RN(√x)` when `x` is normal and
//! positive (its root is normal). Neither can then be invalid, divide by zero, overflow or
//! underflow. Inexact is decided exactly in `f64`: `q·y` and `r·r` have at most 48
//! significant bits, so `f64(q)·f64(y)` and `f64(r)²` are exact, and the result is exact
//! precisely when they equal `x`.
//!
//! **Flush-to-zero.** The input half (`flush_input`) is applied before the host operation,
//! as the bit-level datapaths do; the output half only changes results that are subnormal or
//! rounded to zero from a non-zero value, which never take the host's answer.
//!
//! # Where it falls back
//!
//! To the bit-level op ([`super::add()`], [`super::sub()`], [`super::mul()`],
//! [`super::div()`], [`super::sqrt()`]) lane by lane: NaN or infinite operands, overflow, a
//! subnormal sum (exact, but flushed in flush-to-zero mode), a non-zero product below 2^−126
//! (subnormal, zero or the smallest normal); a division or root with a zero, subnormal,
//! infinite or NaN operand (or a negative radicand), or a quotient out of the normal range
//! or at its smallest value.
//!
//! # Lanes
//!
//! Lanes go in groups of eight through the shared lane loop (`lane_groups`) with no
//! operand pre-check (the host path accepts every operand class and decides from the result):
//! every whole group takes the host path on all its lanes without a branch — vector
//! instructions, eight `f32` lanes or twice four `f64` lanes at a time — then the lanes whose
//! `ok` is clear take the bit-level op. The lanes after the last whole group take the host
//! path one at a time, with the same fallback.

use super::{Flags, FpMode, LANE_GROUP, SIGN, flush_input, is_normal, lane_groups};

/// True on the targets whose `f32`/`f64` arithmetic is IEEE 754 binary32/binary64 with
/// round-to-nearest-even and gradual underflow, as this module requires (see the module doc).
pub const HOST_IS_IEEE: bool = cfg!(any(target_arch = "x86_64", target_arch = "aarch64"));

/// `out[i], flags[i] = add(a[i], b[i])` for every lane `i < out.len()`, bit-identical to
/// [`super::add::add_lanes`]; see the module doc.
///
/// # Panics
/// If `a` or `b` is shorter than `out`, or `flags` is not as long as `out`.
#[inline(never)]
pub fn add_lanes(a: &[u32], b: &[u32], mode: FpMode, out: &mut [u32], flags: &mut [Flags]) {
    if !HOST_IS_IEEE {
        return super::add::add_lanes(a, b, mode, out, flags);
    }
    let bit_level = |a, b| super::add(a, b, mode);
    // The mode is the same on every lane: one loop per mode, the IEEE one without the flush.
    if mode.flush_to_zero {
        let flush = |x| flush_input(x, FpMode::FTZ);
        let host = |a, b| add_lane(flush(a), flush(b));
        host_lanes(a, b, out, flags, host, bit_level);
    } else {
        host_lanes(a, b, out, flags, add_lane, bit_level);
    }
}

/// `out[i], flags[i] = sub(a[i], b[i])` for every lane `i < out.len()`, bit-identical to
/// [`super::add::sub_lanes`]: the host adder with the sign of `b` inverted.
///
/// # Panics
/// If `a` or `b` is shorter than `out`, or `flags` is not as long as `out`.
#[inline(never)]
pub fn sub_lanes(a: &[u32], b: &[u32], mode: FpMode, out: &mut [u32], flags: &mut [Flags]) {
    if !HOST_IS_IEEE {
        return super::add::sub_lanes(a, b, mode, out, flags);
    }
    let bit_level = |a, b| super::sub(a, b, mode);
    if mode.flush_to_zero {
        let flush = |x| flush_input(x, FpMode::FTZ);
        let host = |a, b| add_lane(flush(a), flush(b) ^ SIGN);
        host_lanes(a, b, out, flags, host, bit_level);
    } else {
        host_lanes(a, b, out, flags, |a, b| add_lane(a, b ^ SIGN), bit_level);
    }
}

/// `out[i], flags[i] = mul(a[i], b[i])` for every lane `i < out.len()`, bit-identical to
/// [`super::mul::mul_lanes`]; see the module doc.
///
/// # Panics
/// If `a` or `b` is shorter than `out`, or `flags` is not as long as `out`.
#[inline(never)]
pub fn mul_lanes(a: &[u32], b: &[u32], mode: FpMode, out: &mut [u32], flags: &mut [Flags]) {
    if !HOST_IS_IEEE {
        return super::mul::mul_lanes(a, b, mode, out, flags);
    }
    let bit_level = |a, b| super::mul(a, b, mode);
    if mode.flush_to_zero {
        let flush = |x| flush_input(x, FpMode::FTZ);
        let host = |a, b| mul_lane(flush(a), flush(b));
        host_lanes(a, b, out, flags, host, bit_level);
    } else {
        host_lanes(a, b, out, flags, mul_lane, bit_level);
    }
}

/// `out[i], flags[i] = div(a[i], b[i])` for every lane `i < out.len()`, bit-identical to the
/// divide/sqrt unit's division ([`super::div()`]); see the module doc.
///
/// # Panics
/// If `a` or `b` is shorter than `out`, or `flags` is not as long as `out`.
#[inline(never)]
pub fn div_lanes(a: &[u32], b: &[u32], mode: FpMode, out: &mut [u32], flags: &mut [Flags]) {
    let bit_level = |a, b| super::div(a, b, mode);
    if !HOST_IS_IEEE {
        return bit_by_bit(a, b, out, flags, bit_level);
    }
    // Subnormal operands fall back whatever the mode, so the input flush changes nothing here.
    host_lanes(a, b, out, flags, div_lane, bit_level);
}

/// `out[i], flags[i] = sqrt(a[i])` for every lane `i < out.len()`, bit-identical to the
/// divide/sqrt unit's square root ([`super::sqrt()`]); see the module doc.
///
/// # Panics
/// If `a` is shorter than `out`, or `flags` is not as long as `out`.
#[inline(never)]
pub fn sqrt_lanes(a: &[u32], mode: FpMode, out: &mut [u32], flags: &mut [Flags]) {
    let bit_level = |a, _| super::sqrt(a, mode);
    if !HOST_IS_IEEE {
        return bit_by_bit(a, a, out, flags, bit_level);
    }
    host_lanes(a, a, out, flags, |a, _| sqrt_lane(a), bit_level);
}

/// `bit_level` on every lane.
fn bit_by_bit(
    a: &[u32],
    b: &[u32],
    out: &mut [u32],
    flags: &mut [Flags],
    bit_level: impl Fn(u32, u32) -> (u32, Flags),
) {
    for (((o, f), &a), &b) in out.iter_mut().zip(flags.iter_mut()).zip(a).zip(b) {
        (*o, *f) = bit_level(a, b);
    }
}

/// The lane loop of this module: `host` on every lane, and `bit_level` wherever `host` clears
/// its `ok` bit; the whole groups of lanes in vectors, the lanes after them one by one.
///
/// # Panics
/// If `a` or `b` is shorter than `out`, or `flags` is not as long as `out`.
#[inline(always)]
fn host_lanes(
    a: &[u32],
    b: &[u32],
    out: &mut [u32],
    flags: &mut [Flags],
    host: impl Fn(u32, u32) -> (u32, Flags, bool),
    bit_level: impl Fn(u32, u32) -> (u32, Flags),
) {
    let n = out.len();
    assert_eq!(flags.len(), n, "one flag set per lane");
    let whole = n - n % LANE_GROUP;
    let (a_groups, a_left) = a[..n].split_at(whole);
    let (b_groups, b_left) = b[..n].split_at(whole);
    let (out_groups, out_left) = out.split_at_mut(whole);
    let (flags_groups, flags_left) = flags.split_at_mut(whole);
    // No operand pre-check: the host path takes every operand class, deciding by the result.
    let every_group = |_, _| true;
    let (host, bit_level) = (&host, &bit_level);
    lane_groups(
        a_groups,
        b_groups,
        out_groups,
        flags_groups,
        every_group,
        host,
        bit_level,
    );
    for i in 0..a_left.len() {
        (out_left[i], flags_left[i]) = match host(a_left[i], b_left[i]) {
            (bits, flags, true) => (bits, flags),
            _ => bit_level(a_left[i], b_left[i]),
        };
    }
}

/// `a + b` by the host (see the module doc): the sum, its flags, and `ok`, set where they are
/// the bit-level adder's. Branch-free; every value is computed for every operand.
#[inline(always)]
fn add_lane(a: u32, b: u32) -> (u32, Flags, bool) {
    let (x, y) = (f32::from_bits(a), f32::from_bits(b));
    let sum = x + y;
    let inexact = (sum - x != y) | (sum - y != x);
    // Normal and finite, or zero (tests on the bits, which the compiler keeps in vectors).
    let bits = sum.to_bits();
    let ok = is_normal(bits) | (bits << 1 == 0);
    (bits, Flags::when(inexact, Flags::INEXACT), ok)
}

/// `a × b` by the host (see the module doc): the product, its flags, and `ok`, set where they
/// are the bit-level multiplier's. Branch-free; every value is computed for every operand.
#[inline(always)]
fn mul_lane(a: u32, b: u32) -> (u32, Flags, bool) {
    let exact = f64::from(f32::from_bits(a)) * f64::from(f32::from_bits(b));
    let rounded = exact as f32; // round to nearest even, once
    let inexact = f64::from(rounded) != exact;
    // At least the smallest normal before rounding and finite after, or an exact zero; false
    // for NaN.
    let ok = (exact.abs() >= f64::from(f32::MIN_POSITIVE)) & (rounded.abs() < f32::INFINITY)
        | (exact == 0.0);
    (rounded.to_bits(), Flags::when(inexact, Flags::INEXACT), ok)
}

/// `a / b` by the host (see the module doc): the quotient, its flags, and `ok`, set where
/// they are the bit-level divider's. Branch-free.
#[inline(always)]
fn div_lane(a: u32, b: u32) -> (u32, Flags, bool) {
    let (x, y) = (f32::from_bits(a), f32::from_bits(b));
    let q = x / y;
    let inexact = f64::from(q) * f64::from(y) != f64::from(x);
    let ok =
        is_normal(a) & is_normal(b) & (q.abs() > f32::MIN_POSITIVE) & (q.abs() < f32::INFINITY);
    (q.to_bits(), Flags::when(inexact, Flags::INEXACT), ok)
}

/// `√a` by the host (see the module doc): the root, its flags, and `ok`, set where they are
/// the bit-level unit's. Branch-free.
#[inline(always)]
fn sqrt_lane(a: u32) -> (u32, Flags, bool) {
    let x = f32::from_bits(a);
    let r = x.sqrt();
    let inexact = f64::from(r) * f64::from(r) != f64::from(x);
    let ok = is_normal(a) & (a & SIGN == 0);
    (r.to_bits(), Flags::when(inexact, Flags::INEXACT), ok)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::arith::fp32::testgen::{SPECIALS, SplitMix64, biased_pair};

    type Lanes = fn(&[u32], &[u32], FpMode, &mut [u32], &mut [Flags]);
    type HostLane = fn(u32, u32) -> (u32, Flags, bool);

    /// The host lane functions and the bit-level lane functions they stand in for.
    const OPS: [(&str, Lanes, Lanes); 3] = [
        ("add", add_lanes, super::super::add::add_lanes),
        ("sub", sub_lanes, super::super::add::sub_lanes),
        ("mul", mul_lanes, super::super::mul::mul_lanes),
    ];

    fn sub_lane(a: u32, b: u32) -> (u32, Flags, bool) {
        add_lane(a, b ^ SIGN)
    }

    /// Host and bit-level lane functions agree on `(a, b)` in every lane position: alone, in
    /// a whole group among normal lanes, and as a leftover lane after a group.
    fn agree_everywhere(a: u32, b: u32) {
        for mode in [FpMode::IEEE, FpMode::FTZ] {
            for (name, host, bit_level) in OPS {
                for (len, at) in [(1, 0), (8, 0), (8, 5), (16, 11), (11, 10)] {
                    let mut xs = vec![0x3F80_0000; len];
                    let mut ys = vec![0x4049_0FDB; len];
                    (xs[at], ys[at]) = (a, b);
                    let run = |f: Lanes| {
                        let (mut out, mut flags) = (vec![0; len], vec![Flags::NONE; len]);
                        f(&xs, &ys, mode, &mut out, &mut flags);
                        (out, flags)
                    };
                    assert_eq!(
                        run(host),
                        run(bit_level),
                        "{name}({a:08X}, {b:08X}) {mode:?} in lane {at} of {len}"
                    );
                }
            }
        }
    }

    /// `(a, b)`, the bit-level result and flags, and whether the host lane answers it itself.
    fn case(lane: HostLane, a: u32, b: u32, want: (u32, Flags), host_answers: bool) {
        let (bits, flags, ok) = lane(a, b);
        assert_eq!(ok, host_answers, "host takes ({a:08X}, {b:08X})");
        if ok {
            assert_eq!((bits, flags), want, "host result of ({a:08X}, {b:08X})");
        }
        agree_everywhere(a, b);
    }

    const NX: Flags = Flags::INEXACT;
    const NONE: Flags = Flags::NONE;

    #[test]
    fn add_sub_edges() {
        let add = add_lane as HostLane;
        // Exact and inexact normal sums; a tie to even, down and up; a carry into the
        // exponent; cancellation to a normal result.
        case(add, 0x3F80_0000, 0x4000_0000, (0x4040_0000, NONE), true);
        case(add, 0x3F80_0000, 0x3380_0000, (0x3F80_0000, NX), true);
        case(add, 0x3F80_0001, 0x3380_0000, (0x3F80_0002, NX), true);
        case(add, 0x3FFF_FFFF, 0x3400_0000, (0x4000_0000, NONE), true);
        case(add, 0x3F80_0001, 0xBF80_0000, (0x3400_0000, NONE), true);
        // Far apart: the smaller operand only sets the sticky bit.
        case(add, 0x4F00_0000, 0x0080_0000, (0x4F00_0000, NX), true);
        // Zero sums: x + (−x) is +0, ±0 + ±0 keeps a common sign, x + 0 is x.
        case(add, 0x4049_0FDB, 0xC049_0FDB, (0, NONE), true);
        case(add, SIGN, SIGN, (SIGN, NONE), true);
        case(add, 0, SIGN, (0, NONE), true);
        case(add, 0xC049_0FDB, SIGN, (0xC049_0FDB, NONE), true);
        // A subnormal operand with a normal sum (flushed first in FTZ mode: see below).
        case(add, 0x0080_0000, 1, (0x0080_0001, NONE), true);
        case(add, 0x007F_FFFF, 1, (0x0080_0000, NONE), true);
        // Subnormal sums fall back (an FTZ flush, or the subnormal result).
        case(add, 0x0080_0001, 0x8080_0000, (1, NONE), false);
        case(add, 1, 1, (2, NONE), false);
        // Overflow, and the tie at the top that rounds to infinity.
        let overflow = Flags::OVERFLOW | NX;
        case(
            add,
            0x7F7F_FFFF,
            0x7F7F_FFFF,
            (0x7F80_0000, overflow),
            false,
        );
        case(
            add,
            0x7F7F_FFFF,
            0x7300_0000,
            (0x7F80_0000, overflow),
            false,
        );
        case(add, 0x7F7F_FFFF, 0x72FF_FFFF, (0x7F7F_FFFF, NX), true);
        // Infinities and NaNs.
        case(add, 0x7F80_0000, 0x3F80_0000, (0x7F80_0000, NONE), false);
        case(
            add,
            0x7F80_0000,
            0xFF80_0000,
            (0x7FC0_0000, Flags::INVALID),
            false,
        );
        case(
            add,
            0x7F80_0001,
            0x3F80_0000,
            (0x7FC0_0000, Flags::INVALID),
            false,
        );
        case(add, 0xFFC0_1234, 0x3F80_0000, (0x7FC0_0000, NONE), false);
        // Subtract: the same adder.
        let sub = sub_lane as HostLane;
        case(sub, 0x4049_0FDB, 0x4049_0FDB, (0, NONE), true);
        case(sub, SIGN, 0, (SIGN, NONE), true);
        case(sub, 0x3F80_0000, 0x3380_0000, (0x3F7F_FFFF, NONE), true);
        case(sub, 0x3F80_0000, 0x3300_0000, (0x3F80_0000, NX), true);
        case(
            sub,
            0x7F7F_FFFF,
            0xFF7F_FFFF,
            (0x7F80_0000, overflow),
            false,
        );
    }

    #[test]
    fn ftz_flushes_operands_before_the_host() {
        // 2^-126 + smallest subnormal: the subnormal is a zero in FTZ mode.
        let (a, b) = (0x0080_0000, 1);
        let host = |f: Lanes, mode| {
            let (mut out, mut flags) = ([0; 1], [NONE; 1]);
            f(&[a], &[b], mode, &mut out, &mut flags);
            (out[0], flags[0])
        };
        assert_eq!(host(add_lanes, FpMode::IEEE), (0x0080_0001, NONE));
        assert_eq!(host(add_lanes, FpMode::FTZ), (0x0080_0000, NONE));
        assert_eq!(host(sub_lanes, FpMode::FTZ), (0x0080_0000, NONE));
        assert_eq!(host(mul_lanes, FpMode::IEEE), (0, NX | Flags::UNDERFLOW));
        assert_eq!(host(mul_lanes, FpMode::FTZ), (0, NONE));
        // A subnormal result in FTZ mode is flushed with underflow and inexact.
        let (mut out, mut flags) = ([0; 1], [NONE; 1]);
        sub_lanes(
            &[0x0080_0001],
            &[0x0080_0000],
            FpMode::FTZ,
            &mut out,
            &mut flags,
        );
        assert_eq!((out[0], flags[0]), (0, Flags::UNDERFLOW | NX));
    }

    #[test]
    fn mul_edges() {
        let mul = mul_lane as HostLane;
        case(mul, 0x4000_0000, 0x4040_0000, (0x40C0_0000, NONE), true);
        // (1 + 2^-23)^2 = 1 + 2^-22 + 2^-46: inexact, rounds down.
        case(mul, 0x3F80_0001, 0x3F80_0001, (0x3F80_0002, NX), true);
        // A tie: (1 + 2^-12)^2 = 1 + 2^-11 + 2^-24 rounds to even.
        case(mul, 0x3F80_0800, 0x3F80_0800, (0x3F80_1000, NX), true);
        // Exactly the smallest normal, and one ulp above it.
        case(mul, 0x0100_0000, 0x3F00_0000, (0x0080_0000, NONE), true);
        case(mul, 0x2000_0001, 0x2000_0000, (0x0080_0001, NONE), true);
        // Just above the smallest normal, rounding down to it.
        case(mul, 0x3F7F_FFFF, 0x0080_0001, (0x0080_0000, NX), true);
        // Just below it, rounding up to it: tininess after rounding decides the underflow
        // flag (not tiny at 24 bits, then tiny), so the bit-level multiplier answers.
        case(mul, 0x3F7F_FFFE, 0x0080_0001, (0x0080_0000, NX), false);
        case(
            mul,
            0x3F7F_FFFF,
            0x0080_0000,
            (0x0080_0000, NX | Flags::UNDERFLOW),
            false,
        );
        // Subnormal products fall back; a subnormal operand with a normal product does not.
        case(mul, 0x0080_0000, 0x3F00_0000, (0x0040_0000, NONE), false);
        case(mul, 1, 0x4B00_0000, (0x0080_0000, NONE), true);
        // Largest finite, and overflow.
        case(mul, 0x7F7F_FFFF, 0x3F80_0000, (0x7F7F_FFFF, NONE), true);
        let overflow = Flags::OVERFLOW | NX;
        case(
            mul,
            0x7F00_0000,
            0x4000_0000,
            (0x7F80_0000, overflow),
            false,
        );
        case(
            mul,
            0x7F7F_FFFF,
            0x3F80_0001,
            (0x7F80_0000, overflow),
            false,
        );
        // Zeros: an exact zero with the XOR of the signs; with infinity, invalid.
        case(mul, 0xBF80_0000, 0, (SIGN, NONE), true);
        case(mul, SIGN, SIGN, (0, NONE), true);
        case(mul, 0x8000_0001, 0, (SIGN, NONE), true);
        case(mul, 0x7F80_0000, 0, (0x7FC0_0000, Flags::INVALID), false);
        case(mul, 0x7F80_0000, 0x8000_0001, (0xFF80_0000, NONE), false);
        case(
            mul,
            0x7FA0_0000,
            0x3F80_0000,
            (0x7FC0_0000, Flags::INVALID),
            false,
        );
    }

    #[test]
    fn specials_cross_product() {
        for &a in SPECIALS {
            for &b in SPECIALS {
                agree_everywhere(a, b);
            }
        }
    }

    /// An op over lanes: operands, results, flags.
    type LaneOp<'a> = dyn Fn(&[u32], &[u32], &mut [u32], &mut [Flags]) + 'a;

    /// The host and bit-level divider and square root agree on `(a, b)`, in every lane
    /// position and mode, and the host answers exactly when `host_answers`.
    fn div_sqrt_case(a: u32, b: u32, host_answers: (bool, bool)) {
        assert_eq!(
            div_lane(a, b).2,
            host_answers.0,
            "host takes {a:08X} / {b:08X}"
        );
        assert_eq!(sqrt_lane(a).2, host_answers.1, "host takes sqrt {a:08X}");
        for mode in [FpMode::IEEE, FpMode::FTZ] {
            for (len, at) in [(1, 0), (8, 0), (8, 5), (16, 11), (11, 10)] {
                let mut xs = vec![0x4049_0FDB; len];
                let mut ys = vec![0x3FC0_0000; len];
                (xs[at], ys[at]) = (a, b);
                let lanes = |f: &LaneOp| {
                    let (mut out, mut flags) = (vec![0; len], vec![Flags::NONE; len]);
                    f(&xs, &ys, &mut out, &mut flags);
                    (out, flags)
                };
                let each = |f: fn(u32, u32, FpMode) -> (u32, Flags)| {
                    lanes(&|a, b, out, flags| {
                        for i in 0..a.len() {
                            (out[i], flags[i]) = f(a[i], b[i], mode);
                        }
                    })
                };
                assert_eq!(
                    lanes(&|a, b, out, flags| div_lanes(a, b, mode, out, flags)),
                    each(super::super::div),
                    "{a:08X} / {b:08X} {mode:?} in lane {at} of {len}"
                );
                assert_eq!(
                    lanes(&|a, _, out, flags| sqrt_lanes(a, mode, out, flags)),
                    each(|a, _, mode| super::super::sqrt(a, mode)),
                    "sqrt {a:08X} {mode:?} in lane {at} of {len}"
                );
            }
        }
    }

    #[test]
    fn div_sqrt_edges() {
        // Exact and inexact quotients and roots.
        div_sqrt_case(0x40C0_0000, 0x4040_0000, (true, true));
        div_sqrt_case(0x3F80_0000, 0x4040_0000, (true, true));
        div_sqrt_case(0x4080_0000, 0x3F80_0000, (true, true));
        // A quotient at the smallest normal, which may have been tiny before rounding,
        // falls back; one just above it does not.
        div_sqrt_case(0x0080_0000, 0x3F80_0000, (false, true));
        div_sqrt_case(0x0080_0001, 0x3F80_0000, (true, true));
        div_sqrt_case(0x0080_0000, 0x3F7F_FFFF, (true, true));
        div_sqrt_case(0x0080_0000, 0x3F80_0001, (false, true));
        // Overflow and underflow of the quotient.
        div_sqrt_case(0x7F7F_FFFF, 0x3F00_0000, (false, true));
        div_sqrt_case(0x0100_0000, 0x7F00_0000, (false, true));
        // Zeros, subnormals, negative radicands, infinities and NaNs fall back.
        div_sqrt_case(0, 0x3F80_0000, (false, false));
        div_sqrt_case(SIGN, 0x3F80_0000, (false, false));
        div_sqrt_case(0x3F80_0000, 0, (false, true));
        div_sqrt_case(1, 0x3F80_0000, (false, false));
        div_sqrt_case(0x3F80_0000, 1, (false, true));
        div_sqrt_case(0xBF80_0000, 0x3F80_0000, (true, false));
        div_sqrt_case(0x7F80_0000, 0x3F80_0000, (false, false));
        div_sqrt_case(0x3F80_0000, 0x7F80_0000, (false, true));
        div_sqrt_case(0x7FC0_0000, 0x3F80_0000, (false, false));
        div_sqrt_case(0x3F80_0000, 0xFF80_0001, (false, true));
        // The smallest and largest normal radicands (the first quotient is subnormal).
        div_sqrt_case(0x0080_0000, 0x4000_0000, (false, true));
        div_sqrt_case(0x7F7F_FFFF, 0x4000_0000, (true, true));
        for &a in SPECIALS {
            for &b in SPECIALS {
                div_sqrt_case(a, b, (div_lane(a, b).2, sqrt_lane(a).2));
            }
        }
    }

    /// Random operands, biased and normal: host and bit-level division and root agree, and
    /// the host answers most lanes whose result is normal.
    #[test]
    fn random_divisions_and_roots_agree() {
        let mut rng = SplitMix64::new(0xD1F5);
        let (mut taken, mut normal_results) = (0, 0);
        for round in 0..4000 {
            let mode = [FpMode::IEEE, FpMode::FTZ][round % 2];
            let (a, b) = match round / 2 % 2 {
                0 => biased_pair(&mut rng),
                _ => (normal(&mut rng), normal(&mut rng)),
            };
            let mut got = ([0; 1], [NONE; 1]);
            div_lanes(&[a], &[b], mode, &mut got.0, &mut got.1);
            assert_eq!(
                (got.0[0], got.1[0]),
                super::super::div(a, b, mode),
                "{a:08X} / {b:08X}"
            );
            sqrt_lanes(&[a], mode, &mut got.0, &mut got.1);
            assert_eq!(
                (got.0[0], got.1[0]),
                super::super::sqrt(a, mode),
                "sqrt {a:08X}"
            );
            let (q, _) = super::super::div(a, b, mode);
            if super::super::is_normal(q)
                && q & !SIGN != 0x0080_0000
                && is_normal(a)
                && is_normal(b)
            {
                normal_results += 1;
                taken += div_lane(a, b).2 as u32;
            }
        }
        assert!(
            taken == normal_results && taken > 1000,
            "{taken} of {normal_results}"
        );
    }

    /// A normal operand with a random sign and an exponent in `[2^-27, 2^28)`.
    fn normal(rng: &mut SplitMix64) -> u32 {
        (rng.next_u32() & 0x807F_FFFF) | ((100 + rng.below(55)) << 23)
    }

    /// Host and bit-level lanes agree on random biased vectors of every length up to 40, and
    /// the host answers most lanes whose result is normal.
    #[test]
    fn random_lanes_agree_and_mostly_take_the_host() {
        let mut rng = SplitMix64::new(0x4057);
        let (mut taken, mut normal_results) = ([0u32; 3], [0u32; 3]);
        for round in 0..6000 {
            let len = round % 41;
            let mode = [FpMode::IEEE, FpMode::FTZ][round % 2];
            // Half the rounds mostly normal operands (whole groups on the host), half biased.
            let (a, b): (Vec<u32>, Vec<u32>) = (0..len)
                .map(|_| match round / 2 % 2 {
                    0 => biased_pair(&mut rng),
                    _ => (normal(&mut rng), normal(&mut rng)),
                })
                .unzip();
            for (i, (name, host, bit_level)) in OPS.into_iter().enumerate() {
                let mut got = (vec![0; len], vec![NONE; len]);
                let mut want = got.clone();
                host(&a, &b, mode, &mut got.0, &mut got.1);
                bit_level(&a, &b, mode, &mut want.0, &mut want.1);
                assert_eq!(got, want, "{name} {mode:?} on {a:08X?} {b:08X?}");
                let lane = [add_lane, sub_lane, mul_lane][i];
                for (&x, &y) in a.iter().zip(&b) {
                    taken[i] += lane(x, y).2 as u32;
                }
                normal_results[i] += want
                    .0
                    .iter()
                    .filter(|&&r| super::super::is_normal(r))
                    .count() as u32;
            }
        }
        for i in 0..3 {
            let (taken, normal) = (taken[i], normal_results[i]);
            assert!(
                taken >= normal / 100 * 99,
                "{}: {taken} of {normal}",
                OPS[i].0
            );
        }
    }
}
