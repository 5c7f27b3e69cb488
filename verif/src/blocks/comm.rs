//! Testbench of the intercluster communication unit (`units::comm`): one send per cycle
//! through the permutation network — rotations, butterflies, broadcasts and per-cluster
//! sources — and the conditional-stream reservation of the network.
//!
//! Reference: receiving cluster `c` gets, `comm` cycles after the send, the word of cluster
//! `(c + k) mod C` (rotate), `(c xor k) mod C` (butterfly), `k mod C` (broadcast) or its
//! own register's value mod C (per cluster). A second send, or a send in a cycle whose
//! network a conditional stream reserved, is refused.

use std::collections::VecDeque;

use imagine_units::comm::CommUnit;
use imagine_units::desc::MachineDesc;
use imagine_units::microcode::Permutation;

use super::{BlockClock, Config, Coverage, Outcome, Rng, Scoreboard, Waves, design};

const BINS: &[&str] = &[
    "rotate",
    "butterfly",
    "broadcast",
    "per-cluster sources",
    "identity pattern",
    "pattern index past the cluster count",
    "broadcast from the last cluster",
    "back-to-back sends",
    "conditional-stream reservation",
    "second send refused",
];

/// The cluster each receiving cluster reads from.
fn sources(perm: Permutation, regs: &[u32], clusters: usize) -> Vec<usize> {
    let n = clusters;
    (0..n)
        .map(|c| match perm {
            Permutation::Rotate(k) => (c + k as usize) % n,
            Permutation::Xor(k) => (c ^ k as usize) % n,
            Permutation::Broadcast(k) => k as usize % n,
            Permutation::PerCluster(_) => regs[c] as usize % n,
        })
        .collect()
}

pub fn run(desc: &MachineDesc, config: &Config) -> Outcome {
    let lanes = desc.cluster.count;
    let latency = desc.latency.comm;
    let mut rng = Rng::new(config.seed);
    let mut sb = Scoreboard::default();
    let mut cov = Coverage::new(BINS);
    let mut d = design();
    let mut comm = CommUnit::new(&mut d.scope(), "comm0", lanes, latency);
    let mut arriving: VecDeque<(u64, (u16, Vec<u32>))> = VecDeque::new();
    let mut tag = 0u16;
    let mut last_send = None;
    let mut waves = Waves::new(d.probes(), desc, BlockClock::Core, config);
    let mut cycle = 0u64;
    while sb.transactions < config.transactions || !arriving.is_empty() {
        let drive = sb.transactions < config.transactions;
        let mut used = false;
        if drive && rng.chance(85) {
            sb.transaction();
            used = true;
            if rng.chance(8) {
                let ok = comm.reserve().is_ok();
                sb.check(
                    cycle,
                    || "conditional-stream reservation accepted".into(),
                    true,
                    ok,
                );
                cov.hit("conditional-stream reservation");
            } else {
                // Pattern indices range past the cluster count, to check the wrap.
                let k = rng.below(2 * lanes as u64 + 1) as u16;
                let perm = match rng.below(4) {
                    0 => Permutation::Rotate(k),
                    1 => Permutation::Xor(k),
                    2 => Permutation::Broadcast(if rng.chance(30) { lanes as u16 - 1 } else { k }),
                    _ => Permutation::PerCluster(0),
                };
                let regs: Vec<u32> = (0..lanes)
                    .map(|_| rng.below(3 * lanes as u64) as u32)
                    .collect();
                let data = rng.lane_words(lanes);
                tag = tag.wrapping_add(1);
                let regs_in = matches!(perm, Permutation::PerCluster(_)).then_some(&regs[..]);
                let ok = comm.send(&data, perm, regs_in, tag).is_ok();
                sb.check(cycle, || format!("send {perm:?} accepted"), true, ok);
                let from = sources(perm, &regs, lanes);
                arriving.push_back((
                    cycle + u64::from(latency),
                    (tag, from.iter().map(|&s| data[s]).collect()),
                ));
                match perm {
                    Permutation::Rotate(_) => cov.hit("rotate"),
                    Permutation::Xor(_) => cov.hit("butterfly"),
                    Permutation::Broadcast(b) => {
                        cov.hit("broadcast");
                        cov.hit_if(b as usize == lanes - 1, "broadcast from the last cluster");
                    }
                    Permutation::PerCluster(_) => cov.hit("per-cluster sources"),
                }
                cov.hit_if(
                    from.iter().enumerate().all(|(c, &s)| c == s),
                    "identity pattern",
                );
                let index_wraps = match perm {
                    Permutation::PerCluster(_) => regs.iter().any(|&r| r as usize >= lanes),
                    Permutation::Rotate(k) | Permutation::Xor(k) | Permutation::Broadcast(k) => {
                        k as usize >= lanes
                    }
                };
                cov.hit_if(index_wraps, "pattern index past the cluster count");
                cov.hit_if(
                    last_send == Some(cycle.wrapping_sub(1)),
                    "back-to-back sends",
                );
                last_send = Some(cycle);
            }
        }
        if used && rng.chance(5) {
            sb.transaction();
            let refused = if rng.chance(50) {
                comm.reserve().is_err()
            } else {
                comm.send(&vec![0; lanes], Permutation::Rotate(0), None, 0)
                    .is_err()
            };
            sb.check(
                cycle,
                || "second use of the network in a cycle refused".into(),
                true,
                refused,
            );
            cov.hit("second send refused");
        }
        let expected = match arriving.front() {
            Some((due, _)) if *due == cycle => arriving.pop_front().map(|(_, w)| w),
            _ => None,
        };
        let got = comm.completed().map(|f| (f.tag, f.values.clone()));
        sb.check(cycle, || "words arriving".into(), expected, got);
        comm.commit();
        waves.cycle(cycle, |t| comm.trace(t));
        cycle += 1;
    }
    Outcome {
        scoreboard: sb,
        coverage: cov,
        waves: waves.finish(None),
    }
}
