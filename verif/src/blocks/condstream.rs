//! Testbench of the conditional streams: the path of `units::machine` by which the clusters
//! whose condition code is set read the next words of an input stream, or append their
//! words to an output stream, in cluster order (the SRF's conditional accesses, the
//! intercluster network and scratchpad reserved for them, the packing of the selected
//! clusters' words, the flush of the output at the end of the kernel). It is driven as the
//! machine drives it: small kernels written here as microcode text, assembled at run time
//! for the machine under test (its latencies set the schedule), run on the cluster machine
//! with random streams; bit 0, 1 and 2 of each word of the input stream `x` are the
//! per-cluster conditions, drawn per row as every cluster, none, one, alternate clusters or
//! at random. The kernels: a filter (read `x`, test a bit, append `x` where set, once or
//! twice back to back), the same filter software-pipelined to a row every cycle (every
//! word, and it shifted, also written to two more output streams from the switch, so that
//! the streams outrun the SRF port and the kernel stalls), conditional input (clusters take the next word of `y` where set, once or twice per row;
//! every cluster's last word received is written out), both in one kernel (optionally the
//! received words routed straight to the output stream, or the conditional read and write
//! in one instruction), a loop over the conditional input until it is exhausted, and a
//! scratchpad kernel (each cluster stores `x` at address `x` and reads it back) with and
//! without a conditional stream. One machine runs kernel after kernel; a run it refuses
//! leaves it mid-instruction, and a new one is built.
//!
//! Reference (transaction level, one kernel run a transaction): row by row in time order,
//! a conditional output appends the words of the clusters whose condition is set in cluster
//! order; a conditional input gives each such cluster the next word of the stream in
//! cluster order and leaves the others' registers as they were; an output stream holds
//! exactly the words appended once the kernel has ended (a partial last row and line
//! included); the words of `y` not taken are left in the stream. Contracts: a conditional
//! read of more words than the stream has left is refused; while a kernel with conditional
//! streams runs, the top `2 × srf.conditional_words_per_cycle` scratchpad words are refused
//! to its scratchpad accesses (and are usable by a kernel without); a conditional access in
//! the instruction of another use of the network (`comm0`) or of the scratchpad (`sp0`),
//! or more conditional accesses in one instruction than `srf.conditional_words_per_cycle`,
//! is refused when the kernel is assembled.

use std::collections::HashMap;
use std::fmt;

use imagine_hdl::{Design, Module};
use imagine_units::desc::MachineDesc;
use imagine_units::machine::{Machine, StreamBinding};
use imagine_units::microcode::{MAX_STAGES, Program, assemble};

use super::{BlockClock, Config, Coverage, Outcome, Rng, Scoreboard, Waves, design};

const BINS: &[&str] = &[
    "conditional input",
    "conditional output",
    "conditional input and output in one kernel",
    "conditional input routed straight to an output stream",
    "loop over a conditional input stream",
    "conditional output every cycle (software-pipelined)",
    "kernel stalled on its stream buffers",
    "back-to-back conditional outputs",
    "back-to-back conditional reads",
    "no cluster set",
    "every cluster set",
    "one cluster set",
    "alternate clusters set",
    "empty input stream",
    "empty output stream",
    "output of whole rows",
    "output not a multiple of the row",
    "partial line flushed at kernel end",
    "conditional read across a row of the input stream",
    "conditional input exhausted mid-row",
    "conditional input exhausted exactly",
    "conditional input left unread at kernel end",
    "conditional read past the end refused",
    "scratchpad word reserved for conditional streams refused",
    "reserved scratchpad words usable without conditional streams",
    "top usable scratchpad word with conditional streams",
    "conditional access with comm0 in one instruction refused",
    "conditional access with sp0 in one instruction refused",
    "two conditional accesses in one instruction",
];

/// Bins that need more than one cluster.
const MULTI_CLUSTER_BINS: &[&str] = &[
    "one cluster set",
    "alternate clusters set",
    "output not a multiple of the row",
    "conditional read across a row of the input stream",
    "conditional input exhausted mid-row",
];

/// What the machine says when it refuses a conditional read past the end of the stream,
/// a scratchpad address past the end, and one in the conditional streams' buffers.
const PAST_THE_END: &str = "with only";
const OUTSIDE_THE_SCRATCHPAD: &str = "outside the";
const IN_THE_BUFFERS: &str = "buffer conditional streams";

/// The registers' contents before a kernel's first conditional read (seen in every cluster
/// that has not received a word yet).
const MARKERS: [u32; 2] = [0x5EED_0000, 0x5EED_0001];

// ---- kernels ------------------------------------------------------------------------------

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Kind {
    /// Read `x`, append it to `z` where bit 1 is set (and, twice, `!x` where bit 2 is).
    Filter,
    /// The filter software-pipelined, a row every cycle, each row also copied to `w` and
    /// shifted to `v` from the switch: the streams outrun the SRF port and the kernel
    /// stalls.
    Pipelined,
    /// Take the next word of `y` where bit 0 is set (and, twice, bit 2), write every
    /// cluster's last received word to `w`.
    Input,
    /// The filter and the conditional input in one kernel.
    Both,
    /// The conditional input as a loop over `y`, until it is exhausted.
    InputLoop,
    /// Store `x` at scratchpad address `x`, read it back to `w`; with `cond`, also the
    /// filter, so the kernel has a conditional stream.
    Scratchpad { cond: bool },
    /// The filter with a `comm0` send in the instruction of its conditional output.
    SharesNetwork,
    /// The filter with an `sp0` read in the instruction of its conditional output.
    SharesScratchpad,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct Spec {
    kind: Kind,
    /// A second conditional output (filter, both) or read (input, loop) in each row, in the
    /// next instruction.
    twice: bool,
    /// Both: the words received also go straight to `z` from the switch.
    echo: bool,
    /// Both: the conditional read in the instruction of the last conditional output.
    fused: bool,
}

impl fmt::Display for Spec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = match self.kind {
            Kind::Filter => "filter",
            Kind::Pipelined => "pipelined filter",
            Kind::Input => "conditional input",
            Kind::Both => "input and output",
            Kind::InputLoop => "loop over the conditional input",
            Kind::Scratchpad { cond: true } => "scratchpad, with a conditional stream",
            Kind::Scratchpad { cond: false } => "scratchpad, no conditional stream",
            Kind::SharesNetwork => "filter sharing comm0",
            Kind::SharesScratchpad => "filter sharing sp0",
        };
        f.write_str(name)?;
        for (on, what) in [
            (self.twice, "twice"),
            (self.echo, "echo"),
            (self.fused, "fused"),
        ] {
            if on {
                write!(f, ", {what}")?;
            }
        }
        Ok(())
    }
}

impl Spec {
    fn has_y(&self) -> bool {
        matches!(self.kind, Kind::Input | Kind::Both | Kind::InputLoop)
    }

    fn has_z(&self) -> bool {
        !matches!(
            self.kind,
            Kind::Input | Kind::InputLoop | Kind::Scratchpad { cond: false }
        )
    }

    fn has_w(&self) -> bool {
        matches!(
            self.kind,
            Kind::Pipelined | Kind::Input | Kind::Both | Kind::InputLoop | Kind::Scratchpad { .. }
        )
    }

    /// The kernel's streams in declaration order: `x`, then those of `y`, `z`, `w` it has.
    fn streams(&self) -> Vec<(&'static str, bool)> {
        let mut s = vec![("x", true)];
        if self.has_y() {
            s.push(("y", true));
        }
        if self.has_z() {
            s.push(("z", false));
        }
        if self.has_w() {
            s.push(("w", false));
        }
        if self.kind == Kind::Pipelined {
            s.push(("v", false));
        }
        s
    }

    fn index(&self, name: &str) -> Option<usize> {
        self.streams().iter().position(|(n, _)| *n == name)
    }

    /// What one row (one pass of the loop) does, in time order.
    fn steps(&self) -> Vec<Step> {
        use Step::*;
        let outs = |v: &mut Vec<Step>| {
            v.push(CondOut {
                value: Value::X,
                bit: 1,
            });
            if self.twice {
                v.push(CondOut {
                    value: Value::NotX,
                    bit: 2,
                });
            }
        };
        let mut v = Vec::new();
        match self.kind {
            Kind::Filter | Kind::SharesNetwork | Kind::SharesScratchpad => outs(&mut v),
            Kind::Pipelined => {
                v.push(CondOut {
                    value: Value::X,
                    bit: 1,
                });
                v.push(Out {
                    value: Value::X,
                    to_v: false,
                });
                v.push(Out {
                    value: Value::Half,
                    to_v: true,
                });
            }
            Kind::Input | Kind::InputLoop => {
                v.push(CondIn {
                    bit: 0,
                    reg: 0,
                    echo: false,
                });
                if self.twice {
                    v.push(CondIn {
                        bit: 2,
                        reg: 1,
                        echo: false,
                    });
                }
                v.push(Out {
                    value: Value::Reg(0),
                    to_v: false,
                });
                if self.twice {
                    v.push(Out {
                        value: Value::Reg(1),
                        to_v: false,
                    });
                }
            }
            Kind::Both => {
                outs(&mut v);
                v.push(CondIn {
                    bit: 0,
                    reg: 0,
                    echo: self.echo,
                });
                v.push(Out {
                    value: Value::Reg(0),
                    to_v: false,
                });
            }
            Kind::Scratchpad { cond } => {
                v.push(Out {
                    value: Value::X,
                    to_v: false,
                });
                if cond {
                    v.push(CondOut {
                        value: Value::X,
                        bit: 1,
                    });
                }
            }
        }
        v
    }

    /// Refused when assembled for `desc`, and the unit the refusal names.
    fn refused_by_assembler(&self, desc: &MachineDesc) -> Option<&'static str> {
        match self.kind {
            Kind::SharesNetwork => Some("comm0"),
            Kind::SharesScratchpad => Some("sp0"),
            Kind::Both if self.fused && desc.srf.conditional_words_per_cycle < 2 => {
                Some("conditional_words_per_cycle")
            }
            _ => None,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Value {
    X,
    NotX,
    /// `x >> 1` (the shift whose bit 0 is the condition).
    Half,
    /// Sticky register `r`: the last word of `y` the cluster received.
    Reg(usize),
}

impl Value {
    /// The value in cluster `c`, whose word of `x` is `x`.
    fn of(self, x: u32, regs: &[Vec<u32>; 2], c: usize) -> u32 {
        match self {
            Value::X => x,
            Value::NotX => !x,
            Value::Half => x >> 1,
            Value::Reg(k) => regs[k][c],
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    /// The clusters with bit `bit` of their `x` set append `value` to `z`.
    CondOut { value: Value, bit: u32 },
    /// The clusters with bit `bit` set take the next word of `y` into register `reg` (and,
    /// with `echo`, append it to `z`).
    CondIn { bit: u32, reg: usize, echo: bool },
    /// Every cluster appends `value` to `w` (or, `to_v`, to `v`).
    Out { value: Value, to_v: bool },
}

/// Instructions of a loop body by cycle, each a list of slots.
#[derive(Default)]
struct Body(Vec<Vec<String>>);

impl Body {
    fn put(&mut self, t: usize, slot: String) {
        if self.0.len() <= t {
            self.0.resize_with(t + 1, Vec::new);
        }
        self.0[t].push(slot);
    }

    fn text(&self, out: &mut String) {
        for slots in &self.0 {
            if slots.is_empty() {
                out.push_str("    nop\n");
            } else {
                out.push_str("    ");
                out.push_str(&slots.join(" | "));
                out.push('\n');
            }
        }
    }
}

/// The LRF entry of sticky register `r`: adder `(1 + r) mod adders`, entry 0 (or, on
/// adder 0 where `x` lives in entry 0, entry `1 + r`).
fn reg(r: usize, adders: usize) -> (usize, usize) {
    let unit = (1 + r) % adders;
    (unit, if unit == 0 { 1 + r } else { 0 })
}

/// The microcode of `spec` for `desc`, scheduled by its latencies; `None` if this machine
/// cannot hold it.
/// The software-pipelined filter, as the generator draws it.
const PIPELINED: Spec = Spec {
    kind: Kind::Pipelined,
    twice: false,
    echo: false,
    fused: false,
};

fn kernel_text(spec: &Spec, desc: &MachineDesc) -> Option<String> {
    let ls = desc.latency.stream as usize;
    let li = desc.latency.int as usize;
    let adders = desc.cluster.adders;
    let mut s = String::from("kernel condstream\n");
    for (name, input) in spec.streams() {
        s.push_str(if input { "in " } else { "out " });
        s.push_str(name);
        s.push('\n');
    }
    let mut body = Body::default();
    match spec.kind {
        Kind::Pipelined => {
            // Every cycle reads `x` and writes `v` and `w`: three unconditional words per
            // cluster, which the clusters' stream bandwidth must allow.
            if adders < 2 || desc.srf.cluster_words_per_cycle < 3 {
                return None;
            }
            let a = ls + 1;
            let b = a + li + 1;
            if b + 1 > MAX_STAGES as usize {
                return None;
            }
            s.push_str("    imm 0 -> add1.b[0]\n    imm 1 -> add0.b[1]\n");
            s.push_str(&format!("loop stream x, stages {}:\n", b + 1));
            body.put(0, "sin0 x -> add0.a[0], add1.a[0]".into());
            body.put(0, format!("add0 shr a[0], b[1] -> cc[1], stream v @{a}"));
            body.put(
                0,
                format!("add1 or a[0], b[0] -> sout.data[0], stream w @{a}"),
            );
            body.put(0, format!("sout z, data[0] if cc[1] @{b}"));
        }
        Kind::Scratchpad { cond } => {
            let (lr, lw) = (
                desc.latency.scratchpad_read as usize,
                desc.latency.scratchpad_write as usize,
            );
            s.push_str("    imm 1 -> add0.b[1]\nloop stream x:\n");
            body.put(0, "sin0 x -> sp0.addr[0], sp0.data[0]".into());
            let st = ls + 1;
            body.put(st, "sp0 st 0, addr[0], data[0]".into());
            let ld = st + lw + 1;
            body.put(ld, "sp0 ld 0, addr[0] -> sout.data[0], add0.a[0]".into());
            let out = ld + lr + 1;
            body.put(out, "sout w, data[0]".into());
            if cond {
                body.put(out, "add0 shr a[0], b[1] -> cc[1]".into());
                body.put(out + li + 1, "sout z, data[0] if cc[1]".into());
            }
        }
        _ => {
            let steps = spec.steps();
            let regs = steps
                .iter()
                .filter(|st| matches!(st, Step::CondIn { .. }))
                .count();
            if adders > 1 {
                s.push_str("    imm 0 -> add0.b[0], add1.b[0]\n");
            } else {
                s.push_str("    imm 0 -> add0.b[0]\n");
            }
            if adders > 2 {
                s.push_str("    imm 0 -> add2.b[0]\n");
            }
            s.push_str("    imm 1 -> add0.b[1]\n    imm 2 -> add0.b[2]\n");
            for (r, marker) in MARKERS.iter().enumerate().take(regs) {
                let (u, e) = reg(r, adders);
                s.push_str(&format!("    imm {marker:#x} -> add{u}.a[{e}]\n"));
            }
            let over = if spec.kind == Kind::InputLoop {
                "y"
            } else {
                "x"
            };
            s.push_str(&format!("loop stream {over}:\n"));
            body.put(0, "sin0 x -> add0.a[0], sout.data[0]".into());
            let tc = ls + 1;
            for bit in 0..3 {
                body.put(tc + bit, format!("add0 shr a[0], b[{bit}] -> cc[{bit}]"));
            }
            body.put(tc + 3, "add0 not a[0] -> sout.data[1]".into());
            let mut t = tc + 4 + li;
            let mut last_in = 0;
            let mut copies = Vec::new();
            for (i, step) in steps.iter().enumerate() {
                match *step {
                    Step::CondOut { value, bit } => {
                        let data = if value == Value::X { 0 } else { 1 };
                        body.put(t, format!("sout z, data[{data}] if cc[{bit}]"));
                        if i == 0 {
                            match spec.kind {
                                Kind::SharesNetwork => {
                                    body.put(t, "comm0 data[0], rotate 0 -> add0.a[1]".into())
                                }
                                Kind::SharesScratchpad => {
                                    body.put(t, "sp0 ld 0 -> add0.a[1]".into())
                                }
                                _ => {}
                            }
                        }
                        t += 1;
                    }
                    Step::CondIn { bit, reg: r, echo } => {
                        let at = if spec.fused { t - 1 } else { t };
                        let (u, e) = reg(r, adders);
                        let echo = if echo { ", stream z" } else { "" };
                        body.put(at, format!("sin1 y if cc[{bit}] -> add{u}.a[{e}]{echo}"));
                        last_in = at;
                        t = at + 1;
                    }
                    Step::Out { value, .. } => {
                        if let Value::Reg(r) = value {
                            copies.push(r);
                        }
                    }
                }
            }
            if !copies.is_empty() {
                let first = t.max(last_in + ls + 1);
                for (k, &r) in copies.iter().enumerate() {
                    let (u, e) = reg(r, adders);
                    body.put(
                        first + k,
                        format!("add{u} or a[{e}], b[0] -> sout.data[{}]", 2 + r),
                    );
                }
                let out = first + copies.len() + li;
                for (k, &r) in copies.iter().enumerate() {
                    body.put(out + k, format!("sout w, data[{}]", 2 + r));
                }
            }
        }
    }
    body.text(&mut s);
    s.push_str("end\ndone\n");
    Some(s)
}

// ---- stimulus and reference ---------------------------------------------------------------

#[derive(Clone, Copy, Debug)]
enum Pattern {
    All,
    None,
    One,
    Alternate,
    Random,
}

fn draw_pattern(rng: &mut Rng) -> Pattern {
    match rng.below(10) {
        0 | 1 => Pattern::All,
        2 | 3 => Pattern::None,
        4 | 5 => Pattern::One,
        6 => Pattern::Alternate,
        _ => Pattern::Random,
    }
}

fn mask(rng: &mut Rng, lanes: usize, p: Pattern) -> Vec<bool> {
    match p {
        Pattern::All => vec![true; lanes],
        Pattern::None => vec![false; lanes],
        Pattern::One => {
            let on = rng.index(lanes);
            (0..lanes).map(|c| c == on).collect()
        }
        Pattern::Alternate => {
            let phase = rng.index(2);
            (0..lanes).map(|c| c % 2 == phase).collect()
        }
        Pattern::Random => (0..lanes).map(|_| rng.chance(50)).collect(),
    }
}

/// How the conditions of one bit are drawn over a kernel's rows: one pattern for all, or
/// a new one every row.
struct Conditions {
    fixed: Option<Pattern>,
}

impl Conditions {
    fn new(rng: &mut Rng) -> Self {
        Conditions {
            fixed: rng.chance(40).then(|| draw_pattern(rng)),
        }
    }

    fn row(&self, rng: &mut Rng, lanes: usize) -> Vec<bool> {
        let p = match self.fixed {
            Some(p) => p,
            None => draw_pattern(rng),
        };
        mask(rng, lanes, p)
    }
}

/// Keeps the first `n` set clusters of `m`.
fn trim(m: &mut [bool], n: usize) {
    let mut kept = 0;
    for b in m.iter_mut() {
        if *b {
            if kept == n {
                *b = false;
            } else {
                kept += 1;
            }
        }
    }
}

/// A row of `x`: random words with bits 0, 1, 2 set as `masks` say.
fn row_words(rng: &mut Rng, masks: &[Vec<bool>; 3]) -> Vec<u32> {
    (0..masks[0].len())
        .map(|c| {
            let mut w = rng.corner_word() & !7;
            for (bit, m) in masks.iter().enumerate() {
                w |= u32::from(m[c]) << bit;
            }
            w
        })
        .collect()
}

/// What the reference expects of one kernel run.
#[derive(Debug, Default)]
struct Expect {
    z: Vec<u32>,
    w: Vec<u32>,
    v: Vec<u32>,
    /// Where each word of `z`, `w` and `v` comes from: the pass of the loop and the cluster.
    z_from: Vec<(usize, usize)>,
    w_from: Vec<(usize, usize)>,
    v_from: Vec<(usize, usize)>,
    /// Words of `y` taken.
    consumed: usize,
    /// Refused while running: what the refusal says.
    refused: Option<&'static str>,
}

/// The coverage facts of a run, as the reference saw it.
#[derive(Default)]
struct Seen {
    cond_in: bool,
    cond_out: bool,
    echo: bool,
    masks: Vec<Vec<bool>>,
    back_to_back_out: bool,
    back_to_back_in: bool,
    across_row: bool,
    exhausted_mid_row: bool,
}

/// The reference: the kernel's rows in order, each step as the conditional streams are
/// specified.
fn reference(spec: &Spec, x: &[u32], y: &[u32], lanes: usize, seen: &mut Seen) -> Expect {
    let steps = spec.steps();
    let mut e = Expect::default();
    let mut regs = [vec![MARKERS[0]; lanes], vec![MARKERS[1]; lanes]];
    let loop_y = spec.kind == Kind::InputLoop;
    if loop_y && y.is_empty() {
        return e;
    }
    let mut last_out_row: Option<usize> = None;
    for (r, xr) in x.chunks(lanes).enumerate() {
        let mut outs_this_row = 0;
        let mut ins_this_row = 0;
        for step in &steps {
            match *step {
                Step::CondOut { value, bit } => {
                    let m: Vec<bool> = xr.iter().map(|w| w >> bit & 1 == 1).collect();
                    let before = e.z.len();
                    for c in (0..lanes).filter(|&c| m[c]) {
                        e.z_from.push((r, c));
                        e.z.push(value.of(xr[c], &regs, c));
                    }
                    if e.z.len() > before {
                        seen.cond_out = true;
                        outs_this_row += 1;
                        if spec.kind == Kind::Pipelined && last_out_row == Some(r.wrapping_sub(1)) {
                            seen.back_to_back_out = true;
                        }
                        last_out_row = Some(r);
                    }
                    seen.masks.push(m);
                }
                Step::CondIn { bit, reg, echo } => {
                    let m: Vec<bool> = xr.iter().map(|w| w >> bit & 1 == 1).collect();
                    let n = m.iter().filter(|&&b| b).count();
                    if e.consumed + n > y.len() {
                        e.refused = Some(PAST_THE_END);
                        return e;
                    }
                    if n > 0 {
                        seen.cond_in = true;
                        ins_this_row += 1;
                        seen.echo |= echo;
                        let start = e.consumed % lanes;
                        seen.across_row |= start + n > lanes;
                        if e.consumed + n == y.len() && n < lanes {
                            seen.exhausted_mid_row = true;
                        }
                    }
                    for c in (0..lanes).filter(|&c| m[c]) {
                        regs[reg][c] = y[e.consumed];
                        if echo {
                            e.z_from.push((r, c));
                            e.z.push(y[e.consumed]);
                        }
                        e.consumed += 1;
                    }
                    seen.masks.push(m);
                }
                Step::Out { value, to_v } => {
                    let (out, from) = if to_v {
                        (&mut e.v, &mut e.v_from)
                    } else {
                        (&mut e.w, &mut e.w_from)
                    };
                    for (c, &xc) in xr.iter().enumerate() {
                        from.push((r, c));
                        out.push(value.of(xc, &regs, c));
                    }
                }
            }
        }
        seen.back_to_back_out |= spec.twice && outs_this_row == 2;
        seen.back_to_back_in |= spec.twice && ins_this_row == 2;
        if loop_y && e.consumed == y.len() {
            break;
        }
    }
    e
}

/// One kernel run's stimulus.
struct Stimulus {
    x: Vec<u32>,
    y: Vec<u32>,
}

fn max_rows(spec: &Spec) -> usize {
    match spec.kind {
        Kind::Pipelined => 32,
        Kind::Scratchpad { .. } => 4,
        _ => 10,
    }
}

fn draw_rows(rng: &mut Rng, max: usize) -> usize {
    match rng.below(8) {
        0 => 0,
        1 | 2 => 1,
        3 => 2,
        _ => rng.index(max + 1),
    }
}

/// Streams for the kernels that loop over `x`.
fn stream_stimulus(rng: &mut Rng, spec: &Spec, lanes: usize) -> Stimulus {
    let rows = draw_rows(rng, max_rows(spec));
    let conds: [Conditions; 3] = std::array::from_fn(|_| Conditions::new(rng));
    let mut x = Vec::with_capacity(rows * lanes);
    let mut reads = 0;
    for _ in 0..rows {
        let masks: [Vec<bool>; 3] = std::array::from_fn(|b| conds[b].row(rng, lanes));
        reads += masks[0].iter().filter(|&&b| b).count();
        if spec.twice {
            reads += masks[2].iter().filter(|&&b| b).count();
        }
        x.extend(row_words(rng, &masks));
    }
    let y = if spec.has_y() {
        let needed = reads.div_ceil(lanes);
        let y_rows = match rng.below(20) {
            // One row short: a conditional read runs past the end.
            0 if needed > 0 => needed - 1,
            0..=11 => needed,
            12..=16 => needed + 1,
            _ => needed + 2,
        };
        (0..y_rows * lanes).map(|_| rng.word()).collect()
    } else {
        Vec::new()
    };
    Stimulus { x, y }
}

/// Streams for the loop over `y`: rows of conditions until `y` is taken (trimming the last
/// reads to what is left, or now and then not, to run past its end), then a few rows of `x`
/// the loop never reads.
fn loop_stimulus(rng: &mut Rng, spec: &Spec, lanes: usize) -> Stimulus {
    let y_len = draw_rows(rng, 6) * lanes;
    let y: Vec<u32> = (0..y_len).map(|_| rng.word()).collect();
    let conds: [Conditions; 3] = std::array::from_fn(|_| Conditions::new(rng));
    let mut x = Vec::new();
    let mut taken = 0;
    let mut rows = 0;
    while taken < y_len {
        let mut masks: [Vec<bool>; 3] = std::array::from_fn(|b| {
            if rows >= 16 {
                vec![true; lanes]
            } else {
                conds[b].row(rng, lanes)
            }
        });
        let mut over = false;
        for bit in [0, 2].into_iter().take(1 + usize::from(spec.twice)) {
            let n = masks[bit].iter().filter(|&&b| b).count();
            let left = y_len - taken;
            if n > left && !rng.chance(8) {
                trim(&mut masks[bit], left);
            }
            let n = masks[bit].iter().filter(|&&b| b).count();
            over |= n > left;
            taken += n.min(left);
        }
        x.extend(row_words(rng, &masks));
        rows += 1;
        if over {
            break;
        }
    }
    for _ in 0..rng.index(3) {
        let masks: [Vec<bool>; 3] = std::array::from_fn(|b| conds[b].row(rng, lanes));
        x.extend(row_words(rng, &masks));
    }
    Stimulus { x, y }
}

/// Scratchpad words a kernel with conditional streams leaves to their buffers (at the top).
fn reserved_buffers(desc: &MachineDesc) -> usize {
    (2 * desc.srf.conditional_words_per_cycle).min(desc.scratchpad.words - 1)
}

/// Addresses for the scratchpad kernel: each cluster's word is the address it stores it
/// at; now and then one falls in the reserved words or past the end.
fn scratchpad_stimulus(rng: &mut Rng, desc: &MachineDesc, cond: bool) -> (Stimulus, usize) {
    let lanes = desc.cluster.count;
    let words = desc.scratchpad.words;
    let buffers = reserved_buffers(desc);
    let usable = if cond { words - buffers } else { words };
    let rows = 1 + rng.index(max_rows(&Spec {
        kind: Kind::Scratchpad { cond },
        twice: false,
        echo: false,
        fused: false,
    }));
    let mut x: Vec<u32> = (0..rows * lanes)
        .map(|_| match rng.below(8) {
            0 => 0,
            1 | 2 => usable as u32 - 1,
            _ => rng.index(usable) as u32,
        })
        .collect();
    if rng.chance(35) {
        let at = rng.index(x.len());
        x[at] = if rng.chance(75) {
            (words - 1 - rng.index(buffers)) as u32
        } else {
            (words + rng.index(3)) as u32
        };
    }
    (Stimulus { x, y: Vec::new() }, usable)
}

// ---- the testbench -------------------------------------------------------------------------

/// The machine under test, rebuilt after a run it refused.
struct Dut {
    design: Design,
    machine: Machine,
}

impl Dut {
    fn new(desc: &MachineDesc) -> Self {
        let mut d = design();
        let machine = Machine::new(&mut d.scope(), desc);
        Dut { design: d, machine }
    }
}

/// A word printed in hex in a mismatch.
#[derive(Clone, Copy, PartialEq, Eq)]
struct Hex(u32);

impl fmt::Debug for Hex {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:#010x}", self.0)
    }
}

struct Bench<'a> {
    desc: &'a MachineDesc,
    lanes: usize,
    rng: Rng,
    sb: Scoreboard,
    cov: Coverage,
    dut: Dut,
    programs: HashMap<Spec, Result<Program, String>>,
    cycle: u64,
    run: u64,
    /// The machine's probes, once a cycle (a rebuilt machine registers the same ones).
    waves: Waves,
}

pub fn run(desc: &MachineDesc, config: &Config) -> Outcome {
    let lanes = desc.cluster.count;
    let bins: Vec<&str> = BINS
        .iter()
        .copied()
        .filter(|b| lanes > 1 || !MULTI_CLUSTER_BINS.contains(b))
        // The pipelined kernel's three full streams must outrun the SRF port to stall.
        .filter(|b| {
            3 * lanes > desc.srf.words_per_cycle || *b != "kernel stalled on its stream buffers"
        })
        // A machine that cannot run the pipelined kernel reaches neither of its bins.
        .filter(|b| {
            kernel_text(&PIPELINED, desc).is_some()
                || !matches!(
                    *b,
                    "kernel stalled on its stream buffers"
                        | "conditional output every cycle (software-pipelined)"
                )
        })
        .collect();
    let dut = Dut::new(desc);
    let waves = Waves::new(dut.design.probes(), desc, BlockClock::Core, config);
    let mut b = Bench {
        desc,
        lanes,
        rng: Rng::new(config.seed),
        sb: Scoreboard::default(),
        cov: Coverage::new(&bins),
        dut,
        programs: HashMap::new(),
        cycle: 0,
        run: 0,
        waves,
    };
    while b.sb.transactions < config.transactions && b.sb.mismatches == 0 {
        let spec = b.draw_spec();
        b.sb.transaction();
        b.run += 1;
        b.kernel(spec);
    }
    Outcome {
        scoreboard: b.sb,
        coverage: b.cov,
        waves: b.waves.finish(None),
    }
}

impl Bench<'_> {
    fn draw_spec(&mut self) -> Spec {
        let rng = &mut self.rng;
        let kind = match rng.below(100) {
            0..=15 => Kind::Filter,
            16..=25 => Kind::Pipelined,
            26..=43 => Kind::Input,
            44..=63 => Kind::Both,
            64..=81 => Kind::InputLoop,
            82..=93 => Kind::Scratchpad {
                cond: rng.chance(50),
            },
            94..=96 => Kind::SharesNetwork,
            _ => Kind::SharesScratchpad,
        };
        let both = kind == Kind::Both;
        Spec {
            kind,
            twice: !matches!(kind, Kind::Pipelined | Kind::Scratchpad { .. }) && rng.chance(40),
            echo: both && rng.chance(50),
            fused: both && rng.chance(10),
        }
    }

    /// Assembles `spec` (once per spec).
    fn program(&mut self, spec: &Spec) -> Option<Result<Program, String>> {
        if let Some(p) = self.programs.get(spec) {
            return Some(p.clone());
        }
        let text = kernel_text(spec, self.desc)?;
        let p = assemble(&text, self.desc).map_err(|e| e.to_string());
        self.programs.insert(*spec, p.clone());
        Some(p)
    }

    /// Drives one kernel run and checks it.
    fn kernel(&mut self, spec: Spec) {
        let Some(program) = self.program(&spec) else {
            // This machine cannot hold the kernel (too few adders, too deep a pipeline):
            // run the plain filter instead.
            return self.kernel(Spec {
                kind: Kind::Filter,
                twice: false,
                echo: false,
                fused: false,
            });
        };
        let cycle = self.cycle;
        let run = self.run;
        let what = move |s: &str| format!("run {run}, kernel `{spec}`: {s}");
        let expected = spec.refused_by_assembler(self.desc);
        let got = program.as_ref().err().cloned();
        self.sb.check(
            cycle,
            || what("refused by the assembler, naming"),
            expected,
            got.as_ref().map(|e| {
                ["comm0", "sp0", "conditional_words_per_cycle"]
                    .into_iter()
                    .find(|u| e.contains(u))
                    .unwrap_or("something else")
            }),
        );
        match spec.kind {
            Kind::SharesNetwork => self.cov.hit_if(
                got.is_some(),
                "conditional access with comm0 in one instruction refused",
            ),
            Kind::SharesScratchpad => self.cov.hit_if(
                got.is_some(),
                "conditional access with sp0 in one instruction refused",
            ),
            _ => {}
        }
        if spec.fused {
            self.cov.hit("two conditional accesses in one instruction");
        }
        let Ok(program) = program else {
            return;
        };
        let lanes = self.lanes;
        let (stim, usable) = match spec.kind {
            Kind::InputLoop => (loop_stimulus(&mut self.rng, &spec, lanes), 0),
            Kind::Scratchpad { cond } => scratchpad_stimulus(&mut self.rng, self.desc, cond),
            _ => (stream_stimulus(&mut self.rng, &spec, lanes), 0),
        };
        let mut seen = Seen::default();
        let mut expect = reference(&spec, &stim.x, &stim.y, lanes, &mut seen);
        if let Kind::Scratchpad { cond } = spec.kind {
            let words = self.desc.scratchpad.words;
            let reserved = words - reserved_buffers(self.desc)..words;
            let in_reserved = stim.x.iter().any(|&a| reserved.contains(&(a as usize)));
            if let Some(&bad) = stim.x.iter().find(|&&a| a as usize >= usable) {
                expect.refused = Some(if bad as usize >= words {
                    OUTSIDE_THE_SCRATCHPAD
                } else {
                    IN_THE_BUFFERS
                });
                self.cov.hit_if(
                    cond && in_reserved,
                    "scratchpad word reserved for conditional streams refused",
                );
            } else {
                self.cov.hit_if(
                    !cond && in_reserved,
                    "reserved scratchpad words usable without conditional streams",
                );
                self.cov.hit_if(
                    cond && stim.x.contains(&(usable as u32 - 1)),
                    "top usable scratchpad word with conditional streams",
                );
            }
        }
        self.cover(&spec, &stim, &expect, &seen);

        // Lay the streams out, block-aligned: inputs, then each output with room for the
        // most words it could receive (filled with a pattern the kernel must overwrite).
        let block = self.desc.srf.block_words;
        let rows = stim.x.len() / lanes;
        let steps = spec.steps();
        let z_room = rows
            * lanes
            * steps
                .iter()
                .filter(|s| matches!(s, Step::CondOut { .. } | Step::CondIn { echo: true, .. }))
                .count();
        let room = |v: bool| {
            rows * lanes
                * steps
                    .iter()
                    .filter(|s| matches!(s, Step::Out { to_v, .. } if *to_v == v))
                    .count()
        };
        let mut bindings = Vec::new();
        let mut next = 0;
        for (name, _) in spec.streams() {
            let words = match name {
                "x" => stim.x.len(),
                "y" => stim.y.len(),
                "z" => z_room,
                "w" => room(false),
                _ => room(true),
            };
            bindings.push(StreamBinding { start: next, words });
            next += words.div_ceil(block).max(1) * block;
        }
        if next > self.desc.srf.words {
            // A machine with too small an SRF for this run: skip it.
            return;
        }
        let m = &mut self.dut.machine;
        let released = m.release_streams().map_err(|e| e.to_string());
        self.sb
            .check(cycle, || what("streams released"), Ok(()), released);
        for ((name, _), b) in spec.streams().iter().zip(&bindings) {
            let data: Vec<u32> = match *name {
                "x" => stim.x.clone(),
                "y" => stim.y.clone(),
                _ => (0..b.words as u32).map(|i| 0xBAD0_0000 | i).collect(),
            };
            let loaded = m.srf_mut().load(b.start, &data).map_err(|e| e.to_string());
            self.sb
                .check(cycle, || what(&format!("{name} loaded")), Ok(()), loaded);
        }
        let started = m.start(&program, &bindings).map_err(|e| e.to_string());
        let ok = started.is_ok();
        self.sb
            .check(cycle, || what("kernel started"), Ok(()), started);
        if !ok {
            return;
        }
        // Clock the machine until the kernel has ended (its outputs flushed) or it refuses.
        let limit = 2_000 + 200 * rows as u64;
        let mut refused = None;
        let mut n = 0;
        loop {
            if let Err(e) = m.eval() {
                refused = Some(e.to_string());
                break;
            }
            m.commit();
            self.waves.cycle(self.cycle + n, |t| m.trace(t));
            n += 1;
            if m.is_idle() || n > limit {
                break;
            }
        }
        self.cycle += n;
        let end = self.cycle;
        let got = refused.as_ref().map(|e| {
            [PAST_THE_END, OUTSIDE_THE_SCRATCHPAD, IN_THE_BUFFERS]
                .into_iter()
                .find(|k| e.contains(k))
                .unwrap_or("something else")
        });
        self.sb.check(
            end,
            || what(&format!("refused while running ({refused:?})")),
            expect.refused,
            got,
        );
        if refused.is_some() {
            self.cov.hit_if(
                expect.refused == Some(PAST_THE_END),
                "conditional read past the end refused",
            );
            // A refused kernel leaves the machine mid-instruction: build a new one.
            self.dut = Dut::new(self.desc);
            return;
        }
        let m = &self.dut.machine;
        self.cov.hit_if(
            m.stats().is_some_and(|st| st.stall_cycles > 0),
            "kernel stalled on its stream buffers",
        );
        self.sb.assert(end, m.is_idle(), || {
            what(&format!("kernel ends within {limit} cycles"))
        });
        if !m.is_idle() || expect.refused.is_some() {
            self.dut = Dut::new(self.desc);
            return;
        }
        for (name, want, from) in [
            ("z", &expect.z, &expect.z_from),
            ("w", &expect.w, &expect.w_from),
            ("v", &expect.v, &expect.v_from),
        ] {
            let Some(i) = spec.index(name) else { continue };
            let len = m.output_len(i);
            let got = m
                .srf()
                .read_back(bindings[i].start, len)
                .unwrap_or_default();
            // The first word that differs, then the length.
            let first = (0..want.len().max(got.len()))
                .find(|&k| want.get(k) != got.get(k))
                .unwrap_or(0);
            self.sb.check(
                end,
                || {
                    let from = match from.get(first) {
                        Some((pass, c)) => format!("from cluster {c} in pass {pass}"),
                        None => "past the end".into(),
                    };
                    what(&format!(
                        "output stream `{name}` word {first} ({from}; {} words expected)",
                        want.len()
                    ))
                },
                want.get(first).copied().map(Hex),
                got.get(first).copied().map(Hex),
            );
            self.sb.checks += want.len().min(got.len()) as u64;
            self.sb.check(
                end,
                || what(&format!("length of output stream `{name}` after the flush")),
                want.len(),
                len,
            );
        }
        if let Some(i) = spec.index("y") {
            let left = m.srf().remaining(i);
            self.sb.check(
                end,
                || what("words of `y` left unread at kernel end"),
                stim.y.len() - expect.consumed,
                left,
            );
        }
    }

    fn cover(&mut self, spec: &Spec, stim: &Stimulus, expect: &Expect, seen: &Seen) {
        let cov = &mut self.cov;
        let lanes = self.lanes;
        let ran = expect.refused.is_none();
        cov.hit_if(seen.cond_in, "conditional input");
        cov.hit_if(seen.cond_out, "conditional output");
        cov.hit_if(
            seen.cond_in && seen.cond_out,
            "conditional input and output in one kernel",
        );
        cov.hit_if(
            seen.echo,
            "conditional input routed straight to an output stream",
        );
        cov.hit_if(
            ran && spec.kind == Kind::InputLoop && expect.consumed > 0,
            "loop over a conditional input stream",
        );
        cov.hit_if(
            ran && spec.kind == Kind::Pipelined && stim.x.len() >= 2 * lanes && seen.cond_out,
            "conditional output every cycle (software-pipelined)",
        );
        cov.hit_if(seen.back_to_back_out, "back-to-back conditional outputs");
        cov.hit_if(seen.back_to_back_in, "back-to-back conditional reads");
        for m in &seen.masks {
            let n = m.iter().filter(|&&b| b).count();
            cov.hit_if(n == 0, "no cluster set");
            cov.hit_if(n == lanes, "every cluster set");
            if lanes > 1 {
                cov.hit_if(n == 1, "one cluster set");
                let alternate = m.iter().enumerate().all(|(c, &b)| b == (c % 2 == 0))
                    || m.iter().enumerate().all(|(c, &b)| b == (c % 2 == 1));
                cov.hit_if(alternate, "alternate clusters set");
            }
        }
        cov.hit_if(stim.x.is_empty(), "empty input stream");
        if ran && spec.has_z() && !stim.x.is_empty() {
            let z = expect.z.len();
            cov.hit_if(z == 0, "empty output stream");
            cov.hit_if(z > 0 && z.is_multiple_of(lanes), "output of whole rows");
            if lanes > 1 {
                cov.hit_if(!z.is_multiple_of(lanes), "output not a multiple of the row");
            }
            cov.hit_if(
                !z.is_multiple_of(self.desc.srf.words_per_cycle),
                "partial line flushed at kernel end",
            );
        }
        if ran && spec.has_y() {
            if lanes > 1 {
                cov.hit_if(
                    seen.across_row,
                    "conditional read across a row of the input stream",
                );
                cov.hit_if(
                    seen.exhausted_mid_row,
                    "conditional input exhausted mid-row",
                );
            }
            cov.hit_if(
                !stim.y.is_empty() && expect.consumed == stim.y.len(),
                "conditional input exhausted exactly",
            );
            cov.hit_if(
                expect.consumed < stim.y.len(),
                "conditional input left unread at kernel end",
            );
        }
    }
}
