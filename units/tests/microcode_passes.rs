//! Loop bodies of several passes (modulo variable expansion, Lam 1988: the kernel unrolled
//! `K` times, each copy one pass, `pass_end` between copies): the microcontroller, driven
//! cycle by cycle, issues exactly what the squash formula says — pass `p` runs copy
//! `p mod K`, stage `s` is live iff `s <= p < N + s`, `N + S − 1` passes, then the
//! instruction after `end`, whichever copy the last pass was — for counted, stream and
//! `until cc` loops; and kernels with `pass` lines compute the right streams on the machine.

use std::cell::Cell;

use imagine_hdl::{ContractError, Design, default_domains};
use imagine_units::desc::MachineDesc;
use imagine_units::microcode::{
    Control, Instruction, LoopKind, Program, StreamDecl, StreamDir, StreamIn, assemble,
};
use imagine_units::microcontroller::{LoopEnv, Microcontroller};
use imagine_units::runner::{KernelRun, RunOptions, run_kernel};

/// The rest of the machine as the sequencer sees it: one input stream whose rows the
/// harness consumes as reads issue, and a condition code that becomes set at a chosen test.
#[derive(Default)]
struct Env {
    /// Rows left in stream 0.
    rows: u64,
    /// `cc_all` answers true from this call on (1-based).
    cc_true_at: u32,
    cc_calls: Cell<u32>,
}

impl LoopEnv for Env {
    fn rows_left(&self, _stream: u16) -> u64 {
        self.rows
    }

    fn exhausted(&self, _stream: u16) -> bool {
        self.rows == 0
    }

    fn cc_all(&self, _cc: u16) -> Result<bool, ContractError> {
        let n = self.cc_calls.get() + 1;
        self.cc_calls.set(n);
        Ok(n >= self.cc_true_at)
    }
}

/// Every cycle's `(pc, live stages)` until `done` has issued.
fn sequence(code: &[Instruction], env: &mut Env) -> Vec<(u16, u64)> {
    let mut design = Design::new("top", default_domains()).unwrap();
    let mut uc = Microcontroller::new(&mut design.scope(), 2048, 4);
    uc.start(code).unwrap();
    let mut trace = Vec::new();
    while let Some((pc, live)) = uc.fetch(code, env).unwrap() {
        assert!(trace.len() < 10_000, "runaway");
        trace.push((pc, live.stages));
        // A live unconditional read takes a row (a word from every cluster).
        let reads = code[usize::from(pc)]
            .sin
            .iter()
            .flatten()
            .filter(|r| r.cond.is_none() && live.live(r.stage))
            .count();
        env.rows = env.rows.saturating_sub(reads as u64);
        uc.advance(code, env).unwrap();
        uc.commit();
    }
    trace
}

fn gold8() -> MachineDesc {
    MachineDesc::gold8()
}

/// `nop`, a loop whose body is `k` copies of `l` instructions (`pass_end` on the last of
/// every copy but the last, `end` on that), `nop`, `done`. In a stream loop the first
/// `reads` instructions of every copy read stream `x` (stage 0).
fn program(kind: LoopKind, stages: u8, k: usize, l: usize, reads: usize) -> Program {
    let desc = gold8();
    let mut code = vec![Instruction::empty(&desc)];
    for copy in 0..k {
        for j in 0..l {
            let mut ins = Instruction::empty(&desc);
            if j < reads {
                ins.sin[0] = Some(StreamIn {
                    stream: 0,
                    cond: None,
                    dests: [None; 2],
                    stage: 0,
                });
            }
            if copy == 0 && j == 0 {
                ins.control = Control::begin(kind, stages);
            }
            if j + 1 == l {
                if copy + 1 == k {
                    ins.control.end = true;
                } else {
                    ins.control.pass_end = true;
                }
            }
            code.push(ins);
        }
    }
    code.push(Instruction::empty(&desc));
    let mut done = Instruction::empty(&desc);
    done.control = Control::DONE;
    code.push(done);
    let p = Program {
        name: "passes".into(),
        streams: vec![StreamDecl {
            name: "x".into(),
            dir: StreamDir::In,
        }],
        code,
    };
    p.check(&desc).unwrap();
    p
}

/// The formula: `passes` passes, pass `p` running copy `p mod k` with stages `live(p)`,
/// between the `nop`s around the loop.
fn expected(k: usize, l: usize, passes: u64, live: impl Fn(u64) -> u64) -> Vec<(u16, u64)> {
    let mut t = vec![(0, 1)];
    for p in 0..passes {
        let copy = p as usize % k;
        for j in 0..l {
            t.push(((1 + copy * l + j) as u16, live(p)));
        }
    }
    let after = (1 + k * l) as u16;
    t.extend([(after, 1), (after + 1, 1)]);
    t
}

/// Stage `s` is live in pass `p` of a loop of `n` iterations iff `s <= p < n + s`.
fn squash(n: u64, stages: u8) -> impl Fn(u64) -> u64 {
    move |p| {
        (0..u64::from(stages))
            .filter(|&s| s <= p && p < n + s)
            .fold(0, |bits, s| bits | 1 << s)
    }
}

/// A counted loop of `n` iterations: `n + S − 1` passes (none if `n` is 0: skipped).
fn check_counted(k: usize, l: usize, stages: u8, n: u32) {
    let p = program(LoopKind::Counted(n), stages, k, l, 0);
    let passes = if n == 0 {
        0
    } else {
        u64::from(n) + u64::from(stages) - 1
    };
    let want = expected(k, l, passes, squash(u64::from(n), stages));
    let got = sequence(&p.code, &mut Env::default());
    assert_eq!(
        got, want,
        "{k} passes of {l}, {stages} stages, {n} iterations"
    );
}

#[test]
fn counted_loop_of_two_passes_of_three_follows_the_squash_formula() {
    // N + 2 passes: odd N ends at `end`, even N in the middle of the body.
    for n in 1..=6 {
        check_counted(2, 3, 3, n);
    }
}

#[test]
fn counted_loop_of_three_passes_follows_the_squash_formula() {
    for n in 1..=7 {
        check_counted(3, 3, 3, n);
        check_counted(3, 2, 4, n);
    }
}

#[test]
fn every_body_shape_follows_the_squash_formula() {
    // One pass (no `pass_end`: the loop as it always was), one-instruction passes (the
    // first on the `begin` instruction), skipped loops.
    for k in 1..=4 {
        for l in 1..=3 {
            for stages in 1..=5 {
                for n in 0..=7 {
                    check_counted(k, l, stages, n);
                }
            }
        }
    }
}

#[test]
fn pipelined_stream_loop_counts_words_over_one_pass() {
    // Two passes of three instructions, two reads in each: a pass takes two rows, so `R`
    // rows are `ceil(R / 2)` iterations (counting the whole body would give `ceil(R / 4)`).
    for rows in 1..=12u64 {
        let p = program(LoopKind::UntilStreamEmpty(0), 3, 2, 3, 2);
        let n = rows.div_ceil(2);
        let want = expected(2, 3, n + 2, squash(n, 3));
        let mut env = Env {
            rows,
            ..Env::default()
        };
        assert_eq!(sequence(&p.code, &mut env), want, "{rows} rows");
        assert_eq!(env.rows, 0, "{rows} rows: every row read");
    }
}

#[test]
fn unpipelined_stream_loop_leaves_at_the_pass_that_empties_the_stream() {
    // One stage: the loop tests "exhausted" at every pass end, `end` or `pass_end`.
    for (k, l, reads) in [(2, 3, 2), (3, 2, 1), (2, 1, 1)] {
        for rows in 0..=9u64 {
            let p = program(LoopKind::UntilStreamEmpty(0), 1, k, l, reads);
            let passes = rows.div_ceil(reads as u64);
            let want = expected(k, l, passes, |_| 1);
            let mut env = Env {
                rows,
                ..Env::default()
            };
            assert_eq!(sequence(&p.code, &mut env), want, "{k}x{l}, {rows} rows");
        }
    }
}

#[test]
fn until_cc_loop_tests_at_every_pass_end_and_leaves_mid_body() {
    for (k, l) in [(2, 3), (3, 1), (3, 2)] {
        for at in 1..=7 {
            let p = program(LoopKind::UntilCc(0), 1, k, l, 0);
            let mut env = Env {
                cc_true_at: at,
                ..Env::default()
            };
            let want = expected(k, l, u64::from(at), |_| 1);
            assert_eq!(
                sequence(&p.code, &mut env),
                want,
                "{k}x{l}, set at test {at}"
            );
            assert_eq!(env.cc_calls.get(), at, "one test per pass");
        }
    }
}

#[test]
fn inner_loops_do_not_end_a_pass_of_the_outer_loop() {
    // 0: begin outer (count 3) | 1: inner (count 2, one instruction) | 2: pass_end |
    // 3: plain | 4: inner (count 2, one instruction) | 5: end | 6: done
    let desc = gold8();
    let mut code: Vec<Instruction> = (0..7).map(|_| Instruction::empty(&desc)).collect();
    code[0].control = Control::begin(LoopKind::Counted(3), 1);
    code[1].control = Control::begin_end(LoopKind::Counted(2), 1);
    code[2].control = Control::PASS_END;
    code[4].control = Control::begin_end(LoopKind::Counted(2), 1);
    code[5].control = Control::END;
    code[6].control = Control::DONE;
    let p = Program {
        name: "nested".into(),
        streams: vec![],
        code,
    };
    p.check(&desc).unwrap();
    let pcs: Vec<u16> = sequence(&p.code, &mut Env::default())
        .into_iter()
        .map(|(pc, _)| pc)
        .collect();
    // Passes: copy 0, copy 1, copy 0 — the third leaves from instruction 2.
    assert_eq!(pcs, [0, 1, 1, 2, 3, 4, 4, 5, 0, 1, 1, 2, 6]);
}

#[test]
fn start_rejects_a_pass_end_outside_a_loop_or_with_end() {
    let desc = gold8();
    let mut design = Design::new("top", default_domains()).unwrap();
    let mut uc = Microcontroller::new(&mut design.scope(), 2048, 4);
    let mut code: Vec<Instruction> = (0..3).map(|_| Instruction::empty(&desc)).collect();
    code[0].control = Control::PASS_END;
    code[2].control = Control::DONE;
    let e = uc.start(&code).unwrap_err().to_string();
    assert!(e.contains("instruction 0: `pass` without a loop"), "{e}");
    code[0].control = Control::begin(LoopKind::Counted(2), 1);
    code[1].control = Control::END;
    code[1].control.pass_end = true;
    let e = uc.start(&code).unwrap_err().to_string();
    assert!(
        e.contains("instruction 1: `pass` and `end` on one instruction"),
        "{e}"
    );
}

// ---- on the machine ---------------------------------------------------------------------

/// z = x + 1.0, one iteration per cycle over 5 stages, in a body of two passes that keep
/// x in alternate entries (modulo variable expansion; see the file).
const PLUS_ONE: &str = include_str!("microcode/plus1_passes.uc");

/// Runs `prog` on one input stream `x`; `what` names the case in a failure.
fn run_rows(desc: &MachineDesc, prog: &Program, x: &[u32], what: &str) -> KernelRun {
    run_kernel(desc, prog, &[x.to_vec()], RunOptions::default())
        .unwrap_or_else(|e| panic!("{what}: {e}"))
}

#[test]
fn unrolled_pipelined_kernel_runs_on_the_machine() {
    for m in ["gold8", "gold1"] {
        let desc = MachineDesc::resolve(m).unwrap();
        let c = desc.cluster.count;
        let prog = assemble(PLUS_ONE, &desc).unwrap();
        for rows in 1..=6u64 {
            let x: Vec<u32> = (0..rows as usize * c)
                .map(|i| (i as f32 * 0.5 - 3.0).to_bits())
                .collect();
            let run = run_rows(&desc, &prog, &x, &format!("{m}, {rows} rows"));
            let want: Vec<u32> = x
                .iter()
                .map(|&v| (f32::from_bits(v) + 1.0).to_bits())
                .collect();
            assert_eq!(run.outputs[0], want, "{m}, {rows} rows");
            // `imm`, N + 4 passes of one instruction, `done`; one add per iteration; the
            // prologue squashes 4 adds and the epilogue 4 reads, on whichever copy.
            let s = &run.stats;
            assert_eq!(s.instructions, 1 + rows + 4 + 1, "{m}, {rows} rows: {s:?}");
            assert_eq!(s.fu_ops.iter().sum::<u64>(), rows, "{m}, {rows} rows");
            assert_eq!(s.squashed, 8, "{m}, {rows} rows: {s:?}");
        }
    }
}

#[test]
fn unpipelined_copy_of_two_passes_runs_on_the_machine() {
    // The first pass is the `begin` instruction alone; an odd row count leaves after it.
    let text = "\
kernel copy2
in x
out z
loop stream x:
    sin0 x -> stream z
pass
    sin0 x -> stream z
end
done
";
    for m in ["gold8", "gold1"] {
        let desc = MachineDesc::resolve(m).unwrap();
        let c = desc.cluster.count;
        let prog = assemble(text, &desc).unwrap();
        assert_eq!(
            prog.code[0].control,
            Control::begin_pass_end(LoopKind::UntilStreamEmpty(0), 1)
        );
        for rows in 1..=5u64 {
            let x: Vec<u32> = (0..rows as u32 * c as u32).map(|i| 7000 + i).collect();
            let run = run_rows(&desc, &prog, &x, &format!("{m}, {rows} rows"));
            assert_eq!(run.outputs[0], x, "{m}, {rows} rows");
            assert_eq!(run.stats.instructions, rows + 1, "{m}, {rows} rows");
        }
    }
}
