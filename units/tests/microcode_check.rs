//! `Program::check`: every way a program can fail to fit the machine, each triggered by a
//! minimal program, with the message naming the kernel, the instruction and the field.

use imagine_units::desc::MachineDesc;
use imagine_units::microcode::{
    CommSlot, Control, Dest, FuSlot, ImmValue, Immediate, Instruction, LoopKind, MicrocodeError,
    Permutation, Program, SpSlot, StreamDecl, StreamDir, StreamIn, StreamOut,
};
use imagine_units::ops::Op;

fn gold8() -> MachineDesc {
    MachineDesc::gold8()
}

fn empty(desc: &MachineDesc) -> Instruction {
    let c = &desc.cluster;
    Instruction {
        control: Control::NEXT,
        fu: vec![None; c.adders + c.multipliers + c.divsqrt],
        sp: vec![None; c.scratchpads],
        comm: vec![None; c.comm_units],
        sin: vec![None; desc.srf.cluster_words_per_cycle],
        sout: None,
        imm: None,
    }
}

fn done(desc: &MachineDesc) -> Instruction {
    Instruction {
        control: Control::DONE,
        ..empty(desc)
    }
}

/// Kernel `k` with streams `x` (in) and `y` (out): `ins`, then a `done`.
/// An empty instruction carrying `control`.
fn with_control(desc: &MachineDesc, control: Control) -> Instruction {
    Instruction {
        control,
        ..empty(desc)
    }
}

/// An empty instruction beginning a two-iteration loop of one stage.
fn counted_begin(desc: &MachineDesc) -> Instruction {
    with_control(desc, Control::begin(LoopKind::Counted(2), 1))
}

fn program(desc: &MachineDesc, ins: Instruction) -> Program {
    Program {
        name: "k".into(),
        streams: vec![
            StreamDecl {
                name: "x".into(),
                dir: StreamDir::In,
            },
            StreamDecl {
                name: "y".into(),
                dir: StreamDir::Out,
            },
        ],
        code: vec![ins, done(desc)],
    }
}

fn fu(op: Op) -> FuSlot {
    FuSlot {
        op,
        a: 0,
        b: 0,
        cc: 0,
        dests: [None; 2],
        stage: 0,
    }
}

fn lrf(desc: &MachineDesc, name: &str, entry: u16) -> Dest {
    let lrf = desc.lrf_names().iter().position(|n| n == name).unwrap() as u16;
    Dest::Lrf { lrf, entry }
}

/// The check fails at `instruction` on `field`, and the message says all of it and `text`.
fn fails(desc: &MachineDesc, p: &Program, instruction: usize, field: &str, text: &str) {
    let e: MicrocodeError = p.check(desc).expect_err("the program must be rejected");
    let msg = e.to_string();
    assert_eq!(e.kernel.as_deref(), Some(p.name.as_str()), "{msg}");
    assert_eq!(e.instruction, Some(instruction), "{msg}");
    assert_eq!(e.field.as_deref(), Some(field), "{msg}");
    let head = format!(
        "kernel `{}`, instruction {instruction}, `{field}`: ",
        p.name
    );
    assert!(msg.starts_with(&head), "`{msg}` should start with `{head}`");
    assert!(msg.contains(text), "`{msg}` should contain `{text}`");
}

fn fails_kernel(desc: &MachineDesc, p: &Program, text: &str) {
    let e = p.check(desc).expect_err("the program must be rejected");
    let msg = e.to_string();
    assert_eq!((e.instruction, e.field.as_deref()), (None, None), "{msg}");
    assert!(msg.starts_with(&format!("kernel `{}` ", p.name)), "{msg}");
    assert!(msg.contains(text), "`{msg}` should contain `{text}`");
}

fn with_fu(desc: &MachineDesc, k: usize, s: FuSlot) -> Program {
    let mut ins = empty(desc);
    ins.fu[k] = Some(s);
    program(desc, ins)
}

#[test]
fn a_minimal_program_passes() {
    let d = gold8();
    program(&d, empty(&d)).check(&d).unwrap();
    let mut only = program(&d, empty(&d));
    only.code.remove(0);
    only.check(&d).unwrap();
}

#[test]
fn slot_vectors_have_the_machines_lengths() {
    let d = gold8();
    let mut ins = empty(&d);
    ins.fu.pop();
    fails(
        &d,
        &program(&d, ins),
        0,
        "fu",
        "has 5 slots; machine `gold8` has 6 (3 adders, 2 multipliers, 1 divide/sqrt unit)",
    );
    let mut ins = empty(&d);
    ins.sp.push(None);
    fails(&d, &program(&d, ins), 0, "sp", "has 2 slots");
    let mut ins = empty(&d);
    ins.comm.clear();
    fails(&d, &program(&d, ins), 0, "comm", "has 0 slots");
    let mut ins = empty(&d);
    ins.sin.push(None);
    fails(
        &d,
        &program(&d, ins),
        0,
        "sin",
        "`srf.cluster_words_per_cycle`",
    );
    // gold8+C has 3 scratchpads: a gold8 instruction does not fit it.
    let c = MachineDesc::resolve("gold8+C").unwrap();
    fails(
        &c,
        &program(&c, empty(&d)),
        0,
        "sp",
        "has 1 slot; machine `gold8+C` has 3",
    );
}

#[test]
fn ops_run_on_their_unit_class() {
    let d = gold8();
    fails(
        &d,
        &with_fu(&d, 3, fu(Op::FAdd)),
        0,
        "mul0.op",
        "`fadd` runs on an adder, but `mul0` is a multiplier",
    );
    fails(
        &d,
        &with_fu(&d, 0, fu(Op::FMul)),
        0,
        "add0.op",
        "`fmul` runs on a multiplier",
    );
    fails(
        &d,
        &with_fu(&d, 2, fu(Op::FDiv)),
        0,
        "add2.op",
        "divide/sqrt",
    );
    with_fu(&d, 5, fu(Op::FSqrt)).check(&d).unwrap();
}

#[test]
fn operand_entries_are_inside_their_lrfs() {
    let d = gold8();
    // add0.a has 32 entries, add0.b 16.
    with_fu(
        &d,
        0,
        FuSlot {
            a: 31,
            b: 15,
            ..fu(Op::IAdd)
        },
    )
    .check(&d)
    .unwrap();
    fails(
        &d,
        &with_fu(
            &d,
            0,
            FuSlot {
                a: 32,
                ..fu(Op::IAdd)
            },
        ),
        0,
        "add0.a",
        "entry 32 is out of range: LRF `add0.a` has 32 entries",
    );
    fails(
        &d,
        &with_fu(
            &d,
            0,
            FuSlot {
                b: 16,
                ..fu(Op::IAdd)
            },
        ),
        0,
        "add0.b",
        "has 16 entries",
    );
    fails(
        &d,
        &with_fu(
            &d,
            2,
            FuSlot {
                a: 16,
                ..fu(Op::IAdd)
            },
        ),
        0,
        "add2.a",
        "LRF `add2.a` has 16 entries",
    );
    fails(
        &d,
        &with_fu(
            &d,
            4,
            FuSlot {
                b: 20,
                ..fu(Op::FMul)
            },
        ),
        0,
        "mul1.b",
        "entry 20",
    );
}

#[test]
fn unused_fields_are_zero() {
    let d = gold8();
    fails(
        &d,
        &with_fu(
            &d,
            0,
            FuSlot {
                b: 3,
                ..fu(Op::FAbs)
            },
        ),
        0,
        "add0.b",
        "`fabs` takes one operand; an unused field must be 0",
    );
    fails(
        &d,
        &with_fu(
            &d,
            1,
            FuSlot {
                cc: 2,
                ..fu(Op::FAdd)
            },
        ),
        0,
        "add1.cc",
        "only `select` reads a condition code",
    );
    fails(
        &d,
        &with_fu(
            &d,
            0,
            FuSlot {
                cc: 16,
                ..fu(Op::Select)
            },
        ),
        0,
        "add0.cc",
        "condition code 16 is out of range: a cluster has 16",
    );
    with_fu(
        &d,
        0,
        FuSlot {
            cc: 15,
            a: 1,
            b: 2,
            ..fu(Op::Select)
        },
    )
    .check(&d)
    .unwrap();

    let sp = SpSlot {
        write: false,
        base: 0,
        offset: None,
        data: 0,
        dests: [None; 2],
        stage: 0,
    };
    let mut ins = empty(&d);
    ins.sp[0] = Some(SpSlot { data: 1, ..sp });
    fails(
        &d,
        &program(&d, ins),
        0,
        "sp0.data",
        "a scratchpad read writes no data",
    );
    let mut ins = empty(&d);
    ins.sp[0] = Some(SpSlot {
        write: true,
        dests: [Some(Dest::Cc { index: 0 }), None],
        ..sp
    });
    fails(
        &d,
        &program(&d, ins),
        0,
        "sp0.dest0",
        "a scratchpad write has no result",
    );
}

#[test]
fn destinations_exist_and_are_canonical() {
    let d = gold8();
    let with_dests = |dests| {
        with_fu(
            &d,
            0,
            FuSlot {
                dests,
                ..fu(Op::IAdd)
            },
        )
    };
    fails(
        &d,
        &with_dests([Some(Dest::Lrf { lrf: 17, entry: 0 }), None]),
        0,
        "add0.dest0",
        "LRF 17 does not exist: a cluster has 17 LRFs",
    );
    fails(
        &d,
        &with_dests([Some(lrf(&d, "mul0.b", 16)), None]),
        0,
        "add0.dest0",
        "entry 16 is out of range: LRF `mul0.b` has 16 entries",
    );
    fails(
        &d,
        &with_dests([None, Some(Dest::Cc { index: 16 })]),
        0,
        "add0.dest1",
        "a second destination without a first",
    );
    fails(
        &d,
        &with_dests([Some(Dest::Cc { index: 1 }), Some(Dest::Cc { index: 16 })]),
        0,
        "add0.dest1",
        "condition code 16 is out of range",
    );
    fails(
        &d,
        &with_dests([Some(Dest::Cc { index: 1 }), Some(Dest::Cc { index: 1 })]),
        0,
        "add0.dest1",
        "both destinations are the same",
    );
    fails(
        &d,
        &with_dests([Some(lrf(&d, "add1.a", 1)), Some(lrf(&d, "add1.a", 2))]),
        0,
        "add0.dest1",
        "both destinations write LRF `add1.a` in the same cycle",
    );
    fails(
        &d,
        &with_dests([Some(Dest::Stream { stream: 2 }), None]),
        0,
        "add0.dest0",
        "stream 2 is not declared (the kernel declares 2)",
    );
    fails(
        &d,
        &with_dests([Some(Dest::Stream { stream: 0 }), None]),
        0,
        "add0.dest0",
        "writes an output stream, but stream 0 `x` is an input stream",
    );
    with_dests([
        Some(Dest::Stream { stream: 1 }),
        Some(lrf(&d, "sout.data", 15)),
    ])
    .check(&d)
    .unwrap();
    // Destinations of every kind of slot are checked.
    let mut ins = empty(&d);
    ins.imm = Some(Immediate {
        value: ImmValue::ClusterId,
        dests: [Some(lrf(&d, "add0.a", 32)), None],
        stage: 0,
    });
    fails(&d, &program(&d, ins), 0, "imm.dest0", "entry 32");
}

#[test]
fn streams_are_read_and_written_in_their_direction() {
    let d = gold8();
    let sin = StreamIn {
        stream: 0,
        cond: None,
        dests: [None; 2],
        stage: 0,
    };
    let mut ins = empty(&d);
    ins.sin[2] = Some(StreamIn { stream: 1, ..sin });
    fails(
        &d,
        &program(&d, ins),
        0,
        "sin2.stream",
        "reads an input stream, but stream 1 `y` is an output stream",
    );
    let mut ins = empty(&d);
    ins.sin[0] = Some(StreamIn { stream: 5, ..sin });
    fails(
        &d,
        &program(&d, ins),
        0,
        "sin0.stream",
        "stream 5 is not declared",
    );
    let mut ins = empty(&d);
    ins.sin[0] = Some(StreamIn {
        cond: Some(16),
        ..sin
    });
    fails(&d, &program(&d, ins), 0, "sin0.cond", "condition code 16");
    let sout = StreamOut {
        stream: 1,
        data: 0,
        cond: None,
        stage: 0,
    };
    let mut ins = empty(&d);
    ins.sout = Some(StreamOut { stream: 0, ..sout });
    fails(
        &d,
        &program(&d, ins),
        0,
        "sout.stream",
        "writes an output stream, but stream 0 `x` is an input stream",
    );
    let mut ins = empty(&d);
    ins.sout = Some(StreamOut { data: 16, ..sout });
    fails(
        &d,
        &program(&d, ins),
        0,
        "sout.data",
        "LRF `sout.data` has 16 entries",
    );
    let mut ins = empty(&d);
    ins.sout = Some(StreamOut {
        cond: Some(20),
        ..sout
    });
    fails(&d, &program(&d, ins), 0, "sout.cond", "condition code 20");
}

#[test]
fn stream_bandwidth_per_instruction() {
    let d = gold8();
    let sin = StreamIn {
        stream: 0,
        cond: None,
        dests: [None; 2],
        stage: 0,
    };
    let sout = StreamOut {
        stream: 1,
        data: 0,
        cond: None,
        stage: 0,
    };
    let mut ins = empty(&d);
    ins.sin = vec![Some(sin); 4];
    program(&d, ins.clone()).check(&d).unwrap();
    ins.sout = Some(sout);
    fails(
        &d,
        &program(&d, ins),
        0,
        "sout",
        "moves 5 stream words per cluster (stream inputs and the stream output); the SRF gives a cluster 4 per cycle",
    );
    let mut ins = empty(&d);
    ins.sin[0] = Some(StreamIn {
        cond: Some(1),
        ..sin
    });
    ins.sin[1] = Some(StreamIn {
        cond: Some(2),
        ..sin
    });
    fails(
        &d,
        &program(&d, ins),
        0,
        "sin1",
        "moves 2 conditional stream words per cluster; conditional streams carry 1 per cycle",
    );
    let mut ins = empty(&d);
    ins.sin[0] = Some(StreamIn {
        cond: Some(1),
        ..sin
    });
    ins.sout = Some(StreamOut {
        cond: Some(1),
        ..sout
    });
    fails(
        &d,
        &program(&d, ins),
        0,
        "sout",
        "2 conditional stream words",
    );
}

#[test]
fn kernel_stream_declarations() {
    let d = gold8();
    let mut p = program(&d, empty(&d));
    p.streams = (0..9)
        .map(|i| StreamDecl {
            name: format!("s{i}"),
            dir: StreamDir::In,
        })
        .collect();
    fails_kernel(
        &d,
        &p,
        "declares 9 streams; a kernel may address at most 8 (`srf.kernel_streams`)",
    );
    let mut p = program(&d, empty(&d));
    p.streams[1].name = "x".into();
    fails_kernel(&d, &p, "declares stream `x` more than once");
    let mut p = program(&d, empty(&d));
    p.streams[1].name = "two words".into();
    fails_kernel(&d, &p, "`two words`, which is not an identifier");
    let mut p = program(&d, empty(&d));
    p.name = "9lives".into();
    fails_kernel(&d, &p, "not an identifier");
}

#[test]
fn scratchpad_bases_and_offsets() {
    let d = gold8();
    let sp = SpSlot {
        write: true,
        base: 255,
        offset: Some(15),
        data: 15,
        dests: [None; 2],
        stage: 0,
    };
    let mut ins = empty(&d);
    ins.sp[0] = Some(sp);
    program(&d, ins).check(&d).unwrap();
    let mut ins = empty(&d);
    ins.sp[0] = Some(SpSlot { base: 256, ..sp });
    fails(
        &d,
        &program(&d, ins),
        0,
        "sp0.base",
        "base 256 is out of range: the scratchpad has 256 words",
    );
    let mut ins = empty(&d);
    ins.sp[0] = Some(SpSlot {
        offset: Some(16),
        ..sp
    });
    fails(
        &d,
        &program(&d, ins),
        0,
        "sp0.addr",
        "LRF `sp0.addr` has 16 entries",
    );
    let mut ins = empty(&d);
    ins.sp[0] = Some(SpSlot { data: 16, ..sp });
    fails(
        &d,
        &program(&d, ins),
        0,
        "sp0.data",
        "LRF `sp0.data` has 16 entries",
    );
    // Reyes machines may have bigger scratchpads.
    let big = MachineDesc::parse(
        "name = \"b\"\nbase = \"gold8\"\n[scratchpad]\nwords = 512",
        "b",
    )
    .unwrap();
    let mut ins = empty(&big);
    ins.sp[0] = Some(SpSlot { base: 511, ..sp });
    program(&big, ins).check(&big).unwrap();
}

/// Found by fuzzing (`fuzz/fuzz_targets/asm.rs`): a `perm[i]` permutation skipped the
/// check of the slot's destinations, so an entry beyond its LRF passed, and then failed to
/// encode (a panic) or, within the field's width, reached the machine.
#[test]
fn per_cluster_permutations_check_their_destinations() {
    let d = gold8();
    for (perm, field) in [
        (Permutation::PerCluster(0), "comm0.dest0"),
        (Permutation::Rotate(1), "comm0.dest0"),
    ] {
        let mut ins = empty(&d);
        ins.comm[0] = Some(CommSlot {
            data: 1,
            perm,
            dests: [Some(lrf(&d, "add0.b", 16)), None],
            stage: 0,
        });
        fails(
            &d,
            &program(&d, ins),
            0,
            field,
            "entry 16 is out of range: LRF `add0.b` has 16 entries",
        );
    }
    let mut ins = empty(&d);
    ins.comm[0] = Some(CommSlot {
        data: 1,
        perm: Permutation::PerCluster(3),
        dests: [Some(lrf(&d, "add0.b", 1)), Some(lrf(&d, "add0.b", 2))],
        stage: 0,
    });
    fails(&d, &program(&d, ins), 0, "comm0.dest1", "one write port");
}

#[test]
fn permutation_constants_name_clusters() {
    let d = gold8();
    let one = MachineDesc::resolve("gold1").unwrap();
    let comm = |perm| CommSlot {
        data: 0,
        perm,
        dests: [None; 2],
        stage: 0,
    };
    let with = |desc: &MachineDesc, perm| {
        let mut ins = empty(desc);
        ins.comm[0] = Some(comm(perm));
        program(desc, ins)
    };
    for perm in [
        Permutation::Rotate(7),
        Permutation::Xor(7),
        Permutation::Broadcast(7),
        Permutation::PerCluster(15),
    ] {
        with(&d, perm).check(&d).unwrap();
    }
    fails(
        &d,
        &with(&d, Permutation::Rotate(8)),
        0,
        "comm0.perm",
        "`rotate 8` names cluster 8, but the machine has 8 clusters (0..=7)",
    );
    fails(
        &d,
        &with(&d, Permutation::Xor(8)),
        0,
        "comm0.perm",
        "`xor 8`",
    );
    fails(
        &d,
        &with(&d, Permutation::Broadcast(9)),
        0,
        "comm0.perm",
        "`bcast 9`",
    );
    fails(
        &d,
        &with(&d, Permutation::PerCluster(16)),
        0,
        "comm0.perm",
        "LRF `comm0.perm` has 16 entries",
    );
    fails(
        &one,
        &with(&one, Permutation::Rotate(1)),
        0,
        "comm0.perm",
        "the machine has 1 cluster (0..=0)",
    );
    with(&one, Permutation::Rotate(0)).check(&one).unwrap();
    // xor on a cluster count that is not a power of two can leave the machine.
    let six = MachineDesc::parse(
        "name = \"six\"\nbase = \"gold8\"\n[cluster]\ncount = 6",
        "six",
    )
    .unwrap();
    fails(
        &six,
        &with(&six, Permutation::Xor(2)),
        0,
        "comm0.perm",
        "`xor 2` sends cluster 4 to cluster 6",
    );
    with(&six, Permutation::Xor(1)).check(&six).unwrap();
}

fn looped(desc: &MachineDesc, kind: LoopKind, stages: u8, body: Vec<Instruction>) -> Program {
    let mut p = program(desc, empty(desc));
    let mut code = body;
    code[0].control = Control::begin(kind, stages);
    let last = code.len() - 1;
    code[last].control.end = true;
    code.push(done(desc));
    p.code = code;
    p
}

#[test]
fn stages_are_inside_the_innermost_loop() {
    let d = gold8();
    let staged = |stage| {
        let mut ins = empty(&d);
        ins.fu[0] = Some(FuSlot {
            stage,
            ..fu(Op::IAdd)
        });
        ins
    };
    fails(
        &d,
        &program(&d, staged(1)),
        0,
        "add0.stage",
        "stage 1 is out of range: outside a software-pipelined loop every slot is stage 0",
    );
    looped(&d, LoopKind::Counted(4), 2, vec![staged(1), staged(0)])
        .check(&d)
        .unwrap();
    fails(
        &d,
        &looped(&d, LoopKind::Counted(4), 2, vec![staged(0), staged(2)]),
        1,
        "add0.stage",
        "stage 2 is out of range: the loop has 2 stages (0..=1)",
    );
    // The loop's first instruction's own slots are inside the loop; its last's too.
    looped(&d, LoopKind::Counted(4), 3, vec![staged(2), staged(2)])
        .check(&d)
        .unwrap();
    // And a one-instruction body's, which is both.
    looped(&d, LoopKind::Counted(4), 3, vec![staged(2)])
        .check(&d)
        .unwrap();
    fails(
        &d,
        &looped(&d, LoopKind::Counted(4), 3, vec![staged(3)]),
        0,
        "add0.stage",
        "stage 3 is out of range: the loop has 3 stages (0..=2)",
    );
    // Every kind of slot has its stage checked.
    let mut ins = empty(&d);
    ins.imm = Some(Immediate {
        value: ImmValue::Const(1),
        dests: [None; 2],
        stage: 3,
    });
    fails(
        &d,
        &looped(&d, LoopKind::Counted(4), 3, vec![empty(&d), ins]),
        1,
        "imm.stage",
        "stage 3",
    );
}

#[test]
fn loop_headers() {
    let d = gold8();
    let body = || vec![empty(&d), empty(&d)];
    fails(
        &d,
        &looped(&d, LoopKind::Counted(4), 0, body()),
        0,
        "ctl.stages",
        "a loop has 1..=16 software-pipeline stages, not 0",
    );
    fails(
        &d,
        &looped(&d, LoopKind::Counted(4), 17, body()),
        0,
        "ctl.stages",
        "not 17",
    );
    looped(&d, LoopKind::Counted(4), 16, body())
        .check(&d)
        .unwrap();
    fails(
        &d,
        &looped(&d, LoopKind::UntilCc(3), 2, body()),
        0,
        "ctl.stages",
        "an `until cc` loop cannot be software-pipelined (stages must be 1, not 2)",
    );
    fails(
        &d,
        &looped(&d, LoopKind::UntilCc(16), 1, body()),
        0,
        "ctl.value",
        "condition code 16",
    );
    fails(
        &d,
        &looped(&d, LoopKind::UntilStreamEmpty(1), 1, body()),
        0,
        "ctl.value",
        "reads an input stream, but stream 1 `y` is an output stream",
    );
    fails(
        &d,
        &looped(&d, LoopKind::UntilStreamEmpty(2), 1, body()),
        0,
        "ctl.value",
        "stream 2 is not declared",
    );
    looped(&d, LoopKind::UntilStreamEmpty(0), 4, body())
        .check(&d)
        .unwrap();
    looped(&d, LoopKind::Counted(0), 1, body())
        .check(&d)
        .unwrap();
}

#[test]
fn loops_nest_properly_and_not_too_deep() {
    let d = gold8();
    let at = |control| with_control(&d, control);
    let begin = || counted_begin(&d);
    let mut p = program(&d, empty(&d));
    // Depth 4 fits (`microcontroller.loop_depth`), depth 5 does not.
    let mut code = Vec::new();
    for _ in 0..4 {
        code.push(begin());
    }
    code.push(empty(&d));
    for _ in 0..4 {
        code.push(at(Control::END));
    }
    code.push(done(&d));
    p.code = code.clone();
    p.check(&d).unwrap();
    code.insert(4, begin());
    code.insert(6, at(Control::END));
    p.code = code;
    fails(
        &d,
        &p,
        4,
        "ctl.begin",
        "opens a loop nested 5 deep; the loop stack holds 4 (`microcontroller.loop_depth`)",
    );

    p.code = vec![empty(&d), at(Control::END), done(&d)];
    fails(&d, &p, 1, "ctl.end", "`end` closes no open loop");
    p.code = vec![begin(), empty(&d), done(&d)];
    fails(
        &d,
        &p,
        2,
        "ctl.done",
        "`done` inside the loop that begins at instruction 0",
    );
    p.code = vec![empty(&d), begin(), empty(&d)];
    fails(
        &d,
        &p,
        1,
        "ctl.begin",
        "opens a loop that is never closed by an `end`",
    );
}

#[test]
fn one_instruction_loops_begin_and_end_on_one_instruction() {
    let d = gold8();
    let at = |control| with_control(&d, control);
    let one = |n| at(Control::begin_end(LoopKind::Counted(n), 1));
    let mut p = program(&d, empty(&d));
    // Alone, in sequence, and nested in a longer loop (the loop stack still counts it).
    p.code = vec![one(3), one(0), done(&d)];
    p.check(&d).unwrap();
    let begin = || counted_begin(&d);
    let mut code = vec![begin(), begin(), begin(), one(5)];
    code.extend([
        at(Control::END),
        at(Control::END),
        at(Control::END),
        done(&d),
    ]);
    p.code = code.clone();
    p.check(&d).unwrap();
    code.insert(3, begin());
    code.insert(5, at(Control::END));
    p.code = code;
    fails(&d, &p, 4, "ctl.begin", "opens a loop nested 5 deep");
    // The begin+end closes the loop it opens, not the enclosing one.
    p.code = vec![begin(), one(2), done(&d)];
    fails(
        &d,
        &p,
        2,
        "ctl.done",
        "`done` inside the loop that begins at instruction 0",
    );
    // Its header is checked like any loop's.
    p.code = vec![at(Control::begin_end(LoopKind::UntilCc(0), 2)), done(&d)];
    fails(
        &d,
        &p,
        0,
        "ctl.stages",
        "an `until cc` loop cannot be software-pipelined",
    );
}

#[test]
fn done_neither_begins_nor_ends_a_loop() {
    let d = gold8();
    let mut p = program(&d, empty(&d));
    let last = |control| Instruction {
        control,
        ..empty(&d)
    };
    let with_done = |mut c: Control| {
        c.done = true;
        last(c)
    };
    p.code = vec![
        last(Control::begin(LoopKind::Counted(2), 1)),
        with_done(Control::END),
    ];
    fails(
        &d,
        &p,
        1,
        "ctl.done",
        "`done` on an instruction that also ends a loop",
    );
    p.code = vec![with_done(Control::begin_end(LoopKind::Counted(2), 1))];
    fails(
        &d,
        &p,
        0,
        "ctl.done",
        "`done` on an instruction that also begins a loop; the kernel's last instruction is \
         outside every loop",
    );
    // The same loops with `done` on an instruction of its own are fine.
    p.code = vec![
        last(Control::begin(LoopKind::Counted(2), 1)),
        last(Control::END),
        last(Control::DONE),
    ];
    p.check(&d).unwrap();
    p.code = vec![
        last(Control::begin_end(LoopKind::Counted(2), 1)),
        last(Control::DONE),
    ];
    p.check(&d).unwrap();
}

#[test]
fn exactly_one_done_at_the_end() {
    let d = gold8();
    let mut p = program(&d, empty(&d));
    p.code = vec![empty(&d), empty(&d)];
    fails(&d, &p, 1, "ctl.done", "the last instruction is not `done`");
    p.code = vec![done(&d), done(&d)];
    fails(
        &d,
        &p,
        0,
        "ctl.done",
        "`done` before the last instruction (1)",
    );
    p.code = vec![done(&d), empty(&d)];
    fails(&d, &p, 0, "ctl.done", "`done` must be the last instruction");
    p.code.clear();
    fails_kernel(&d, &p, "has no instructions");
}

#[test]
fn code_fits_the_microcode_store() {
    let d = gold8();
    let mut p = program(&d, empty(&d));
    p.name = "x".into();
    p.code = vec![empty(&d); 2099];
    p.code.push(done(&d));
    let e = p.check(&d).unwrap_err();
    assert_eq!(
        e.to_string(),
        "kernel `x` needs 2100 instructions; the microcode store holds 2048"
    );
    p.code.drain(..2100 - 2048);
    p.check(&d).unwrap();
}

#[test]
fn errors_are_std_errors() {
    let d = gold8();
    let e: Box<dyn std::error::Error> =
        Box::new(program(&d, Instruction::default()).check(&d).unwrap_err());
    assert!(
        e.to_string().starts_with("kernel `k`, instruction 0, `fu`"),
        "{e}"
    );
}

#[test]
fn pass_ends_are_inside_a_loop_and_never_with_end_or_done() {
    let d = gold8();
    let at = |control| with_control(&d, control);
    let begin = || counted_begin(&d);
    let with_pass = |mut c: Control| {
        c.pass_end = true;
        at(c)
    };
    let mut p = program(&d, empty(&d));
    // Where a pass may end: inside the body, on the first instruction (a first pass of one
    // instruction), several times, and in an inner loop (whose pass it ends).
    for code in [
        vec![begin(), at(Control::PASS_END), empty(&d), at(Control::END)],
        vec![
            at(Control::begin_pass_end(LoopKind::Counted(2), 1)),
            at(Control::END),
        ],
        vec![
            at(Control::begin_pass_end(LoopKind::Counted(2), 1)),
            at(Control::PASS_END),
            at(Control::PASS_END),
            at(Control::END),
        ],
        vec![
            begin(),
            begin(),
            at(Control::PASS_END),
            at(Control::END),
            at(Control::PASS_END),
            at(Control::END),
        ],
    ] {
        p.code = code;
        p.code.push(done(&d));
        p.check(&d).unwrap();
    }

    p.code = vec![at(Control::PASS_END), done(&d)];
    fails(
        &d,
        &p,
        0,
        "ctl.pass",
        "`pass` outside every loop; it ends a pass of the innermost loop",
    );
    // After the loop has closed.
    p.code = vec![begin(), at(Control::END), at(Control::PASS_END), done(&d)];
    fails(&d, &p, 2, "ctl.pass", "`pass` outside every loop");
    // With `end`: the last pass would be empty.
    p.code = vec![begin(), with_pass(Control::END), done(&d)];
    fails(
        &d,
        &p,
        1,
        "ctl.pass",
        "`pass` on an instruction that also ends a loop: `end` ends the body's last pass, so \
         a pass end here too would leave that pass empty",
    );
    p.code = vec![
        with_pass(Control::begin_end(LoopKind::Counted(2), 1)),
        done(&d),
    ];
    fails(&d, &p, 0, "ctl.pass", "also ends a loop");
    // With `done`.
    p.code = vec![with_pass(Control::DONE)];
    fails(
        &d,
        &p,
        0,
        "ctl.pass",
        "`pass` on the `done` instruction; the kernel's last instruction is outside every loop",
    );
    // Slots after a pass end are still in the loop: their stages are the loop's.
    let staged = |control, stage| {
        let mut ins = at(control);
        ins.fu[0] = Some(FuSlot {
            stage,
            ..fu(Op::IAdd)
        });
        ins
    };
    let b = Control::begin(LoopKind::Counted(2), 3);
    p.code = vec![
        staged(b, 0),
        staged(Control::PASS_END, 2),
        staged(Control::END, 2),
        done(&d),
    ];
    p.check(&d).unwrap();
    p.code[2] = staged(Control::END, 3);
    fails(&d, &p, 2, "add0.stage", "the loop has 3 stages");
}

#[test]
fn every_pass_of_a_stream_loop_reads_as_many_words() {
    let d = gold8();
    let stream = Control::begin(LoopKind::UntilStreamEmpty(0), 2);
    // An instruction with `n` unconditional reads of `x` and `c` conditional ones.
    let reads = |control, n: usize, c: usize| {
        let mut ins = Instruction {
            control,
            ..empty(&d)
        };
        for k in 0..n + c {
            ins.sin[k] = Some(StreamIn {
                stream: 0,
                cond: (k >= n).then_some(0),
                dests: [None; 2],
                stage: 0,
            });
        }
        ins
    };
    let mut p = program(&d, empty(&d));
    p.code = vec![
        reads(stream, 1, 0),
        reads(Control::PASS_END, 1, 0),
        reads(Control::NEXT, 2, 0),
        reads(Control::PASS_END, 0, 0),
        reads(Control::END, 2, 0),
        done(&d),
    ];
    p.check(&d).unwrap();
    // The last pass reads 1 word, the first 2.
    p.code[4] = reads(Control::END, 1, 1);
    fails(
        &d,
        &p,
        4,
        "ctl.end",
        "the pass of instructions 4..=4 reads 1 unconditional word of stream `x` per cluster, \
         but the loop's first pass (instructions 0..=1) reads 2; every pass of a loop over a \
         stream reads as many",
    );
    // A middle pass, at its `pass_end`.
    p.code[4] = reads(Control::END, 2, 0);
    p.code[2] = reads(Control::NEXT, 3, 0);
    fails(
        &d,
        &p,
        3,
        "ctl.pass",
        "the pass of instructions 2..=3 reads 3 unconditional words of stream `x`",
    );
    // A first pass of one instruction.
    p.code = vec![
        reads(
            Control::begin_pass_end(LoopKind::UntilStreamEmpty(0), 1),
            1,
            0,
        ),
        reads(Control::END, 0, 1),
        done(&d),
    ];
    fails(
        &d,
        &p,
        1,
        "ctl.end",
        "reads 0 unconditional words of stream `x` per cluster, but the loop's first pass \
         (instructions 0..=0) reads 1",
    );
    // Reads inside an inner loop count for the pass they are in (as the microcontroller
    // counts words per pass).
    p.code = vec![
        reads(stream, 1, 0),
        reads(Control::begin_end(LoopKind::Counted(3), 1), 1, 0),
        reads(Control::PASS_END, 0, 0),
        reads(Control::END, 1, 0),
        done(&d),
    ];
    fails(
        &d,
        &p,
        3,
        "ctl.end",
        "first pass (instructions 0..=2) reads 2",
    );
    // Other loops' passes may differ.
    p.code = vec![
        reads(Control::begin(LoopKind::Counted(4), 2), 2, 0),
        reads(Control::PASS_END, 0, 0),
        reads(Control::END, 1, 0),
        done(&d),
    ];
    p.check(&d).unwrap();
}
