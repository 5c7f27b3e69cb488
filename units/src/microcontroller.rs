//! The microcontroller (ARCHITECTURE §4): holds the kernel's microcode, sequences it one
//! VLIW instruction per cycle to every cluster, runs loops (counted, until a stream is
//! exhausted, until a condition code is set in every cluster) with no arbitrary branches,
//! and squashes the ops of software-pipeline stages that are not yet (prologue) or no
//! longer (epilogue) live.
//!
//! A loop body spans from the instruction whose [`Control`] `begin`s the loop (`kind`,
//! `stages: S`) to the matching `end`, which may be the same instruction (a one-instruction
//! body: an iteration, or a software-pipeline stage, every cycle). A loop is entered when its
//! first instruction is reached in sequence; reached by the loop's own back edge, it is not
//! entered again. For a loop of `N` iterations the body runs `N + S − 1` passes and an
//! op of stage `s` is live in pass `p` iff `s ≤ p < N + s` (Rau, "Iterative modulo
//! scheduling", 1994, kernel-only code with stage predicates). `N` is known on entry for
//! counted loops and for stream loops with `S > 1` (rows left in the stream); a stream loop
//! with `S = 1` instead tests "stream exhausted" at the end of every pass, which also serves
//! conditional streams; a condition loop tests its code at the end of every pass. A loop
//! whose first pass would do nothing (`N = 0`) is skipped.
//!
//! A body may hold several passes: a modulo-scheduled kernel unrolled `K` times for modulo
//! variable expansion (Lam, "Software pipelining", PLDI 1988), since there is no rotating
//! register file to rename long-lived values. Every instruction that ends a pass — `end`, or
//! `pass_end` inside the body — advances the pass counter and runs the loop's test: at
//! `end`, going on means back to the first instruction; at `pass_end`, the next pass is the
//! next instruction, and a loop that is done leaves there for the instruction after its
//! `end`. The squash rule is the same, on the same counter, so prologue and epilogue may
//! start or stop on any copy. A stream loop's words per pass are counted over its first
//! pass (the check makes every pass read as many).
//!
//! The cycle's decisions update the sequencer's state as they are made: nothing outside it
//! reads that state before the edge, so the edge has nothing to copy, and a fetch that a
//! stall discards is undone.

use imagine_hdl::{
    ContractError, Display, Scope, SignalId, SignalKind, Trace, Violation, bits_for,
};

use crate::microcode::{Control, Instruction, LoopBegin, LoopKind};

/// What the microcontroller needs to know about the rest of the machine to sequence a loop.
pub trait LoopEnv {
    /// Rows (`clusters` elements) left to read in kernel stream `stream`.
    fn rows_left(&self, stream: u16) -> u64;
    /// Whether every element of kernel stream `stream` has been read.
    fn exhausted(&self, stream: u16) -> bool;
    /// Whether condition code `cc` is set in every cluster.
    fn cc_all(&self, cc: u16) -> Result<bool, ContractError>;
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Frame {
    begin: u16,
    end: u16,
    kind: LoopKind,
    stages: u8,
    /// Iterations, when known on entry.
    iterations: Option<u64>,
    pass: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    Idle,
    Running,
    /// The `done` instruction has issued; results still in flight land.
    Finishing,
}

/// Sequencer state.
#[derive(Clone, Debug, PartialEq, Eq)]
struct State {
    phase: Phase,
    pc: u16,
    /// The instruction at `pc` was reached by a loop's back edge (its frame exists).
    looped_back: bool,
    frames: Vec<Frame>,
}

/// What a cycle's fetch changed, so that a stall can take it back. The state is updated in
/// place as the cycle decides (nothing outside the sequencer reads it before the edge), so
/// that a cycle does not copy the loop stack; a fetch discarded by a stall is undone.
#[derive(Clone, Copy, Debug)]
struct Undo {
    phase: Phase,
    pc: u16,
    looped_back: bool,
    /// The fetch entered a loop (pushed its frame).
    pushed: bool,
}

#[derive(Debug)]
pub struct Microcontroller {
    path: String,
    store_words: usize,
    loop_depth: usize,
    /// For each instruction that begins a loop, the index of the instruction that ends it
    /// (itself for a one-instruction body).
    loop_end: Vec<u16>,
    /// For each instruction that begins a stream loop, the words of its stream each pass
    /// reads per cluster (its unconditional reads of that stream, in the first pass: from
    /// the loop's first instruction to the first that ends a pass of it): a record of `k`
    /// words is `k` rows, so a software-pipelined loop runs `rows / k` iterations.
    rows_per_pass: Vec<u64>,
    state: State,
    /// Set by the first decision of a cycle, cleared at the edge.
    undo: Option<Undo>,
    probes: [SignalId; 5],
}

/// The ops of one instruction that are live this pass, by software-pipeline stage.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Liveness {
    /// Bit `s` set: ops of stage `s` are live.
    pub stages: u64,
}

impl Liveness {
    #[inline]
    pub fn live(self, stage: u8) -> bool {
        stage < 64 && self.stages & (1 << stage) != 0
    }
}

impl Microcontroller {
    pub fn new(scope: &mut Scope<'_>, store_words: usize, loop_depth: usize) -> Self {
        let mut s = scope.child("uc");
        let pc_bits = bits_for(store_words as u64);
        let probes = [
            s.signal("pc", pc_bits, SignalKind::Reg),
            s.signal_shown(
                "phase",
                2,
                SignalKind::Reg,
                Display::Names(&["idle", "running", "finishing"]),
            ),
            s.signal("loop_depth", bits_for(loop_depth as u64), SignalKind::Reg),
            s.signal("pass", 32, SignalKind::Reg),
            s.signal("iterations", 32, SignalKind::Reg),
        ];
        let idle = State {
            phase: Phase::Idle,
            pc: 0,
            looped_back: false,
            frames: Vec::with_capacity(loop_depth),
        };
        Microcontroller {
            path: s.path().to_string(),
            store_words,
            loop_depth,
            loop_end: Vec::new(),
            rows_per_pass: Vec::new(),
            state: idle,
            undo: None,
            probes,
        }
    }

    /// Loads a kernel's microcode and starts it at instruction 0. The code must have passed
    /// the microcode check (loops nested, one `done` at the end).
    pub fn start(&mut self, code: &[Instruction]) -> Result<(), ContractError> {
        if code.len() > self.store_words || code.is_empty() {
            return Err(ContractError::at(
                &format!("{}.store", self.path),
                Violation::Other(format!(
                    "{} instructions do not fit the microcode store of {}",
                    code.len(),
                    self.store_words
                )),
            ));
        }
        self.loop_end = vec![0; code.len()];
        // For each loop's first instruction, the last of its first pass.
        let mut first_pass_end = vec![0; code.len()];
        // Open loops: first instruction, and whether a pass of it has ended.
        let mut open: Vec<(usize, bool)> = Vec::new();
        for (i, inst) in code.iter().enumerate() {
            let ctl = inst.control;
            // Begin first: an instruction that begins and ends a loop (or a pass of one)
            // ends the loop it begins (or a pass of it).
            if ctl.begin.is_some() {
                open.push((i, false));
            }
            if ctl.pass_end && ctl.end {
                return Err(self.malformed(i, "`pass` and `end` on one instruction"));
            }
            if ctl.ends_pass() {
                let what = if ctl.end { "`end`" } else { "`pass`" };
                let (b, passed) = open
                    .last_mut()
                    .ok_or_else(|| self.malformed(i, &format!("{what} without a loop")))?;
                if !*passed {
                    *passed = true;
                    first_pass_end[*b] = i;
                }
            }
            if ctl.end {
                let (b, _) = open.pop().expect("an open loop, found above");
                self.loop_end[b] = i as u16;
            }
        }
        if let Some(&(b, _)) = open.first() {
            return Err(self.malformed(b, "loop without an end"));
        }
        self.rows_per_pass = vec![1; code.len()];
        for (b, inst) in code.iter().enumerate() {
            if let Some(LoopBegin {
                kind: LoopKind::UntilStreamEmpty(s),
                ..
            }) = inst.control.begin
            {
                let reads: usize = code[b..=first_pass_end[b]]
                    .iter()
                    .map(|i| i.unconditional_reads(s))
                    .sum();
                self.rows_per_pass[b] = reads.max(1) as u64;
            }
        }
        self.state.phase = Phase::Running;
        self.state.pc = 0;
        self.state.looped_back = false;
        self.state.frames.clear();
        self.undo = None;
        Ok(())
    }

    fn malformed(&self, at: usize, what: &str) -> ContractError {
        ContractError::at(
            &format!("{}.store", self.path),
            Violation::Other(format!("instruction {at}: {what}")),
        )
    }

    pub fn phase(&self) -> Phase {
        self.state.phase
    }

    pub fn pc(&self) -> u16 {
        self.state.pc
    }

    /// Decides this cycle's instruction: enters or skips loops starting at `pc`. Returns the
    /// instruction index to issue and which stages are live, or `None` if nothing issues.
    pub fn fetch(
        &mut self,
        code: &[Instruction],
        env: &impl LoopEnv,
    ) -> Result<Option<(u16, Liveness)>, ContractError> {
        self.prepare();
        if self.state.phase != Phase::Running {
            return Ok(None);
        }
        let mut pc = self.state.pc;
        // Enter loops that start here (a skipped loop may be followed by another).
        while let Some(LoopBegin { kind, stages }) = code[pc as usize].control.begin {
            // Reached by the back edge: the loop's frame exists (for a one-instruction body,
            // the instruction loops to itself).
            if self.state.looped_back {
                break;
            }
            if self.state.frames.len() == self.loop_depth {
                return Err(self.malformed(pc as usize, "loops nested deeper than the loop stack"));
            }
            let iterations = match kind {
                LoopKind::Counted(n) => Some(n as u64),
                LoopKind::UntilStreamEmpty(s) if stages > 1 => {
                    Some(env.rows_left(s).div_ceil(self.rows_per_pass[pc as usize]))
                }
                LoopKind::UntilStreamEmpty(s) if env.exhausted(s) => Some(0),
                LoopKind::UntilStreamEmpty(_) | LoopKind::UntilCc(_) => None,
            };
            let end = self.loop_end[pc as usize];
            if iterations == Some(0) {
                pc = end + 1;
                continue;
            }
            if let Some(u) = &mut self.undo {
                u.pushed = true;
            }
            self.state.frames.push(Frame {
                begin: pc,
                end,
                kind,
                stages: stages.max(1),
                iterations,
                pass: 0,
            });
            break;
        }
        self.state.pc = pc;
        let live = match self.state.frames.last() {
            Some(f) => {
                #[cfg(feature = "inject-bugs")]
                let f = &Frame {
                    iterations: f.iterations.map(|n| {
                        n + u64::from(imagine_hdl::inject::active(
                            imagine_hdl::inject::Bug::MicrocontrollerSquashesOneStageLate,
                        ))
                    }),
                    ..*f
                };
                let mut bits = 0u64;
                for s in 0..f.stages.min(64) as u64 {
                    let live = match f.iterations {
                        Some(n) => s <= f.pass && f.pass < n + s,
                        None => s == 0,
                    };
                    bits |= (live as u64) << s;
                }
                Liveness { stages: bits }
            }
            None => Liveness { stages: 1 },
        };
        Ok(Some((pc, live)))
    }

    /// Computes the next instruction after the one `fetch` returned has issued.
    pub fn advance(
        &mut self,
        code: &[Instruction],
        env: &impl LoopEnv,
    ) -> Result<(), ContractError> {
        let pc = self.state.pc;
        self.state.looped_back = false;
        let Control {
            end,
            pass_end,
            done,
            ..
        } = code[pc as usize].control;
        if done {
            self.state.phase = Phase::Finishing;
            return Ok(());
        }
        if end || pass_end {
            let f = self
                .state
                .frames
                .last_mut()
                .expect("an `end` or `pass` ends a pass of a frame");
            f.pass += 1;
            let again = match (f.kind, f.iterations) {
                (_, Some(n)) => f.pass < n + f.stages as u64 - 1,
                (LoopKind::UntilCc(cc), None) => !env.cc_all(cc)?,
                (LoopKind::UntilStreamEmpty(s), None) => !env.exhausted(s),
                (LoopKind::Counted(_), None) => {
                    unreachable!("counted loops know their iterations")
                }
            };
            if again && end {
                // Back to the first instruction (this one, for a one-instruction body).
                self.state.pc = f.begin;
                self.state.looped_back = true;
                return Ok(());
            }
            if !again {
                // Out of the loop, from its last instruction or from the middle of its body.
                let exit = f.end;
                self.state.frames.pop();
                self.state.pc = exit + 1;
                return Ok(());
            }
            // Going on at a `pass_end`: the next pass starts on the next instruction.
        }
        self.state.pc = pc + 1;
        Ok(())
    }

    /// The kernel has finished draining.
    pub fn finish(&mut self) {
        self.prepare();
        self.state.phase = Phase::Idle;
    }

    /// Forgets this cycle's decisions: the clusters stalled and nothing issued (called
    /// after `fetch`, before `advance`).
    pub fn discard(&mut self) {
        if let Some(u) = self.undo.take() {
            self.state.phase = u.phase;
            self.state.pc = u.pc;
            self.state.looped_back = u.looped_back;
            if u.pushed {
                self.state.frames.pop();
            }
        }
    }

    /// Notes the state as it was before this cycle's first decision.
    fn prepare(&mut self) {
        if self.undo.is_none() {
            self.undo = Some(Undo {
                phase: self.state.phase,
                pc: self.state.pc,
                looped_back: self.state.looped_back,
                pushed: false,
            });
        }
    }

    /// The edge: the decisions of this cycle stand. A cycle in which the fetch was
    /// discarded (a stall) leaves the state as it was.
    pub fn commit(&mut self) {
        self.undo = None;
    }

    pub fn trace(&self, t: &mut Trace) {
        let [pc, phase, depth, pass, iterations] = self.probes;
        t.value(pc, self.state.pc as u64);
        t.value(phase, self.state.phase as u64);
        t.value(depth, self.state.frames.len() as u64);
        let top = self.state.frames.last();
        t.value(pass, top.map_or(0, |f| f.pass & 0xFFFF_FFFF));
        t.value(
            iterations,
            top.and_then(|f| f.iterations)
                .map_or(0, |n| n & 0xFFFF_FFFF),
        );
    }
}
