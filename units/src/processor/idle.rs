//! Jumping over idle time in a processor run.
//!
//! A stretch of core cycles is *idle* when stepping through it would change nothing but
//! counters and ring positions. That holds when every block is quiet:
//!
//! * **Stream controller**: no scoreboard entry may issue on the units as they are, and no
//!   instruction can move from the host into the queue or from the queue into the
//!   scoreboard ([`StreamController::idle`]). Each cycle it still counts a unit-busy cycle
//!   (an entry waits for a busy unit, typically the clusters) and a scoreboard-full cycle.
//! * **Clusters and SRF**: no kernel running (none started, or the last one finished and
//!   flushed and only held for the minimum kernel time), nothing in flight in any unit, and
//!   no stream buffer asking for the SRF port ([`Machine::idle_skippable`]). Each cycle the
//!   SRF counts an idle port cycle and each bound buffer its starved or blocked cycle; the
//!   units' delay lines and rings turn.
//! * **Address generators**: none running.
//! * **Crossings**: both FIFOs of every channel empty, their synchronisers settled.
//! * **Channels**: quiet as the trace replay defines it ([`DramChannel::can_skip_idle`]:
//!   nothing pending or on the buses, banks closed, no timing constraint running). They
//!   only count cycles and refresh, which they do in closed form.
//!
//! Nothing then changes until the first timed event: the held kernel's release
//! (`started + min_kernel_cycles`), the end of a microcode load, the end of a host
//! transfer, or the run's cycle limit. Every core edge before that event's cycle is idle,
//! so the jump lands just after the last of them: each block counts the skipped core
//! cycles, the channels the DRAM edges up to that instant, and the clocks are set as
//! stepping leaves them ([`Sim::skip_to`]). Stepping then resumes with the event's edge.
//! With a tracer attached nothing is skipped: the waveform shows every cycle.
//!
//! [`StreamController::idle`]: crate::stream_controller::StreamController::idle
//! [`Machine::idle_skippable`]: crate::machine::Machine::idle_skippable

use imagine_hdl::{ContractError, Sim};

use super::{Processor, processor_mut};
use crate::dram::DramChannel;
use crate::stream_controller::IdleCounts;

/// Core cycles from a failed attempt to jump to the next. The test costs as much as tens
/// of stepped cycles, and where the clusters wait but a channel is busy (a row it leaves
/// open until the next refresh closes it) it fails for thousands of cycles; an idle stretch
/// is found at most this much later.
const RETRY: u64 = 16;

/// Runs `sim` (a built processor) until `done` holds, checked (with the processor) after
/// every core-clock edge, or `max` more core cycles have elapsed; returns whether `done`
/// held. Idle time is jumped over (see the module doc), so `done` must depend on the
/// design's state, not on the cycle count: it does not change in idle cycles.
pub fn run_until(
    sim: &mut Sim,
    max: u64,
    mut done: impl FnMut(&Processor, &Sim) -> bool,
) -> Result<bool, ContractError> {
    let end = sim.core_cycles().saturating_add(max);
    // Found once: searching the modules for it every cycle cost more than the check.
    let at = sim
        .module_index::<Processor>()
        .expect("the design holds a processor");
    let maybe_idle = sim
        .module::<Processor>(at)
        .expect("found above")
        .maybe_idle
        .clone();
    let mut next_try = 0;
    while sim.core_cycles() < end {
        let before = sim.core_cycles();
        sim.step()?;
        let now = sim.core_cycles();
        if now > before {
            let processor = sim.module::<Processor>(at).expect("found above");
            if done(processor, sim) {
                return Ok(true);
            }
            if maybe_idle.get() && now >= next_try && skip_idle(sim, end) == 0 {
                next_try = now + RETRY;
            }
        }
    }
    Ok(false)
}

/// Between core cycles: if the processor is idle until a known cycle (at most `end`),
/// jumps there. Returns the core cycles skipped.
fn skip_idle(sim: &mut Sim, end: u64) -> u64 {
    if !sim.can_skip() {
        return 0;
    }
    let now = sim.core_cycles();
    let Some((until, counts)) = processor_mut(sim).idle_until(end) else {
        return 0;
    };
    debug_assert_eq!(super::processor(sim).cycle, now);
    if !sim
        .modules_of::<DramChannel>()
        .all(DramChannel::can_skip_idle)
    {
        return 0;
    }
    let Some(dram) = sim.clocks().find("dram") else {
        return 0;
    };
    let Some(at) = sim.cycles_at(until) else {
        return 0;
    };
    let dram_edges = at[dram.0 as usize] - sim.clocks().cycles(dram);
    let n = until - now;
    processor_mut(sim).skip_idle(n, counts);
    for c in sim.modules_of_mut::<DramChannel>() {
        c.skip_idle(dram_edges);
    }
    let skipped = sim.skip_to(until);
    debug_assert!(skipped, "checked by can_skip and cycles_at");
    n
}

impl Processor {
    /// If every core-domain block is quiet (see the module doc), the core cycle of the
    /// first timed event, capped at `end`, and what the controller counts each cycle
    /// until then; `None` if something may change at the next edge.
    fn idle_until(&mut self, end: u64) -> Option<(u64, IdleCounts)> {
        if !self.skip_idle
            || self.deferred.is_some()
            || self.issue.is_some()
            || self.ags.iter().any(|a| a.is_busy())
            || self.rasterizer_busy()
            || !self.machine.idle_skippable()
        {
            return None;
        }
        // The edge of core cycle `c` completes an operation when `c >= done`.
        let mut until = end;
        if let Some(k) = &self.kernel {
            until = until.min(k.started.saturating_add(self.sc.min_kernel_cycles()));
        }
        if let Some((_, done)) = self.loader {
            until = until.min(done);
        }
        if let Some(t) = &self.host_transfer {
            until = until.min(t.done);
        }
        if until <= self.cycle || !self.ports.is_settled() {
            return None;
        }
        let counts = self.sc.idle(
            |_| true,
            self.ags.len(),
            self.kernel.is_none(),
            self.loader.is_none(),
            self.host_transfer.is_none(),
            true,
        )?;
        Some((until, counts))
    }

    /// Brings the core-domain blocks over `n` idle cycles, as stepping them would.
    fn skip_idle(&mut self, n: u64, counts: IdleCounts) {
        debug_assert!(n > 0);
        self.machine.skip_idle(n);
        self.ags.iter_mut().for_each(|a| a.skip_idle(n));
        self.ports.commit();
        self.sc.skip_idle(n, counts);
        self.replies.clear();
        self.cycle += n;
        self.skipped += n;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::desc::MachineDesc;
    use crate::machine::StreamBinding;
    use crate::memory::{MemOp, MemOpKind, Pattern};
    use crate::microcode::asm::assemble;
    use crate::processor::{ProcessorOptions, StreamProgram, build, processor};
    use crate::stream_controller::StreamInstr;

    const N: usize = 256;
    const BATCHES: usize = 3;
    const X: u64 = 0;
    const Y: u64 = 0x1_0000;
    const Z: u64 = 0x3_0000;

    fn mem(kind: MemOpKind, base: u64, srf_start: usize) -> StreamInstr {
        StreamInstr::Memory(MemOp {
            kind,
            base,
            pattern: Pattern::Strided { stride: 1 },
            record_words: 1,
            records: N,
            srf_start,
            row_records: 1,
            cacheable: false,
        })
    }

    /// Every kind of stream instruction: a microcode load, a long host write (`w`, read by
    /// every kernel), then per batch (two SRF buffers) loads of `x` and `y`, the madd
    /// kernel and a store of `z`, and a host read of the last `z`.
    fn program(desc: &MachineDesc) -> (StreamProgram, Vec<(u64, Vec<u32>)>) {
        let madd = assemble(include_str!("../../tests/microcode/madd.uc"), desc).unwrap();
        let w_at = 2 * 3 * N;
        let mut instrs = vec![
            StreamInstr::LoadMicrocode { program: 0 },
            StreamInstr::WriteSrf {
                start: w_at,
                words: (0..N as u32).map(|i| 0x3F80_0000 + i).collect(),
            },
        ];
        for b in 0..BATCHES {
            let s = (b % 2) * 3 * N;
            let off = (b * N) as u64;
            instrs.push(mem(MemOpKind::Load, X + off, s));
            instrs.push(mem(MemOpKind::Load, Y + off, s + N));
            instrs.push(StreamInstr::Kernel {
                program: 0,
                bindings: [s, s + N, w_at, s + 2 * N]
                    .map(|start| StreamBinding { start, words: N })
                    .to_vec(),
            });
            instrs.push(mem(MemOpKind::Store, Z + off, s + 2 * N));
        }
        instrs.push(StreamInstr::ReadSrf {
            start: ((BATCHES - 1) % 2) * 3 * N + 2 * N,
            len: N,
        });
        let words = |seed: u32| {
            (0..(N * BATCHES) as u32)
                .map(|i| 0x3F00_0000 + seed * i)
                .collect()
        };
        let program = StreamProgram {
            kernels: vec![madd],
            instrs,
        };
        (program, vec![(X, words(3)), (Y, words(5))])
    }

    /// Everything that evolves in the design but the count of skipped cycles.
    fn state(sim: &mut Sim) -> String {
        // Sleeping clusters are brought over the cycles they slept, as stepping leaves them.
        crate::processor::processor_mut(sim).machine.wake_clusters();
        let p = processor(sim);
        let mut out = format!(
            "clocks {:?}\ncycle {} issue {:?} kernel {:?} loader {:?} ag_ops {:?} deferred {:?}\n\
             host {:?}\nports {} {} {:?}\nags {:?}\nmachine {}\nsc {}\n",
            sim.clocks(),
            p.cycle,
            p.issue,
            p.kernel.as_ref().map(|k| (k.id, k.program, k.started)),
            p.loader,
            p.ag_ops,
            p.deferred,
            p.host_transfer.as_ref().map(|t| (t.id, t.done, t.start)),
            p.ports.pushed,
            p.ports.is_settled(),
            p.replies,
            p.ags,
            p.machine.debug_state(),
            p.sc.debug_state(),
        );
        for c in sim.modules_of::<DramChannel>() {
            out += &c.debug_state();
            out.push('\n');
        }
        out
    }

    /// Asserts that two runs are in the same state, naming the first line that differs.
    fn same(fast: &mut Sim, slow: &mut Sim, when: &str) {
        let (f, s) = (state(fast), state(slow));
        if let Some((a, b)) = f.lines().zip(s.lines()).find(|(a, b)| a != b) {
            let cut = |l: &str| {
                let at = l
                    .bytes()
                    .zip(if l == a { b } else { a }.bytes())
                    .take_while(|(x, y)| x == y)
                    .count();
                l[at.saturating_sub(200)..(at + 200).min(l.len())].to_string()
            };
            panic!(
                "{when}, cycle {}:\nskipped {}\nstepped {}",
                fast.core_cycles(),
                cut(a),
                cut(b)
            );
        }
        assert_eq!(f, s, "{when}");
    }

    fn done(sim: &Sim) -> bool {
        processor(sim).is_done() && sim.modules_of::<DramChannel>().all(DramChannel::is_idle)
    }

    /// Runs the program twice in lock step, one run jumping over idle time and one stepping
    /// it; after every jump, steps the other run to the same cycle and compares the whole
    /// state of the design. Returns the jumps, and how many of them ended with a refresh
    /// decided but not yet on a channel's bus.
    fn compare(desc: &MachineDesc) -> (usize, usize) {
        let (program, init) = program(desc);
        let sim = || {
            let opts = ProcessorOptions {
                dram_init: init.clone(),
                ..ProcessorOptions::default()
            };
            build(desc, program.clone(), opts).unwrap()
        };
        let (mut fast, mut slow) = (sim(), sim());
        let end = 1 << 40;
        let (mut skips, mut refreshing) = (0, 0);
        // As `run_until` does: `done` after each core edge, then perhaps a jump.
        loop {
            let before = fast.core_cycles();
            assert_eq!(fast.step().unwrap(), slow.step().unwrap());
            if fast.core_cycles() == before {
                continue;
            }
            if done(&fast) {
                break;
            }
            if skip_idle(&mut fast, end) > 0 {
                skips += 1;
                while slow.core_cycles() < fast.core_cycles() {
                    slow.step().unwrap();
                    assert!(!done(&slow), "done inside idle time");
                }
                same(&mut fast, &mut slow, "after a jump");
                refreshing +=
                    usize::from(state(&mut fast).contains("\nbus Some(Issued { cmd: Refresh"));
            }
        }
        assert!(done(&slow));
        same(&mut fast, &mut slow, "at the end");
        assert_eq!(processor(&fast).skipped_cycles() > 0, skips > 0);
        assert_eq!(processor(&slow).skipped_cycles(), 0);
        (skips, refreshing)
    }

    #[test]
    fn after_a_jump_the_processor_is_in_the_state_stepping_leaves() {
        let gold8 = MachineDesc::gold8();
        let refi =
            gold8.dram.refresh_interval as u64 * gold8.clocks.core_mhz / gold8.clocks.dram_mhz;
        let (mut skips, mut refreshing) = (0, 0);
        let mut run = |desc: &MachineDesc| {
            let (s, r) = compare(desc);
            skips += s;
            refreshing += r;
        };
        // Held kernels much longer than a refresh interval, and about as long.
        for min in [100_000, refi - 1, refi, refi + 1, 3 * refi + 7] {
            let mut desc = gold8.clone();
            desc.stream_controller.min_kernel_cycles = min;
            run(&desc);
        }
        // The shortest refresh interval allowed: jumps cross many refreshes and end in
        // every phase of one (some just as one is due).
        let mut desc = gold8.clone();
        desc.dram.refresh_interval = 4 * (desc.dram.t_rc + desc.dram.t_rfc);
        for k in 0..40 {
            desc.stream_controller.min_kernel_cycles = 20_000 + 37 * k;
            run(&desc);
        }
        assert!(skips >= 45 * BATCHES, "only {skips} jumps");
        assert!(refreshing > 0, "no jump ended on a refresh");
    }

    /// A tracer that keeps nothing.
    struct Discard;

    impl imagine_hdl::Tracer for Discard {
        fn start(
            &mut self,
            _: &imagine_hdl::ProbeRegistry,
            _: &[imagine_hdl::ClockDomain],
        ) -> std::io::Result<()> {
            Ok(())
        }
        fn time(&mut self, _: u64, _: u64) {}
        fn change(&mut self, _: imagine_hdl::SignalId, _: &[u64]) {}
        fn finish(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn nothing_is_skipped_with_a_tracer_or_when_stepping_is_asked_for() {
        let mut desc = MachineDesc::gold8();
        desc.stream_controller.min_kernel_cycles = 20_000;
        let (program, init) = program(&desc);
        let mut reports = Vec::new();
        for (step_idle, traced) in [(false, false), (true, false), (false, true)] {
            let opts = ProcessorOptions {
                dram_init: init.clone(),
                step_idle,
                on_start: traced.then(|| -> crate::runner::OnStart {
                    Box::new(|sim| sim.attach(Box::new(Discard)).map_err(|e| e.to_string()))
                }),
                ..ProcessorOptions::default()
            };
            let mut sim = build(&desc, program.clone(), opts).unwrap();
            // With the `probes` feature off a tracer is not kept, and the jump is allowed.
            let may_skip = !step_idle && sim.can_skip();
            let r = crate::processor::run(&mut sim, &desc, 10_000_000).unwrap();
            assert!(r.core_cycles > BATCHES as u64 * 20_000);
            assert_eq!(processor(&sim).skipped_cycles() > 0, may_skip);
            reports.push((r.core_cycles, r.records, state(&mut sim)));
        }
        for r in &reports[1..] {
            assert_eq!((r.0, &r.1), (reports[0].0, &reports[0].1));
            if let Some((a, b)) = r.2.lines().zip(reports[0].2.lines()).find(|(a, b)| a != b) {
                let at = a.bytes().zip(b.bytes()).take_while(|(x, y)| x == y).count();
                let cut = |l: &str| l[at.saturating_sub(300)..(at + 200).min(l.len())].to_string();
                panic!("state differs:\n{}\n{}", cut(a), cut(b));
            }
        }
    }
}
