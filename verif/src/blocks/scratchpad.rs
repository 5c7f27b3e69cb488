//! Testbench of the scratchpad (`units::scratchpad`): one access per cycle, reads and
//! writes addressed by a base plus per-cluster offsets, under a cluster mask, with the top
//! words set aside for conditional stream buffers; sizes and latencies from the machine.
//!
//! Reference: a word array per cluster; a write issued in cycle `t` is visible to reads
//! issued from cycle `t + scratchpad_write`; a read issued in cycle `t` returns, in cycle
//! `t + scratchpad_read`, the words as they were when it issued. An access that addresses
//! the reserved buffers or past the end in an active cluster, or a second access in one
//! cycle, is refused.

use std::collections::VecDeque;

use imagine_units::desc::MachineDesc;
use imagine_units::scratchpad::Scratchpad;

use super::{BlockClock, Config, Coverage, Outcome, Rng, Scoreboard, Waves, design};

const BINS: &[&str] = &[
    "read",
    "write",
    "indexed read",
    "indexed write",
    "masked access",
    "read in the cycle a write becomes visible",
    "read one cycle before a write becomes visible",
    "back-to-back reads",
    "conditional-stream claim",
    "second access refused",
    "address in the reserved buffers",
    "address past the end",
    "top usable word",
    "word 0",
];

/// A write in flight in the reference: visible from cycle `visible`.
struct PendingWrite {
    visible: u64,
    addrs: Vec<usize>,
    values: Vec<u32>,
    mask: Vec<bool>,
}

/// What a read returns: per cluster, the word (active clusters) or nothing.
type ReadResult = (u16, Vec<Option<u32>>);

pub fn run(desc: &MachineDesc, config: &Config) -> Outcome {
    let lanes = desc.cluster.count;
    let words = desc.scratchpad.words;
    let (read_latency, write_latency) =
        (desc.latency.scratchpad_read, desc.latency.scratchpad_write);
    let buffers = 2 * desc.srf.conditional_words_per_cycle;
    let mut rng = Rng::new(config.seed);
    let mut sb = Scoreboard::default();
    // With a write latency of 1 the write itself holds the port the cycle before it lands.
    let bins: Vec<&str> = BINS
        .iter()
        .copied()
        .filter(|b| write_latency > 1 || *b != "read one cycle before a write becomes visible")
        .collect();
    let mut cov = Coverage::new(&bins);
    let mut d = design();
    let mut sp = Scratchpad::new(
        &mut d.scope(),
        "sp0",
        words,
        lanes,
        read_latency,
        write_latency,
    );

    let mut memory = vec![vec![0u32; lanes]; words];
    let mut writes: Vec<PendingWrite> = Vec::new();
    let mut reads: VecDeque<(u64, ReadResult)> = VecDeque::new();
    // Targets of recent writes by issue cycle, to read them back exactly as they land.
    let mut recent: VecDeque<(u64, Vec<usize>)> = VecDeque::new();
    let mut reserved = 0;
    let mut tag = 0u16;
    let mut last_read = None;
    let mut waves = Waves::new(d.probes(), desc, BlockClock::Core, config);
    let mut cycle = 0u64;
    while sb.transactions < config.transactions || !reads.is_empty() || !writes.is_empty() {
        let driving = sb.transactions < config.transactions;
        if driving && cycle.is_multiple_of(97) {
            // Kernels with and without conditional streams come and go.
            reserved = if rng.chance(50) {
                buffers.min(words - 1)
            } else {
                0
            };
            sp.reserve_for_conditional_streams(reserved);
        }
        let limit = words - reserved;
        // Writes due now land before this cycle's reads.
        let landing: Vec<(usize, usize)> = writes
            .iter()
            .filter(|w| w.visible == cycle)
            .flat_map(|w| (0..lanes).filter(|&c| w.mask[c]).map(|c| (w.addrs[c], c)))
            .collect();
        let next: Vec<(usize, usize)> = writes
            .iter()
            .filter(|w| w.visible == cycle + 1)
            .flat_map(|w| (0..lanes).filter(|&c| w.mask[c]).map(|c| (w.addrs[c], c)))
            .collect();
        // A write stays in the block's delay line through the cycle it becomes visible.
        let landing_writes = writes.iter().filter(|w| w.visible == cycle).count();
        writes.retain(|w| {
            if w.visible > cycle {
                return true;
            }
            for c in 0..lanes {
                if w.mask[c] {
                    memory[w.addrs[c]][c] = w.values[c];
                }
            }
            false
        });

        let mut port_used = false;
        if driving && rng.chance(80) {
            sb.transaction();
            port_used = true;
            let kind = rng.below(10);
            if kind == 0 {
                let got = sp.claim_for_conditional_stream().is_ok();
                sb.check(
                    cycle,
                    || "conditional-stream claim accepted".into(),
                    true,
                    got,
                );
                cov.hit("conditional-stream claim");
            } else {
                let is_read = kind <= 5;
                let mask = if rng.chance(30) {
                    rng.mask(lanes)
                } else {
                    vec![true; lanes]
                };
                let mut targets: Vec<usize> = match recent
                    .iter()
                    .find(|(t, _)| *t + u64::from(write_latency) == cycle)
                {
                    Some((_, t)) if is_read && rng.chance(60) => t.clone(),
                    _ => (0..lanes)
                        .map(|_| match rng.below(6) {
                            0 => 0,
                            1 => limit - 1,
                            2 | 3 => rng.index(4.min(limit)),
                            _ => rng.index(limit),
                        })
                        .collect(),
                };
                // Now and then an active cluster addresses the buffers or past the end.
                let bad_lane = (0..lanes).find(|&c| mask[c]).filter(|_| rng.chance(8));
                if let Some(c) = bad_lane {
                    targets[c] = limit + rng.index(reserved + 3);
                }
                let uniform = targets.iter().all(|&t| t == targets[0]);
                let (base, offsets) = if uniform && rng.chance(50) {
                    (targets[0], None)
                } else {
                    let base = rng.index(targets.iter().copied().min().unwrap_or(0) + 1);
                    (
                        base,
                        Some(
                            targets
                                .iter()
                                .map(|&t| (t - base) as u32)
                                .collect::<Vec<_>>(),
                        ),
                    )
                };
                let refused = (0..lanes).any(|c| mask[c] && targets[c] >= limit);
                let got = if is_read {
                    tag = tag.wrapping_add(1);
                    sp.read(base as u16, offsets.as_deref(), &mask, tag)
                } else {
                    let values = rng.lane_words(lanes);
                    let r = sp.write(base as u16, offsets.as_deref(), &values, &mask);
                    if !refused {
                        writes.push(PendingWrite {
                            visible: cycle + u64::from(write_latency),
                            addrs: targets.clone(),
                            values,
                            mask: mask.clone(),
                        });
                        recent.push_back((cycle, targets.clone()));
                    }
                    r
                };
                sb.check(
                    cycle,
                    || {
                        format!(
                            "{} at base {base} offsets {offsets:?} mask {mask:?} refused",
                            if is_read { "read" } else { "write" }
                        )
                    },
                    refused,
                    got.is_err(),
                );
                if refused {
                    let c = bad_lane.unwrap_or(0);
                    cov.hit_if(targets[c] < words, "address in the reserved buffers");
                    cov.hit_if(targets[c] >= words, "address past the end");
                } else {
                    let active = |a: usize| (0..lanes).any(|c| mask[c] && targets[c] == a);
                    cov.hit_if(active(0), "word 0");
                    cov.hit_if(active(limit - 1), "top usable word");
                    cov.hit_if(mask.iter().any(|&m| !m), "masked access");
                }
                if is_read && !refused {
                    let values = (0..lanes)
                        .map(|c| mask[c].then(|| memory[targets[c]][c]))
                        .collect();
                    reads.push_back((cycle + u64::from(read_latency), (tag, values)));
                    let hits = |set: &[(usize, usize)]| {
                        (0..lanes).any(|c| mask[c] && set.contains(&(targets[c], c)))
                    };
                    cov.hit("read");
                    cov.hit_if(offsets.is_some(), "indexed read");
                    cov.hit_if(hits(&landing), "read in the cycle a write becomes visible");
                    cov.hit_if(
                        write_latency > 1 && hits(&next),
                        "read one cycle before a write becomes visible",
                    );
                    cov.hit_if(
                        last_read == Some(cycle.wrapping_sub(1)),
                        "back-to-back reads",
                    );
                    last_read = Some(cycle);
                } else if !is_read && !refused {
                    cov.hit("write");
                    cov.hit_if(offsets.is_some(), "indexed write");
                }
            }
        }
        // One port: a second access in the cycle is refused (and changes nothing).
        if driving && port_used && rng.chance(5) {
            sb.transaction();
            let refused = match rng.below(3) {
                0 => sp.read(0, None, &vec![true; lanes], 0).is_err(),
                1 => sp
                    .write(0, None, &vec![0; lanes], &vec![true; lanes])
                    .is_err(),
                _ => sp.claim_for_conditional_stream().is_err(),
            };
            sb.check(
                cycle,
                || "second access in one cycle refused".into(),
                true,
                refused,
            );
            cov.hit("second access refused");
        }

        // The read result leaving this cycle.
        let expected = match reads.front() {
            Some((due, _)) if *due == cycle => reads.pop_front().map(|(_, r)| r),
            _ => None,
        };
        let got = sp.completed().map(|f| {
            let values = (0..lanes)
                .map(|c| f.mask[c].then_some(f.values[c]))
                .collect();
            (f.tag, values)
        });
        sb.check(cycle, || "read result leaving".into(), expected, got);
        let leaving = usize::from(sp.completed().is_some());
        sb.check(
            cycle,
            || "accesses in flight".into(),
            reads.len() + leaving + writes.len() + landing_writes,
            sp.in_flight(),
        );
        sp.commit();
        waves.cycle(cycle, |t| sp.trace(t));
        recent.retain(|(t, _)| *t + u64::from(write_latency) > cycle);
        cycle += 1;
    }
    Outcome {
        scoreboard: sb,
        coverage: cov,
        waves: waves.finish(None),
    }
}
