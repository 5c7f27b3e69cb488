//! Round trips of the microcode formats on random valid programs: binary
//! (`InstructionLayout::encode` → `decode`) and text (`disassemble` → `assemble`), on gold8,
//! gold1, gold8+F and gold8+C; and decoding random words never panics.

use imagine_units::arith::fp32::testgen::SplitMix64;
use imagine_units::desc::MachineDesc;
use imagine_units::microcode::check::Shape;
use imagine_units::microcode::*;
use imagine_units::microcode::{
    CommSlot, Control, Dest, Dests, FuSlot, ImmValue, Immediate, Instruction, LoopKind,
    Permutation, Program, SpSlot, StreamDecl, StreamDir, StreamIn, StreamOut,
};
use imagine_units::ops::{Op, UnitClass};
use proptest::prelude::*;

const MACHINES: &[&str] = &["gold8", "gold1", "gold8+F", "gold8+C"];

struct Gen<'a> {
    rng: SplitMix64,
    sh: Shape,
    desc: &'a MachineDesc,
    streams: Vec<StreamDecl>,
}

impl Gen<'_> {
    fn below(&mut self, n: usize) -> usize {
        self.rng.below(n as u32) as usize
    }

    fn chance(&mut self, percent: u32) -> bool {
        self.rng.below(100) < percent
    }

    fn pick<T: Copy>(&mut self, items: &[T]) -> T {
        items[self.below(items.len())]
    }

    fn streams_of(&self, dir: StreamDir) -> Vec<u16> {
        (0..self.streams.len())
            .filter(|&i| self.streams[i].dir == dir)
            .map(|i| i as u16)
            .collect()
    }

    fn entry(&mut self, slot: &str, input: &str) -> u16 {
        let (_, size) = self.sh.lrf(slot, input);
        self.below(size) as u16
    }

    fn cc(&mut self) -> u16 {
        self.below(self.sh.condition_codes) as u16
    }

    fn dest(&mut self) -> Option<Dest> {
        let outs = self.streams_of(StreamDir::Out);
        match self.below(10) {
            0..=5 => {
                let lrf = self.below(self.sh.lrf_names.len());
                let entry = self.below(self.sh.lrf_sizes[lrf]) as u16;
                Some(Dest::Lrf {
                    lrf: lrf as u16,
                    entry,
                })
            }
            6 | 7 => Some(Dest::Cc { index: self.cc() }),
            _ if !outs.is_empty() => Some(Dest::Stream {
                stream: self.pick(&outs),
            }),
            _ => None,
        }
    }

    fn dests(&mut self) -> Dests {
        let mut d = [None; 2];
        let n = self.pick(&[0, 1, 1, 2, 2]);
        if n >= 1 {
            d[0] = self.dest();
        }
        if n == 2 && d[0].is_some() {
            let second = self.dest();
            let clash = match (d[0], second) {
                (Some(Dest::Lrf { lrf: a, .. }), Some(Dest::Lrf { lrf: b, .. })) => a == b,
                (a, b) => a == b,
            };
            if !clash {
                d[1] = second;
            }
        }
        d
    }

    fn imm_value(&mut self) -> ImmValue {
        match self.below(6) {
            0 => ImmValue::ClusterId,
            1 => ImmValue::Const(self.pick(&[
                0,
                1,
                u32::MAX,
                0x8000_0000,
                0x7FC0_0000,
                0x4020_0000,
                0x0000_0001,
                0xFFFF_0000,
                65536,
                65537,
            ])),
            2 => ImmValue::Const(self.below(100) as u32),
            _ => ImmValue::Const(self.rng.next_u32()),
        }
    }

    /// A random instruction valid inside a loop of `stages` stages (1 outside loops).
    fn instruction(&mut self, stages: u8, fullness: u32) -> Instruction {
        let sh = self.sh.clone();
        let stage = |g: &mut Self| g.below(usize::from(stages)) as u8;
        let mut ins = Instruction {
            control: Control::NEXT,
            fu: vec![None; sh.fu_count()],
            sp: vec![None; sh.scratchpads],
            comm: vec![None; sh.comm_units],
            sin: vec![None; sh.stream_ins],
            sout: None,
            imm: None,
        };
        for k in 0..sh.fu_count() {
            if !self.chance(fullness) {
                continue;
            }
            let class = sh.fu_class(k);
            let ops: Vec<Op> = Op::ALL
                .iter()
                .copied()
                .filter(|o| o.unit() == class)
                .collect();
            let op = self.pick(&ops);
            let name = sh.fu_name(k);
            let a = self.entry(&name, "a");
            let b = if op.arity() >= 2 {
                self.entry(&name, "b")
            } else {
                0
            };
            let cc = if op == Op::Select { self.cc() } else { 0 };
            ins.fu[k] = Some(FuSlot {
                op,
                a,
                b,
                cc,
                dests: self.dests(),
                stage: stage(self),
            });
        }
        for k in 0..sh.scratchpads {
            if !self.chance(fullness) {
                continue;
            }
            let name = format!("sp{k}");
            let write = self.chance(50);
            let offset = if self.chance(60) {
                Some(self.entry(&name, "addr"))
            } else {
                None
            };
            ins.sp[k] = Some(SpSlot {
                write,
                base: self.below(sh.scratchpad_words) as u16,
                offset,
                data: if write { self.entry(&name, "data") } else { 0 },
                dests: if write { [None; 2] } else { self.dests() },
                stage: stage(self),
            });
        }
        for k in 0..sh.comm_units {
            if !self.chance(fullness) {
                continue;
            }
            let name = format!("comm{k}");
            let c = sh.clusters;
            let perm = match self.below(4) {
                0 => Permutation::Rotate(self.below(c) as u16),
                1 => {
                    let x = self.below(c);
                    let ok = (0..c).all(|from| from ^ x < c);
                    Permutation::Xor(if ok { x as u16 } else { 0 })
                }
                2 => Permutation::Broadcast(self.below(c) as u16),
                _ => Permutation::PerCluster(self.entry(&name, "perm")),
            };
            ins.comm[k] = Some(CommSlot {
                data: self.entry(&name, "data"),
                perm,
                dests: self.dests(),
                stage: stage(self),
            });
        }
        let ins_streams = self.streams_of(StreamDir::In);
        let outs = self.streams_of(StreamDir::Out);
        let mut conditional = 0;
        // Conditional stream words use the intercluster network and the scratchpad: only
        // without a comm0 or sp0 op.
        let cond_max = if ins.comm.first().is_some_and(Option::is_some)
            || ins.sp.first().is_some_and(Option::is_some)
        {
            0
        } else {
            self.desc.srf.conditional_words_per_cycle
        };
        for k in 0..sh.stream_ins {
            if ins_streams.is_empty() || !self.chance(fullness / 2) {
                continue;
            }
            let cond = if conditional < cond_max && self.chance(30) {
                conditional += 1;
                Some(self.cc())
            } else {
                None
            };
            ins.sin[k] = Some(StreamIn {
                stream: self.pick(&ins_streams),
                cond,
                dests: self.dests(),
                stage: stage(self),
            });
        }
        let used = ins.sin.iter().flatten().count();
        if !outs.is_empty() && used < self.desc.srf.cluster_words_per_cycle && self.chance(fullness)
        {
            let cond = if conditional < cond_max && self.chance(30) {
                Some(self.cc())
            } else {
                None
            };
            ins.sout = Some(StreamOut {
                stream: self.pick(&outs),
                data: self.entry("sout", "data"),
                cond,
                stage: stage(self),
            });
        }
        if self.chance(fullness) {
            ins.imm = Some(Immediate {
                value: self.imm_value(),
                dests: self.dests(),
                stage: stage(self),
            });
        }
        ins
    }

    fn loop_kind(&mut self, stages: &mut u8) -> LoopKind {
        let ins_streams = self.streams_of(StreamDir::In);
        match self.below(3) {
            0 => LoopKind::Counted(self.pick(&[0, 1, 7, 1000, u32::MAX])),
            1 if !ins_streams.is_empty() => LoopKind::UntilStreamEmpty(self.pick(&ins_streams)),
            _ => {
                *stages = 1;
                LoopKind::UntilCc(self.cc())
            }
        }
    }

    /// Appends a block of instructions (and nested loops) to `code`.
    fn block(&mut self, code: &mut Vec<Instruction>, depth: usize, stages: u8, budget: &mut usize) {
        let n = 1 + self.below(4);
        for _ in 0..n {
            if *budget == 0 {
                return;
            }
            if depth < self.desc.microcontroller.loop_depth && self.chance(30) {
                self.a_loop(code, depth + 1, budget);
            } else {
                *budget -= 1;
                let fullness = self.pick(&[0, 20, 50, 90]);
                code.push(self.instruction(stages, fullness));
            }
        }
    }

    /// A loop: its first and last instructions are plain (they carry `begin` and `end`), or
    /// its body is one instruction that carries both. Some bodies hold several passes (as
    /// modulo variable expansion unrolls them): each but the last ends on a plain
    /// instruction carrying `pass_end`, and the first pass may be the `begin` instruction
    /// alone. A stream loop's passes are copies of the first, so that each reads as many
    /// words of its stream; other loops' passes are drawn afresh.
    fn a_loop(&mut self, code: &mut Vec<Instruction>, depth: usize, budget: &mut usize) {
        let mut stages = 1 + self.below(usize::from(MAX_STAGES)) as u8;
        let kind = self.loop_kind(&mut stages);
        let fullness = self.pick(&[0, 30, 70]);
        let mut first = self.instruction(stages, fullness);
        if self.chance(25) {
            first.control = Control::begin_end(kind, stages);
            code.push(first);
            *budget = budget.saturating_sub(1);
            return;
        }
        let passes = if self.chance(35) {
            2 + self.below(3)
        } else {
            1
        };
        first.control = Control::begin(kind, stages);
        let begin = code.len();
        code.push(first);
        *budget = budget.saturating_sub(1);
        // The first pass: the `begin` instruction alone, or it, a block and a last one.
        if passes == 1 || !self.chance(30) {
            if self.chance(60) {
                self.block(code, depth, stages, budget);
            }
            code.push(self.instruction(stages, fullness));
            *budget = budget.saturating_sub(1);
        }
        let first_pass = code[begin..].to_vec();
        let stream = matches!(kind, LoopKind::UntilStreamEmpty(_));
        // Copies of copies (nested stream loops) would grow without bound.
        let passes = if stream && first_pass.len() * passes > 12 {
            1
        } else {
            passes
        };
        for pass in 0..passes {
            if pass > 0 {
                if stream {
                    let mut copy = first_pass.clone();
                    copy[0].control = Control::NEXT;
                    *budget = budget.saturating_sub(copy.len());
                    code.extend(copy);
                } else {
                    if self.chance(50) {
                        self.block(code, depth, stages, budget);
                    }
                    code.push(self.instruction(stages, fullness));
                    *budget = budget.saturating_sub(1);
                }
            }
            // The pass's last instruction is plain (or the `begin` instruction itself).
            let last = code.last_mut().expect("a pass has an instruction");
            debug_assert!(!last.control.end && !last.control.pass_end);
            if pass + 1 == passes {
                last.control.end = true;
            } else {
                last.control.pass_end = true;
            }
        }
    }

    fn program(&mut self) -> Program {
        let names = [
            "x", "y", "in", "out", "stream", "cc", "a.b", "_t9", "loop", "z_1",
        ];
        let n = self.below(self.desc.srf.kernel_streams + 1);
        let mut pool: Vec<&str> = names.to_vec();
        self.streams = (0..n.min(pool.len()))
            .map(|_| {
                let name = pool.remove(self.below(pool.len()));
                StreamDecl {
                    name: name.to_string(),
                    dir: if self.chance(50) {
                        StreamDir::In
                    } else {
                        StreamDir::Out
                    },
                }
            })
            .collect();
        let mut code = Vec::new();
        let mut budget = 30;
        self.block(&mut code, 0, 1, &mut budget);
        // `done`: on the last instruction if it is plain, else on an extra one.
        match code.last_mut() {
            Some(last) if last.control.is_next() && self.chance(50) => {
                last.control = Control::DONE;
            }
            _ => {
                let fullness = self.pick(&[0, 0, 50]);
                let mut done = self.instruction(1, fullness);
                done.control = Control::DONE;
                code.push(done);
            }
        }
        Program {
            name: self
                .pick(&["k", "saxpy", "kernel", "done", "v.2"])
                .to_string(),
            streams: self.streams.clone(),
            code,
        }
    }
}

fn generator(desc: &MachineDesc, seed: u64) -> Gen<'_> {
    Gen {
        rng: SplitMix64::new(seed),
        sh: Shape::new(desc),
        desc,
        streams: Vec::new(),
    }
}

fn machines() -> Vec<MachineDesc> {
    MACHINES
        .iter()
        .map(|m| MachineDesc::resolve(m).unwrap())
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn random_programs_are_valid_and_round_trip_through_text(seed in any::<u64>()) {
        for desc in machines() {
            let p = generator(&desc, seed).program();
            if let Err(e) = p.check(&desc) {
                panic!("generator made an invalid program on {}: {e}", desc.name);
            }
            let text = disassemble(&p, &desc);
            match assemble(&text, &desc) {
                Ok(q) => prop_assert_eq!(&q, &p, "{}: text\n{}", desc.name, text),
                Err(e) => panic!("{}: {e}\n{text}", desc.name),
            }
        }
    }

    #[test]
    fn random_instructions_round_trip_through_binary(seed in any::<u64>()) {
        for desc in machines() {
            let layout = InstructionLayout::new(&desc);
            let p = generator(&desc, seed).program();
            for ins in &p.code {
                let w = layout.encode(ins);
                prop_assert_eq!(w.len(), layout.width());
                prop_assert_eq!(&layout.decode(&w).unwrap(), ins);
            }
            // Loops with every control value.
            let mut g = generator(&desc, seed ^ 0x5555);
            let mut ins = g.instruction(MAX_STAGES, 60);
            let mut stages = 1 + g.below(usize::from(MAX_STAGES)) as u8;
            let kind = g.loop_kind(&mut stages);
            ins.control = Control::begin(kind, stages);
            prop_assert_eq!(&layout.decode(&layout.encode(&ins)).unwrap(), &ins);
            ins.control.end = true;
            prop_assert_eq!(&layout.decode(&layout.encode(&ins)).unwrap(), &ins);
            ins.control.end = false;
            ins.control.pass_end = true;
            prop_assert_eq!(&layout.decode(&layout.encode(&ins)).unwrap(), &ins);
            ins.control = Control::PASS_END;
            prop_assert_eq!(&layout.decode(&layout.encode(&ins)).unwrap(), &ins);
        }
    }

    #[test]
    fn decoding_random_words_never_panics(seed in any::<u64>()) {
        for desc in machines() {
            let layout = InstructionLayout::new(&desc);
            let mut rng = SplitMix64::new(seed);
            let mut w = imagine_hdl::wide_word(layout.width());
            let density = rng.below(4);
            for i in 0..w.len() {
                let bits = rng.next_u32();
                // Sparse words too, so that some decode successfully.
                w.set(i, match density { 0 => bits.is_multiple_of(8), 1 => bits.is_multiple_of(32), _ => bits & 1 == 1 });
            }
            if let Ok(ins) = layout.decode(&w) {
                // What decodes re-encodes, and the re-encoding decodes the same.
                let again = layout.try_encode(&ins).unwrap();
                prop_assert_eq!(layout.decode(&again).unwrap(), ins);
            }
        }
    }
}

#[test]
fn every_machine_generates_every_slot_kind() {
    // The generator reaches every slot (guards against a generator that silently
    // produces only empty instructions).
    for desc in machines() {
        let sh = Shape::new(&desc);
        let mut seen_fu = vec![false; sh.fu_count()];
        let (mut sp, mut comm, mut sin, mut sout, mut imm) = (false, false, false, false, false);
        let (mut long_loop, mut one_instruction_loop) = (false, false);
        let (mut pass_end, mut one_instruction_pass) = (false, false);
        for seed in 0..200 {
            let p = generator(&desc, seed).program();
            for ins in &p.code {
                for (k, s) in ins.fu.iter().enumerate() {
                    seen_fu[k] |= s.is_some();
                }
                sp |= ins.sp.iter().any(Option::is_some);
                comm |= ins.comm.iter().any(Option::is_some);
                sin |= ins.sin.iter().any(Option::is_some);
                sout |= ins.sout.is_some();
                imm |= ins.imm.is_some();
                long_loop |= ins.control.begin.is_some() && !ins.control.end;
                one_instruction_loop |= ins.control.begin.is_some() && ins.control.end;
                pass_end |= ins.control.pass_end;
                one_instruction_pass |= ins.control.begin.is_some() && ins.control.pass_end;
            }
        }
        assert!(seen_fu.iter().all(|&s| s) && sp && comm && sin && sout && imm);
        assert!(long_loop && one_instruction_loop, "{}", desc.name);
        assert!(pass_end && one_instruction_pass, "{}", desc.name);
        assert!(matches!(sh.fu_class(sh.fu_count() - 1), UnitClass::DivSqrt));
    }
}
