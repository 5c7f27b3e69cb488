//! Running compiled kernels on the clocked machine, and checking them against the
//! interpreter (`imagine kernel check`): every word of every output stream must be equal.

use std::fmt;

use imagine_units::desc::MachineDesc;
use imagine_units::machine::KernelStats;
use imagine_units::runner::{RunError, RunOptions, run_kernel};

use crate::compile::Compiled;
use crate::kernel::{Dir, Kernel, KernelInputs, interpret};

/// What a compiled kernel produced on the machine.
#[derive(Clone, Debug)]
pub struct MachineRun {
    /// One vector per kernel stream (inputs empty, outputs as written).
    pub streams: Vec<Vec<u32>>,
    pub stats: KernelStats,
}

/// The program's input streams: the kernel's inputs, then the parameters, each replicated
/// once per cluster (every cluster reads its own copy).
pub fn program_inputs(
    kernel: &Kernel,
    c: &Compiled,
    inputs: &KernelInputs,
    clusters: usize,
) -> Vec<Vec<u32>> {
    let mut v: Vec<Vec<u32>> = kernel
        .streams
        .iter()
        .zip(&inputs.streams)
        .filter(|(s, _)| s.dir == Dir::In)
        .map(|(_, w)| w.clone())
        .collect();
    if c.params_stream.is_some() {
        v.push(
            inputs
                .params
                .iter()
                .flat_map(|&p| std::iter::repeat_n(p, clusters))
                .collect(),
        );
    }
    v
}

/// Runs a compiled kernel on a machine built from `desc`.
pub fn run_on_machine(
    kernel: &Kernel,
    c: &Compiled,
    desc: &MachineDesc,
    inputs: &KernelInputs,
    options: RunOptions,
) -> Result<MachineRun, RunError> {
    let ins = program_inputs(kernel, c, inputs, desc.cluster.count);
    let run = run_kernel(desc, &c.program, &ins, options)?;
    let mut outs = run.outputs.into_iter();
    let streams = kernel
        .streams
        .iter()
        .map(|s| match s.dir {
            Dir::In => Vec::new(),
            Dir::Out => outs.next().unwrap_or_default(),
        })
        .collect();
    Ok(MachineRun {
        streams,
        stats: run.stats,
    })
}

/// The first word where the machine and the interpreter disagree.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mismatch {
    pub stream: String,
    pub index: usize,
    pub machine: Option<u32>,
    pub interpreter: Option<u32>,
}

impl fmt::Display for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let w = |x: Option<u32>| x.map_or("(nothing)".to_string(), |x| format!("{x:#010x}"));
        write!(
            f,
            "stream `{}` word {}: machine {}, interpreter {}",
            self.stream,
            self.index,
            w(self.machine),
            w(self.interpreter)
        )
    }
}

/// The outcome of a check.
#[derive(Clone, Debug)]
pub struct Check {
    /// Output words compared.
    pub words: usize,
    pub mismatch: Option<Mismatch>,
    pub stats: KernelStats,
}

/// Runs `kernel` on the machine and in the interpreter with the same inputs and compares
/// every output word.
pub fn check(
    kernel: &Kernel,
    c: &Compiled,
    desc: &MachineDesc,
    inputs: &KernelInputs,
) -> Result<Check, String> {
    let golden = interpret(kernel, inputs, desc).map_err(|e| e.to_string())?;
    let run = run_on_machine(kernel, c, desc, inputs, RunOptions::default())
        .map_err(|e| e.to_string())?;
    let mut words = 0;
    let mut mismatch = None;
    for (i, s) in kernel.streams.iter().enumerate() {
        if s.dir != Dir::Out {
            continue;
        }
        let (m, g) = (&run.streams[i], &golden[i]);
        words += g.len().max(m.len());
        if mismatch.is_none()
            && let Some(k) = (0..g.len().max(m.len())).find(|&k| m.get(k) != g.get(k))
        {
            mismatch = Some(Mismatch {
                stream: s.name.clone(),
                index: k,
                machine: m.get(k).copied(),
                interpreter: g.get(k).copied(),
            });
        }
    }
    Ok(Check {
        words,
        mismatch,
        stats: run.stats,
    })
}

/// Random inputs for any kernel, from its IR alone (`imagine kernel check` of the
/// pipeline's kernels, which have no generator of their own): each input stream gets the
/// words `rows` iterations of a loop over a stream (a counted loop: its count) and the
/// code before and after the loop read, a conditional read counted as if every cluster
/// read; each word is drawn by the type the kernel reads it as — fp32 uniform in
/// [−2, 2), int32 and untyped words in [0, 64), packed and condition words any bits —
/// and parameters likewise. The words need not be ones the kernel meets in a frame: the
/// check compares the machine with the interpreter word for word, whatever the words.
pub fn random_inputs(kernel: &Kernel, desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    use crate::kernel::{LoopSpec, Node, Region, Ty};
    use imagine_units::arith::fp32::testgen::SplitMix64;
    let mut rng = SplitMix64::new(seed);
    let mut word = |ty: Option<Ty>| match ty {
        Some(Ty::F32) => {
            let unit = (rng.next_u32() >> 8) as f32 / (1u32 << 24) as f32;
            (4.0 * unit - 2.0).to_bits()
        }
        Some(Ty::I32 | Ty::Word) | None => rng.next_u32() % 64,
        Some(Ty::P16 | Ty::P8 | Ty::Cc) => rng.next_u32(),
    };
    let iterations = match kernel.main_loop {
        Some(LoopSpec::OverStream(_)) => rows,
        Some(LoopSpec::Counted(n)) => n as usize,
        None => 0,
    };
    let clusters = desc.cluster.count;
    let streams = (0..kernel.streams.len())
        .map(|s| {
            if kernel.streams[s].dir != Dir::In {
                return Vec::new();
            }
            // The stream's reads in program order: those before the loop, the loop's
            // `iterations` times, those after it; each takes a word per cluster.
            let reads = |region: Region| -> Vec<Option<Ty>> {
                kernel
                    .nodes
                    .iter()
                    .filter(|d| {
                        d.region == region
                            && matches!(d.node, Node::Read { stream, .. } if stream.0 as usize == s)
                    })
                    .map(|d| d.ty)
                    .collect()
            };
            let body = reads(Region::Loop);
            let order = reads(Region::Pre)
                .into_iter()
                .chain((0..iterations).flat_map(|_| body.iter().copied()))
                .chain(reads(Region::Post));
            let mut words = Vec::new();
            for ty in order {
                for _ in 0..clusters {
                    words.push(word(ty));
                }
            }
            words
        })
        .collect();
    let params = (0..kernel.params.len())
        .map(|p| {
            let ty = kernel
                .nodes
                .iter()
                .find(|d| matches!(d.node, Node::Param(i) if i as usize == p))
                .and_then(|d| d.ty);
            word(ty)
        })
        .collect();
    KernelInputs { streams, params }
}
