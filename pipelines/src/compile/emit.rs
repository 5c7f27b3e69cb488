//! Emission: scheduled, allocated ops become microcode instructions.
//!
//! Layout: the code before the loop, padded until its last result has landed; the loop body
//! (one instruction per cycle of the initiation interval, each slot tagged with its
//! software-pipeline stage, so the microcontroller's squash makes the prologue and epilogue;
//! repeated once per pass when values outlive the interval, each pass reading and writing
//! its own entries of them and ending with `pass_end`, so the loop may leave after any);
//! a drain until the last pass's results have landed, if code follows; the code after the
//! loop; `done` on the last instruction.

use imagine_units::desc::MachineDesc;
use imagine_units::microcode::{
    CommSlot, Control, Dest, Dests, FuSlot, Immediate, Instruction, LoopKind, Permutation, Program,
    SpSlot, StreamDecl, StreamDir, StreamIn, StreamOut,
};
use imagine_units::ops::Op;

use super::alloc::Entries;
use super::graph::{Graph, Input, Kind, Loc, Source};
use super::schedule::{Schedule, Slots};
use crate::kernel::{Dir, Kernel, LoopSpec, Region};

/// Where each region starts in the program, and how long the loop body is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    pub pre: usize,
    pub loop_start: usize,
    pub ii: usize,
    /// Passes of `ii` instructions in the loop body (see [`super::schedule::reach`]).
    pub unroll: usize,
    pub stages: usize,
    pub post_start: usize,
    pub len: usize,
}

/// Cycles from an op's issue until its result has landed (or its write is done).
fn done_after(g: &Graph, u: usize, desc: &MachineDesc) -> i64 {
    g.latency(u, desc) + 1
}

pub fn layout(
    g: &Graph,
    s: &Schedule,
    ii: Option<i64>,
    unroll: usize,
    desc: &MachineDesc,
) -> Layout {
    let end_of = |r: Region| {
        g.in_region(r)
            .iter()
            .filter_map(|&u| s.place[u].map(|p| p.time + done_after(g, u, desc)))
            .max()
            .unwrap_or(0) as usize
    };
    let pre = end_of(Region::Pre);
    let (ii, stages, drain) = match ii {
        Some(ii) => {
            let ops = g.in_region(Region::Loop);
            let last = ops
                .iter()
                .filter_map(|&u| s.place[u].map(|p| p.time))
                .max()
                .unwrap_or(0);
            let drain = ops
                .iter()
                .filter_map(|&u| s.place[u].map(|p| p.time.rem_euclid(ii) + done_after(g, u, desc)))
                .max()
                .unwrap_or(0)
                - ii;
            (ii as usize, (last / ii + 1) as usize, drain.max(0) as usize)
        }
        None => (0, 0, 0),
    };
    let post_len = end_of(Region::Post);
    let unroll = if ii > 0 { unroll.max(1) } else { 1 };
    // (The loop may leave after any pass: the drain follows the body.)
    let post_start = pre + ii * unroll + if post_len > 0 { drain } else { 0 };
    // `done` sits on the last instruction outside every loop: after the loop that needs an
    // instruction of its own when nothing follows it.
    let len = if post_len > 0 {
        post_start + post_len
    } else if ii > 0 || pre == 0 {
        post_start + 1
    } else {
        pre
    };
    Layout {
        pre,
        loop_start: pre,
        ii,
        unroll,
        stages,
        post_start,
        len,
    }
}

/// Writes the instructions. (Its inputs are the compiler's whole state; bundling them
/// would only rename them.)
#[allow(clippy::too_many_arguments)]
pub fn emit(
    kernel: &Kernel,
    g: &Graph,
    s: &Schedule,
    e: &Entries,
    lay: &Layout,
    slots: &Slots,
    desc: &MachineDesc,
    providers: &rustc_hash::FxHashMap<(usize, Loc), usize>,
) -> Program {
    let empty = Instruction::empty(desc);
    let clusters = desc.cluster.count as u16;
    let mut code = vec![empty; lay.len];
    // The entry `loc` holds `u`'s value in (of the iterations `i` with `i mod unroll == c`).
    let entry = |u: usize, loc: Loc, c: usize| -> Option<u16> {
        e.entry
            .get(&(u, loc))
            .or_else(|| e.instances.get(&(u, loc)).map(|es| &es[c]))
            .copied()
    };
    // The entry an operand is read from.
    let entry_of = |src: Source, loc: Loc, c: usize| -> u16 {
        let producer = match src {
            Source::Local(p) | Source::Carried(p) => p,
            Source::Earlier(p) => providers.get(&(p, loc)).copied().unwrap_or(p),
        };
        entry(producer, loc, c).unwrap_or_else(|| panic!("no entry for op {producer} in {loc:?}"))
    };
    let passes = |op: &super::graph::MOp| {
        if op.region == Region::Loop {
            lay.unroll
        } else {
            1
        }
    };
    for (u, op) in g.ops.iter().enumerate() {
        let Some(pl) = s.place[u] else { continue };
        for pass in 0..passes(op) {
            let (at, stage) = match op.region {
                Region::Pre => (pl.time as usize, 0u8),
                Region::Loop => {
                    let ii = lay.ii as i64;
                    (
                        lay.loop_start + pass * lay.ii + pl.time.rem_euclid(ii) as usize,
                        (pl.time / ii) as u8,
                    )
                }
                Region::Post => (lay.post_start + pl.time as usize, 0),
            };
            // Pass `pass` of the body runs stage `stage` of iteration `pass − stage` (modulo
            // the unrolling), whose copies of the loop's values it reads and writes.
            let copy = (pass + lay.unroll - usize::from(stage) % lay.unroll) % lay.unroll;
            let mut dests: Dests = [None; 2];
            for (k, &loc) in s.dests[u].iter().enumerate() {
                let Some(entry) = entry(u, loc, copy) else {
                    continue;
                };
                dests[k] = Some(match loc {
                    Loc::Lrf(l) => Dest::Lrf { lrf: l, entry },
                    Loc::Cc => Dest::Cc { index: entry },
                });
            }
            let arg = |input: Input| -> Option<u16> {
                op.args
                    .iter()
                    .find(|a| a.input == input)
                    .map(|a| entry_of(a.src, slots.operand_loc(op.kind, pl.slot, pl.swap, a), copy))
            };
            let ins = &mut code[at];
            match op.kind {
                Kind::Fu(o) => {
                    let (mut a, mut b) = (arg(Input::A).unwrap_or(0), arg(Input::B).unwrap_or(0));
                    if pl.swap {
                        std::mem::swap(&mut a, &mut b);
                    }
                    ins.fu[pl.slot] = Some(FuSlot {
                        op: o,
                        a,
                        b: if o.arity() >= 2 { b } else { 0 },
                        cc: if o == Op::Select {
                            arg(Input::Cc).unwrap_or(0)
                        } else {
                            0
                        },
                        dests,
                        stage,
                    });
                }
                Kind::SpRead { base } | Kind::SpWrite { base } => {
                    ins.sp[pl.slot] = Some(SpSlot {
                        write: matches!(op.kind, Kind::SpWrite { .. }),
                        base,
                        offset: arg(Input::SpAddr),
                        data: arg(Input::SpData).unwrap_or(0),
                        dests: if matches!(op.kind, Kind::SpRead { .. }) {
                            dests
                        } else {
                            [None; 2]
                        },
                        stage,
                    });
                }
                Kind::Comm(p) => {
                    let perm = match p {
                        Permutation::PerCluster(_) => {
                            Permutation::PerCluster(arg(Input::CommPerm).unwrap_or(0))
                        }
                        Permutation::Rotate(k) => Permutation::Rotate(k % clusters),
                        other => other,
                    };
                    ins.comm[pl.slot] = Some(CommSlot {
                        data: arg(Input::CommData).unwrap_or(0),
                        perm,
                        dests,
                        stage,
                    });
                }
                Kind::StreamIn { stream, cond } => {
                    let k = ins
                        .sin
                        .iter()
                        .position(Option::is_none)
                        .expect("the scheduler counts stream words");
                    ins.sin[k] = Some(StreamIn {
                        stream,
                        cond: if cond { arg(Input::Cc) } else { None },
                        dests,
                        stage,
                    });
                }
                Kind::StreamOut { stream, cond } => {
                    ins.sout = Some(StreamOut {
                        stream,
                        data: arg(Input::SoutData).unwrap_or(0),
                        cond: if cond { arg(Input::Cc) } else { None },
                        stage,
                    });
                }
                Kind::Imm(value) => {
                    ins.imm = Some(Immediate {
                        value,
                        dests,
                        stage,
                    });
                }
            }
        }
    }
    if lay.ii > 0 {
        let kind = match g.main_loop.expect("a loop") {
            LoopSpec::OverStream(s) => LoopKind::UntilStreamEmpty(s.0),
            LoopSpec::Counted(n) => LoopKind::Counted(n),
        };
        let stages = lay.stages as u8;
        if lay.ii * lay.unroll == 1 {
            code[lay.loop_start].control = Control::begin_end(kind, stages);
        } else {
            code[lay.loop_start].control = Control::begin(kind, stages);
            for pass in 1..lay.unroll {
                code[lay.loop_start + pass * lay.ii - 1].control.pass_end = true;
            }
            code[lay.loop_start + lay.unroll * lay.ii - 1].control = Control::END;
        }
    }
    code[lay.len - 1].control.done = true;
    let mut streams: Vec<StreamDecl> = kernel
        .streams
        .iter()
        .map(|st| StreamDecl {
            name: st.name.clone(),
            dir: match st.dir {
                Dir::In => StreamDir::In,
                Dir::Out => StreamDir::Out,
            },
        })
        .collect();
    if g.params_stream.is_some() {
        streams.push(StreamDecl {
            name: "params".into(),
            dir: StreamDir::In,
        });
    }
    Program {
        name: kernel.name.clone(),
        streams,
        code,
    }
}
