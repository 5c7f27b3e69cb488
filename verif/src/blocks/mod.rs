//! Block testbenches (ARCHITECTURE §6, layer 1): each hardware block driven through its
//! ports as the machine drives it, on any [`MachineDesc`], by seeded constrained-random
//! stimulus biased to the block's corner cases. Every testbench keeps
//!
//! * a transaction-level **reference model** written independently of the block (it shares
//!   nothing with it but the arithmetic op functions);
//! * a [`Scoreboard`] comparing every transaction and every contract assertion, keeping the
//!   first mismatch with its cycle;
//! * functional [`Coverage`] bins named per block, with hit counts.
//!
//! One file per block; [`BLOCKS`] registers them by name for `imagine verify`.

pub mod address_gen;
pub mod alu;
pub mod ccfile;
pub mod cdc;
pub mod comm;
pub mod condstream;
pub mod fpu;
pub mod fu;
pub mod lrf;
pub mod microcontroller;
pub mod scheduler;
pub mod scoreboard;
pub mod scratchpad;
pub mod sdram;
pub mod srf;
pub mod waves;

use imagine_units::arith::fp32::testgen::SplitMix64;
use std::fmt;
use std::time::{Duration, Instant};

use imagine_units::desc::MachineDesc;
use imagine_waves::VcdSummary;

pub use waves::{BlockClock, WaveRequest, Waves};

/// How a testbench runs: the stimulus seed (the same seed replays the same run), the
/// number of transactions to drive, and the waveform to write, if any.
#[derive(Clone, Debug)]
pub struct Config {
    pub seed: u64,
    pub transactions: u64,
    pub waves: Option<WaveRequest>,
}

impl Config {
    pub fn new(seed: u64, transactions: u64) -> Self {
        Config {
            seed,
            transactions,
            waves: None,
        }
    }
}

/// A registered testbench.
pub struct Block {
    pub name: &'static str,
    /// One line for `imagine verify list`.
    pub about: &'static str,
    pub run: fn(&MachineDesc, &Config) -> Outcome,
}

/// Every block testbench, in the order `imagine verify all` runs them.
pub const BLOCKS: &[Block] = &[
    Block {
        name: "lrf",
        about: "local register files: read/write ports, capacity, same-cycle read+write, port conflicts",
        run: lrf::run,
    },
    Block {
        name: "scratchpad",
        about: "scratchpad: read/write latencies, indexed addressing, conditional-stream reservation",
        run: scratchpad::run,
    },
    Block {
        name: "fu",
        about: "functional-unit pipelines: latency, issue interval, writeback conflicts, divide/sqrt occupancy",
        run: fu::run,
    },
    Block {
        name: "fpu",
        about: "fp32 ops through the adder, multiplier and divide/sqrt pipelines against SoftFloat's vectors",
        run: fpu::run,
    },
    Block {
        name: "alu",
        about: "integer and packed ops of the adders and multipliers against a plain-Rust reference",
        run: alu::run,
    },
    Block {
        name: "ccfile",
        about: "condition-code file: masked writes of bit 0, reads and every-cluster tests, port refusals",
        run: ccfile::run,
    },
    Block {
        name: "comm",
        about: "intercluster network: rotate, butterfly, broadcast and per-cluster permutations, latency",
        run: comm::run,
    },
    Block {
        name: "cdc",
        about: "synchronising FIFO across the core and DRAM clocks: order, no loss or duplication, full/empty",
        run: cdc::run,
    },
    Block {
        name: "sdram",
        about: "SDRAM banks and data under legal and illegal command sequences, with the timing checker",
        run: sdram::run,
    },
    Block {
        name: "scheduler",
        about: "DRAM access scheduler under every policy: each reference served once, same-burst order, timing",
        run: scheduler::run,
    },
    Block {
        name: "address_gen",
        about: "memory address generator: strided, record and indexed loads and stores, reorder buffer, SRF order",
        run: address_gen::run,
    },
    Block {
        name: "srf",
        about: "stream register file: streams through stream buffers, port arbitration, bandwidth, flush, refusals",
        run: srf::run,
    },
    Block {
        name: "scoreboard",
        about: "stream controller scoreboard: SRF and DRAM hazards, oldest-ready issue, units, completion",
        run: scoreboard::run,
    },
    Block {
        name: "condstream",
        about: "conditional streams: input and output in cluster order, flush at kernel end, network and scratchpad reservation",
        run: condstream::run,
    },
    Block {
        name: "microcontroller",
        about: "microcontroller: counted, stream and condition loops, nesting, multi-pass bodies, squash, refusals",
        run: microcontroller::run,
    },
];

/// The testbench called `name`.
pub fn find(name: &str) -> Option<&'static Block> {
    BLOCKS.iter().find(|b| b.name == name)
}

/// What a testbench hands back: its scoreboard, coverage and waveform.
pub struct Outcome {
    pub scoreboard: Scoreboard,
    pub coverage: Coverage,
    /// What the waveform holds, when one was asked for, or why it could not be written.
    pub waves: Result<Option<VcdSummary>, String>,
}

/// Runs `block` on `desc` and times it.
pub fn run_block(block: &Block, desc: &MachineDesc, config: &Config) -> Report {
    let start = Instant::now();
    let Outcome {
        scoreboard,
        coverage,
        waves,
    } = (block.run)(desc, config);
    Report {
        block: block.name,
        machine: desc.name.clone(),
        seed: config.seed,
        scoreboard,
        coverage,
        vcd: config.waves.as_ref().map(|w| w.path.clone()),
        waves,
        host_time: start.elapsed(),
    }
}

/// Runs `block` and, if it fails and `vcd` is given, replays it from its seed with a
/// waveform around the first mismatch written to `vcd` (see [`waves`]); the report is the
/// replay's, which is the same run.
pub fn run_block_with_waves(
    block: &Block,
    desc: &MachineDesc,
    config: &Config,
    vcd: Option<&std::path::Path>,
) -> Report {
    let report = run_block(block, desc, config);
    match (vcd, &report.scoreboard.first) {
        (Some(path), Some(first)) => {
            let replay = Config {
                waves: Some(WaveRequest::around(path, first.cycle)),
                ..config.clone()
            };
            run_block(block, desc, &replay)
        }
        _ => report,
    }
}

// ---- stimulus ----------------------------------------------------------------------------

/// A small deterministic generator (the arithmetic tests' SplitMix64) with the draws the
/// testbenches use: the same seed gives the same stimulus on every host, so a failure is
/// replayed by its seed.
#[derive(Clone, Debug)]
pub struct Rng(SplitMix64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(SplitMix64::new(seed))
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    pub fn word(&mut self) -> u32 {
        (self.next_u64() >> 32) as u32
    }

    /// Uniform in `0..n` (`n > 0`).
    pub fn below(&mut self, n: u64) -> u64 {
        ((self.next_u64() as u128 * n as u128) >> 64) as u64
    }

    /// Uniform in `0..n` as a `usize`.
    pub fn index(&mut self, n: usize) -> usize {
        self.below(n as u64) as usize
    }

    /// True with probability `percent`/100.
    pub fn chance(&mut self, percent: u64) -> bool {
        self.below(100) < percent
    }

    pub fn pick<T: Copy>(&mut self, from: &[T]) -> T {
        from[self.index(from.len())]
    }

    /// A word biased to the corners of the datapath: half the time one of the boundary
    /// patterns of 32-bit, 16-bit and 8-bit lanes, else uniform.
    pub fn corner_word(&mut self) -> u32 {
        const CORNERS: &[u32] = &[
            0,
            1,
            u32::MAX,
            0x7FFF_FFFF,
            0x8000_0000,
            0x7FFF_7FFF,
            0x8000_8000,
            0xFFFF_0000,
            0x0000_FFFF,
            0x7F7F_7F7F,
            0x8080_8080,
            0xFF00_FF00,
            0x00FF_00FF,
            0x0001_0001,
            31,
            32,
        ];
        if self.chance(50) {
            self.pick(CORNERS)
        } else {
            self.word()
        }
    }

    /// One word per cluster, each a [`corner_word`](Self::corner_word).
    pub fn lane_words(&mut self, lanes: usize) -> Vec<u32> {
        (0..lanes).map(|_| self.corner_word()).collect()
    }

    /// A write mask over `lanes` clusters, biased to all on, all off and one on.
    pub fn mask(&mut self, lanes: usize) -> Vec<bool> {
        match self.below(4) {
            0 => vec![true; lanes],
            1 => vec![false; lanes],
            2 => {
                let on = self.index(lanes);
                (0..lanes).map(|c| c == on).collect()
            }
            _ => (0..lanes).map(|_| self.chance(50)).collect(),
        }
    }
}

// ---- checking ----------------------------------------------------------------------------

/// The first disagreement between block and reference.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mismatch {
    pub cycle: u64,
    pub what: String,
    pub expected: String,
    pub got: String,
}

/// Compares every transaction with the reference model; counts transactions and
/// mismatches and keeps the first mismatch.
#[derive(Debug, Default)]
pub struct Scoreboard {
    pub transactions: u64,
    pub checks: u64,
    pub mismatches: u64,
    pub first: Option<Mismatch>,
}

impl Scoreboard {
    /// One transaction driven into the block.
    pub fn transaction(&mut self) {
        self.transactions += 1;
    }

    /// Checks that the block `got` what the reference `expected`.
    pub fn check<T: PartialEq + fmt::Debug>(
        &mut self,
        cycle: u64,
        what: impl FnOnce() -> String,
        expected: T,
        got: T,
    ) {
        self.checks += 1;
        if expected != got {
            self.mismatch(cycle, what(), format!("{expected:?}"), format!("{got:?}"));
        }
    }

    /// A contract assertion: `holds` must be true.
    pub fn assert(&mut self, cycle: u64, holds: bool, what: impl FnOnce() -> String) {
        self.check(cycle, what, true, holds);
    }

    fn mismatch(&mut self, cycle: u64, what: String, expected: String, got: String) {
        self.mismatches += 1;
        self.first.get_or_insert(Mismatch {
            cycle,
            what,
            expected,
            got,
        });
    }
}

/// Functional coverage: named bins, each counting how often its corner case was reached.
#[derive(Clone, Debug)]
pub struct Coverage {
    bins: Vec<(String, u64)>,
}

impl Coverage {
    pub fn new<S: AsRef<str>>(names: &[S]) -> Self {
        Coverage {
            bins: names.iter().map(|n| (n.as_ref().to_string(), 0)).collect(),
        }
    }

    /// Counts one hit of bin `name` (a bin this testbench declared).
    pub fn hit(&mut self, name: &str) {
        match self.bins.iter_mut().find(|(n, _)| *n == name) {
            Some((_, count)) => *count += 1,
            None => panic!("coverage bin `{name}` was not declared"),
        }
    }

    /// Counts a hit of `name` when `cond` holds.
    pub fn hit_if(&mut self, cond: bool, name: &str) {
        if cond {
            self.hit(name);
        }
    }

    pub fn bins(&self) -> &[(String, u64)] {
        &self.bins
    }

    pub fn reached(&self) -> usize {
        self.bins.iter().filter(|(_, n)| *n > 0).count()
    }

    pub fn total(&self) -> usize {
        self.bins.len()
    }
}

/// The result of one testbench run.
#[derive(Debug)]
pub struct Report {
    pub block: &'static str,
    pub machine: String,
    pub seed: u64,
    pub scoreboard: Scoreboard,
    pub coverage: Coverage,
    /// The waveform this run was asked to write (a replay of a failure), and what it holds
    /// or why it could not be written.
    pub vcd: Option<std::path::PathBuf>,
    pub waves: Result<Option<VcdSummary>, String>,
    pub host_time: Duration,
}

impl Report {
    /// Passed: transactions were driven and none disagreed with the reference.
    pub fn passed(&self) -> bool {
        self.scoreboard.transactions > 0 && self.scoreboard.mismatches == 0
    }

    /// The first mismatch as a person reads it, with the command that replays it.
    pub fn first_mismatch(&self) -> Option<String> {
        let m = self.scoreboard.first.as_ref()?;
        Some(format!(
            "{} on {}: first mismatch in cycle {}: {}\n  expected: {}\n  got:      {}\n  replay:   imagine verify {} --machine {} --seed {}",
            self.block,
            self.machine,
            m.cycle,
            m.what,
            m.expected,
            m.got,
            self.block,
            self.machine,
            self.seed
        ))
    }
}

/// The cycle-level harness a lane-batched block needs: a design to register its probes in.
pub(crate) fn design() -> imagine_hdl::Design {
    imagine_hdl::Design::new("top", imagine_hdl::default_domains())
        .expect("the default clock domains are valid")
}
