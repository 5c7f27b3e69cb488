//! What the compiler reports about a kernel (`imagine kernel show`): op counts per unit
//! class, the lower bounds on the initiation interval and the one achieved, stages, ops per
//! cycle, LRF use per file, and the loop's schedule table.

use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

use imagine_units::desc::MachineDesc;
use imagine_units::microcode::Program;
use imagine_units::ops::UnitClass;

use super::Bounds;
use super::alloc::Entries;
use super::emit::Layout;
use super::graph::{Graph, Kind};
use super::schedule::{Schedule, Slots};
use crate::kernel::{Kernel, Region};

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct OpCounts {
    pub adder: usize,
    pub multiplier: usize,
    pub divsqrt: usize,
    /// Register copies the compiler added (on adders or multipliers, not counted above).
    pub copies: usize,
    pub scratchpad: usize,
    pub comm: usize,
    pub stream_in: usize,
    pub stream_out: usize,
    pub immediate: usize,
}

impl OpCounts {
    /// Arithmetic ops of the kernel (without copies).
    pub fn arithmetic(&self) -> usize {
        self.adder + self.multiplier + self.divsqrt
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LrfUse {
    pub name: String,
    pub used: usize,
    pub entries: usize,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Report {
    pub kernel: String,
    pub machine: String,
    pub clusters: usize,
    /// Ops of the main loop body (or of the whole kernel when it has no loop).
    pub loop_ops: OpCounts,
    pub total_ops: OpCounts,
    pub res_mii: u32,
    /// The resource that sets the resource bound.
    pub res_limit: String,
    pub rec_mii: u32,
    /// Achieved initiation interval (`None`: no loop).
    pub ii: Option<u32>,
    pub stages: u32,
    /// Passes of `ii` instructions in the loop body: more than one when values outlive the
    /// interval and each pass holds them in entries of its own (modulo variable expansion).
    pub unroll: u32,
    /// Arithmetic ops per cycle across all clusters in the loop (copies not counted).
    pub ops_per_cycle: f64,
    pub instructions: usize,
    pub before_loop: usize,
    pub after_loop: usize,
    pub lrfs: Vec<LrfUse>,
    pub condition_codes: LrfUse,
    /// The loop body: one row per cycle, one column per slot (`slots`).
    pub slots: Vec<String>,
    pub table: Vec<Vec<String>>,
}

fn count(g: &Graph, ops: &[usize]) -> OpCounts {
    let mut c = OpCounts::default();
    for &o in ops {
        let op = &g.ops[o];
        match op.kind {
            Kind::Fu(_) if op.copy => c.copies += 1,
            Kind::Fu(x) => match x.unit() {
                UnitClass::Adder => c.adder += 1,
                UnitClass::Multiplier => c.multiplier += 1,
                UnitClass::DivSqrt => c.divsqrt += 1,
            },
            Kind::SpRead { .. } | Kind::SpWrite { .. } => c.scratchpad += 1,
            Kind::Comm(_) => c.comm += 1,
            Kind::StreamIn { .. } => c.stream_in += 1,
            Kind::StreamOut { .. } => c.stream_out += 1,
            Kind::Imm(_) => c.immediate += 1,
        }
    }
    c
}

#[allow(clippy::too_many_arguments)]
pub fn build(
    kernel: &Kernel,
    g: &Graph,
    s: &Schedule,
    lay: &Layout,
    e: &Entries,
    slots: &Slots,
    desc: &MachineDesc,
    bounds: &Bounds,
    program: &Program,
) -> Report {
    let sh = &slots.shape;
    let loop_ops = g.in_region(Region::Loop);
    let all: Vec<usize> = (0..g.ops.len()).filter(|&o| s.place[o].is_some()).collect();
    let total_ops = count(g, &all);
    let has_loop = lay.ii > 0;
    let loop_counts = if has_loop {
        count(g, &loop_ops)
    } else {
        total_ops.clone()
    };
    let ops_per_cycle = if has_loop {
        (loop_counts.arithmetic() * sh.clusters) as f64 / lay.ii as f64
    } else {
        0.0
    };
    let mut names: Vec<String> = (0..sh.fu_count()).map(|i| sh.fu_name(i)).collect();
    names.extend((0..sh.scratchpads).map(|i| format!("sp{i}")));
    names.extend((0..sh.comm_units).map(|i| format!("comm{i}")));
    names.extend(["sin".to_string(), "sout".into(), "imm".into()]);
    let mut table = vec![vec![String::new(); names.len()]; lay.ii];
    if has_loop {
        let fu = sh.fu_count();
        for &o in &loop_ops {
            let Some(p) = s.place[o] else { continue };
            let op = &g.ops[o];
            let row = p.time.rem_euclid(lay.ii as i64) as usize;
            let stage = p.time / lay.ii as i64;
            let (col, what) = match op.kind {
                Kind::Fu(x) => (p.slot, x.name().to_string()),
                Kind::SpRead { .. } => (fu + p.slot, "spread".into()),
                Kind::SpWrite { .. } => (fu + p.slot, "spwrite".into()),
                Kind::Comm(_) => (fu + sh.scratchpads + p.slot, "comm".into()),
                Kind::StreamIn { stream, .. } => (
                    names.len() - 3,
                    format!("read {}", stream_name(kernel, stream)),
                ),
                Kind::StreamOut { stream, .. } => (
                    names.len() - 2,
                    format!("write {}", stream_name(kernel, stream)),
                ),
                Kind::Imm(_) => (names.len() - 1, "imm".into()),
            };
            let cell = &mut table[row][col];
            if !cell.is_empty() {
                cell.push(',');
            }
            let _ = write!(cell, "{what}/{stage}");
        }
    }
    let lrfs = sh
        .lrf_names
        .iter()
        .zip(&sh.lrf_sizes)
        .enumerate()
        .map(|(i, (n, &size))| LrfUse {
            name: n.clone(),
            used: e.peak.get(i).copied().unwrap_or(0),
            entries: size,
        })
        .collect();
    Report {
        kernel: kernel.name.clone(),
        machine: desc.name.clone(),
        clusters: sh.clusters,
        loop_ops: loop_counts,
        total_ops,
        res_mii: bounds.res_mii,
        res_limit: bounds.res_limit.clone(),
        rec_mii: bounds.rec_mii,
        ii: has_loop.then_some(lay.ii as u32),
        stages: lay.stages as u32,
        unroll: lay.unroll as u32,
        ops_per_cycle,
        instructions: program.code.len(),
        before_loop: lay.pre,
        after_loop: program.code.len() - lay.post_start.min(program.code.len()),
        lrfs,
        condition_codes: LrfUse {
            name: "cc".into(),
            used: e.cc_peak,
            entries: sh.condition_codes,
        },
        slots: names,
        table,
    }
}

fn stream_name(kernel: &Kernel, stream: u16) -> String {
    kernel
        .streams
        .get(stream as usize)
        .map_or_else(|| "params".into(), |s| s.name.clone())
}

impl Report {
    /// The lower bound on the initiation interval.
    pub fn mii(&self) -> u32 {
        self.res_mii.max(self.rec_mii).max(1)
    }

    /// The interval against its bound and the loop's rate, as `imagine kernel show` and
    /// `imagine kernel check` print them: `II 8 (bound 8: ResMII 8 set by multipliers,
    /// RecMII 2), 28.0 ops/cycle`, or `no main loop`.
    pub fn interval(&self) -> String {
        match self.ii {
            Some(ii) => format!(
                "II {ii} (bound {}: ResMII {} set by {}, RecMII {}), {:.1} ops/cycle",
                self.mii(),
                self.res_mii,
                self.res_limit,
                self.rec_mii,
                self.ops_per_cycle
            ),
            None => "no main loop".into(),
        }
    }

    /// The text `imagine kernel show` prints.
    pub fn text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "kernel {} on {} ({} clusters)",
            self.kernel, self.machine, self.clusters
        );
        let c = &self.loop_ops;
        let _ = writeln!(
            s,
            "ops per iteration: {} adder, {} multiplier, {} divide/sqrt ({} arithmetic), {} copies, \
             {} scratchpad, {} comm, {} stream reads, {} stream writes",
            c.adder,
            c.multiplier,
            c.divsqrt,
            c.arithmetic(),
            c.copies,
            c.scratchpad,
            c.comm,
            c.stream_in,
            c.stream_out
        );
        let _ = write!(s, "{}", self.interval());
        if self.ii.is_some() {
            let _ = write!(
                s,
                ", {} stage{}",
                self.stages,
                if self.stages == 1 { "" } else { "s" }
            );
        }
        s.push('\n');
        let _ = writeln!(
            s,
            "{} instructions: {} before the loop, {} in it{}, {} after",
            self.instructions,
            self.before_loop,
            self.ii.unwrap_or(0) * self.unroll,
            if self.unroll > 1 {
                format!(" ({} passes: values outlive the interval)", self.unroll)
            } else {
                String::new()
            },
            self.after_loop
        );
        let _ = write!(s, "LRF use:");
        for l in &self.lrfs {
            let _ = write!(s, " {} {}/{}", l.name, l.used, l.entries);
        }
        let _ = writeln!(
            s,
            "\ncondition codes {}/{}",
            self.condition_codes.used, self.condition_codes.entries
        );
        if !self.table.is_empty() {
            let used: Vec<usize> = (0..self.slots.len())
                .filter(|&c| self.table.iter().any(|r| !r[c].is_empty()))
                .collect();
            let width = |c: usize| {
                self.table
                    .iter()
                    .map(|r| r[c].len())
                    .chain([self.slots[c].len()])
                    .max()
                    .unwrap_or(0)
            };
            let _ = write!(s, "\nschedule (op/stage)\n{:>5}", "cycle");
            for &c in &used {
                let _ = write!(s, "  {:<w$}", self.slots[c], w = width(c));
            }
            s.push('\n');
            for (i, r) in self.table.iter().enumerate() {
                let _ = write!(s, "{i:>5}");
                for &c in &used {
                    let _ = write!(s, "  {:<w$}", r[c], w = width(c));
                }
                s.push('\n');
            }
        }
        s
    }
}
