//! Running one kernel on a machine from the host's side: place the input streams in the
//! SRF, start the kernel, clock the machine until it is idle, read the output streams back.
//! Used by `imagine kernel run`, the machine bench and the tests.

use std::fmt;

use imagine_hdl::{ClockDomain, ContractError, Design, Sim};

use crate::desc::MachineDesc;
use crate::machine::{KernelStats, Machine, StreamBinding};
use crate::microcode::{Program, StreamDir};
use crate::ops::Datapath;

/// A kernel run that could not be set up or did not complete.
#[derive(Debug)]
pub enum RunError {
    Setup(String),
    Contract(ContractError),
    Timeout { kernel: String, cycles: u64 },
}

impl fmt::Display for RunError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RunError::Setup(s) => f.write_str(s),
            RunError::Contract(e) => e.fmt(f),
            RunError::Timeout { kernel, cycles } => {
                write!(f, "kernel `{kernel}` did not finish within {cycles} cycles")
            }
        }
    }
}

impl std::error::Error for RunError {}

impl From<ContractError> for RunError {
    fn from(e: ContractError) -> Self {
        RunError::Contract(e)
    }
}

/// Called with the simulator before the first cycle, e.g. to attach a VCD writer.
pub type OnStart = Box<dyn FnOnce(&mut Sim) -> Result<(), String>>;

/// How to run a kernel.
pub struct RunOptions {
    /// Give up after this many core cycles.
    pub max_cycles: u64,
    pub on_start: Option<OnStart>,
    /// What computes the fp32 ops without a tracer ([`Machine::set_datapath`]).
    pub datapath: Datapath,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            max_cycles: 10_000_000,
            on_start: None,
            datapath: Datapath::Host,
        }
    }
}

/// What a kernel produced.
#[derive(Clone, Debug)]
pub struct KernelRun {
    /// One vector per output stream, in declaration order.
    pub outputs: Vec<Vec<u32>>,
    pub stats: KernelStats,
}

/// Runs `program` on a machine built from `desc`, with `inputs` for its input streams in
/// declaration order. Output streams share the SRF space the inputs leave.
pub fn run_kernel(
    desc: &MachineDesc,
    program: &Program,
    inputs: &[Vec<u32>],
    options: RunOptions,
) -> Result<KernelRun, RunError> {
    let domains = vec![
        ClockDomain::mhz("core", desc.clocks.core_mhz),
        ClockDomain::mhz("dram", desc.clocks.dram_mhz),
    ];
    let mut design = Design::new("top", domains).map_err(|e| RunError::Setup(e.to_string()))?;
    let mut machine = Machine::new(&mut design.scope(), desc);
    machine.set_datapath(options.datapath);
    let bindings = place_streams(desc, program, inputs)?;
    let mut next_input = inputs.iter();
    for (s, b) in program.streams.iter().zip(&bindings) {
        if s.dir == StreamDir::In {
            let data = next_input.next().expect("counted by place_streams");
            machine.srf_mut().load(b.start, data)?;
        }
    }
    machine
        .start(program, &bindings)
        .map_err(|e| RunError::Setup(e.to_string()))?;
    design.add(machine);
    let mut sim = Sim::new(design);
    if let Some(on_start) = options.on_start {
        on_start(&mut sim).map_err(RunError::Setup)?;
    }
    let finished = sim.run_until(options.max_cycles, |sim| machine_of(sim).is_idle())?;
    sim.finish()
        .map_err(|e| RunError::Setup(format!("cannot finish the trace: {e}")))?;
    if !finished {
        return Err(RunError::Timeout {
            kernel: program.name.clone(),
            cycles: options.max_cycles,
        });
    }
    let machine = machine_of(&sim);
    let mut outputs = Vec::new();
    for (i, (s, b)) in program.streams.iter().zip(&bindings).enumerate() {
        if s.dir == StreamDir::Out {
            outputs.push(machine.srf().read_back(b.start, machine.output_len(i))?);
        }
    }
    Ok(KernelRun {
        outputs,
        stats: machine.stats().cloned().unwrap_or_default(),
    })
}

fn machine_of(sim: &Sim) -> &Machine {
    sim.modules_of::<Machine>()
        .next()
        .expect("the design holds a machine")
}

/// Lays the streams out in the SRF: inputs first, each on a block boundary, then the
/// outputs sharing what is left equally.
fn place_streams(
    desc: &MachineDesc,
    program: &Program,
    inputs: &[Vec<u32>],
) -> Result<Vec<StreamBinding>, RunError> {
    let n_in = program
        .streams
        .iter()
        .filter(|s| s.dir == StreamDir::In)
        .count();
    if inputs.len() != n_in {
        return Err(RunError::Setup(format!(
            "kernel `{}` has {n_in} input streams, {} given",
            program.name,
            inputs.len()
        )));
    }
    let block = desc.srf.block_words;
    let round_up = |w: usize| w.div_ceil(block) * block;
    let used: usize = inputs.iter().map(|i| round_up(i.len())).sum();
    if used > desc.srf.words {
        return Err(RunError::Setup(format!(
            "the input streams need {used} SRF words; the SRF holds {}",
            desc.srf.words
        )));
    }
    let n_out = program.streams.len() - n_in;
    let out_words = (desc.srf.words - used).checked_div(n_out).unwrap_or(0) / block * block;
    let mut next = 0;
    let mut input = inputs.iter();
    let mut bindings = Vec::new();
    for s in &program.streams {
        let words = match s.dir {
            StreamDir::In => input.next().expect("counted").len(),
            StreamDir::Out => out_words,
        };
        bindings.push(StreamBinding { start: next, words });
        next += round_up(words);
    }
    Ok(bindings)
}
