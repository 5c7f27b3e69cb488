//! The OpenGL-like pipeline as a stream program (ARCHITECTURE §5, §7, §8), built for each
//! scene and run on the clocked processor through the stream-program layer
//! ([`crate::stream`]).
//!
//! **Phases.** The host loads the scene's inputs into DRAM over the host interface (vertex
//! records, corner indices, each object's OpenGL state), then the machine clears the
//! framebuffer (`clear`, and stores), renders the frame, and the host reads the colour
//! buffer back. Each phase is timed apart; the frame's cycles are the render's alone, as
//! the thesis counts them (§5.1: inputs start in memory, the image ends there).
//!
//! **Per batch** of `B` triangles of one object (`B` a multiple of the cluster count,
//! sized by strip-mining to the SRF and to `xyrast`'s scratchpad): the object's vertices
//! the batch uses are loaded and shaded once each (`perbegin` first when the object
//! changes); for a mesh with shared vertices the shaded vertices go to DRAM and come back
//! gathered by the batch's corner indices, three per triangle in drawing order (for a
//! mesh of separate triangles they are already in that order). Then `assemble_clip`,
//! `viewport_cull` and `baryprep`, whose interpolation records are stored for the
//! fragments' gathers; then, per scissor tile (the window, split while a tile's fragments
//! would overflow their SRF streams), `xyprep` and `xyrast`; the fragments go through in
//! chunks: their interpolation records are gathered by triangle, `irast` interpolates, and
//! the composite runs in rounds — the pixels are gathered while `hash` marks fragments
//! that share a pixel with an earlier one, `zcompare` applies the depth test to the
//! others, the pixels that passed are scattered, and the held-back fragments are recycled
//! (`compact_recycle`), or sorted and merged (`sort32`, `mergefrag`) when many are, until
//! none is left. A blending frame keeps each pixel's fragments in drawing order through all
//! of this: `xyrast` walks the boxes in primitive order, `zcompare` blends, and the merge
//! stage stays off (see [`kernels::xyrast`]).
//!
//! **Geometry only** ([`render_geometry`]): each batch stops after `viewport_cull`, its
//! triangles' records are stored to DRAM, and the host reads them back as window-space
//! triangles for another rasterizer (the S3 engine's, `imagine s3 --scene`).
//!
//! **Two batches in flight.** The next batch's vertices are loaded while this one is set
//! up, and its vertex program is deferred to where the host first waits for the machine
//! in this batch (the host's read-back of `xyprep`'s counts), so the clusters shade while
//! the host would otherwise leave them idle. Within a batch the next chunk's records are
//! gathered while this one is composited (two SRF buffers).
//!
//! **Specialisation.** Only what the scene needs is built: a vertex program per material
//! (unlit with or without per-vertex colours; lit for the scene's light count, with the
//! specular term only when there is one, and its exponent unrolled; beyond the lights one
//! kernel holds, light passes after it, deferred with it, that hand partial records on in
//! the SRF), `viewport_cull` for the scene's cull mode, `zcompare` for its depth test;
//! `sort32` and `mergefrag` are compiled only if a round needs them (and never for depth
//! tests other than LESS, whose minimum they implement); fragment programs only when an
//! object is textured, marble or `bump_env` (then every object has one: see
//! [`super::fragment_program`]; a frame with a marble over Perlin's noise loads his
//! permutation table into the SRF once, before its first batch, and a marble frame writes
//! the marble parameters at each batch of a marble object). A `bump_env` object's vertex
//! program is split at its vertex texture: `vtexaddr` runs as soon as the batch's vertices
//! are loaded, its texels are gathered over its addresses, and the rest of the program is
//! deferred as any vertex program; its fragment program is a dependent read, `bumpaddr`, a
//! gather, `envaddr`, a gather and `fragment` ([`crate::kernels::bump_env`]).
//! `--no-specialize` builds the
//! general pipeline instead: every vertex carries position, normal or colour, specular
//! lighting always, and every kernel compiled up front.

use std::ops::Range;
use std::time::Instant;

use imagine_hdl::Sim;
use imagine_units::desc::MachineDesc;
use imagine_units::dram::trace::TraceRequest;
use imagine_units::dram::{DramChannel, ReplayReport};
use imagine_units::hwrast::{RasterJob, RasterState};
use imagine_units::machine::{KernelStats, StreamBinding};
use imagine_units::ops::Datapath;
use imagine_units::processor;
use imagine_units::stream_controller::StreamInstr;

use super::fragment_program::{self, TextureMemory};
use super::kernels::{
    self, CLIPPED_WORDS, FrameShape, NULL_DEPTH, PIXEL_WORDS, RASTER_WORDS, Varyings, WINDOW_WORDS,
};
use super::mergefrag::{self, GROUP};
use super::scanline::{self, EDGE_WORDS, HALF_WORDS, SENTINEL_ROWS, SPAN_WORDS};
use super::srf_model::SrfModelReport;
use super::stats::{BatchRow, Phases, Specialisation, TextureCacheReport};
use super::vertex_program::{self, VertexProgram};
use crate::compile::CompileCache;
use crate::kernel::MachineRequirementError;
use crate::kernels::bump_env;
use crate::kernels::texture::{self, FragmentProgram};
use crate::kernels::turbulence;
use crate::scene::model::{Blend, DepthTest, Object, PipelineKind, Scene, Shader, TriangleId};
use crate::scene::{MAX_TRI_COORDINATE, MAX_WINDOW, bump_map};
use crate::stream::attribution::{self, Attribution, DramActivity, WaitingOn};
use crate::stream::timeline::{self, ProgramInfo, TimelineInput};
use crate::stream::{
    Buffer, Call, DramMap, Fit, HostError, KernelId, KernelLibrary, Layout, Lifetime, PARAMS,
    PlanError, SrfPlan, SrfPlanner, StreamHost, StreamId, live, pipelined, split_to_fit,
    strip_mine,
};

pub use super::stats::{FrameStats, KernelShare};

use imagine_units::limits::MAX_RUN_CYCLES;

/// Fragments per composite chunk (before rounding to whole blocks and rows). Its buffers
/// bound how many fragments go round together; 96 was the fastest on SPHERE (gold8) of the
/// sizes 64 to 256 tried.
const CHUNK: usize = 96;

/// Triangles per batch unless the scene or the options say otherwise: on gold8 the fastest
/// for SPHERE, MARBLE and ADVS-8 of 64, 128 and 152 (larger batches need more scissor
/// tiles split to fit their fragments). ADVS-1, PIN, PIN-8 and VERONA run faster at 112,
/// 128, 80 and 32, which their scene files ask for (`pipeline.batch`): the thesis, too,
/// sized each scene's batch by profiling (Table 5.1).
pub const DEFAULT_BATCH: usize = 64;

/// Words of `xyrast`'s tickets stream: its iteration count is the busiest cluster's runs,
/// so this bounds a pass at `TICKET_WORDS / C` runs per cluster (a tile splits beyond).
/// A run tests 4 candidate pixels, so 2048 words (256 runs per cluster on gold8) bind only
/// when a cluster's boxes hold about as many candidates as the fragment streams do.
const TICKET_WORDS: usize = 2048;
/// Iterations of a pass of `xyrast` in primitive order, where the clusters walk every box
/// together (one iteration at least per triangle of the batch): the stream takes this
/// many rows, as many as [`TICKET_WORDS`] gives gold8 in the other order.
const ORDERED_TICKET_ROWS: usize = 256;

/// Words of the staging buffer the host interface fills for loads and read-backs.
const STAGING_WORDS: usize = 8192;

/// Pixels the clear kernel writes per call; its records are stored over the framebuffer
/// again and again.
const CLEAR_PIXELS: usize = 1024;

/// A rendered frame.
#[derive(Clone, Debug)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    /// Packed RGBA8 (red in the low byte), row 0 at the bottom.
    pub pixels: Vec<u32>,
    pub stats: FrameStats,
    /// For every pixel (row 0 at the bottom), the triangle it shows, `None` where no
    /// fragment was drawn: the framebuffer's primitive words, read after the frame.
    pub triangles: Vec<Option<TriangleId>>,
    /// For every pixel (row 0 at the bottom), the depth word of its framebuffer record
    /// (fp32 bits; 1.0 where nothing was drawn), read with [`Frame::triangles`]: what the
    /// stress suite checks for NaN and infinities, which the RGBA8 colour cannot show.
    pub depths: Vec<u32>,
    /// The frame as a timeline in the Trace Event format (see [`timeline`]), when
    /// [`RenderOptions::timeline`] asks for it.
    pub timeline: Option<serde_json::Value>,
    /// The DRAM requests of the frame (the clear and read-back apart) as the channels
    /// received them, when [`RenderOptions::record_dram`] asks for them.
    pub dram_requests: Vec<TraceRequest>,
}

/// A frame that could not be rendered.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RenderError(pub String);

impl std::fmt::Display for RenderError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for RenderError {}

impl From<HostError> for RenderError {
    fn from(e: HostError) -> Self {
        RenderError(e.0)
    }
}

impl From<PlanError> for RenderError {
    fn from(e: PlanError) -> Self {
        RenderError(e.0)
    }
}

/// How the host runs the pipeline (choices that change the cycles, never the image).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RenderOptions {
    /// Sort and merge a round's conflicting fragments (`sort32`, `mergefrag`) when `hash`
    /// holds back at least this many; else, or when `None`, recycle them as they are.
    pub merge_min_conflicts: Option<usize>,
    /// Build the pipeline for the scene (`false`: the general pipeline, for comparison).
    pub specialise: bool,
    /// Where compiled kernels are kept between renders (disabled by default: the CLI
    /// passes [`CompileCache::from_env`] unless `--no-cache`).
    pub cache: CompileCache,
    /// The host gives up on a frame that takes longer, in core cycles.
    pub max_cycles: u64,
    /// Step the simulation through idle time instead of jumping over it (the same frame
    /// and statistics either way; tests compare the two).
    pub step_idle: bool,
    /// Evaluate and commit the design's blocks in the reverse of their order (the same
    /// frame, cycle for cycle, by the two-phase contract; tests prove it).
    pub reverse_eval_order: bool,
    /// The most triangles per batch, instead of the scene's `pipeline.batch` or
    /// [`DEFAULT_BATCH`].
    pub batch: Option<usize>,
    /// Build the frame's timeline ([`Frame::timeline`]).
    pub timeline: bool,
    /// Keep the frame's DRAM requests ([`Frame::dram_requests`], `--dram-trace`).
    pub record_dram: bool,
    /// The rasterizer kernels: barycentric (`xyprep`, `xyrast`) or scanline.
    pub rasterizer: Rasterizer,
    /// What computes the clusters' fp32 ops without a tracer (the same frame either way).
    pub datapath: Datapath,
}

/// The rasterizer kernels a frame runs (machines with a hardware rasterizer use it
/// instead).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Rasterizer {
    /// `xyprep` and `xyrast`: each cluster walks its triangles' bounding boxes.
    #[default]
    Barycentric,
    /// `spanprep`, `spangen`, `spanpack` and `spanrast` ([`super::scanline`]): half-triangles
    /// and spans, load-balanced over the clusters.
    Scanline,
}

impl Rasterizer {
    pub const ALL: [Rasterizer; 2] = [Rasterizer::Barycentric, Rasterizer::Scanline];

    pub fn name(self) -> &'static str {
        match self {
            Rasterizer::Barycentric => "barycentric",
            Rasterizer::Scanline => "scanline",
        }
    }
}

impl std::str::FromStr for Rasterizer {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        Rasterizer::ALL
            .into_iter()
            .find(|r| r.name() == text)
            .ok_or_else(|| format!("`{text}` is not a rasterizer (barycentric or scanline)"))
    }
}

impl std::fmt::Display for Rasterizer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Conflicts from which the host sorts and merges. The stage costs more cycles than the
/// recycling it replaces (on gold8, chunks of 96 fragments of a stacked scene: `sort32`
/// about 600 cycles a call and `mergefrag` 540, against 300 each, the least a kernel
/// holds the clusters, for `compact_recycle`), and saves rounds only when fragments of one
/// pixel share a group; few conflicts are more often stamp aliases (different pixels, the
/// same stamp key) than a pixel's stack.
pub const MERGE_MIN_CONFLICTS: usize = 24;

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            merge_min_conflicts: Some(MERGE_MIN_CONFLICTS),
            specialise: true,
            cache: CompileCache::disabled(),
            max_cycles: MAX_RUN_CYCLES,
            step_idle: false,
            datapath: Datapath::Host,
            reverse_eval_order: false,
            batch: None,
            timeline: false,
            record_dram: false,
            rasterizer: Rasterizer::Barycentric,
        }
    }
}

/// The pipeline's batch schedule: the phases stream lifetimes are given in.
const PHASES: [&str; 7] = [
    "vertex",
    "assemble",
    "cull",
    "baryprep",
    "xyprep",
    "xyrast",
    "composite",
];

/// The streams of a batch.
struct Streams {
    state: StreamId,
    vertex_params: StreamId,
    /// `perlight`'s parameters and input (lit programs).
    perlight_params: StreamId,
    lights: StreamId,
    xyprep_params: StreamId,
    baryprep_params: StreamId,
    vertices: StreamId,
    corner_index: [StreamId; 2],
    /// A vertex texture's addresses, the texels gathered over them (`bump_env`).
    vertex_texels: Option<StreamId>,
    shaded: [StreamId; 2],
    /// The records a lit program's kernels hand on to its next light pass: none, or one
    /// buffer, or two that alternate between passes.
    partial: Vec<StreamId>,
    corners: StreamId,
    clipped: StreamId,
    attribs: StreamId,
    det: StreamId,
    window: StreamId,
    interp: StreamId,
    raster: StreamId,
    rows: StreamId,
    tickets: StreamId,
    /// The fragments' addresses: `xyrast`'s or the hardware rasterizer's.
    addr: StreamId,
    /// `xyrast`'s other outputs, on machines without a hardware rasterizer.
    kernel_fragments: Option<KernelFragments>,
    /// The hardware rasterizer's other outputs, on machines with one.
    unit: Option<UnitFragments>,
    gathered: [StreamId; 2],
    /// irast's outputs (`zcap[0]`) and the composite's streams.
    composite: CompositeStreams,
    /// The fragment program's streams (frames with textures or marble).
    texturing: Option<TexturingStreams>,
    /// The scanline rasterizer's streams, when it runs.
    scanline: Option<ScanlineStreams>,
}

/// The scanline rasterizer's streams ([`super::scanline`]): per tile, `spanprep`'s
/// half-triangles, edge records (stored to DRAM at a batch's first tile) and counts;
/// `spangen`'s spans as three conditional streams; `spanpack`'s span records and counts;
/// the spans' edge records gathered by triangle.
struct ScanlineStreams {
    halves: StreamId,
    edges: StreamId,
    prep_counts: StreamId,
    pos: StreamId,
    end: StreamId,
    tri: StreamId,
    spans: StreamId,
    pack_counts: StreamId,
    span_edges: StreamId,
}

/// The SRF's share the scanline rasterizer's span streams take at most (1/4: a span is 16
/// words, a fragment 5), halved while the fragments would get room for fewer than twice
/// as many records (frames whose other streams are large, such as PIN's textures).
const SPAN_SHARE: usize = 4;

/// The composite's streams: the fragments of a chunk's rounds (the first set, or the
/// rasterizer's outputs, then two recycle sets that alternate: z, colour, addr, prim), the
/// merge's sorted streams, the pixels gathered and scattered by address, and `hash`'s
/// flags and count. The Reyes pipeline composites through them too.
pub(crate) struct CompositeStreams {
    pub zcap: [[StreamId; 4]; 3],
    pub sorted: [StreamId; 3],
    pub pixel: StreamId,
    pub new_pixel: StreamId,
    pub newaddr: StreamId,
    pub conflict: StreamId,
    pub conflicts: StreamId,
    /// Fragments per chunk (see [`composite_chunk`]).
    pub chunk: usize,
}

/// Fragments per composite chunk on `desc`: [`CHUNK`] in whole rows of clusters and whole
/// SRF blocks, so that a chunk's slices of the fragment streams start on block boundaries.
pub(crate) fn composite_chunk(desc: &MachineDesc) -> usize {
    let c = desc.cluster.count;
    let gcd = |mut a: usize, mut b: usize| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    let block = desc.srf.block_words.max(1);
    let unit = c / gcd(c, block) * block;
    CHUNK.div_ceil(unit) * unit
}

/// Declares the composite's streams for chunks of `chunk` fragments, live in phase
/// `composite` (the framebuffer's pixels for the whole program: a last scatter may still
/// run when the next work is set up).
pub(crate) fn plan_composite(
    p: &mut SrfPlanner,
    desc: &MachineDesc,
    chunk: usize,
) -> CompositeStreams {
    let c = desc.cluster.count;
    let words = Layout::words();
    let groups = chunk.next_multiple_of(GROUP);
    CompositeStreams {
        zcap: [0, 1, 2].map(|set| {
            ["z", "colour", "addr", "prim"].map(|n| {
                p.stream(
                    &format!("{n}[{set}]"),
                    words,
                    groups + c,
                    live("composite", "composite"),
                )
            })
        }),
        sorted: ["key", "z_sorted", "prim_sorted"]
            .map(|n| p.stream(n, words, groups, live("composite", "composite"))),
        // The framebuffer's gathers and scatters: a batch's last scatter is still running
        // when the next batch is set up, so these words are not shared with anything.
        pixel: p.stream(
            "pixel",
            Layout::records(PIXEL_WORDS),
            chunk,
            Lifetime::Always,
        ),
        new_pixel: p.stream(
            "new_pixel",
            Layout::records(PIXEL_WORDS),
            chunk,
            Lifetime::Always,
        ),
        newaddr: p.stream("newaddr", words, chunk, Lifetime::Always),
        // `hash`'s flags and the rows of zeros after them.
        conflict: p.stream(
            "conflict",
            words,
            chunk + GROUP,
            live("composite", "composite"),
        ),
        conflicts: p.stream("conflicts", words, c, live("composite", "composite")),
        chunk,
    }
}

/// `xyrast`'s fragments beside their addresses: the triangle index and the edge values.
struct KernelFragments {
    tri: StreamId,
    edges: [StreamId; 3],
}

/// The hardware rasterizer's fragments beside their addresses (a whole tile's): depth,
/// primitive, and the packed colour or the fragment program's varyings.
struct UnitFragments {
    z: StreamId,
    prim: StreamId,
    values: StreamId,
}

/// A chunk's streams between `irast` and the composite in a frame with fragment programs:
/// the interpolated values, then the fragment program's address, weight and texel streams
/// (texels are gathered over their addresses), and the marble program's table and
/// parameters.
struct TexturingStreams {
    varyings: StreamId,
    addr: Option<StreamId>,
    weights: Option<StreamId>,
    addr8: Option<StreamId>,
    weights5: Option<StreamId>,
    filtered: Option<StreamId>,
    /// Dependent reads' addresses, their texels gathered over them (`bump_env`'s
    /// environment texel).
    dependent: Option<StreamId>,
    marble: Option<MarbleStreams>,
}

/// The marble program's permutation table (Perlin's noise only; loaded once per frame)
/// and parameters (written per batch of a marble object).
struct MarbleStreams {
    perm: Option<StreamId>,
    params: StreamId,
}

/// Words of the largest state and parameter lists of the scene's vertex programs.
struct Sizes {
    batch: usize,
    state_words: usize,
    params: usize,
    vertex_words: usize,
    /// `perlight`'s input: 12 words per light, in every cluster.
    light_words: usize,
    /// Words of the largest record lit programs hand on between light passes, and the
    /// most passes a program has after its first kernel.
    partial_words: usize,
    passes: usize,
    varyings: Varyings,
    /// The most texel fetches outside mipmapped units, bilinear weights and mipmapped
    /// units of any fragment program.
    direct_fetches: usize,
    direct_weights: usize,
    mipmapped: usize,
    /// Whether an object is marble (its parameters in the SRF), and whether one is over
    /// Perlin's noise (his permutation table in the SRF).
    marble: bool,
    perlin_table: bool,
    /// Whether `xyrast` walks the boxes in primitive order (blending).
    ordered: bool,
    /// The most dependent texel fetches of any fragment program.
    dependent_fetches: usize,
    /// Texel words per vertex of the vertex textures (`bump_env`), 0 without.
    vertex_texels: usize,
    /// Whether the scanline rasterizer runs (else `xyprep` and `xyrast`, or the hardware).
    scanline: bool,
}

/// Words of `perlight`'s parameters (see [`VertexProgram::perlight_params`]).
const PERLIGHT_PARAMS: usize = 24;

fn plan_streams(desc: &MachineDesc, s: &Sizes) -> Result<(SrfPlan, Streams), PlanError> {
    let c = desc.cluster.count;
    // A one-pixel tile's spans (a row of every half-triangle), then the sentinels.
    let fewest = (2 * s.batch + (SENTINEL_ROWS + 1) * c).div_ceil(c) * c;
    let mut spans = (desc.srf.words / SPAN_SHARE / (SPAN_WORDS + EDGE_WORDS + 3)).max(fewest);
    loop {
        let planned = plan_streams_with(desc, s, spans);
        let halve = match &planned {
            Ok((plan, streams)) => s.scanline && plan.capacity(streams.addr) < 2 * spans,
            Err(_) => s.scanline,
        };
        if !halve || spans == fewest {
            return planned;
        }
        spans = (spans / 2).div_ceil(c).max(1) * c;
        spans = spans.max(fewest);
    }
}

/// The streams of a batch, with room for `spans` spans when the scanline rasterizer runs.
fn plan_streams_with(
    desc: &MachineDesc,
    s: &Sizes,
    spans: usize,
) -> Result<(SrfPlan, Streams), PlanError> {
    let c = desc.cluster.count;
    let b = s.batch;
    let mut p = SrfPlanner::new(desc, &PHASES);
    let always = Lifetime::Always;
    // With a hardware rasterizer it writes a tile's fragments whole, and the composite
    // takes them in chunks; the rasterizer kernels' streams are left empty, so that the
    // fragments have their room.
    let hardware = desc.rasterizer.is_some();
    let kernels_only = |records: usize| if hardware { 0 } else { records };
    let barycentric_only = |records: usize| if s.scanline { 0 } else { kernels_only(records) };
    let words = Layout::words();
    let chunk = composite_chunk(desc);
    let streams = Streams {
        state: p.stream("state", Layout::packed(1), s.state_words, always),
        vertex_params: p.stream("vertex_params", words, s.params * c, always),
        perlight_params: p.stream("perlight_params", words, PERLIGHT_PARAMS * c, always),
        lights: p.stream("lights", words, s.light_words.max(c), always),
        xyprep_params: p.stream("xyprep_params", words, 4 * c, always),
        baryprep_params: p.stream("baryprep_params", words, c, always),
        vertices: p.stream("vertices", Layout::records(s.vertex_words), 3 * b, always),
        corner_index: p.buffers("corner_index", words, 3 * b, always),
        vertex_texels: (s.vertex_texels > 0).then(|| {
            p.stream(
                "vertex_texels",
                Layout::records(s.vertex_texels),
                3 * b,
                always,
            )
        }),
        shaded: p.buffers(
            "shaded",
            Layout::records(s.varyings.shaded_words()),
            3 * b,
            always,
        ),
        // Written and read by the deferred vertex work of one batch, which runs in order.
        partial: (0..s.passes.min(2))
            .map(|i| {
                let name = format!("partial[{i}]");
                p.stream(&name, Layout::records(s.partial_words), 3 * b, always)
            })
            .collect(),
        corners: p.stream(
            "corners",
            Layout::records(s.varyings.shaded_words()),
            3 * b,
            live("assemble", "assemble"),
        ),
        clipped: p.stream(
            "clipped",
            Layout::records(CLIPPED_WORDS),
            b,
            live("assemble", "cull"),
        ),
        // The hardware rasterizer reads them at every tile, between composites.
        attribs: p.stream(
            "attribs",
            Layout::records(s.varyings.attrib_words()),
            b,
            live("assemble", if hardware { "composite" } else { "baryprep" }),
        ),
        det: p.stream(
            "det",
            words,
            b,
            live("cull", if hardware { "composite" } else { "baryprep" }),
        ),
        // Read by every tile's `xyprep`.
        window: p.stream(
            "window",
            Layout::records(WINDOW_WORDS),
            b,
            live("cull", "composite"),
        ),
        // Stored to DRAM while the tiles start: live until that store has surely completed,
        // so that `xyprep` and `xyrast` do not wait for it.
        interp: p.stream(
            "interp",
            Layout::records(s.varyings.interp_words()),
            kernels_only(b),
            live("baryprep", "xyrast"),
        ),
        raster: p.stream(
            "raster",
            Layout::records(RASTER_WORDS),
            barycentric_only(b),
            live("xyprep", "xyrast"),
        ),
        rows: p.stream(
            "rows",
            words,
            barycentric_only(2 * c),
            live("xyprep", "xyprep"),
        ),
        // The scanline rasterizer's `spangen` runs over them too.
        tickets: p.stream(
            "tickets",
            words,
            kernels_only(if s.ordered {
                ORDERED_TICKET_ROWS * c
            } else {
                TICKET_WORDS / c * c
            }),
            live(if s.scanline { "xyprep" } else { "xyrast" }, "xyrast"),
        ),
        addr: p.elastic("addr", words, live("xyrast", "composite")),
        kernel_fragments: (!hardware).then(|| KernelFragments {
            tri: p.elastic("tri", words, live("xyrast", "composite")),
            edges: ["e0", "e1", "e2"].map(|n| p.elastic(n, words, live("xyrast", "composite"))),
        }),
        unit: hardware.then(|| {
            let values = if s.varyings.fragment_program() {
                s.varyings.fragment_words()
            } else {
                1
            };
            UnitFragments {
                z: p.elastic("z", words, live("xyrast", "composite")),
                prim: p.elastic("prim", words, live("xyrast", "composite")),
                values: p.elastic(
                    "values",
                    Layout::records(values),
                    live("xyrast", "composite"),
                ),
            }
        }),
        gathered: p.buffers(
            "gathered",
            Layout::records(s.varyings.interp_words()),
            kernels_only(chunk),
            live("composite", "composite"),
        ),
        composite: plan_composite(&mut p, desc, chunk),
        texturing: s.varyings.fragment_program().then(|| {
            let mut per_fragment = |name: &str, words: usize| {
                (words > 0).then(|| {
                    p.stream(
                        name,
                        Layout::records(words),
                        chunk,
                        live("composite", "composite"),
                    )
                })
            };
            TexturingStreams {
                varyings: per_fragment("varyings", s.varyings.fragment_words())
                    .expect("a fragment program's fragments carry their varyings"),
                addr: per_fragment("texel_addr", s.direct_fetches),
                weights: per_fragment("texel_weights", s.direct_weights),
                addr8: per_fragment("mipmap_addr", texture::FILTER8_TEXELS * s.mipmapped),
                weights5: per_fragment("mipmap_weights", texture::FILTER8_WEIGHTS * s.mipmapped),
                filtered: per_fragment("filtered", s.mipmapped),
                dependent: per_fragment("dependent_addr", s.dependent_fetches),
                marble: s.marble.then(|| MarbleStreams {
                    perm: s
                        .perlin_table
                        .then(|| p.stream("perm", words, turbulence::TABLE * c, always)),
                    params: p.stream(
                        "marble_params",
                        words,
                        turbulence::SCALAR_PARAMS * c,
                        always,
                    ),
                }),
            }
        }),
        scanline: s.scanline.then(|| {
            let per_tile = |p: &mut SrfPlanner, name: &str, words: usize, records: usize| {
                p.stream(
                    name,
                    Layout::records(words),
                    records,
                    live("xyprep", "xyprep"),
                )
            };
            ScanlineStreams {
                halves: per_tile(&mut p, "halves", HALF_WORDS, 2 * b + SENTINEL_ROWS * c),
                // Stored to DRAM at the first tile: live until the store has surely ended.
                edges: p.stream(
                    "edges",
                    Layout::records(EDGE_WORDS),
                    b + c,
                    live("xyprep", "xyrast"),
                ),
                prep_counts: per_tile(&mut p, "prep_counts", 1, 2 * c),
                pos: per_tile(&mut p, "pos", 1, spans),
                end: per_tile(&mut p, "end", 1, spans),
                tri: per_tile(&mut p, "span_tri", 1, spans),
                pack_counts: per_tile(&mut p, "pack_counts", 1, 2 * c),
                spans: p.stream(
                    "spans",
                    Layout::records(SPAN_WORDS),
                    spans,
                    live("xyprep", "xyrast"),
                ),
                span_edges: p.stream(
                    "span_edges",
                    Layout::records(EDGE_WORDS),
                    spans,
                    live("xyprep", "xyrast"),
                ),
            }
        }),
    };
    let plan = p.place()?;
    // Splitting a tile ends at one pixel, which may hold a fragment of every triangle of
    // the batch (and, walked in primitive order, needs an iteration for each): a batch
    // whose streams cannot take that is too large, not a frame to refuse.
    let fragments = plan.capacity(streams.addr);
    if fragments < (b + c).max(4 * c) {
        return Err(PlanError(format!(
            "machine `{}`: the SRF ({} words) leaves room for {fragments} fragments, fewer \
             than a one-pixel tile of a batch of {b} triangles may have ({})",
            desc.name,
            desc.srf.words,
            b + c
        )));
    }
    if !hardware && s.ordered && b > ORDERED_TICKET_ROWS {
        return Err(PlanError(format!(
            "a batch of {b} triangles walked in primitive order needs more than \
             {ORDERED_TICKET_ROWS} rasterizer iterations for a one-pixel tile"
        )));
    }
    Ok((plan, streams))
}

/// The streams of the host phases (load, clear, read-back), placed before the frame's.
pub(crate) struct PhaseStreams {
    pub staging: StreamId,
    clear_tickets: StreamId,
    clear_pixels: StreamId,
    clear_params: StreamId,
}

pub(crate) fn plan_phases(desc: &MachineDesc) -> Result<(SrfPlan, PhaseStreams), PlanError> {
    let c = desc.cluster.count;
    let mut p = SrfPlanner::new(desc, &["load", "clear", "readback"]);
    let pixels = CLEAR_PIXELS.div_ceil(c) * c;
    let staging_words = STAGING_WORDS.min(desc.srf.words / 4);
    let s = PhaseStreams {
        staging: p.stream(
            "staging",
            Layout::packed(1),
            staging_words,
            live("load", "readback"),
        ),
        clear_tickets: p.stream(
            "clear_tickets",
            Layout::words(),
            pixels,
            live("clear", "clear"),
        ),
        clear_pixels: p.stream(
            "clear_pixels",
            Layout::records(PIXEL_WORDS),
            pixels,
            live("clear", "clear"),
        ),
        clear_params: p.stream(
            "clear_params",
            Layout::words(),
            2 * c,
            live("clear", "clear"),
        ),
    };
    Ok((p.place()?, s))
}

impl Kernels {
    fn composite(&self) -> CompositeKernels {
        CompositeKernels {
            hash: self.hash,
            zcompare: self.zcompare,
            recycle_zc: self.recycle_zc,
            recycle_ap: self.recycle_ap,
            merge: self.merge,
        }
    }
}

/// The rasterizer kernels of a frame.
enum RasterKernels {
    Barycentric { xyprep: KernelId, xyrast: KernelId },
    Scanline(ScanlineKernels),
}

/// The scanline rasterizer's kernels ([`scanline`]).
#[derive(Clone, Copy)]
struct ScanlineKernels {
    spanprep: KernelId,
    spangen: KernelId,
    spanpack: KernelId,
    spanrast: KernelId,
}

impl RasterKernels {
    fn all(&self) -> Vec<KernelId> {
        match *self {
            RasterKernels::Barycentric { xyprep, xyrast } => vec![xyprep, xyrast],
            RasterKernels::Scanline(k) => vec![k.spanprep, k.spangen, k.spanpack, k.spanrast],
        }
    }
}

/// The kernels a frame may call.
struct Kernels {
    /// Per object: its `perbegin`, `perlight` (lit programs), vertex program and light passes.
    per_object: Vec<ObjectKernels>,
    assemble_clip: KernelId,
    viewport_cull: KernelId,
    baryprep: KernelId,
    raster: RasterKernels,
    irast: KernelId,
    hash: KernelId,
    zcompare: KernelId,
    recycle_zc: KernelId,
    recycle_ap: KernelId,
    clear: KernelId,
    /// `sort32` and `mergefrag`, when the depth test allows merging.
    merge: Option<(KernelId, KernelId)>,
    /// Per object (frames with fragment programs): its program's kernels.
    fragment: Vec<FragmentKernels>,
    /// `filter8`, when a texture is mipmapped.
    filter8: Option<KernelId>,
}

fn register_kernels(
    lib: &mut KernelLibrary,
    desc: &MachineDesc,
    shape: FrameShape,
    pp: &PipelinePlan,
    options: &RenderOptions,
) -> Result<Kernels, MachineRequirementError> {
    let programs = &pp.programs;
    let varyings = pp.varyings;
    let mut per_program: Vec<(VertexProgram, ObjectKernels)> = Vec::new();
    let per_object: Vec<ObjectKernels> = programs
        .iter()
        .map(|vp| {
            if let Some((_, ids)) = per_program.iter().find(|(p, _)| p == vp) {
                return ids.clone();
            }
            let name = vp.name();
            let ids = ObjectKernels {
                perbegin: lib.register(&format!("perbegin:{name}"), vp.perbegin(desc)),
                vtexaddr: None,
                perlight: vp
                    .perlight(desc)
                    .map(|k| lib.register(&format!("perlight:{name}"), k)),
                vertex: lib.register(&name, vp.build(desc)),
                passes: vp
                    .pass_names()
                    .iter()
                    .zip(vp.passes(desc))
                    .map(|(n, k)| lib.register(n, k))
                    .collect(),
            };
            per_program.push((vp.clone(), ids.clone()));
            ids
        })
        .collect();
    // Built in pipeline order, so that a machine shape none of them can serve is named by
    // the first kernel a frame needs.
    let assemble_clip = lib.register(
        "assemble_clip",
        kernels::assemble_clip(desc, varyings, pp.normalise_clip)?,
    );
    let viewport_cull = lib.register("viewport_cull", kernels::viewport_cull(desc, shape)?);
    let baryprep = lib.register("baryprep", kernels::baryprep(desc, varyings)?);
    let raster = match pp.rasterizer {
        Rasterizer::Barycentric => RasterKernels::Barycentric {
            xyprep: lib.register("xyprep", kernels::xyprep(desc, shape)?),
            xyrast: lib.register("xyrast", kernels::xyrast(desc, shape)?),
        },
        Rasterizer::Scanline => RasterKernels::Scanline(ScanlineKernels {
            spanprep: lib.register("spanprep", scanline::spanprep(desc, shape)?),
            spangen: lib.register("spangen", scanline::spangen(desc, shape)?),
            spanpack: lib.register("spanpack", scanline::spanpack(desc)?),
            spanrast: lib.register("spanrast", scanline::spanrast(desc, shape)?),
        }),
    };
    let irast = lib.register("irast", kernels::irast(desc, varyings, pp.newton_steps)?);
    let mut per_object = per_object;
    // A vertex texture's address kernel per combined map.
    let mut vertex_textures: Vec<(bump_env::Maps, KernelId)> = Vec::new();
    for (ids, fp) in per_object.iter_mut().zip(&pp.fragment_programs) {
        if let Some(maps) = fp.as_ref().and_then(|f| f.bump_env) {
            let same = |(m, _): &&(bump_env::Maps, KernelId)| {
                m.vertex_kernel_name() == maps.vertex_kernel_name()
            };
            ids.vtexaddr = Some(match vertex_textures.iter().find(same) {
                Some(&(_, id)) => id,
                None => {
                    let k = bump_env::vertex_texel_address(&maps)?;
                    let id = lib.register(&maps.vertex_kernel_name(), k);
                    vertex_textures.push((maps, id));
                    id
                }
            });
        }
    }
    let mut fragment = Vec::new();
    let mut registered: Vec<(&FragmentProgram, FragmentKernels)> = Vec::new();
    for fp in pp.fragment_programs.iter().flatten() {
        let ids = match registered.iter().find(|(p, _)| *p == fp) {
            Some((_, ids)) => *ids,
            None if fp.bump_env.is_some() => {
                let (name, maps) = (fp.name(), fp.bump_env.expect("a bump_env program"));
                let words = varyings.fragment_words();
                let ids = FragmentKernels {
                    texaddr: Some(lib.register(
                        &format!("bumpaddr:{name}"),
                        bump_env::bump_address(&maps, words)?,
                    )),
                    dependent: Some(lib.register(
                        &format!("envaddr:{name}"),
                        bump_env::environment_address(&maps, words)?,
                    )),
                    colour: lib.register(&format!("fragment:{name}"), bump_env::shade(words)?),
                };
                registered.push((fp, ids));
                ids
            }
            None => {
                let name = fp.name();
                let texaddr = if fp.units.is_empty() {
                    None
                } else {
                    Some(lib.register(
                        &format!("texaddr:{name}"),
                        fp.texaddr(varyings.fragment_words(), varyings.derivatives_at())?,
                    ))
                };
                let kernel = if let Some(noise) = fp.marble {
                    turbulence::build_fragment(desc, varyings.fragment_words(), noise)?
                } else {
                    fp.fragment(varyings.fragment_words())?
                };
                let colour = lib.register(&format!("fragment:{name}"), kernel);
                let ids = FragmentKernels {
                    texaddr,
                    dependent: None,
                    colour,
                };
                registered.push((fp, ids));
                ids
            }
        };
        fragment.push(ids);
    }
    // Mipmapped textures are what the derivatives are for.
    let filter8 = if varyings.derivatives {
        Some(lib.register("filter8", texture::filter8(desc)?))
    } else {
        None
    };
    let hash = lib.register("hash", kernels::hash(desc, shape)?);
    let zcompare = lib.register("zcompare", kernels::zcompare(desc, shape)?);
    let recycle_zc = lib.register(
        "compact_recycle:z,colour",
        kernels::compact_recycle(desc, [NULL_DEPTH, 0])?,
    );
    let recycle_ap = lib.register(
        "compact_recycle:addr,prim",
        kernels::compact_recycle(desc, [shape.trash(), 0])?,
    );
    let clear = lib.register("clear", kernels::clear(desc)?);
    let merge = if merges(shape, options) {
        Some((
            lib.register("sort32", mergefrag::sort32(desc, shape)?),
            lib.register("mergefrag", mergefrag::mergefrag(desc, shape)?),
        ))
    } else {
        None
    };
    Ok(Kernels {
        per_object,
        assemble_clip,
        viewport_cull,
        baryprep,
        raster,
        irast,
        hash,
        zcompare,
        recycle_zc,
        recycle_ap,
        clear,
        merge,
        fragment,
        filter8,
    })
}

/// The kernels of the pipeline planned for `scene` on `desc` (see [`plan_pipeline`]),
/// built but not compiled, under the names a frame registers them by — the names of its
/// kernel breakdown and of [`Specialisation::kernels_built`] — in the order a frame
/// registers them. `imagine kernel list|show|check` show and check them.
pub fn pipeline_kernels(
    scene: &Scene,
    desc: &MachineDesc,
    options: &RenderOptions,
) -> Result<Vec<(String, crate::kernel::Kernel)>, RenderError> {
    let pp = plan_pipeline(scene, desc, options)?;
    let mut lib = KernelLibrary::new(desc, CompileCache::disabled());
    register_kernels(&mut lib, desc, pp.shape, &pp, options)
        .map_err(|e| RenderError(format!("cannot build the pipeline: {e}")))?;
    Ok(lib.into_kernels())
}

/// What a pipeline kernel registered as `name` (see [`pipeline_kernels`]) computes, per
/// element.
pub fn kernel_description(name: &str) -> String {
    let (stem, of) = name.split_once(':').unwrap_or((name, ""));
    let about = match stem {
        "perbegin" => "once per object: the vertex program's matrices from the OpenGL state",
        "perlight" => "once per object: the lights in eye space and their colour products",
        "clear" => "pixel: the clear colour and depth (the framebuffer's clear)",
        "assemble_clip" => "triangle: its three shaded vertices into one cluster, trivial reject",
        "viewport_cull" => "triangle: window corners, edge functions, facing and cull, box",
        "baryprep" => "triangle: the interpolation record",
        "xyprep" => "triangle, per scissor tile: the box clamped to the tile, xyrast's cost",
        "xyrast" => "run of 4 candidate pixels: coverage by the three edge functions",
        "spanprep" => "triangle, per scissor tile: two half-triangles, the edge record",
        "spangen" => "half-triangle (load-balanced): 2 spans a loop",
        "spanpack" => "span: its words side by side, spanrast's cost",
        "spanrast" => "span (load-balanced): 4 pixels a loop, coverage by the three edges",
        "irast" => "fragment: perspective-correct depth and colour (or varyings)",
        "hash" => "fragment: held back if an earlier fragment of the round shares its stamp",
        "zcompare" => "fragment: the depth test and the blend",
        "compact_recycle" => "fragment: keeps the held-back fragments for the next round",
        "sort32" => "group of 32 fragments: the held-back ones sorted by address",
        "mergefrag" => "sorted group: one fragment per address, the one zcompare would keep",
        "filter8" => "fragment: trilinear filter of 8 texels",
        "texaddr" => "fragment: the texel addresses of the fragment program's textures",
        "fragment" if of.starts_with("marble") => {
            "fragment: the marble shader (four octaves of Perlin noise, a colour ramp)"
        }
        "fragment" if of.starts_with("bump_env") => {
            "fragment: environment texel times the colour (bump_env, depth 0)"
        }
        "fragment" => "fragment: the fragment program's colour from its texels",
        "vtexaddr" => "vertex: the vertex texture's addresses (bump_env)",
        "bumpaddr" => "fragment: the bump-map normal's addresses (bump_env, depth 2)",
        "envaddr" => "fragment: bumped normal, reflection, sphere-map address (bump_env, depth 1)",
        _ if stem.starts_with("vertex_") && of.starts_with("pass") => {
            "vertex: the vertex program's next lights (a light pass)"
        }
        _ if stem.starts_with("vertex_") => "vertex: the vertex program (clip position, colour)",
        // The Reyes pipeline's own (it shares the composite and `perlight`).
        "project" => "patch (Reyes): its 16 control points to window space",
        "subdiv_split" => "patch (Reyes): its four children, a breadth-first level",
        "subdiv" => "iteration (Reyes): one quad of each cluster's depth-first walk",
        "shade" => {
            "quad (Reyes): its colour from the material, lit at its centre (marble: its \
             object-space centre and normal, for the marble kernel)"
        }
        "sample" => "quad (Reyes): the pixel centres of its box against its four edges",
        _ => "a kernel of the OpenGL pipeline",
    };
    about.to_string()
}

/// A fragment program's kernels: the texel addresses (`texaddr`, or `bump_env`'s depth-2
/// `bumpaddr`; none without textures), the dependent read's addresses (`bump_env`'s
/// `envaddr`) and the colour (`fragment`, `marble`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct FragmentKernels {
    texaddr: Option<KernelId>,
    dependent: Option<KernelId>,
    colour: KernelId,
}

impl FragmentKernels {
    fn all(&self) -> impl Iterator<Item = KernelId> {
        [self.texaddr, self.dependent, Some(self.colour)]
            .into_iter()
            .flatten()
    }
}

#[derive(Clone, Debug, PartialEq, Eq)]
struct ObjectKernels {
    perbegin: KernelId,
    /// The vertex texture's address kernel (`bump_env` objects: `vtexaddr`).
    vtexaddr: Option<KernelId>,
    perlight: Option<KernelId>,
    vertex: KernelId,
    /// The light passes after `vertex` (lit programs with more lights than it holds).
    passes: Vec<KernelId>,
}

/// One batch's work: triangles of one object.
#[derive(Clone, Debug)]
struct Batch {
    object: usize,
    /// Whether it is the object's first batch (its `perbegin` runs first).
    first_of_object: bool,
    /// The primitive number of its first triangle (numbers run over the whole scene).
    first_prim: usize,
    triangles: usize,
    /// Vertex records to load (a multiple of the cluster count), from record `vertex_at`.
    vertices: usize,
    vertex_at: u64,
    /// Corner indices at word `index_at` (shared meshes; 3 per triangle of the batch).
    index_at: Option<u64>,
}

/// The scene's inputs as the host lays them out in DRAM.
struct Inputs {
    batches: Vec<Batch>,
    vertex_words: Vec<u32>,
    index_words: Vec<u32>,
    /// Per object: its state words, and where they go.
    states: Vec<(Vec<u32>, u64)>,
    /// The lights, for `perlight`.
    light_words: Vec<u32>,
    shaded_vertices: u64,
}

/// Cuts every object into batches of `batch` triangles (the last padded with degenerate
/// triangles) and lays out their inputs: vertex records in the order each batch loads
/// them; for shared meshes, each batch's vertices once (in order of first use) and its
/// corners as indices into them.
fn inputs(scene: &Scene, programs: &[VertexProgram], batch: usize, clusters: usize) -> Inputs {
    let mut out = Inputs {
        batches: Vec::new(),
        vertex_words: Vec::new(),
        index_words: Vec::new(),
        states: Vec::new(),
        light_words: programs
            .iter()
            .max_by_key(|p| p.lighting().map_or(0, |(lights, _)| lights))
            .map(|p| p.light_words(scene, clusters))
            .unwrap_or_default(),
        shaded_vertices: 0,
    };
    let mut prim = 0;
    let mut state_at = 0u64;
    for (o, object) in scene.objects.iter().enumerate() {
        let vp = &programs[o];
        let words = vp.state_words(scene, object, clusters);
        let len = words.len() as u64;
        out.states.push((words, state_at));
        state_at += len;
        let tris = &object.mesh.triangles;
        for (k, chunk) in tris.chunks(batch).enumerate() {
            // Loads address whole records of this program's size: objects with records of
            // another size before it leave the words padded to a multiple of it.
            let aligned = out.vertex_words.len().next_multiple_of(vp.record_words());
            out.vertex_words.resize(aligned, 0);
            let vertex_at = (aligned / vp.record_words()) as u64;
            let mut local: Vec<u32> = Vec::new();
            let mut corners: Vec<u32> = Vec::new();
            if object.mesh.separate {
                for t in chunk {
                    local.extend(t);
                }
                // Degenerate padding: the batch's first vertex three times.
                local.resize(3 * batch, chunk[0][0]);
            } else {
                let mut slot = std::collections::HashMap::new();
                for &v in chunk.iter().flatten() {
                    let next = local.len() as u32;
                    let s = *slot.entry(v).or_insert_with(|| {
                        local.push(v);
                        next
                    });
                    corners.push(s);
                }
                corners.resize(3 * batch, 0);
                out.shaded_vertices += local.len() as u64;
                let padded = local.len().div_ceil(clusters) * clusters;
                local.resize(padded, local[0]);
            }
            if object.mesh.separate {
                out.shaded_vertices += 3 * chunk.len() as u64;
            }
            for &v in &local {
                vp.vertex_words(object, v as usize, &mut out.vertex_words);
            }
            let index_at = (!object.mesh.separate).then(|| {
                let at = out.index_words.len() as u64;
                out.index_words.extend(&corners);
                at
            });
            out.batches.push(Batch {
                object: o,
                first_of_object: k == 0,
                first_prim: prim,
                triangles: chunk.len(),
                vertices: local.len(),
                vertex_at,
                index_at,
            });
            prim += batch;
        }
    }
    out
}

/// Whether the merge stage may run: it keeps one fragment per pixel, the minimum over
/// (depth, primitive), which is what the LESS test keeps of them, and what a blend must
/// not lose.
fn merges(shape: FrameShape, options: &RenderOptions) -> bool {
    shape.depth_test == DepthTest::Less
        && shape.blend == Blend::None
        && options.merge_min_conflicts.is_some()
}

/// Reasons the pipeline cannot draw `scene` yet.
fn check_supported(scene: &Scene) -> Result<(), RenderError> {
    let bad = |m: String| Err(RenderError(format!("scene `{}`: {m}", scene.name)));
    if scene.pipeline.kind != PipelineKind::OpenGl {
        return bad(
            "its pipeline is Reyes (`crate::reyes`; `imagine render --pipeline reyes`), \
             not OpenGL"
                .into(),
        );
    }
    if scene.width == 0
        || scene.height == 0
        || scene.width > MAX_WINDOW
        || scene.height > MAX_WINDOW
    {
        return bad(format!(
            "window {}x{} is outside 1..={MAX_WINDOW} pixels per side",
            scene.width, scene.height
        ));
    }
    Ok(())
}

/// The pipeline built for a scene on a machine, before anything is compiled or run: its
/// vertex programs, batch size and SRF plan, and what it leaves out.
pub struct PipelinePlan {
    /// Per object, its vertex program.
    pub programs: Vec<VertexProgram>,
    /// Triangles per batch.
    pub batch: usize,
    pub plan: SrfPlan,
    streams: Streams,
    shape: FrameShape,
    general: bool,
    /// Whether the merge stage may run (depth test LESS, merging on).
    merge: bool,
    /// What vertices carry beyond position and colour.
    pub varyings: Varyings,
    /// Per object, in a frame with fragment programs (textures or marble), its program
    /// (none in other frames).
    pub fragment_programs: Vec<Option<FragmentProgram>>,
    /// Where the textures lie in DRAM.
    pub textures: TextureMemory,
    /// Whether `assemble_clip` normalises each triangle's clip corners
    /// (`pipeline.normalise_clip`).
    pub normalise_clip: bool,
    /// Newton–Raphson steps for `irast`'s reciprocal, 0 for the divide unit
    /// (`pipeline.newton_raphson`).
    pub newton_steps: u8,
    /// The rasterizer kernels the frame runs.
    pub rasterizer: Rasterizer,
}

impl PipelinePlan {
    /// Fragments a rasterization pass may write (the SRF plan's fragment streams).
    pub fn fragment_capacity(&self) -> usize {
        self.plan.capacity(self.streams.addr)
    }

    /// The kernels the pipeline may call, by the names they are built under; the merge
    /// stage's are compiled only if a round needs them.
    pub fn kernel_names(&self) -> Vec<String> {
        let mut names: Vec<String> = Vec::new();
        for p in &self.programs {
            let mut these = vec![format!("perbegin:{}", p.name())];
            if p.lit() {
                these.push(format!("perlight:{}", p.name()));
            }
            these.push(p.name());
            these.extend(p.pass_names());
            for n in these {
                if !names.contains(&n) {
                    names.push(n);
                }
            }
        }
        names.extend(["clear", "assemble_clip", "viewport_cull", "baryprep"].map(String::from));
        names.extend(self.rasterizer_kernels().iter().map(|n| n.to_string()));
        names.extend(
            [
                "irast",
                "hash",
                "zcompare",
                "compact_recycle:z,colour",
                "compact_recycle:addr,prim",
            ]
            .map(String::from),
        );
        for fp in self.fragment_programs.iter().flatten() {
            let name = fp.name();
            let mut these = vec![format!("fragment:{name}")];
            if !fp.units.is_empty() {
                these.insert(0, format!("texaddr:{name}"));
            }
            if let Some(maps) = fp.bump_env {
                these.splice(
                    0..0,
                    [
                        maps.vertex_kernel_name(),
                        format!("bumpaddr:{name}"),
                        format!("envaddr:{name}"),
                    ],
                );
            }
            for n in these {
                if !names.contains(&n) {
                    names.push(n);
                }
            }
        }
        if self.varyings.derivatives {
            names.push("filter8".into());
        }
        if self.merge {
            names.extend(["sort32".into(), "mergefrag".into()]);
        }
        names
    }

    /// The rasterizer kernels' names, in the order a frame calls them.
    pub fn rasterizer_kernels(&self) -> &'static [&'static str] {
        match self.rasterizer {
            Rasterizer::Barycentric => &["xyprep", "xyrast"],
            Rasterizer::Scanline => &["spanprep", "spangen", "spanpack", "spanrast"],
        }
    }

    /// What the general pipeline has and this one leaves out.
    pub fn left_out(&self) -> Vec<String> {
        let mut out = Vec::new();
        let p = &self.programs;
        if !self.general {
            if p.iter().all(|p| matches!(p, VertexProgram::Unlit { .. })) {
                out.push("lighting".to_string());
            } else if p.iter().all(|p| {
                matches!(
                    p,
                    VertexProgram::Lit {
                        specular: false,
                        ..
                    } | VertexProgram::Unlit { .. }
                )
            }) {
                out.push("specular lighting".to_string());
            }
            if p.iter().any(|p| {
                matches!(
                    p,
                    VertexProgram::Unlit {
                        per_vertex_colour: false,
                        ..
                    }
                )
            }) {
                out.push("per-vertex colours (a constant colour instead)".to_string());
            }
        }
        let programs = self.fragment_programs.iter().flatten();
        if !programs
            .clone()
            .any(|f| f.marble.is_none() && (!f.units.is_empty() || f.bump_env.is_some()))
        {
            out.push("textures".into());
        }
        if !programs.clone().any(|f| f.marble.is_some()) {
            out.push("procedural noise".into());
        }
        if !self.shape.ordered() {
            out.push("blending (and fragments in primitive order)".into());
        }
        if !self.merge {
            out.push("merge of conflicting fragments (sort32, mergefrag)".into());
        }
        out
    }

    /// The words of the largest vertex record.
    pub fn words_per_vertex(&self) -> usize {
        self.programs
            .iter()
            .map(VertexProgram::record_words)
            .max()
            .unwrap_or(0)
    }

    /// Texel words a vertex texture fetches per vertex (the most of any program).
    pub fn vertex_texel_words(&self) -> usize {
        if self
            .programs
            .iter()
            .any(|p| matches!(p, VertexProgram::BumpEnv { .. }))
        {
            bump_map::TEXEL_WORDS
        } else {
            0
        }
    }

    /// Interpolated words per fragment, by name.
    pub fn interpolants(&self) -> Vec<String> {
        let mut names: Vec<String> = self
            .programs
            .first()
            .map(|p| p.interpolants().into_iter().map(String::from).collect())
            .unwrap_or_default();
        if self.varyings.derivatives {
            names.extend(["ds/dx", "ds/dy", "dt/dx", "dt/dy"].map(String::from));
        }
        names
    }

    pub fn specialised(&self) -> bool {
        !self.general
    }
}

/// Plans the pipeline for `scene` on `desc`: vertex programs, batch size (strip-mined to
/// the SRF) and the SRF plan; errors name what the scene or machine lacks.
pub fn plan_pipeline(
    scene: &Scene,
    desc: &MachineDesc,
    options: &RenderOptions,
) -> Result<PipelinePlan, RenderError> {
    check_supported(scene)?;
    let clusters = desc.cluster.count;
    let general = !options.specialise;
    let scanline = options.rasterizer == Rasterizer::Scanline;
    if scanline && desc.rasterizer.is_some() {
        return Err(RenderError(format!(
            "machine `{}` rasterizes in hardware; `--rasterizer scanline` chooses between \
             the rasterizer kernels",
            desc.name
        )));
    }
    if scanline && kernels::in_primitive_order(scene.pipeline.blend) {
        return Err(RenderError(format!(
            "scene `{}` blends, so its fragments must reach the composite in primitive \
             order; the scanline rasterizer's load-balanced spans do not keep it (render it \
             with `--rasterizer barycentric`)",
            scene.name
        )));
    }
    let programs: Vec<VertexProgram> = scene
        .objects
        .iter()
        .map(|o| VertexProgram::for_object(scene, o, general))
        .collect::<Result<_, _>>()
        .map_err(|e| RenderError(format!("scene `{}`: {e}", scene.name)))?;
    let extras = vertex_program::extra_words(scene);
    let textures = TextureMemory::new(scene, desc.texture_cache.as_ref());
    let fragment_programs: Vec<Option<FragmentProgram>> = scene
        .objects
        .iter()
        .map(|o| {
            let m = &scene.materials[o.material];
            (extras > 0).then(|| match m.shader {
                Shader::Marble(marble) => FragmentProgram::marble(marble.noise),
                Shader::BumpEnv(_) => fragment_program::for_bump_env(scene, o.material, &textures)
                    .expect("the scene file checked a bump_env material's one texture"),
                _ => fragment_program::for_material(scene, &m.textures, m.texture_mode, &textures),
            })
        })
        .collect();
    let marble = fragment_programs
        .iter()
        .flatten()
        .any(|f| f.marble.is_some());
    let perlin_table = fragment_programs
        .iter()
        .flatten()
        .any(|f| f.marble.is_some_and(|n| n.uses_table()));
    let varyings = Varyings {
        extras,
        derivatives: fragment_programs
            .iter()
            .flatten()
            .any(|f| f.mipmapped() > 0),
        reference_depth: scene.pipeline.reference_depth,
    };
    let most_of = |f: fn(&FragmentProgram) -> usize| {
        fragment_programs.iter().flatten().map(f).max().unwrap_or(0)
    };
    let (direct_fetches, direct_weights, mipmapped, dependent_fetches) = (
        most_of(FragmentProgram::direct_fetches),
        most_of(FragmentProgram::direct_weights),
        most_of(FragmentProgram::mipmapped),
        most_of(FragmentProgram::dependent_fetches),
    );
    let vertex_texels = if programs
        .iter()
        .any(|p| matches!(p, VertexProgram::BumpEnv { .. }))
    {
        bump_map::TEXEL_WORDS
    } else {
        0
    };
    // (`PipelinePlan::vertex_texel_words` says the same once the plan is built.)
    // `xyrast` keeps a batch's raster records in the scratchpad; the scanline rasterizer
    // keeps only its buffered records there (its kernels name what they lack).
    let rows = if scanline {
        usize::MAX / clusters
    } else {
        kernels::xyrast_rows(desc)
    };
    if rows == 0 {
        // `xyrast` names what its scratchpad lacks for a batch of one row.
        let one_row = FrameShape {
            width: scene.width,
            height: scene.height,
            clusters,
            cull: scene.pipeline.cull,
            depth_test: scene.pipeline.depth_test,
            batch: clusters,
            blend: scene.pipeline.blend,
        };
        let e = match kernels::xyrast(desc, one_row) {
            Err(e) => e.to_string(),
            Ok(_) => format!(
                "machine `{}`: the scratchpad cannot hold a raster record",
                desc.name
            ),
        };
        return Err(RenderError(format!("cannot build the pipeline: {e}")));
    }
    // Strip-mining: the largest batch up to the one asked for (whole rows of clusters, at
    // most `rows` per cluster for `xyrast`'s scratchpad, no more than the largest object
    // needs) whose streams fit the SRF.
    let most = scene
        .objects
        .iter()
        .map(|o| o.mesh.triangles.len())
        .max()
        .unwrap_or(0);
    let asked = options
        .batch
        .or(scene.pipeline.batch.map(|b| b as usize))
        .unwrap_or(DEFAULT_BATCH);
    let want = asked.max(clusters).div_ceil(clusters) * clusters;
    let top = want
        .min(most.div_ceil(clusters) * clusters)
        .min(rows * clusters)
        .max(clusters);
    let candidates = (1..=top / clusters).rev().map(|r| r * clusters);
    let state_words = programs
        .iter()
        .zip(&scene.objects)
        .map(|(p, o)| p.state_words(scene, o, clusters).len())
        .max()
        .unwrap_or(clusters);
    let params = programs
        .iter()
        .map(|p| p.param_count(desc))
        .max()
        .unwrap_or(0)
        .max(1);
    let vertex_words = programs
        .iter()
        .map(VertexProgram::record_words)
        .max()
        .unwrap_or(3);
    let light_words = 12
        * clusters
        * programs
            .iter()
            .filter_map(|p| p.lighting().map(|(lights, _)| lights))
            .max()
            .unwrap_or(0);
    let split = programs.iter().filter(|p| !p.pass_names().is_empty());
    let partial_words = split.clone().map(VertexProgram::partial_words).max();
    let passes = split.map(|p| p.pass_names().len()).max().unwrap_or(0);
    let sizes_for = |batch| Sizes {
        batch,
        state_words,
        params,
        vertex_words,
        light_words,
        partial_words: partial_words.unwrap_or(1),
        passes,
        varyings,
        direct_fetches,
        direct_weights,
        mipmapped,
        marble,
        perlin_table,
        ordered: kernels::in_primitive_order(scene.pipeline.blend),
        dependent_fetches,
        vertex_texels,
        scanline,
    };
    let (batch, plan, s) = strip_mine(candidates, |b| plan_streams(desc, &sizes_for(b)))?;
    let shape = FrameShape {
        width: scene.width,
        height: scene.height,
        clusters,
        cull: scene.pipeline.cull,
        depth_test: scene.pipeline.depth_test,
        batch,
        blend: scene.pipeline.blend,
    };
    Ok(PipelinePlan {
        merge: merges(shape, options),
        programs,
        batch,
        plan,
        streams: s,
        shape,
        general,
        varyings,
        fragment_programs,
        textures,
        normalise_clip: scene.pipeline.normalise_clip,
        newton_steps: scene.pipeline.newton_raphson,
        rasterizer: options.rasterizer,
    })
}

/// Renders `scene` on a processor built from `desc`; `progress(done, total)` is called
/// after each batch; `on_start` sees the simulation before the first cycle (to attach a
/// waveform tracer).
pub fn render(
    scene: &Scene,
    desc: &MachineDesc,
    on_start: Option<imagine_units::runner::OnStart>,
    progress: impl FnMut(usize, usize),
) -> Result<Frame, RenderError> {
    render_with(scene, desc, RenderOptions::default(), on_start, progress)
}

/// [`render`] with the host's choices in `options`.
pub fn render_with(
    scene: &Scene,
    desc: &MachineDesc,
    options: RenderOptions,
    on_start: Option<imagine_units::runner::OnStart>,
    progress: impl FnMut(usize, usize),
) -> Result<Frame, RenderError> {
    run_frame(scene, desc, options, on_start, progress, false).map(|(frame, _)| frame)
}

/// Runs `scene`'s geometry stage alone on a processor built from `desc`: each batch's
/// vertex program, `assemble_clip` and `viewport_cull`, whose `clipped`, `attribs` and
/// `window` records are then stored to DRAM (stream stores, in drawing order) instead of
/// going on to the rasterizer. The framebuffer is neither cleared nor read back. After the
/// run the host reads the stored records out of DRAM (the backdoor, as for
/// [`Frame::triangles`]) and turns them into window-space triangles ([`Geometry`]): the
/// input of another rasterizer, such as the S3 engine's (`imagine s3 --scene`).
pub fn render_geometry(
    scene: &Scene,
    desc: &MachineDesc,
    options: RenderOptions,
    on_start: Option<imagine_units::runner::OnStart>,
    progress: impl FnMut(usize, usize),
) -> Result<Geometry, RenderError> {
    let (_, geometry) = run_frame(scene, desc, options, on_start, progress, true)?;
    Ok(geometry.expect("a geometry-only run returns its geometry"))
}

/// The frame ([`render_with`]), or with `geometry_only` the geometry stage alone
/// ([`render_geometry`]; the frame then has no pixels).
fn run_frame(
    scene: &Scene,
    desc: &MachineDesc,
    options: RenderOptions,
    on_start: Option<imagine_units::runner::OnStart>,
    mut progress: impl FnMut(usize, usize),
    geometry_only: bool,
) -> Result<(Frame, Option<Geometry>), RenderError> {
    let host_start = Instant::now();
    let pp = plan_pipeline(scene, desc, &options)?;
    let clusters = desc.cluster.count;
    let general = pp.general;
    let (programs, batch, plan, s, shape) =
        (&pp.programs, pp.batch, &pp.plan, &pp.streams, pp.shape);
    let (phase_plan, ps) = plan_phases(desc)?;
    let mut lib = KernelLibrary::new(desc, options.cache.clone());
    let k = register_kernels(&mut lib, desc, shape, &pp, &options)
        .map_err(|e| RenderError(format!("cannot build the pipeline: {e}")))?;
    // Compile what every frame reaches now, on the host's cores; the merge stage when a
    // round first needs it (or now, for the general pipeline).
    let mut eager: Vec<KernelId> = k
        .per_object
        .iter()
        .flat_map(|o| {
            [Some(o.perbegin), o.perlight, o.vtexaddr, Some(o.vertex)]
                .into_iter()
                .flatten()
                .chain(o.passes.iter().copied())
        })
        .collect();
    // A geometry-only run reaches neither the clear nor anything after `viewport_cull`.
    if !geometry_only {
        eager.push(k.clear);
    }
    eager.extend([k.assemble_clip, k.viewport_cull]);
    if !geometry_only {
        // The hardware rasterizer, where there is one, does the rasterizer kernels' work.
        if desc.rasterizer.is_none() {
            eager.push(k.baryprep);
            eager.extend(k.raster.all());
            eager.push(k.irast);
        }
        eager.extend([k.hash, k.zcompare, k.recycle_zc, k.recycle_ap]);
        eager.extend(k.fragment.iter().flat_map(FragmentKernels::all));
        eager.extend(k.filter8);
        if general && let Some((a, b)) = k.merge {
            eager.extend([a, b]);
        }
    }
    lib.compile_now(&eager)
        .map_err(|e| RenderError(format!("cannot compile the pipeline: {e}")))?;

    let input = inputs(scene, programs, batch, clusters);
    let pixels = (scene.width * scene.height) as usize + 1;
    let mut dram = DramMap::new(desc);
    let fb_pixels = pixels.div_ceil(clusters) * clusters;
    let shaded_words = pp.varyings.shaded_words();
    // The marble program's permutation table, each word once per cluster.
    let perm_words = turbulence::perlin_perm_stream(clusters);
    let m = Memory {
        textures: dram.read_only_buffer("textures", pp.textures.words.len().max(1) as u64)?,
        perm: dram.buffer("perm", perm_words.len() as u64)?,
        texture_words: pp.textures.words.len().max(1) as u64,
        vertices: dram.buffer("vertices", input.vertex_words.len() as u64)?,
        indices: dram.buffer("corner_indices", input.index_words.len() as u64)?,
        state: dram.buffer(
            "state",
            input.states.iter().map(|(w, _)| w.len() as u64).sum(),
        )?,
        lights: dram.buffer("lights", input.light_words.len() as u64)?,
        shaded: [
            dram.buffer("shaded[0]", (3 * batch * shaded_words) as u64)?,
            dram.buffer("shaded[1]", (3 * batch * shaded_words) as u64)?,
        ],
        interp: dram.buffer("interp", (batch * pp.varyings.interp_words()) as u64)?,
        framebuffer: dram.buffer("framebuffer", (fb_pixels * PIXEL_WORDS) as u64)?,
        pixels: pixels as u64,
        interp_records: batch as u64,
        edges: dram.buffer("edges", ((batch + clusters) * EDGE_WORDS) as u64)?,
        edge_records: (batch + clusters) as u64,
    };
    let geometry_store = if geometry_only {
        let triangles: usize = input.batches.iter().map(|b| b.triangles).sum();
        let mut words = |name: &str, record_words: usize| {
            dram.buffer(name, (triangles * record_words).max(1) as u64)
        };
        Some(GeometryStore {
            window: words("geometry_window", WINDOW_WORDS)?,
            clipped: words("geometry_clipped", CLIPPED_WORDS)?,
            attribs: words("geometry_attribs", pp.varyings.attrib_words())?,
            stored: 0,
        })
    } else {
        None
    };
    let mut host = StreamHost::new(desc, lib, dram, on_start, options.max_cycles)?;
    let processor = processor::processor_mut(host.sim_mut());
    processor.set_skip_idle(!options.step_idle);
    processor.set_datapath(options.datapath);
    if options.record_dram {
        for c in host.sim_mut().modules_of_mut::<DramChannel>() {
            c.start_recording();
        }
    }
    if options.reverse_eval_order {
        host.sim_mut().reverse_eval_order();
    }
    let mut stats = FrameStats {
        scene: scene.name.clone(),
        machine: desc.name.clone(),
        width: scene.width,
        height: scene.height,
        triangles: scene.triangles() as u64,
        vertices: input.shaded_vertices,
        batch_triangles: batch,
        srf_plan: plan.rows(),
        srf_peak_words: plan.peak_words(),
        ..FrameStats::default()
    };

    // Load: the scene's inputs into DRAM over the host interface.
    let sim_start = Instant::now();
    let compiled_before = host.kernels.compile_seconds();
    let staging = phase_plan.whole(ps.staging);
    host.upload(&input.vertex_words, m.vertices, 0, staging);
    host.upload(&input.index_words, m.indices, 0, staging);
    for (words, at) in &input.states {
        host.upload(words, m.state, *at, staging);
    }
    host.upload(&input.light_words, m.lights, 0, staging);
    // The textures' mipmap pyramids, built when the scene loaded.
    host.upload(&pp.textures.words, m.textures, 0, staging);
    let perm_stream = s
        .texturing
        .as_ref()
        .and_then(|t| t.marble.as_ref())
        .and_then(|ms| ms.perm);
    if perm_stream.is_some() {
        host.upload(&perm_words, m.perm, 0, staging);
    }
    host.drain()?;
    let loaded = host.cycles();

    // Clear: the machine writes the clear pixel and stores it over the framebuffer.
    if !geometry_only {
        let background = pack_rgb(scene.background);
        clear_framebuffer(
            &mut host,
            k.clear,
            (&phase_plan, &ps),
            m.framebuffer,
            fb_pixels,
            background,
        )?;
        host.drain()?;
    }
    let cleared = host.cycles();

    // The frame. The Perlin marble program's table comes into the SRF first.
    if let Some(perm) = perm_stream {
        let perm = plan.first(perm, perm_words.len());
        host.load(m.perm, 0, Layout::words(), perm_words.len(), perm);
    }
    let mut frame = FrameRun {
        k: &k,
        plan,
        s,
        m: &m,
        input: &input,
        scene,
        merge_min_conflicts: options.merge_min_conflicts,
        stats: &mut stats,
        batch,
        last_cycles: cleared,
        max_fragment_words: 0,
        programs,
        varyings: pp.varyings,
        fragment_programs: &pp.fragment_programs,
        current_object: 0,
        first_prim: 0,
        geometry: geometry_store,
        edges_stored: false,
    };
    let batches = input.batches.len();
    let mut run = (&mut host, &mut frame);
    pipelined(
        &mut run,
        batches,
        |(h, f), b| f.prefetch(h, b),
        |(h, f), b| f.batch(h, b),
        |(h, f), b| {
            f.finish_batch(h);
            progress(b + 1, batches);
        },
    )?;
    host.drain()?;
    let rendered = host.cycles();
    let geometry_store = frame.geometry.take();

    // Read-back: the colour words of the framebuffer.
    let pixels_out = if geometry_only {
        Vec::new()
    } else {
        host.download(m.framebuffer, 0, PIXEL_WORDS as u64, pixels - 1, staging)?
    };
    host.drain()?;
    let read = host.cycles();
    host.finish()?;
    let simulate_seconds = sim_start.elapsed().as_secs_f64();
    let records = if geometry_only {
        Vec::new()
    } else {
        processor::read_dram(
            host.sim(),
            desc,
            host.dram.base(m.framebuffer),
            (pixels - 1) * PIXEL_WORDS,
        )
    };
    let triangles = visible_triangles(&records, &input, batch);
    let depths = records.chunks(PIXEL_WORDS).map(|r| r[1]).collect();
    let geometry = geometry_store.map(|g| {
        read_geometry(
            &host,
            desc,
            &g,
            &input,
            pp.varyings,
            (scene.width, scene.height),
        )
    });

    stats.phases = Phases {
        load_cycles: loaded,
        clear_cycles: cleared - loaded,
        frame_plus_clear_cycles: rendered - loaded,
        readback_cycles: read - rendered,
    };
    stats.cycles = rendered - cleared;
    let segments = finish_stats(&mut stats, &host, desc, &pp, cleared..rendered);
    let timeline = options.timeline.then(|| {
        let controller = processor::processor(host.sim()).controller();
        let programs: Vec<ProgramInfo> = controller
            .programs()
            .iter()
            .enumerate()
            .map(|(p, program)| ProgramInfo {
                // The breakdown's names: the pipeline's registered ones.
                name: host
                    .kernels
                    .name_of_program(p)
                    .map_or_else(|| program.name.clone(), String::from),
                ii: host.kernels.ii_of_program(p),
            })
            .collect();
        timeline::timeline(
            &TimelineInput {
                records: controller.records(),
                programs: &programs,
                batch_tags: host.batch_tags(),
                segments: &segments,
                dram: &dram_activity(host.sim(), desc),
                window: cleared..rendered,
                core_mhz: desc.clocks.core_mhz as f64,
                address_generators: desc.memory.address_generators,
            },
            timeline::MAX_EVENTS,
        )
    });
    stats.compile_seconds = host.kernels.compile_seconds();
    stats.kernels_from_cache = host.kernels.from_cache();
    stats.kernel_programs = host.kernels.built().len();
    // Kernels first reached during the run were compiled inside it.
    stats.simulate_seconds = simulate_seconds - (stats.compile_seconds - compiled_before);
    stats.host_seconds = host_start.elapsed().as_secs_f64();
    stats.simulated_cycles_per_second = read as f64 / stats.simulate_seconds.max(1e-9);
    stats.skipped_cycles = processor::processor(host.sim()).skipped_cycles();
    // The frame's requests: those the channels received between its first and last core
    // cycles, in DRAM cycles.
    let dram_per_core = desc.clocks.dram_mhz as f64 / desc.clocks.core_mhz as f64;
    let window = (cleared as f64 * dram_per_core) as u64..(rendered as f64 * dram_per_core) as u64;
    let dram_requests = imagine_units::dram::replay::recorded(host.sim())
        .into_iter()
        .filter(|r| window.contains(&r.cycle))
        .collect();
    let geometry = geometry.map(|(triangles, ids, discarded, unrepresentable)| Geometry {
        width: scene.width,
        height: scene.height,
        triangles,
        ids,
        discarded,
        unrepresentable,
        stats: stats.clone(),
    });
    let frame = Frame {
        width: scene.width,
        height: scene.height,
        pixels: pixels_out,
        stats,
        triangles,
        depths,
        timeline,
        dram_requests,
    };
    Ok((frame, geometry))
}

/// Queues the clear of `pixels` framebuffer pixels (whole rows) to `background` and depth
/// 1.0: `clear` writes the clear pixel records into the SRF and they are stored over the
/// framebuffer again and again.
pub(crate) fn clear_framebuffer(
    host: &mut StreamHost,
    clear: KernelId,
    (phase_plan, ps): (&SrfPlan, &PhaseStreams),
    framebuffer: Buffer,
    pixels: usize,
    background: u32,
) -> Result<(), HostError> {
    host.write_params(
        phase_plan.whole(ps.clear_params),
        &[background, 1.0f32.to_bits()],
    );
    let clear_rows = phase_plan.capacity(ps.clear_pixels);
    host.call(
        clear,
        &[
            ("tickets", phase_plan.first(ps.clear_tickets, clear_rows)),
            ("pixels", phase_plan.first(ps.clear_pixels, clear_rows)),
            (PARAMS, phase_plan.whole(ps.clear_params)),
        ],
    )?;
    let mut at = 0;
    while at < pixels {
        let n = clear_rows.min(pixels - at);
        host.store(
            phase_plan.first(ps.clear_pixels, n),
            Layout::records(PIXEL_WORDS),
            n,
            framebuffer,
            at as u64,
        );
        at += n;
    }
    Ok(())
}

/// Which triangle each pixel shows: the primitive word of its framebuffer `records`
/// (`baryprep` numbers primitives `first_prim + index + 1`, 0 for a pixel never drawn, and
/// every batch spans `batch` numbers, padding included), read through the DRAM's backdoor
/// after the frame, so that it costs no simulated cycle and leaves the read-back phase as
/// it is.
fn visible_triangles(records: &[u32], input: &Inputs, batch: usize) -> Vec<Option<TriangleId>> {
    let first_triangle = batch_first_triangles(input);
    records
        .chunks(PIXEL_WORDS)
        .map(|record| {
            let primitive = (record[2] as usize).checked_sub(1)?;
            let (index, local) = (primitive / batch, primitive % batch);
            let b = input.batches.get(index)?;
            (local < b.triangles).then(|| TriangleId {
                object: b.object,
                triangle: first_triangle[index] + local,
            })
        })
        .collect()
}

/// Each batch's first triangle within its object (batches are in drawing order).
fn batch_first_triangles(input: &Inputs) -> Vec<usize> {
    let objects = input
        .batches
        .iter()
        .map(|b| b.object + 1)
        .max()
        .unwrap_or(0);
    let mut object_triangles = vec![0usize; objects];
    input
        .batches
        .iter()
        .map(|b| {
            let first = object_triangles[b.object];
            object_triangles[b.object] += b.triangles;
            first
        })
        .collect()
}

/// The stored geometry ([`GeometryStore`]) read out of DRAM after the run (the backdoor:
/// no simulated cycle) and decoded: the window-space triangles with their scene ids, the
/// discarded count and the count of kept triangles reaching behind the eye.
fn read_geometry(
    host: &StreamHost,
    desc: &MachineDesc,
    g: &GeometryStore,
    input: &Inputs,
    varyings: Varyings,
    size: (u32, u32),
) -> (Vec<WindowTriangle>, Vec<TriangleId>, usize, usize) {
    let n = g.stored as usize;
    let attrib_words = varyings.attrib_words();
    let read = |b: Buffer, words: usize| {
        processor::read_dram(host.sim(), desc, host.dram.base(b), n * words)
    };
    let window = read(g.window, WINDOW_WORDS);
    let clipped = read(g.clipped, CLIPPED_WORDS);
    let attribs = read(g.attribs, attrib_words);
    // Scene ids in drawing order: each batch's triangles, numbered within their object.
    let ids = input
        .batches
        .iter()
        .zip(batch_first_triangles(input))
        .flat_map(|(b, first)| {
            (first..first + b.triangles).map(move |triangle| TriangleId {
                object: b.object,
                triangle,
            })
        });
    let (mut triangles, mut kept_ids) = (Vec::new(), Vec::new());
    let (mut discarded, mut unrepresentable) = (0, 0);
    for (((w, c), a), id) in window
        .chunks(WINDOW_WORDS)
        .zip(clipped.chunks(CLIPPED_WORDS))
        .zip(attribs.chunks(attrib_words))
        .zip(ids)
    {
        // Bit 0 of the window record's flags: kept by `viewport_cull`.
        if w[WINDOW_WORDS - 1] & 1 == 0 {
            discarded += 1;
            continue;
        }
        match window_triangle(c, a, varyings, size) {
            Some(t) => {
                triangles.push(t);
                kept_ids.push(id);
            }
            None => unrepresentable += 1,
        }
    }
    (triangles, kept_ids, discarded, unrepresentable)
}

/// A kept triangle's window-space form from its `clipped` record (clip x, y, w per
/// corner) and `attribs` record (clip z, or `z − ζ·w` after the reference depth ζ, then
/// r, g, b per corner): `viewport_cull`'s transform `((x + w)·W/2, (y + w)·H/2)` divided by
/// `w` (on the host, in f32), and the window depth `(z/w)·½ + ½` that `irast` interpolates.
/// `None` when a corner has `w ≤ 0` or lies beyond ±[`MAX_TRI_COORDINATE`] pixels.
fn window_triangle(
    clipped: &[u32],
    attribs: &[u32],
    varyings: Varyings,
    size: (u32, u32),
) -> Option<WindowTriangle> {
    let f = |w: u32| f32::from_bits(w);
    let (zeta, attribs) = if varyings.reference_depth {
        (f(attribs[0]), &attribs[1..])
    } else {
        (0.0, attribs)
    };
    let (half_w, half_h) = (size.0 as f32 / 2.0, size.1 as f32 / 2.0);
    let mut t = WindowTriangle {
        positions: [[0.0; 3]; 3],
        colours: [[0.0; 3]; 3],
    };
    for k in 0..3 {
        let [x, y, w] = [0, 1, 2].map(|i| f(clipped[3 * k + i]));
        if w.is_nan() || w <= 0.0 {
            return None;
        }
        let z_ndc = zeta + f(attribs[k]) / w;
        let (wx, wy) = ((x + w) * half_w / w, (y + w) * half_h / w);
        // NaN fails the test too.
        if !(wx.abs() <= MAX_TRI_COORDINATE && wy.abs() <= MAX_TRI_COORDINATE) {
            return None;
        }
        t.positions[k] = [wx, wy, z_ndc * 0.5 + 0.5];
        t.colours[k] = [0, 1, 2].map(|i| f(attribs[3 + 3 * k + i]));
    }
    Some(t)
}

/// `[r, g, b]` in [0, 1] as an opaque RGBA8 word (red in the low byte), rounded.
pub fn pack_rgb(c: [f32; 3]) -> u32 {
    let byte = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u32;
    byte(c[0]) | byte(c[1]) << 8 | byte(c[2]) << 16 | 0xFF00_0000
}

/// DRAM buffers of the frame.
struct Memory {
    /// Every texture's levels ([`TextureMemory`]), and its words: the bound of texel
    /// gathers.
    textures: Buffer,
    texture_words: u64,
    /// The marble program's permutation table.
    perm: Buffer,
    vertices: Buffer,
    /// The lights as `perlight` reads them.
    lights: Buffer,
    indices: Buffer,
    state: Buffer,
    /// Shaded vertices of shared meshes, two sets, gathered back by corner.
    shaded: [Buffer; 2],
    interp: Buffer,
    framebuffer: Buffer,
    /// Window pixels and the trash pixel: the bound of gathers and scatters by pixel.
    pixels: u64,
    /// A batch's interpolation records: the bound of gathers by triangle.
    interp_records: u64,
    /// A batch's edge records and the sentinel's (the scanline rasterizer's), and their
    /// count: the bound of gathers by span.
    edges: Buffer,
    edge_records: u64,
}

/// A frame in progress.
struct FrameRun<'a> {
    k: &'a Kernels,
    plan: &'a SrfPlan,
    s: &'a Streams,
    m: &'a Memory,
    input: &'a Inputs,
    scene: &'a Scene,
    programs: &'a [VertexProgram],
    varyings: Varyings,
    fragment_programs: &'a [Option<FragmentProgram>],
    /// The object of the batch being rasterized.
    current_object: usize,
    /// The primitive number before the batch's first triangle's.
    first_prim: u32,
    merge_min_conflicts: Option<usize>,
    stats: &'a mut FrameStats,
    batch: usize,
    last_cycles: u64,
    /// The most SRF words fragments held in this batch's passes.
    max_fragment_words: usize,
    /// Where a geometry-only run stores its triangles' records (`None`: a whole frame).
    geometry: Option<GeometryStore>,
    /// Whether this batch's edge records are in DRAM (the scanline rasterizer's).
    edges_stored: bool,
}

/// The DRAM buffers of a geometry-only run ([`render_geometry`]): each kept batch
/// triangle's `window`, `clipped` and `attribs` records, in drawing order (padding
/// triangles of a batch are not stored).
struct GeometryStore {
    window: Buffer,
    clipped: Buffer,
    attribs: Buffer,
    /// Triangles stored so far: where the next batch's go.
    stored: u64,
}

/// A window-space triangle of the geometry stage, with per-vertex colour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WindowTriangle {
    /// Per corner: x, y in window pixels (origin bottom-left, pixel centres at +½), and the
    /// window depth `z_ndc·½ + ½` (what the rasterizer's depth test compares).
    pub positions: [[f32; 3]; 3],
    /// Per corner: the vertex program's r, g, b (lit or not; before any texture or
    /// fragment program, which are per fragment).
    pub colours: [[f32; 3]; 3],
}

/// What [`render_geometry`] read back: the scene's triangles after its geometry stage.
#[derive(Clone, Debug)]
pub struct Geometry {
    pub width: u32,
    pub height: u32,
    /// The triangles the geometry stage kept (not rejected by a clip plane, not
    /// degenerate, not culled) with every corner in front of the eye, in drawing order.
    pub triangles: Vec<WindowTriangle>,
    /// Which scene triangle each of [`Geometry::triangles`] is.
    pub ids: Vec<TriangleId>,
    /// Triangles the geometry stage discarded (trivial reject, zero area, culled).
    pub discarded: usize,
    /// Kept triangles with no window-space form in the `.tri` range, left out: a corner at
    /// `w ≤ 0` (this pipeline rasterizes those homogeneously, with no clipping) or beyond
    /// ±[`MAX_TRI_COORDINATE`] pixels.
    pub unrepresentable: usize,
    /// The run's statistics: `cycles` are the geometry's (vertex loads and programs,
    /// `assemble_clip`, `viewport_cull` and the stores, to the last store's end).
    pub stats: FrameStats,
}

impl FrameRun<'_> {
    fn object(&self, b: usize) -> &Object {
        &self.scene.objects[self.input.batches[b].object]
    }

    /// Queues batch `b`'s loads, and defers its `perbegin` (first batch of an object) and
    /// vertex program (with its light passes) to where the host next waits.
    fn prefetch(&mut self, h: &mut StreamHost, b: usize) -> Result<(), RenderError> {
        // Work deferred for the previous batch goes first: it reads the streams these
        // loads overwrite.
        h.flush_deferred()?;
        h.set_batch(Some(b));
        let (p, s, m) = (self.plan, self.s, self.m);
        let bt = self.input.batches[b].clone();
        let vp = &self.programs[bt.object];
        let k = self.k;
        let ok = &k.per_object[bt.object];
        let c = h.clusters();
        let params = p.words(s.vertex_params, vp.param_count(h.desc()) * c);
        let vertices = p.words(s.vertices, bt.vertices * vp.record_words());
        if bt.first_of_object {
            let (words, at) = &self.input.states[bt.object];
            let state = p.words(s.state, words.len());
            h.load(m.state, *at, Layout::words(), words.len(), state);
            let own = p.words(s.vertex_params, vp.perbegin_rows(h.desc()) * c);
            h.defer(ok.perbegin, &[("state", state), ("params", own)]);
            if let Some(perlight) = ok.perlight {
                let object = &self.scene.objects[bt.object];
                let pl = p.whole(s.perlight_params);
                h.write_params(pl, &VertexProgram::perlight_params(self.scene, object));
                let lights = p.words(s.lights, self.input.light_words.len());
                h.load(
                    m.lights,
                    0,
                    Layout::words(),
                    self.input.light_words.len(),
                    lights,
                );
                let first = vp.perbegin_rows(h.desc()) * c;
                let rest = p.word_range(s.vertex_params, first, params.words - first);
                h.defer(
                    perlight,
                    &[("lights", lights), ("light_params", rest), (PARAMS, pl)],
                );
            }
        }
        let layout = Layout::records(vp.record_words());
        h.load(m.vertices, bt.vertex_at, layout, bt.vertices, vertices);
        if let Some(at) = bt.index_at {
            let ci = p.first(s.corner_index[b % 2], 3 * self.batch);
            h.load(m.indices, at, Layout::words(), 3 * self.batch, ci);
        }
        let shaded = p.first(s.shaded[b % 2], bt.vertices);
        if let (Some(vtexaddr), Some(texels)) = (ok.vtexaddr, s.vertex_texels) {
            // The vertex texture: the texel addresses now (they need only the records),
            // the texels gathered over them, the rest of the program deferred as usual.
            let words = bt.vertices * bump_map::TEXEL_WORDS;
            let texels = p.words(texels, words);
            h.call(vtexaddr, &[("vertices", vertices), ("addr", texels)])?;
            h.gather(
                m.textures,
                texels,
                m.texture_words,
                Layout::words(),
                words,
                texels,
            );
            self.stats.texel_words += words as u64;
            self.stats.vertex_texel_fetches += words as u64;
            h.defer(
                ok.vertex,
                &[
                    ("vertices", vertices),
                    ("texels", texels),
                    ("shaded", shaded),
                    (PARAMS, params),
                ],
            );
        } else if ok.passes.is_empty() {
            h.defer(
                ok.vertex,
                &[("vertices", vertices), ("shaded", shaded), (PARAMS, params)],
            );
        } else {
            // The first lights, then the rest in passes, each reading the record the one
            // before wrote; the last writes the shaded vertices.
            // This program's records, which may be shorter than the stream's (declared
            // for the scene's longest).
            let words = bt.vertices * vp.partial_words();
            let partial = |i: usize| p.words(s.partial[i % s.partial.len()], words);
            h.defer(
                ok.vertex,
                &[
                    ("vertices", vertices),
                    ("partial", partial(0)),
                    (PARAMS, params),
                ],
            );
            for (i, &pass) in ok.passes.iter().enumerate() {
                let out = if i + 1 == ok.passes.len() {
                    ("shaded", shaded)
                } else {
                    ("partial_out", partial(i + 1))
                };
                h.defer(pass, &[("partial", partial(i)), out, (PARAMS, params)]);
            }
        }
        h.set_batch(None);
        Ok(())
    }

    /// Sets up, rasterizes and composites batch `b`.
    fn batch(&mut self, h: &mut StreamHost, b: usize) -> Result<(), RenderError> {
        // This batch's vertex program, if it is still deferred (the next batch's stays).
        h.flush_deferred_through(b)?;
        h.set_batch(Some(b));
        let (p, s, m) = (self.plan, self.s, self.m);
        let bt = self.input.batches[b].clone();
        self.stats.batch_rows.push(BatchRow {
            batch: b,
            object: self.object(b).name.clone(),
            triangles: bt.triangles,
            vertices: bt.vertices,
            ..BatchRow::default()
        });
        let tris = self.batch;
        self.current_object = bt.object;
        let set = b % 2;
        let corners = match bt.index_at {
            None => p.first(s.shaded[set], 3 * tris),
            Some(_) => {
                // Shared vertices: shaded once, then gathered three per triangle.
                let shaded = Layout::records(self.varyings.shaded_words());
                h.store(
                    p.first(s.shaded[set], bt.vertices),
                    shaded,
                    bt.vertices,
                    m.shaded[set],
                    0,
                );
                let index = p.first(s.corner_index[set], 3 * tris);
                let to = p.first(s.corners, 3 * tris);
                h.gather(
                    m.shaded[set],
                    index,
                    bt.vertices as u64,
                    shaded,
                    3 * tris,
                    to,
                );
                to
            }
        };
        let (clipped, attribs) = (p.first(s.clipped, tris), p.first(s.attribs, tris));
        let (window, det) = (p.first(s.window, tris), p.first(s.det, tris));
        h.call(
            self.k.assemble_clip,
            &[
                ("shaded", corners),
                ("clipped", clipped),
                ("attribs", attribs),
            ],
        )?;
        h.call(
            self.k.viewport_cull,
            &[("clipped", clipped), ("window", window), ("det", det)],
        )?;
        if let Some(g) = &mut self.geometry {
            // Geometry only: the batch's real triangles go to DRAM, and no further.
            let n = bt.triangles;
            let attrib_words = self.varyings.attrib_words();
            for (stream, words, buffer) in [
                (s.window, WINDOW_WORDS, g.window),
                (s.clipped, CLIPPED_WORDS, g.clipped),
                (s.attribs, attrib_words, g.attribs),
            ] {
                h.store(
                    p.first(stream, n),
                    Layout::records(words),
                    n,
                    buffer,
                    g.stored,
                );
            }
            g.stored += n as u64;
            h.set_batch(None);
            return Ok(());
        }
        self.first_prim = bt.first_prim as u32;
        self.edges_stored = false;
        if s.unit.is_none() {
            let interp = p.first(s.interp, tris);
            let bparams = p.whole(s.baryprep_params);
            h.write_params(bparams, &[bt.first_prim as u32]);
            let mut bindings = vec![
                ("attribs", attribs),
                ("det", det),
                ("interp", interp),
                (PARAMS, bparams),
            ];
            if self.varyings.derivatives {
                bindings.push(("window", window));
            }
            h.call(self.k.baryprep, &bindings)?;
        }
        let object = &self.scene.objects[bt.object];
        let marble = s.texturing.as_ref().and_then(|t| t.marble.as_ref());
        if let (Some(ms), Shader::Marble(shader)) =
            (marble, self.scene.materials[object.material].shader)
        {
            let params = fragment_program::marble_params(self.scene, object, &shader);
            h.write_params(p.first(ms.params, params.len() * h.clusters()), &params);
        }
        if s.unit.is_none() {
            let records = Layout::records(self.varyings.interp_words());
            h.store(p.first(s.interp, tris), records, tris, m.interp, 0);
        }
        let (w, ht) = (self.scene.width as i32, self.scene.height as i32);
        let splits = split_to_fit(
            [0, 0, w - 1, ht - 1],
            |tile| self.tile(h, *tile),
            |&[x0, y0, x1, y1]| {
                if x1 > x0 && x1 - x0 >= y1 - y0 {
                    let mid = (x0 + x1) / 2;
                    Some(([x0, y0, mid, y1], [mid + 1, y0, x1, y1]))
                } else if y1 > y0 {
                    let mid = (y0 + y1) / 2;
                    Some(([x0, y0, x1, mid], [x0, mid + 1, x1, y1]))
                } else {
                    None
                }
            },
            RenderError,
        )?;
        self.stats.tile_splits += splits;
        if let Some(row) = self.stats.batch_rows.last_mut() {
            row.tile_splits = splits;
        }
        h.set_batch(None);
        Ok(())
    }

    /// Bounding boxes of scissor tile `tile`, then rasterization and composite, unless the
    /// tile's fragments would overflow their streams.
    fn tile(&mut self, h: &mut StreamHost, tile: [i32; 4]) -> Result<Fit, RenderError> {
        if self.s.unit.is_some() {
            return self.tile_in_hardware(h, tile);
        }
        let (xyprep, xyrast) = match self.k.raster {
            RasterKernels::Barycentric { xyprep, xyrast } => (xyprep, xyrast),
            RasterKernels::Scanline(k) => return self.tile_in_spans(h, tile, k),
        };
        let (p, s) = (self.plan, self.s);
        let c = h.clusters();
        let tris = self.batch;
        let xparams = p.whole(s.xyprep_params);
        h.write_params(xparams, &tile.map(|v| v as u32));
        let rows_stream = p.whole(s.rows);
        h.call(
            xyprep,
            &[
                ("window", p.first(s.window, tris)),
                ("raster", p.first(s.raster, tris)),
                ("rows", rows_stream),
                (PARAMS, xparams),
            ],
        )?;
        let counts = h.read_back(rows_stream)?;
        let rows = counts[0] as usize;
        // Each candidate pixel gives at most one fragment; then a row of nulls.
        let candidates: usize = counts[c..].iter().map(|&n| n as usize).sum();
        let capacity = p.capacity(s.addr);
        if candidates + c > capacity || rows * c > p.capacity(s.tickets) {
            return Ok(Fit::Overflow(format!(
                "a one-pixel tile needs {rows} rasterizer iterations and {candidates} fragments; \
                 the SRF holds {} iterations and {capacity} fragments",
                p.capacity(s.tickets) / c
            )));
        }
        self.rasterize(h, xyrast, rows, candidates + c)?;
        Ok(Fit::Done)
    }

    /// Scissor tile `tile` through the scanline rasterizer ([`scanline`]), then the
    /// composite, unless the tile's spans or fragments would overflow their streams.
    fn tile_in_spans(
        &mut self,
        h: &mut StreamHost,
        tile: [i32; 4],
        k: ScanlineKernels,
    ) -> Result<Fit, RenderError> {
        let (p, s, m) = (self.plan, self.s, self.m);
        let ss = s
            .scanline
            .as_ref()
            .expect("the scanline rasterizer's streams");
        let c = h.clusters();
        let tris = self.batch;
        let params = p.whole(s.xyprep_params);
        h.write_params(params, &tile.map(|v| v as u32));
        let halves = p.whole(ss.halves);
        let edges = p.whole(ss.edges);
        h.call(
            k.spanprep,
            &[
                ("window", p.first(s.window, tris)),
                ("halves", halves),
                ("edges", edges),
                ("rows", p.whole(ss.prep_counts)),
                (PARAMS, params),
            ],
        )?;
        if !self.edges_stored {
            // The same records at every tile of the batch: stored once.
            h.store(edges, Layout::records(EDGE_WORDS), tris + c, m.edges, 0);
            self.edges_stored = true;
        }
        let counts = h.read_back(p.whole(ss.prep_counts))?;
        let iterations = counts[0] as usize;
        let most_spans: usize = counts[c..].iter().map(|&n| n as usize).sum();
        let tickets = p.capacity(s.tickets) / c;
        let span_room = p.capacity(ss.pos);
        let sentinels = (SENTINEL_ROWS + 1) * c;
        if iterations > tickets || most_spans + sentinels > span_room {
            return Ok(Fit::Overflow(format!(
                "a one-pixel tile needs {iterations} span-generator iterations and up to \
                 {most_spans} spans; the SRF holds {tickets} iterations and {} spans",
                span_room - sentinels
            )));
        }
        let spans_out = [ss.pos, ss.end, ss.tri].map(|id| p.whole(id));
        let call = h.call(
            k.spangen,
            &[
                ("halves", halves),
                ("tickets", p.first(s.tickets, iterations * c)),
                ("pos", spans_out[0]),
                ("end", spans_out[1]),
                ("tri", spans_out[2]),
            ],
        )?;
        h.wait(call)?;
        let spans = h.written(call, "pos")? - sentinels;
        // Every span, and the sentinels up to the rows `spanrast` reads.
        let len = (spans.div_ceil(c) + SENTINEL_ROWS) * c;
        h.call(
            k.spanpack,
            &[
                ("pos", p.first(ss.pos, len)),
                ("end", p.first(ss.end, len)),
                ("spans", p.first(ss.spans, len)),
                ("counts", p.whole(ss.pack_counts)),
            ],
        )?;
        let span_edges = p.first(ss.span_edges, len);
        h.gather(
            m.edges,
            p.first(ss.tri, len),
            m.edge_records,
            Layout::records(EDGE_WORDS),
            len,
            span_edges,
        );
        let counts = h.read_back(p.whole(ss.pack_counts))?;
        let iterations = counts[0] as usize;
        let candidates: usize = counts[c..].iter().map(|&n| n as usize).sum();
        let capacity = p.capacity(s.addr);
        if candidates + c > capacity || iterations > tickets {
            return Ok(Fit::Overflow(format!(
                "a one-pixel tile needs {iterations} span-rasterizer iterations and \
                 {candidates} fragments; the SRF holds {tickets} iterations and {capacity} \
                 fragments"
            )));
        }
        let mut bindings = vec![
            ("spans", p.first(ss.spans, len)),
            ("edges", span_edges),
            ("tickets", p.first(s.tickets, iterations * c)),
        ];
        bindings.extend(self.fragment_outputs());
        let call = h.call(k.spanrast, &bindings)?;
        self.composite_rasterized(h, call, candidates + c)?;
        Ok(Fit::Done)
    }

    /// Scissor tile `tile` through the hardware rasterizer, then the composite, unless
    /// the tile's fragments overflowed the rasterizer's output streams.
    fn tile_in_hardware(&mut self, h: &mut StreamHost, tile: [i32; 4]) -> Result<Fit, RenderError> {
        let (p, s) = (self.plan, self.s);
        let u = s.unit.as_ref().expect("a hardware rasterizer's streams");
        let c = h.clusters();
        let tris = self.batch;
        let cap = [s.addr, u.z, u.prim, u.values]
            .into_iter()
            .map(|id| p.capacity(id))
            .min()
            .unwrap_or(0);
        let v = self.varyings;
        let job = RasterJob {
            inputs: [
                p.first(s.window, tris),
                p.first(s.det, tris),
                p.first(s.attribs, tris),
            ],
            outputs: [s.addr, u.z, u.prim, u.values].map(|id| p.first(id, cap)),
            state: RasterState {
                width: self.scene.width,
                trash: self.scene.width * self.scene.height,
                tile,
                prim_base: self.first_prim,
                extras: v.extras,
                derivatives: v.derivatives,
                fragment_program: v.fragment_program(),
                reference_depth: v.reference_depth,
                newton_steps: self.scene.pipeline.newton_raphson,
            },
        };
        let call = h.rasterize(job)?;
        let result = h.raster_result(call)?;
        if result.overflowed {
            return Ok(Fit::Overflow(format!(
                "a one-pixel tile has more fragments than the rasterizer's output streams \
                 hold ({cap})"
            )));
        }
        let real = result.fragments;
        let words = 3 + p.get(u.values).layout.record_words;
        self.max_fragment_words = self.max_fragment_words.max(words * (real + c));
        self.count_fragments(real);
        let total = real.div_ceil(c) * c;
        for start in (0..total).step_by(s.composite.chunk) {
            let len = s.composite.chunk.min(total - start);
            let values = p.slice(u.values, start, len);
            let colour = match &s.texturing {
                Some(t) => {
                    let [_, colour, _, _] = s.composite.zcap[0];
                    self.fragment_program(h, t, len, values, p.first(colour, len))?;
                    (colour, 0)
                }
                None => (u.values, start),
            };
            self.composite(
                h,
                [(u.z, start), colour, (s.addr, start), (u.prim, start)],
                len,
            )?;
        }
        Ok(Fit::Done)
    }

    /// Counts `real` fragments of the batch.
    fn count_fragments(&mut self, real: usize) {
        self.stats.fragments += real as u64;
        if let Some(fp) = &self.fragment_programs[self.current_object] {
            self.stats.texel_fetches += (real * fp.texel_fetches()) as u64;
        }
        if let Some(row) = self.stats.batch_rows.last_mut() {
            row.fragments += real as u64;
        }
    }

    fn rasterize(
        &mut self,
        h: &mut StreamHost,
        xyrast: KernelId,
        rows: usize,
        bound: usize,
    ) -> Result<(), RenderError> {
        let (p, s) = (self.plan, self.s);
        let c = h.clusters();
        let mut bindings = vec![
            ("raster", p.first(s.raster, self.batch)),
            ("tickets", p.first(s.tickets, rows * c)),
        ];
        bindings.extend(self.fragment_outputs());
        let call = h.call(xyrast, &bindings)?;
        self.composite_rasterized(h, call, bound)
    }

    /// The rasterizer kernels' fragment outputs, each over its whole stream.
    fn fragment_outputs(&self) -> [(&'static str, StreamBinding); 5] {
        let (p, s) = (self.plan, self.s);
        let cap = p.capacity(s.addr);
        let frags = |id| p.first(id, cap);
        let kf = s
            .kernel_fragments
            .as_ref()
            .expect("the rasterizer kernels' streams");
        [
            ("addr", frags(s.addr)),
            ("tri", frags(kf.tri)),
            ("e0", frags(kf.edges[0])),
            ("e1", frags(kf.edges[1])),
            ("e2", frags(kf.edges[2])),
        ]
    }

    /// Interpolates and composites the fragments rasterizer kernel call `call` writes
    /// (at most `bound`, the row of nulls included).
    fn composite_rasterized(
        &mut self,
        h: &mut StreamHost,
        call: Call,
        bound: usize,
    ) -> Result<(), RenderError> {
        let s = self.s;
        let c = h.clusters();
        h.wait(call)?;
        // The real fragments, then the row of nulls.
        let real = h.written(call, "addr")? - c;
        debug_assert!(real + c <= bound);
        self.max_fragment_words = self.max_fragment_words.max(5 * (real + c));
        // Whole rows: every real fragment and the nulls that fill its last row; the rest
        // of the nulls are not composited.
        let total = real.div_ceil(c) * c;
        self.count_fragments(real);
        let chunk = s.composite.chunk;
        let chunks: Vec<(usize, usize)> = (0..total)
            .step_by(chunk)
            .map(|start| (start, chunk.min(total - start)))
            .collect();
        if let Some(&(start, len)) = chunks.first() {
            self.gather_interp(h, start, len, 0);
        }
        for (i, &(start, len)) in chunks.iter().enumerate() {
            // The next chunk's records are gathered while this one is composited.
            if let Some(&(next, next_len)) = chunks.get(i + 1) {
                self.gather_interp(h, next, next_len, (i + 1) % 2);
            }
            self.fragments(h, start, len, i % 2)?;
        }
        Ok(())
    }

    /// Queues the gather of the interpolation records of fragments `start..start + len`
    /// (by triangle index) into buffer `buffer`.
    fn gather_interp(&self, h: &mut StreamHost, start: usize, len: usize, buffer: usize) {
        let (p, s, m) = (self.plan, self.s, self.m);
        let kf = s.kernel_fragments.as_ref().expect("xyrast's streams");
        let tri = p.slice(kf.tri, start, len);
        let to = p.first(s.gathered[buffer], len);
        h.gather(
            m.interp,
            tri,
            m.interp_records,
            Layout::records(self.varyings.interp_words()),
            len,
            to,
        );
    }

    /// Interpolates and composites fragments `start..start + len` of the xyrast output,
    /// their interpolation records gathered into buffer `buffer`.
    fn fragments(
        &mut self,
        h: &mut StreamHost,
        start: usize,
        len: usize,
        buffer: usize,
    ) -> Result<(), RenderError> {
        let (p, s) = (self.plan, self.s);
        let kf = s.kernel_fragments.as_ref().expect("xyrast's streams");
        let edge = |i: usize| p.slice(kf.edges[i], start, len);
        let [z, colour, _, prim] = s.composite.zcap[0];
        let interpolated = match &s.texturing {
            Some(t) => ("varyings", p.first(t.varyings, len)),
            None => ("colour", p.first(colour, len)),
        };
        h.call(
            self.k.irast,
            &[
                ("e0", edge(0)),
                ("e1", edge(1)),
                ("e2", edge(2)),
                ("interp", p.first(s.gathered[buffer], len)),
                ("z", p.first(z, len)),
                interpolated,
                ("prim", p.first(prim, len)),
            ],
        )?;
        if let Some(t) = &s.texturing {
            let varyings = p.first(t.varyings, len);
            self.fragment_program(h, t, len, varyings, p.first(colour, len))?;
        }
        self.composite(h, [(z, 0), (colour, 0), (s.addr, start), (prim, 0)], len)
    }

    /// Composites `len` fragments, their depth, colour, address and primitive in
    /// `current` (each a stream and its first record), in rounds until none is held back.
    fn composite(
        &mut self,
        h: &mut StreamHost,
        current: [(StreamId, usize); 4],
        len: usize,
    ) -> Result<(), RenderError> {
        let (p, s, m) = (self.plan, self.s, self.m);
        let composite = Composite {
            k: &self.k.composite(),
            plan: p,
            s: &s.composite,
            framebuffer: m.framebuffer,
            pixels: m.pixels,
            merge_min_conflicts: self.merge_min_conflicts,
        };
        let mut counts = CompositeCounts::default();
        let done = composite.run(h, current, len, &mut counts);
        self.stats.composite_rounds += counts.rounds;
        if let Some(row) = self.stats.batch_rows.last_mut() {
            row.composite_rounds += counts.rounds;
        }
        self.stats.merge_rounds += counts.merge_rounds;
        self.stats.merged_fragments += counts.merged_fragments;
        done
    }

    /// The fragment program of the batch's object on `len` fragments (`varyings`): its
    /// `texaddr`, the texel gathers (each texel over its address), `filter8` for mipmapped
    /// units and `fragment`, which writes the packed colours to `colour`.
    fn fragment_program(
        &mut self,
        h: &mut StreamHost,
        t: &TexturingStreams,
        len: usize,
        varyings: StreamBinding,
        colour: StreamBinding,
    ) -> Result<(), RenderError> {
        let (p, m) = (self.plan, self.m);
        let object = self.current_object;
        let FragmentKernels {
            texaddr,
            dependent,
            colour: fragment,
        } = self.k.fragment[object];
        let fp = self.fragment_programs[object]
            .as_ref()
            .expect("a frame with fragment programs has one per object");
        if let Some(envaddr) = dependent {
            return self.dependent_read(
                h,
                t,
                (len, varyings),
                (texaddr, envaddr, fragment),
                colour,
            );
        }
        let per_fragment = |id: Option<StreamId>, words: usize| {
            id.filter(|_| words > 0).map(|id| p.words(id, len * words))
        };
        let addr = per_fragment(t.addr, fp.direct_fetches());
        let weights = per_fragment(t.weights, fp.direct_weights());
        let mipmapped = fp.mipmapped();
        let addr8 = per_fragment(t.addr8, texture::FILTER8_TEXELS * mipmapped);
        let weights5 = per_fragment(t.weights5, texture::FILTER8_WEIGHTS * mipmapped);
        let filtered = per_fragment(t.filtered, mipmapped);
        if let Some(texaddr) = texaddr {
            let mut bindings = vec![("varyings", varyings)];
            bindings.extend(addr.map(|b| ("addr", b)));
            bindings.extend(weights.map(|b| ("weights", b)));
            bindings.extend(addr8.map(|b| ("addr8", b)));
            bindings.extend(weights5.map(|b| ("weights5", b)));
            h.call(texaddr, &bindings)?;
            for (index, words) in [
                (addr, fp.direct_fetches()),
                (addr8, texture::FILTER8_TEXELS * mipmapped),
            ] {
                if let Some(index) = index {
                    h.gather(
                        m.textures,
                        index,
                        m.texture_words,
                        Layout::words(),
                        len * words,
                        index,
                    );
                    self.stats.texel_words += (len * words) as u64;
                }
            }
        }
        if let (Some(texels), Some(w), Some(out)) = (addr8, weights5, filtered) {
            let filter8 = self.k.filter8.expect("filter8 for mipmapped textures");
            h.call(
                filter8,
                &[("texels", texels), ("weights", w), ("filtered", out)],
            )?;
        }
        let mut bindings = vec![("varyings", varyings)];
        if let (Some(ms), Some(noise)) = (t.marble.as_ref(), fp.marble) {
            let c = h.clusters();
            if noise.uses_table() {
                let perm = ms
                    .perm
                    .expect("a Perlin marble frame has the table's stream");
                bindings.push(("perm", p.first(perm, turbulence::TABLE * c)));
            }
            bindings.push((PARAMS, p.first(ms.params, turbulence::SCALAR_PARAMS * c)));
        }
        bindings.extend(addr.map(|b| ("texels", b)));
        bindings.extend(weights.map(|b| ("weights", b)));
        bindings.extend(filtered.map(|b| ("filtered", b)));
        bindings.push(("colour", colour));
        h.call(fragment, &bindings)?;
        Ok(())
    }

    /// A fragment program with a dependent read (`bump_env`) on `len` fragments: the
    /// depth-2 kernel's addresses, their texels gathered over them, the depth-1 kernel's
    /// addresses from those texels, the dependent texels gathered over them, and the
    /// depth-0 kernel, which writes the packed colours to `colour`.
    fn dependent_read(
        &mut self,
        h: &mut StreamHost,
        t: &TexturingStreams,
        (len, varyings): (usize, StreamBinding),
        (first, second, last): (Option<KernelId>, KernelId, KernelId),
        colour: StreamBinding,
    ) -> Result<(), RenderError> {
        let (p, m) = (self.plan, self.m);
        let fp = self.fragment_programs[self.current_object]
            .as_ref()
            .expect("a frame with fragment programs has one per object");
        let first = first.expect("a dependent read's first addresses");
        let (direct, dependent) = (fp.direct_fetches(), fp.dependent_fetches());
        let texels = p.words(t.addr.expect("a texel address stream"), len * direct);
        let dependent_texels = p.words(t.dependent.expect("a dependent stream"), len * dependent);
        let gather = |h: &mut StreamHost, stats: &mut FrameStats, index: StreamBinding, words| {
            h.gather(
                m.textures,
                index,
                m.texture_words,
                Layout::words(),
                words,
                index,
            );
            stats.texel_words += words as u64;
        };
        h.call(first, &[("varyings", varyings), ("addr", texels)])?;
        gather(h, self.stats, texels, len * direct);
        h.call(
            second,
            &[
                ("varyings", varyings),
                ("texels", texels),
                ("addr", dependent_texels),
            ],
        )?;
        gather(h, self.stats, dependent_texels, len * dependent);
        h.call(
            last,
            &[
                ("varyings", varyings),
                ("texels", dependent_texels),
                ("colour", colour),
            ],
        )?;
        Ok(())
    }

    fn finish_batch(&mut self, h: &mut StreamHost) {
        let now = h.cycles();
        if let Some(row) = self.stats.batch_rows.last_mut() {
            row.cycles = now.saturating_sub(self.last_cycles);
            row.srf_words = self.plan.peak_words();
            row.srf_fragment_words = self.max_fragment_words;
        }
        self.last_cycles = now;
        self.max_fragment_words = 0;
        self.stats.batches += 1;
    }
}

/// The composite kernels of a frame (the OpenGL pipeline's, which the Reyes pipeline
/// shares).
#[derive(Clone, Copy)]
pub(crate) struct CompositeKernels {
    pub hash: KernelId,
    pub zcompare: KernelId,
    pub recycle_zc: KernelId,
    pub recycle_ap: KernelId,
    /// `sort32` and `mergefrag`, when the depth test allows merging.
    pub merge: Option<(KernelId, KernelId)>,
}

/// What a chunk's composite counted.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct CompositeCounts {
    pub rounds: u64,
    pub merge_rounds: u64,
    pub merged_fragments: u64,
}

/// The composite of chunks of fragments against a framebuffer in DRAM.
pub(crate) struct Composite<'a> {
    pub k: &'a CompositeKernels,
    pub plan: &'a SrfPlan,
    pub s: &'a CompositeStreams,
    pub framebuffer: Buffer,
    /// Window pixels and the trash pixel: the bound of gathers and scatters by pixel.
    pub pixels: u64,
    pub merge_min_conflicts: Option<usize>,
}

impl Composite<'_> {
    /// Composites `len` fragments (whole rows, at most a chunk) whose `z`, `colour`, `addr`
    /// and `prim` are the records from the given first record of the given streams, in
    /// rounds: the pixels are gathered while `hash` marks fragments that share a pixel with
    /// an earlier one, `zcompare` applies the depth test to the others, the pixels that
    /// passed are scattered, and the held-back fragments are recycled (`compact_recycle`),
    /// or sorted and merged (`sort32`, `mergefrag`) when many are, until none is left.
    pub fn run(
        &self,
        h: &mut StreamHost,
        first: [(StreamId, usize); 4],
        len: usize,
        counts: &mut CompositeCounts,
    ) -> Result<(), RenderError> {
        // The current round's streams: (stream, first record).
        let mut current = first;
        let (p, s, k) = (self.plan, self.s, self.k);
        let c = h.clusters();
        let mut len = len;
        let mut set = 1;
        // Whether a merge of this chunk dropped fragments, or dropped none.
        let mut stacked = false;
        let mut fruitless = false;
        let by_pixel = Layout::records(PIXEL_WORDS);
        loop {
            counts.rounds += 1;
            let view = |(id, first): (StreamId, usize), n: usize| p.slice(id, first, n);
            let [zs, cs, addr, ps] = current;
            let pixel = p.first(s.pixel, len);
            // The pixels are gathered while `hash` looks for conflicts.
            h.gather(
                self.framebuffer,
                view(addr, len),
                self.pixels,
                by_pixel,
                len,
                pixel,
            );
            let conflict = p.first(s.conflict, len + GROUP);
            let conflicts = p.whole(s.conflicts);
            h.call(
                k.hash,
                &[
                    ("addr", view(addr, len)),
                    ("conflict", conflict),
                    ("count", conflicts),
                ],
            )?;
            let (new_pixel, newaddr) = (p.first(s.new_pixel, len), p.first(s.newaddr, len));
            h.call(
                k.zcompare,
                &[
                    ("z", view(zs, len)),
                    ("colour", view(cs, len)),
                    ("addr", view(addr, len)),
                    ("prim", view(ps, len)),
                    ("pixel", pixel),
                    ("conflict", p.first(s.conflict, len)),
                    ("new_pixel", new_pixel),
                    ("newaddr", newaddr),
                ],
            )?;
            h.scatter(
                new_pixel,
                newaddr,
                self.pixels,
                by_pixel,
                len,
                self.framebuffer,
            );
            // The zcompare and the scatter are queued; the host needs only the count.
            let held = h.read_back(p.first(s.conflicts, 1))?[0] as usize;
            if held == 0 {
                return Ok(());
            }
            let next = s.zcap[set];
            let cap = s.chunk.next_multiple_of(GROUP) + c;
            let out = |i: usize| p.first(next[i], cap);
            // Merge on many conflicts, and after a merge of this chunk that found a pixel's
            // fragments together, on any that could merge; not again after a merge of this
            // chunk that dropped nothing.
            let merge = k.merge.filter(|_| {
                !fruitless
                    && self
                        .merge_min_conflicts
                        .is_some_and(|m| held >= m || (stacked && held >= 2))
            });
            if let Some((sort32, mergefrag)) = merge {
                // Sort the conflicting fragments by address in groups of 32 and keep one
                // per address: whole groups, `hash`'s rows of zeros after its flags.
                counts.merge_rounds += 1;
                let groups = len.next_multiple_of(GROUP);
                let sorted = s.sorted.map(|id| p.first(id, groups));
                h.call(
                    sort32,
                    &[
                        ("conflict", p.first(s.conflict, groups)),
                        ("addr", view(addr, groups)),
                        ("z", view(zs, groups)),
                        ("prim", view(ps, groups)),
                        ("key", sorted[0]),
                        ("z_sorted", sorted[1]),
                        ("prim_sorted", sorted[2]),
                    ],
                )?;
                let merged = h.call(
                    mergefrag,
                    &[
                        ("key", sorted[0]),
                        ("z_sorted", sorted[1]),
                        ("prim_sorted", sorted[2]),
                        ("colour", view(cs, groups)),
                        ("z", out(0)),
                        ("colour_kept", out(1)),
                        ("addr", out(2)),
                        ("prim_kept", out(3)),
                    ],
                )?;
                // The next round needs the survivors' count.
                h.wait(merged)?;
                let written = h.written(merged, "z")?;
                let dropped = held + c - written;
                counts.merged_fragments += dropped as u64;
                stacked |= dropped > 0;
                fruitless = dropped == 0;
                len = written / c * c;
            } else {
                h.call(
                    k.recycle_zc,
                    &[
                        ("conflict", p.first(s.conflict, len)),
                        ("a", view(zs, len)),
                        ("b", view(cs, len)),
                        ("a_kept", out(0)),
                        ("b_kept", out(1)),
                    ],
                )?;
                h.call(
                    k.recycle_ap,
                    &[
                        ("conflict", p.first(s.conflict, len)),
                        ("a", view(addr, len)),
                        ("b", view(ps, len)),
                        ("a_kept", out(2)),
                        ("b_kept", out(3)),
                    ],
                )?;
                // The conflicting fragments, then `compact_recycle`'s row of nulls: whole
                // rows.
                len = (held + c) / c * c;
            }
            current = next.map(|id| (id, 0));
            set = if set == 1 { 2 } else { 1 };
        }
    }
}

/// What the DRAM channels did over the run, channel 0 first (whatever order the design
/// holds its modules in: the attribution's ties are broken by channel order).
pub(crate) fn dram_activity<'a>(sim: &'a Sim, desc: &MachineDesc) -> DramActivity<'a> {
    let mut channels: Vec<&DramChannel> = sim.modules_of::<DramChannel>().collect();
    channels.sort_by_key(|c| c.index());
    DramActivity {
        channels: channels
            .into_iter()
            .map(DramChannel::activity_log)
            .collect(),
        dram_per_core: desc.clocks.dram_mhz as f64 / desc.clocks.core_mhz as f64,
    }
}

fn finish_stats(
    s: &mut FrameStats,
    host: &StreamHost,
    desc: &MachineDesc,
    pp: &PipelinePlan,
    frame: Range<u64>,
) -> Vec<attribution::Segment> {
    let sim = host.sim();
    let p = processor::processor(sim);
    // Every frame cycle in one category; each batch's window follows the last one's.
    let dram = dram_activity(sim, desc);
    let segments = attribution::attribute(p.controller().records(), &dram, frame.clone());
    s.attribution = Attribution::of(&segments, frame.clone());
    s.waiting_on = WaitingOn::of(&segments, frame.clone());
    let mut batch_start = frame.start;
    for row in &mut s.batch_rows {
        let window = batch_start..batch_start + row.cycles;
        row.attribution = Attribution::of(&segments, window.clone());
        row.waiting_on = WaitingOn::of(&segments, window);
        batch_start += row.cycles;
    }
    let cycles = s.cycles.max(1);
    let mhz = desc.clocks.core_mhz as f64;
    let seconds = cycles as f64 / (mhz * 1e6);
    s.core_mhz = mhz;
    s.frames_per_second = 1.0 / seconds.max(1e-12);
    s.vertices_per_second = s.vertices as f64 / seconds.max(1e-12);
    s.fragments_per_second = s.fragments as f64 / seconds.max(1e-12);
    // Each program by the name the pipeline registered it under (`compact_recycle:z,colour`,
    // `perbegin:vertex_lit3_s16`): unique, and the name `imagine kernel show` takes.
    let names: Vec<String> = p
        .controller()
        .programs()
        .iter()
        .enumerate()
        .map(|(i, pr)| {
            host.kernels
                .name_of_program(i)
                .map_or_else(|| pr.name.clone(), String::from)
        })
        .collect();
    let mut shares: Vec<KernelShare> = Vec::new();
    let (mut busy, mut stalls, mut ops, mut rasterizing) = (0, 0, 0, 0);
    let tags = host.batch_tags();
    let mut dram_words = 0u64;
    for (id, r) in p.controller().records().iter().enumerate() {
        let batch = tags.get(id).copied().flatten();
        match (&r.instr, &r.kernel_stats) {
            (StreamInstr::Kernel { program, .. }, Some(st)) => {
                let st: &KernelStats = st;
                let name = &names[*program];
                if name == "clear" {
                    continue;
                }
                let o: u64 = st.fu_ops.iter().sum::<u64>() * desc.cluster.count as u64;
                let share = KernelShare::of(&mut shares, name);
                share.calls += 1;
                share.cycles += st.cycles;
                share.stall_cycles += st.stall_cycles;
                share.ops += o;
                busy += st.cycles;
                stalls += st.stall_cycles;
                ops += o;
                if let Some(row) =
                    batch.and_then(|b| s.batch_rows.iter_mut().find(|row| row.batch == b))
                {
                    row.kernel_cycles += st.cycles;
                }
            }
            (StreamInstr::Rasterize(_), _) => {
                // A hardware kernel: in the breakdown by its time from issue to
                // completion, and apart from the clusters' occupancy.
                let (Some(i), Some(c)) = (r.issued, r.completed) else {
                    continue;
                };
                let name = imagine_units::stream_controller::RASTERIZER_KERNEL;
                let share = KernelShare::of(&mut shares, name);
                share.calls += 1;
                share.cycles += c - i;
                rasterizing += c - i;
            }
            (StreamInstr::Memory(op), _) if batch.is_some() => {
                dram_words += op.words() as u64;
                if let Some(row) = s.batch_rows.iter_mut().find(|row| Some(row.batch) == batch) {
                    row.dram_words += op.words() as u64;
                }
            }
            _ => {}
        }
    }
    s.kernels = shares;
    s.ops_per_cycle = ops as f64 / cycles as f64;
    s.cluster_occupancy = busy as f64 / cycles as f64;
    s.cluster_occupancy_without_stalls = busy.saturating_sub(stalls) as f64 / cycles as f64;
    s.rasterizer_occupancy = desc
        .rasterizer
        .as_ref()
        .map(|_| rasterizing as f64 / cycles as f64);
    let dram: ReplayReport = imagine_units::dram::replay::report_of(
        sim,
        imagine_units::dram::Policy::parse(&desc.memory.policy)
            .unwrap_or(imagine_units::dram::Policy::FirstReady),
        &imagine_units::dram::DramParams::of(desc),
    );
    s.texture_cache = p.texture_cache().map(|c| TextureCacheReport {
        counts: c.stats().clone(),
        hit_rate: c.stats().hit_rate(),
    });
    // Words the texture cache served never reached DRAM; its line fills did. (Texture
    // gathers run only inside the frame, so the run's counts are the frame's.)
    let (served, filled) = s
        .texture_cache
        .as_ref()
        .map_or((0, 0), |t| (t.counts.hits, t.counts.fill_words));
    s.dram_bytes = 4 * (dram_words - served + filled);
    s.dram_gbs = s.dram_bytes as f64 / seconds.max(1e-12) / 1e9;
    s.dram_row_hit_rate = dram.row_hit_rate;
    let srf = p.machine().srf().stats();
    s.srf_words_per_cycle = srf.words_per_cycle();
    let (lrf_read, lrf_written) = p.machine().lrf_words_moved();
    s.lrf_reads_per_cycle = lrf_read as f64 / cycles as f64;
    s.lrf_writes_per_cycle = lrf_written as f64 / cycles as f64;
    // Table 5.1's counting: a vertex's input words; a fragment's framebuffer words read
    // and written.
    // A vertex texture's texel words count per vertex (the thesis's VERONA row does).
    s.bytes_per_vertex = 4.0 * (pp.words_per_vertex() + pp.vertex_texel_words()) as f64;
    s.texel_bytes_per_fragment = 4.0 * s.texel_fetches as f64 / s.fragments.max(1) as f64;
    s.bytes_per_fragment = (4 * 2 * PIXEL_WORDS) as f64 + s.texel_bytes_per_fragment;
    s.specialisation = Specialisation {
        specialised: pp.specialised(),
        kernels_built: host.kernels.built().into_iter().map(String::from).collect(),
        kernels_not_reached: host
            .kernels
            .not_built()
            .into_iter()
            .map(String::from)
            .collect(),
        left_out: pp.left_out(),
        interpolants: pp.interpolants(),
        words_per_vertex: pp.words_per_vertex(),
        words_per_fragment: 4,
    };
    // Table 5.3's `i` counts depth with the interpolants.
    s.srf_model = SrfModelReport::of(
        &s.batch_rows,
        1 + pp.interpolants().len(),
        pp.varyings.interp_words(),
        s.srf_peak_words,
    );
    segments
}
