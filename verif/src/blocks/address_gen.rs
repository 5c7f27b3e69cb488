//! Testbench of a memory address generator (`units::memory::address_gen`), driven as the
//! processor drives it: each core cycle the replies of the channels reach it, it retires
//! load words through its reorder buffer into its SRF stream buffer and issues up to
//! `ag_words_per_cycle` references; the SRF, the clock crossings and the DRAM channels
//! (all four, under the machine's policy) are the real ones. One stream operation runs at
//! a time: loads and stores, strided (stride 0, 1, the record size, large), record
//! (1–4 words per record) and indexed (gather and scatter, with and without a bound,
//! repeated indices), laid out one record after another or in cluster rows.
//!
//! Reference, from the operation's definition alone: record `i`'s word `j` is at DRAM word
//! `base + i·stride + j` (strided) or `base + index[i]·scale + j` (indexed), and at SRF
//! word `(i / C)·k·C + j·C + i mod C` of the stream (`C` records per row, `k` words per
//! record); the references go out in SRF order. Checked after every operation: the words
//! a load leaves in the SRF, the memory a store leaves (a later word of the stream to the
//! same address wins), and, per channel, the sequence of references it received.

use imagine_hdl::{ClockDomain, ContractError, Design, DomainId, Module, Sim, Trace};
use imagine_units::desc::MachineDesc;
use imagine_units::dram::{DramChannel, DramParams, Policy, Reply, TraceKind};
use imagine_units::memory::{
    AddressGenerator, MemOp, MemOpKind, MemPorts, MemoryConfig, Pattern, build_memory,
};
use imagine_units::srf::Srf;

use super::{Config, Coverage, Outcome, Rng, Scoreboard, Waves};

const BINS: &[&str] = &[
    "strided load",
    "strided store",
    "record load (more than one word per record)",
    "record store (more than one word per record)",
    "indexed load (gather)",
    "indexed store (scatter)",
    "bounded indexed stream",
    "stride 0",
    "stride 1",
    "large stride",
    "repeated index",
    "cluster-row layout",
    "reply out of stream order",
    "two replies in one cycle",
    "references to several channels",
];

/// DRAM words the stimulus touches: `[0, SPAN)`, preloaded with random words.
const SPAN: u64 = 4096;

/// The address generator with the SRF and the memory ports, clocked by the core.
struct Harness {
    domain: DomainId,
    srf: Srf,
    ag: AddressGenerator,
    ports: MemPorts,
    replies: Vec<Reply>,
    /// Replies seen (by sequence number) during the running load, and their count.
    next_reply: u32,
    out_of_order: u64,
    two_in_a_cycle: u64,
    deferred: Option<ContractError>,
}

impl Module for Harness {
    fn domain(&self) -> DomainId {
        self.domain
    }

    fn eval(&mut self) -> Result<(), ContractError> {
        if let Some(e) = self.deferred.take() {
            return Err(e);
        }
        self.replies.clear();
        self.ports.pop_replies(&mut self.replies)?;
        self.two_in_a_cycle += (self.replies.len() > 1) as u64;
        for r in &self.replies {
            if !r.write {
                self.out_of_order += (r.tag.seq != self.next_reply) as u64;
                self.next_reply = self.next_reply.max(r.tag.seq + 1);
            }
            self.ag.accept(r)?;
        }
        self.ag.eval(&mut self.srf, &mut self.ports, None)?;
        self.srf.eval();
        Ok(())
    }

    fn commit(&mut self) {
        self.srf.commit();
        if let Err(e) = self.ag.commit(&mut self.srf) {
            self.deferred = Some(e);
        }
        self.ports.commit();
    }

    fn trace(&self, t: &mut Trace) {
        self.srf.trace(t);
        self.ag.trace(t);
    }
}

/// One operation as the stimulus chose it, with what the reference derives from it.
struct Planned {
    op: MemOp,
    /// DRAM word of each reference, in SRF order.
    addresses: Vec<u64>,
}

fn plan(rng: &mut Rng, desc: &MachineDesc) -> (Planned, Vec<u64>) {
    let lanes = desc.cluster.count;
    let block = desc.srf.block_words;
    let kind = if rng.chance(50) {
        MemOpKind::Load
    } else {
        MemOpKind::Store
    };
    let k = rng.pick(&[1, 1, 2, 3, 4]);
    let rows = if rng.chance(30) { lanes } else { 1 };
    let records = if rows > 1 {
        lanes * (1 + rng.index((32 / lanes).max(1)))
    } else {
        1 + rng.index(32)
    };
    let indexed = rng.chance(35);
    let index_start = (4 * block + 128).div_ceil(block) * block;
    let mut indices = Vec::new();
    let (pattern, base) = if indexed {
        let scale = rng.pick(&[1, k as u64, 7]);
        let bound = 1 + rng.below(48);
        for _ in 0..records {
            let i = if !indices.is_empty() && rng.chance(15) {
                indices[rng.index(indices.len())]
            } else {
                rng.below(bound)
            };
            indices.push(i);
        }
        let bounded = rng.chance(50);
        let span = bound * scale + k as u64;
        (
            Pattern::Indexed {
                index_start,
                scale,
                bound: bounded.then_some(bound),
            },
            rng.below(SPAN - span),
        )
    } else {
        let stride = rng.pick(&[0, 1, k as u64, k as u64 + 1, 61, 97]);
        let span = (records as u64 - 1) * stride + k as u64;
        (Pattern::Strided { stride }, rng.below(SPAN - span))
    };
    let op = MemOp {
        kind,
        base,
        pattern,
        record_words: k,
        records,
        srf_start: block * rng.index(4),
        row_records: rows,
        cacheable: false,
    };
    let mut addresses = vec![0; records * k];
    for i in 0..records {
        for j in 0..k {
            let start = match pattern {
                Pattern::Strided { stride } => base + i as u64 * stride,
                Pattern::Indexed { scale, .. } => base + indices[i] * scale,
            };
            addresses[(i / rows) * k * rows + j * rows + i % rows] = start + j as u64;
        }
    }
    (Planned { op, addresses }, indices)
}

pub fn run(desc: &MachineDesc, config: &Config) -> Outcome {
    let mut rng = Rng::new(config.seed);
    let mut sb = Scoreboard::default();
    // With one cluster every layout is one record after another.
    let bins: Vec<&str> = BINS
        .iter()
        .copied()
        .filter(|b| desc.cluster.count > 1 || *b != "cluster-row layout")
        .collect();
    let mut cov = Coverage::new(&bins);
    let p = DramParams::of(desc);
    let mut memory: Vec<u32> = (0..SPAN).map(|_| rng.corner_word()).collect();
    let domains = vec![
        ClockDomain::mhz("core", desc.clocks.core_mhz),
        ClockDomain::mhz("dram", desc.clocks.dram_mhz),
    ];
    let mut design = Design::new("top", domains).expect("two valid clock domains");
    let core = design.domain("core").expect("declared");
    let policy = Policy::parse(&desc.memory.policy).unwrap_or(Policy::FirstReady);
    let ports = match build_memory(
        &mut design,
        desc,
        MemoryConfig {
            policy,
            record: true,
            init: vec![(0, memory.clone())],
        },
    ) {
        Ok(ports) => ports,
        Err(e) => {
            sb.assert(0, false, || format!("the memory system builds: {e}"));
            return Outcome {
                scoreboard: sb,
                coverage: cov,
                waves: Ok(None),
            };
        }
    };
    let mut top = design.scope();
    let srf = Srf::new(&mut top.child("srf"), desc);
    let m = &desc.memory;
    let ag = AddressGenerator::new(
        &mut top.child("ag0"),
        0,
        desc.srf.stream_buffers,
        m.ag_words_per_cycle,
        m.ag_reorder_words,
    );
    design.add(Harness {
        domain: core,
        srf,
        ag,
        ports,
        replies: Vec::new(),
        next_reply: 0,
        out_of_order: 0,
        two_in_a_cycle: 0,
        deferred: None,
    });
    let mut sim = Sim::new(design);
    let waves = Waves::attach(&mut sim, config);
    let mut seen = vec![0usize; p.channels];
    while sb.transactions < config.transactions && sb.mismatches == 0 {
        let (planned, indices) = plan(&mut rng, desc);
        let op = planned.op;
        let words = op.words();
        let data: Vec<u32> = (0..words).map(|_| rng.corner_word()).collect();
        note(&mut cov, &op, &indices, &planned.addresses, &p);
        let cycle = sim.core_cycles();
        let started = {
            let h = sim.modules_of_mut::<Harness>().next().expect("added");
            h.next_reply = 0;
            let mut go = || -> Result<(), ContractError> {
                if op.kind == MemOpKind::Store {
                    h.srf.load(op.srf_start, &data)?;
                }
                if let Pattern::Indexed { index_start, .. } = op.pattern {
                    let words: Vec<u32> = indices.iter().map(|&i| i as u32).collect();
                    h.srf.load(index_start, &words)?;
                }
                h.ag.start(op, &mut h.srf)
            };
            go()
        };
        if let Err(e) = started {
            sb.assert(cycle, false, || format!("{op:?} starts: {e}"));
            break;
        }
        sb.transactions += words as u64;
        // Every word crosses twice and waits behind at most the others: far fewer cycles.
        let limit = cycle + 2000 + 200 * words as u64;
        let finished = loop {
            match sim.step() {
                Ok(edge) if edge.rising.contains(core) => {
                    let h = sim.modules_of::<Harness>().next().expect("added");
                    if h.ag.just_finished() {
                        break true;
                    }
                    if sim.core_cycles() > limit {
                        break false;
                    }
                }
                Ok(_) => {}
                Err(e) => {
                    sb.assert(sim.core_cycles(), false, || format!("{op:?}: {e}"));
                    break false;
                }
            }
        };
        let cycle = sim.core_cycles();
        sb.assert(cycle, finished, || format!("{op:?} finishes"));
        if !finished {
            break;
        }
        // The references each channel received, in order.
        for (c, ch) in sim.modules_of::<DramChannel>().enumerate() {
            let got: Vec<(u64, bool)> = ch.recorded()[seen[c]..]
                .iter()
                .map(|r| (r.byte_addr, r.kind == TraceKind::Write))
                .collect();
            seen[c] = ch.recorded().len();
            let expected: Vec<(u64, bool)> = planned
                .addresses
                .iter()
                .map(|&w| w * 4)
                .filter(|&b| p.map(b).is_some_and(|l| l.channel == ch.index()))
                .map(|b| (b, op.kind == MemOpKind::Store))
                .collect();
            sb.check(
                cycle,
                || format!("references channel {} received for {op:?}", ch.index()),
                expected,
                got,
            );
        }
        match op.kind {
            MemOpKind::Load => {
                let expected: Vec<u32> = planned
                    .addresses
                    .iter()
                    .map(|&w| memory[w as usize])
                    .collect();
                let h = sim.modules_of::<Harness>().next().expect("added");
                cov.hit_if(h.out_of_order > 0, "reply out of stream order");
                let got = h
                    .srf
                    .read_back(op.srf_start, words)
                    .map_err(|e| e.to_string());
                sb.check(
                    cycle,
                    || format!("words {op:?} left in the SRF"),
                    Ok(expected),
                    got,
                );
            }
            MemOpKind::Store => {
                for (&w, &v) in planned.addresses.iter().zip(&data) {
                    memory[w as usize] = v;
                }
                let mut touched = planned.addresses.clone();
                touched.sort_unstable();
                touched.dedup();
                for w in touched {
                    let byte = w * 4;
                    let channel = p.map(byte).map_or(0, |l| l.channel);
                    let got = sim
                        .modules_of::<DramChannel>()
                        .find(|c| c.index() == channel)
                        .and_then(|c| c.peek(byte));
                    sb.check(
                        cycle,
                        || format!("DRAM word {w} after {op:?}"),
                        Some(memory[w as usize]),
                        got,
                    );
                }
            }
        }
    }
    let h = sim.modules_of::<Harness>().next().expect("added");
    cov.hit_if(h.two_in_a_cycle > 0, "two replies in one cycle");
    Outcome {
        scoreboard: sb,
        coverage: cov,
        waves: waves.finish(Some(&mut sim)),
    }
}

/// Counts the coverage an operation reaches.
fn note(cov: &mut Coverage, op: &MemOp, indices: &[u64], addresses: &[u64], p: &DramParams) {
    let load = op.kind == MemOpKind::Load;
    match op.pattern {
        Pattern::Strided { stride } => {
            cov.hit(if load {
                "strided load"
            } else {
                "strided store"
            });
            cov.hit_if(stride == 0, "stride 0");
            cov.hit_if(stride == 1, "stride 1");
            cov.hit_if(stride > 8, "large stride");
        }
        Pattern::Indexed { bound, .. } => {
            cov.hit(if load {
                "indexed load (gather)"
            } else {
                "indexed store (scatter)"
            });
            cov.hit_if(bound.is_some(), "bounded indexed stream");
            let mut sorted = indices.to_vec();
            sorted.sort_unstable();
            cov.hit_if(sorted.windows(2).any(|w| w[0] == w[1]), "repeated index");
        }
    }
    if op.record_words > 1 {
        cov.hit(if load {
            "record load (more than one word per record)"
        } else {
            "record store (more than one word per record)"
        });
    }
    cov.hit_if(op.row_records > 1, "cluster-row layout");
    let first = p.map(addresses[0] * 4).map(|l| l.channel);
    cov.hit_if(
        addresses
            .iter()
            .any(|&w| p.map(w * 4).map(|l| l.channel) != first),
        "references to several channels",
    );
}
