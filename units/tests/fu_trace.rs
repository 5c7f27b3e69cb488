//! The units inside an hdl `Design`: a module issues to an adder, a multiplier and a
//! divide/sqrt unit every cycle it may and collects their results; a recording tracer checks
//! that the per-cluster probes exist with their real widths and that the stage registers
//! change as ops move through.

use std::collections::{BTreeMap, BTreeSet};

use imagine_hdl::{
    ContractError, Design, DomainId, Module, Recorder, SignalKind, Sim, Trace, default_domains,
};
use imagine_units::desc::MachineDesc;
use imagine_units::fu::{Adder, DivSqrt, Issue, Multiplier};
use imagine_units::ops::Op;

const LANES: usize = 8;

/// One cluster column of functional units and the microcode that drives them.
struct Fus {
    domain: DomainId,
    mode: imagine_units::arith::fp32::FpMode,
    add: Adder,
    mul: Multiplier,
    dsq: DivSqrt,
    cycle: u32,
    /// Operands by tag, to check results.
    issued: BTreeMap<u16, (Op, Vec<u32>, Vec<u32>)>,
    next_tag: u16,
    checked: usize,
}

impl Fus {
    fn operands(&self, k: u32) -> (Vec<u32>, Vec<u32>) {
        let a = (0..LANES as u32)
            .map(|l| 0x3F80_0000 + (k * 977 + l * 131) % 0x0100_0000)
            .collect();
        let b = (0..LANES as u32)
            .map(|l| 0x4000_0000 + (k * 313 + l * 71) % 0x0080_0000)
            .collect();
        (a, b)
    }

    fn check(
        issued: &mut BTreeMap<u16, (Op, Vec<u32>, Vec<u32>)>,
        mode: imagine_units::arith::fp32::FpMode,
        c: imagine_units::fu::Completion<'_>,
    ) {
        let (op, a, b) = issued.remove(&c.tag).expect("issued tag");
        assert_eq!(op, c.op);
        for l in 0..LANES {
            assert_eq!(
                (c.values[l], c.flags[l]),
                op.eval(a[l], b[l], 0, mode),
                "{op}"
            );
        }
    }
}

impl Module for Fus {
    fn domain(&self) -> DomainId {
        self.domain
    }

    fn eval(&mut self) -> Result<(), ContractError> {
        let mode = self.mode;
        for c in [
            self.add.completed(),
            self.mul.completed(),
            self.dsq.completed(),
        ]
        .into_iter()
        .flatten()
        {
            Self::check(&mut self.issued, mode, c);
            self.checked += 1;
        }
        let t = self.cycle;
        // Adder: fadd, with a bubble every 6th cycle that lets an iadd (2 cycles, not 4)
        // issue two cycles later without a writeback conflict.
        let mut plan = vec![];
        match t % 6 {
            0 => {}
            2 => plan.push((0, Op::IAdd)),
            _ => plan.push((0, Op::FAdd)),
        }
        if t & 1 == 0 {
            plan.push((1, Op::FMul));
        }
        if self.dsq.can_issue(Op::FDiv) {
            plan.push((2, if t & 15 == 0 { Op::FDiv } else { Op::FSqrt }));
        }
        for (unit, op) in plan {
            let (a, b) = self.operands(t * 3 + unit);
            let tag = self.next_tag;
            self.next_tag += 1;
            let is = Issue::binary(op, &a, &b, tag);
            match unit {
                0 => self.add.issue(is)?,
                1 => self.mul.issue(is)?,
                _ => self.dsq.issue(is)?,
            }
            let b = if op.arity() == 1 { vec![0; LANES] } else { b };
            self.issued.insert(tag, (op, a, b));
        }
        self.cycle += 1;
        Ok(())
    }

    fn commit(&mut self) {
        self.add.commit();
        self.mul.commit();
        self.dsq.commit();
    }

    fn trace(&self, t: &mut Trace) {
        self.add.trace(t);
        self.mul.trace(t);
        self.dsq.trace(t);
    }
}

#[test]
fn units_in_a_design_trace_their_stage_registers() {
    let desc = MachineDesc::gold8();
    let mut design = Design::new("top", default_domains()).unwrap();
    let core = design.domain("core").unwrap();
    let fus = {
        let mut top = design.scope();
        Fus {
            domain: core,
            mode: desc.fp_mode(),
            add: Adder::new(&mut top, "add0", LANES, &desc),
            mul: Multiplier::new(&mut top, "mul0", LANES, &desc),
            dsq: DivSqrt::new(&mut top, "dsq0", LANES, &desc),
            cycle: 0,
            issued: BTreeMap::new(),
            next_tag: 0,
            checked: 0,
        }
    };
    design.add(fus);
    let mut sim = Sim::new(design);
    let recorder = Recorder::default();
    sim.attach(Box::new(recorder.clone())).unwrap();
    sim.run_core_cycles(200, |_| {}).unwrap();
    sim.finish().unwrap();

    let fus = sim.modules_of::<Fus>().next().unwrap();
    assert!(fus.checked > 250, "{} results checked", fus.checked);

    let recording = recorder.recording();
    let reg = &recording.probes;
    let sig = |path: &str| {
        let id = reg.find(path).unwrap_or_else(|| panic!("no probe {path}"));
        (id, reg.get(id).width, reg.get(id).kind)
    };
    let op_bits = Op::OPCODE_BITS;
    for c in 0..LANES {
        for (path, width) in [
            (format!("top.cluster{c}.add0.op"), op_bits),
            (format!("top.cluster{c}.add0.issue"), 1),
            (format!("top.cluster{c}.add0.a"), 32),
            (format!("top.cluster{c}.add0.b"), 32),
            (format!("top.cluster{c}.add0.c"), 32),
            (format!("top.cluster{c}.add0.result"), 32),
            (format!("top.cluster{c}.add0.flags"), 5),
            (format!("top.cluster{c}.add0.valid"), 1),
            (format!("top.cluster{c}.add0.stage1.valid"), 1),
            (format!("top.cluster{c}.add0.stage4.op"), op_bits),
            (format!("top.cluster{c}.mul0.stage4.valid"), 1),
            (format!("top.cluster{c}.dsq0.core.valid"), 1),
            (format!("top.cluster{c}.dsq0.core.op"), op_bits),
            (format!("top.cluster{c}.dsq0.core.rem"), 26),
            (format!("top.cluster{c}.dsq0.core.quotient"), 25),
            (format!("top.cluster{c}.dsq0.core.step"), 4),
            (format!("top.cluster{c}.dsq0.stage9.valid"), 1),
            (format!("top.cluster{c}.dsq0.stage16.op"), op_bits),
        ] {
            let (_, w, kind) = sig(&path);
            assert_eq!(w, width, "{path}");
            assert_eq!(kind, SignalKind::Reg, "{path}");
        }
    }
    // Stages exist exactly up to the longest latency; the multiplier has no `c` port; the
    // divide/sqrt unit's stages 1..=8 are its recurrence core.
    for missing in [
        "top.cluster0.add0.stage5.valid",
        "top.cluster0.mul0.c",
        "top.cluster0.dsq0.stage8.valid",
        "top.cluster0.dsq0.stage17.valid",
    ] {
        assert!(reg.find(missing).is_none(), "{missing}");
    }

    let seen = |path: &str| -> Vec<u64> {
        let values = recording
            .values(path)
            .unwrap_or_else(|| panic!("no probe {path}"));
        assert!(!values.is_empty(), "{path} never reported");
        values
    };
    let distinct = |path: &str| seen(path).into_iter().collect::<BTreeSet<_>>();
    // Stage valid bits toggle (bubbles in the adder around iadd), stage ops carry both ops.
    for k in 1..=4 {
        let v = distinct(&format!("top.cluster5.add0.stage{k}.valid"));
        assert_eq!(v, BTreeSet::from([0, 1]), "stage{k}.valid");
    }
    let ops = distinct("top.cluster5.add0.stage2.op");
    assert!(ops.contains(&u64::from(Op::FAdd.opcode())));
    assert!(ops.contains(&u64::from(Op::IAdd.opcode())));
    // iadd leaves from stage 2, so stage 3 and 4 only ever hold fadd.
    assert_eq!(
        distinct("top.cluster5.add0.stage4.op"),
        BTreeSet::from([u64::from(Op::FAdd.opcode())])
    );
    // The recurrence core steps 2 digits per cycle: 2, 4, …, 12.
    let steps = distinct("top.cluster1.dsq0.core.step");
    assert_eq!(steps, BTreeSet::from([2, 4, 6, 8, 10, 12]));
    assert!(distinct("top.cluster1.dsq0.core.rem").len() > 10);
    assert!(distinct("top.cluster1.dsq0.core.quotient").len() > 10);
    let core_ops = distinct("top.cluster1.dsq0.core.op");
    assert_eq!(
        core_ops,
        BTreeSet::from([u64::from(Op::FDiv.opcode()), u64::from(Op::FSqrt.opcode())])
    );
    // Results reach the probes and differ per cluster.
    assert!(distinct("top.cluster0.add0.result").len() > 50);
    assert_ne!(
        seen("top.cluster0.mul0.result"),
        seen("top.cluster1.mul0.result")
    );
    assert_eq!(
        distinct("top.cluster2.mul0.stage1.valid"),
        BTreeSet::from([0, 1])
    );
}
