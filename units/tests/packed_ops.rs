//! Packed-subword ops against a lane-by-lane host-arithmetic reference (extract each lane,
//! compute in i64, clamp or wrap explicitly, repack), plus hand-checked examples.

use imagine_units::arith::packed::*;
use proptest::prelude::*;

fn lane16() -> impl Strategy<Value = u32> {
    prop_oneof![
        1 => prop::sample::select(vec![
            0u32, 1, 2, 0x7FFE, 0x7FFF, 0x8000, 0x8001, 0xFFFE, 0xFFFF, 0x00FF, 0x0100,
        ]),
        1 => any::<u16>().prop_map(u32::from),
    ]
}

fn lane8() -> impl Strategy<Value = u32> {
    prop_oneof![
        1 => prop::sample::select(vec![0u32, 1, 2, 0x7E, 0x7F, 0x80, 0x81, 0xFE, 0xFF]),
        1 => any::<u8>().prop_map(u32::from),
    ]
}

/// Words whose lanes (of either width) are biased toward the lane range boundaries.
fn word() -> impl Strategy<Value = u32> {
    prop_oneof![
        2 => (lane16(), lane16()).prop_map(|(l0, l1)| l0 | (l1 << 16)),
        2 => (lane8(), lane8(), lane8(), lane8())
            .prop_map(|(l0, l1, l2, l3)| l0 | (l1 << 8) | (l2 << 16) | (l3 << 24)),
        1 => any::<u32>(),
    ]
}

/// Read lane `i` of width `w` as unsigned or sign-extended.
fn lane(x: u32, w: u32, i: u32, signed: bool) -> i64 {
    let raw = ((x >> (i * w)) & ((1u32 << w) - 1)) as i64;
    if signed && raw >= 1 << (w - 1) {
        raw - (1 << w)
    } else {
        raw
    }
}

/// Apply `f` lane by lane and pack the results, each reduced modulo 2^w.
fn reference(a: u32, b: u32, w: u32, signed: bool, f: impl Fn(i64, i64) -> i64) -> u32 {
    let mut out = 0u32;
    for i in 0..32 / w {
        let r = f(lane(a, w, i, signed), lane(b, w, i, signed)).rem_euclid(1 << w) as u32;
        out |= r << (i * w);
    }
    out
}

fn smin(w: u32) -> i64 {
    -(1 << (w - 1))
}

fn smax(w: u32) -> i64 {
    (1 << (w - 1)) - 1
}

fn umax(w: u32) -> i64 {
    (1 << w) - 1
}

/// Condition as a lane mask value (-1 reduces to all ones).
fn mask(c: bool) -> i64 {
    if c { -1 } else { 0 }
}

fn config() -> ProptestConfig {
    ProptestConfig::with_cases(4096)
}

type Op = fn(u32, u32) -> u32;

/// Check the full family of adder-side ops for lane width `w` against the reference.
fn check_family(
    a: u32,
    b: u32,
    w: u32,
    [add, sub, add_sat_s, add_sat_u, sub_sat_s, sub_sat_u]: [Op; 6],
    [eq, lt_s, le_s, lt_u, le_u]: [Op; 5],
    [min_s, max_s, min_u, max_u]: [Op; 4],
) -> Result<(), TestCaseError> {
    let (lo, hi, top) = (smin(w), smax(w), umax(w));
    prop_assert_eq!(add(a, b), reference(a, b, w, false, |x, y| x + y), "add");
    prop_assert_eq!(
        add(a, b),
        reference(a, b, w, true, |x, y| x + y),
        "add signed"
    );
    prop_assert_eq!(sub(a, b), reference(a, b, w, false, |x, y| x - y), "sub");
    prop_assert_eq!(
        sub(a, b),
        reference(a, b, w, true, |x, y| x - y),
        "sub signed"
    );
    prop_assert_eq!(
        add_sat_s(a, b),
        reference(a, b, w, true, |x, y| (x + y).clamp(lo, hi)),
        "add_sat_s"
    );
    prop_assert_eq!(
        add_sat_u(a, b),
        reference(a, b, w, false, |x, y| (x + y).clamp(0, top)),
        "add_sat_u"
    );
    prop_assert_eq!(
        sub_sat_s(a, b),
        reference(a, b, w, true, |x, y| (x - y).clamp(lo, hi)),
        "sub_sat_s"
    );
    prop_assert_eq!(
        sub_sat_u(a, b),
        reference(a, b, w, false, |x, y| (x - y).clamp(0, top)),
        "sub_sat_u"
    );
    prop_assert_eq!(
        eq(a, b),
        reference(a, b, w, false, |x, y| mask(x == y)),
        "eq"
    );
    prop_assert_eq!(
        lt_s(a, b),
        reference(a, b, w, true, |x, y| mask(x < y)),
        "lt_s"
    );
    prop_assert_eq!(
        le_s(a, b),
        reference(a, b, w, true, |x, y| mask(x <= y)),
        "le_s"
    );
    prop_assert_eq!(
        lt_u(a, b),
        reference(a, b, w, false, |x, y| mask(x < y)),
        "lt_u"
    );
    prop_assert_eq!(
        le_u(a, b),
        reference(a, b, w, false, |x, y| mask(x <= y)),
        "le_u"
    );
    prop_assert_eq!(min_s(a, b), reference(a, b, w, true, i64::min), "min_s");
    prop_assert_eq!(max_s(a, b), reference(a, b, w, true, i64::max), "max_s");
    prop_assert_eq!(min_u(a, b), reference(a, b, w, false, i64::min), "min_u");
    prop_assert_eq!(max_u(a, b), reference(a, b, w, false, i64::max), "max_u");
    Ok(())
}

fn check_16x2(a: u32, b: u32) -> Result<(), TestCaseError> {
    check_family(
        a,
        b,
        16,
        [
            add_16x2,
            sub_16x2,
            add_sat_s_16x2,
            add_sat_u_16x2,
            sub_sat_s_16x2,
            sub_sat_u_16x2,
        ],
        [eq_16x2, lt_s_16x2, le_s_16x2, lt_u_16x2, le_u_16x2],
        [min_s_16x2, max_s_16x2, min_u_16x2, max_u_16x2],
    )
}

fn check_8x4(a: u32, b: u32) -> Result<(), TestCaseError> {
    check_family(
        a,
        b,
        8,
        [
            add_8x4,
            sub_8x4,
            add_sat_s_8x4,
            add_sat_u_8x4,
            sub_sat_s_8x4,
            sub_sat_u_8x4,
        ],
        [eq_8x4, lt_s_8x4, le_s_8x4, lt_u_8x4, le_u_8x4],
        [min_s_8x4, max_s_8x4, min_u_8x4, max_u_8x4],
    )
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn ops_16x2_match_reference(a in word(), b in word()) {
        check_16x2(a, b)?;
    }

    #[test]
    fn ops_8x4_match_reference(a in word(), b in word()) {
        check_8x4(a, b)?;
    }

    #[test]
    fn ops_match_reference_with_equal_operands(a in word()) {
        // Equal lanes exercise eq/le and the no-overflow paths of saturation.
        check_16x2(a, a)?;
        check_8x4(a, a)?;
    }

    #[test]
    fn mul_16x2_matches_reference(a in word(), b in word()) {
        prop_assert_eq!(mul_lo_16x2(a, b), reference(a, b, 16, false, |x, y| x * y));
        prop_assert_eq!(mul_lo_16x2(a, b), reference(a, b, 16, true, |x, y| x * y));
        prop_assert_eq!(
            mul_hi_s_16x2(a, b),
            reference(a, b, 16, true, |x, y| (x * y).div_euclid(1 << 16))
        );
        prop_assert_eq!(
            mul_hi_u_16x2(a, b),
            reference(a, b, 16, false, |x, y| (x * y).div_euclid(1 << 16))
        );
    }
}

/// Every op checked against the reference on all pairs of boundary words.
#[test]
fn boundary_words_exhaustive() {
    let lanes16 = [0u32, 1, 0x7FFF, 0x8000, 0x8001, 0xFFFF];
    let lanes8 = [0u32, 1, 0x7F, 0x80, 0x81, 0xFF];
    let mut words = Vec::new();
    for &h in &lanes16 {
        for &l in &lanes16 {
            words.push(l | (h << 16));
        }
    }
    for &x in &lanes8 {
        for &y in &lanes8 {
            words.push(x | (y << 8) | (x << 16) | (y << 24));
            words.push(y | (x << 8) | (y << 16) | (y << 24));
        }
    }
    for &a in &words {
        for &b in &words {
            check_16x2(a, b).unwrap();
            check_8x4(a, b).unwrap();
        }
    }
}

#[test]
fn add_sub_examples() {
    // Lane 0 wraps without carrying into lane 1.
    assert_eq!(add_16x2(0x0001_FFFF, 0x0001_0001), 0x0002_0000);
    assert_eq!(add_8x4(0x01FF_FF7F, 0x0101_0101), 0x0200_0080);
    // Lane 0 borrows without borrowing from lane 1.
    assert_eq!(sub_16x2(0x0005_0000, 0x0001_0001), 0x0004_FFFF);
    assert_eq!(sub_8x4(0x0300_8000, 0x0101_0101), 0x02FF_7FFF);
}

#[test]
fn saturating_examples() {
    // Signed 16: 0x7FFF + 1 clamps to 0x7FFF; -0x8000 + -1 clamps to 0x8000.
    assert_eq!(add_sat_s_16x2(0x8000_7FFF, 0xFFFF_0001), 0x8000_7FFF);
    assert_eq!(sub_sat_s_16x2(0x7FFF_8000, 0xFFFF_0001), 0x7FFF_8000);
    assert_eq!(add_sat_s_16x2(0x0003_FFFE, 0x0004_0001), 0x0007_FFFF);
    // Unsigned 16: 0xFFFF + 1 clamps to 0xFFFF; 0 - 1 clamps to 0.
    assert_eq!(add_sat_u_16x2(0x0001_FFFF, 0x0001_0001), 0x0002_FFFF);
    assert_eq!(sub_sat_u_16x2(0x0005_0000, 0x0001_0001), 0x0004_0000);
    // Signed 8, lanes (lane 3..0): [0x7F+0x01, 0x80+0xFF, 0x10+0x20, 0xC0+0xC0].
    assert_eq!(add_sat_s_8x4(0x7F80_10C0, 0x01FF_20C0), 0x7F80_3080);
    assert_eq!(sub_sat_s_8x4(0x7F80_1000, 0xFF01_2001), 0x7F80_F0FF);
    // Unsigned 8.
    assert_eq!(add_sat_u_8x4(0xFF80_1001, 0x0180_20FE), 0xFFFF_30FF);
    assert_eq!(sub_sat_u_8x4(0x0080_1020, 0x0181_0120), 0x0000_0F00);
}

#[test]
fn compare_min_max_examples() {
    assert_eq!(eq_16x2(0x1234_5678, 0x1234_5679), 0xFFFF_0000);
    assert_eq!(eq_8x4(0x0012_8000, 0x0013_8001), 0xFF00_FF00);
    // Lane 1: -1 < 1 signed but not unsigned; lane 0: 1 < 0x8000 unsigned but not signed.
    assert_eq!(lt_s_16x2(0xFFFF_0001, 0x0001_8000), 0xFFFF_0000);
    assert_eq!(lt_u_16x2(0xFFFF_0001, 0x0001_8000), 0x0000_FFFF);
    assert_eq!(le_s_8x4(0x8005_0107, 0x7F05_0006), 0xFFFF_0000);
    assert_eq!(le_u_8x4(0x8005_0107, 0x7F05_0006), 0x00FF_0000);
    assert_eq!(min_s_16x2(0xFFFF_0001, 0x0001_8000), 0xFFFF_8000);
    assert_eq!(max_s_16x2(0xFFFF_0001, 0x0001_8000), 0x0001_0001);
    assert_eq!(min_u_8x4(0xFF01_7F80, 0x0102_807F), 0x0101_7F7F);
    assert_eq!(max_u_8x4(0xFF01_7F80, 0x0102_807F), 0xFF02_8080);
}

#[test]
fn multiply_examples() {
    // Lane 1: 0x100 * 0x100 = 0x1_0000 (low 0, high 1); lane 0: 3 * 5 = 15.
    assert_eq!(mul_lo_16x2(0x0100_0003, 0x0100_0005), 0x0000_000F);
    assert_eq!(mul_hi_u_16x2(0x0100_0003, 0x0100_0005), 0x0001_0000);
    // Lane 1: -1 * -1 = 1; lane 0: -0x8000 * -0x8000 = 0x4000_0000.
    assert_eq!(mul_lo_16x2(0xFFFF_8000, 0xFFFF_8000), 0x0001_0000);
    assert_eq!(mul_hi_s_16x2(0xFFFF_8000, 0xFFFF_8000), 0x0000_4000);
    assert_eq!(mul_hi_u_16x2(0xFFFF_8000, 0xFFFF_8000), 0xFFFE_4000);
    // Lane 0: -2 * 3 = -6: high half all ones when signed.
    assert_eq!(mul_hi_s_16x2(0x0000_FFFE, 0x0000_0003), 0x0000_FFFF);
    assert_eq!(mul_hi_u_16x2(0x0000_FFFE, 0x0000_0003), 0x0000_0002);
}
