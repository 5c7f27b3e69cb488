//! 32-bit integer datapath ops against a straightforward host-arithmetic reference
//! (i64/u64/i128 arithmetic, explicit reductions), plus hand-checked examples.

use imagine_units::arith::int::*;
use proptest::prelude::*;

/// Words biased toward the edges of the signed and unsigned ranges and small shift amounts.
fn word() -> impl Strategy<Value = u32> {
    prop_oneof![
        3 => prop::sample::select(vec![
            0u32,
            1,
            2,
            31,
            32,
            33,
            0x7FFF_FFFF,
            0x8000_0000,
            0x8000_0001,
            0xFFFF_FFFF,
            0xFFFF_FFFE,
            0x0000_FFFF,
            0x0001_0000,
            0x0000_8000,
            0xFFFF_8000,
        ]),
        1 => (-40i32..40).prop_map(|v| v as u32),
        4 => any::<u32>(),
    ]
}

fn s(x: u32) -> i64 {
    x as i32 as i64
}

fn u(x: u32) -> i64 {
    x as i64
}

/// Reduce a host integer modulo 2^32.
fn wrap(x: i128) -> u32 {
    x.rem_euclid(1 << 32) as u32
}

fn config() -> ProptestConfig {
    ProptestConfig::with_cases(4096)
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn add_sub_neg_match_reference(a in word(), b in word()) {
        prop_assert_eq!(add(a, b), wrap(u(a) as i128 + u(b) as i128));
        prop_assert_eq!(sub(a, b), wrap(u(a) as i128 - u(b) as i128));
        prop_assert_eq!(neg(a), wrap(-(u(a) as i128)));
        // Signed reading gives the same bits.
        prop_assert_eq!(add(a, b), wrap(s(a) as i128 + s(b) as i128));
        prop_assert_eq!(sub(a, b), wrap(s(a) as i128 - s(b) as i128));
    }

    #[test]
    fn logic_matches_reference(a in word(), b in word()) {
        for bit in 0..32 {
            let x = (a >> bit) & 1 == 1;
            let y = (b >> bit) & 1 == 1;
            prop_assert_eq!((and(a, b) >> bit) & 1 == 1, x && y);
            prop_assert_eq!((or(a, b) >> bit) & 1 == 1, x || y);
            prop_assert_eq!((xor(a, b) >> bit) & 1 == 1, x != y);
            prop_assert_eq!((not(a) >> bit) & 1 == 1, !x);
        }
    }

    #[test]
    fn shifts_match_reference(a in word(), b in word()) {
        let n = b % 32;
        // Left shift: multiply by 2^n and keep 32 bits.
        prop_assert_eq!(shift_left(a, b), wrap(u(a) as i128 * (1i128 << n)));
        // Logical right: unsigned floor division by 2^n.
        prop_assert_eq!(shift_right_logical(a, b), (u(a) / (1i64 << n)) as u32);
        // Arithmetic right: signed floor division by 2^n.
        prop_assert_eq!(shift_right_arith(a, b), wrap(s(a).div_euclid(1i64 << n) as i128));
    }

    #[test]
    fn compares_match_reference(a in word(), b in word()) {
        prop_assert_eq!(eq(a, b), u(a) == u(b));
        prop_assert_eq!(ne(a, b), u(a) != u(b));
        prop_assert_eq!(lt_s(a, b), s(a) < s(b));
        prop_assert_eq!(le_s(a, b), s(a) <= s(b));
        prop_assert_eq!(lt_u(a, b), u(a) < u(b));
        prop_assert_eq!(le_u(a, b), u(a) <= u(b));
        // Compares against themselves.
        prop_assert!(eq(a, a) && !ne(a, a) && !lt_s(a, a) && le_s(a, a) && !lt_u(a, a) && le_u(a, a));
    }

    #[test]
    fn select_min_max_abs_match_reference(a in word(), b in word(), c in any::<bool>()) {
        prop_assert_eq!(select(c, a, b), if c { a } else { b });
        prop_assert_eq!(s(min_s(a, b)), s(a).min(s(b)));
        prop_assert_eq!(s(max_s(a, b)), s(a).max(s(b)));
        prop_assert_eq!(u(min_u(a, b)), u(a).min(u(b)));
        prop_assert_eq!(u(max_u(a, b)), u(a).max(u(b)));
        prop_assert_eq!(abs_s(a), wrap(s(a).abs() as i128));
    }

    #[test]
    fn multiplies_match_reference(a in word(), b in word()) {
        let pu = u(a) as i128 * u(b) as i128;
        let ps = s(a) as i128 * s(b) as i128;
        let psu = s(a) as i128 * u(b) as i128;
        prop_assert_eq!(mul_lo(a, b), wrap(pu));
        prop_assert_eq!(mul_lo(a, b), wrap(ps));
        prop_assert_eq!(mul_hi_u(a, b), wrap(pu.div_euclid(1 << 32)));
        prop_assert_eq!(mul_hi_s(a, b), wrap(ps.div_euclid(1 << 32)));
        prop_assert_eq!(mul_hi_su(a, b), wrap(psu.div_euclid(1 << 32)));
    }
}

#[test]
fn add_sub_examples() {
    assert_eq!(add(0xFFFF_FFFF, 1), 0);
    assert_eq!(add(0x7FFF_FFFF, 1), 0x8000_0000);
    assert_eq!(add(2, 3), 5);
    assert_eq!(sub(0, 1), 0xFFFF_FFFF);
    assert_eq!(sub(0x8000_0000, 1), 0x7FFF_FFFF);
    assert_eq!(sub(10, 3), 7);
    assert_eq!(neg(1), 0xFFFF_FFFF);
    assert_eq!(neg(0x8000_0000), 0x8000_0000);
    assert_eq!(neg(0), 0);
}

#[test]
fn logic_examples() {
    assert_eq!(and(0xF0F0_1234, 0xFF00_FF00), 0xF000_1200);
    assert_eq!(or(0xF0F0_0000, 0x0F00_00FF), 0xFFF0_00FF);
    assert_eq!(xor(0xFFFF_0000, 0x0FF0_0FF0), 0xF00F_0FF0);
    assert_eq!(not(0x1234_5678), 0xEDCB_A987);
}

#[test]
fn shift_examples() {
    assert_eq!(shift_left(1, 31), 0x8000_0000);
    assert_eq!(
        shift_left(1, 32),
        1,
        "only the low 5 bits of the amount count"
    );
    assert_eq!(shift_left(0x8000_0001, 1), 2);
    assert_eq!(shift_right_logical(0x8000_0000, 31), 1);
    assert_eq!(shift_right_logical(0x8000_0000, 33), 0x4000_0000);
    assert_eq!(shift_right_arith(0x8000_0000, 31), 0xFFFF_FFFF);
    assert_eq!(shift_right_arith(0x8000_0000, 4), 0xF800_0000);
    assert_eq!(shift_right_arith(0x7000_0000, 4), 0x0700_0000);
    assert_eq!(shift_right_arith(0xFFFF_FFF0, 0xFFFF_FFE2), 0xFFFF_FFFC);
}

#[test]
fn compare_and_select_examples() {
    let m1 = 0xFFFF_FFFF;
    assert!(lt_s(m1, 0));
    assert!(!lt_u(m1, 0));
    assert!(lt_s(0x8000_0000, 0x7FFF_FFFF));
    assert!(!lt_u(0x8000_0000, 0x7FFF_FFFF));
    assert!(le_s(5, 5) && le_u(5, 5) && !lt_s(5, 5) && !lt_u(5, 5));
    assert!(eq(7, 7) && !eq(7, 8) && ne(7, 8) && !ne(7, 7));
    assert_eq!(select(true, 1, 2), 1);
    assert_eq!(select(false, 1, 2), 2);
}

#[test]
fn min_max_abs_examples() {
    assert_eq!(min_s(0xFFFF_FFFF, 1), 0xFFFF_FFFF);
    assert_eq!(min_u(0xFFFF_FFFF, 1), 1);
    assert_eq!(max_s(0x8000_0000, 0x7FFF_FFFF), 0x7FFF_FFFF);
    assert_eq!(max_u(0x8000_0000, 0x7FFF_FFFF), 0x8000_0000);
    assert_eq!(abs_s(0xFFFF_FFFB), 5);
    assert_eq!(abs_s(5), 5);
    assert_eq!(abs_s(0x8000_0000), 0x8000_0000);
}

#[test]
fn multiply_examples() {
    // (-1) * (-1) = 1: low 1, signed high 0; unsigned (2^32-1)^2 = 2^64 - 2^33 + 1.
    assert_eq!(mul_lo(0xFFFF_FFFF, 0xFFFF_FFFF), 1);
    assert_eq!(mul_hi_s(0xFFFF_FFFF, 0xFFFF_FFFF), 0);
    assert_eq!(mul_hi_u(0xFFFF_FFFF, 0xFFFF_FFFF), 0xFFFF_FFFE);
    // (-1) * (2^32 - 1) read signed×unsigned = -(2^32 - 1): high word 0xFFFF_FFFF.
    assert_eq!(mul_hi_su(0xFFFF_FFFF, 0xFFFF_FFFF), 0xFFFF_FFFF);
    // i32::MIN * i32::MIN = 2^62.
    assert_eq!(mul_hi_s(0x8000_0000, 0x8000_0000), 0x4000_0000);
    assert_eq!(mul_lo(0x8000_0000, 0x8000_0000), 0);
    // i32::MIN * i32::MAX = -2^62 + 2^31.
    assert_eq!(mul_hi_s(0x8000_0000, 0x7FFF_FFFF), 0xC000_0000);
    assert_eq!(mul_lo(0x8000_0000, 0x7FFF_FFFF), 0x8000_0000);
    assert_eq!(mul_hi_u(0x1_0000, 0x1_0000), 1);
    assert_eq!(mul_lo(0x1_0000, 0x1_0000), 0);
    assert_eq!(mul_lo(12345, 6789), 83_810_205);
}
