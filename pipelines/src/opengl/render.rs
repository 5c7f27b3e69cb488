//! The host of the OpenGL-like pipeline: it drives the stream processor (stream
//! controller, address generators, clusters, SRF and SDRAM, all clocked) through a frame,
//! batch by batch (ARCHITECTURE §5, §7).
//!
//! Per batch of `B` triangles (`B` a multiple of the cluster count, 64 unless the
//! scratchpads cannot hold that many raster records for `xyrast`): load the vertices
//! (records laid out in cluster rows, in drawing order), run the vertex program,
//! `assemble_clip`, `viewport_cull` and `baryprep`, and store the interpolation records to
//! memory; then for each scissor tile (the whole window unless the batch overflows) run
//! `xyprep` and `xyrast` for as many iterations as `xyprep` counted. Fragments
//! then go through in chunks: gather their interpolation records by triangle index, run
//! `irast`, and composite in rounds — gather the fragments' pixels while `hash` marks
//! the fragments that share a pixel (their stamp key) with an earlier one, run `zcompare`
//! on the others, scatter the pixels that passed, and recycle the conflicting fragments
//! (`compact_recycle`) until none is left. The framebuffer (colour, depth, primitive per
//! pixel) lives in DRAM.
//!
//! **Two batches in flight.** The next batch's vertices are loaded while this one is set
//! up, and its vertex program is queued right after this batch's `xyrast`, so that it runs
//! while the first chunk's interpolation records are gathered (the clusters would
//! otherwise wait for the memory system). The shaded vertices have two SRF sets. Within a
//! batch, the next chunk's records are gathered while the current chunk is composited
//! (two SRF buffers); the gathers and the framebuffer's scatters carry bounds, so the
//! scoreboard knows they touch different memory and lets them overlap.
//!
//! **Spilling.** `xyprep` also counts each cluster's candidate pixels (its boxes' areas),
//! which bound the fragments `xyrast` can write. When they would overflow their SRF region,
//! the host splits the scissor tile in two and runs `xyprep` and `xyrast` once per half,
//! recursively: a triangle larger than the SRF is drawn tile by tile, never dropped.
//!
//! The host waits for the processor where it needs a number the machine computed, and
//! then only for what brings it that number: a count a kernel wrote into the SRF
//! (`xyprep`'s iteration and candidate counts, `hash`'s conflicts) comes back over the
//! host interface (`ReadSrf`, which the scoreboard orders after the kernel), and the length
//! of a conditional output stream is the stream controller's once the kernel completes.
//! Work queued earlier that does not write those words (such as a round's `zcompare` and
//! pixel scatter) goes on meanwhile. Everything else is queued and ordered by the stream
//! controller's scoreboard. Kernel parameters reach the SRF through the host interface too
//! (`WriteSrf`, ordered like any instruction).

use std::time::Instant;

use imagine_hdl::Sim;
use imagine_units::desc::MachineDesc;
use imagine_units::dram::ReplayReport;
use imagine_units::machine::{KernelStats, StreamBinding};
use imagine_units::memory::{MemOp, MemOpKind, Pattern};
use imagine_units::processor::{self, ProcessorOptions, StreamProgram};
use imagine_units::stream_controller::StreamInstr;
use serde::Serialize;

use super::kernels::{
    self, ATTRIB_WORDS, CLIPPED_WORDS, FrameShape, INTERP_WORDS, NULL_DEPTH, PIXEL_WORDS,
    RASTER_WORDS, WINDOW_WORDS,
};
use super::mergefrag::{self, GROUP};
use crate::compile::cache::Outcome;
use crate::compile::{CompileCache, Compiled};
use crate::kernel::Kernel;
use crate::scene::{Scene, Shading};

/// Words per vertex record in memory: position and normal (lit) or colour (unlit).
const VERTEX_WORDS: usize = 6;
/// Words per shaded vertex.
const SHADED_WORDS: usize = 7;
/// The longest a frame may run, in core cycles, before the host gives up.
const MAX_FRAME_CYCLES: u64 = 20_000_000_000;

/// A rendered frame.
#[derive(Clone, Debug)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    /// Packed RGBA8 (red in the low byte), row 0 at the bottom.
    pub pixels: Vec<u32>,
    pub stats: FrameStats,
}

/// One kernel's share of the frame.
#[derive(Clone, Debug, Default, Serialize)]
pub struct KernelShare {
    pub kernel: String,
    pub calls: u64,
    pub cycles: u64,
    pub stall_cycles: u64,
    pub ops: u64,
}

/// Statistics of a frame (ARCHITECTURE §7).
#[derive(Clone, Debug, Default, Serialize)]
pub struct FrameStats {
    pub scene: String,
    pub machine: String,
    pub width: u32,
    pub height: u32,
    pub core_mhz: f64,
    pub cycles: u64,
    pub frames_per_second: f64,
    pub triangles: u64,
    pub vertices: u64,
    pub fragments: u64,
    pub vertices_per_second: f64,
    pub fragments_per_second: f64,
    /// Arithmetic ops per core cycle over the frame, all clusters.
    pub ops_per_cycle: f64,
    /// Share of the frame's cycles a kernel was running (with and without its stalls).
    pub cluster_occupancy: f64,
    pub cluster_occupancy_without_stalls: f64,
    pub kernels: Vec<KernelShare>,
    pub batch_triangles: usize,
    pub batches: u64,
    /// Scissor splits made because a batch's fragments overflowed the SRF.
    pub spills: u64,
    pub composite_rounds: u64,
    /// Composite rounds whose conflicting fragments were sorted and merged (`sort32`,
    /// `mergefrag`) rather than recycled as they were.
    pub merge_rounds: u64,
    /// Conflicting fragments `mergefrag` dropped (another fragment of the same pixel in
    /// their group beats them).
    pub merged_fragments: u64,
    pub dram_gbs: f64,
    pub dram_row_hit_rate: f64,
    pub dram_bytes: u64,
    pub srf_words_per_cycle: f64,
    /// LRF words read and written per core cycle, all clusters.
    pub lrf_reads_per_cycle: f64,
    pub lrf_writes_per_cycle: f64,
    pub host_seconds: f64,
    pub simulated_cycles_per_second: f64,
    /// Host seconds spent compiling (or fetching from the compile cache) the kernels.
    pub compile_seconds: f64,
    /// Kernel programs the frame loads, and how many of them came from the compile cache.
    pub kernel_programs: usize,
    pub kernels_from_cache: usize,
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

/// The kernels of a frame, compiled.
struct Kernels {
    perbegin: usize,
    vertex: usize,
    assemble_clip: usize,
    viewport_cull: usize,
    xyprep: usize,
    baryprep: usize,
    xyrast: usize,
    irast: usize,
    hash: usize,
    zcompare: usize,
    recycle_zc: usize,
    recycle_ap: usize,
    sort32: usize,
    mergefrag: usize,
    compiled: Vec<(Kernel, Compiled)>,
    /// Of `compiled`, read from the compile cache.
    from_cache: usize,
    compile_seconds: f64,
}

fn compile_all(
    scene: &Scene,
    desc: &MachineDesc,
    shape: FrameShape,
    cache: &CompileCache,
) -> Result<Kernels, RenderError> {
    let start = Instant::now();
    let vertex = match scene.shading {
        Shading::Lit(_) => crate::kernels::vertex::build(desc),
        Shading::Unlit => kernels::vertex_unlit(desc),
    };
    let list = vec![
        kernels::perbegin(desc, passthrough(scene).len()),
        vertex,
        kernels::assemble_clip(desc),
        kernels::viewport_cull(desc, shape),
        kernels::xyprep(desc, shape),
        kernels::baryprep(desc),
        kernels::xyrast(desc, shape),
        kernels::irast(desc),
        kernels::hash(desc, shape),
        kernels::zcompare(desc, shape),
        kernels::compact_recycle(desc, [NULL_DEPTH, 0]),
        kernels::compact_recycle(desc, [shape.trash(), 0]),
        mergefrag::sort32(desc, shape),
        mergefrag::mergefrag(desc, shape),
    ];
    let (compiled, from_cache) = compile_in_parallel(list, desc, cache)
        .map_err(|e| RenderError(format!("cannot compile the pipeline: {e}")))?;
    Ok(Kernels {
        perbegin: 0,
        vertex: 1,
        assemble_clip: 2,
        viewport_cull: 3,
        xyprep: 4,
        baryprep: 5,
        xyrast: 6,
        irast: 7,
        hash: 8,
        zcompare: 9,
        recycle_zc: 10,
        recycle_ap: 11,
        sort32: 12,
        mergefrag: 13,
        compiled,
        from_cache,
        compile_seconds: start.elapsed().as_secs_f64(),
    })
}

/// Compiles `kernels` on as many host threads as there are cores (each kernel on its own;
/// the microcode does not depend on which thread compiled it), in their order, through
/// `cache`; also returns how many came from the cache.
fn compile_in_parallel(
    kernels: Vec<Kernel>,
    desc: &MachineDesc,
    cache: &CompileCache,
) -> Result<(Vec<(Kernel, Compiled)>, usize), crate::compile::CompileError> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let next = AtomicUsize::new(0);
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(kernels.len());
    let mut done: Vec<(usize, (Result<Compiled, _>, Outcome))> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                scope.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        let Some(k) = kernels.get(i) else { break };
                        mine.push((i, cache.compile_with_outcome(k, desc)));
                    }
                    mine
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().expect("a compiler thread panicked"))
            .collect()
    });
    done.sort_by_key(|&(i, _)| i);
    let hits = done.iter().filter(|(_, (_, o))| *o == Outcome::Hit).count();
    let compiled = kernels
        .into_iter()
        .zip(done)
        .map(|(k, (_, (r, _)))| r.map(|c| (k, c)))
        .collect::<Result<_, _>>()?;
    Ok((compiled, hits))
}

/// SRF regions, block-aligned, bump-allocated once per frame.
struct SrfPlan {
    next: usize,
    block: usize,
    words: usize,
}

impl SrfPlan {
    fn take(&mut self, words: usize) -> Result<usize, RenderError> {
        let start = self.next;
        let words = words.div_ceil(self.block) * self.block;
        if start + words > self.words {
            return Err(RenderError(format!(
                "the SRF ({} words) is too small for the pipeline's streams",
                self.words
            )));
        }
        self.next += words;
        Ok(start)
    }
}

struct Regions {
    /// The OpenGL state `perbegin` reads, and the vertex program's parameters it writes.
    state: usize,
    vertex_params: usize,
    /// `xyprep`'s scissor rectangle and `baryprep`'s first primitive number.
    xyprep_params: usize,
    baryprep_params: usize,
    /// One batch's vertices as loaded: the next batch's load waits (by the scoreboard)
    /// only until the vertex program has read them.
    vertices: usize,
    /// Two sets of shaded vertices, so that one batch is shaded while the previous one is
    /// still being set up.
    shaded: [usize; 2],
    /// A batch's triangles between the setup kernels: `assemble_clip`'s `clipped` and
    /// `attribs`, `viewport_cull`'s `det` (its `window` records go over the shaded
    /// vertices).
    clipped: usize,
    attribs: usize,
    det: usize,
    raster: usize,
    interp: usize,
    rows: usize,
    tickets: usize,
    tickets_words: usize,
    /// xyrast outputs: addr, tri, e0, e1, e2.
    frags: [usize; 5],
    /// Fragments xyrast may write per pass (nulls included).
    frag_capacity: usize,
    /// Two buffers of gathered interpolation records: the next chunk's are gathered while
    /// this one is composited.
    gathered: [usize; 2],
    /// irast outputs, then two recycle sets: z, colour, addr, prim (room for a chunk
    /// rounded up to whole groups of 32 and a row of nulls).
    zcap: [[usize; 4]; 3],
    /// `sort32`'s outputs: key, z, prim (in `pixel`'s words).
    sorted: [usize; 3],
    pixel: usize,
    new_pixel: usize,
    newaddr: usize,
    conflict: usize,
    /// `hash`'s row of conflict counts.
    conflicts: usize,
    /// Fragments per chunk.
    chunk: usize,
}

/// DRAM word addresses.
struct Memory {
    vertices: u64,
    /// The OpenGL state (see [`state_words`]).
    state: u64,
    interp: u64,
    /// Interpolation records (a batch's triangles): the bound of gathers by triangle.
    interp_records: u64,
    framebuffer: u64,
    /// Framebuffer pixels with the trash pixel: the bound of gathers and scatters by pixel.
    pixels: u64,
}

struct Host {
    sim: Sim,
    k: Kernels,
    r: Regions,
    m: Memory,
    clusters: usize,
    stats: FrameStats,
    /// The vertex set whose vertex program is still to be queued, with its triangles.
    pending_vertex: Option<(usize, usize)>,
    /// [`RenderOptions::merge_min_conflicts`].
    merge_min_conflicts: Option<usize>,
}

fn bind(start: usize, words: usize) -> StreamBinding {
    StreamBinding { start, words }
}

impl Host {
    fn push(&mut self, instr: StreamInstr) -> usize {
        processor::processor_mut(&mut self.sim).push(instr)
    }

    fn kernel(
        &mut self,
        k: usize,
        mut streams: Vec<StreamBinding>,
        params: Option<usize>,
    ) -> usize {
        let (kernel, c) = &self.k.compiled[k];
        if c.params_stream.is_some() {
            let start = params.expect("the host passes the parameters' region");
            streams.push(bind(start, kernel.params.len() * self.clusters));
        }
        self.push(StreamInstr::Kernel {
            program: k,
            bindings: streams,
        })
    }

    fn mem(
        &mut self,
        kind: MemOpKind,
        base: u64,
        pattern: Pattern,
        record_words: usize,
        records: usize,
        srf_start: usize,
    ) {
        self.push(StreamInstr::Memory(MemOp {
            kind,
            base,
            pattern,
            record_words,
            records,
            srf_start,
            row_records: if record_words > 1 { self.clusters } else { 1 },
        }));
    }

    /// Runs until every queued instruction has completed.
    fn drain(&mut self) -> Result<(), RenderError> {
        self.run_until(|s| {
            processor::processor(s).is_done()
                && s.modules_of::<imagine_units::dram::DramChannel>()
                    .all(imagine_units::dram::DramChannel::is_idle)
        })
    }

    fn run_until(&mut self, done: impl Fn(&Sim) -> bool) -> Result<(), RenderError> {
        let left = MAX_FRAME_CYCLES.saturating_sub(self.sim.core_cycles());
        let finished = self
            .sim
            .run_until(left, done)
            .map_err(|e| RenderError(format!("the machine stopped: {e}")))?;
        if !finished {
            return Err(RenderError(format!(
                "the frame did not finish within {MAX_FRAME_CYCLES} core cycles"
            )));
        }
        Ok(())
    }

    /// Runs until instruction `id` has completed; later ones may still be in flight.
    fn wait_for(&mut self, id: usize) -> Result<(), RenderError> {
        self.run_until(|s| {
            processor::processor(s).controller().records()[id]
                .completed
                .is_some()
        })
    }

    fn outputs(&self, id: usize) -> Vec<usize> {
        processor::processor(&self.sim).controller().records()[id]
            .outputs
            .clone()
    }

    /// Queues the host's write of kernel parameters (each replicated per cluster) at SRF
    /// word `start`.
    fn write_params(&mut self, start: usize, words: &[u32]) {
        let c = self.clusters;
        let words = words
            .iter()
            .flat_map(|&w| std::iter::repeat_n(w, c))
            .collect();
        self.push(StreamInstr::WriteSrf { start, words });
    }

    /// Reads `len` SRF words from `start` back over the host interface, once every
    /// instruction queued before that writes them has completed.
    fn read_srf(&mut self, start: usize, len: usize) -> Result<Vec<u32>, RenderError> {
        let id = self.push(StreamInstr::ReadSrf { start, len });
        self.wait_for(id)?;
        Ok(processor::processor(&self.sim).controller().records()[id]
            .read
            .clone())
    }

    /// Queues the load of the OpenGL state (`words` words) and `perbegin`, which writes
    /// the vertex program's parameters.
    fn begin(&mut self, words: usize) {
        let (state, params) = (self.r.state, self.r.vertex_params);
        let stride = Pattern::Strided { stride: 1 };
        self.mem(MemOpKind::Load, self.m.state, stride, 1, words, state);
        let params_words = self.k.compiled[self.k.vertex].0.params.len() * self.clusters;
        let streams = vec![bind(state, words), bind(params, params_words)];
        self.kernel(self.k.perbegin, streams, None);
    }

    /// Queues the load of a batch's vertices, to be shaded into set `set`; its vertex
    /// program is queued later by [`Host::shade_pending`], where the clusters would
    /// otherwise wait.
    fn load_batch(&mut self, first_triangle: usize, triangles: usize, set: usize) {
        let verts = 3 * triangles;
        self.mem(
            MemOpKind::Load,
            self.m.vertices + (3 * first_triangle * VERTEX_WORDS) as u64,
            Pattern::Strided {
                stride: VERTEX_WORDS as u64,
            },
            VERTEX_WORDS,
            verts,
            self.r.vertices,
        );
        self.pending_vertex = Some((set, triangles));
    }

    /// Queues the vertex program of the loaded batch, if it is not queued yet.
    fn shade_pending(&mut self) {
        let Some((set, triangles)) = self.pending_vertex.take() else {
            return;
        };
        let verts = 3 * triangles;
        let r = &self.r;
        let streams = vec![
            bind(r.vertices, verts * VERTEX_WORDS),
            bind(r.shaded[set], verts * SHADED_WORDS),
        ];
        let vparams = r.vertex_params;
        self.kernel(self.k.vertex, streams, Some(vparams));
    }

    /// Rasterizes and composites a batch whose vertices are shaded into vertex set `set`.
    fn batch(
        &mut self,
        first_triangle: usize,
        triangles: usize,
        set: usize,
        width: u32,
        height: u32,
    ) -> Result<(), RenderError> {
        let c = self.clusters;
        let verts = 3 * triangles;
        // Once per batch: assembly, clipping, viewport and culling, and the interpolation
        // records, stored for the fragments' gathers.
        let r = &self.r;
        let (clipped, attribs, window, det, interp) =
            (r.clipped, r.attribs, r.shaded[set], r.det, r.interp);
        let streams = vec![
            bind(r.shaded[set], verts * SHADED_WORDS),
            bind(clipped, triangles * CLIPPED_WORDS),
            bind(attribs, triangles * ATTRIB_WORDS),
        ];
        self.kernel(self.k.assemble_clip, streams, None);
        let streams = vec![
            bind(clipped, triangles * CLIPPED_WORDS),
            bind(window, triangles * WINDOW_WORDS),
            bind(det, triangles),
        ];
        self.kernel(self.k.viewport_cull, streams, None);
        let bparams = self.r.baryprep_params;
        self.write_params(bparams, &[first_triangle as u32]);
        let streams = vec![
            bind(attribs, triangles * ATTRIB_WORDS),
            bind(det, triangles),
            bind(interp, triangles * INTERP_WORDS),
        ];
        self.kernel(self.k.baryprep, streams, Some(bparams));
        self.mem(
            MemOpKind::Store,
            self.m.interp,
            Pattern::Strided {
                stride: INTERP_WORDS as u64,
            },
            INTERP_WORDS,
            triangles,
            interp,
        );
        // Per scissor tile: the bounding boxes, then rasterization.
        let mut tiles = vec![[0, 0, width as i32 - 1, height as i32 - 1]];
        while let Some(tile) = tiles.pop() {
            let xparams = self.r.xyprep_params;
            self.write_params(xparams, &tile.map(|v| v as u32));
            let r = &self.r;
            let streams = vec![
                bind(window, triangles * WINDOW_WORDS),
                bind(r.raster, triangles * RASTER_WORDS),
                bind(r.rows, 2 * c),
            ];
            self.kernel(self.k.xyprep, streams, Some(xparams));
            let counts = self.read_srf(self.r.rows, 2 * c)?;
            let rows = counts[0] as usize;
            // Each candidate pixel gives at most one fragment; then a row of nulls.
            let candidates: usize = counts[c..].iter().map(|&n| n as usize).sum();
            if candidates + c > self.r.frag_capacity || rows * c > self.r.tickets_words {
                let [x0, y0, x1, y1] = tile;
                if x1 > x0 || y1 > y0 {
                    self.stats.spills += 1;
                    if x1 - x0 >= y1 - y0 {
                        let mid = (x0 + x1) / 2;
                        tiles.push([mid + 1, y0, x1, y1]);
                        tiles.push([x0, y0, mid, y1]);
                    } else {
                        let mid = (y0 + y1) / 2;
                        tiles.push([x0, mid + 1, x1, y1]);
                        tiles.push([x0, y0, x1, mid]);
                    }
                    continue;
                }
                return Err(RenderError(format!(
                    "a one-pixel tile needs {rows} rasterizer iterations; the SRF holds {}",
                    self.r.frag_capacity / c
                )));
            }
            self.rasterize(triangles, rows)?;
        }
        Ok(())
    }

    fn rasterize(&mut self, triangles: usize, rows: usize) -> Result<(), RenderError> {
        let c = self.clusters;
        let r = &self.r;
        let (raster, tickets, frags, cap) = (r.raster, r.tickets, r.frags, r.frag_capacity);
        let mut streams = vec![
            bind(raster, triangles * RASTER_WORDS),
            bind(tickets, rows * c),
        ];
        streams.extend(frags.iter().map(|&f| bind(f, cap)));
        let id = self.kernel(self.k.xyrast, streams, None);
        self.shade_pending();
        self.wait_for(id)?;
        // The real fragments, then the row of nulls.
        let real = self.outputs(id)[2] - c;
        // Whole rows: every real fragment and the nulls that fill its last row; the rest of
        // the nulls are not composited.
        let total = real.div_ceil(c) * c;
        self.stats.fragments += real as u64;
        let chunk = self.r.chunk;
        let chunks: Vec<(usize, usize)> = (0..total)
            .step_by(chunk)
            .map(|start| (start, chunk.min(total - start)))
            .collect();
        if let Some(&(start, len)) = chunks.first() {
            self.gather_interp(start, len, 0);
        }
        for (i, &(start, len)) in chunks.iter().enumerate() {
            // The next chunk's records are gathered while this one is composited.
            if let Some(&(next, next_len)) = chunks.get(i + 1) {
                self.gather_interp(next, next_len, (i + 1) % 2);
            }
            self.fragments(start, len, i % 2)?;
        }
        Ok(())
    }

    /// Queues the gather of the interpolation records of fragments `start..start + len`
    /// (by triangle index) into buffer `buffer`.
    fn gather_interp(&mut self, start: usize, len: usize, buffer: usize) {
        let tri = self.r.frags[1] + start;
        self.mem(
            MemOpKind::Load,
            self.m.interp,
            Pattern::Indexed {
                index_start: tri,
                scale: INTERP_WORDS as u64,
                bound: Some(self.m.interp_records),
            },
            INTERP_WORDS,
            len,
            self.r.gathered[buffer],
        );
    }

    /// Interpolates and composites fragments `start..start + len` of the xyrast output,
    /// their interpolation records gathered into buffer `buffer`.
    fn fragments(&mut self, start: usize, len: usize, buffer: usize) -> Result<(), RenderError> {
        let r = &self.r;
        let [addr, _, e0, e1, e2] = r.frags.map(|f| f + start);
        let gathered = r.gathered[buffer];
        let [z, colour, _, prim] = r.zcap[0];
        self.kernel(
            self.k.irast,
            vec![
                bind(e0, len),
                bind(e1, len),
                bind(e2, len),
                bind(gathered, len * INTERP_WORDS),
                bind(z, len),
                bind(colour, len),
                bind(prim, len),
            ],
            None,
        );
        let mut current = [z, colour, addr, prim];
        let mut len = len;
        let mut set = 1;
        // Whether a merge of this chunk dropped fragments.
        let mut stacked = false;
        let mut fruitless = false;
        loop {
            self.stats.composite_rounds += 1;
            let r = &self.r;
            let (pixel, new_pixel, newaddr, conflict) =
                (r.pixel, r.new_pixel, r.newaddr, r.conflict);
            let next = r.zcap[set];
            let (fb, pixels) = (self.m.framebuffer, self.m.pixels);
            let [z, colour, addr, prim] = current;
            let by_pixel = |index_start| Pattern::Indexed {
                index_start,
                scale: PIXEL_WORDS as u64,
                bound: Some(pixels),
            };
            // The pixels are gathered while `hash` looks for conflicts.
            self.mem(MemOpKind::Load, fb, by_pixel(addr), PIXEL_WORDS, len, pixel);
            self.kernel(
                self.k.hash,
                vec![
                    bind(addr, len),
                    bind(conflict, len + GROUP),
                    bind(self.r.conflicts, self.clusters),
                ],
                None,
            );
            self.kernel(
                self.k.zcompare,
                vec![
                    bind(z, len),
                    bind(colour, len),
                    bind(addr, len),
                    bind(prim, len),
                    bind(pixel, len * PIXEL_WORDS),
                    bind(conflict, len),
                    bind(new_pixel, len * PIXEL_WORDS),
                    bind(newaddr, len),
                ],
                None,
            );
            let scatter = by_pixel(newaddr);
            self.mem(MemOpKind::Store, fb, scatter, PIXEL_WORDS, len, new_pixel);
            // The zcompare and the scatter are queued; the host needs only the count.
            let conflicts = self.read_srf(self.r.conflicts, 1)?[0] as usize;
            if conflicts == 0 {
                return Ok(());
            }
            let c = self.clusters;
            let cap = self.r.chunk.next_multiple_of(GROUP) + c;
            // Merge on many conflicts, and after a merge of this chunk that found a pixel's
            // fragments together, on any that could merge; not again after a merge of this
            // chunk that dropped nothing.
            let merge = !fruitless
                && self
                    .merge_min_conflicts
                    .is_some_and(|m| conflicts >= m || (stacked && conflicts >= 2));
            if merge {
                // Sort the conflicting fragments by address in groups of 32 and keep one
                // per address: whole groups, `hash`'s rows of zeros after its flags.
                self.stats.merge_rounds += 1;
                let groups = len.next_multiple_of(GROUP);
                let sorted = self.r.sorted;
                self.kernel(
                    self.k.sort32,
                    vec![
                        bind(conflict, groups),
                        bind(addr, groups),
                        bind(z, groups),
                        bind(prim, groups),
                        bind(sorted[0], groups),
                        bind(sorted[1], groups),
                        bind(sorted[2], groups),
                    ],
                    None,
                );
                let merged = self.kernel(
                    self.k.mergefrag,
                    vec![
                        bind(sorted[0], groups),
                        bind(sorted[1], groups),
                        bind(sorted[2], groups),
                        bind(colour, groups),
                        bind(next[0], cap),
                        bind(next[1], cap),
                        bind(next[2], cap),
                        bind(next[3], cap),
                    ],
                    None,
                );
                // The next round needs the survivors' count.
                self.wait_for(merged)?;
                let written = self.outputs(merged)[4];
                let dropped = conflicts + c - written;
                self.stats.merged_fragments += dropped as u64;
                stacked |= dropped > 0;
                fruitless = dropped == 0;
                len = written / c * c;
            } else {
                self.kernel(
                    self.k.recycle_zc,
                    vec![
                        bind(conflict, len),
                        bind(z, len),
                        bind(colour, len),
                        bind(next[0], cap),
                        bind(next[1], cap),
                    ],
                    None,
                );
                self.kernel(
                    self.k.recycle_ap,
                    vec![
                        bind(conflict, len),
                        bind(addr, len),
                        bind(prim, len),
                        bind(next[2], cap),
                        bind(next[3], cap),
                    ],
                    None,
                );
                // The conflicting fragments, then `compact_recycle`'s row of nulls: whole
                // rows.
                len = (conflicts + c) / c * c;
            }
            current = next;
            set = if set == 1 { 2 } else { 1 };
        }
    }
}

/// Chooses the batch size: the largest multiple of the cluster count up to 64 triangles
/// (fewer for tiny scenes, and at most `rows` triangles per cluster: `xyrast` keeps the
/// batch's raster records in the scratchpads).
fn batch_size(triangles: usize, clusters: usize, rows: usize) -> usize {
    let want = 64usize.max(clusters).div_ceil(clusters) * clusters;
    want.min(triangles.div_ceil(clusters) * clusters)
        .min(rows * clusters)
        .max(clusters)
}

fn plan(
    desc: &MachineDesc,
    batch: usize,
    state: usize,
    params: usize,
) -> Result<Regions, RenderError> {
    let c = desc.cluster.count;
    let mut p = SrfPlan {
        next: 0,
        block: desc.srf.block_words,
        words: desc.srf.words,
    };
    // Fragments per chunk. Its buffers also hold xyrast's tickets, so smaller chunks split
    // more tiles, and larger ones leave fewer words for fragments; 96 was the fastest on
    // SPHERE (gold8) of the sizes 64 to 256 tried. A chunk is whole rows of clusters and
    // whole SRF blocks: its slices of the fragment streams start on block boundaries.
    let gcd = |mut a: usize, mut b: usize| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    let unit = c / gcd(c, desc.srf.block_words) * desc.srf.block_words;
    let chunk = 96usize.div_ceil(unit) * unit;
    let state = p.take(state)?;
    let vertex_params = p.take(params * c)?;
    let xyprep_params = p.take(4 * c)?;
    let baryprep_params = p.take(c)?;
    let vertices = p.take(3 * batch * VERTEX_WORDS)?;
    let shaded = [
        p.take(3 * batch * SHADED_WORDS)?,
        p.take(3 * batch * SHADED_WORDS)?,
    ];
    let raster = p.take(batch * RASTER_WORDS)?;
    // Words only kernels use can be shared by streams whose kernels do not overlap in the
    // queue (the kernels run one after another): `clipped` lives from `assemble_clip` to
    // `viewport_cull`, before any `xyprep` writes raster records.
    const _: () = assert!(CLIPPED_WORDS <= RASTER_WORDS);
    let clipped = raster;
    // (`window` goes over the batch's shaded vertices, which `assemble_clip` has read; the
    // vertex program writes that set again only after the batch's last `xyprep`.)
    const _: () = assert!(WINDOW_WORDS <= 3 * SHADED_WORDS);
    let interp = p.take(batch * INTERP_WORDS)?;
    let rows = p.take(2 * c)?;
    // The fragment chunk's streams; xyrast, which runs alone, reads its tickets (whose
    // contents do not matter) from the same words.
    // `attribs` and `det` live from `assemble_clip` to `baryprep`, in the second buffer of
    // gathered records: the previous batch's `irast`s have read it, and this batch's first
    // gather into it comes after `baryprep`.
    let attribs_words = (batch * ATTRIB_WORDS).next_multiple_of(p.block);
    let gathered = [
        p.take(chunk * INTERP_WORDS)?,
        p.take((chunk * INTERP_WORDS).max(attribs_words + batch))?,
    ];
    let (attribs, det) = (gathered[1], gathered[1] + attribs_words);
    let tickets = gathered[0];
    let mut zcap = [[0; 4]; 3];
    let groups = chunk.next_multiple_of(GROUP);
    for set in &mut zcap {
        for s in set.iter_mut() {
            *s = p.take(groups + c)?;
        }
    }
    // `sort32`'s outputs reuse the gathered pixels' words, which the round's `zcompare`
    // has read by then (the scoreboard sees to it): SRF words left for fragments mean
    // fewer scissor splits.
    let pixel = p.take((chunk * PIXEL_WORDS).max(3 * groups))?;
    let sorted = [0, 1, 2].map(|i| pixel + i * groups);
    let new_pixel = p.take(chunk * PIXEL_WORDS)?;
    let newaddr = p.take(chunk)?;
    // `hash`'s flags and the rows of zeros after them.
    let conflict = p.take(chunk + GROUP)?;
    let conflicts = p.take(c)?;
    let tickets_words = p.next - tickets;
    // What is left: the five xyrast outputs, equal shares.
    let left = p.words.saturating_sub(p.next);
    let share = (left / 5) / p.block * p.block;
    let frag_capacity = share / c * c;
    if frag_capacity < 4 * c {
        return Err(RenderError(format!(
            "machine `{}`: the SRF ({} words) leaves no room for fragments",
            desc.name, desc.srf.words
        )));
    }
    let frags = [(); 5].map(|_| p.take(share).expect("shares fit"));
    Ok(Regions {
        state,
        vertex_params,
        xyprep_params,
        baryprep_params,
        vertices,
        shaded,
        clipped,
        attribs,
        det,
        raster,
        interp,
        rows,
        tickets,
        tickets_words,
        frags,
        frag_capacity,
        gathered,
        zcap,
        sorted,
        pixel,
        new_pixel,
        newaddr,
        conflict,
        conflicts,
        chunk,
    })
}

/// Vertex records of `scene` in drawing order (triangle `t` is vertices `3t..3t + 3`),
/// padded with degenerate triangles to whole batches.
fn vertex_words(scene: &Scene, batch: usize) -> Vec<u32> {
    let tris = scene.triangles();
    let padded = tris.div_ceil(batch) * batch;
    let last = tris.saturating_sub(1);
    (0..3 * padded)
        .flat_map(|v| {
            // Padding repeats one vertex three times: a degenerate triangle.
            let v = if v < 3 * tris { v } else { 3 * last };
            let q = match scene.shading {
                Shading::Lit(_) => scene.normals[v],
                Shading::Unlit => scene.colours[v],
            };
            scene.positions[v].into_iter().chain(q).map(f32::to_bits)
        })
        .collect()
}

/// The words of the vertex program's parameters that `perbegin` passes through after the
/// model-view-projection matrix: the lit program's eye, lights and material.
fn passthrough(scene: &Scene) -> Vec<u32> {
    let mut p: Vec<f32> = Vec::new();
    if let Shading::Lit(l) = &scene.shading {
        p.extend(l.eye);
        for (pos, colour) in &l.lights {
            p.extend(pos);
            p.extend(colour);
        }
        p.extend(l.diffuse);
        p.extend(l.specular);
        p.extend(l.ambient);
    }
    p.iter().map(|x| x.to_bits()).collect()
}

/// The OpenGL state as `perbegin` reads it: the model-view and projection matrices and the
/// passthrough words, padded with zeros to whole rows of `clusters` words.
fn state_words(scene: &Scene, clusters: usize) -> Vec<u32> {
    let mut words: Vec<u32> = scene
        .modelview
        .iter()
        .chain(&scene.projection)
        .map(|x| x.to_bits())
        .collect();
    words.extend(passthrough(scene));
    words.resize(words.len().div_ceil(clusters) * clusters, 0);
    words
}

/// How the host runs the pipeline (choices that change the cycles, never the image).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RenderOptions {
    /// Sort and merge a round's conflicting fragments (`sort32`, `mergefrag`) when `hash`
    /// holds back at least this many; else, or when `None`, recycle them as they are
    /// (`compact_recycle`).
    pub merge_min_conflicts: Option<usize>,
    /// Where compiled kernels are kept between renders (disabled by default: the CLI
    /// passes [`CompileCache::from_env`] unless `--no-cache`).
    pub cache: CompileCache,
}

/// Conflicts from which the host sorts and merges. The stage costs more cycles than the
/// recycling it replaces (on gold8, chunks of 96 fragments of a stacked scene: `sort32`
/// about 600 cycles a call and `mergefrag` 540, against 300 each, the least a kernel
/// holds the clusters, for `compact_recycle`), and
/// saves rounds only when fragments of one pixel share a group; few conflicts are more
/// often stamp aliases (different pixels, the same stamp key) than a pixel's stack.
pub const MERGE_MIN_CONFLICTS: usize = 24;

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            merge_min_conflicts: Some(MERGE_MIN_CONFLICTS),
            cache: CompileCache::disabled(),
        }
    }
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
    mut progress: impl FnMut(usize, usize),
) -> Result<Frame, RenderError> {
    scene.validate().map_err(|e| RenderError(e.to_string()))?;
    let host_start = Instant::now();
    let clusters = desc.cluster.count;
    let rows = kernels::xyrast_rows(desc);
    if rows == 0 {
        return Err(RenderError(format!(
            "machine `{}`: the scratchpad cannot hold a raster record",
            desc.name
        )));
    }
    let batch = batch_size(scene.triangles(), clusters, rows);
    let shape = FrameShape {
        width: scene.width,
        height: scene.height,
        clusters,
        cull_back: scene.cull_back,
        batch,
    };
    let k = compile_all(scene, desc, shape, &options.cache)?;
    let state = state_words(scene, clusters);
    let params = k.compiled[k.vertex].0.params.len();
    let regions = plan(desc, batch, state.len(), params)?;
    let verts = vertex_words(scene, batch);
    let pixels = (scene.width * scene.height) as usize + 1;
    let mut fb = Vec::with_capacity(pixels * PIXEL_WORDS);
    for _ in 0..pixels {
        fb.extend([0xFF00_0000, 1.0f32.to_bits(), 0]);
    }
    let align = |x: u64| x.div_ceil(1024) * 1024;
    let interp = align(verts.len() as u64);
    let state_at = align(interp + (batch * INTERP_WORDS) as u64);
    let memory = Memory {
        vertices: 0,
        state: state_at,
        interp,
        interp_records: batch as u64,
        framebuffer: align(state_at + state.len() as u64),
        pixels: pixels as u64,
    };
    let capacity_words = imagine_units::dram::DramParams::of(desc).capacity_bytes() / 4;
    if memory.framebuffer + fb.len() as u64 > capacity_words {
        return Err(RenderError(format!(
            "the scene needs {} words of DRAM; machine `{}` has {capacity_words}",
            memory.framebuffer + fb.len() as u64,
            desc.name
        )));
    }
    let program = StreamProgram {
        kernels: k.compiled.iter().map(|(_, c)| c.program.clone()).collect(),
        instrs: (0..k.compiled.len())
            .map(|p| StreamInstr::LoadMicrocode { program: p })
            .collect(),
    };
    let state_len = state.len();
    let opts = ProcessorOptions {
        dram_init: vec![
            (memory.vertices, verts),
            (memory.state, state),
            (memory.framebuffer, fb),
        ],
        on_start,
        ..ProcessorOptions::default()
    };
    let sim = processor::build(desc, program, opts).map_err(|e| RenderError(e.to_string()))?;
    let triangles = scene.triangles();
    let mut host = Host {
        sim,
        k,
        r: regions,
        m: memory,
        clusters,
        pending_vertex: None,
        merge_min_conflicts: options.merge_min_conflicts,
        stats: FrameStats {
            scene: scene.name.clone(),
            machine: desc.name.clone(),
            width: scene.width,
            height: scene.height,
            triangles: triangles as u64,
            vertices: 3 * triangles as u64,
            batch_triangles: batch,
            ..FrameStats::default()
        },
    };
    host.begin(state_len);
    let batches = triangles.div_ceil(batch);
    // Two batches in flight: batch b+1's vertices are loaded while batch b is set up and
    // shaded while its first fragments are composited.
    host.load_batch(0, batch, 0);
    host.shade_pending();
    for b in 0..batches {
        let set = b % 2;
        if b + 1 < batches {
            host.load_batch((b + 1) * batch, batch, 1 - set);
        }
        host.batch(b * batch, batch, set, scene.width, scene.height)?;
        host.shade_pending();
        host.stats.batches += 1;
        progress(b + 1, batches);
    }
    host.drain()?;
    host.sim
        .finish()
        .map_err(|e| RenderError(format!("cannot finish the waveform: {e}")))?;
    let fb_words = processor::read_dram(
        &host.sim,
        desc,
        host.m.framebuffer,
        (pixels - 1) * PIXEL_WORDS,
    );
    let pixels_out: Vec<u32> = fb_words.chunks(PIXEL_WORDS).map(|p| p[0]).collect();
    let mut stats = host.stats;
    finish_stats(&mut stats, &host.sim, desc, &host.k, host_start);
    Ok(Frame {
        width: scene.width,
        height: scene.height,
        pixels: pixels_out,
        stats,
    })
}

fn finish_stats(s: &mut FrameStats, sim: &Sim, desc: &MachineDesc, k: &Kernels, start: Instant) {
    let p = processor::processor(sim);
    let cycles = sim.core_cycles();
    let mhz = desc.clocks.core_mhz as f64;
    let seconds = cycles as f64 / (mhz * 1e6);
    s.core_mhz = mhz;
    s.cycles = cycles;
    s.frames_per_second = 1.0 / seconds.max(1e-12);
    s.vertices_per_second = s.vertices as f64 / seconds.max(1e-12);
    s.fragments_per_second = s.fragments as f64 / seconds.max(1e-12);
    let mut shares: Vec<KernelShare> = k
        .compiled
        .iter()
        .map(|(kernel, _)| KernelShare {
            kernel: kernel.name.clone(),
            ..KernelShare::default()
        })
        .collect();
    let mut busy = 0;
    let mut stalls = 0;
    let mut ops = 0;
    for r in p.controller().records() {
        if let (StreamInstr::Kernel { program, .. }, Some(st)) = (&r.instr, &r.kernel_stats) {
            let share = &mut shares[*program];
            let st: &KernelStats = st;
            share.calls += 1;
            share.cycles += st.cycles;
            share.stall_cycles += st.stall_cycles;
            let o: u64 = st.fu_ops.iter().sum::<u64>() * desc.cluster.count as u64;
            share.ops += o;
            busy += st.cycles;
            stalls += st.stall_cycles;
            ops += o;
        }
    }
    // The two recycle kernels share a name: merge them.
    let mut merged: Vec<KernelShare> = Vec::new();
    for sh in shares {
        match merged.iter_mut().find(|m| m.kernel == sh.kernel) {
            Some(m) => {
                m.calls += sh.calls;
                m.cycles += sh.cycles;
                m.stall_cycles += sh.stall_cycles;
                m.ops += sh.ops;
            }
            None => merged.push(sh),
        }
    }
    s.kernels = merged;
    s.ops_per_cycle = ops as f64 / cycles.max(1) as f64;
    s.cluster_occupancy = busy as f64 / cycles.max(1) as f64;
    s.cluster_occupancy_without_stalls = busy.saturating_sub(stalls) as f64 / cycles.max(1) as f64;
    let dram: ReplayReport = imagine_units::dram::replay::report_of(
        sim,
        imagine_units::dram::Policy::parse(&desc.memory.policy)
            .unwrap_or(imagine_units::dram::Policy::FirstReady),
        &imagine_units::dram::DramParams::of(desc),
    );
    s.dram_bytes = dram.bytes;
    s.dram_gbs = dram.bytes as f64 / seconds.max(1e-12) / 1e9;
    s.dram_row_hit_rate = dram.row_hit_rate;
    let srf = p.machine().srf().stats();
    s.srf_words_per_cycle = srf.words_per_cycle();
    let (lrf_read, lrf_written) = p.machine().lrf_words_moved();
    s.lrf_reads_per_cycle = lrf_read as f64 / cycles.max(1) as f64;
    s.lrf_writes_per_cycle = lrf_written as f64 / cycles.max(1) as f64;
    s.host_seconds = start.elapsed().as_secs_f64();
    s.compile_seconds = k.compile_seconds;
    s.kernel_programs = k.compiled.len();
    s.kernels_from_cache = k.from_cache;
    s.simulated_cycles_per_second = cycles as f64 / s.host_seconds.max(1e-9);
}
