//! The microcode assembler and disassembler: syntax, numbers, `nop`/`end`/`done`
//! placement, errors with `line:column`, and readable disassembly.

use imagine_units::desc::MachineDesc;
use imagine_units::microcode::{
    AsmError, CommSlot, Control, Dest, FuSlot, ImmValue, InstructionLayout, LoopBegin, LoopKind,
    Permutation, Program, SpSlot, StreamIn, StreamOut, assemble, disassemble,
};
use imagine_units::ops::Op;

fn gold8() -> MachineDesc {
    MachineDesc::gold8()
}

fn asm(text: &str) -> Program {
    assemble(text, &gold8()).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

/// Assembling `text` fails at `line:col` with a message containing `what`.
fn fails(text: &str, line: usize, col: usize, what: &str) -> AsmError {
    let Err(e) = assemble(text, &gold8()) else {
        panic!("must not assemble:\n{text}");
    };
    assert!(
        (e.line, e.col) == (line, col) && e.message.contains(what),
        "got `{e}`, want {line}:{col} with `{what}`"
    );
    assert!(e.to_string().starts_with(&format!("{line}:{col}: ")));
    e
}

fn lrf(name: &str, entry: u16) -> Dest {
    let lrf = gold8().lrf_names().iter().position(|n| n == name).unwrap() as u16;
    Dest::Lrf { lrf, entry }
}

fn round_trips(p: &Program) {
    let text = disassemble(p, &gold8());
    assert_eq!(&asm(&text), p, "{text}");
}

const HEAD: &str = "kernel k\nin x\nin w\nout y\n";

fn body(lines: &str) -> String {
    format!("{HEAD}{lines}")
}

#[test]
fn every_slot_kind_assembles_to_its_fields() {
    let p = asm(&body(
        "add0 fadd a[1], b[2] -> mul0.a[3], cc[4] @0 | add1 fabs a[5] -> stream y | \
         add2 select cc[6], a[7], b[8] -> sout.data[9] | mul1 imul_lo a[1], b[1] |
         dsq0 fsqrt a[2] -> dsq0.b[0]
         sp0 ld 17, addr[3] -> add0.b[1], add1.b[1] | comm0 data[4], rotate 3 -> comm0.perm[1] | sin0 x -> add2.a[1]
         sp0 st 255, data[5] | comm0 data[0], perm[2] | sin3 w | sin1 x -> cc[15] | sout y, data[15]
         sp0 ld 3 | comm0 data[0], xor 5 | imm -1 -> add0.a[31]
         comm0 data[0], bcast 7 -> stream y | imm cid -> add1.a[0]
         sin0 x if cc[1] -> add2.a[1]
         sout y, data[15] if cc[2]
         done",
    ));
    assert_eq!(p.name, "k");
    assert_eq!(p.code.len(), 7);
    let i0 = &p.code[0];
    assert_eq!(
        i0.fu[0],
        Some(FuSlot {
            op: Op::FAdd,
            a: 1,
            b: 2,
            cc: 0,
            dests: [Some(lrf("mul0.a", 3)), Some(Dest::Cc { index: 4 })],
            stage: 0
        })
    );
    assert_eq!(
        i0.fu[1].unwrap().dests,
        [Some(Dest::Stream { stream: 2 }), None]
    );
    assert_eq!((i0.fu[1].unwrap().a, i0.fu[1].unwrap().b), (5, 0));
    let sel = i0.fu[2].unwrap();
    assert_eq!((sel.op, sel.cc, sel.a, sel.b), (Op::Select, 6, 7, 8));
    assert_eq!(i0.fu[4].unwrap().op, Op::IMulLo);
    assert_eq!(i0.fu[5].unwrap().dests[0], Some(lrf("dsq0.b", 0)));
    let i1 = &p.code[1];
    assert_eq!(
        i1.sp[0],
        Some(SpSlot {
            write: false,
            base: 17,
            offset: Some(3),
            data: 0,
            dests: [Some(lrf("add0.b", 1)), Some(lrf("add1.b", 1))],
            stage: 0
        })
    );
    assert_eq!(
        i1.comm[0],
        Some(CommSlot {
            data: 4,
            perm: Permutation::Rotate(3),
            dests: [Some(lrf("comm0.perm", 1)), None],
            stage: 0
        })
    );
    assert_eq!(i1.sin[0].unwrap().cond, None);
    assert_eq!(
        p.code[5].sin[0],
        Some(StreamIn {
            stream: 0,
            cond: Some(1),
            dests: [Some(lrf("add2.a", 1)), None],
            stage: 0
        })
    );
    let i2 = &p.code[2];
    assert_eq!(
        i2.sp[0],
        Some(SpSlot {
            write: true,
            base: 255,
            offset: None,
            data: 5,
            dests: [None; 2],
            stage: 0
        })
    );
    assert_eq!(i2.comm[0].unwrap().perm, Permutation::PerCluster(2));
    assert_eq!(i2.sin[3].unwrap().stream, 1);
    assert_eq!(i2.sout.unwrap().cond, None);
    assert_eq!(
        p.code[6].sout,
        Some(StreamOut {
            stream: 2,
            data: 15,
            cond: Some(2),
            stage: 0
        })
    );
    let i3 = &p.code[3];
    assert_eq!(i3.comm[0].unwrap().perm, Permutation::Xor(5));
    assert_eq!(i3.imm.unwrap().value, ImmValue::Const(0xFFFF_FFFF));
    assert_eq!(p.code[4].comm[0].unwrap().perm, Permutation::Broadcast(7));
    assert_eq!(p.code[4].imm.unwrap().value, ImmValue::ClusterId);
    assert_eq!(p.code[6].control, Control::DONE);
    round_trips(&p);
}

#[test]
fn immediates_parse_exactly() {
    let imm = |v: &str| match asm(&body(&format!("imm {v} -> add0.a[0]\ndone"))).code[0]
        .imm
        .unwrap()
        .value
    {
        ImmValue::Const(c) => c,
        ImmValue::ClusterId => panic!(),
    };
    assert_eq!(imm("0"), 0);
    assert_eq!(imm("42"), 42);
    assert_eq!(imm("-1"), 0xFFFF_FFFF);
    assert_eq!(imm("-2147483648"), 0x8000_0000);
    assert_eq!(imm("4294967295"), 0xFFFF_FFFF);
    assert_eq!(imm("0x7fc00000"), 0x7FC0_0000);
    assert_eq!(imm("0XDEADBEEF"), 0xDEAD_BEEF);
    assert_eq!(imm("2.5"), 0x4020_0000);
    assert_eq!(imm("-0.0"), 0x8000_0000);
    assert_eq!(imm("0.1"), 0x3DCC_CCCD, "correctly rounded");
    assert_eq!(imm("1e-45"), 1, "smallest subnormal");
    assert_eq!(imm("1.4e-45"), 1);
    assert_eq!(imm("1e10"), 1e10f32.to_bits());
    assert_eq!(imm("3.4028235e38"), 0x7F7F_FFFF);
    assert_eq!(imm("1.5E-3"), 1.5e-3f32.to_bits());
    assert_eq!(imm("1."), 0x3F80_0000);
    assert_eq!(imm("0.0e-60"), 0, "an exact zero is not an underflow");
    assert_eq!(imm("-0e5"), 0x8000_0000);
    let err = |v: &str, what: &str| {
        let text = body(&format!("imm {v} -> add0.a[0]\ndone"));
        fails(&text, 5, 5, what);
    };
    err("4294967296", "does not fit 32 bits");
    err("-2147483649", "does not fit 32 bits");
    err("0x123456789", "not a 32-bit hex number");
    err("0xg", "not a 32-bit hex number");
    err("-0x1", "without a sign");
    err("1e39", "beyond the range of fp32");
    err("1e-50", "rounds to zero");
    err("-1e-46", "rounds to zero");
    err("1.5f", "not a number");
    err("1.2.3", "not a number");
    err("12abc", "not a number");
}

#[test]
fn disassembly_is_readable() {
    let p = asm(include_str!("microcode/saxpy.uc"));
    let text = disassemble(&p, &gold8());
    let want = "\
; kernel saxpy: 4 instructions for machine `gold8`
kernel saxpy
in x
in y
out z

    imm 0x40200000 -> mul0.a[0]  ; f32 2.5
loop stream x, stages 5:
        mul0 fmul a[0], b[0] -> add0.a[0] @2 | sin0 x -> mul0.b[0]
        add0 fadd a[0], b[0] -> stream z @4 | sin1 y -> add0.b[0] @2
end
done
";
    assert_eq!(text, want);
    // Small integers are commented as integers, everything else as fp32.
    let p = asm(&body(
        "imm 7 -> add0.a[0] | add0 iadd a[0], b[0]\nimm -3 -> cc[1]\nimm 0x7fc00000 -> cc[2]\ndone",
    ));
    let text = disassemble(&p, &gold8());
    assert!(
        text.contains("    add0 iadd a[0], b[0] | imm 0x00000007 -> add0.a[0]  ; int 7\n"),
        "{text}"
    );
    assert!(
        text.contains("imm 0xfffffffd -> cc[1]  ; int -3\n"),
        "{text}"
    );
    assert!(
        text.contains("imm 0x7fc00000 -> cc[2]  ; f32 NaN\n"),
        "{text}"
    );
}

#[test]
fn nested_loops_indent_and_round_trip() {
    let p = asm(&body(
        "
        imm 0 -> cc[0]
loop count 3:
        nop
    loop until cc[0]:
            imm 1 -> cc[0]
            nop
    end
        nop
    loop count 2, stages 2:
            add0 iadd a[0], b[0] @1
            nop
    end
        nop
end
done",
    ));
    let kinds: Vec<Control> = p.code.iter().map(|i| i.control).collect();
    assert_eq!(
        kinds,
        vec![
            Control::NEXT,
            Control::begin(LoopKind::Counted(3), 1),
            Control::begin(LoopKind::UntilCc(0), 1),
            Control::END,
            Control::NEXT,
            Control::begin(LoopKind::Counted(2), 2),
            Control::END,
            Control::END,
            Control::DONE,
        ]
    );
    let text = disassemble(&p, &gold8());
    assert!(text.contains("\n    loop until cc[0]:\n            imm 0x00000001 -> cc[0]  ; int 1\n            nop\n    end\n"), "{text}");
    round_trips(&p);
}

#[test]
fn one_instruction_loop_bodies_begin_and_end_on_one_instruction() {
    let p = asm(&body(
        "
        imm 2.5 -> mul0.b[0]
loop stream x, stages 5:
        sin0 x -> mul0.a[0] | mul0 fmul a[0], b[0] -> stream y @4
end
loop count 3:
        nop
    loop count 7:
            add0 iadd a[0], b[0] -> add0.a[0]
    end
        nop
end
done",
    ));
    let kinds: Vec<Control> = p.code.iter().map(|i| i.control).collect();
    assert_eq!(
        kinds,
        vec![
            Control::NEXT,
            Control::begin_end(LoopKind::UntilStreamEmpty(0), 5),
            Control::begin(LoopKind::Counted(3), 1),
            Control::begin_end(LoopKind::Counted(7), 1),
            Control::END,
            Control::DONE,
        ]
    );
    assert_eq!(
        p.code[1].control,
        Control {
            begin: Some(LoopBegin {
                kind: LoopKind::UntilStreamEmpty(0),
                stages: 5
            }),
            end: true,
            pass_end: false,
            done: false,
        }
    );
    let text = disassemble(&p, &gold8());
    assert!(
        text.contains(
            "\nloop stream x, stages 5:\n        mul0 fmul a[0], b[0] -> stream y @4 | \
             sin0 x -> mul0.a[0]\nend\n"
        ),
        "{text}"
    );
    assert!(
        text.contains(
            "\n    loop count 7:\n            add0 iadd a[0], b[0] -> add0.a[0]\n    end\n"
        ),
        "{text}"
    );
    // The `done` after the last `end` is the short form: an empty instruction carries it.
    assert!(text.ends_with("        nop\nend\ndone\n"), "{text}");
    round_trips(&p);
    // And in binary: every word decodes to the instruction it encodes.
    let layout = InstructionLayout::new(&gold8());
    for ins in &p.code {
        assert_eq!(&layout.decode(&layout.encode(ins)).unwrap(), ins);
    }
    // A one-instruction loop right before `done`: the `done` needs an instruction of its own.
    let q = asm(&body("loop count 2:\nimm 1 -> cc[0]\nend\ndone"));
    assert_eq!(q.code.len(), 2);
    assert_eq!(
        q.code[0].control,
        Control::begin_end(LoopKind::Counted(2), 1)
    );
    assert_eq!(q.code[1].control, Control::DONE);
    assert!(q.code[1].is_empty());
    round_trips(&q);
    // …and the explicit `nop` gives the same program.
    assert_eq!(
        asm(&body("loop count 2:\nimm 1 -> cc[0]\nend\nnop\ndone")),
        q
    );
}

#[test]
fn done_after_end_adds_an_empty_instruction_and_nop_done_round_trips() {
    // `done` right after `end`: an extra empty instruction carries `done`.
    let a = asm(&body("loop count 2:\nnop\nnop\nend\ndone"));
    assert_eq!(a.code.len(), 3);
    assert_eq!(a.code[2].control, Control::DONE);
    assert!(disassemble(&a, &gold8()).ends_with("        nop\nend\ndone\n"));
    round_trips(&a);
    // Writing the `nop` explicitly gives the same program.
    assert_eq!(asm(&body("loop count 2:\nnop\nnop\nend\nnop\ndone")), a);
    // `nop` then `done` after a plain instruction: the nop is the `done` instruction.
    let b = asm(&body("imm 1 -> cc[0]\nnop\ndone"));
    assert_eq!(b.code.len(), 2);
    assert!(disassemble(&b, &gold8()).ends_with("    nop\ndone\n"));
    round_trips(&b);
    // `done` alone: one empty instruction.
    let c = asm(&body("done"));
    assert_eq!(c.code.len(), 1);
    assert_eq!(disassemble(&c, &gold8()).lines().last(), Some("done"));
    round_trips(&c);
    // `done` on an instruction with slots.
    let d = asm(&body("imm 1 -> cc[0]\ndone"));
    assert_eq!(d.code.len(), 1);
    round_trips(&d);
}

#[test]
fn comments_blank_lines_and_continuations() {
    let p = asm(
        "; header comment\n\nkernel k   ; the name\n  in x\nout y\n\n   sin0 x -> add0.a[0] |   ; first slot\n\n  imm 1 -> add0.b[0]\n\tadd0 iadd a[0], b[0] -> stream y ; tab\ndone ; end",
    );
    assert_eq!(p.code.len(), 2);
    assert!(p.code[0].sin[0].is_some() && p.code[0].imm.is_some());
    // A continued instruction still reports errors at the right line.
    fails(
        "kernel k\nin x\nsin0 x -> add0.a[0] |\n  imm 1 -> add0.q[0]\ndone",
        4,
        12,
        "`add0.q` is not an LRF of machine `gold8`",
    );
    fails("kernel k\nnop |\n", 2, 6, "ends in `|` but no slot follows");
}

#[test]
fn syntax_errors_have_line_and_column() {
    fails(
        "kernal k\ndone",
        1,
        1,
        "expected `kernel`, found `kernal`: a program starts with `kernel NAME`",
    );
    fails("", 1, 1, "empty program");
    fails(
        "kernel\ndone",
        1,
        7,
        "expected the kernel's name at the end of the line",
    );
    fails(
        "kernel k x\ndone",
        1,
        10,
        "expected the end of the line, found `x`",
    );
    fails(
        &body("add0 fadx a[0], b[0]\ndone"),
        5,
        6,
        "unknown op mnemonic `fadx`",
    );
    fails(
        &body("add3 fadd a[0], b[0]\ndone"),
        5,
        1,
        "unknown slot `add3`: the slots are add0..add2, mul0..mul1, dsq0, sp0, comm0, sin0..sin3, sout, imm",
    );
    fails(&body("sp1 ld 0\ndone"), 5, 1, "unknown slot `sp1`");
    fails(
        &body("add0 fadd a[0] b[0]\ndone"),
        5,
        16,
        "expected `,`, found `b`",
    );
    fails(
        &body("add0 fadd a[0, b[0]\ndone"),
        5,
        14,
        "expected `]`, found `,`",
    );
    fails(
        &body("add0 fadd b[0], a[0]\ndone"),
        5,
        11,
        "expected `a`, found `b`",
    );
    fails(
        &body("add0 fabs a[0], b[0]\ndone"),
        5,
        15,
        "expected `|` or the end of the instruction, found `,`",
    );
    fails(
        &body("add0 select a[0], b[0]\ndone"),
        5,
        13,
        "expected `cc`, found `a`",
    );
    fails(
        &body("add0 fadd a[0], b[0] -> zz[1]\ndone"),
        5,
        25,
        "`zz` is not an LRF",
    );
    fails(
        &body("add0 fadd a[0], b[0] -> cc[1], cc[2], cc[3]\ndone"),
        5,
        37,
        "at most two destinations",
    );
    fails(
        &body("add0 fadd a[0], b[0] -> stream q\ndone"),
        5,
        32,
        "no stream `q` is declared (declared: x, w, y)",
    );
    fails(
        &body("add0 fadd a[0], b[0] @\ndone"),
        5,
        23,
        "expected a stage at the end of the line",
    );
    fails(
        &body("add0 fadd a[0], b[0] | add0 iadd a[0], b[0]\ndone"),
        5,
        24,
        "slot `add0` appears twice",
    );
    fails(
        &body("sp0 st 0, data[1] -> add0.a[0]\ndone"),
        5,
        19,
        "a scratchpad write (`st`) has no result",
    );
    fails(
        &body("sp0 mv 0\ndone"),
        5,
        5,
        "expected `ld` or `st`, found `mv`",
    );
    fails(
        &body("comm0 data[0], spin 2\ndone"),
        5,
        16,
        "expected `rotate K`, `xor K`, `bcast K` or `perm[i]`",
    );
    fails(
        &body("imm cat -> cc[0]\ndone"),
        5,
        5,
        "expected an immediate",
    );
    fails(
        &body("add0 fadd a[70000], b[0]\ndone"),
        5,
        13,
        "too large (at most 65535)",
    );
    fails(
        &body("add0 fadd a[0x], b[0]\ndone"),
        5,
        13,
        "not a non-negative integer",
    );
    fails(
        &body("sin0 x -> add0.a[0] $\ndone"),
        5,
        21,
        "unexpected character `$`",
    );
    fails(
        &body("nop nop\ndone"),
        5,
        5,
        "expected the end of the line, found `nop`",
    );
}

#[test]
fn declarations() {
    // Declaring before instructions works; after does not; names are unique; at most 8.
    asm(&body("in z\ndone"));
    fails(
        &body("nop\nin z\ndone"),
        6,
        1,
        "streams are declared before the first instruction",
    );
    fails(
        "kernel k\nin x\nout x\ndone",
        3,
        5,
        "stream `x` is already declared",
    );
    let many: String = (0..9).map(|i| format!("in s{i}\n")).collect();
    fails(
        &format!("kernel k\n{many}done"),
        10,
        4,
        "at most 8 streams (`srf.kernel_streams`); `s8` would be stream 8",
    );
    fails("kernel k\nkernel j\ndone", 2, 1, "one program per text");
}

#[test]
fn loop_structure_errors() {
    fails(
        &body("nop\nend\ndone"),
        6,
        1,
        "`end` without an open `loop`",
    );
    fails(
        &body("loop count 2:\nend\ndone"),
        6,
        1,
        "the loop at line 5 has an empty body",
    );
    fails(
        &body("loop count 2:\nloop count 3:\nnop\nnop\nend\nend\ndone"),
        6,
        1,
        "two loops cannot begin on the same instruction",
    );
    fails(
        &body("loop count 2:\nnop\nloop count 3:\nnop\nnop\nend\nend\ndone"),
        11,
        1,
        "two loops cannot end on the same instruction",
    );
    // Nested one-instruction bodies still cannot share an instruction with their outer
    // loop's first or last.
    fails(
        &body("loop count 2:\nloop count 3:\nnop\nend\nend\ndone"),
        6,
        1,
        "two loops cannot begin on the same instruction",
    );
    fails(
        &body("loop count 2:\nnop\nloop count 3:\nnop\nend\nend\ndone"),
        10,
        1,
        "two loops cannot end on the same instruction",
    );
    fails(
        &body("loop count 2:\nnop\nnop\ndone"),
        8,
        1,
        "`done` inside the loop at line 5; close it with `end` first",
    );
    fails(
        &body("loop count 2:\nnop\nnop\n"),
        5,
        1,
        "this loop is never closed with `end`",
    );
    fails(&body("nop"), 5, 4, "the kernel does not end with `done`");
    fails(
        &body("done\nnop"),
        6,
        1,
        "nothing may follow `done` (line 5)",
    );
    fails(&body("done\ndone"), 6, 1, "nothing may follow `done`");
    fails(
        &body("loop count:\nnop\nnop\nend\ndone"),
        5,
        11,
        "expected an iteration count, found `:`",
    );
    fails(
        &body("loop count 2\nnop\nnop\nend\ndone"),
        5,
        13,
        "expected `:` at the end of the line",
    );
    fails(
        &body("loop forever:\nnop\nnop\nend\ndone"),
        5,
        6,
        "expected `count N`, `stream NAME` or `until cc[K]`",
    );
    fails(
        &body("loop count 2, stage 2:\nnop\nnop\nend\ndone"),
        5,
        15,
        "expected `stages`",
    );
    fails(
        &body("loop count 4294967296:\nnop\nnop\nend\ndone"),
        5,
        12,
        "too large",
    );
    fails(
        &body("loop stream q:\nnop\nnop\nend\ndone"),
        5,
        13,
        "no stream `q`",
    );
}

#[test]
fn check_errors_point_at_the_offending_text() {
    // An LRF entry out of range: at the operand.
    let e = fails(
        &body("nop\n  add2 fadd a[16], b[0]\ndone"),
        6,
        13,
        "kernel `k`, instruction 1, `add2.a`: entry 16 is out of range",
    );
    assert_eq!(e.check.unwrap().instruction, Some(1));
    // The wrong unit: at the mnemonic.
    fails(
        &body("mul0 fadd a[0], b[0]\ndone"),
        5,
        6,
        "`fadd` runs on an adder, but `mul0` is a multiplier",
    );
    // A stage outside a software-pipelined loop: at the `@`.
    fails(
        &body("add0 fadd a[0], b[0] @1\ndone"),
        5,
        22,
        "stage 1 is out of range",
    );
    fails(
        &body("loop count 2, stages 2:\nadd0 fadd a[0], b[0] @2\nnop\nend\ndone"),
        6,
        22,
        "the loop has 2 stages",
    );
    // Destinations: at the destination.
    fails(
        &body("imm 1 -> cc[1], cc[16]\ndone"),
        5,
        17,
        "`imm.dest1`: condition code 16 is out of range",
    );
    fails(
        &body("imm 1 -> add0.a[32]\ndone"),
        5,
        10,
        "`imm.dest0`: entry 32 is out of range",
    );
    fails(
        &body("imm 1 -> add0.a[1], add0.a[2]\ndone"),
        5,
        21,
        "both destinations write LRF `add0.a`",
    );
    fails(
        &body("imm 1 -> stream x\ndone"),
        5,
        10,
        "stream 0 `x` is an input stream",
    );
    // Streams in the wrong direction: at the stream name.
    fails(
        &body("sin0 y -> cc[0]\ndone"),
        5,
        6,
        "reads an input stream, but stream 2 `y` is an output stream",
    );
    fails(
        &body("sout x, data[0]\ndone"),
        5,
        6,
        "writes an output stream",
    );
    fails(
        &body("nop\nloop stream y:\nnop\nnop\nend\ndone"),
        6,
        1,
        "`ctl.value`: reads an input stream",
    );
    // Bandwidth: at the sout.
    fails(
        &body("sin0 x | sin1 x | sin2 x | sin3 w | sout y, data[0]\ndone"),
        5,
        37,
        "moves 5 stream words",
    );
    fails(
        &body("sin0 x if cc[0] | sin1 x if cc[1]\ndone"),
        5,
        19,
        "2 conditional stream words",
    );
    // Scratchpads, condition codes, permutations.
    fails(&body("sp0 ld 256\ndone"), 5, 8, "base 256 is out of range");
    fails(
        &body("sp0 st 0, addr[16], data[0]\ndone"),
        5,
        11,
        "LRF `sp0.addr` has 16 entries",
    );
    fails(
        &body("add0 select cc[16], a[0], b[0]\ndone"),
        5,
        13,
        "condition code 16",
    );
    fails(
        &body("comm0 data[0], rotate 8\ndone"),
        5,
        16,
        "`rotate 8` names cluster 8",
    );
    fails(&body("sin0 x if cc[17]\ndone"), 5, 11, "condition code 17");
    // Loop headers: at the `loop` line.
    fails(
        &body("nop\nloop until cc[1], stages 2:\nnop\nnop\nend\ndone"),
        6,
        1,
        "`until cc` loop cannot be software-pipelined",
    );
    fails(
        &body("nop\nloop count 1, stages 17:\nnop\nnop\nend\ndone"),
        6,
        1,
        "1..=16 software-pipeline stages, not 17",
    );
    let nested = "loop count 2:\nnop\n".repeat(5) + &"nop\nend\n".repeat(5);
    fails(&body(&format!("{nested}done")), 13, 1, "nested 5 deep");
}

#[test]
fn the_microcode_store_limit_is_reported_at_the_kernel() {
    let text = body(&format!("{}done", "nop\n".repeat(2049)));
    fails(
        &text,
        1,
        1,
        "kernel `k` needs 2049 instructions; the microcode store holds 2048",
    );
    assert_eq!(
        asm(&body(&format!("{}done", "nop\n".repeat(2048))))
            .code
            .len(),
        2048
    );
}

#[test]
fn the_same_text_fits_some_machines_and_not_others() {
    let text = body("add5 fadd a[0], b[0] | comm2 data[0], rotate 1\ndone");
    let fc = MachineDesc::resolve("gold8+F+C").unwrap();
    let p = assemble(&text, &fc).unwrap();
    assert_eq!(p.code[0].fu.len(), 6 + 4 + 1);
    assert!(assemble(&text, &gold8()).is_err());
    let e = assemble(
        &body("comm0 data[0], rotate 1\ndone"),
        &MachineDesc::resolve("gold1").unwrap(),
    )
    .unwrap_err();
    assert!(e.message.contains("the machine has 1 cluster"), "{e}");
}

#[test]
fn pass_lines_end_passes_of_the_innermost_loop() {
    // Two copies of a kernel (modulo variable expansion): `pass` marks the first's last
    // instruction.
    let p = asm(&body(
        "loop count 4, stages 2:
             add0 iadd a[0], b[0] -> add0.a[1]
             nop
         pass
             add0 iadd a[1], b[0] -> add0.a[0] @1
         end
         done",
    ));
    let kinds: Vec<Control> = p.code.iter().map(|i| i.control).collect();
    assert_eq!(
        kinds,
        [
            Control::begin(LoopKind::Counted(4), 2),
            Control::PASS_END,
            Control::END,
            Control::DONE
        ]
    );
    let text = disassemble(&p, &gold8());
    assert!(
        text.contains("        nop\npass\n        add0 iadd a[1], b[0] -> add0.a[0] @1\nend\n"),
        "{text}"
    );
    round_trips(&p);
    // A first pass of one instruction, passes of one instruction, and a `pass` of an inner
    // loop (indented with it).
    let p = asm(&body(
        "loop stream x:
             sin0 x -> stream y
         pass
             sin0 x -> stream y
         pass
             loop count 3:
                 nop
             pass
                 nop
             end
             sin1 x -> stream y
         end
         done",
    ));
    let kinds: Vec<Control> = p.code.iter().map(|i| i.control).collect();
    assert_eq!(
        kinds,
        [
            Control::begin_pass_end(LoopKind::UntilStreamEmpty(0), 1),
            Control::PASS_END,
            Control::begin_pass_end(LoopKind::Counted(3), 1),
            Control::END,
            Control::END,
            Control::DONE
        ]
    );
    let text = disassemble(&p, &gold8());
    assert!(
        text.contains("    loop count 3:\n            nop\n    pass\n            nop\n    end\n"),
        "{text}"
    );
    round_trips(&p);
    // In the binary word too.
    let layout = InstructionLayout::new(&gold8());
    for ins in &p.code {
        assert_eq!(&layout.decode(&layout.encode(ins)).unwrap(), ins);
    }
}

#[test]
fn pass_errors() {
    fails(
        &body("nop\npass\ndone"),
        6,
        1,
        "`pass` outside a loop; it ends a pass of the innermost loop's body",
    );
    fails(
        &body("loop count 2:\nnop\nend\npass\ndone"),
        8,
        1,
        "`pass` outside a loop",
    );
    fails(
        &body("loop count 2:\npass\nnop\nend\ndone"),
        6,
        1,
        "`pass` right after the `loop` at line 5: the pass has no instruction",
    );
    fails(
        &body("loop count 2:\nnop\npass\npass\nnop\nend\ndone"),
        8,
        1,
        "no instruction since the `pass` at line 7: a pass holds at least one instruction",
    );
    fails(
        &body("loop count 2:\nnop\npass\nend\ndone"),
        8,
        1,
        "`end` right after the `pass` at line 7: the loop's last pass would be empty, and one \
         instruction would end both a pass and the loop; drop that `pass`",
    );
    // An inner loop's `pass` then its `end`: the same, for the inner loop.
    fails(
        &body("loop count 2:\nnop\nloop count 3:\nnop\npass\nend\nnop\nend\ndone"),
        10,
        1,
        "`end` right after the `pass` at line 9",
    );
    fails(
        &body("loop count 2:\nnop\nloop count 3:\nnop\nend\npass\nnop\nend\ndone"),
        10,
        1,
        "the previous instruction ends an inner loop, so it cannot end a pass of this one too",
    );
    fails(
        &body("loop count 2:\nnop\npass 2\nnop\nend\ndone"),
        7,
        6,
        "expected the end of the line, found `2`",
    );
    fails(
        &body("loop count 2:\nnop\npass\nnop\ndone"),
        9,
        1,
        "`done` inside the loop at line 5",
    );
    // Check errors about passes point at the `pass` or `end` line of the pass.
    let e = fails(
        &body("loop stream x, stages 2:\nsin0 x\nsin1 x\npass\nsin0 x\nend\ndone"),
        10,
        1,
        "instruction 2, `ctl.end`: the pass of instructions 2..=2 reads 1 unconditional word \
         of stream `x` per cluster, but the loop's first pass (instructions 0..=1) reads 2",
    );
    assert_eq!(e.check.unwrap().field.as_deref(), Some("ctl.end"));
    fails(
        &body("loop stream x, stages 2:\nsin0 x\npass\nsin0 x | sin1 x\npass\nsin0 x\nend\ndone"),
        9,
        1,
        "instruction 1, `ctl.pass`: the pass of instructions 1..=1 reads 2 unconditional words",
    );
}

/// Found by fuzzing (`fuzz/fuzz_targets/asm.rs`): the destination of a `perm[i]`
/// communication slot was not checked, and encoding the program panicked on the entry
/// that does not fit its field (the minimised input).
#[test]
fn a_per_cluster_communication_is_refused_a_destination_beyond_its_lrf() {
    let text = "kernel k\nin x\nout s\n    comm0 data[1], perm[3] -> add0.b[40]\ndone\n";
    let e = assemble(text, &gold8()).expect_err("must not assemble");
    assert_eq!(e.line, 4, "{e}");
    assert!(
        e.message
            .contains("entry 40 is out of range: LRF `add0.b` has 16 entries"),
        "{e}"
    );
}
