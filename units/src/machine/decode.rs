//! A kernel's microcode as the clusters issue it, worked out once when a program is first
//! started on the machine (not on every kernel call): for each instruction, only the slots
//! it uses, each with the register files it reads and the unit it drives, in flat arrays;
//! and for every result port and instruction, where the switch sends the result.
//!
//! An [`Instruction`] keeps one `Option` per slot in vectors of its own, which is the form
//! the microcode check, the encoder and the assembler want; a cycle that walked it would
//! test every slot and chase a pointer per slot class, and the switch would look a
//! result's destinations up through the instruction that issued it. Here a cycle reads one
//! record per live slot, and a result's routing is one load from a table indexed by the
//! instruction that issued it (its tag) and the port it leaves by.

use crate::microcode::{Dest, Dests, Immediate, Instruction, Permutation, Program, StreamOut};
use crate::ops::Op;

/// An entry of a register file: the LRF's index (in `MachineDesc::lrf_names` order) and
/// the entry.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LrfEntry {
    pub lrf: u16,
    pub entry: u16,
}

/// The arithmetic unit a slot drives.
#[derive(Clone, Copy, Debug)]
pub(crate) enum FuUnit {
    Adder(u16),
    Multiplier(u16),
    DivSqrt(u16),
}

/// An op on an adder, multiplier or divide/sqrt unit.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FuIssue {
    /// The slot: adders, then multipliers, then divide/sqrt units (its result port too).
    pub slot: u16,
    pub unit: FuUnit,
    pub op: Op,
    pub stage: u8,
    pub a: LrfEntry,
    /// The second operand of a two-operand op.
    pub b: Option<LrfEntry>,
    /// `select`'s condition code (its first operand).
    pub select: Option<u16>,
}

/// A scratchpad access.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SpIssue {
    pub index: u16,
    pub stage: u8,
    pub base: u16,
    pub offset: Option<LrfEntry>,
    /// The word a write stores (`None`: a read).
    pub data: Option<LrfEntry>,
}

/// A word sent over the intercluster network.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CommIssue {
    pub index: u16,
    pub stage: u8,
    pub data: LrfEntry,
    pub perm: Permutation,
    /// The register naming each cluster's source (`Permutation::PerCluster`).
    pub sources: Option<LrfEntry>,
}

/// A stream read.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SinIssue {
    pub index: u16,
    pub stage: u8,
    pub stream: u16,
    pub cond: Option<u16>,
}

/// A range of a flat array of slot records.
#[derive(Clone, Copy, Debug, Default)]
struct Span {
    start: u32,
    end: u32,
}

impl Span {
    fn of<T>(v: &[T], start: usize) -> Span {
        Span {
            start: start as u32,
            end: v.len() as u32,
        }
    }

    fn range(self) -> std::ops::Range<usize> {
        self.start as usize..self.end as usize
    }
}

/// One instruction.
#[derive(Clone, Copy, Debug)]
pub(crate) struct DecodedInst {
    fu: Span,
    sp: Span,
    comm: Span,
    sin: Span,
    pub sout: Option<(StreamOut, LrfEntry)>,
    pub imm: Option<Immediate>,
    /// A `sin` or `sout` slot is used: the stall check has streams to look at.
    pub streams: bool,
    pub ends_pass: bool,
}

/// A program's instructions in issue form, with the routing of every result port.
#[derive(Debug)]
pub(crate) struct Decoded {
    insts: Vec<DecodedInst>,
    fu: Vec<FuIssue>,
    sp: Vec<SpIssue>,
    comm: Vec<CommIssue>,
    sin: Vec<SinIssue>,
    /// `routes[tag · ports + port]`: where the result an instruction `tag` started on
    /// result port `port` goes (ports: the FU slots, then scratchpads, communication units,
    /// stream reads, the immediate).
    routes: Vec<Dests>,
    ports: usize,
    /// The first port of each class after the FU slots.
    pub ports_of: Ports,
    /// Some result goes from the switch straight to an output stream.
    pub switch_writes_streams: bool,
    /// Some instruction reads or writes a stream conditionally.
    pub conditional_streams: bool,
}

/// The first result port of the scratchpads, communication units and stream reads, and
/// the immediate's port (the FU slots are ports `0..`).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Ports {
    pub sp: usize,
    pub comm: usize,
    pub sin: usize,
    pub imm: usize,
}

/// Where each slot input of a cluster reads, as LRF indices.
pub(crate) struct Inputs<'a> {
    pub fu: &'a [[usize; 2]],
    pub sp: &'a [[usize; 2]],
    pub comm: &'a [[usize; 2]],
    pub sout: usize,
    /// Stream-read slots.
    pub sin: usize,
    pub adders: usize,
    pub multipliers: usize,
}

fn entry(lrf: usize, entry: u16) -> LrfEntry {
    LrfEntry {
        lrf: lrf as u16,
        entry,
    }
}

impl Decoded {
    /// `program`, which passed the microcode check for this machine, in issue form.
    pub fn new(program: &Program, inputs: &Inputs<'_>) -> Decoded {
        let sp = inputs.fu.len();
        let ports_of = Ports {
            sp,
            comm: sp + inputs.sp.len(),
            sin: sp + inputs.sp.len() + inputs.comm.len(),
            imm: sp + inputs.sp.len() + inputs.comm.len() + inputs.sin,
        };
        let ports = ports_of.imm + 1;
        let mut d = Decoded {
            insts: Vec::with_capacity(program.code.len()),
            fu: Vec::new(),
            sp: Vec::new(),
            comm: Vec::new(),
            sin: Vec::new(),
            routes: vec![[None; 2]; program.code.len() * ports],
            ports,
            ports_of,
            switch_writes_streams: false,
            conditional_streams: false,
        };
        for (pc, inst) in program.code.iter().enumerate() {
            d.push(pc, inst, inputs);
        }
        d.switch_writes_streams =
            (d.routes.iter().flatten().flatten()).any(|dest| matches!(dest, Dest::Stream { .. }));
        d.conditional_streams = program.code.iter().any(|i| {
            i.sin.iter().flatten().any(|s| s.cond.is_some())
                || i.sout.is_some_and(|s| s.cond.is_some())
        });
        d
    }

    fn push(&mut self, pc: usize, inst: &Instruction, inputs: &Inputs<'_>) {
        let ports = self.ports_of;
        let routes = &mut self.routes[pc * self.ports..(pc + 1) * self.ports];
        let (fu0, sp0, comm0, sin0) = (
            self.fu.len(),
            self.sp.len(),
            self.comm.len(),
            self.sin.len(),
        );
        for (slot, fu) in inst.fu.iter().enumerate() {
            let Some(fu) = fu else { continue };
            let [la, lb] = inputs.fu[slot];
            let unit = if slot < inputs.adders {
                FuUnit::Adder(slot as u16)
            } else if slot < inputs.adders + inputs.multipliers {
                FuUnit::Multiplier((slot - inputs.adders) as u16)
            } else {
                FuUnit::DivSqrt((slot - inputs.adders - inputs.multipliers) as u16)
            };
            self.fu.push(FuIssue {
                slot: slot as u16,
                unit,
                op: fu.op,
                stage: fu.stage,
                a: entry(la, fu.a),
                b: (fu.op.arity() >= 2).then(|| entry(lb, fu.b)),
                select: (fu.op == Op::Select).then_some(fu.cc),
            });
            routes[slot] = fu.dests;
        }
        for (i, sp) in inst.sp.iter().enumerate() {
            if let Some(sp) = sp {
                let [laddr, ldata] = inputs.sp[i];
                self.sp.push(SpIssue {
                    index: i as u16,
                    stage: sp.stage,
                    base: sp.base,
                    offset: sp.offset.map(|e| entry(laddr, e)),
                    data: sp.write.then(|| entry(ldata, sp.data)),
                });
                routes[ports.sp + i] = sp.dests;
            }
        }
        for (i, cs) in inst.comm.iter().enumerate() {
            if let Some(cs) = cs {
                let [ldata, lperm] = inputs.comm[i];
                self.comm.push(CommIssue {
                    index: i as u16,
                    stage: cs.stage,
                    data: entry(ldata, cs.data),
                    perm: cs.perm,
                    sources: match cs.perm {
                        Permutation::PerCluster(e) => Some(entry(lperm, e)),
                        _ => None,
                    },
                });
                routes[ports.comm + i] = cs.dests;
            }
        }
        for (i, s) in inst.sin.iter().enumerate() {
            if let Some(s) = s {
                self.sin.push(SinIssue {
                    index: i as u16,
                    stage: s.stage,
                    stream: s.stream,
                    cond: s.cond,
                });
                routes[ports.sin + i] = s.dests;
            }
        }
        if let Some(imm) = inst.imm {
            routes[ports.imm] = imm.dests;
        }
        self.insts.push(DecodedInst {
            fu: Span::of(&self.fu, fu0),
            sp: Span::of(&self.sp, sp0),
            comm: Span::of(&self.comm, comm0),
            sin: Span::of(&self.sin, sin0),
            sout: inst.sout.map(|s| (s, entry(inputs.sout, s.data))),
            imm: inst.imm,
            streams: inst.sin.iter().any(Option::is_some) || inst.sout.is_some(),
            ends_pass: inst.control.ends_pass(),
        });
    }

    #[inline(always)]
    pub fn inst(&self, pc: u16) -> &DecodedInst {
        &self.insts[pc as usize]
    }

    #[inline(always)]
    pub fn fu(&self, i: &DecodedInst) -> &[FuIssue] {
        &self.fu[i.fu.range()]
    }

    #[inline(always)]
    pub fn sp(&self, i: &DecodedInst) -> &[SpIssue] {
        &self.sp[i.sp.range()]
    }

    #[inline(always)]
    pub fn comm(&self, i: &DecodedInst) -> &[CommIssue] {
        &self.comm[i.comm.range()]
    }

    #[inline(always)]
    pub fn sin(&self, i: &DecodedInst) -> &[SinIssue] {
        &self.sin[i.sin.range()]
    }

    /// Where the result instruction `tag` started on result port `port` goes.
    #[inline(always)]
    pub fn route(&self, tag: u16, port: usize) -> &Dests {
        &self.routes[tag as usize * self.ports + port]
    }
}
