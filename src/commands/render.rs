//! `imagine render`: a scene through the OpenGL-like pipeline on the machine, with its
//! statistics and its error against the independent reference renderer.

use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::Args;
use imagine_pipelines::compile::CompileCache;
use imagine_pipelines::opengl::render::{Frame, Rasterizer, RenderOptions, render_with};
use imagine_pipelines::scene::model::{PipelineKind, Scene};
use imagine_pipelines::scene::{self, LoadOptions};
use imagine_units::desc::MachineDesc;
use imagine_units::dram::trace::write_trace;
use imagine_units::limits::{MAX_BATCH, MAX_RUN_CYCLES};
use imagine_verif::image::Metrics;

use super::outputs::Outputs;
use super::reference_error::{self, image_of};
use super::waves::WaveArgs;

#[derive(Args)]
pub struct RenderArgs {
    /// Scene: a built-in name (`imagine scene list`: SPHERE, SPHERE-FULL, RATE-1 …
    /// RATE-128, ADVS-1, ADVS-8, PIN, PIN-8, MARBLE, VERONA) or a `.toml` scene file or
    /// `.tri` triangle file
    /// [default: SPHERE]
    pub(super) scene: Option<String>,
    /// Machine description name or file
    #[arg(long, default_value = "gold8")]
    machine: String,
    /// Window side in pixels: overrides the scene's window with a square one
    #[arg(long)]
    pub(super) size: Option<u32>,
    /// Icosphere subdivisions: overrides every icosphere's (SPHERE has 6: 81,920 triangles)
    #[arg(long)]
    subdivisions: Option<u32>,
    /// Build the general pipeline instead of one specialised for the scene (to compare)
    #[arg(long)]
    no_specialize: bool,
    /// At most N triangles per batch, instead of the scene's `pipeline.batch` or 64 (the
    /// largest batch up to N that the machine's scratchpad and SRF hold)
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=i64::from(MAX_BATCH)))]
    batch: Option<u32>,
    /// The rasterizer kernels: barycentric (xyprep, xyrast: each cluster walks its
    /// triangles' boxes) or scanline (spanprep, spangen, spanpack, spanrast: half-triangles
    /// and spans, load-balanced over the clusters; not for blending scenes)
    #[arg(long, default_value = "barycentric", value_parser = parse_rasterizer)]
    rasterizer: Rasterizer,
    /// Write the frame as PNG
    #[arg(long)]
    pub(super) png: Option<PathBuf>,
    /// Write statistics as JSON
    #[arg(long)]
    pub(super) stats: Option<PathBuf>,
    /// Write one CSV row per batch (cycles, kernel cycles, fragments, DRAM words, SRF use)
    #[arg(long)]
    stats_csv: Option<PathBuf>,
    /// Also write the reference renderer's frame as PNG
    #[arg(long)]
    pub(super) reference_png: Option<PathBuf>,
    /// Write the frame as a timeline (Trace Event JSON, opened by ui.perfetto.dev and
    /// chrome://tracing): kernel calls, memory operations, host transfers, waits (with
    /// what they waited on), and counters of DRAM bandwidth, DRAM row hits and misses,
    /// cluster busy share, scoreboard occupancy and SRF words; slices carry their core
    /// cycles for --vcd-window
    #[arg(long, value_name = "F.json")]
    timeline: Option<PathBuf>,
    /// Write the frame's DRAM requests as the channels received them (DRAMsim3 text
    /// format; `imagine dram --trace F --untimed` replays them with no computation)
    #[arg(long, value_name = "FILE")]
    dram_trace: Option<PathBuf>,
    /// Compile every kernel afresh: neither read nor write the compile cache
    /// ($IMAGINE_CACHE_DIR, else the platform's cache directory)
    #[arg(long)]
    pub(super) no_cache: bool,
    /// Give up on a frame that takes longer, in core cycles
    #[arg(long, default_value_t = MAX_RUN_CYCLES, value_parser = clap::value_parser!(u64).range(1..))]
    max_cycles: u64,
    /// The pipeline: `opengl` or `reyes` (default: the scene's `pipeline.kind`). Reyes
    /// draws the scene's patch objects from their Bezier nets (run it on `--machine reyes`)
    #[arg(long, value_parser = ["opengl", "reyes"])]
    pipeline: Option<String>,
    /// Reyes: the largest quad side in pixels (default: the scene's
    /// `pipeline.stop_length`, 1.5)
    #[arg(long, value_name = "L")]
    pub(super) stop_length: Option<f32>,
    #[command(flatten)]
    waves: WaveArgs,
    #[command(flatten)]
    pub(super) datapath: super::datapath::DatapathArg,
    /// Dump the cycles of a call of kernel NAME (the render runs once to find it on the
    /// timeline, then again dumping them); a name of the kernel breakdown
    #[arg(
        long,
        value_name = "NAME",
        requires = "vcd",
        conflicts_with = "vcd_window"
    )]
    vcd_kernel: Option<String>,
    /// Which call of --vcd-kernel to dump, counting from 1
    #[arg(long, value_name = "N", default_value_t = 1, requires = "vcd_kernel",
          value_parser = clap::value_parser!(u64).range(1..))]
    vcd_call: u64,
}

fn load_scene(a: &RenderArgs) -> Result<Scene> {
    let name = a.scene.as_deref().unwrap_or("SPHERE");
    if let Some(size) = a.size
        && (size == 0 || size > scene::MAX_WINDOW)
    {
        bail!("--size {size} is outside 1..={}", scene::MAX_WINDOW);
    }
    let opts = LoadOptions {
        size: a.size,
        subdivisions: a.subdivisions,
        filter: None,
    };
    Ok(scene::load(name, &opts)?)
}

/// The core cycles of call `--vcd-call` of kernel `name`, found on the timeline of a first
/// render (the same frame, cycle for cycle, as the one that is dumped).
fn kernel_window(
    a: &RenderArgs,
    scene: &Scene,
    desc: &MachineDesc,
    name: &str,
) -> Result<imagine_waves::CycleWindow> {
    eprintln!(
        "finding call {} of `{name}` (a first render, without a waveform)",
        a.vcd_call
    );
    let options = RenderOptions {
        timeline: true,
        ..render_options(a)
    };
    let frame = render_with(scene, desc, options, None, |_, _| {})?;
    let timeline = frame.timeline.expect("asked for");
    let calls: Vec<&serde_json::Value> = timeline["traceEvents"]
        .as_array()
        .map(|e| e.iter().filter(|e| e["cat"] == "kernel").collect())
        .unwrap_or_default();
    let of_name: Vec<&&serde_json::Value> = calls.iter().filter(|e| e["name"] == name).collect();
    let Some(call) = of_name.get(a.vcd_call as usize - 1) else {
        if of_name.is_empty() {
            let mut names: Vec<&str> = calls.iter().filter_map(|e| e["name"].as_str()).collect();
            names.sort_unstable();
            names.dedup();
            bail!(
                "--vcd-kernel {name}: the frame calls no kernel of that name; it calls {}",
                names.join(", ")
            );
        }
        bail!(
            "--vcd-call {}: the frame calls `{name}` {} times",
            a.vcd_call,
            of_name.len()
        );
    };
    let cycle = |k: &str| call["args"][k].as_u64().expect("slices carry their cycles");
    let window = imagine_waves::CycleWindow::new(cycle("from_cycle"), Some(cycle("to_cycle")))
        .expect("a call lasts a cycle at least");
    eprintln!(
        "dumping core cycles {window} (call {} of `{name}`)",
        a.vcd_call
    );
    Ok(window)
}

/// Far over near beyond which a frame interpolating depth from 0 loses depth to the edge
/// functions' rounding (near 1e-3 and far 1e6 lost 0.8 % of a mesh's silhouette pixels).
const DEPTH_RANGE_WARNING: f64 = 1e4;

/// Warns when the scene's depth range asks for `pipeline.reference_depth` and it is off.
fn warn_of_depth_range(scene: &Scene) {
    let Some(ratio) = scene.camera.far_over_near() else {
        return;
    };
    if !scene.pipeline.reference_depth && ratio > DEPTH_RANGE_WARNING {
        let ratio = if ratio.is_finite() {
            format!("{ratio:.1e}")
        } else {
            "beyond 1e7".into()
        };
        eprintln!(
            "warning: far/near is {ratio}: depths crowd near 1, where the rasterizer's \
             rounding can drop silhouette pixels and swap close surfaces; set \
             `reference_depth = true` in the scene's [pipeline] (about 1 % more cycles)"
        );
    }
}

/// The render the options ask for.
fn render_options(a: &RenderArgs) -> RenderOptions {
    RenderOptions {
        specialise: !a.no_specialize,
        cache: if a.no_cache {
            CompileCache::disabled()
        } else {
            CompileCache::from_env()
        },
        max_cycles: a.max_cycles,
        batch: a.batch.map(|b| b as usize),
        timeline: a.timeline.is_some(),
        record_dram: a.dram_trace.is_some(),
        rasterizer: a.rasterizer,
        datapath: a.datapath.datapath,
        ..RenderOptions::default()
    }
}

fn parse_rasterizer(text: &str) -> Result<Rasterizer, String> {
    text.parse()
}

pub fn run(a: RenderArgs) -> Result<ExitCode> {
    let mut outputs = Outputs::default();
    outputs.add_opt("--png", a.png.as_ref())?;
    outputs.add_opt("--reference-png", a.reference_png.as_ref())?;
    outputs.add_opt("--stats", a.stats.as_ref())?;
    outputs.add_opt("--stats-csv", a.stats_csv.as_ref())?;
    outputs.add_opt("--timeline", a.timeline.as_ref())?;
    outputs.add_opt("--dram-trace", a.dram_trace.as_ref())?;
    a.waves.check_outputs(&mut outputs)?;
    let desc = MachineDesc::resolve(&a.machine)?;
    let mut scene = load_scene(&a)?;
    let reyes = match a.pipeline.as_deref() {
        Some(p) => p == "reyes",
        None => scene.pipeline.kind == PipelineKind::Reyes,
    };
    if a.stop_length.is_some() && !reyes {
        bail!("--stop-length is for the Reyes pipeline (`--pipeline reyes`)");
    }
    if reyes {
        if a.stats_csv.is_some() || a.timeline.is_some() || a.waves.wants_vcd() {
            bail!(
                "the Reyes pipeline writes --png, --reference-png and --stats; \
                 --stats-csv, --timeline and waveforms are the OpenGL pipeline's"
            );
        }
        return super::render_reyes::run(&a, &desc, &scene);
    }
    // A scene that asks for Reyes, drawn by OpenGL on request.
    scene.pipeline.kind = PipelineKind::OpenGl;
    warn_of_depth_range(&scene);
    let waves = match &a.vcd_kernel {
        Some(name) => a.waves.with_window(kernel_window(&a, &scene, &desc, name)?),
        None => a.waves.clone(),
    };
    let on_start: Option<imagine_units::runner::OnStart> = waves.wants_vcd().then(|| {
        let waves = waves.clone();
        Box::new(move |sim: &mut imagine_hdl::Sim| {
            waves.attach(sim).map(|_| ()).map_err(|e| format!("{e:#}"))
        }) as imagine_units::runner::OnStart
    });
    let mut stderr = std::io::stderr();
    // The bar is redrawn at each whole percent, and only on a terminal (a log gets no bar).
    let terminal = stderr.is_terminal();
    let mut drawn = None;
    let options = render_options(&a);
    let frame = render_with(&scene, &desc, options, on_start, |done, total| {
        let width = 40;
        let filled = done * width / total.max(1);
        let percent = done * 100 / total.max(1);
        if !terminal || drawn == Some(percent) {
            return;
        }
        drawn = Some(percent);
        let _ = write!(
            stderr,
            "\r{} [{}{}] batch {done}/{total}",
            scene.name,
            "#".repeat(filled),
            " ".repeat(width - filled)
        );
        if done == total {
            let _ = writeln!(stderr);
        }
    })?;
    let image = image_of(&frame);
    // Written before the reference runs, so that a frame is kept whatever the comparison.
    if let Some(p) = &a.png {
        image.write_png(p).map_err(anyhow::Error::msg)?;
    }
    let error = reference_error::measure(&scene, &frame)?;
    let (metrics, reference_seconds) = (error.metrics, error.seconds);
    let write_start = std::time::Instant::now();
    if let Some(p) = &a.reference_png {
        error.reference.write_png(p).map_err(anyhow::Error::msg)?;
    }
    if let Some(p) = &a.stats {
        let json = serde_json::json!({
            "frame": frame.stats,
            "reference_error": metrics,
            "reference_seconds": reference_seconds,
        });
        std::fs::write(p, serde_json::to_string_pretty(&json)? + "\n")
            .with_context(|| format!("cannot write `{}`", p.display()))?;
    }
    if let (Some(p), Some(timeline)) = (&a.timeline, &frame.timeline) {
        std::fs::write(p, serde_json::to_string(timeline)? + "\n")
            .with_context(|| format!("cannot write `{}`", p.display()))?;
    }
    if let Some(p) = &a.dram_trace {
        let write = || -> std::io::Result<()> {
            let mut w = std::io::BufWriter::new(std::fs::File::create(p)?);
            write_trace(&mut w, &frame.dram_requests)?;
            w.flush()
        };
        write().with_context(|| format!("cannot write `{}`", p.display()))?;
    }
    if let Some(p) = &a.stats_csv {
        std::fs::write(p, frame.stats.batches_csv())
            .with_context(|| format!("cannot write `{}`", p.display()))?;
    }
    let host = HostTimes {
        reference: reference_seconds,
        write: write_start.elapsed().as_secs_f64(),
    };
    print_stats(&frame, &metrics, &desc, &host);
    Ok(ExitCode::SUCCESS)
}

/// Host time the CLI spends around the render: the reference renderer and the comparison,
/// and writing the outputs (before the summary).
struct HostTimes {
    reference: f64,
    write: f64,
}

/// A rate in cycles per second with a unit that keeps three significant digits.
fn cycles_per_second(x: f64) -> String {
    if x >= 1e6 {
        format!("{:.2} M cycles/s", x / 1e6)
    } else {
        format!("{:.1} k cycles/s", x / 1e3)
    }
}

fn print_stats(f: &Frame, m: &Metrics, desc: &MachineDesc, host: &HostTimes) {
    let s = &f.stats;
    println!(
        "scene              {} ({}x{}, {} triangles)",
        s.scene, s.width, s.height, s.triangles
    );
    println!("machine            {} at {} MHz", s.machine, s.core_mhz);
    println!(
        "cycles             {} (frame; {} with the clear)",
        s.cycles, s.phases.frame_plus_clear_cycles
    );
    println!(
        "host phases        load {} cycles, clear {}, read-back {}",
        s.phases.load_cycles, s.phases.clear_cycles, s.phases.readback_cycles
    );
    println!("frames/s           {:.2}", s.frames_per_second);
    println!("vertices/s         {:.2} M", s.vertices_per_second / 1e6);
    println!(
        "fragments/s        {:.2} M ({} fragments)",
        s.fragments_per_second / 1e6,
        s.fragments
    );
    println!(
        "ops/cycle          {:.1} (arithmetic ops issued per core cycle, each cluster's counted)",
        s.ops_per_cycle
    );
    println!(
        "cluster occupancy  {:.1} % of frame cycles running a kernel ({:.1} % issuing, {:.1} % \
         stalled on stream buffers)",
        100.0 * s.cluster_occupancy,
        100.0 * s.cluster_occupancy_without_stalls,
        100.0 * (s.cluster_occupancy - s.cluster_occupancy_without_stalls)
    );
    if let Some(r) = s.rasterizer_occupancy {
        println!(
            "rasterizer         {:.1} % of frame cycles running a call of the hardware rasterizer",
            100.0 * r
        );
    }
    println!(
        "batches            {} of {} triangles, {} tile splits, {} composite rounds ({} merged, \
         {} fragments dropped)",
        s.batches,
        s.batch_triangles,
        s.tile_splits,
        s.composite_rounds,
        s.merge_rounds,
        s.merged_fragments
    );
    // Peaks: a word per DRAM cycle per channel; the SRF's words per core cycle; a read and
    // a write port per LRF per cluster.
    let dram_peak = (desc.dram.channels * 4) as f64 * desc.clocks.dram_mhz as f64 / 1e3;
    let srf_peak = desc.srf.words_per_cycle as f64;
    let lrf_peak = (2 * desc.lrf_names().len() * desc.cluster.count) as f64;
    let of_peak = |x: f64, peak: f64| 100.0 * x / peak.max(1e-12);
    println!(
        "DRAM               {:.3} GB/s ({:.1} % of {:.2} GB/s peak), row hits {:.1} % of accesses",
        s.dram_gbs,
        of_peak(s.dram_gbs, dram_peak),
        dram_peak,
        100.0 * s.dram_row_hit_rate
    );
    if let Some(tc) = &s.texture_cache {
        println!(
            "texture cache      {:.1} % hits ({} hits, {} misses, {} words of line fills)",
            100.0 * tc.hit_rate,
            tc.counts.hits,
            tc.counts.misses,
            tc.counts.fill_words
        );
    }
    println!(
        "traffic            {:.0} B per vertex, {:.1} B per fragment ({:.1} B of texels)",
        s.bytes_per_vertex, s.bytes_per_fragment, s.texel_bytes_per_fragment
    );
    println!(
        "SRF                {:.2} words/cycle ({:.1} % of {} words/cycle peak)",
        s.srf_words_per_cycle,
        of_peak(s.srf_words_per_cycle, srf_peak),
        desc.srf.words_per_cycle
    );
    let model = &s.srf_model;
    println!(
        "SRF model          Table 5.3 at its largest batch (i = {}, t = {}, f = {:.1}): \
         barycentric {:.0} words, scanline {:.0}; measured (barycentric) {} words of \
         interpolation records and fragments at once, plan {} words",
        model.interpolants,
        model.peak_batch_triangles,
        model.peak_batch_fragments_per_triangle,
        model.barycentric_words,
        model.scanline_words,
        model.measured_words,
        model.plan_words
    );
    let lrf_words = s.lrf_reads_per_cycle + s.lrf_writes_per_cycle;
    println!(
        "LRF                {:.1} words/cycle ({:.1} read, {:.1} written; {:.1} % of the {} \
         its ports can move), {:.1} GB/s",
        lrf_words,
        s.lrf_reads_per_cycle,
        s.lrf_writes_per_cycle,
        of_peak(lrf_words, lrf_peak),
        lrf_peak,
        lrf_words * 4.0 * s.core_mhz * 1e6 / 1e9
    );
    let sp = &s.specialisation;
    println!(
        "pipeline           {} ({} words per vertex, {} per fragment, interpolants {})",
        if sp.specialised {
            "specialised for the scene"
        } else {
            "general (--no-specialize)"
        },
        sp.words_per_vertex,
        sp.words_per_fragment,
        sp.interpolants.join(" ")
    );
    println!("  kernels built    {}", sp.kernels_built.join(", "));
    if !sp.kernels_not_reached.is_empty() {
        println!(
            "  not reached      {} (not compiled)",
            sp.kernels_not_reached.join(", ")
        );
    }
    println!("  left out         {}", sp.left_out.join(", "));
    println!("where cycles went  (every frame cycle in one category; share of frame cycles)");
    for (name, cycles) in s.attribution.rows() {
        if cycles > 0 {
            println!(
                "  {:<24} {:>12} cycles {:>5.1} %",
                name,
                cycles,
                100.0 * cycles as f64 / s.cycles.max(1) as f64
            );
        }
    }
    let waiting = s.waiting_on.total();
    if waiting > 0 {
        println!("  waiting, on what         (share of the waiting cycles)");
        for (on, cycles) in s.waiting_on.rows() {
            if cycles > 0 {
                println!(
                    "    {:<22} {:>12} cycles {:>5.1} %",
                    on,
                    cycles,
                    100.0 * cycles as f64 / waiting as f64
                );
            }
        }
    }
    // Kernels by the names the pipeline registered them under (`imagine kernel show NAME`).
    println!("kernel breakdown   (share of frame cycles)");
    let width = s
        .kernels
        .iter()
        .map(|k| k.kernel.len())
        .max()
        .unwrap_or(0)
        .max(16);
    for k in &s.kernels {
        println!(
            "  {:<width$} {:>6} calls {:>12} cycles {:>5.1} %",
            k.kernel,
            k.calls,
            k.cycles,
            100.0 * k.cycles as f64 / s.cycles.max(1) as f64
        );
    }
    println!(
        "reference error    PSNR {:.2} dB, max abs error {} of 255 (an 8-bit channel), {:.3} % \
         of pixels differ, {:.3} % differ in coverage",
        m.psnr_db,
        m.max_abs_error,
        100.0 * m.differing_share,
        100.0 * m.coverage_mismatch_share
    );
    let visibility = m.visibility_differing_share.map_or(String::new(), |v| {
        format!(", {:.3} % show another triangle", 100.0 * v)
    });
    println!(
        "  covered in both  {} pixels: PSNR {:.2} dB, max abs error {} of 255{visibility}; \
         {:.3} % of pixels wrongly covered, {:.3} % missed",
        m.covered_in_both_pixels,
        m.covered_psnr_db,
        m.covered_max_abs_error_levels,
        100.0 * m.wrongly_covered_share,
        100.0 * m.missed_share
    );
    let p = &s.phases;
    let simulated = p.load_cycles + p.frame_plus_clear_cycles + p.readback_cycles;
    let jumped = if s.skipped_cycles > 0 {
        format!(
            ", {:.1} % of them idle and jumped over",
            100.0 * s.skipped_cycles as f64 / simulated.max(1) as f64
        )
    } else {
        String::new()
    };
    let prepare = (s.host_seconds - s.compile_seconds - s.simulate_seconds).max(0.0);
    println!(
        "host               {:.2} s: compile {:.2} s ({} of {} kernels from the cache), \
         prepare {:.2} s, simulate {:.2} s ({} over every phase simulated{jumped}), \
         reference {:.2} s, write {:.2} s",
        s.host_seconds + host.reference + host.write,
        s.compile_seconds,
        s.kernels_from_cache,
        s.kernel_programs,
        prepare,
        s.simulate_seconds,
        cycles_per_second(s.simulated_cycles_per_second),
        host.reference,
        host.write
    );
}
