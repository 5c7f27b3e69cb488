//! Machine descriptions: every count, size and latency of the modelled machine comes from a
//! TOML file in `machines/` (ARCHITECTURE §4). Parsing rejects unknown keys, so a typo is
//! an error rather than a silently ignored setting, and [`MachineDesc::validate`] rejects
//! descriptions that cannot be built, naming the offending key.

use std::fmt;
use std::path::Path;

use serde::Deserialize;

use crate::arith::fp32::FpMode;

#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct MachineDesc {
    pub name: String,
    #[serde(default)]
    pub description: String,
    pub clocks: Clocks,
    pub cluster: Cluster,
    #[serde(default)]
    pub arithmetic: Arithmetic,
    pub latency: Latency,
    pub lrf: Lrf,
    pub scratchpad: Scratchpad,
    pub srf: Srf,
    pub microcontroller: Microcontroller,
    pub dram: Dram,
    pub memory: Memory,
    pub stream_controller: StreamController,
    /// A texture cache between memory and the SRF (thesis §6.5); none when absent.
    #[serde(default)]
    pub texture_cache: Option<TextureCacheDesc>,
    /// The S3 superscalar rasterizer (Wolfe & Noonburg); absent means the paper's defaults.
    #[serde(default)]
    pub s3: S3,
    /// The thesis's hardware rasterizer beside the clusters (§6.6, `gold8+hwrast`); none
    /// when absent.
    #[serde(default)]
    pub rasterizer: Option<RasterizerDesc>,
}

/// The hardware rasterizer ([`crate::hwrast`]): an SRF client the stream controller runs
/// as a *hardware kernel* (thesis §6.6). The thesis gives the output rate (1 word per
/// cycle) and the latency (100 cycles from a triangle to its fragments); the other keys are
/// ours (A), chosen so that they do not bind on the thesis's scenes (see the README).
#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct RasterizerDesc {
    /// Core cycles from the last word of a triangle's input records to its first
    /// fragment word (100 in the thesis).
    pub latency: u64,
    /// Fragment words written into the SRF per core cycle, over all output streams (1 in
    /// the thesis).
    pub output_words_per_cycle: usize,
    /// Words read per core cycle from each input stream (A).
    pub input_words_per_cycle: usize,
    /// Triangles between input and output at once: set up and waiting out the latency,
    /// or being written (A).
    pub triangles_in_flight: usize,
    /// Candidate pixels of a triangle's bounding box tested per core cycle (A).
    pub pixels_per_cycle: usize,
}

/// Stream buffers the rasterizer uses beside the kernels' and the address generators':
/// its input streams (window, |det|, attributes) and its output streams (address, depth,
/// primitive, colour or varyings).
pub const RASTERIZER_STREAM_BUFFERS: usize = 7;

/// The S3 superscalar out-of-order rasterizer (`units::s3`): Wolfe & Noonburg, "A
/// Superscalar 3D Graphics Engine" (spec `s3-ellsworth-piko.md` §1.2). Every key has the
/// paper's value as its default; where the paper gives none the default is ours, marked (A).
#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields, default)]
pub struct S3 {
    /// Rasterizing accelerators K; the paper quotes its results at 16.
    pub accelerators: usize,
    /// Candidate buffers per accelerator (the issue window is this × K): 8 in Fig. 12,
    /// swept 1, 2, 4, 8 in Fig. 13. Destination reservation stations are candidates + K
    /// (the paper's sizing rule).
    pub window_per_accelerator: usize,
    /// Source-region slots per primitive (each a source reservation-station file): 0 to 2.
    pub source_slots: usize,
    /// Cut triangles taller than `split_height` rows into slices at fetch (§4.5).
    pub split: bool,
    /// Rows per slice when splitting: 32.
    pub split_height: usize,
    /// Dependence-chain breaking for opaque Z-buffered triangles (§4.6).
    pub chain_break: bool,
    /// Which ready candidate issues: `random` (l.175, from a 32-bit LFSR seeded with
    /// `select_seed`) or `oldest` (l.128).
    pub select: String,
    /// Seed of the random select policy's LFSR (non-zero).
    pub select_seed: u32,
    /// Entries of the command queue between the host and fetch (A).
    pub queue_entries: usize,
    /// Cycles of triangle setup in an accelerator (A: the paper calls setup negligible
    /// and gives no figure).
    pub setup_cycles: u32,
    /// Frame-buffer memory: `ideal` (multi-ported, fixed latency, 128 bits per clock per
    /// accelerator, as simulated in the paper) or `dram` (the machine's `[dram]` channels
    /// through `[memory]`'s scheduler and crossings, see `s3::fbdram`).
    pub memory: String,
    /// Cycles from an accelerator's request to the memory and from the memory back (A).
    pub memory_latency: u32,
}

impl Default for S3 {
    fn default() -> Self {
        S3 {
            accelerators: 16,
            window_per_accelerator: 8,
            source_slots: 1,
            split: true,
            split_height: 32,
            chain_break: true,
            select: "random".into(),
            select_seed: 1,
            queue_entries: 16,
            setup_cycles: 8,
            memory: "ideal".into(),
            memory_latency: 1,
        }
    }
}

/// The select policies of [`S3::select`].
pub const S3_SELECT: &[&str] = &["random", "oldest"];
/// The S3 frame-buffer memory modes (`s3.memory`).
pub const S3_MEMORY: &[&str] = &["ideal", "dram"];

#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Clocks {
    pub core_mhz: u64,
    pub dram_mhz: u64,
}

#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Cluster {
    /// Clusters, all driven by one microcontroller (SIMD).
    pub count: usize,
    pub adders: usize,
    pub multipliers: usize,
    pub divsqrt: usize,
    /// Scratchpads per cluster (each with its own address and data LRFs).
    pub scratchpads: usize,
    /// Intercluster communication units per cluster.
    pub comm_units: usize,
    /// Condition-code registers (1 bit each) per cluster.
    pub condition_codes: usize,
}

/// Local register files: one per functional-unit input.
#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Lrf {
    /// Entries of an ordinary LRF.
    pub entries: usize,
    /// Entries of the larger LRFs.
    pub large_entries: usize,
    /// The LRFs that are large, named `unit.input` (e.g. `add0.a`).
    pub large: Vec<String>,
}

#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Scratchpad {
    /// Words per cluster per scratchpad.
    pub words: usize,
}

/// The stream register file.
#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Srf {
    /// Capacity in 32-bit words.
    pub words: usize,
    pub banks: usize,
    /// Allocation and transfer unit; streams start on block boundaries.
    pub block_words: usize,
    /// Total SRF bandwidth, words per core cycle.
    pub words_per_cycle: usize,
    pub stream_buffers: usize,
    /// Streams one kernel may address.
    pub kernel_streams: usize,
    /// Unconditional stream words per cluster per cycle.
    pub cluster_words_per_cycle: usize,
    /// Conditional stream words per cluster per cycle.
    pub conditional_words_per_cycle: usize,
}

#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Microcontroller {
    /// Microcode store, in VLIW instructions.
    pub store_words: usize,
    /// Nested loops the loop stack holds.
    pub loop_depth: usize,
}

/// The SDRAM: geometry and timing of one channel's part, in DRAM clock cycles (gold8: a
/// 128 Mb ×32 SDR part, Micron MT48LC4M32B2 -6 at 167 MHz; see `dram` for the sources).
#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Dram {
    /// Independent channels, each with its own command and 32-bit data bus.
    pub channels: usize,
    /// Internal banks per channel.
    pub banks: usize,
    /// Rows per bank.
    pub rows: usize,
    /// Columns (32-bit words) per row.
    pub columns: usize,
    /// Words moved by one READ or WRITE command (the burst length).
    pub burst_words: usize,
    /// CAS latency: READ command to first data word.
    pub cas_latency: u32,
    /// ACTIVATE to READ/WRITE of the same bank.
    pub t_rcd: u32,
    /// PRECHARGE to ACTIVATE of the same bank.
    pub t_rp: u32,
    /// ACTIVATE to PRECHARGE of the same bank.
    pub t_ras: u32,
    /// ACTIVATE to ACTIVATE of the same bank.
    pub t_rc: u32,
    /// ACTIVATE to ACTIVATE of different banks of a channel.
    pub t_rrd: u32,
    /// Last write data word to PRECHARGE of the same bank (write recovery).
    pub t_wr: u32,
    /// Idle data-bus cycles between the last read data word and the first write data word.
    pub turnaround: u32,
    /// Average interval between AUTO REFRESH commands (tREFI).
    pub refresh_interval: u32,
    /// AUTO REFRESH to any command (tRFC).
    pub t_rfc: u32,
}

/// The memory system between the SRF and the SDRAM (ARCHITECTURE §4, memory row).
#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Memory {
    /// Memory access scheduling policy (Rixner et al. ISCA 2000): `in-order`,
    /// `first-ready`, `col-open`, `col-closed`, `row-open`, `row-closed`,
    /// `load-over-store`.
    pub policy: String,
    /// Entries of each channel's pending-reference buffer.
    pub pending_references: usize,
    /// Address generators (each runs one load or store stream at a time).
    pub address_generators: usize,
    /// Words each address generator issues and retires per core cycle.
    pub ag_words_per_cycle: usize,
    /// Words an address generator may have outstanding (its reorder buffer).
    pub ag_reorder_words: usize,
    /// Entries of each clock-crossing FIFO between the core and a channel.
    pub crossing_entries: usize,
    /// Flip-flops in each pointer synchroniser of a crossing FIFO.
    pub sync_stages: usize,
}

/// The texture cache (thesis §6.5, [`crate::memory::TextureCache`]): read-only,
/// direct-mapped, serving the streams the stream program marks cacheable.
#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct TextureCacheDesc {
    /// Data words (a power of two; 16 K in the thesis).
    pub words: usize,
    /// Words per line (a power of two; 2 in the thesis).
    pub line_words: usize,
    /// Words of hits handed to the address generators per core cycle, all together (the
    /// thesis's memory-to-SRF bandwidth ×n).
    pub hit_words_per_cycle: usize,
}

/// The stream controller (ARCHITECTURE §4).
#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct StreamController {
    /// Stream instructions the host may queue ahead of the scoreboard.
    pub queue_entries: usize,
    /// Stream instructions tracked at once for dependencies.
    pub scoreboard_entries: usize,
    /// Host dispatch overhead: a kernel occupies the clusters for at least this many core
    /// cycles.
    pub min_kernel_cycles: u64,
    /// Words per core cycle the host interface moves between the host and the SRF (kernel
    /// parameters in, counts out).
    pub host_words_per_cycle: usize,
}

#[derive(Clone, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Arithmetic {
    /// Flush subnormal fp32 inputs and results to zero.
    #[serde(default)]
    pub flush_to_zero: bool,
}

/// Latencies in core cycles.
#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Latency {
    /// Integer, logic, shift, select and packed add/sub in an adder.
    pub int: u32,
    /// fp32 add, subtract, compare, convert, min/max in an adder.
    pub fp_add: u32,
    /// Every multiply.
    pub mul: u32,
    pub div: u32,
    pub sqrt: u32,
    /// Cycles between issues to one divide/sqrt unit (1 = fully pipelined).
    pub divsqrt_issue_interval: u32,
    pub scratchpad_read: u32,
    pub scratchpad_write: u32,
    pub comm: u32,
    /// From a stream buffer to an LRF, or from an LRF into a stream buffer.
    pub stream: u32,
}

/// A machine description that cannot be read or built.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DescError {
    Io {
        path: String,
        message: String,
    },
    Parse {
        source: String,
        message: String,
    },
    Invalid {
        machine: String,
        /// The file (or built-in name) the description came from, once known.
        source: Option<String>,
        key: &'static str,
        problem: String,
    },
}

impl fmt::Display for DescError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DescError::Io { path, message } => {
                write!(f, "cannot read machine description {path}: {message}")
            }
            DescError::Parse { source, message } => {
                write!(f, "machine description {source}: {}", message.trim_end())
            }
            DescError::Invalid {
                machine,
                source,
                key,
                problem,
            } => match source {
                Some(source) if source != machine => {
                    write!(f, "machine `{machine}` ({source}): `{key}` {problem}")
                }
                _ => write!(f, "machine `{machine}`: `{key}` {problem}"),
            },
        }
    }
}

impl std::error::Error for DescError {}

use crate::limits::{MAX_BASE_DEPTH, MAX_LATENCY, MAX_MHZ, MAX_MIN_KERNEL_CYCLES, MAX_UNITS};
pub use crate::limits::{MAX_CLUSTERS, MAX_KERNEL_STREAMS};

/// The machine descriptions in `machines/`, built into the binary.
pub const BUILTIN: &[(&str, &str)] = &[
    ("gold8", include_str!("../../machines/gold8.toml")),
    ("gold1", include_str!("../../machines/gold1.toml")),
    ("gold2", include_str!("../../machines/gold2.toml")),
    ("gold4", include_str!("../../machines/gold4.toml")),
    ("gold16", include_str!("../../machines/gold16.toml")),
    ("gold32", include_str!("../../machines/gold32.toml")),
    ("gold8+F", include_str!("../../machines/gold8+F.toml")),
    ("gold8+C", include_str!("../../machines/gold8+C.toml")),
    ("gold8+F+C", include_str!("../../machines/gold8+F+C.toml")),
    (
        "gold8+srf4x",
        include_str!("../../machines/gold8+srf4x.toml"),
    ),
    (
        "gold32combo",
        include_str!("../../machines/gold32combo.toml"),
    ),
    (
        "gold32combo+tc1",
        include_str!("../../machines/gold32combo+tc1.toml"),
    ),
    (
        "gold32combo+tc4",
        include_str!("../../machines/gold32combo+tc4.toml"),
    ),
    (
        "gold32combo+tc32",
        include_str!("../../machines/gold32combo+tc32.toml"),
    ),
    (
        "gold8+hwrast",
        include_str!("../../machines/gold8+hwrast.toml"),
    ),
    ("reyes", include_str!("../../machines/reyes.toml")),
    ("reyes400", include_str!("../../machines/reyes400.toml")),
];

impl MachineDesc {
    /// Parses a description; `source` names it in errors (a path or a built-in name). A
    /// description may name a built-in `base` and give only the keys it changes.
    pub fn parse(text: &str, source: &str) -> Result<Self, DescError> {
        let table = resolve_base(text, source, 0)?;
        let desc: MachineDesc =
            table
                .try_into()
                .map_err(|e: toml::de::Error| DescError::Parse {
                    source: source.into(),
                    message: e.to_string(),
                })?;
        desc.validate().map_err(|e| match e {
            DescError::Invalid {
                machine,
                key,
                problem,
                ..
            } => DescError::Invalid {
                machine,
                source: Some(source.into()),
                key,
                problem,
            },
            e => e,
        })?;
        Ok(desc)
    }

    pub fn load(path: &Path) -> Result<Self, DescError> {
        let text = crate::limits::read_text_file(path).map_err(|e| DescError::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        Self::parse(&text, &path.display().to_string())
    }

    /// A built-in machine by name, or a description file by path.
    pub fn resolve(name_or_path: &str) -> Result<Self, DescError> {
        match builtin_text(name_or_path) {
            Some(text) => Self::parse(text, name_or_path),
            None if name_or_path.ends_with(".toml") || Path::new(name_or_path).exists() => {
                Self::load(Path::new(name_or_path))
            }
            None => Err(DescError::Io {
                path: name_or_path.into(),
                message: format!(
                    "no such machine; built-in machines are {}",
                    BUILTIN
                        .iter()
                        .map(|(n, _)| *n)
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            }),
        }
    }

    /// The built-in default machine, `machines/gold8.toml`.
    pub fn gold8() -> Self {
        Self::resolve("gold8").expect("gold8 is valid")
    }

    pub fn fp_mode(&self) -> FpMode {
        FpMode {
            flush_to_zero: self.arithmetic.flush_to_zero,
        }
    }

    /// The LRFs of a cluster, one per functional-unit input, named `unit.input`: adders
    /// `addN.a/b`, multipliers `mulN.a/b`, divide/sqrt `dsqN.a/b`, scratchpads `spN.addr/data`,
    /// communication units `commN.data/perm`, and the stream output port `sout.data`.
    pub fn lrf_names(&self) -> Vec<String> {
        let c = &self.cluster;
        let mut names = Vec::new();
        for (unit, n, inputs) in [
            ("add", c.adders, ["a", "b"]),
            ("mul", c.multipliers, ["a", "b"]),
            ("dsq", c.divsqrt, ["a", "b"]),
            ("sp", c.scratchpads, ["addr", "data"]),
            ("comm", c.comm_units, ["data", "perm"]),
        ] {
            for i in 0..n {
                names.extend(inputs.iter().map(|input| format!("{unit}{i}.{input}")));
            }
        }
        names.push("sout.data".into());
        names
    }

    /// Entries of the LRF called `name` (see [`lrf_names`](Self::lrf_names)).
    pub fn lrf_entries(&self, name: &str) -> usize {
        if self.lrf.large.iter().any(|l| l == name) {
            self.lrf.large_entries
        } else {
            self.lrf.entries
        }
    }

    /// The error naming `key` of this description and its `problem`.
    fn invalid(&self, key: &'static str, problem: String) -> Result<(), DescError> {
        Err(DescError::Invalid {
            machine: self.name.clone(),
            source: None,
            key,
            problem,
        })
    }

    /// Rejects descriptions that cannot be built.
    pub fn validate(&self) -> Result<(), DescError> {
        let bad = |key, problem| self.invalid(key, problem);
        let c = &self.cluster;
        if !(1..=MAX_CLUSTERS).contains(&c.count) {
            return bad(
                "cluster.count",
                format!("is {}, must be 1..={MAX_CLUSTERS}", c.count),
            );
        }
        for (key, n) in [
            ("cluster.adders", c.adders),
            ("cluster.multipliers", c.multipliers),
            ("cluster.divsqrt", c.divsqrt),
            ("cluster.scratchpads", c.scratchpads),
            ("cluster.comm_units", c.comm_units),
        ] {
            if !(1..=MAX_UNITS).contains(&n) {
                return bad(key, format!("is {n}, must be 1..={MAX_UNITS}"));
            }
        }
        let sizes = [
            ("cluster.condition_codes", c.condition_codes, 1, 256),
            ("lrf.entries", self.lrf.entries, 2, 1024),
            ("lrf.large_entries", self.lrf.large_entries, 2, 1024),
            ("scratchpad.words", self.scratchpad.words, 1, 1 << 16),
            ("srf.banks", self.srf.banks, 1, 256),
            ("srf.block_words", self.srf.block_words, 1, 1 << 16),
            ("srf.words_per_cycle", self.srf.words_per_cycle, 1, 1 << 12),
            ("srf.stream_buffers", self.srf.stream_buffers, 2, 256),
            (
                "srf.kernel_streams",
                self.srf.kernel_streams,
                1,
                MAX_KERNEL_STREAMS,
            ),
            (
                "srf.cluster_words_per_cycle",
                self.srf.cluster_words_per_cycle,
                1,
                64,
            ),
            (
                "srf.conditional_words_per_cycle",
                self.srf.conditional_words_per_cycle,
                1,
                64,
            ),
            (
                "microcontroller.store_words",
                self.microcontroller.store_words,
                1,
                1 << 20,
            ),
            (
                "microcontroller.loop_depth",
                self.microcontroller.loop_depth,
                1,
                64,
            ),
        ];
        for (key, v, lo, hi) in sizes {
            if !(lo..=hi).contains(&v) {
                return bad(key, format!("is {v}, must be {lo}..={hi}"));
            }
        }
        let srf = &self.srf;
        if !srf.words.is_multiple_of(srf.block_words * srf.banks)
            || srf.words == 0
            || srf.words > 1 << 26
        {
            return bad(
                "srf.words",
                format!(
                    "is {}, must be a positive multiple of banks × block_words = {} (at most 2^26)",
                    srf.words,
                    srf.banks * srf.block_words
                ),
            );
        }
        if srf.kernel_streams > srf.stream_buffers {
            return bad(
                "srf.kernel_streams",
                format!(
                    "is {}, more than the {} stream buffers",
                    srf.kernel_streams, srf.stream_buffers
                ),
            );
        }
        for name in &self.lrf.large {
            if !self.lrf_names().contains(name) {
                return bad(
                    "lrf.large",
                    format!(
                        "names `{name}`, which is not an LRF of this cluster ({})",
                        self.lrf_names().join(", ")
                    ),
                );
            }
        }
        for (key, mhz) in [
            ("clocks.core_mhz", self.clocks.core_mhz),
            ("clocks.dram_mhz", self.clocks.dram_mhz),
        ] {
            if !(1..=MAX_MHZ).contains(&mhz) {
                return bad(key, format!("is {mhz}, must be 1..={MAX_MHZ}"));
            }
        }
        let l = &self.latency;
        for (key, v) in [
            ("latency.int", l.int),
            ("latency.fp_add", l.fp_add),
            ("latency.mul", l.mul),
            ("latency.div", l.div),
            ("latency.sqrt", l.sqrt),
            ("latency.divsqrt_issue_interval", l.divsqrt_issue_interval),
            ("latency.scratchpad_read", l.scratchpad_read),
            ("latency.scratchpad_write", l.scratchpad_write),
            ("latency.comm", l.comm),
            ("latency.stream", l.stream),
        ] {
            if !(1..=MAX_LATENCY).contains(&v) {
                return bad(key, format!("is {v}, must be 1..={MAX_LATENCY} cycles"));
            }
        }
        self.validate_memory()?;
        self.validate_s3()?;
        self.validate_rasterizer()?;
        let shortest = l.div.min(l.sqrt);
        if l.divsqrt_issue_interval > shortest {
            return bad(
                "latency.divsqrt_issue_interval",
                format!(
                    "is {}, longer than the divide/sqrt latency {shortest}",
                    l.divsqrt_issue_interval
                ),
            );
        }
        Ok(())
    }
}

impl MachineDesc {
    fn validate_memory(&self) -> Result<(), DescError> {
        let bad = |key, problem| self.invalid(key, problem);
        let d = &self.dram;
        let pow2 = [
            ("dram.channels", d.channels, 16),
            ("dram.banks", d.banks, 16),
            ("dram.rows", d.rows, 1 << 16),
            ("dram.columns", d.columns, 1 << 12),
            ("dram.burst_words", d.burst_words, 8),
        ];
        for (key, v, hi) in pow2 {
            if !(1..=hi).contains(&v) || !v.is_power_of_two() {
                return bad(key, format!("is {v}, must be a power of two in 1..={hi}"));
            }
        }
        if d.burst_words > d.columns {
            return bad(
                "dram.burst_words",
                format!(
                    "is {}, more than the {} columns of a row",
                    d.burst_words, d.columns
                ),
            );
        }
        for (key, v, lo) in [
            ("dram.cas_latency", d.cas_latency, 1),
            ("dram.t_rcd", d.t_rcd, 1),
            ("dram.t_rp", d.t_rp, 1),
            ("dram.t_ras", d.t_ras, 1),
            ("dram.t_rc", d.t_rc, 1),
            ("dram.t_rrd", d.t_rrd, 1),
            ("dram.t_wr", d.t_wr, 1),
            ("dram.turnaround", d.turnaround, 0),
            ("dram.t_rfc", d.t_rfc, 1),
        ] {
            if !(lo..=MAX_LATENCY).contains(&v) {
                return bad(key, format!("is {v}, must be {lo}..={MAX_LATENCY} cycles"));
            }
        }
        if d.t_rc < d.t_ras + d.t_rp {
            return bad(
                "dram.t_rc",
                format!(
                    "is {}, less than t_ras + t_rp = {} (a row cycle is an activate and a precharge)",
                    d.t_rc,
                    d.t_ras + d.t_rp
                ),
            );
        }
        let min_refi = 4 * (d.t_rc + d.t_rfc);
        if !(min_refi..=1 << 20).contains(&d.refresh_interval) {
            return bad(
                "dram.refresh_interval",
                format!(
                    "is {}, must be {min_refi}..={} cycles (at least 4 × (t_rc + t_rfc))",
                    d.refresh_interval,
                    1 << 20
                ),
            );
        }
        let m = &self.memory;
        if crate::dram::Policy::parse(&m.policy).is_none() {
            return bad(
                "memory.policy",
                format!(
                    "is `{}`, must be one of {}",
                    m.policy,
                    crate::dram::Policy::NAMES.join(", ")
                ),
            );
        }
        for (key, v, lo, hi) in [
            ("memory.pending_references", m.pending_references, 1, 256),
            ("memory.address_generators", m.address_generators, 1, 8),
            ("memory.ag_words_per_cycle", m.ag_words_per_cycle, 1, 16),
            ("memory.ag_reorder_words", m.ag_reorder_words, 1, 1 << 16),
            ("memory.crossing_entries", m.crossing_entries, 1, 1024),
            ("memory.sync_stages", m.sync_stages, 1, 8),
            (
                "stream_controller.queue_entries",
                self.stream_controller.queue_entries,
                1,
                1 << 16,
            ),
            (
                "stream_controller.scoreboard_entries",
                self.stream_controller.scoreboard_entries,
                1,
                256,
            ),
            (
                "stream_controller.host_words_per_cycle",
                self.stream_controller.host_words_per_cycle,
                1,
                64,
            ),
        ] {
            if !(lo..=hi).contains(&v) {
                return bad(key, format!("is {v}, must be {lo}..={hi}"));
            }
        }
        if let Some(t) = &self.texture_cache {
            let pow2 = |v: usize, hi: usize| v.is_power_of_two() && v <= hi;
            if !pow2(t.words, 1 << 20) {
                return bad(
                    "texture_cache.words",
                    format!("is {}, must be a power of two up to {}", t.words, 1 << 20),
                );
            }
            if !pow2(t.line_words, 64.min(t.words)) {
                return bad(
                    "texture_cache.line_words",
                    format!(
                        "is {}, must be a power of two up to {} (and at most 64)",
                        t.line_words, t.words
                    ),
                );
            }
            if !(1..=64).contains(&t.hit_words_per_cycle) {
                return bad(
                    "texture_cache.hit_words_per_cycle",
                    format!("is {}, must be 1..=64", t.hit_words_per_cycle),
                );
            }
            // A line fill's reply carries its word address in the reference tag.
            let words = crate::dram::DramParams::of(self).capacity_bytes() / 4;
            if words > crate::memory::address_gen::FILL_ADDRESS_LIMIT {
                return bad(
                    "texture_cache",
                    format!(
                        "needs DRAM of at most {} words; this machine has {words}",
                        crate::memory::address_gen::FILL_ADDRESS_LIMIT
                    ),
                );
            }
        }
        if m.ag_reorder_words < m.ag_words_per_cycle {
            return bad(
                "memory.ag_reorder_words",
                format!(
                    "is {}, less than ag_words_per_cycle = {}",
                    m.ag_reorder_words, m.ag_words_per_cycle
                ),
            );
        }
        let needed = self.srf.kernel_streams + 2 * m.address_generators;
        if self.srf.stream_buffers < needed {
            return bad(
                "memory.address_generators",
                format!(
                    "is {}: each needs 2 stream buffers besides the {} kernel streams, and \
                     the SRF has {} (need {needed})",
                    m.address_generators, self.srf.kernel_streams, self.srf.stream_buffers
                ),
            );
        }
        if self.stream_controller.min_kernel_cycles > MAX_MIN_KERNEL_CYCLES {
            return bad(
                "stream_controller.min_kernel_cycles",
                format!(
                    "is {}, must be at most {MAX_MIN_KERNEL_CYCLES}",
                    self.stream_controller.min_kernel_cycles,
                ),
            );
        }
        Ok(())
    }
}

impl MachineDesc {
    fn validate_rasterizer(&self) -> Result<(), DescError> {
        let Some(r) = &self.rasterizer else {
            return Ok(());
        };
        let bad = |key, problem| self.invalid(key, problem);
        for (key, v, lo, hi) in [
            ("rasterizer.latency", r.latency as usize, 1, 1 << 16),
            (
                "rasterizer.output_words_per_cycle",
                r.output_words_per_cycle,
                1,
                64,
            ),
            (
                "rasterizer.input_words_per_cycle",
                r.input_words_per_cycle,
                1,
                64,
            ),
            (
                "rasterizer.triangles_in_flight",
                r.triangles_in_flight,
                1,
                4096,
            ),
            (
                "rasterizer.pixels_per_cycle",
                r.pixels_per_cycle,
                1,
                1 << 16,
            ),
        ] {
            if !(lo..=hi).contains(&v) {
                return bad(key, format!("is {v}, must be {lo}..={hi}"));
            }
        }
        let needed = self.srf.kernel_streams
            + 2 * self.memory.address_generators
            + RASTERIZER_STREAM_BUFFERS;
        if self.srf.stream_buffers < needed {
            return bad(
                "rasterizer",
                format!(
                    "needs {RASTERIZER_STREAM_BUFFERS} stream buffers of its own besides the \
                     {} kernel streams and the address generators' {}: srf.stream_buffers \
                     is {}, need {needed}",
                    self.srf.kernel_streams,
                    2 * self.memory.address_generators,
                    self.srf.stream_buffers
                ),
            );
        }
        Ok(())
    }

    fn validate_s3(&self) -> Result<(), DescError> {
        let bad = |key, problem| self.invalid(key, problem);
        let s = &self.s3;
        for (key, v, lo, hi) in [
            (
                "s3.accelerators",
                s.accelerators,
                1,
                crate::limits::MAX_S3_ACCELERATORS,
            ),
            ("s3.window_per_accelerator", s.window_per_accelerator, 1, 64),
            ("s3.source_slots", s.source_slots, 0, 2),
            (
                "s3.split_height",
                s.split_height,
                1,
                crate::limits::MAX_WINDOW as usize,
            ),
            ("s3.queue_entries", s.queue_entries, 1, 1 << 16),
            (
                "s3.setup_cycles",
                s.setup_cycles as usize,
                1,
                MAX_LATENCY as usize,
            ),
            (
                "s3.memory_latency",
                s.memory_latency as usize,
                1,
                MAX_LATENCY as usize,
            ),
        ] {
            if !(lo..=hi).contains(&v) {
                return bad(key, format!("is {v}, must be {lo}..={hi}"));
            }
        }
        if !S3_SELECT.contains(&s.select.as_str()) {
            return bad(
                "s3.select",
                format!("is `{}`, must be one of {}", s.select, S3_SELECT.join(", ")),
            );
        }
        if s.select_seed == 0 {
            return bad(
                "s3.select_seed",
                "is 0, must be non-zero (an LFSR seed)".into(),
            );
        }
        if !S3_MEMORY.contains(&s.memory.as_str()) {
            return bad(
                "s3.memory",
                format!(
                    "is `{}`, must be one of {} (the paper's ideal memory, or the machine's \
                     DRAM channels)",
                    s.memory,
                    S3_MEMORY.join(", ")
                ),
            );
        }
        Ok(())
    }
}

fn builtin_text(name: &str) -> Option<&'static str> {
    BUILTIN.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// Parses `text` and, if it names a `base`, lays its keys over the base's (tables merge key
/// by key; any other value replaces the base's).
fn resolve_base(text: &str, source: &str, depth: usize) -> Result<toml::Table, DescError> {
    let parse_error = |message: String| DescError::Parse {
        source: source.into(),
        message,
    };
    let mut table: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| parse_error(e.to_string()))?;
    let Some(base) = table.remove("base") else {
        return Ok(table);
    };
    let Some(base) = base.as_str() else {
        return Err(parse_error(
            "`base` must be the name of a built-in machine".into(),
        ));
    };
    if depth >= MAX_BASE_DEPTH {
        return Err(parse_error(format!(
            "`base` chain is longer than {MAX_BASE_DEPTH} (a cycle?)"
        )));
    }
    let Some(base_text) = builtin_text(base) else {
        return Err(parse_error(format!(
            "`base` names `{base}`, which is not a built-in machine"
        )));
    };
    let mut merged = resolve_base(base_text, base, depth + 1)?;
    merge(&mut merged, table);
    Ok(merged)
}

fn merge(into: &mut toml::Table, from: toml::Table) {
    for (key, value) in from {
        match (into.get_mut(&key), value) {
            (Some(toml::Value::Table(a)), toml::Value::Table(b)) => merge(a, b),
            (_, value) => {
                into.insert(key, value);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOLD8: &str = include_str!("../../machines/gold8.toml");

    #[test]
    fn gold8_has_the_architecture_defaults() {
        let m = MachineDesc::gold8();
        assert_eq!(
            (
                m.cluster.count,
                m.cluster.adders,
                m.cluster.multipliers,
                m.cluster.divsqrt
            ),
            (8, 3, 2, 1)
        );
        assert_eq!(
            (
                m.latency.int,
                m.latency.fp_add,
                m.latency.mul,
                m.latency.div
            ),
            (2, 4, 4, 16)
        );
        assert_eq!(m.latency.divsqrt_issue_interval, 8);
        // 2×32 + 15×16 LRF entries per cluster.
        let names = m.lrf_names();
        assert_eq!(names.len(), 17);
        let sizes: Vec<usize> = names.iter().map(|n| m.lrf_entries(n)).collect();
        assert_eq!(sizes.iter().filter(|&&e| e == 32).count(), 2);
        assert_eq!(sizes.iter().filter(|&&e| e == 16).count(), 15);
        assert_eq!(
            (
                m.srf.words,
                m.srf.banks,
                m.srf.block_words,
                m.srf.words_per_cycle
            ),
            (32768, 8, 32, 16)
        );
        assert_eq!(
            (
                m.scratchpad.words,
                m.cluster.condition_codes,
                m.microcontroller.store_words
            ),
            (256, 16, 2048)
        );
        assert_eq!((m.clocks.core_mhz, m.clocks.dram_mhz), (500, 167));
        assert!(!m.fp_mode().flush_to_zero);
    }

    #[test]
    fn every_builtin_machine_is_valid_and_differs_as_named() {
        for (name, _) in BUILTIN {
            let m = MachineDesc::resolve(name).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(&m.name, name);
        }
        let get = |n| MachineDesc::resolve(n).unwrap();
        assert_eq!(get("gold1").cluster.count, 1);
        assert_eq!(
            (get("gold16").cluster.count, get("gold16").srf.words),
            (16, 65536)
        );
        assert_eq!(
            (get("gold32").cluster.count, get("gold32").srf.words),
            (32, 131072)
        );
        let f = get("gold8+F");
        assert_eq!(
            (
                f.cluster.adders,
                f.cluster.multipliers,
                f.latency.divsqrt_issue_interval
            ),
            (6, 4, 1)
        );
        let c = get("gold8+C");
        assert_eq!(
            (
                c.cluster.comm_units,
                c.cluster.scratchpads,
                c.cluster.adders
            ),
            (3, 3, 3)
        );
        let fc = get("gold8+F+C");
        assert_eq!((fc.cluster.adders, fc.cluster.comm_units), (6, 3));
        assert_eq!(get("gold8+srf4x").srf.words, 4 * get("gold8").srf.words);
        let combo = get("gold32combo");
        assert_eq!(
            (
                combo.cluster.count,
                combo.cluster.adders,
                combo.cluster.comm_units
            ),
            (32, 6, 3)
        );
        // The texture-cache machines: the thesis's cache, at ×1, ×4 and ×32.
        for (name, n) in [
            ("gold32combo+tc1", 1),
            ("gold32combo+tc4", 4),
            ("gold32combo+tc32", 32),
        ] {
            let tc = get(name);
            let cache = tc.texture_cache.as_ref().expect("a texture cache");
            assert_eq!((cache.words, cache.line_words), (16384, 2));
            assert_eq!(cache.hit_words_per_cycle, n);
            assert_eq!(tc.cluster, combo.cluster);
        }
        assert!(combo.texture_cache.is_none());
        // Inherited keys stay as the base has them.
        assert_eq!(get("gold16").latency, get("gold8").latency);
    }

    #[test]
    fn bad_bases_and_unknown_machines_are_named() {
        let e = MachineDesc::parse("name = \"x\"\nbase = \"gold9\"", "x.toml").unwrap_err();
        assert!(e.to_string().contains("gold9"), "{e}");
        let e = MachineDesc::resolve("gold7").unwrap_err();
        assert!(
            e.to_string().contains("gold7") && e.to_string().contains("gold8+F"),
            "{e}"
        );
        let e = MachineDesc::parse(
            "name = \"x\"\nbase = \"gold8\"\n[cluster]\ncount = 0",
            "x.toml",
        )
        .unwrap_err();
        assert!(e.to_string().contains("cluster.count"), "{e}");
        let e = MachineDesc::parse("name = \"x\"\nbase = 3", "x.toml").unwrap_err();
        assert!(e.to_string().contains("base"), "{e}");
    }

    #[test]
    fn typos_and_impossible_values_are_named() {
        let e = MachineDesc::parse(&GOLD8.replace("adders = 3", "addres = 3"), "t").unwrap_err();
        assert!(e.to_string().contains("addres"), "{e}");
        let e = MachineDesc::parse(&GOLD8.replace("count = 8", "count = 0"), "t").unwrap_err();
        assert!(e.to_string().contains("cluster.count"), "{e}");
        let e = MachineDesc::parse(
            &GOLD8.replace("divsqrt_issue_interval = 8", "divsqrt_issue_interval = 17"),
            "t",
        )
        .unwrap_err();
        assert!(e.to_string().contains("divsqrt_issue_interval"), "{e}");
        let e = MachineDesc::parse(&GOLD8.replace("mul = 4", "mul = 0"), "t").unwrap_err();
        assert!(e.to_string().contains("latency.mul"), "{e}");
        let e =
            MachineDesc::parse(&GOLD8.replace("core_mhz = 500", "core_mhz = -5"), "t").unwrap_err();
        assert!(e.to_string().contains("core_mhz"), "{e}");
        let e =
            MachineDesc::parse(&GOLD8.replace("words = 32768", "words = 1000"), "t").unwrap_err();
        assert!(e.to_string().contains("srf.words"), "{e}");
        let e = MachineDesc::parse(&GOLD8.replace("\"add0.a\"", "\"add9.a\""), "t").unwrap_err();
        assert!(e.to_string().contains("add9.a"), "{e}");
        for (from, to, key) in [
            ("t_rc = 10", "t_rc = 9", "dram.t_rc"),
            ("banks = 4", "banks = 3", "dram.banks"),
            (
                "policy = \"first-ready\"",
                "policy = \"fastest\"",
                "memory.policy",
            ),
            (
                "pending_references = 32",
                "pending_references = 0",
                "memory.pending_references",
            ),
            (
                "address_generators = 2",
                "address_generators = 8",
                "memory.address_generators",
            ),
            (
                "scoreboard_entries = 32",
                "scoreboard_entries = 0",
                "stream_controller.scoreboard_entries",
            ),
            (
                "host_words_per_cycle = 1",
                "host_words_per_cycle = 0",
                "stream_controller.host_words_per_cycle",
            ),
            (
                "refresh_interval = 2604",
                "refresh_interval = 5",
                "dram.refresh_interval",
            ),
        ] {
            let e = MachineDesc::parse(&GOLD8.replace(from, to), "t").unwrap_err();
            assert!(e.to_string().contains(key), "{from}: {e}");
        }
        // More kernel streams than the model keeps state for, with the buffers to serve them.
        let e = MachineDesc::parse(
            &GOLD8
                .replace("kernel_streams = 8", "kernel_streams = 65")
                .replace("stream_buffers = 22", "stream_buffers = 80"),
            "t",
        )
        .unwrap_err();
        assert!(e.to_string().contains("srf.kernel_streams"), "{e}");
        // A file's errors name the file as well as the machine.
        let e = MachineDesc::parse(&GOLD8.replace("count = 8", "count = 257"), "dir/big.toml")
            .unwrap_err();
        assert!(
            e.to_string().contains("dir/big.toml") && e.to_string().contains("cluster.count"),
            "{e}"
        );
        let m = MachineDesc::gold8();
        assert_eq!(
            (m.dram.channels, m.dram.banks, m.dram.rows, m.dram.columns),
            (4, 4, 4096, 256)
        );
        assert_eq!(
            (m.memory.pending_references, m.memory.address_generators),
            (32, 2)
        );
        assert_eq!(m.stream_controller.min_kernel_cycles, 300);
        let e = MachineDesc::load(Path::new("/nonexistent/m.toml")).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/m.toml"), "{e}");
    }

    #[test]
    fn an_impossible_texture_cache_is_refused_naming_its_key() {
        for (keys, key) in [
            (
                "words = 1000\nline_words = 2\nhit_words_per_cycle = 1",
                "texture_cache.words",
            ),
            (
                "words = 16\nline_words = 3\nhit_words_per_cycle = 1",
                "texture_cache.line_words",
            ),
            (
                "words = 16\nline_words = 32\nhit_words_per_cycle = 1",
                "texture_cache.line_words",
            ),
            (
                "words = 16\nline_words = 2\nhit_words_per_cycle = 0",
                "texture_cache.hit_words_per_cycle",
            ),
        ] {
            let text = format!("name = \"x\"\nbase = \"gold8\"\n[texture_cache]\n{keys}");
            let e = MachineDesc::parse(&text, "x.toml").unwrap_err();
            assert!(e.to_string().contains(key), "{keys}: {e}");
        }
    }

    #[test]
    fn an_impossible_rasterizer_is_refused_naming_its_key() {
        let good = MachineDesc::resolve("gold8+hwrast").unwrap();
        let r = good
            .rasterizer
            .as_ref()
            .expect("gold8+hwrast has a rasterizer");
        assert_eq!((r.latency, r.output_words_per_cycle), (100, 1));
        assert!(MachineDesc::gold8().rasterizer.is_none());
        for (change, key) in [
            ("latency = 0", "rasterizer.latency"),
            (
                "output_words_per_cycle = 0",
                "rasterizer.output_words_per_cycle",
            ),
            (
                "input_words_per_cycle = 100",
                "rasterizer.input_words_per_cycle",
            ),
            ("triangles_in_flight = 0", "rasterizer.triangles_in_flight"),
            ("pixels_per_cycle = 0", "rasterizer.pixels_per_cycle"),
            ("lattency = 100", "lattency"),
        ] {
            let text = format!("name = \"x\"\nbase = \"gold8+hwrast\"\n[rasterizer]\n{change}");
            let e = MachineDesc::parse(&text, "x.toml").unwrap_err();
            assert!(e.to_string().contains(key), "{change}: {e}");
        }
        let text = "name = \"x\"\nbase = \"gold8+hwrast\"\n[srf]\nstream_buffers = 14";
        let e = MachineDesc::parse(text, "x.toml").unwrap_err();
        assert!(e.to_string().contains("`rasterizer`"), "{e}");
    }
}
