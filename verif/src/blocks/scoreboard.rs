//! Testbench of the stream controller's scoreboard (`units::stream_controller`): a random
//! stream program of loads, stores (strided and indexed, with and without a bound) and host
//! SRF writes and reads over a few overlapping SRF and DRAM regions, so that most
//! instructions depend on an older one; the units (the machine's address generators and
//! the host interface) take a random number of cycles per operation, and the bench reports
//! completions at the clock edge as the processor does.
//!
//! Reference, from each instruction's definition: the SRF words it reads and writes (a
//! memory operation's stream, an indexed stream's index stream too), the DRAM words (a
//! strided stream's span, a bounded indexed stream's records below the bound, an unbounded
//! one all of memory). An instruction may issue once it has entered the scoreboard, its
//! unit is free and no older instruction not yet completed writes what it reads or writes
//! or reads what it writes; of those, the oldest issues. Checked every issue: it was
//! allowed, it was the oldest allowed, on a free unit of its kind, once; and every
//! instruction completes.

use imagine_hdl::{SignalKind, bits_for};
use imagine_units::desc::MachineDesc;
use imagine_units::memory::{MemOp, MemOpKind, Pattern};
use imagine_units::stream_controller::{Issue, StreamController, StreamInstr, Unit};

use super::{BlockClock, Config, Coverage, Outcome, Rng, Scoreboard, Waves, design};

const BINS: &[&str] = &[
    "load issued",
    "store issued",
    "host write issued",
    "host read issued",
    "indexed stream without a bound",
    "waits: read after write (SRF)",
    "waits: write after read (SRF)",
    "waits: write after write (SRF)",
    "waits: DRAM conflict",
    "younger instruction passes a blocked older one",
    "ready instruction waits for its unit",
    "every address generator busy",
];

/// What an instruction touches: SRF `[start, start + len)` ranges and DRAM `[lo, hi)`
/// ranges (`None`: all of memory).
#[derive(Default)]
struct Touches {
    srf_reads: Vec<(usize, usize)>,
    srf_writes: Vec<(usize, usize)>,
    mem_reads: Vec<Option<(u64, u64)>>,
    mem_writes: Vec<Option<(u64, u64)>>,
}

fn srf_meet(a: &[(usize, usize)], b: &[(usize, usize)]) -> bool {
    a.iter().any(|&(s, n)| {
        b.iter()
            .any(|&(t, m)| n > 0 && m > 0 && s < t + m && t < s + n)
    })
}

fn mem_meet(a: &[Option<(u64, u64)>], b: &[Option<(u64, u64)>]) -> bool {
    a.iter().any(|x| {
        b.iter().any(|y| match (x, y) {
            (Some((lo, hi)), Some((l2, h2))) => lo < h2 && l2 < hi,
            _ => true,
        })
    })
}

fn touches(instr: &StreamInstr) -> Touches {
    let mut t = Touches::default();
    match instr {
        StreamInstr::Memory(m) => {
            let words = m.records * m.record_words;
            let k = m.record_words as u64;
            let span = match m.pattern {
                Pattern::Strided { stride } => {
                    Some((m.base, m.base + (m.records as u64 - 1) * stride + k))
                }
                Pattern::Indexed {
                    scale,
                    bound: Some(bound),
                    ..
                } => Some((m.base, m.base + (bound - 1) * scale + k)),
                Pattern::Indexed { bound: None, .. } => None,
            };
            if let Pattern::Indexed { index_start, .. } = m.pattern {
                t.srf_reads.push((index_start, m.records));
            }
            if m.kind == MemOpKind::Load {
                t.srf_writes.push((m.srf_start, words));
                t.mem_reads.push(span);
            } else {
                t.srf_reads.push((m.srf_start, words));
                t.mem_writes.push(span);
            }
        }
        StreamInstr::WriteSrf { start, words } => t.srf_writes.push((*start, words.len())),
        StreamInstr::ReadSrf { start, len } => t.srf_reads.push((*start, *len)),
        _ => {}
    }
    t
}

/// The kinds of hazard an older instruction puts on a younger one.
fn hazards(older: &Touches, younger: &Touches) -> [bool; 4] {
    [
        srf_meet(&older.srf_writes, &younger.srf_reads),
        srf_meet(&older.srf_reads, &younger.srf_writes),
        srf_meet(&older.srf_writes, &younger.srf_writes),
        mem_meet(&older.mem_writes, &younger.mem_reads)
            || mem_meet(&older.mem_writes, &younger.mem_writes)
            || mem_meet(&older.mem_reads, &younger.mem_writes),
    ]
}

fn program(rng: &mut Rng, desc: &MachineDesc, n: usize) -> Vec<StreamInstr> {
    let block = desc.srf.block_words;
    (0..n)
        .map(|_| {
            let start = block * rng.index(6);
            match rng.below(10) {
                0 => StreamInstr::WriteSrf {
                    start,
                    words: vec![0; 1 + rng.index(2 * block)],
                },
                1 => StreamInstr::ReadSrf {
                    start,
                    len: 1 + rng.index(2 * block),
                },
                _ => {
                    let records = 1 + rng.index(block);
                    let record_words = rng.pick(&[1, 1, 2]);
                    let pattern = if rng.chance(25) {
                        Pattern::Indexed {
                            index_start: block * (6 + rng.index(2)),
                            scale: 1,
                            bound: rng.chance(50).then(|| 1 + rng.below(64)),
                        }
                    } else {
                        Pattern::Strided {
                            stride: rng.pick(&[1, 2, 16]),
                        }
                    };
                    StreamInstr::Memory(MemOp {
                        kind: if rng.chance(50) {
                            MemOpKind::Load
                        } else {
                            MemOpKind::Store
                        },
                        base: 128 * rng.below(8),
                        pattern,
                        record_words,
                        records,
                        srf_start: start,
                        row_records: 1,
                        cacheable: false,
                    })
                }
            }
        })
        .collect()
}

pub fn run(desc: &MachineDesc, config: &Config) -> Outcome {
    let mut rng = Rng::new(config.seed);
    let mut sb = Scoreboard::default();
    let mut cov = Coverage::new(BINS);
    let ags = desc.memory.address_generators;
    let n = config.transactions as usize;
    let instrs = program(&mut rng, desc, n);
    let refs: Vec<Touches> = instrs.iter().map(touches).collect();
    for i in &instrs {
        cov.hit_if(
            matches!(i, StreamInstr::Memory(m) if matches!(m.pattern, Pattern::Indexed { bound: None, .. })),
            "indexed stream without a bound",
        );
    }
    let mut sc = StreamController::new(desc, Vec::new(), instrs.clone());
    // Per unit, the instruction it runs and the cycle it completes.
    let mut ag_busy: Vec<Option<(usize, u64)>> = vec![None; ags];
    let mut host_busy: Option<(usize, u64)> = None;
    let mut completed = vec![false; n];
    let mut issued = vec![false; n];
    let limit = 200 * n as u64 + 1000;
    // The controller has no probes of its own (the processor shows its occupancy): the
    // waveform shows the testbench's view of its ports.
    let mut d = design();
    let mut scope = d.scope();
    let mut s = scope.child("sc");
    let probe_occupancy = s.signal(
        "scoreboard",
        bits_for(desc.stream_controller.scoreboard_entries as u64),
        SignalKind::Reg,
    );
    let probe_issue = s.signal("issue_valid", 1, SignalKind::Wire);
    let probe_issue_id = s.signal("issue_id", 32, SignalKind::Wire);
    let probe_ags_busy = s.signal("ags_busy", ags as u32, SignalKind::Reg);
    let probe_host_busy = s.signal("host_busy", 1, SignalKind::Reg);
    let mut waves = Waves::new(d.probes(), desc, BlockClock::Core, config);
    let mut cycle = 0u64;
    let mut oldest = 0;
    loop {
        while oldest < n && completed[oldest] {
            oldest += 1;
        }
        if oldest == n {
            break;
        }
        if cycle > limit {
            sb.assert(cycle, false, || "every instruction completes".into());
            break;
        }
        let issue = sc.select(
            |a| ag_busy[a].is_none(),
            ags,
            true,
            true,
            host_busy.is_none(),
        );
        // The reference's choice: the oldest entered, unissued instruction with no hazard
        // from an older one not yet completed, whose unit is free.
        let records = sc.records();
        let ag_free = ag_busy.iter().any(Option::is_none);
        cov.hit_if(!ag_free, "every address generator busy");
        let mut expected = None;
        let mut blocked_older = false;
        let mut unit_wait = false;
        // Everything older than the oldest instruction not completed is done; entry is in
        // program order, so nothing past the first not entered has entered.
        for id in oldest..n {
            if records[id].entered.is_none() {
                break;
            }
            if issued[id] {
                continue;
            }
            let mut waits = [false; 4];
            for o in oldest..id {
                if !completed[o] {
                    for (w, h) in waits.iter_mut().zip(hazards(&refs[o], &refs[id])) {
                        *w |= h;
                    }
                }
            }
            if waits.iter().any(|w| *w) {
                cov.hit_if(waits[0], "waits: read after write (SRF)");
                cov.hit_if(waits[1], "waits: write after read (SRF)");
                cov.hit_if(waits[2], "waits: write after write (SRF)");
                cov.hit_if(waits[3], "waits: DRAM conflict");
                blocked_older = true;
                continue;
            }
            let free = match instrs[id] {
                StreamInstr::Memory(_) => ag_free,
                _ => host_busy.is_none(),
            };
            if free {
                cov.hit_if(
                    blocked_older,
                    "younger instruction passes a blocked older one",
                );
                expected = Some(id);
                break;
            }
            unit_wait = true;
        }
        cov.hit_if(unit_wait, "ready instruction waits for its unit");
        sb.check(
            cycle,
            || "the instruction issued".into(),
            expected,
            issue.as_ref().map(|i| i.id),
        );
        if let Some(Issue { id, unit, .. }) = &issue {
            let id = *id;
            issued[id] = true;
            let done = cycle + 1 + rng.below(24);
            match (&instrs[id], unit) {
                (StreamInstr::Memory(m), Unit::AddressGenerator(a)) if *a < ags => {
                    sb.assert(cycle, ag_busy[*a].is_none(), || format!("ag{a} free"));
                    ag_busy[*a] = Some((id, done));
                    cov.hit(if m.kind == MemOpKind::Load {
                        "load issued"
                    } else {
                        "store issued"
                    });
                }
                (
                    StreamInstr::WriteSrf { .. } | StreamInstr::ReadSrf { .. },
                    Unit::HostInterface,
                ) => {
                    sb.assert(cycle, host_busy.is_none(), || "host interface free".into());
                    host_busy = Some((id, done));
                    cov.hit(if matches!(instrs[id], StreamInstr::WriteSrf { .. }) {
                        "host write issued"
                    } else {
                        "host read issued"
                    });
                }
                _ => sb.assert(cycle, false, || {
                    format!("instruction {id} on a unit of its kind, got {unit:?}")
                }),
            }
            sb.transaction();
        }
        // The clock edge: completions first, then the controller's commit.
        for slot in ag_busy.iter_mut().chain(std::iter::once(&mut host_busy)) {
            if let Some((id, done)) = *slot
                && cycle >= done
            {
                sc.complete(id, cycle);
                completed[id] = true;
                *slot = None;
            }
        }
        sc.commit(cycle, issue.as_ref());
        waves.cycle(cycle, |t| {
            t.value(probe_occupancy, sc.occupancy() as u64);
            t.value(probe_issue, issue.is_some() as u64);
            t.value(probe_issue_id, issue.as_ref().map_or(0, |i| i.id as u64));
            let busy = ag_busy.iter().enumerate();
            t.value(
                probe_ags_busy,
                busy.fold(0, |m, (a, b)| m | (b.is_some() as u64) << a),
            );
            t.value(probe_host_busy, host_busy.is_some() as u64);
        });
        cycle += 1;
    }
    Outcome {
        scoreboard: sb,
        coverage: cov,
        waves: waves.finish(None),
    }
}
