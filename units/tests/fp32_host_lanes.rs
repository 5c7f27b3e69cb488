//! The host floating-point fast path (`Op::eval_lanes_host`, `arith::fp32::host`) against the
//! bit-level datapath (`Op::eval_lanes`, the model of record): result word and all five flags
//! on every lane, for every op, in both modes, on lane counts 1, 3, 8, 16, 32 and 37 (a
//! lone lane, leftover lanes only, whole groups of eight, and groups plus leftovers). Also
//! the committed SoftFloat vectors (`tests/vectors/`) through the host path. The live
//! SoftFloat cross-check of the host path is in `fp32_softfloat.rs` (feature `softfloat`).

use imagine_units::arith::fp32::strategies::{f32_pair, finite, normal};
use imagine_units::arith::fp32::testfloat::{self, parse_case};
use imagine_units::arith::fp32::testgen::{SplitMix64, biased_pair};
use imagine_units::arith::fp32::{Flags, FpMode};
use imagine_units::ops::Op;
use proptest::prelude::*;
use proptest::sample::select;
use std::path::Path;

/// The lane counts checked: a cluster, leftover lanes only, one and several whole groups of
/// eight (the fast path's vectors), and groups followed by leftovers.
const LANE_COUNTS: [usize; 6] = [1, 3, 8, 16, 32, 37];

/// The ops with a host fast path, by TestFloat name.
const HOST_OPS: [(testfloat::Op, Op); 3] = [
    (testfloat::Op::Add, Op::FAdd),
    (testfloat::Op::Sub, Op::FSub),
    (testfloat::Op::Mul, Op::FMul),
];

/// An entry point: [`Op::eval_lanes_host`] or [`Op::eval_lanes`].
type EntryPoint = fn(Op, &[u32], &[u32], &[u32], FpMode, &mut [u32], &mut [Flags]);

/// `op` on the lanes `(a, b, c)` by `eval` (one of the two entry points): words and flags.
fn run(eval: EntryPoint, op: Op, [a, b, c]: [&[u32]; 3], mode: FpMode) -> (Vec<u32>, Vec<Flags>) {
    let (mut out, mut flags) = (vec![0; a.len()], vec![Flags::NONE; a.len()]);
    eval(op, a, b, c, mode, &mut out, &mut flags);
    (out, flags)
}

/// Each of `ops` agrees between the two entry points on the lanes `(a, b, c)`; the first
/// differing lane is named.
fn entry_points_agree(
    ops: impl IntoIterator<Item = Op>,
    [a, b, c]: [&[u32]; 3],
    mode: FpMode,
) -> Result<(), String> {
    for op in ops {
        let host = run(Op::eval_lanes_host, op, [a, b, c], mode);
        let bit_level = run(Op::eval_lanes, op, [a, b, c], mode);
        if host != bit_level {
            let i = (0..a.len())
                .find(|&i| (host.0[i], host.1[i]) != (bit_level.0[i], bit_level.1[i]))
                .expect("a differing lane");
            return Err(format!(
                "{op} {mode:?}, lane {i} of {}: ({:08X}, {:08X}) host {:08X} {}, \
                 bit-level {:08X} {}",
                a.len(),
                a[i],
                b[i],
                host.0[i],
                host.1[i],
                bit_level.0[i],
                bit_level.1[i],
            ));
        }
    }
    Ok(())
}

/// Lane operands for a property: each lane an independent draw of `pair`, the lane count one
/// of [`LANE_COUNTS`].
fn lanes(pair: BoxedStrategy<(u32, u32)>) -> impl Strategy<Value = (Vec<u32>, Vec<u32>)> {
    select(&LANE_COUNTS[..])
        .prop_flat_map(move |n| proptest::collection::vec(pair.clone(), n))
        .prop_map(|pairs| pairs.into_iter().unzip())
}

proptest! {
    // Each case is a vector of up to 37 lanes (about 16 on average).
    #![proptest_config(ProptestConfig::with_cases(1024))]

    /// Every op, biased pairs: most groups hold a lane the host leaves to the bit-level
    /// datapath.
    #[test]
    fn host_matches_bit_level_on_biased_lanes((a, b) in lanes(f32_pair()), ftz: bool) {
        let mode = FpMode { flush_to_zero: ftz };
        entry_points_agree(Op::ALL.iter().copied(), [&a, &b, &a], mode)
            .map_err(TestCaseError::fail)?;
    }

    /// Every op, normal and finite pairs: most groups go through the host's vectors whole.
    #[test]
    fn host_matches_bit_level_on_finite_lanes(
        (a, b) in lanes(prop_oneof![(normal(), normal()), (finite(), finite())].boxed()),
        ftz: bool,
    ) {
        let mode = FpMode { flush_to_zero: ftz };
        entry_points_agree(Op::ALL.iter().copied(), [&a, &b, &b], mode)
            .map_err(TestCaseError::fail)?;
    }
}

/// A normal operand with a random sign and an exponent where sums and products stay normal
/// (`[2^-27, 2^28)`), the common case of the machine's kernels.
fn common(rng: &mut SplitMix64) -> u32 {
    (rng.next_u32() & 0x807F_FFFF) | ((100 + rng.below(55)) << 23)
}

/// Many random lanes (over a million per op and entry point) in vectors of every checked lane
/// count, drawn from `testgen`'s biased pairs (hard cases), uniform bit patterns, the common
/// case, and the common case with one lane in eight a biased pair (groups that need one
/// fallback).
#[test]
fn host_matches_bit_level_on_many_random_lanes() {
    const VECTORS_PER_SOURCE: usize = 20_000;
    let mut rng = SplitMix64::new(0x4057_1A4E);
    let mut lanes_checked = 0;
    for source in 0..4 {
        for (round, mode) in [FpMode::IEEE, FpMode::FTZ]
            .into_iter()
            .cycle()
            .take(VECTORS_PER_SOURCE)
            .enumerate()
        {
            let n = LANE_COUNTS[round % LANE_COUNTS.len()];
            let (a, b): (Vec<u32>, Vec<u32>) = (0..n)
                .map(|lane| match source {
                    0 => biased_pair(&mut rng),
                    1 => (rng.next_u32(), rng.next_u32()),
                    2 => (common(&mut rng), common(&mut rng)),
                    _ if lane % 8 == round % 8 => biased_pair(&mut rng),
                    _ => (common(&mut rng), common(&mut rng)),
                })
                .unzip();
            let host_ops = HOST_OPS.map(|(_, op)| op);
            if let Err(e) = entry_points_agree(host_ops, [&a, &b, &a], mode) {
                panic!("source {source}: {e}");
            }
            lanes_checked += n;
        }
    }
    assert!(lanes_checked > 1_000_000, "{lanes_checked} lanes");
}

/// The committed SoftFloat vectors of the ops with a host path, through `eval_lanes_host` in
/// vectors of every checked lane count, in IEEE and (for `ftz_*.txt`) flush-to-zero mode.
#[test]
fn committed_softfloat_vectors_pass_on_the_host_path() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/vectors");
    for (tf_op, op) in HOST_OPS {
        for (prefix, mode) in [("", FpMode::IEEE), ("ftz_", FpMode::FTZ)] {
            let path = dir.join(format!("{prefix}{}.txt", tf_op.name()));
            let text = std::fs::read_to_string(&path)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let cases: Vec<_> = text
                .lines()
                .filter(|line| !line.trim().is_empty())
                .map(|line| parse_case(tf_op, line).expect("a well-formed vector"))
                .collect();
            assert!(
                cases.len() >= 500,
                "{}: {} vectors",
                path.display(),
                cases.len()
            );
            let mut start = 0;
            for n in LANE_COUNTS.into_iter().cycle() {
                if start == cases.len() {
                    break;
                }
                let batch = &cases[start..(start + n).min(cases.len())];
                let a: Vec<u32> = batch.iter().map(|c| c.a).collect();
                let b: Vec<u32> = batch.iter().map(|c| c.b).collect();
                let (out, flags) = run(Op::eval_lanes_host, op, [&a, &b, &a], mode);
                for (i, case) in batch.iter().enumerate() {
                    assert_eq!(
                        (out[i], flags[i]),
                        (case.result, case.flags),
                        "{}: vector {} ({:08X}, {:08X})",
                        path.display(),
                        start + i + 1,
                        case.a,
                        case.b
                    );
                }
                start += batch.len();
            }
        }
    }
}
