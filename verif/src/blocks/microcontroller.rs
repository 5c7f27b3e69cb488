//! Testbench of the microcontroller (`units::microcontroller`): random legal kernels —
//! counted, stream and condition loops nested up to the loop stack, one-instruction bodies,
//! bodies of several passes, software-pipeline stages on their ops, programs filling the
//! microcode store — sequenced cycle by cycle against a mock of the rest of the machine
//! whose stream words and condition codes change as the bench decides: a live read takes a
//! row of its stream (a conditional one a random part of a row), condition codes change at
//! every edge, and the clusters stall now and then (the fetch is discarded). Malformed and
//! oversized programs, and loops nested deeper than the stack, must be refused.
//!
//! Reference, from the definition of the sequencing: the program is parsed into loops of
//! passes; a loop reached in sequence is entered with `N` iterations (counted: its count;
//! stream with `S > 1`: the stream's rows over the words one pass reads, rounded up; stream
//! with `S = 1` and condition loops: not known), or skipped, in no cycle, when `N = 0` (a
//! stream with `S = 1` already exhausted). A loop of `N` iterations runs `N + S − 1` passes,
//! a loop without a known `N` until the test at the end of a pass says stop (the stream
//! exhausted, the condition code set in every cluster); pass `p` runs the body's passes in
//! turn, leaving from whichever ends the last, and an op of stage `s` is live in it iff
//! `s ≤ p < N + s`. Outside loops stage 0 is live. A loop reached with the loop stack full
//! is refused, and `start` refuses an empty or oversized program, a `pass_end` or `end`
//! outside every loop, `pass_end` with `end`, and a loop without its `end`.
//!
//! The bench runs the reference first, recording what the machine answers at each fetch
//! and after each issue, then replays those answers to the block and checks every cycle's
//! instruction and live stages, the phase after each edge, and the cycles to `done`.

use std::fmt;

use imagine_hdl::ContractError;
use imagine_units::desc::MachineDesc;
use imagine_units::microcode::{
    Control, ImmValue, Immediate, Instruction, LoopBegin, LoopKind, MAX_STAGES, Program,
    StreamDecl, StreamDir, StreamIn,
};
use imagine_units::microcontroller::{LoopEnv, Microcontroller, Phase};

use super::{BlockClock, Config, Coverage, Outcome, Rng, Scoreboard, Waves, design};

const BINS: &[&str] = &[
    "counted loop",
    "counted loop of 0 iterations skipped",
    "counted loop of 1 iteration",
    "stream loop, 1 stage: left when the stream is exhausted",
    "stream loop, 1 stage, on conditional reads only",
    "stream loop, S > 1: iterations from the rows left",
    "stream loop, S > 1: rows not a multiple of a pass's words",
    "stream loop on an exhausted stream skipped",
    "condition loop",
    "condition loop left after its first pass",
    "loops nested to the full loop stack",
    "one-instruction body",
    "body of several passes (pass_end)",
    "first pass is the begin instruction alone",
    "loop left at a pass_end, mid-body",
    "prologue squash",
    "epilogue squash",
    "fewer iterations than stages",
    "most stages a loop may have",
    "loop entered again after it was left",
    "two loops skipped in one cycle",
    "stall (fetch discarded)",
    "stall on a loop's first instruction",
    "program filling the microcode store",
    "program too large refused",
    "malformed program refused",
    "loops nested deeper than the loop stack refused",
];

/// Input streams the kernels read (`a`, `b`).
const STREAMS: usize = 2;
/// Condition codes the kernels use, at most.
const CCS: u16 = 4;
/// Cycles after which the bench stops a kernel's run (its generator keeps far below).
const CYCLE_CAP: usize = 50_000;
/// The largest microcode store the bench fills (and overfills): a kernel as long as the
/// store runs at least as many cycles.
const FILL_MOST: usize = 16_384;

// ---- the rest of the machine ------------------------------------------------------------

/// What the rest of the machine answers the microcontroller: the words left in each input
/// stream and which condition codes are set in every cluster.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct World {
    words: [u64; STREAMS],
    cc_all: u16,
}

impl World {
    fn rows(&self, stream: u16, lanes: u64) -> u64 {
        self.words[usize::from(stream)].div_ceil(lanes)
    }

    fn exhausted(&self, stream: u16) -> bool {
        self.words[usize::from(stream)] == 0
    }

    fn cc(&self, cc: u16) -> bool {
        self.cc_all >> cc & 1 != 0
    }
}

/// The mock [`LoopEnv`] the block sees: one recorded [`World`] at a time.
struct Env {
    world: World,
    lanes: u64,
}

impl LoopEnv for Env {
    fn rows_left(&self, stream: u16) -> u64 {
        self.world.rows(stream, self.lanes)
    }

    fn exhausted(&self, stream: u16) -> bool {
        self.world.exhausted(stream)
    }

    fn cc_all(&self, cc: u16) -> Result<bool, ContractError> {
        Ok(self.world.cc(cc))
    }
}

/// How the bench moves the world during one kernel.
struct Bench {
    lanes: u64,
    ccs: u16,
    /// Chance in percent that a fetch is discarded (the clusters stall).
    stall: u64,
    /// Chance in percent that a condition code is set in every cluster after an edge.
    cc_set: u64,
}

impl Bench {
    /// Words a live conditional read takes: biased to none and to a whole row.
    fn conditional_words(&self, rng: &mut Rng) -> u64 {
        match rng.below(10) {
            0 | 1 => 0,
            2..=4 => self.lanes,
            _ => 1 + rng.below(self.lanes),
        }
    }

    fn edge(&self, rng: &mut Rng, world: &mut World) {
        world.cc_all = (0..self.ccs)
            .filter(|_| rng.chance(self.cc_set))
            .fold(0, |bits, cc| bits | 1 << cc);
    }
}

// ---- stimulus: random legal programs ----------------------------------------------------

/// A program as the generator builds it: instructions and loops of passes.
enum Item {
    Inst(Instruction),
    Loop(GenLoop),
}

struct GenLoop {
    kind: LoopKind,
    stages: u8,
    /// Each pass's items; a pass starts (the first: with the loop's first instruction) and
    /// ends on an instruction of its own.
    passes: Vec<Vec<Item>>,
}

/// Instructions `items` take in the store.
fn size(items: &[Item]) -> usize {
    items
        .iter()
        .map(|i| match i {
            Item::Inst(_) => 1,
            Item::Loop(l) => l.passes.iter().map(|p| size(p)).sum(),
        })
        .sum()
}

/// Lays `items` out in `code`, marking each loop's first instruction, pass ends and end.
fn flatten(items: Vec<Item>, code: &mut Vec<Instruction>) {
    for item in items {
        match item {
            Item::Inst(i) => code.push(i),
            Item::Loop(l) => {
                let first = code.len();
                let passes = l.passes.len();
                for (k, pass) in l.passes.into_iter().enumerate() {
                    flatten(pass, code);
                    let last = code.last_mut().expect("a pass has an instruction");
                    if k + 1 == passes {
                        last.control.end = true;
                    } else {
                        last.control.pass_end = true;
                    }
                }
                code[first].control.begin = Some(LoopBegin {
                    kind: l.kind,
                    stages: l.stages,
                });
            }
        }
    }
}

struct Gen<'a> {
    rng: &'a mut Rng,
    desc: &'a MachineDesc,
    /// An instruction shaped for the machine, every slot empty.
    nop: &'a Instruction,
    ccs: u16,
    /// A conditional stream read fits an instruction.
    conditional: bool,
    /// Instructions the program may still grow by (loops stop nesting when it runs out).
    space: usize,
    /// Deepest nesting level a loop may have (1: outermost).
    max_level: usize,
}

impl Gen<'_> {
    /// A slot's stage in a loop of `stages`: biased to the first and the last.
    fn stage(&mut self, stages: u8) -> u8 {
        match self.rng.below(4) {
            0 | 1 => 0,
            2 => stages - 1,
            _ => self.rng.below(u64::from(stages)) as u8,
        }
    }

    /// An instruction of a loop of `stages` (1 outside loops): sometimes an immediate and a
    /// stream read (in the last `sin` slot) on random stages; unconditional reads only of
    /// streams not in `forbid` (those whose loops count their reads).
    fn inst(&mut self, stages: u8, forbid: u8) -> Instruction {
        self.space = self.space.saturating_sub(1);
        let mut ins = self.nop.clone();
        if self.rng.chance(50) {
            ins.imm = Some(Immediate {
                value: ImmValue::Const(self.rng.word()),
                dests: [None; 2],
                stage: self.stage(stages),
            });
        }
        if !ins.sin.is_empty() && self.rng.chance(35) {
            let stream = self.rng.index(STREAMS) as u16;
            let counted = forbid & 1 << stream != 0;
            let cond = if self.conditional && (counted || self.rng.chance(30)) {
                Some(self.rng.below(u64::from(self.ccs)) as u16)
            } else {
                None
            };
            if cond.is_some() || !counted {
                let last = ins.sin.len() - 1;
                ins.sin[last] = Some(StreamIn {
                    stream,
                    cond,
                    dests: [None; 2],
                    stage: self.stage(stages),
                });
            }
        }
        ins
    }

    /// A loop at nesting `level` whose runs may take about `budget` cycles; `chain` > 0
    /// nests a loop in it, and so on, `chain` loops deep, each always entered.
    fn looped(&mut self, level: usize, chain: usize, forbid: u8, budget: u64) -> GenLoop {
        let free: Vec<u16> = (0..STREAMS as u16)
            .filter(|&s| forbid & 1 << s == 0)
            .collect();
        let cc = |g: &mut Self| LoopKind::UntilCc(g.rng.below(u64::from(g.ccs)) as u16);
        // A counted loop gets its count once its stages are known.
        let kind = match self.rng.below(10) {
            _ if chain > 0 && self.ccs > 0 && budget >= 12 && self.rng.chance(25) => cc(self),
            _ if chain > 0 => LoopKind::Counted(1),
            0..=4 => LoopKind::Counted(0),
            5..=7 if !free.is_empty() && self.desc.srf.cluster_words_per_cycle > 0 => {
                LoopKind::UntilStreamEmpty(self.rng.pick(&free))
            }
            _ if self.ccs > 0 => cc(self),
            _ => LoopKind::Counted(0),
        };
        // Keep the passes within the budget, three cycles a pass at least.
        let most_stages = (budget / 3).clamp(1, u64::from(MAX_STAGES)) as u8;
        let stages = match (kind, self.rng.below(10)) {
            (LoopKind::UntilCc(_), _) => 1,
            (_, 0..=4) => 1,
            (_, 5 | 6) => 2 + self.rng.below(2) as u8,
            (_, 7) => MAX_STAGES,
            _ => 2 + self.rng.below(u64::from(MAX_STAGES) - 1) as u8,
        }
        .min(most_stages);
        let s = u32::from(stages);
        let most = (budget / 3).saturating_sub(u64::from(s) - 1).max(1) as u32;
        let kind = match kind {
            // The loops of a chain are always entered.
            LoopKind::Counted(_) if chain > 0 => {
                LoopKind::Counted((1 + self.rng.below(3) as u32).min(most))
            }
            LoopKind::Counted(_) => LoopKind::Counted(
                match self.rng.below(12) {
                    0 => 0,
                    1 | 2 => 1,
                    3 => s - 1,
                    4 => s,
                    5 => s + 1,
                    6 => 20 + self.rng.below(30) as u32,
                    _ => 2 + self.rng.below(6) as u32,
                }
                .min(most),
            ),
            k => k,
        };
        let passes_guess = match kind {
            LoopKind::Counted(n) => u64::from(n + s - 1),
            LoopKind::UntilStreamEmpty(_) => 8 + u64::from(s),
            LoopKind::UntilCc(_) => 3,
        }
        .max(1);
        let per_pass = budget / passes_guess;
        let inner = match kind {
            LoopKind::UntilStreamEmpty(st) => forbid | 1 << st,
            _ => forbid,
        };
        let copies = if self.rng.chance(60) {
            1
        } else {
            2 + self.rng.index(3)
        };
        let mut passes = Vec::with_capacity(copies);
        for copy in 0..copies {
            let mut pass = Vec::new();
            if copy == 0 {
                pass.push(Item::Inst(self.inst(stages, inner)));
            }
            let alone = !(copy == 0 && chain > 1) && self.rng.chance(30);
            if !alone {
                let middle = self.rng.index(3);
                let chain_at = (copy == 0 && chain > 1).then(|| self.rng.index(middle + 1));
                for m in 0..=middle {
                    if chain_at == Some(m) {
                        let l = self.looped(level + 1, chain - 1, inner, per_pass / 2);
                        pass.push(Item::Loop(l));
                    }
                    if m < middle {
                        let nest = chain == 0
                            && level < self.max_level
                            && per_pass >= 12
                            && self.space > 4
                            && self.rng.chance(35);
                        pass.push(if nest {
                            Item::Loop(self.looped(level + 1, 0, inner, per_pass / 2))
                        } else {
                            Item::Inst(self.inst(stages, inner))
                        });
                    }
                }
            }
            if copy > 0 || !alone {
                pass.push(Item::Inst(self.inst(stages, inner)));
            }
            passes.push(pass);
        }
        if let LoopKind::UntilStreamEmpty(st) = kind {
            self.stream_reads(st, stages, &mut passes);
        }
        GenLoop {
            kind,
            stages,
            passes,
        }
    }

    /// Gives every pass of a loop over `stream` the same number of unconditional reads of
    /// it, in the pass's own instructions (the `sin` slots from the first); a loop of one
    /// stage reads at least one word a pass, or reads conditionally only.
    fn stream_reads(&mut self, stream: u16, stages: u8, passes: &mut [Vec<Item>]) {
        let slots = self.desc.srf.cluster_words_per_cycle;
        let conditional_only = stages == 1 && self.conditional && self.rng.chance(20);
        let want = match self.rng.below(4) {
            _ if conditional_only => 0,
            0 if stages > 1 => 0,
            0 | 1 => 1,
            2 => 2,
            _ => 3,
        };
        let own = |p: &[Item]| p.iter().filter(|i| matches!(i, Item::Inst(_))).count();
        let room = passes.iter().map(|p| own(p) * slots).min().unwrap_or(0);
        let reads = want.min(room);
        for pass in passes.iter_mut() {
            let mut used = vec![0usize; own(pass)];
            for _ in 0..reads {
                let open: Vec<usize> = (0..used.len()).filter(|&j| used[j] < slots).collect();
                let j = self.rng.pick(&open);
                let stage = self.stage(stages);
                let ins = own_inst(pass, j);
                ins.sin[used[j]] = Some(StreamIn {
                    stream,
                    cond: None,
                    dests: [None; 2],
                    stage,
                });
                used[j] += 1;
            }
            if conditional_only {
                let j = self.rng.index(used.len());
                let cond = Some(self.rng.below(u64::from(self.ccs)) as u16);
                let ins = own_inst(pass, j);
                let last = ins.sin.len() - 1;
                ins.sin[last] = Some(StreamIn {
                    stream,
                    cond,
                    dests: [None; 2],
                    stage: 0,
                });
            }
        }
    }

    /// A kernel: a few instructions and loops (one of them `chain` loops deep), then `done`.
    fn kernel(&mut self, chain: usize, budget: u64) -> Vec<Item> {
        let n = 1 + self.rng.index(4);
        let chain_at = self.rng.index(n);
        let mut items = Vec::with_capacity(n + 1);
        for k in 0..n {
            items.push(if chain > 0 && k == chain_at {
                Item::Loop(self.looped(1, chain, 0, budget / 2))
            } else if self.space > 2 && self.rng.chance(60) {
                Item::Loop(self.looped(1, 0, 0, budget / n as u64))
            } else {
                Item::Inst(self.inst(1, 0))
            });
        }
        let mut done = self.nop.clone();
        done.control = Control::DONE;
        items.push(Item::Inst(done));
        items
    }

    /// Pads a kernel with `nops` empty instructions outside its loops, in a few blocks.
    fn pad(&mut self, items: &mut Vec<Item>, mut nops: usize) {
        while nops > 0 {
            let n = if nops < 8 || self.rng.chance(40) {
                nops
            } else {
                1 + self.rng.index(nops)
            };
            let at = self.rng.index(items.len());
            let block = (0..n).map(|_| Item::Inst(self.nop.clone()));
            items.splice(at..at, block);
            nops -= n;
        }
    }
}

/// The `j`th instruction of `pass` that is not in a nested loop.
fn own_inst(pass: &mut [Item], j: usize) -> &mut Instruction {
    pass.iter_mut()
        .filter_map(|i| match i {
            Item::Inst(ins) => Some(ins),
            Item::Loop(_) => None,
        })
        .nth(j)
        .expect("an instruction of the pass")
}

/// Breaks a legal program in one of the ways the block must refuse: no instructions, a
/// `pass_end` or an `end` outside every loop, a loop without its `end`, `pass_end` with
/// `end`.
fn malform(rng: &mut Rng, code: &mut Vec<Instruction>) {
    let ends: Vec<usize> = (0..code.len()).filter(|&i| code[i].control.end).collect();
    // Where an instruction would be outside every loop.
    let mut outside = Vec::new();
    let mut depth = 0usize;
    for (i, ins) in code.iter().enumerate() {
        if depth == 0 {
            outside.push(i);
        }
        depth += usize::from(ins.control.begin.is_some());
        depth -= usize::from(ins.control.end);
    }
    match rng.below(5) {
        0 => code.clear(),
        3 if !ends.is_empty() => code[rng.pick(&ends)].control.end = false,
        4 if !ends.is_empty() => code[rng.pick(&ends)].control.pass_end = true,
        k => {
            let at = rng.pick(&outside);
            let mut stray = code[at].clone();
            stray.control = if k == 1 {
                Control::END
            } else {
                Control::PASS_END
            };
            code.insert(at, stray);
        }
    }
}

// ---- reference model ---------------------------------------------------------------------

/// The program as the reference reads it: instructions and loops of passes.
enum Node {
    Inst(u16),
    Loop(Loop),
}

struct Loop {
    begin: u16,
    kind: LoopKind,
    stages: u8,
    passes: Vec<Vec<Node>>,
    /// Unconditional words of the loop's stream its first pass reads (nested loops'
    /// instructions counted once).
    words: u64,
}

/// Why a program is refused before it runs.
#[derive(Debug)]
enum Refusal {
    Empty,
    TooLarge,
    PassAndEnd,
    OutsideLoops,
    Unclosed,
}

/// Parses a program: loops nested, each pass of a loop ending on an instruction of its
/// own, `pass_end` and `end` never together and never outside a loop.
fn parse(code: &[Instruction], store: usize) -> Result<Vec<Node>, Refusal> {
    if code.is_empty() {
        return Err(Refusal::Empty);
    }
    if code.len() > store {
        return Err(Refusal::TooLarge);
    }
    let mut nodes = Vec::new();
    let mut at = 0;
    while at < code.len() {
        let c = code[at].control;
        if c.begin.is_some() {
            nodes.push(Node::Loop(parse_loop(code, &mut at)?));
        } else if c.end || c.pass_end {
            return Err(if c.end && c.pass_end {
                Refusal::PassAndEnd
            } else {
                Refusal::OutsideLoops
            });
        } else {
            nodes.push(Node::Inst(at as u16));
            at += 1;
        }
    }
    Ok(nodes)
}

/// The loop beginning at `*at`; leaves `*at` after its `end`.
fn parse_loop(code: &[Instruction], at: &mut usize) -> Result<Loop, Refusal> {
    let begin = *at;
    let LoopBegin { kind, stages } = code[begin].control.begin.expect("a loop's first");
    let mut passes = Vec::new();
    let mut pass = Vec::new();
    let mut i = begin;
    loop {
        let c = code.get(i).ok_or(Refusal::Unclosed)?.control;
        if c.end && c.pass_end {
            return Err(Refusal::PassAndEnd);
        }
        if c.begin.is_some() && i != begin {
            pass.push(Node::Loop(parse_loop(code, &mut i)?));
            continue;
        }
        pass.push(Node::Inst(i as u16));
        i += 1;
        if c.end || c.pass_end {
            passes.push(std::mem::take(&mut pass));
        }
        if c.end {
            break;
        }
    }
    *at = i;
    let mut words = 0;
    if let LoopKind::UntilStreamEmpty(s) = kind {
        count_reads(&passes[0], code, s, &mut words);
    }
    Ok(Loop {
        begin: begin as u16,
        kind,
        stages,
        passes,
        words,
    })
}

fn count_reads(nodes: &[Node], code: &[Instruction], stream: u16, words: &mut u64) {
    for n in nodes {
        match n {
            Node::Inst(i) => {
                *words += code[usize::from(*i)]
                    .sin
                    .iter()
                    .flatten()
                    .filter(|r| r.stream == stream && r.cond.is_none())
                    .count() as u64;
            }
            Node::Loop(l) => l
                .passes
                .iter()
                .for_each(|p| count_reads(p, code, stream, words)),
        }
    }
}

/// Which pass of which loop an instruction issues in.
#[derive(Clone, Copy)]
struct Pass {
    pass: u64,
    /// Iterations, when known on entry.
    iterations: Option<u64>,
    stages: u8,
}

impl Pass {
    /// Outside every loop: stage 0, always live.
    const OUTSIDE: Pass = Pass {
        pass: 0,
        iterations: Some(1),
        stages: 1,
    };

    fn live(self, stage: u8) -> bool {
        stage < self.stages
            && match self.iterations {
                Some(n) => u64::from(stage) <= self.pass && self.pass < n + u64::from(stage),
                // Not known in advance: a loop of one stage, live in every pass.
                None => true,
            }
    }

    fn live_stages(self) -> u64 {
        (0..self.stages)
            .filter(|&s| self.live(s))
            .fold(0, |bits, s| bits | 1 << s)
    }
}

/// One cycle as the reference sees it: what issues (or is fetched and discarded) and what
/// the machine answers at the fetch and after the issue.
#[derive(Clone, Copy)]
struct Cycle {
    pc: u16,
    live: u64,
    stall: bool,
    fetch: World,
    issue: World,
}

/// How a kernel's run ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stop {
    /// `done` issued (the last cycle recorded).
    Done,
    /// A loop reached with the loop stack full: the next fetch is refused.
    TooDeep,
    /// The bench's cycle cap.
    Cap,
}

struct Reference<'a> {
    code: &'a [Instruction],
    loop_depth: usize,
    depth: usize,
    world: World,
    /// An instruction issued and its edge has not yet changed the condition codes.
    edge: bool,
    bench: &'a Bench,
    rng: &'a mut Rng,
    cov: &'a mut Coverage,
    trace: &'a mut Vec<Cycle>,
    /// Times each loop (by first instruction) was entered.
    entries: Vec<u32>,
    /// Loops skipped since the last issue.
    skipped: u32,
    /// The next fetch enters a loop.
    entering: bool,
}

impl Reference<'_> {
    fn run(&mut self, nodes: &[Node], pass: Pass) -> Result<(), Stop> {
        for n in nodes {
            match n {
                Node::Inst(pc) => {
                    self.issue(*pc, pass)?;
                    if self.code[usize::from(*pc)].control.done {
                        return Err(Stop::Done);
                    }
                }
                Node::Loop(l) => self.run_loop(l)?,
            }
        }
        Ok(())
    }

    fn run_loop(&mut self, l: &Loop) -> Result<(), Stop> {
        if self.depth == self.loop_depth {
            self.cov
                .hit("loops nested deeper than the loop stack refused");
            return Err(Stop::TooDeep);
        }
        let lanes = self.bench.lanes;
        let iterations = match l.kind {
            LoopKind::Counted(n) => Some(u64::from(n)),
            LoopKind::UntilStreamEmpty(s) if l.stages > 1 => {
                // A pass that reads no word of the stream unconditionally counts as one.
                let per_pass = l.words.max(1);
                let rows = self.world.rows(s, lanes);
                self.cov.hit_if(
                    rows > 0 && per_pass > 1 && !rows.is_multiple_of(per_pass),
                    "stream loop, S > 1: rows not a multiple of a pass's words",
                );
                Some(rows.div_ceil(per_pass))
            }
            LoopKind::UntilStreamEmpty(s) if self.world.exhausted(s) => Some(0),
            LoopKind::UntilStreamEmpty(_) | LoopKind::UntilCc(_) => None,
        };
        let cov = &mut *self.cov;
        match l.kind {
            LoopKind::Counted(n) => {
                cov.hit("counted loop");
                cov.hit_if(n == 0, "counted loop of 0 iterations skipped");
                cov.hit_if(n == 1, "counted loop of 1 iteration");
            }
            LoopKind::UntilStreamEmpty(_) => {
                cov.hit_if(
                    iterations == Some(0),
                    "stream loop on an exhausted stream skipped",
                );
                cov.hit_if(
                    l.stages > 1 && iterations > Some(0),
                    "stream loop, S > 1: iterations from the rows left",
                );
                cov.hit_if(
                    l.stages == 1 && l.words == 0 && iterations.is_none(),
                    "stream loop, 1 stage, on conditional reads only",
                );
            }
            LoopKind::UntilCc(_) => cov.hit("condition loop"),
        }
        if iterations == Some(0) {
            self.skipped += 1;
            cov.hit_if(self.skipped == 2, "two loops skipped in one cycle");
            return Ok(());
        }
        let begin = usize::from(l.begin);
        cov.hit_if(
            self.entries[begin] > 0,
            "loop entered again after it was left",
        );
        cov.hit_if(
            self.depth + 1 == self.loop_depth,
            "loops nested to the full loop stack",
        );
        cov.hit_if(
            l.passes.len() == 1 && l.passes[0].len() == 1,
            "one-instruction body",
        );
        cov.hit_if(l.passes.len() > 1, "body of several passes (pass_end)");
        cov.hit_if(
            l.passes.len() > 1 && l.passes[0].len() == 1,
            "first pass is the begin instruction alone",
        );
        cov.hit_if(
            iterations.is_some_and(|n| n < u64::from(l.stages)),
            "fewer iterations than stages",
        );
        cov.hit_if(l.stages == MAX_STAGES, "most stages a loop may have");
        self.entries[begin] += 1;
        self.depth += 1;
        self.entering = true;
        let total = iterations.map(|n| n + u64::from(l.stages) - 1);
        let mut pass = 0;
        'passes: loop {
            for (k, body) in l.passes.iter().enumerate() {
                let p = Pass {
                    pass,
                    iterations,
                    stages: l.stages,
                };
                self.run(body, p)?;
                pass += 1;
                // The test at the end of the pass sees the world after its last issue.
                let again = match (total, l.kind) {
                    (Some(total), _) => pass < total,
                    (None, LoopKind::UntilCc(cc)) => {
                        self.cov.hit_if(
                            pass == 1 && self.world.cc(cc),
                            "condition loop left after its first pass",
                        );
                        !self.world.cc(cc)
                    }
                    (None, LoopKind::UntilStreamEmpty(s)) => {
                        let exhausted = self.world.exhausted(s);
                        self.cov.hit_if(
                            exhausted,
                            "stream loop, 1 stage: left when the stream is exhausted",
                        );
                        !exhausted
                    }
                    (None, LoopKind::Counted(_)) => unreachable!("counted loops know N"),
                };
                if !again {
                    self.cov
                        .hit_if(k + 1 < l.passes.len(), "loop left at a pass_end, mid-body");
                    break 'passes;
                }
            }
        }
        self.depth -= 1;
        Ok(())
    }

    /// One instruction issues: stalls first, maybe; its live reads take their words.
    fn issue(&mut self, pc: u16, pass: Pass) -> Result<(), Stop> {
        if self.trace.len() >= CYCLE_CAP {
            return Err(Stop::Cap);
        }
        if std::mem::take(&mut self.edge) {
            self.bench.edge(self.rng, &mut self.world);
        }
        let live = pass.live_stages();
        while self.bench.stall > 0 && self.rng.chance(self.bench.stall) {
            self.cov.hit("stall (fetch discarded)");
            self.cov
                .hit_if(self.entering, "stall on a loop's first instruction");
            self.trace.push(Cycle {
                pc,
                live,
                stall: true,
                fetch: self.world,
                issue: self.world,
            });
        }
        let fetch = self.world;
        let ins = &self.code[usize::from(pc)];
        for r in ins.sin.iter().flatten() {
            if !pass.live(r.stage) {
                continue;
            }
            let words = match r.cond {
                None => self.bench.lanes,
                Some(_) => self.bench.conditional_words(self.rng),
            };
            let w = &mut self.world.words[usize::from(r.stream)];
            *w = w.saturating_sub(words);
        }
        let stages = ins
            .sin
            .iter()
            .flatten()
            .map(|r| r.stage)
            .chain(ins.imm.map(|i| i.stage));
        for s in stages {
            if !pass.live(s) {
                let prologue = pass.pass < u64::from(s);
                self.cov.hit_if(prologue, "prologue squash");
                self.cov.hit_if(!prologue, "epilogue squash");
            }
        }
        self.trace.push(Cycle {
            pc,
            live,
            stall: false,
            fetch,
            issue: self.world,
        });
        self.edge = true;
        self.entering = false;
        self.skipped = 0;
        Ok(())
    }
}

// ---- checking ------------------------------------------------------------------------------

/// What a fetch gives, as the scoreboard prints it.
#[derive(Clone, PartialEq, Eq)]
enum Fetched {
    Issue { pc: u16, live: u64 },
    Nothing,
    Refused(String),
}

impl fmt::Debug for Fetched {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Fetched::Issue { pc, live } => {
                let stages: Vec<u32> = (0..64).filter(|s| live >> s & 1 != 0).collect();
                write!(f, "instruction {pc}, live stages {stages:?}")
            }
            Fetched::Nothing => write!(f, "nothing"),
            Fetched::Refused(e) => write!(f, "refused: {e}"),
        }
    }
}

/// The block's fetch as a [`Fetched`].
fn fetch(uc: &mut Microcontroller, code: &[Instruction], env: &Env) -> Fetched {
    match uc.fetch(code, env) {
        Ok(Some((pc, live))) => Fetched::Issue {
            pc,
            live: live.stages,
        },
        Ok(None) => Fetched::Nothing,
        Err(e) => Fetched::Refused(e.to_string()),
    }
}

/// What kind of kernel a transaction drives.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Shape {
    Ordinary,
    FullDepth,
    FillStore,
    TooLarge,
    Malformed,
    TooDeep,
}

/// Replays the reference's `trace` to the block: every fetch's instruction and live
/// stages, the phase after every edge, and the end of the run.
#[allow(clippy::too_many_arguments)]
fn replay(
    uc: &mut Microcontroller,
    code: &[Instruction],
    trace: &[Cycle],
    stop: Stop,
    last: World,
    lanes: u64,
    kernel: u64,
    cycle: &mut u64,
    sb: &mut Scoreboard,
    waves: &mut Waves,
) {
    let mut env = Env {
        world: World::default(),
        lanes,
    };
    // Cycles the block spends running the kernel, stalls included.
    let mut ran = 0usize;
    for (t, c) in trace.iter().enumerate() {
        let now = *cycle;
        *cycle += 1;
        ran += usize::from(uc.phase() == Phase::Running);
        env.world = c.fetch;
        let want = Fetched::Issue {
            pc: c.pc,
            live: c.live,
        };
        let got = fetch(uc, code, &env);
        let agree = want == got;
        sb.check(
            now,
            || {
                format!(
                    "kernel {kernel}, cycle {t} of its run: instruction fetched and its live stages"
                )
            },
            want,
            got,
        );
        if !agree {
            return;
        }
        if c.stall {
            uc.discard();
            uc.commit();
            waves.cycle(now, |t| uc.trace(t));
            continue;
        }
        env.world = c.issue;
        let got = uc.advance(code, &env).map_err(|e| e.to_string());
        let agree = got.is_ok();
        sb.check(
            now,
            || {
                format!(
                    "kernel {kernel}, cycle {t} of its run: instruction {} issued",
                    c.pc
                )
            },
            Ok(()),
            got,
        );
        uc.commit();
        waves.cycle(now, |t| uc.trace(t));
        let done = code[usize::from(c.pc)].control.done;
        let want = if done {
            Phase::Finishing
        } else {
            Phase::Running
        };
        let phase = uc.phase();
        sb.check(
            now,
            || format!("kernel {kernel}, cycle {t} of its run: phase after the edge"),
            want,
            phase,
        );
        if !agree || phase != want {
            return;
        }
    }
    env.world = last;
    match stop {
        Stop::Done => {
            sb.check(
                *cycle,
                || format!("kernel {kernel}: cycles to `done`, stalls included"),
                trace.len(),
                ran,
            );
            sb.check(
                *cycle,
                || format!("kernel {kernel}: nothing fetched after `done`"),
                Fetched::Nothing,
                fetch(uc, code, &env),
            );
            uc.finish();
            uc.commit();
            sb.check(
                *cycle,
                || format!("kernel {kernel}: idle once finished"),
                Phase::Idle,
                uc.phase(),
            );
        }
        Stop::TooDeep => {
            let refused = matches!(fetch(uc, code, &env), Fetched::Refused(_));
            sb.assert(*cycle, refused, || {
                format!("kernel {kernel}: a loop nested deeper than the loop stack refused")
            });
        }
        Stop::Cap => {}
    }
}

pub fn run(desc: &MachineDesc, config: &Config) -> Outcome {
    let lanes = desc.cluster.count as u64;
    let store = desc.microcontroller.store_words;
    let loop_depth = desc.microcontroller.loop_depth;
    let ccs = CCS.min(desc.cluster.condition_codes as u16);
    let conditional = ccs > 0 && desc.srf.conditional_words_per_cycle > 0;
    let mut rng = Rng::new(config.seed);
    let mut sb = Scoreboard::default();
    let mut cov = Coverage::new(BINS);
    let mut d = design();
    let mut uc = Microcontroller::new(&mut d.scope(), store, loop_depth);
    let mut waves = Waves::new(d.probes(), desc, BlockClock::Core, config);
    let streams = ["a", "b"].map(|name| StreamDecl {
        name: name.into(),
        dir: StreamDir::In,
    });
    let nop = Instruction::empty(desc);
    let mut trace = Vec::new();
    let mut cycle = 0u64;
    let mut kernel = 0u64;
    while sb.transactions < config.transactions {
        sb.transaction();
        kernel += 1;
        let shape = match rng.below(100) {
            // A store too large to fill in a moment gets none of these.
            0..=4 if store > FILL_MOST => Shape::Ordinary,
            0..=2 => Shape::FillStore,
            3 | 4 => Shape::TooLarge,
            5..=8 => Shape::Malformed,
            9..=11 => Shape::TooDeep,
            12..=24 => Shape::FullDepth,
            _ => Shape::Ordinary,
        };
        let (chain, max_level) = match shape {
            Shape::FullDepth => (loop_depth, loop_depth),
            Shape::TooDeep => (loop_depth + 1, loop_depth + 1),
            _ => (0, loop_depth),
        };
        let space = 8 + rng.pick(&[8, 24, 64, 160]);
        let mut generator = Gen {
            rng: &mut rng,
            desc,
            nop: &nop,
            ccs,
            conditional,
            space,
            max_level,
        };
        let budget = 100 + generator.rng.below(400);
        let mut items = generator.kernel(chain, budget);
        let target = match shape {
            Shape::FillStore => Some(store),
            Shape::TooLarge => Some(store + 1),
            _ => None,
        };
        if let Some(target) = target {
            let nops = target.saturating_sub(size(&items));
            generator.pad(&mut items, nops);
        }
        let len = size(&items);
        // A kernel meant to be legal that outgrows a small store is refused as too large.
        let legal =
            matches!(shape, Shape::Ordinary | Shape::FullDepth | Shape::FillStore) && len <= store;
        let mut code = Vec::with_capacity(len);
        flatten(items, &mut code);
        if shape == Shape::Malformed {
            malform(&mut rng, &mut code);
        }
        let program = Program {
            name: "uc_bench".into(),
            streams: streams.to_vec(),
            code,
        };
        if legal {
            // The bench's own contract: it drives the block with programs the microcode
            // check accepts, as the machine does.
            let legal = program.check(desc).map_err(|e| e.to_string());
            sb.check(
                cycle,
                || format!("kernel {kernel}: generated program passes the microcode check"),
                Ok(()),
                legal,
            );
        }
        let code = &program.code;
        let verdict = parse(code, store);
        let phase = uc.phase();
        let started = uc.start(code);
        sb.check(
            cycle,
            || {
                let why = match &verdict {
                    Ok(_) => "legal".to_string(),
                    Err(r) => format!("{r:?}"),
                };
                format!(
                    "kernel {kernel}: program of {} instructions ({why}) accepted",
                    code.len()
                )
            },
            verdict.is_ok(),
            started.is_ok(),
        );
        let nodes = match (verdict, started) {
            (Err(refusal), Err(_)) => {
                cov.hit_if(
                    matches!(refusal, Refusal::TooLarge),
                    "program too large refused",
                );
                cov.hit_if(
                    !matches!(refusal, Refusal::TooLarge),
                    "malformed program refused",
                );
                sb.check(
                    cycle,
                    || format!("kernel {kernel}: a refused program leaves the phase as it was"),
                    phase,
                    uc.phase(),
                );
                continue;
            }
            (Ok(nodes), Ok(())) => nodes,
            _ => continue,
        };
        cov.hit_if(code.len() == store, "program filling the microcode store");
        let bench = Bench {
            lanes,
            ccs,
            stall: rng.pick(&[0, 0, 5, 20]),
            cc_set: rng.pick(&[100, 60, 30]),
        };
        let mut world = World::default();
        for w in &mut world.words {
            *w = match rng.below(8) {
                0 => 0,
                1 => 1 + rng.below(lanes),
                2 | 3 => lanes * (1 + rng.below(8)),
                _ => lanes * rng.below(12) + rng.below(lanes),
            };
        }
        bench.edge(&mut rng, &mut world);
        trace.clear();
        let mut reference = Reference {
            code,
            loop_depth,
            depth: 0,
            world,
            edge: false,
            bench: &bench,
            rng: &mut rng,
            cov: &mut cov,
            trace: &mut trace,
            entries: vec![0; code.len()],
            skipped: 0,
            entering: false,
        };
        let stop = match reference.run(&nodes, Pass::OUTSIDE) {
            Err(stop) => stop,
            Ok(()) => unreachable!("the kernel ends with `done`"),
        };
        let last = reference.world;
        replay(
            &mut uc, code, &trace, stop, last, lanes, kernel, &mut cycle, &mut sb, &mut waves,
        );
    }
    Outcome {
        scoreboard: sb,
        coverage: cov,
        waves: waves.finish(None),
    }
}
