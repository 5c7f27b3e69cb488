//! The binary microcode word: field table snapshot for gold8 (`tests/microcode/gold8.layout`,
//! regenerate with `UPDATE_SNAPSHOTS=1`), widths derived from the machine description,
//! fields that tile the word, and decode/encode errors that name the field.

use imagine_hdl::{WideWord, wide_word};
use imagine_units::desc::MachineDesc;
use imagine_units::microcode::{
    Control, Dest, FuSlot, ImmValue, Immediate, Instruction, InstructionLayout, LoopBegin, LoopKind,
};
use imagine_units::ops::Op;

const SNAPSHOT: &str = "tests/microcode/gold8.layout";

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

fn set(layout: &InstructionLayout, w: &mut WideWord, name: &str, value: u64) {
    let f = layout
        .field(name)
        .unwrap_or_else(|| panic!("no field {name}"));
    for b in 0..f.width {
        w.set(f.offset + b, (value >> b) & 1 == 1);
    }
}

#[test]
fn gold8_field_table_matches_the_snapshot() {
    let layout = InstructionLayout::new(&MachineDesc::gold8());
    assert_eq!(layout.width(), 648, "gold8 instruction width");
    let table = layout.describe();
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(SNAPSHOT);
    if std::env::var_os("UPDATE_SNAPSHOTS").is_some() {
        std::fs::write(&path, &table).unwrap();
    }
    let want = std::fs::read_to_string(&path).expect("snapshot exists (UPDATE_SNAPSHOTS=1)");
    assert_eq!(
        table, want,
        "field table changed; review and regenerate the snapshot"
    );
    assert!(table.starts_with("microcode word of machine `gold8`: 648 bits"));
}

#[test]
fn fields_tile_the_word_and_have_unique_names() {
    for name in ["gold8", "gold1", "gold8+F", "gold8+C", "gold32combo"] {
        let layout = InstructionLayout::new(&MachineDesc::resolve(name).unwrap());
        let mut next = 0;
        let mut names = std::collections::HashSet::new();
        for f in layout.fields() {
            assert_eq!(
                f.offset, next,
                "{name}: {} does not follow its predecessor",
                f.name
            );
            assert!(f.width >= 1, "{name}: {}", f.name);
            assert!(names.insert(f.name.clone()), "{name}: {} twice", f.name);
            next += f.width;
        }
        assert_eq!(next, layout.width(), "{name}");
    }
}

#[test]
fn widths_follow_the_machine_description() {
    let gold8 = InstructionLayout::new(&MachineDesc::gold8());
    let w = |l: &InstructionLayout, n: &str| l.field(n).unwrap().width;
    assert_eq!(w(&gold8, "add0.op"), Op::OPCODE_BITS as usize);
    assert_eq!(w(&gold8, "add0.a"), 5, "32-entry LRFs");
    assert_eq!(w(&gold8, "add0.cc"), 4, "16 condition codes");
    assert!(gold8.field("mul0.cc").is_none(), "only adders run select");
    assert_eq!(w(&gold8, "add0.dest0.kind"), 2);
    assert_eq!(w(&gold8, "add0.dest0.lrf"), 5, "17 LRFs");
    assert_eq!(w(&gold8, "add0.dest0.index"), 5);
    assert_eq!(w(&gold8, "add0.stage"), 4, "16 stages");
    assert_eq!(w(&gold8, "sp0.base"), 8, "256-word scratchpad");
    assert_eq!(w(&gold8, "sin0.stream"), 3, "8 kernel streams");
    assert_eq!(w(&gold8, "comm0.perm"), 5);
    assert_eq!(w(&gold8, "imm.value"), 32);
    assert_eq!(w(&gold8, "ctl.value"), 32);
    for one_bit in ["ctl.begin", "ctl.end", "ctl.done"] {
        assert_eq!(w(&gold8, one_bit), 1, "{one_bit}");
    }
    assert!(gold8.field("sin3.valid").is_some() && gold8.field("sin4.valid").is_none());

    // More units, more slots; more LRFs, a wider LRF index.
    let f = InstructionLayout::new(&MachineDesc::resolve("gold8+F").unwrap());
    assert!(f.field("add5.op").is_some() && f.field("mul3.op").is_some());
    assert_eq!(w(&f, "add0.dest0.lrf"), 5, "27 LRFs");
    let c = InstructionLayout::new(&MachineDesc::resolve("gold8+C").unwrap());
    assert!(c.field("sp2.base").is_some() && c.field("comm2.perm").is_some());
    let one = InstructionLayout::new(&MachineDesc::resolve("gold1").unwrap());
    assert_eq!(
        one.width(),
        gold8.width(),
        "perm constants share the entry-sized field"
    );
    let big = MachineDesc::parse(
        "name = \"big\"\nbase = \"gold8\"\n[scratchpad]\nwords = 512\n[lrf]\nentries = 64\nlarge_entries = 128\nlarge = []",
        "big",
    )
    .unwrap();
    let big = InstructionLayout::new(&big);
    assert_eq!(w(&big, "sp0.base"), 9);
    assert_eq!(w(&big, "add0.a"), 6, "largest LRF has 64 entries");
}

#[test]
fn describe_lists_every_field_once() {
    let layout = InstructionLayout::new(&MachineDesc::resolve("gold8+C").unwrap());
    let text = layout.describe();
    for f in layout.fields() {
        let line = format!("  {}  ", f.name);
        assert_eq!(text.matches(&line).count(), 1, "{}", f.name);
    }
}

#[test]
fn decode_rejects_bad_opcodes_loop_kinds_and_widths() {
    let desc = MachineDesc::gold8();
    let layout = InstructionLayout::new(&desc);

    let mut w = wide_word(layout.width());
    set(&layout, &mut w, "mul1.valid", 1);
    set(&layout, &mut w, "mul1.op", Op::ALL.len() as u64);
    let e = layout.decode(&w).unwrap_err();
    assert_eq!(e.field.as_deref(), Some("mul1.op"));
    assert!(e.to_string().contains("names no op"), "{e}");
    // The same bits in an empty slot are ignored.
    set(&layout, &mut w, "mul1.valid", 0);
    assert_eq!(layout.decode(&w).unwrap(), empty(&desc));

    let mut w = wide_word(layout.width());
    set(&layout, &mut w, "ctl.begin", 1);
    set(&layout, &mut w, "ctl.loop", 3);
    let e = layout.decode(&w).unwrap_err();
    assert_eq!(e.field.as_deref(), Some("ctl.loop"));
    assert!(e.to_string().contains("`ctl.loop`"), "{e}");
    // Without `ctl.begin` the loop fields are ignored, like an empty slot's.
    set(&layout, &mut w, "ctl.begin", 0);
    assert_eq!(layout.decode(&w).unwrap(), empty(&desc));

    let e = layout.decode(&wide_word(layout.width() - 1)).unwrap_err();
    assert!(e.to_string().contains("647 bits wide"), "{e}");
}

#[test]
fn decode_reads_fields_where_describe_says() {
    let desc = MachineDesc::gold8();
    let layout = InstructionLayout::new(&desc);
    let mut w = wide_word(layout.width());
    set(&layout, &mut w, "ctl.begin", 1);
    set(&layout, &mut w, "ctl.loop", 0);
    set(&layout, &mut w, "ctl.stages", 2);
    set(&layout, &mut w, "ctl.value", 1000);
    set(&layout, &mut w, "ctl.end", 1);
    set(&layout, &mut w, "add2.valid", 1);
    set(&layout, &mut w, "add2.op", u64::from(Op::Select.opcode()));
    set(&layout, &mut w, "add2.a", 31);
    set(&layout, &mut w, "add2.b", 15);
    set(&layout, &mut w, "add2.cc", 9);
    set(&layout, &mut w, "add2.dest1.kind", 2);
    set(&layout, &mut w, "add2.dest1.index", 4);
    set(&layout, &mut w, "add2.dest0.kind", 1);
    set(&layout, &mut w, "add2.dest0.lrf", 16);
    set(&layout, &mut w, "add2.dest0.index", 7);
    set(&layout, &mut w, "add2.stage", 2);
    set(&layout, &mut w, "imm.valid", 1);
    set(&layout, &mut w, "imm.kind", 1);
    let ins = layout.decode(&w).unwrap();
    let mut want = empty(&desc);
    want.control = Control {
        begin: Some(LoopBegin {
            kind: LoopKind::Counted(1000),
            stages: 3,
        }),
        end: true,
        pass_end: false,
        done: false,
    };
    want.fu[2] = Some(FuSlot {
        op: Op::Select,
        a: 31,
        b: 15,
        cc: 9,
        dests: [
            Some(Dest::Lrf { lrf: 16, entry: 7 }),
            Some(Dest::Cc { index: 4 }),
        ],
        stage: 2,
    });
    want.imm = Some(Immediate {
        value: ImmValue::ClusterId,
        dests: [None; 2],
        stage: 0,
    });
    assert_eq!(ins, want);
    assert_eq!(layout.encode(&ins), w);
}

#[test]
fn encode_reports_values_that_do_not_fit() {
    let desc = MachineDesc::gold8();
    let layout = InstructionLayout::new(&desc);
    let mut ins = empty(&desc);
    ins.fu[0] = Some(FuSlot {
        op: Op::FAdd,
        a: 32,
        b: 0,
        cc: 0,
        dests: [None; 2],
        stage: 0,
    });
    let e = layout.try_encode(&ins).unwrap_err();
    assert_eq!(e.field.as_deref(), Some("add0.a"));
    assert!(
        e.to_string().contains("does not fit the 5-bit field"),
        "{e}"
    );

    let mut ins = empty(&desc);
    ins.fu[3] = Some(FuSlot {
        op: Op::FMul,
        a: 0,
        b: 0,
        cc: 1,
        dests: [None; 2],
        stage: 0,
    });
    let e = layout.try_encode(&ins).unwrap_err();
    assert_eq!(e.field.as_deref(), Some("mul0.cc"));

    let mut ins = empty(&desc);
    ins.sin.pop();
    let e = layout.try_encode(&ins).unwrap_err();
    assert!(e.to_string().contains("`sin`: has 3 slots"), "{e}");

    let mut ins = empty(&desc);
    ins.control = Control::begin(LoopKind::Counted(1), 17);
    let e = layout.try_encode(&ins).unwrap_err();
    assert_eq!(e.field.as_deref(), Some("ctl.stages"));
}

#[test]
#[should_panic(expected = "cannot encode instruction")]
fn encode_panics_on_what_check_rejects() {
    let desc = MachineDesc::gold8();
    let mut ins = empty(&desc);
    ins.fu.clear();
    InstructionLayout::new(&desc).encode(&ins);
}

#[test]
fn control_bits_are_independent() {
    let desc = MachineDesc::gold8();
    let layout = InstructionLayout::new(&desc);
    let controls = [
        Control::NEXT,
        Control::END,
        Control::DONE,
        Control::begin(LoopKind::UntilStreamEmpty(3), 8),
        Control::begin_end(LoopKind::UntilCc(15), 1),
        Control::begin_end(LoopKind::Counted(u32::MAX), 5),
        Control::PASS_END,
        Control::begin_pass_end(LoopKind::UntilStreamEmpty(1), 2),
    ];
    for control in controls {
        let ins = Instruction {
            control,
            ..empty(&desc)
        };
        let w = layout.encode(&ins);
        assert_eq!(layout.decode(&w).unwrap(), ins, "{control:?}");
        let bit = |name: &str| {
            let f = layout.field(name).unwrap();
            w[f.offset]
        };
        assert_eq!(bit("ctl.begin"), control.begin.is_some(), "{control:?}");
        assert_eq!(bit("ctl.end"), control.end, "{control:?}");
        assert_eq!(bit("ctl.pass"), control.pass_end, "{control:?}");
        assert_eq!(bit("ctl.done"), control.done, "{control:?}");
    }
}

#[test]
fn pass_bit_is_one_bit_after_end_and_decodes_where_describe_says() {
    let desc = MachineDesc::gold8();
    let layout = InstructionLayout::new(&desc);
    let end = layout.field("ctl.end").unwrap();
    let pass = layout.field("ctl.pass").unwrap();
    assert_eq!((pass.width, pass.offset), (1, end.offset + 1));
    assert_eq!(layout.field("ctl.done").unwrap().offset, pass.offset + 1);
    // The bit alone is a pass end and nothing else.
    let mut w = wide_word(layout.width());
    set(&layout, &mut w, "ctl.pass", 1);
    let ins = layout.decode(&w).unwrap();
    assert_eq!(ins.control, Control::PASS_END);
    assert_eq!(layout.encode(&ins), w);
    // With a loop begin: a first pass of one instruction.
    set(&layout, &mut w, "ctl.begin", 1);
    set(&layout, &mut w, "ctl.loop", 1);
    set(&layout, &mut w, "ctl.stages", 3);
    set(&layout, &mut w, "ctl.value", 2);
    let ins = layout.decode(&w).unwrap();
    assert_eq!(
        ins.control,
        Control::begin_pass_end(LoopKind::UntilStreamEmpty(2), 4)
    );
    assert_eq!(layout.encode(&ins), w);
    // Decoding does not judge combinations (the check does): `pass` with `end` reads back.
    set(&layout, &mut w, "ctl.end", 1);
    let ins = layout.decode(&w).unwrap();
    assert!(ins.control.pass_end && ins.control.end);
    assert_eq!(layout.encode(&ins), w);
    // Every machine's word has the bit.
    for name in ["gold1", "gold8+F", "gold8+C", "gold32combo"] {
        let l = InstructionLayout::new(&MachineDesc::resolve(name).unwrap());
        assert_eq!(l.field("ctl.pass").map(|f| f.width), Some(1), "{name}");
    }
}
