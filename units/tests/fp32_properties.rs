//! Property tests of the fp32 datapath that need no SoftFloat: algebraic identities, IEEE
//! special-value rules, flush-to-zero invariants, recurrence invariants, and agreement with
//! the host's IEEE binary32 arithmetic (x86-64 SSE / AArch64 are correctly rounded, RNE,
//! with subnormals) on every non-NaN result. The operand strategies live in
//! `imagine_units::arith::fp32::strategies` (feature `proptest`, enabled for tests).

use imagine_units::arith::fp32::div::{DIV_STEPS, DivRecurrence};
use imagine_units::arith::fp32::sqrt::{SQRT_STEPS, SqrtRecurrence};
use imagine_units::arith::fp32::strategies::*;
use imagine_units::arith::fp32::{self as fp, CANONICAL_NAN, Flags, FpMode, SIGN};
use proptest::prelude::*;

const M: FpMode = FpMode::IEEE;

fn host(a: u32) -> f32 {
    f32::from_bits(a)
}

/// Our result agrees with the host's: equal bits, or both NaN (ours canonical).
fn agrees(ours: u32, host: f32) -> Result<(), TestCaseError> {
    if host.is_nan() {
        prop_assert_eq!(ours, CANONICAL_NAN, "host NaN, ours {:08X}", ours);
    } else {
        prop_assert_eq!(
            ours,
            host.to_bits(),
            "ours {:08X} host {:08X}",
            ours,
            host.to_bits()
        );
    }
    Ok(())
}

fn invalid_iff_snan_or(a: u32, b: u32, flags: Flags, extra: bool) -> Result<(), TestCaseError> {
    prop_assert_eq!(
        flags.contains(Flags::INVALID),
        fp::is_snan(a) || fp::is_snan(b) || extra
    );
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4096))]

    #[test]
    fn add_sub_mul_div_match_host((a, b) in f32_pair()) {
        agrees(fp::add(a, b, M).0, host(a) + host(b))?;
        agrees(fp::sub(a, b, M).0, host(a) - host(b))?;
        agrees(fp::mul(a, b, M).0, host(a) * host(b))?;
        agrees(fp::div(a, b, M).0, host(a) / host(b))?;
    }

    #[test]
    fn sqrt_matches_host(a in any_f32()) {
        agrees(fp::sqrt(a, M).0, host(a).sqrt())?;
    }

    #[test]
    fn add_and_mul_commute((a, b) in f32_pair(), ftz in any::<bool>()) {
        let mode = FpMode { flush_to_zero: ftz };
        prop_assert_eq!(fp::add(a, b, mode), fp::add(b, a, mode));
        prop_assert_eq!(fp::mul(a, b, mode), fp::mul(b, a, mode));
        prop_assert_eq!(fp::min(a, b, mode), fp::min(b, a, mode));
        prop_assert_eq!(fp::max(a, b, mode), fp::max(b, a, mode));
    }

    #[test]
    fn sub_is_add_of_negation((a, b) in f32_pair(), ftz in any::<bool>()) {
        let mode = FpMode { flush_to_zero: ftz };
        prop_assert_eq!(fp::sub(a, b, mode), fp::add(a, fp::neg(b), mode));
    }

    #[test]
    fn x_minus_x_is_positive_zero(x in finite(), ftz in any::<bool>()) {
        let mode = FpMode { flush_to_zero: ftz };
        prop_assert_eq!(fp::add(x, fp::neg(x), mode), (0, Flags::NONE));
        prop_assert_eq!(fp::sub(x, x, mode), (0, Flags::NONE));
    }

    #[test]
    fn cancellation_is_exact((a, b) in cancellation_pair()) {
        // Sterbenz: a + b with b ≈ −a is exact (a and −b within a factor 2 of each other).
        let (r, f) = fp::add(a, b, M);
        prop_assert!(!f.contains(Flags::INEXACT), "{:08X} + {:08X} = {:08X} {:?}", a, b, r, f);
        agrees(r, host(a) + host(b))?;
    }

    #[test]
    fn nan_results_are_canonical_and_invalid_rules((a, b) in f32_pair()) {
        for (r, f, extra) in [
            {
                let (r, f) = fp::add(a, b, M);
                (r, f, fp::is_inf(a) && fp::is_inf(b) && (a ^ b) & SIGN != 0)
            },
            {
                let (r, f) = fp::mul(a, b, M);
                let zi = |x: u32, y: u32| fp::is_zero(x) && fp::is_inf(y);
                (r, f, zi(a, b) || zi(b, a))
            },
            {
                let (r, f) = fp::div(a, b, M);
                let both = |p: fn(u32) -> bool| p(a) && p(b);
                (r, f, both(fp::is_zero) || both(fp::is_inf))
            },
        ] {
            if fp::is_nan(r) {
                prop_assert_eq!(r, CANONICAL_NAN);
            }
            invalid_iff_snan_or(a, b, f, extra)?;
        }
        let (r, f) = fp::sqrt(a, M);
        if fp::is_nan(r) {
            prop_assert_eq!(r, CANONICAL_NAN);
        }
        let negative = a & SIGN != 0 && !fp::is_zero(a) && !fp::is_nan(a);
        invalid_iff_snan_or(a, a, f, negative)?;
        // Divide-by-zero exactly for finite non-zero / zero.
        let dz = fp::div(a, b, M).1.contains(Flags::INFINITE);
        prop_assert_eq!(dz, fp::is_zero(b) && !fp::is_zero(a) && !fp::is_nan(a) && !fp::is_inf(a));
    }

    #[test]
    fn exact_square_roots(x in short_significand()) {
        let (sq, f) = fp::mul(x, x, M);
        prop_assume!(f.is_empty());
        prop_assert_eq!(fp::sqrt(sq, M), (fp::abs(x), Flags::NONE));
    }

    #[test]
    fn exact_quotients(a in short_significand(), b in short_significand()) {
        prop_assume!(!fp::is_zero(b));
        let (p, f) = fp::mul(a, b, M);
        prop_assume!(f.is_empty());
        prop_assert_eq!(fp::div(p, b, M), (a, Flags::NONE));
    }

    #[test]
    fn compares_follow_the_value_order((a, b) in f32_pair(), ftz in any::<bool>()) {
        let mode = FpMode { flush_to_zero: ftz };
        let (lt, flt) = fp::lt(a, b, mode);
        let (le, fle) = fp::le(a, b, mode);
        let (eq, feq) = fp::eq(a, b, mode);
        let unordered = fp::is_nan(a) || fp::is_nan(b);
        prop_assert_eq!(flt.contains(Flags::INVALID), unordered);
        prop_assert_eq!(fle.contains(Flags::INVALID), unordered);
        prop_assert_eq!(feq.contains(Flags::INVALID), fp::is_snan(a) || fp::is_snan(b));
        prop_assert!((flt | fle | feq).bits() & !Flags::INVALID.bits() == 0);
        if !ftz {
            prop_assert_eq!(lt, host(a) < host(b));
            prop_assert_eq!(le, host(a) <= host(b));
            prop_assert_eq!(eq, host(a) == host(b));
        }
        if !unordered {
            prop_assert_eq!(lt, !fp::le(b, a, mode).0);
            prop_assert_eq!(eq, le && fp::le(b, a, mode).0);
        } else {
            prop_assert!(!lt && !le && !eq);
        }
    }

    #[test]
    fn min_max_pick_an_operand((a, b) in f32_pair()) {
        let (mn, f1) = fp::min(a, b, M);
        let (mx, f2) = fp::max(a, b, M);
        prop_assert_eq!(f1, f2);
        invalid_iff_snan_or(a, b, f1, false)?;
        match (fp::is_nan(a), fp::is_nan(b)) {
            (true, true) => prop_assert!(mn == CANONICAL_NAN && mx == CANONICAL_NAN),
            (true, false) => prop_assert!(mn == b && mx == b),
            (false, true) => prop_assert!(mn == a && mx == a),
            (false, false) => {
                prop_assert!((mn == a && mx == b) || (mn == b && mx == a));
                prop_assert!(fp::le(mn, mx, M).0);
                if fp::is_zero(a) && fp::is_zero(b) && a != b {
                    prop_assert_eq!((mn, mx), (SIGN, 0)); // -0 < +0
                }
            }
        }
    }

    #[test]
    fn sign_ops_touch_only_the_sign(x in any::<u32>()) {
        prop_assert_eq!(fp::abs(x), x & !SIGN);
        prop_assert_eq!(fp::neg(fp::neg(x)), x);
        prop_assert_eq!(fp::neg(x) ^ x, SIGN);
        prop_assert_eq!(fp::abs(fp::neg(x)), fp::abs(x));
    }

    #[test]
    fn int_round_trip(x in i32_bits()) {
        let (f, fl) = fp::from_i32(x);
        agrees(f, x as i32 as f32)?;
        prop_assert_eq!(fl.is_empty(), (x as i32 as f32) as i64 == x as i32 as i64);
        if fl.is_empty() {
            prop_assert_eq!(fp::to_i32(f, M), (x, Flags::NONE));
            prop_assert_eq!(fp::to_i32_rtz(f, M), (x, Flags::NONE));
        }
    }

    #[test]
    fn float_to_int_matches_host_in_range(a in any_f32()) {
        let v = host(a);
        let in_range = (-2147483648.0..2147483648.0).contains(&v);
        let (t, ft) = fp::to_i32_rtz(a, M);
        let (n, fne) = fp::to_i32(a, M);
        if in_range {
            prop_assert_eq!(t, v as i32 as u32);
            prop_assert_eq!(ft.contains(Flags::INEXACT), v.trunc() != v);
            prop_assert_eq!(n, v.round_ties_even() as i32 as u32);
            prop_assert_eq!(fne, Flags::when(v.round_ties_even() != v, Flags::INEXACT));
        } else {
            prop_assert_eq!(ft, Flags::INVALID);
            prop_assert_eq!(fne, Flags::INVALID);
            let expect = if a & SIGN != 0 && !v.is_nan() { 0x8000_0000 } else { 0x7FFF_FFFF };
            prop_assert_eq!((t, n), (expect, expect));
        }
    }

    #[test]
    fn ftz_outputs_never_subnormal((a, b) in f32_pair()) {
        let ftz = FpMode::FTZ;
        for (r, f) in [
            fp::add(a, b, ftz),
            fp::sub(a, b, ftz),
            fp::mul(a, b, ftz),
            fp::div(a, b, ftz),
            fp::sqrt(a, ftz),
            fp::min(a, b, ftz),
            fp::max(a, b, ftz),
        ] {
            prop_assert!(!fp::is_subnormal(r), "{:08X} {:08X} -> {:08X} {:?}", a, b, r, f);
        }
    }

    #[test]
    fn ftz_agrees_with_ieee_away_from_subnormals((a, b) in f32_pair()) {
        prop_assume!(!fp::is_subnormal(a) && !fp::is_subnormal(b));
        for op in [fp::add, fp::sub, fp::mul, fp::div] {
            let ieee = op(a, b, M);
            let ftz = op(a, b, FpMode::FTZ);
            if fp::is_subnormal(ieee.0) || (fp::is_zero(ieee.0) && ieee.1.contains(Flags::UNDERFLOW)) {
                prop_assert_eq!(ftz, (ieee.0 & SIGN, Flags::UNDERFLOW | Flags::INEXACT));
            } else {
                prop_assert_eq!(ftz, ieee);
            }
        }
    }

    #[test]
    fn ftz_treats_subnormal_inputs_as_zero(x in subnormal(), y in any_f32()) {
        let z = x & SIGN;
        let ftz = FpMode::FTZ;
        prop_assert_eq!(fp::add(x, y, ftz), fp::add(z, y, ftz));
        prop_assert_eq!(fp::mul(y, x, ftz), fp::mul(y, z, ftz));
        prop_assert_eq!(fp::div(x, y, ftz), fp::div(z, y, ftz));
        prop_assert_eq!(fp::div(y, x, ftz), fp::div(y, z, ftz));
        prop_assert_eq!(fp::sqrt(x, ftz), (z, Flags::NONE));
        prop_assert_eq!(fp::lt(x, y, ftz), fp::lt(z, y, ftz));
        prop_assert_eq!(fp::to_i32(x, ftz), (0, Flags::NONE));
    }

    #[test]
    fn division_recurrence_invariants(x in 0x80_0000u32..0x100_0000, d in 0x80_0000u32..0x100_0000) {
        let x = if x < d { x << 1 } else { x };
        let mut r = DivRecurrence::new(x, d);
        for _ in 0..DIV_STEPS {
            prop_assert!(r.rem < d);
            r.step();
        }
        // quotient = floor(x·4^12 / d), remainder consistent with it.
        let q = ((x as u64) << 24) / d as u64;
        prop_assert_eq!(r.quotient as u64, q);
        prop_assert_eq!(r.rem as u64, ((x as u64) << 24) - q * d as u64);
    }

    #[test]
    fn sqrt_recurrence_invariants(int_part in 1u32..4, frac in any::<u32>()) {
        let frac64 = (frac as u64 & !0x1FF) << 32; // 23 fraction bits, as the datapath feeds
        let mut r = SqrtRecurrence::new(int_part, frac64);
        for _ in 0..SQRT_STEPS {
            prop_assert!(r.rem <= 2 * r.root);
            r.step();
        }
        // root = floor(sqrt(X·2^48)), rem = X·2^48 − root².
        let n = ((int_part as u128) << 48) | ((frac64 as u128) >> 16);
        let root = r.root as u128;
        prop_assert!(root * root <= n && (root + 1) * (root + 1) > n);
        prop_assert_eq!(r.rem as u128, n - root * root);
    }
}
