//! Conversions between binary32 and 32-bit two's-complement integers (IEEE 754-2008 §5.4.1
//! convertFromInt, §5.8 convertToInteger / convertToIntegerExact).
//!
//! * [`to_i32`] (round to nearest even) and [`to_i32_rtz`] (round toward zero, the C cast and
//!   RISC-V `fcvt.w.s rtz`): a barrel shifter places the significand on a fixed point with
//!   32 fraction bits, an incrementer rounds, and a negater applies the sign. They match
//!   SoftFloat `f32_to_i32(a, mode, exact = true)` with the RISC-V specialisation: inexact is
//!   raised when the value was not an integer (the RISC-V `fcvt` behaviour); an out-of-range
//!   value or NaN is invalid and returns `0x7FFFFFFF` for NaN and positive overflow (incl.
//!   `+inf`), `0x80000000` for negative overflow (incl. `-inf`). `-2^31` itself converts
//!   exactly.
//! * [`from_i32`]: absolute value, leading-zero normaliser, and the shared round-and-pack
//!   stage (inexact for magnitudes above 2^24 that are not representable).
//!
//! Integer values are carried as `u32` bit patterns (two's complement).

use super::round::round_pack;
use super::{FRAC_MASK, FpMode, HIDDEN, SIGN, exp_field, flush_input, is_nan};
use crate::arith::flags::Flags;

const I32_MAX: u32 = 0x7FFF_FFFF;
const I32_MIN: u32 = 0x8000_0000;

/// Shared f32 → i32 datapath; `nearest` selects round-to-nearest-even, else toward zero.
#[inline(always)]
fn to_i32_core(a: u32, mode: FpMode, nearest: bool) -> (u32, Flags) {
    let a = flush_input(a, mode);
    let negative = a & SIGN != 0;
    let e = exp_field(a);
    let m = (a & FRAC_MASK) | if e != 0 { HIDDEN } else { 0 };
    // value = m × 2^(e − 150)
    if e >= 150 {
        // Integer already; overflow unless below 2^31 (or exactly −2^31).
        if e <= 157 {
            let mag = m << (e - 150);
            return (if negative { mag.wrapping_neg() } else { mag }, Flags::NONE);
        }
        if negative && a == 0xCF00_0000 {
            return (I32_MIN, Flags::NONE);
        }
        let r = if negative && !is_nan(a) {
            I32_MIN
        } else {
            I32_MAX
        };
        return (r, Flags::INVALID);
    }
    if e < 126 {
        // |value| < 0.5: rounds to 0 in both modes.
        return (0, Flags::when(a & !SIGN != 0, Flags::INEXACT));
    }
    // 126 ≤ e ≤ 149: fixed point with 32 fraction bits, no bits lost (shift ≤ 24).
    let fixed = (m as u64) << (32 - (150 - e));
    let int = (fixed >> 32) as u32;
    let frac = fixed as u32;
    let up = nearest && (frac > 0x8000_0000 || (frac == 0x8000_0000 && int & 1 != 0));
    let mag = int + up as u32; // ≤ 2^24: no overflow
    (
        if negative { mag.wrapping_neg() } else { mag },
        Flags::when(frac != 0, Flags::INEXACT),
    )
}

/// f32 → i32, rounding to nearest even (SoftFloat `f32_to_i32(a, near_even, true)`).
#[inline]
pub fn to_i32(a: u32, mode: FpMode) -> (u32, Flags) {
    to_i32_core(a, mode, true)
}

/// f32 → i32, rounding toward zero (SoftFloat `f32_to_i32_r_minMag(a, true)`).
#[inline]
pub fn to_i32_rtz(a: u32, mode: FpMode) -> (u32, Flags) {
    to_i32_core(a, mode, false)
}

/// i32 → f32 (two's-complement bits in), rounding to nearest even (SoftFloat `i32_to_f32`).
/// The mode is irrelevant (the result is never subnormal) and is not taken.
#[inline]
pub fn from_i32(x: u32) -> (u32, Flags) {
    if x == 0 {
        return (0, Flags::NONE);
    }
    let sign = x & SIGN;
    let mag = if sign != 0 { x.wrapping_neg() } else { x }; // 2^31 for i32::MIN
    let lz = mag.leading_zeros();
    let norm = mag << lz; // leading one at bit 31
    // Move the leading one to bit 30, jamming the dropped bit.
    let sig = (norm >> 1) | (norm & 1);
    round_pack(sign, 158 - lz as i32, sig, FpMode::IEEE)
}

#[cfg(test)]
mod tests {
    use super::*;
    const M: FpMode = FpMode::IEEE;

    #[test]
    fn float_to_int() {
        assert_eq!(to_i32(0x3FC0_0000, M), (2, Flags::INEXACT)); // 1.5 → 2
        assert_eq!(to_i32(0x4020_0000, M), (2, Flags::INEXACT)); // 2.5 → 2
        assert_eq!(to_i32(0xC020_0000, M), (-2i32 as u32, Flags::INEXACT)); // -2.5 → -2
        assert_eq!(to_i32_rtz(0xC060_0000, M), (-3i32 as u32, Flags::INEXACT)); // -3.5 → -3
        assert_eq!(to_i32(0x3F00_0000, M), (0, Flags::INEXACT)); // 0.5 → 0
        assert_eq!(to_i32(0x3F00_0001, M), (1, Flags::INEXACT));
        assert_eq!(to_i32(0x3EFF_FFFF, M), (0, Flags::INEXACT));
        assert_eq!(to_i32(0x8000_0000, M), (0, Flags::NONE));
        assert_eq!(to_i32(0x4EFF_FFFF, M), (0x7FFF_FF80, Flags::NONE));
        assert_eq!(to_i32(0x4F00_0000, M), (I32_MAX, Flags::INVALID));
        assert_eq!(to_i32(0xCF00_0000, M), (I32_MIN, Flags::NONE));
        assert_eq!(to_i32(0xCF00_0001, M), (I32_MIN, Flags::INVALID));
        assert_eq!(to_i32(0xFF80_0000, M), (I32_MIN, Flags::INVALID));
        assert_eq!(to_i32(0x7F80_0000, M), (I32_MAX, Flags::INVALID));
        assert_eq!(to_i32(0xFFC0_0000, M), (I32_MAX, Flags::INVALID));
        assert_eq!(to_i32(0x8000_0001, M), (0, Flags::INEXACT));
        assert_eq!(to_i32(0x8000_0001, FpMode::FTZ), (0, Flags::NONE));
    }

    #[test]
    fn int_to_float() {
        assert_eq!(from_i32(1), (0x3F80_0000, Flags::NONE));
        assert_eq!(from_i32(-1i32 as u32), (0xBF80_0000, Flags::NONE));
        assert_eq!(from_i32(I32_MIN), (0xCF00_0000, Flags::NONE));
        assert_eq!(from_i32(I32_MAX), (0x4F00_0000, Flags::INEXACT));
        assert_eq!(from_i32(0x0100_0001), (0x4B80_0000, Flags::INEXACT)); // tie → even
        assert_eq!(from_i32(0x0100_0003), (0x4B80_0002, Flags::INEXACT)); // tie → even (up)
        assert_eq!(from_i32(0x00FF_FFFF), (0x4B7F_FFFF, Flags::NONE));
    }
}
