//! IEEE 754-2008 binary32 combinational datapath on raw bit patterns.
//!
//! Every op is a pure function `u32` bits in, `u32` bits (or `bool`) and [`Flags`] out. No host
//! floating point is used by the datapath: the blocks are the integer datapaths a hardware FPU
//! is built from — unpack/classify, alignment shifter with sticky, significand adder,
//! multiplier array, digit-recurrence divider / square-rooter, leading-zero normaliser, and one
//! shared round-and-pack stage ([`round`]).
//!
//! The one exception is [`host`], an alternative evaluation of the add, sub and mul lane
//! datapaths for the simulator's speed: it computes the cases it can prove bit-identical
//! (result and flags) with the host's IEEE arithmetic and hands every other lane to the
//! bit-level datapath, which stays the model of record.
//!
//! # Arithmetic contract (ARCHITECTURE §4)
//!
//! Results and flags are bit-identical to Berkeley SoftFloat 3 built with the RISC-V
//! specialisation (`softfloat-sys` feature `riscv`), round-to-nearest-even:
//!
//! * every NaN result is the canonical quiet NaN [`CANONICAL_NAN`] `0x7FC00000` (no payload
//!   propagation); a signalling NaN operand raises invalid;
//! * tininess is detected *after* rounding; underflow is raised when the result is tiny and
//!   inexact;
//! * subnormal operands and results are fully supported unless [`FpMode::flush_to_zero`].
//!
//! # Flush-to-zero mode
//!
//! With [`FpMode::flush_to_zero`] set (a machine parameter, off by default):
//!
//! * **inputs**: a subnormal operand is replaced by a zero of the same sign before the op.
//!   This raises no flag (IEEE 754 has no denormal-operand flag). It applies to every op that
//!   takes a mode: arithmetic, compares, min/max and `f32 -> i32` conversion (so a subnormal
//!   converts to 0 with no inexact).
//! * **outputs**: an arithmetic result that would be a subnormal number, or a zero produced
//!   by rounding a non-zero tiny value, is delivered as a zero of the same sign and raises
//!   exactly **underflow | inexact**. A result that rounds up to the smallest normal
//!   `±0x00800000` is kept (with the flags the non-FTZ op raises). Exact zeros (e.g.
//!   `x - x`) are not affected. Thus an FTZ result is never subnormal.
//! * [`abs`] and [`neg`] are sign-bit operations and take no mode: they never flush.
//!   [`min`]/[`max`] return one of the (flushed) operands and raise no underflow.
//!
//! # Ops
//!
//! | op | function | reference |
//! |---|---|---|
//! | add, sub | [`add()`], [`sub()`] | `f32_add`, `f32_sub` |
//! | mul | [`mul()`] | `f32_mul` |
//! | div | [`div()`] (radix-4 digit recurrence, [`div::DivRecurrence`]) | `f32_div` |
//! | sqrt | [`sqrt()`] (radix-4 digit recurrence, [`sqrt::SqrtRecurrence`]) | `f32_sqrt` |
//! | compare | [`lt`], [`le`] (signalling), [`eq`] (quiet) | `f32_lt`, `f32_le`, `f32_eq` |
//! | min, max | [`min`], [`max`] | RISC-V `fmin.s`/`fmax.s` built on SoftFloat |
//! | abs, neg | [`abs`], [`neg`] | sign-bit ops, no flags |
//! | f32→i32 | [`to_i32`] (nearest-even), [`to_i32_rtz`] (toward zero) | `f32_to_i32(.., exact = true)` |
//! | i32→f32 | [`from_i32`] | `i32_to_f32` |
//!
//! References: IEEE Std 754-2008; J. R. Hauser, *Berkeley SoftFloat Release 3* documentation
//! (`SoftFloat.html`, `SoftFloat-specialize.html`) and *TestFloat* documentation; M. D.
//! Ercegovac and T. Lang, *Digital Arithmetic*, Morgan Kaufmann 2004 (ch. 2 addition,
//! ch. 4 multiplication, ch. 5 division by digit recurrence, ch. 6 square root, ch. 8
//! floating-point representation and rounding).

/// The bit-level first guess of `1/x` for a positive normal `x`: `RECIPROCAL_GUESS −
/// bits(x)` as an integer subtract, within 5.1 % of it; each Newton–Raphson step
/// `y·(2 − x·y)` then squares the relative error (0.26 %, 6.5e-6, then fp32's rounding).
/// `irast` and the hardware rasterizer take `1/ΣE` so when a scene asks for Newton steps.
pub const RECIPROCAL_GUESS: u32 = 0x7EF3_11C3;

pub mod add;
pub mod compare;
pub mod convert;
pub mod div;
pub mod host;
pub mod mul;
pub mod round;
pub mod sign;
pub mod sqrt;
pub mod testfloat;
pub mod testgen;

#[cfg(feature = "proptest")]
pub mod strategies;

#[cfg(feature = "softfloat")]
pub mod reference;

pub use crate::arith::flags::Flags;
pub use add::{add, sub};
pub use compare::{eq, le, lt, max, min};
pub use convert::{from_i32, to_i32, to_i32_rtz};
pub use div::div;
pub use mul::mul;
pub use sign::{abs, neg};
pub use sqrt::sqrt;

/// Operating mode of the FPU datapath (a machine parameter, not per op).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct FpMode {
    /// Flush subnormal inputs and outputs to signed zero (see the module doc for the flags).
    pub flush_to_zero: bool,
}

impl FpMode {
    /// IEEE mode: full subnormal support (the default).
    pub const IEEE: FpMode = FpMode {
        flush_to_zero: false,
    };
    /// Flush-to-zero mode.
    pub const FTZ: FpMode = FpMode {
        flush_to_zero: true,
    };
}

/// Outcome of the setup (unpack) stage of a multi-cycle op such as [`div()`] or [`sqrt()`]:
/// either the result is already known (special operands), or a job for the iterative core.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Setup<J> {
    /// Special-case result (NaN, infinity, zero, invalid, divide-by-zero) and its flags.
    Done(u32, Flags),
    /// Work for the digit-recurrence core.
    Run(J),
}

/// Sign bit.
pub const SIGN: u32 = 0x8000_0000;
/// Biased-exponent field.
pub const EXP_MASK: u32 = 0x7F80_0000;
/// Fraction (trailing significand) field.
pub const FRAC_MASK: u32 = 0x007F_FFFF;
/// The fraction's MSB: set for a quiet NaN, clear for a signalling NaN.
pub const QUIET_BIT: u32 = 0x0040_0000;
/// The hidden (implicit) significand bit of a normal number, at fraction position 23.
pub const HIDDEN: u32 = 0x0080_0000;
/// The canonical quiet NaN of the RISC-V specialisation.
pub const CANONICAL_NAN: u32 = 0x7FC0_0000;
/// `+inf`.
pub const POS_INF: u32 = 0x7F80_0000;
/// Exponent bias.
pub const BIAS: i32 = 127;

/// True for any NaN (quiet or signalling).
#[inline]
pub const fn is_nan(a: u32) -> bool {
    a & !SIGN > POS_INF
}

/// True for a signalling NaN (exponent all ones, fraction non-zero with its MSB clear).
#[inline]
pub const fn is_snan(a: u32) -> bool {
    a & 0x7FC0_0000 == 0x7F80_0000 && a & (FRAC_MASK >> 1) != 0
}

/// True for `±inf`.
#[inline]
pub const fn is_inf(a: u32) -> bool {
    a & !SIGN == POS_INF
}

/// True for `±0`.
#[inline]
pub const fn is_zero(a: u32) -> bool {
    a & !SIGN == 0
}

/// True for a subnormal (denormal) number: exponent field 0, fraction non-zero.
#[inline]
pub const fn is_subnormal(a: u32) -> bool {
    a & EXP_MASK == 0 && a & FRAC_MASK != 0
}

/// True for a normal number: biased exponent field in `1..=254`. One test on the exponent
/// field (`e + 1` is at least 2 modulo 256, so its bits 7..1 are not all zero), the operand
/// check of the arithmetic fast paths.
#[inline(always)]
pub(crate) const fn is_normal(a: u32) -> bool {
    (a >> 23).wrapping_add(1) & 0xFE != 0
}

/// Biased exponent field.
#[inline]
pub(crate) const fn exp_field(a: u32) -> i32 {
    ((a >> 23) & 0xFF) as i32
}

/// The input half of flush-to-zero: a subnormal becomes a zero of the same sign.
#[inline(always)]
pub(crate) fn flush_input(a: u32, mode: FpMode) -> u32 {
    if mode.flush_to_zero && a & EXP_MASK == 0 {
        a & SIGN
    } else {
        a
    }
}

/// NaN stage shared by the arithmetic ops: the result is always the canonical NaN, and
/// invalid is raised if either operand is signalling.
#[inline]
pub(crate) fn propagate_nan(a: u32, b: u32) -> (u32, Flags) {
    (
        CANONICAL_NAN,
        Flags::when(is_snan(a) | is_snan(b), Flags::INVALID),
    )
}

/// Unpack a finite non-zero operand into `(biased exponent, significand)` with the
/// significand's leading one at bit 23 (subnormals are normalised by the leading-zero
/// counter, giving an exponent below 1).
#[inline]
pub(crate) fn unpack_normalised(a: u32) -> (i32, u32) {
    let e = exp_field(a);
    let f = a & FRAC_MASK;
    if e != 0 {
        (e, f | HIDDEN)
    } else {
        let shift = f.leading_zeros() as i32 - 8;
        (1 - shift, f << shift)
    }
}

/// Lanes per group of [`lane_loop`] (two 4-lane vector registers).
pub(crate) const LANE_GROUP: usize = 8;

/// The lane loop of the `*_lanes` datapaths (one op issued to a unit in every cluster):
/// `out[i], flags[i] = one(a[i], b[i])` for every lane, where `one` is the op on one set of
/// operands and `fast` a branch-free fast path for normal operands returning
/// `(bits, flags, ok)` that agrees with `one` wherever `ok` is set.
///
/// Lanes go in groups of [`LANE_GROUP`]. A group whose operands are all normal takes `fast`
/// on every lane — a fixed trip count without branches, which the compiler unrolls and
/// evaluates several lanes at a time in vector registers — and then `one` on the lanes whose
/// `ok` is clear. A group with a zero, subnormal, infinite or NaN operand, where `fast` would
/// be wasted work, and the lanes left over after the last whole group, take `one` lane by
/// lane. Callers keep their lane functions out of line (`#[inline(never)]`) so that this is
/// compiled once, in that context, whatever their own callers.
///
/// # Panics
/// If `a` or `b` is shorter than `out`, or `flags` is not as long as `out`.
#[inline(always)]
pub(crate) fn lane_loop(
    a: &[u32],
    b: &[u32],
    out: &mut [u32],
    flags: &mut [Flags],
    fast: impl Fn(u32, u32) -> (u32, Flags, bool),
    one: impl Fn(u32, u32) -> (u32, Flags),
) {
    lane_groups(
        a,
        b,
        out,
        flags,
        |a, b| is_normal(a) & is_normal(b),
        fast,
        one,
    );
}

/// [`lane_loop`] with the group test given: a group takes `fast` on every lane when every
/// lane's operands pass `worth_trying` (a fast path that accepts every operand class passes
/// `|_, _| true`, and then every whole group takes it).
///
/// # Panics
/// If `a` or `b` is shorter than `out`, or `flags` is not as long as `out`.
#[inline(always)]
pub(crate) fn lane_groups(
    a: &[u32],
    b: &[u32],
    out: &mut [u32],
    flags: &mut [Flags],
    worth_trying: impl Fn(u32, u32) -> bool,
    fast: impl Fn(u32, u32) -> (u32, Flags, bool),
    one: impl Fn(u32, u32) -> (u32, Flags),
) {
    let n = out.len();
    let (a, b) = (&a[..n], &b[..n]);
    assert_eq!(flags.len(), n, "one flag set per lane");
    let (ag, ar) = a.as_chunks::<LANE_GROUP>();
    let (bg, br) = b.as_chunks::<LANE_GROUP>();
    let (og, or) = out.as_chunks_mut::<LANE_GROUP>();
    let (fg, fr) = flags.as_chunks_mut::<LANE_GROUP>();
    for (((a, b), out), flags) in ag.iter().zip(bg).zip(og.iter_mut()).zip(fg.iter_mut()) {
        let mut try_fast = true;
        for i in 0..LANE_GROUP {
            try_fast &= worth_trying(a[i], b[i]);
        }
        if try_fast {
            let (mut ok, mut all_ok) = ([false; LANE_GROUP], true);
            for i in 0..LANE_GROUP {
                (out[i], flags[i], ok[i]) = fast(a[i], b[i]);
                all_ok &= ok[i];
            }
            if !all_ok {
                redo_group(a, b, &ok, out, flags, &one);
            }
        } else {
            for i in 0..LANE_GROUP {
                (out[i], flags[i]) = one(a[i], b[i]);
            }
        }
    }
    for (((&a, &b), out), flags) in ar.iter().zip(br).zip(or.iter_mut()).zip(fr.iter_mut()) {
        (*out, *flags) = one(a, b);
    }
}

/// The lanes of a group whose `ok` is clear, through `one`.
#[cold]
#[inline(never)]
fn redo_group(
    a: &[u32; LANE_GROUP],
    b: &[u32; LANE_GROUP],
    ok: &[bool; LANE_GROUP],
    out: &mut [u32; LANE_GROUP],
    flags: &mut [Flags; LANE_GROUP],
    one: &impl Fn(u32, u32) -> (u32, Flags),
) {
    for i in 0..LANE_GROUP {
        if !ok[i] {
            (out[i], flags[i]) = one(a[i], b[i]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classify() {
        assert!(is_nan(0x7FC0_0000) && !is_snan(0x7FC0_0000));
        assert!(is_nan(0xFF80_0001) && is_snan(0xFF80_0001));
        assert!(is_snan(0x7FBF_FFFF));
        assert!(!is_nan(POS_INF) && is_inf(POS_INF) && is_inf(0xFF80_0000));
        assert!(is_zero(0) && is_zero(SIGN) && !is_zero(1));
        assert!(is_subnormal(1) && is_subnormal(0x807F_FFFF) && !is_subnormal(HIDDEN));
        assert!(is_normal(HIDDEN) && is_normal(0xFF7F_FFFF) && is_normal(0x3F80_0000));
        assert!(!is_normal(0) && !is_normal(SIGN | FRAC_MASK) && !is_normal(POS_INF | SIGN));
        assert!(!is_normal(CANONICAL_NAN) && !is_normal(0xFFFF_FFFF));
        assert_eq!(unpack_normalised(1), (-22, HIDDEN));
        assert_eq!(unpack_normalised(0x0040_0000), (0, HIDDEN));
        assert_eq!(unpack_normalised(0x3F80_0001), (127, HIDDEN | 1));
        assert_eq!(flush_input(0x8000_0001, FpMode::FTZ), SIGN);
        assert_eq!(flush_input(0x8000_0001, FpMode::IEEE), 0x8000_0001);
        assert_eq!(flush_input(0x0080_0000, FpMode::FTZ), 0x0080_0000);
    }
}
