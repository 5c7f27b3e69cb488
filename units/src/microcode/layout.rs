//! The binary VLIW format: how an [`Instruction`] is packed into a microcode word whose
//! fields and widths follow from the machine description.
//!
//! The word is a [`WideWord`], bit 0 first. Fields are laid out from bit 0 up in this order:
//! the microcontroller's `ctl` field, the arithmetic slots (`add0…`, `mul0…`, `dsq0…`), the
//! scratchpads (`sp0…`), the communication units (`comm0…`), the stream inputs (`sin0…`),
//! `sout` and `imm`. Every slot starts with a `valid` bit; a slot whose valid bit is clear
//! is empty and the rest of its bits are ignored (encoded as 0); likewise the loop fields of
//! `ctl` when `ctl.begin` is clear.
//!
//! | field | width | meaning |
//! |---|---|---|
//! | `ctl.begin` | 1 | the instruction begins a loop (the next three fields describe it) |
//! | `ctl.loop` | 2 | loop begin: 0 counted, 1 until stream empty, 2 until cc |
//! | `ctl.stages` | 4 | loop begin: software-pipeline stages − 1 |
//! | `ctl.value` | 32 | loop begin: iteration count, stream or condition code |
//! | `ctl.end` | 1 | the instruction ends the innermost loop (with `ctl.begin`: the loop it begins) |
//! | `ctl.pass` | 1 | the instruction ends a pass of the innermost loop but not its body (a body unrolled for modulo variable expansion holds several passes) |
//! | `ctl.done` | 1 | the kernel's last instruction |
//! | `U.valid` | 1 | slot `U` issues (every slot) |
//! | `U.op` | [`Op::OPCODE_BITS`] | arithmetic slots: opcode ([`Op::opcode`]) |
//! | `U.a`, `U.b` | *e* | arithmetic slots: entries of the `U.a`, `U.b` LRFs |
//! | `U.cc` | *c* | adder slots: condition code `select` tests |
//! | `spN.write`, `spN.base` | 1, *w* | scratchpad: write (else read), base address |
//! | `spN.offset.valid`, `spN.offset` | 1, *e* | scratchpad: offset from `spN.addr[offset]`, else 0 |
//! | `spN.data` | *e* | scratchpad write: entry of `spN.data` |
//! | `commN.data` | *e* | entry of `commN.data` to send |
//! | `commN.perm.kind`, `commN.perm` | 2, max(*k*, *e*) | 0 rotate, 1 xor, 2 broadcast (cluster constant), 3 per cluster (`commN.perm` entry) |
//! | `sinN.stream`, `sout.stream` | *s* | kernel stream index |
//! | `sinN.cond.valid`, `sinN.cond` (and `sout.`) | 1, *c* | conditional stream: condition code |
//! | `sout.data` | *e* | entry of `sout.data` |
//! | `imm.kind`, `imm.value` | 1, 32 | 0 the constant `value`, 1 the cluster index |
//! | `U.destD.kind` | 2 | `D` = 0, 1: 0 none, 1 LRF, 2 condition code, 3 stream |
//! | `U.destD.lrf` | *l* | LRF index ([`MachineDesc::lrf_names`] order) |
//! | `U.destD.index` | max(*e*, *c*, *s*) | LRF entry, condition code or stream |
//! | `U.stage` | 4 | software-pipeline stage (every slot) |
//!
//! with *e* = bits of the largest LRF entry index, *c* = bits of the largest condition code,
//! *s* = bits of the largest stream index (`srf.kernel_streams − 1`), *l* = bits of the
//! largest LRF index, *w* = bits of the largest scratchpad address, *k* = bits of the largest
//! cluster index. [`InstructionLayout::describe`] prints the table with offsets for a
//! machine; the `gold8` word is 648 bits wide (snapshot in `tests/microcode_layout.rs`).
//!
//! [`InstructionLayout::encode`] requires every value to fit its field (a program that
//! passes [`Program::check`](super::Program::check) always does);
//! [`InstructionLayout::decode`] accepts any word of the right width and fails, never
//! panics, on an opcode or kind that names nothing.

use std::fmt::Write as _;

use imagine_hdl::{WideWord, bits_for, wide_word};

use crate::desc::MachineDesc;
use crate::ops::{Op, UnitClass};

use super::check::{MAX_STAGES, MicrocodeError, Shape};
use super::{
    CommSlot, Control, Dest, Dests, FuSlot, ImmValue, Immediate, Instruction, LoopBegin, LoopKind,
    Permutation, Program, SpSlot, StreamIn, StreamOut,
};

/// One field of the microcode word.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Field {
    /// Dotted name: `ctl.kind`, `add0.op`, `sin1.dest0.index`.
    pub name: String,
    /// Bit offset of the field's least significant bit.
    pub offset: usize,
    pub width: usize,
    pub meaning: String,
}

/// Index of a field in [`InstructionLayout::fields`].
type F = usize;

#[derive(Clone, Debug)]
struct DestFields {
    kind: F,
    lrf: F,
    index: F,
}

#[derive(Clone, Debug)]
struct FuFields {
    valid: F,
    op: F,
    a: F,
    b: F,
    /// Adders only: the condition code `select` tests (no other unit runs `select`).
    cc: Option<F>,
    dests: [DestFields; 2],
    stage: F,
}

#[derive(Clone, Debug)]
struct SpFields {
    valid: F,
    write: F,
    base: F,
    offset_valid: F,
    offset: F,
    data: F,
    dests: [DestFields; 2],
    stage: F,
}

#[derive(Clone, Debug)]
struct CommFields {
    valid: F,
    data: F,
    perm_kind: F,
    perm: F,
    dests: [DestFields; 2],
    stage: F,
}

#[derive(Clone, Debug)]
struct SinFields {
    valid: F,
    stream: F,
    cond_valid: F,
    cond: F,
    dests: [DestFields; 2],
    stage: F,
}

#[derive(Clone, Debug)]
struct SoutFields {
    valid: F,
    stream: F,
    data: F,
    cond_valid: F,
    cond: F,
    stage: F,
}

#[derive(Clone, Debug)]
struct ImmFields {
    valid: F,
    kind: F,
    value: F,
    dests: [DestFields; 2],
    stage: F,
}

#[derive(Clone, Debug)]
struct CtlFields {
    begin: F,
    lp: F,
    stages: F,
    value: F,
    end: F,
    pass: F,
    done: F,
}

/// The microcode word format of one machine (see the [module documentation](self)).
#[derive(Clone, Debug)]
pub struct InstructionLayout {
    machine: String,
    fields: Vec<Field>,
    width: usize,
    ctl: CtlFields,
    fu: Vec<FuFields>,
    sp: Vec<SpFields>,
    comm: Vec<CommFields>,
    sin: Vec<SinFields>,
    sout: SoutFields,
    imm: ImmFields,
}

/// Width of a `stage` field.
const STAGE_BITS: usize = bits_for(MAX_STAGES as u64 - 1) as usize;
const DEST_NONE: u64 = 0;
const DEST_LRF: u64 = 1;
const DEST_CC: u64 = 2;
const DEST_STREAM: u64 = 3;

struct Builder {
    fields: Vec<Field>,
    offset: usize,
}

impl Builder {
    fn add(&mut self, name: String, width: usize, meaning: impl Into<String>) -> F {
        self.fields.push(Field {
            name,
            offset: self.offset,
            width,
            meaning: meaning.into(),
        });
        self.offset += width;
        self.fields.len() - 1
    }
}

/// Bits to hold every value in `0..n` (at least 1).
fn bits_below(n: usize) -> usize {
    bits_for(n.saturating_sub(1) as u64) as usize
}

impl InstructionLayout {
    pub fn new(desc: &MachineDesc) -> InstructionLayout {
        let sh = Shape::new(desc);
        let e = bits_below(sh.max_lrf_entries());
        let c = bits_below(sh.condition_codes);
        let s = bits_below(sh.kernel_streams);
        let l = bits_below(sh.lrf_names.len());
        let w = bits_below(sh.scratchpad_words);
        let k = bits_below(sh.clusters);
        let index = e.max(c).max(s);
        let mut b = Builder {
            fields: Vec::new(),
            offset: 0,
        };
        let ctl = CtlFields {
            begin: b.add(
                "ctl.begin".into(),
                1,
                "begins a loop (the next three fields describe it)",
            ),
            lp: b.add(
                "ctl.loop".into(),
                2,
                "loop begin: 0 counted, 1 until stream empty, 2 until cc",
            ),
            stages: b.add(
                "ctl.stages".into(),
                STAGE_BITS,
                "loop begin: software-pipeline stages - 1",
            ),
            value: b.add(
                "ctl.value".into(),
                32,
                "loop begin: iteration count, stream or condition code",
            ),
            end: b.add(
                "ctl.end".into(),
                1,
                "ends the innermost loop (with ctl.begin: the loop it begins)",
            ),
            pass: b.add(
                "ctl.pass".into(),
                1,
                "ends a pass of the innermost loop, not its body",
            ),
            done: b.add("ctl.done".into(), 1, "the kernel's last instruction"),
        };
        let dests = |b: &mut Builder, slot: &str| -> [DestFields; 2] {
            [0, 1].map(|d| DestFields {
                kind: b.add(
                    format!("{slot}.dest{d}.kind"),
                    2,
                    "0 none, 1 LRF, 2 condition code, 3 stream",
                ),
                lrf: b.add(format!("{slot}.dest{d}.lrf"), l, "LRF index"),
                index: b.add(
                    format!("{slot}.dest{d}.index"),
                    index,
                    "LRF entry, condition code or stream",
                ),
            })
        };
        let valid = |b: &mut Builder, slot: &str| b.add(format!("{slot}.valid"), 1, "slot issues");
        let stage = |b: &mut Builder, slot: &str| {
            b.add(
                format!("{slot}.stage"),
                STAGE_BITS,
                "software-pipeline stage",
            )
        };
        let fu = (0..sh.fu_count())
            .map(|i| {
                let n = sh.fu_name(i);
                FuFields {
                    valid: valid(&mut b, &n),
                    op: b.add(
                        format!("{n}.op"),
                        Op::OPCODE_BITS as usize,
                        format!("opcode ({} class)", sh.fu_class(i)),
                    ),
                    a: b.add(format!("{n}.a"), e, format!("entry of `{n}.a`")),
                    b: b.add(format!("{n}.b"), e, format!("entry of `{n}.b`")),
                    cc: (sh.fu_class(i) == UnitClass::Adder)
                        .then(|| b.add(format!("{n}.cc"), c, "condition code `select` tests")),
                    dests: dests(&mut b, &n),
                    stage: stage(&mut b, &n),
                }
            })
            .collect();
        let sp = (0..sh.scratchpads)
            .map(|i| {
                let n = format!("sp{i}");
                SpFields {
                    valid: valid(&mut b, &n),
                    write: b.add(format!("{n}.write"), 1, "1 write, 0 read"),
                    base: b.add(format!("{n}.base"), w, "base address"),
                    offset_valid: b.add(
                        format!("{n}.offset.valid"),
                        1,
                        format!("add the offset in `{n}.addr`"),
                    ),
                    offset: b.add(format!("{n}.offset"), e, format!("entry of `{n}.addr`")),
                    data: b.add(
                        format!("{n}.data"),
                        e,
                        format!("write: entry of `{n}.data`"),
                    ),
                    dests: dests(&mut b, &n),
                    stage: stage(&mut b, &n),
                }
            })
            .collect();
        let comm = (0..sh.comm_units)
            .map(|i| {
                let n = format!("comm{i}");
                CommFields {
                    valid: valid(&mut b, &n),
                    data: b.add(format!("{n}.data"), e, format!("entry of `{n}.data`")),
                    perm_kind: b.add(
                        format!("{n}.perm.kind"),
                        2,
                        "0 rotate, 1 xor, 2 broadcast, 3 per cluster",
                    ),
                    perm: b.add(
                        format!("{n}.perm"),
                        k.max(e),
                        format!("cluster constant, or entry of `{n}.perm`"),
                    ),
                    dests: dests(&mut b, &n),
                    stage: stage(&mut b, &n),
                }
            })
            .collect();
        let sin = (0..sh.stream_ins)
            .map(|i| {
                let n = format!("sin{i}");
                SinFields {
                    valid: valid(&mut b, &n),
                    stream: b.add(format!("{n}.stream"), s, "input stream"),
                    cond_valid: b.add(format!("{n}.cond.valid"), 1, "conditional input"),
                    cond: b.add(format!("{n}.cond"), c, "condition code"),
                    dests: dests(&mut b, &n),
                    stage: stage(&mut b, &n),
                }
            })
            .collect();
        let sout = SoutFields {
            valid: valid(&mut b, "sout"),
            stream: b.add("sout.stream".into(), s, "output stream"),
            data: b.add("sout.data".into(), e, "entry of `sout.data`"),
            cond_valid: b.add("sout.cond.valid".into(), 1, "conditional output"),
            cond: b.add("sout.cond".into(), c, "condition code"),
            stage: stage(&mut b, "sout"),
        };
        let imm = ImmFields {
            valid: valid(&mut b, "imm"),
            kind: b.add("imm.kind".into(), 1, "0 constant, 1 cluster index"),
            value: b.add("imm.value".into(), 32, "constant"),
            dests: dests(&mut b, "imm"),
            stage: stage(&mut b, "imm"),
        };
        InstructionLayout {
            machine: desc.name.clone(),
            width: b.offset,
            fields: b.fields,
            ctl,
            fu,
            sp,
            comm,
            sin,
            sout,
            imm,
        }
    }

    /// Total bits of a microcode word.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Every field, from bit 0 up.
    pub fn fields(&self) -> &[Field] {
        &self.fields
    }

    /// The field called `name`.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// The field table as text: `[msb:lsb]`, width, name and meaning of every field.
    pub fn describe(&self) -> String {
        let mut out = format!(
            "microcode word of machine `{}`: {} bits, {} fields (bit 0 first)\n",
            self.machine,
            self.width,
            self.fields.len()
        );
        let name_width = self.fields.iter().map(|f| f.name.len()).max().unwrap_or(0);
        let digits = self.width.to_string().len();
        let _ = writeln!(
            out,
            "{:<bits$}  {:>5}  {:<name_width$}  meaning",
            "bits",
            "width",
            "field",
            bits = 2 * digits + 3
        );
        for f in &self.fields {
            let bits = format!(
                "[{:>digits$}:{:>digits$}]",
                f.offset + f.width - 1,
                f.offset
            );
            let _ = writeln!(
                out,
                "{bits}  {:>5}  {:<name_width$}  {}",
                f.width, f.name, f.meaning
            );
        }
        out
    }

    fn put(&self, w: &mut WideWord, f: F, value: u64) -> Result<(), MicrocodeError> {
        let field = &self.fields[f];
        if field.width < 64 && value >> field.width != 0 {
            return Err(MicrocodeError::field(
                field.name.clone(),
                format!("value {value} does not fit the {}-bit field", field.width),
            ));
        }
        for bit in 0..field.width {
            w.set(field.offset + bit, (value >> bit) & 1 != 0);
        }
        Ok(())
    }

    fn get(&self, w: &WideWord, f: F) -> u64 {
        let field = &self.fields[f];
        (0..field.width).fold(0, |v, bit| v | (u64::from(w[field.offset + bit]) << bit))
    }

    /// A field that is at most 16 bits wide, as the `u16` the instruction types use.
    fn get16(&self, w: &WideWord, f: F) -> Result<u16, MicrocodeError> {
        let v = self.get(w, f);
        u16::try_from(v).map_err(|_| {
            MicrocodeError::field(
                self.fields[f].name.clone(),
                format!("value {v} does not fit 16 bits"),
            )
        })
    }

    /// Packs `ins` into a word of [`width`](Self::width) bits.
    ///
    /// # Panics
    /// If a slot vector does not have the machine's length or a value does not fit its
    /// field — which cannot happen for instructions of a program that passes
    /// [`Program::check`](super::Program::check). [`try_encode`](Self::try_encode) reports
    /// the problem instead.
    pub fn encode(&self, ins: &Instruction) -> WideWord {
        self.try_encode(ins)
            .unwrap_or_else(|e| panic!("cannot encode instruction: {e}"))
    }

    /// Packs the whole code of `program`.
    ///
    /// # Panics
    /// As [`encode`](Self::encode).
    pub fn encode_program(&self, program: &Program) -> Vec<WideWord> {
        program.code.iter().map(|i| self.encode(i)).collect()
    }

    /// [`encode`](Self::encode), reporting a slot vector of the wrong length or a value too
    /// wide for its field.
    pub fn try_encode(&self, ins: &Instruction) -> Result<WideWord, MicrocodeError> {
        for (name, have, want) in [
            ("fu", ins.fu.len(), self.fu.len()),
            ("sp", ins.sp.len(), self.sp.len()),
            ("comm", ins.comm.len(), self.comm.len()),
            ("sin", ins.sin.len(), self.sin.len()),
        ] {
            if have != want {
                return Err(MicrocodeError::field(
                    name,
                    format!("has {have} slots; machine `{}` has {want}", self.machine),
                ));
            }
        }
        let mut w = wide_word(self.width);
        let c = &self.ctl;
        if let Some(LoopBegin { kind, stages }) = ins.control.begin {
            self.put(&mut w, c.begin, 1)?;
            let (lp, value) = match kind {
                LoopKind::Counted(n) => (0, u64::from(n)),
                LoopKind::UntilStreamEmpty(s) => (1, u64::from(s)),
                LoopKind::UntilCc(cc) => (2, u64::from(cc)),
            };
            self.put(&mut w, c.lp, lp)?;
            if stages == 0 {
                return Err(MicrocodeError::field(
                    "ctl.stages",
                    "a loop has at least one stage",
                ));
            }
            self.put(&mut w, c.stages, u64::from(stages - 1))?;
            self.put(&mut w, c.value, value)?;
        }
        self.put(&mut w, c.end, u64::from(ins.control.end))?;
        self.put(&mut w, c.pass, u64::from(ins.control.pass_end))?;
        self.put(&mut w, c.done, u64::from(ins.control.done))?;
        for (f, slot) in self.fu.iter().zip(&ins.fu) {
            if let Some(s) = slot {
                self.put(&mut w, f.valid, 1)?;
                self.put(&mut w, f.op, u64::from(s.op.opcode()))?;
                self.put(&mut w, f.a, u64::from(s.a))?;
                self.put(&mut w, f.b, u64::from(s.b))?;
                match f.cc {
                    Some(cc) => self.put(&mut w, cc, u64::from(s.cc))?,
                    None if s.cc != 0 => {
                        return Err(MicrocodeError::field(
                            self.fields[f.op].name.replace(".op", ".cc"),
                            "only adders run `select`; this slot has no condition-code field",
                        ));
                    }
                    None => {}
                }
                self.put_dests(&mut w, &f.dests, &s.dests)?;
                self.put(&mut w, f.stage, u64::from(s.stage))?;
            }
        }
        for (f, slot) in self.sp.iter().zip(&ins.sp) {
            if let Some(s) = slot {
                self.put(&mut w, f.valid, 1)?;
                self.put(&mut w, f.write, u64::from(s.write))?;
                self.put(&mut w, f.base, u64::from(s.base))?;
                if let Some(o) = s.offset {
                    self.put(&mut w, f.offset_valid, 1)?;
                    self.put(&mut w, f.offset, u64::from(o))?;
                }
                self.put(&mut w, f.data, u64::from(s.data))?;
                self.put_dests(&mut w, &f.dests, &s.dests)?;
                self.put(&mut w, f.stage, u64::from(s.stage))?;
            }
        }
        for (f, slot) in self.comm.iter().zip(&ins.comm) {
            if let Some(s) = slot {
                self.put(&mut w, f.valid, 1)?;
                self.put(&mut w, f.data, u64::from(s.data))?;
                let (kind, v) = match s.perm {
                    Permutation::Rotate(k) => (0, k),
                    Permutation::Xor(k) => (1, k),
                    Permutation::Broadcast(k) => (2, k),
                    Permutation::PerCluster(e) => (3, e),
                };
                self.put(&mut w, f.perm_kind, kind)?;
                self.put(&mut w, f.perm, u64::from(v))?;
                self.put_dests(&mut w, &f.dests, &s.dests)?;
                self.put(&mut w, f.stage, u64::from(s.stage))?;
            }
        }
        for (f, slot) in self.sin.iter().zip(&ins.sin) {
            if let Some(s) = slot {
                self.put(&mut w, f.valid, 1)?;
                self.put(&mut w, f.stream, u64::from(s.stream))?;
                if let Some(cc) = s.cond {
                    self.put(&mut w, f.cond_valid, 1)?;
                    self.put(&mut w, f.cond, u64::from(cc))?;
                }
                self.put_dests(&mut w, &f.dests, &s.dests)?;
                self.put(&mut w, f.stage, u64::from(s.stage))?;
            }
        }
        if let Some(s) = &ins.sout {
            let f = &self.sout;
            self.put(&mut w, f.valid, 1)?;
            self.put(&mut w, f.stream, u64::from(s.stream))?;
            self.put(&mut w, f.data, u64::from(s.data))?;
            if let Some(cc) = s.cond {
                self.put(&mut w, f.cond_valid, 1)?;
                self.put(&mut w, f.cond, u64::from(cc))?;
            }
            self.put(&mut w, f.stage, u64::from(s.stage))?;
        }
        if let Some(s) = &ins.imm {
            let f = &self.imm;
            self.put(&mut w, f.valid, 1)?;
            match s.value {
                ImmValue::Const(v) => self.put(&mut w, f.value, u64::from(v))?,
                ImmValue::ClusterId => self.put(&mut w, f.kind, 1)?,
            }
            self.put_dests(&mut w, &f.dests, &s.dests)?;
            self.put(&mut w, f.stage, u64::from(s.stage))?;
        }
        Ok(w)
    }

    fn put_dests(
        &self,
        w: &mut WideWord,
        f: &[DestFields; 2],
        dests: &Dests,
    ) -> Result<(), MicrocodeError> {
        for (f, d) in f.iter().zip(dests) {
            let (kind, lrf, index) = match *d {
                None => (DEST_NONE, 0, 0),
                Some(Dest::Lrf { lrf, entry }) => (DEST_LRF, lrf, entry),
                Some(Dest::Cc { index }) => (DEST_CC, 0, index),
                Some(Dest::Stream { stream }) => (DEST_STREAM, 0, stream),
            };
            self.put(w, f.kind, kind)?;
            self.put(w, f.lrf, u64::from(lrf))?;
            self.put(w, f.index, u64::from(index))?;
        }
        Ok(())
    }

    /// Unpacks a word. Fails on a word of the wrong width, an opcode that names no op or a
    /// loop kind that names none; fields of empty slots are ignored. Range checks against
    /// the machine (LRF entries, streams, …) are [`Program::check`](super::Program::check)'s.
    pub fn decode(&self, w: &WideWord) -> Result<Instruction, MicrocodeError> {
        if w.len() != self.width {
            return Err(MicrocodeError {
                kernel: None,
                instruction: None,
                field: None,
                message: format!(
                    "is {} bits wide; machine `{}` has {}-bit instructions",
                    w.len(),
                    self.machine,
                    self.width
                ),
            });
        }
        let c = &self.ctl;
        let begin = match self.get(w, c.begin) {
            0 => None,
            _ => {
                let value = self.get(w, c.value);
                let kind = match self.get(w, c.lp) {
                    0 => LoopKind::Counted(value as u32),
                    lp @ (1 | 2) => {
                        let v = u16::try_from(value).map_err(|_| {
                            MicrocodeError::field(
                                "ctl.value",
                                format!("stream or condition code {value} does not fit 16 bits"),
                            )
                        })?;
                        if lp == 1 {
                            LoopKind::UntilStreamEmpty(v)
                        } else {
                            LoopKind::UntilCc(v)
                        }
                    }
                    other => {
                        return Err(MicrocodeError::field(
                            "ctl.loop",
                            format!("loop kind {other} names no loop kind (0..=2)"),
                        ));
                    }
                };
                Some(LoopBegin {
                    kind,
                    stages: self.get(w, c.stages) as u8 + 1,
                })
            }
        };
        let control = Control {
            begin,
            end: self.get(w, c.end) == 1,
            pass_end: self.get(w, c.pass) == 1,
            done: self.get(w, c.done) == 1,
        };
        let mut ins = Instruction {
            control,
            ..Instruction::default()
        };
        for f in &self.fu {
            ins.fu.push(if self.get(w, f.valid) == 1 {
                let code = self.get(w, f.op);
                let op = u8::try_from(code)
                    .ok()
                    .and_then(Op::from_opcode)
                    .ok_or_else(|| {
                        MicrocodeError::field(
                            self.fields[f.op].name.clone(),
                            format!("opcode {code} names no op (there are {})", Op::ALL.len()),
                        )
                    })?;
                Some(FuSlot {
                    op,
                    a: self.get16(w, f.a)?,
                    b: self.get16(w, f.b)?,
                    cc: match f.cc {
                        Some(cc) => self.get16(w, cc)?,
                        None => 0,
                    },
                    dests: self.get_dests(w, &f.dests)?,
                    stage: self.get(w, f.stage) as u8,
                })
            } else {
                None
            });
        }
        for f in &self.sp {
            ins.sp.push(if self.get(w, f.valid) == 1 {
                Some(SpSlot {
                    write: self.get(w, f.write) == 1,
                    base: self.get16(w, f.base)?,
                    offset: if self.get(w, f.offset_valid) == 1 {
                        Some(self.get16(w, f.offset)?)
                    } else {
                        None
                    },
                    data: self.get16(w, f.data)?,
                    dests: self.get_dests(w, &f.dests)?,
                    stage: self.get(w, f.stage) as u8,
                })
            } else {
                None
            });
        }
        for f in &self.comm {
            ins.comm.push(if self.get(w, f.valid) == 1 {
                let v = self.get16(w, f.perm)?;
                let perm = match self.get(w, f.perm_kind) {
                    0 => Permutation::Rotate(v),
                    1 => Permutation::Xor(v),
                    2 => Permutation::Broadcast(v),
                    _ => Permutation::PerCluster(v),
                };
                Some(CommSlot {
                    data: self.get16(w, f.data)?,
                    perm,
                    dests: self.get_dests(w, &f.dests)?,
                    stage: self.get(w, f.stage) as u8,
                })
            } else {
                None
            });
        }
        for f in &self.sin {
            ins.sin.push(if self.get(w, f.valid) == 1 {
                Some(StreamIn {
                    stream: self.get16(w, f.stream)?,
                    cond: if self.get(w, f.cond_valid) == 1 {
                        Some(self.get16(w, f.cond)?)
                    } else {
                        None
                    },
                    dests: self.get_dests(w, &f.dests)?,
                    stage: self.get(w, f.stage) as u8,
                })
            } else {
                None
            });
        }
        let f = &self.sout;
        if self.get(w, f.valid) == 1 {
            ins.sout = Some(StreamOut {
                stream: self.get16(w, f.stream)?,
                data: self.get16(w, f.data)?,
                cond: if self.get(w, f.cond_valid) == 1 {
                    Some(self.get16(w, f.cond)?)
                } else {
                    None
                },
                stage: self.get(w, f.stage) as u8,
            });
        }
        let f = &self.imm;
        if self.get(w, f.valid) == 1 {
            ins.imm = Some(Immediate {
                value: if self.get(w, f.kind) == 1 {
                    ImmValue::ClusterId
                } else {
                    ImmValue::Const(self.get(w, f.value) as u32)
                },
                dests: self.get_dests(w, &f.dests)?,
                stage: self.get(w, f.stage) as u8,
            });
        }
        Ok(ins)
    }

    fn get_dests(&self, w: &WideWord, f: &[DestFields; 2]) -> Result<Dests, MicrocodeError> {
        let mut out = [None; 2];
        for (o, f) in out.iter_mut().zip(f) {
            *o = match self.get(w, f.kind) {
                DEST_NONE => None,
                DEST_LRF => Some(Dest::Lrf {
                    lrf: self.get16(w, f.lrf)?,
                    entry: self.get16(w, f.index)?,
                }),
                DEST_CC => Some(Dest::Cc {
                    index: self.get16(w, f.index)?,
                }),
                _ => Some(Dest::Stream {
                    stream: self.get16(w, f.index)?,
                }),
            };
        }
        Ok(out)
    }
}
