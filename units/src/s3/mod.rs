//! The S3 superscalar out-of-order rasterizer: Wolfe & Noonburg, "A Superscalar 3D
//! Graphics Engine" (spec `s3-ellsworth-piko.md` §1; source text seed 001), as clocked
//! blocks.
//!
//! The primitive stream is treated as an instruction stream whose operands are screen
//! regions. Triangles are issued out of order to K rasterizing accelerators while the
//! dependence checks keep the frame exactly as in-order drawing makes it:
//!
//! ```text
//!  host ──fifo commands──▶ Fetch ──fifo decoded──▶ Issue ──pipe dispatch k──▶ Accel k ──┐
//!  (trace memory)         (bbox, split)           (RS, candidates,            (setup,   │
//!                                                  dependence vectors)         spans,    │
//!                                                   ▲                          pixels)   │
//!                                                   └──────── pipe retire k ◀───────────┤
//!                                               FbMem ◀── pipe mem_req k / mem_rsp k ──▶┘
//!                                    (or FbDram ◀── … and pipe mem_ack k ──▶ DRAM channels)
//! ```
//!
//! * [`fetch`] — the command queue's reader: decodes a triangle into fixed point,
//!   computes its bounding box (its destination region) and, with splitting on, cuts a
//!   triangle taller than the split height into slices with their own boxes (§4.5);
//! * [`issue`] — destination and source reservation stations, candidate buffers, the
//!   dependence matrix (RAW, WAW and WAR on regions; vectors one bit per destination RS),
//!   the conflict vectors of dependence-chain breaking (§4.6), one insert, one issue and
//!   any number of retirements (tag broadcasts) per cycle;
//! * [`accel`] — one rasterizing accelerator: setup, the span generator, and the pixel
//!   pipeline (Z read → Z compare → Z write, destination read → blend → destination
//!   write), one pixel per clock at peak;
//! * [`fbmem`] — the ideal multi-ported frame-buffer memory of the paper's simulator
//!   (four 32-bit-class accesses per accelerator per clock, fixed latency);
//! * [`fbdram`] — the other memory mode: the same ports arbitrated onto the machine's
//!   DRAM channels ([`crate::dram`]) through the main machine's clock crossings;
//! * [`raster`] — the accelerators' arithmetic as pure functions, and the in-order golden
//!   frame;
//! * [`run`] — the design, the trace driver and the statistics (triangle-level
//!   parallelism, stalls by cause);
//! * [`game`] — generated game-like traces (the paper's traces are not available).
//!
//! Parameters come from the machine description's `[s3]` table ([`crate::desc::S3`]).

pub mod accel;
pub mod fbdram;
pub mod fbmem;
pub mod fetch;
pub mod game;
pub mod issue;
pub mod raster;
pub mod run;

use crate::desc::MachineDesc;
use raster::{FixedTriangle, Mode, Region};

/// The S3 parameters of one run: the machine's `[s3]` table with the driver's switches.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct S3Config {
    pub accelerators: usize,
    pub window_per_accelerator: usize,
    pub source_slots: usize,
    pub split: bool,
    pub split_height: u16,
    pub chain_break: bool,
    pub select: Select,
    pub select_seed: u32,
    pub queue_entries: usize,
    pub setup_cycles: u32,
    pub memory: S3Memory,
    pub memory_latency: u32,
}

/// The frame-buffer memory behind the accelerators' ports (`s3.memory`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum S3Memory {
    /// The paper's ideal multi-ported memory ([`fbmem`]).
    Ideal,
    /// The DRAM channels, scheduler, crossings and clocks of this machine ([`fbdram`]).
    Dram(Box<MachineDesc>),
}

impl S3Memory {
    pub fn name(&self) -> &'static str {
        match self {
            S3Memory::Ideal => "ideal",
            S3Memory::Dram(_) => "dram",
        }
    }
}

/// Which of several ready candidates issues.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Select {
    /// "One is selected at random" (l.175): a 32-bit Galois LFSR picks among them.
    Random,
    /// The earliest inserted (l.128).
    Oldest,
}

impl S3Config {
    /// The configuration of a (validated) machine description's `[s3]` table (and, for
    /// `memory = "dram"`, its `[dram]`, `[memory]` and `[clocks]`).
    pub fn of(m: &MachineDesc) -> S3Config {
        let s = &m.s3;
        S3Config {
            accelerators: s.accelerators,
            window_per_accelerator: s.window_per_accelerator,
            source_slots: s.source_slots,
            split: s.split,
            split_height: s.split_height as u16,
            chain_break: s.chain_break,
            select: if s.select == "oldest" {
                Select::Oldest
            } else {
                Select::Random
            },
            select_seed: s.select_seed,
            queue_entries: s.queue_entries,
            setup_cycles: s.setup_cycles,
            memory: if s.memory == "dram" {
                S3Memory::Dram(Box::new(m.clone()))
            } else {
                S3Memory::Ideal
            },
            memory_latency: s.memory_latency,
        }
    }

    /// Candidate buffers: the issue window.
    pub fn candidates(&self) -> usize {
        self.window_per_accelerator * self.accelerators
    }

    /// Destination reservation stations: candidates + K (the paper's sizing rule, l.169).
    pub fn dest_rs(&self) -> usize {
        self.candidates() + self.accelerators
    }

    /// Bits of state in the issue unit, as modelled: per destination RS a box (4 × 12
    /// bits), valid, issued and independent bits; per source-RS entry a box, the owner's
    /// tag and valid; per candidate buffer the dependence and conflict vectors, tag,
    /// valid, independent, its box (for the conflict broadcast) and a 32-bit age (the
    /// primitive's own data is held beside it, a pointer in the paper). For comparison
    /// with "well under 100k gates, including storage" for 8 accelerators and 32
    /// candidates (l.184).
    pub fn issue_storage_bits(&self) -> usize {
        let (rs, cand) = (self.dest_rs(), self.candidates());
        let tag = imagine_hdl::bits_for(rs as u64 - 1) as usize;
        let bbox = 48;
        rs * (bbox + 3)
            + self.source_slots * rs * (bbox + tag + 1)
            + cand * (2 * rs + tag + 3 + bbox + 32)
    }
}

/// A decoded primitive (a triangle or one slice of it) with its operand regions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Prim {
    /// The triangle's 24-bit order tag: its position in the trace, from 1.
    pub order: u32,
    /// Which slice of its triangle (0 when not split).
    pub slice: u16,
    pub tri: FixedTriangle,
    /// The destination region: the pixels it may write.
    pub dest: Region,
    /// Source regions: the pixels it reads (a blended triangle reads its destination).
    pub sources: [Option<Region>; 2],
}

impl Prim {
    /// Opaque Z-buffered triangles are *independent* for chain breaking: the depth test
    /// (with its order tag) orders them, provided overlapping ones never run at once.
    pub fn independent(&self) -> bool {
        self.tri.mode == Mode::Opaque
    }

    /// The paper's `depend(P, D)` for this primitive P and an earlier one D: RAW
    /// (P's sources against D's destination), WAW, and WAR (P's destination against D's
    /// sources). Symmetric, as the three tests together are.
    pub fn hazard(&self, d: &Prim) -> bool {
        hazard(&self.dest, &self.sources, &d.dest, &d.sources)
    }
}

/// [`Prim::hazard`] on bare regions.
pub fn hazard(
    pd: &Region,
    ps: &[Option<Region>; 2],
    dd: &Region,
    ds: &[Option<Region>; 2],
) -> bool {
    let raw = ps.iter().flatten().any(|s| s.overlaps(dd));
    let war = ds.iter().flatten().any(|s| pd.overlaps(s));
    raw || pd.overlaps(dd) || war
}

/// A primitive handed to an accelerator with its tag (its destination RS).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Job {
    pub tag: u16,
    pub prim: Prim,
}

/// An accelerator's completion: the tag it broadcasts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Retire {
    pub accel: u8,
    pub tag: u16,
}

/// A frame-buffer access (word address = y · width + x).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemReq {
    ReadDepth(u32),
    ReadColour(u32),
    WriteDepth(u32, u64),
    WriteColour(u32, u32),
}

/// Read data, in request order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemRsp {
    Depth(u64),
    Colour(u32),
}
