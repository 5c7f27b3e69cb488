//! The hand-written microcode programs of `tests/microcode/` run on the clocked machine, on
//! gold8 and gold1, and their output streams equal what the op functions give directly.

use imagine_units::arith::fp32::{self, FpMode};
use imagine_units::desc::MachineDesc;
use imagine_units::machine::KernelStats;
use imagine_units::microcode::asm::assemble;
use imagine_units::runner::{RunOptions, run_kernel};

const MODE: FpMode = FpMode::IEEE;

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 32) as u32
    }
    /// A float of magnitude in [2^-7, 4), either sign.
    fn float(&mut self) -> u32 {
        let x = self.next();
        let mag = 0x3C00_0000 + (x & 0x7FF_FFFF) % 0x0480_0000;
        mag | (x & 0x8000_0000)
    }
}

fn run(program: &str, machine: &str, inputs: &[Vec<u32>]) -> (Vec<Vec<u32>>, KernelStats) {
    let text = std::fs::read_to_string(format!(
        "{}/tests/microcode/{program}.uc",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap();
    run_text(program, &text, machine, inputs)
}

/// Assembles `text` (kernel `name`) for `machine` and runs it.
fn run_text(
    name: &str,
    text: &str,
    machine: &str,
    inputs: &[Vec<u32>],
) -> (Vec<Vec<u32>>, KernelStats) {
    let desc = MachineDesc::resolve(machine).unwrap();
    let prog = assemble(text, &desc).unwrap_or_else(|e| panic!("{name} on {machine}: {e}"));
    let run = run_kernel(&desc, &prog, inputs, RunOptions::default())
        .unwrap_or_else(|e| panic!("{name} on {machine}: {e}"));
    (run.outputs, run.stats)
}

const MACHINES: [&str; 2] = ["gold8", "gold1"];

#[test]
fn streaming_multiply_add() {
    for m in MACHINES {
        let mut rng = Rng(1);
        let n = 64;
        let [x, y, w]: [Vec<u32>; 3] =
            std::array::from_fn(|_| (0..n).map(|_| rng.float()).collect());
        let (out, stats) = run("madd", m, &[x.clone(), y.clone(), w.clone()]);
        let expected: Vec<u32> = (0..n)
            .map(|i| fp32::add(fp32::mul(x[i], y[i], MODE).0, w[i], MODE).0)
            .collect();
        assert_eq!(out[0], expected, "{m}");
        assert!(
            stats.cycles > 0 && stats.fu_ops.iter().sum::<u64>() > 0,
            "{m}: {stats:?}"
        );
    }
}

#[test]
fn software_pipelined_saxpy_squashes_prologue_and_epilogue() {
    for m in MACHINES {
        let mut rng = Rng(2);
        let n = 48;
        let x: Vec<u32> = (0..n).map(|_| rng.float()).collect();
        let y: Vec<u32> = (0..n).map(|_| rng.float()).collect();
        let (out, stats) = run("saxpy", m, &[x.clone(), y.clone()]);
        let a = 2.5f32.to_bits();
        let expected: Vec<u32> = (0..n)
            .map(|i| fp32::add(fp32::mul(a, x[i], MODE).0, y[i], MODE).0)
            .collect();
        // Exactly N results: the epilogue's extra passes wrote nothing.
        assert_eq!(out[0], expected, "{m}");
        assert!(stats.squashed > 0, "{m}: nothing was squashed: {stats:?}");
    }
}

#[test]
fn prefix_sum_across_clusters() {
    for m in MACHINES {
        let mut rng = Rng(3);
        let x: Vec<u32> = (0..64).map(|_| rng.next() % 1000).collect();
        let (out, _) = run("prefix_sum", m, std::slice::from_ref(&x));
        let expected: Vec<u32> = x
            .iter()
            .scan(0u32, |s, &v| {
                *s = s.wrapping_add(v);
                Some(*s)
            })
            .collect();
        assert_eq!(out[0], expected, "{m}");
    }
}

#[test]
fn conditional_output_keeps_order() {
    for m in MACHINES {
        let mut rng = Rng(4);
        let x: Vec<u32> = (0..80).map(|_| rng.float()).collect();
        let (out, _) = run("filter", m, std::slice::from_ref(&x));
        let half = 0.5f32.to_bits();
        let expected: Vec<u32> = x
            .iter()
            .copied()
            .filter(|&v| fp32::lt(half, v, MODE).0)
            .collect();
        assert!(!expected.is_empty() && expected.len() < x.len());
        assert_eq!(out[0], expected, "{m}");
    }
}

#[test]
fn conditional_input_load_balances() {
    for m in MACHINES {
        let mut rng = Rng(5);
        let x: Vec<u32> = (0..64)
            .map(|_| rng.next() % 200)
            .map(|v| (v as i32 - 100) as u32)
            .collect();
        let negatives = x.iter().filter(|&&v| (v as i32) < 0).count();
        let lanes = MachineDesc::resolve(m).unwrap().cluster.count;
        let y: Vec<u32> = (0..negatives.div_ceil(lanes) * lanes)
            .map(|i| 1000 + i as u32)
            .collect();
        let (out, _) = run("cond_input", m, &[x.clone(), y.clone()]);
        let mut next_y = y.iter();
        let expected: Vec<u32> = x
            .iter()
            .map(|&v| {
                if (v as i32) < 0 {
                    *next_y.next().unwrap()
                } else {
                    v
                }
            })
            .collect();
        assert_eq!(out[0], expected, "{m}");
    }
}

#[test]
fn scratchpad_table_lookup() {
    for m in MACHINES {
        let lanes = MachineDesc::resolve(m).unwrap().cluster.count;
        let table_values: Vec<u32> = (0..16).map(|j| 7 * j * j + 3).collect();
        let table: Vec<u32> = table_values
            .iter()
            .flat_map(|&v| std::iter::repeat_n(v, lanes))
            .collect();
        let mut rng = Rng(6);
        let x: Vec<u32> = (0..64).map(|_| rng.next() % 16).collect();
        let (out, _) = run("lookup", m, &[table, x.clone()]);
        let expected: Vec<u32> = x.iter().map(|&i| table_values[i as usize]).collect();
        assert_eq!(out[0], expected, "{m}");
    }
}

/// z[i] = x[i] * y[i] (fp32), software-pipelined with an initiation interval of 1: the loop
/// body is one instruction, so a new iteration starts every cycle.
///
/// Schedule of one iteration (cycle = stage, gold8 latencies):
///   t0  sin0 x, sin1 y  -> mul0.a[0], mul0.b[0]   land t3 (readable from t4)
///   t4  mul0 fmul       -> stream z               lands t8
/// Each operand is read in the one cycle it can be: it becomes readable at t4, and the next
/// iteration's copy, landing at t4, overwrites it at the end of that cycle.
const MUL_II1: &str = "\
kernel mul_ii1
in x
in y
out z

loop stream x, stages 5:
    sin0 x -> mul0.a[0] | sin1 y -> mul0.b[0] | mul0 fmul a[0], b[0] -> stream z @4
end
done
";

#[test]
fn software_pipelined_loop_with_initiation_interval_one() {
    for m in MACHINES {
        let lanes = MachineDesc::resolve(m).unwrap().cluster.count;
        let mut rng = Rng(7);
        let n = 96;
        let x: Vec<u32> = (0..n).map(|_| rng.float()).collect();
        let y: Vec<u32> = (0..n).map(|_| rng.float()).collect();
        let (out, stats) = run_text("mul_ii1", MUL_II1, m, &[x.clone(), y.clone()]);
        let expected: Vec<u32> = (0..n).map(|i| fp32::mul(x[i], y[i], MODE).0).collect();
        assert_eq!(out[0], expected, "{m}");
        // N iterations take N + 4 passes of the one-instruction body, then `done` (on an
        // instruction of its own after the `end`).
        let iterations = (n / lanes) as u64;
        assert_eq!(stats.instructions, iterations + 4 + 1, "{m}: {stats:?}");
        // One multiply per iteration; the prologue squashes the multiply 4 times, the
        // epilogue the two stream reads 4 times.
        assert_eq!(
            stats.fu_ops.iter().sum::<u64>(),
            iterations,
            "{m}: {stats:?}"
        );
        assert_eq!(stats.squashed, 4 + 2 * 4, "{m}: {stats:?}");
        // An instruction every cycle the clusters do not stall: no bubble at the back edge.
        // What is left is the drain (the last multiply's 4 cycles and the output flush).
        let drain = stats.cycles - stats.stall_cycles - stats.instructions;
        assert!((4..=8).contains(&drain), "{m}: {stats:?}");
    }
}

#[test]
fn one_instruction_loops_run_exactly_their_passes() {
    for m in MACHINES {
        let lanes = MachineDesc::resolve(m).unwrap().cluster.count as u32;
        let cids = || 0..lanes;
        // A counted loop: N passes, each appending every cluster's index.
        for n in [0u32, 1, 2, 7] {
            let text = format!(
                "kernel count1\nout z\nloop count {n}:\n    imm cid -> stream z\nend\ndone\n"
            );
            let (out, stats) = run_text("count1", &text, m, &[]);
            let expected: Vec<u32> = (0..n).flat_map(|_| cids()).collect();
            assert_eq!(out[0], expected, "{m}, count {n}");
            assert_eq!(stats.instructions, u64::from(n) + 1, "{m}, count {n}");
        }
        // A stream loop without pipelining (tests "exhausted" after every pass): a copy.
        let x: Vec<u32> = (0..5 * lanes).map(|i| 1000 + i).collect();
        let (out, stats) = run_text(
            "copy1",
            "kernel copy1\nin x\nout z\nloop stream x:\n    sin0 x -> stream z\nend\ndone\n",
            m,
            std::slice::from_ref(&x),
        );
        assert_eq!(out[0], x, "{m}");
        assert_eq!(stats.instructions, 5 + 1, "{m}");
        // Nested in a longer loop: the inner loop is entered afresh on every outer pass and
        // loops to itself without re-entering.
        let text = "\
kernel nested1
out z
loop count 3:
    imm 0x100 -> stream z
    loop count 4:
        imm cid -> stream z
    end
    nop
end
done
";
        let (out, stats) = run_text("nested1", text, m, &[]);
        let expected: Vec<u32> = (0..3)
            .flat_map(|_| {
                std::iter::repeat_n(0x100, lanes as usize).chain((0..4).flat_map(|_| cids()))
            })
            .collect();
        assert_eq!(out[0], expected, "{m}");
        assert_eq!(stats.instructions, 3 * (1 + 4 + 1) + 1, "{m}");
    }
}
