//! What a frame reports (ARCHITECTURE §7): cycles by phase, rates, kernels, the memory
//! system, the pipeline the scene was given and the SRF plan, per frame and per batch.

use imagine_units::memory::TextureCacheStats;
use serde::Serialize;

use super::srf_model::SrfModelReport;
use crate::stream::attribution::{Attribution, WaitingOn};
use crate::stream::srf::PlanRow;

/// One kernel's share of the frame.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct KernelShare {
    pub kernel: String,
    pub calls: u64,
    pub cycles: u64,
    pub stall_cycles: u64,
    pub ops: u64,
}

impl KernelShare {
    /// The share of kernel `name` in `shares`, added (empty) at the end if it has none.
    pub fn of<'a>(shares: &'a mut Vec<KernelShare>, name: &str) -> &'a mut KernelShare {
        let i = match shares.iter().position(|sh| sh.kernel == name) {
            Some(i) => i,
            None => {
                shares.push(KernelShare {
                    kernel: name.into(),
                    ..KernelShare::default()
                });
                shares.len() - 1
            }
        };
        &mut shares[i]
    }

    /// Arithmetic ops per cycle of its calls, across all clusters.
    pub fn ops_per_cycle(&self) -> f64 {
        self.ops as f64 / self.cycles.max(1) as f64
    }
}

/// The pipeline built for the scene (ARCHITECTURE §8: leave out what a scene does not
/// need).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Specialisation {
    /// Whether the pipeline was specialised (`false`: `--no-specialize`).
    pub specialised: bool,
    /// Kernels compiled for the frame.
    pub kernels_built: Vec<String>,
    /// Kernels the pipeline could call but the frame never reached (not compiled).
    pub kernels_not_reached: Vec<String>,
    /// Features of the general pipeline this scene's pipeline leaves out.
    pub left_out: Vec<String>,
    /// Interpolated words per fragment, by name.
    pub interpolants: Vec<String>,
    /// Words a vertex record carries from memory (the largest over the scene's objects).
    pub words_per_vertex: usize,
    /// Words a fragment carries through the composite (z, colour, address, primitive).
    pub words_per_fragment: usize,
}

/// Host-side phases, in core cycles (the frame itself is [`FrameStats::cycles`]).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Phases {
    /// The scene's inputs (vertex records, indices, OpenGL state) written into DRAM over
    /// the host interface. Not frame time (the thesis's inputs start in memory, §5.1).
    pub load_cycles: u64,
    /// The framebuffer cleared by the machine (`clear` kernel and stores).
    pub clear_cycles: u64,
    /// The frame plus the clear.
    pub frame_plus_clear_cycles: u64,
    /// The colour buffer read back to the host over the host interface.
    pub readback_cycles: u64,
}

/// One batch (`--stats-csv`).
#[derive(Clone, Debug, Default, Serialize)]
pub struct BatchRow {
    pub batch: usize,
    pub object: String,
    pub triangles: usize,
    /// Vertices shaded (each vertex of the batch once).
    pub vertices: usize,
    /// Core cycles from the end of the previous batch's body to the end of this one's.
    pub cycles: u64,
    /// Cycles of the kernels queued for this batch.
    pub kernel_cycles: u64,
    pub fragments: u64,
    /// Scissor-tile splits of this batch (its fragments overflowed the SRF, so the screen
    /// was cut into tiles rasterized one at a time).
    pub tile_splits: u64,
    pub composite_rounds: u64,
    /// Words the batch's memory operations moved.
    pub dram_words: u64,
    /// SRF words the plan gives the batch's streams (all phases).
    pub srf_words: usize,
    /// SRF words holding fragments at the batch's largest rasterization pass.
    pub srf_fragment_words: usize,
    /// The batch's `cycles`, each in one category (they sum to `cycles`).
    pub attribution: Attribution,
    /// What the batch's waiting cycles were spent on.
    pub waiting_on: WaitingOn,
}

/// What the texture cache did (thesis §6.5): its counters and hit rate.
#[derive(Clone, Debug, Default, Serialize)]
pub struct TextureCacheReport {
    #[serde(flatten)]
    pub counts: TextureCacheStats,
    pub hit_rate: f64,
}

/// Statistics of a frame.
#[derive(Clone, Debug, Default, Serialize)]
pub struct FrameStats {
    pub scene: String,
    pub machine: String,
    pub width: u32,
    pub height: u32,
    pub core_mhz: f64,
    /// Core cycles of the frame: from the first vertex load to the last pixel written
    /// (inputs in DRAM, framebuffer cleared).
    pub cycles: u64,
    pub frames_per_second: f64,
    pub phases: Phases,
    pub triangles: u64,
    /// Vertices shaded (a shared vertex once per batch that uses it).
    pub vertices: u64,
    pub fragments: u64,
    pub vertices_per_second: f64,
    pub fragments_per_second: f64,
    /// Input bytes per vertex and framebuffer bytes per fragment, counted as the thesis's
    /// Table 5.1 counts them (vertex record and index words; depth, colour and primitive
    /// words read and written).
    pub bytes_per_vertex: f64,
    pub bytes_per_fragment: f64,
    /// Texel bytes the fragment programs fetch per fragment (4 per texel word; a
    /// mipmapped lookup fetches 8), over the frame's fragments; included in
    /// `bytes_per_fragment`.
    pub texel_bytes_per_fragment: f64,
    /// Texel words gathered in the frame, null fragments of a chunk's last row included.
    pub texel_words: u64,
    /// Texel words the frame's real fragments asked for.
    pub texel_fetches: u64,
    /// Texel words the vertex textures fetched (`bump_env`: 4 per shaded vertex, padding
    /// vertices of a batch's last row included); `bytes_per_vertex` counts their 16 bytes
    /// per vertex.
    pub vertex_texel_fetches: u64,
    /// Arithmetic ops per core cycle over the frame, all clusters.
    pub ops_per_cycle: f64,
    /// Share of the frame's cycles a kernel was running, and running without a stall.
    pub cluster_occupancy: f64,
    pub cluster_occupancy_without_stalls: f64,
    /// Share of the frame's cycles the hardware rasterizer was running a call (machines
    /// with one; its calls are `hwrast` in `kernels`, and not cluster time).
    pub rasterizer_occupancy: Option<f64>,
    /// Every frame cycle in one category (kernels running, dispatch, waiting on a stream
    /// operation by kind, issue, host, drain; see `stream::attribution`); they sum to
    /// `cycles`.
    pub attribution: Attribution,
    /// What the waiting cycles of `attribution` were spent on (scoreboard, DRAM bandwidth,
    /// bank conflicts, memory latency, the unit at work); they sum to its waiting cycles.
    pub waiting_on: WaitingOn,
    /// Per kernel called in the frame (the clear apart), by the name the pipeline
    /// registered it under (`perbegin:vertex_lit3_s16`, `compact_recycle:z,colour`): the
    /// names of [`Specialisation::kernels_built`] and of `imagine kernel show`.
    pub kernels: Vec<KernelShare>,
    pub specialisation: Specialisation,
    pub batch_triangles: usize,
    pub batches: u64,
    /// Scissor splits made because a batch's fragments overflowed the SRF.
    pub tile_splits: u64,
    pub composite_rounds: u64,
    /// Composite rounds whose conflicting fragments were sorted and merged.
    pub merge_rounds: u64,
    /// Conflicting fragments `mergefrag` dropped.
    pub merged_fragments: u64,
    /// DRAM bytes the frame's memory operations moved (less the words the texture cache
    /// served, plus its line fills), and per second of the frame.
    pub dram_bytes: u64,
    pub dram_gbs: f64,
    /// Row hits over every DRAM access of the run (load and read-back included).
    pub dram_row_hit_rate: f64,
    /// The texture cache's counters over the run, on a machine that has one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub texture_cache: Option<TextureCacheReport>,
    pub srf_words_per_cycle: f64,
    pub lrf_reads_per_cycle: f64,
    pub lrf_writes_per_cycle: f64,
    /// The SRF plan of a batch, and the most words it holds at once.
    pub srf_plan: Vec<PlanRow>,
    pub srf_peak_words: usize,
    /// Table 5.3's model of the rasterizers' peak SRF words on this frame's batches, next
    /// to the fragment words the frame held.
    pub srf_model: SrfModelReport,
    /// Host time: all of it, compiling, and simulating.
    pub host_seconds: f64,
    pub compile_seconds: f64,
    pub simulate_seconds: f64,
    /// Kernels compiled for the frame, and how many of them came from the compile cache.
    pub kernel_programs: usize,
    pub kernels_from_cache: usize,
    /// Simulated core cycles (all phases) per second of simulation.
    pub simulated_cycles_per_second: f64,
    /// Core cycles (all phases) the simulator jumped over as idle time instead of stepping
    /// them: how the host simulated, not what the machine did.
    #[serde(skip)]
    pub skipped_cycles: u64,
    #[serde(skip)]
    pub batch_rows: Vec<BatchRow>,
}

impl FrameStats {
    /// The per-batch rows as CSV.
    pub fn batches_csv(&self) -> String {
        let mut out = String::from(
            "batch,object,triangles,vertices,cycles,kernel_cycles,fragments,tile_splits,\
             composite_rounds,dram_words,srf_words,srf_fragment_words",
        );
        for (name, _) in Attribution::default().rows() {
            out += &format!(
                ",{}_cycles",
                name.replace("waiting: ", "waiting_").replace(' ', "_")
            );
        }
        for (name, _) in WaitingOn::default().rows() {
            out += &format!(",waiting_on_{}_cycles", name.replace(' ', "_"));
        }
        out += "\n";
        for r in &self.batch_rows {
            out += &format!(
                "{},{},{},{},{},{},{},{},{},{},{},{}",
                r.batch,
                r.object.replace(',', ";"),
                r.triangles,
                r.vertices,
                r.cycles,
                r.kernel_cycles,
                r.fragments,
                r.tile_splits,
                r.composite_rounds,
                r.dram_words,
                r.srf_words,
                r.srf_fragment_words
            );
            for (_, cycles) in r.attribution.rows().into_iter().chain(r.waiting_on.rows()) {
                out += &format!(",{cycles}");
            }
            out += "\n";
        }
        out
    }
}
