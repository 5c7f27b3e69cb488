//! `imagine s3`: run a triangle trace, or a scene's triangles from the OpenGL pipeline's
//! geometry stage on the stream machine, through the S3 superscalar out-of-order
//! rasterizer (`imagine_units::s3`) and report its triangle-level parallelism, cycles and
//! stalls; the frame is checked against in-order drawing every run.
//!
//! **Scenes** (`--scene`): the stream machine runs the scene's vertex programs,
//! `assemble_clip` and `viewport_cull`, and stores each kept batch's records to its DRAM
//! (`imagine_pipelines::opengl::render::render_geometry`); the host reads them out of DRAM
//! into S3's trace memory in drawing order, as window-space `.tri` triangles: window x, y,
//! depth `z_ndc·½ + ½` and the vertex program's colour per corner. S3 then snaps them to
//! its fixed point (1/16 pixel, 24-bit depth, 8-bit colour), interpolates colour and depth
//! linearly in the window (the pipeline: perspective-correct), draws no texture, clamps
//! depth to [0, 1] (the pipeline drops fragments outside it) and keeps its own clear
//! (black, far depth). Triangles the geometry discarded never reach S3.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::{ArgGroup, Args};
use imagine_pipelines::compile::CompileCache;
use imagine_pipelines::opengl::render::{Geometry, RenderOptions, render_geometry};
use imagine_pipelines::scene::model::{Blend, DepthTest, PipelineKind};
use imagine_pipelines::scene::{self, LoadOptions};
use imagine_units::desc::{MachineDesc, S3_MEMORY};
use imagine_units::s3::game::{self, GameParams};
use imagine_units::s3::issue::CAUSE_NAMES;
use imagine_units::s3::raster::{Frame, Mode, TraceTriangle, reference_frame};
use imagine_units::s3::run::{RunOptions, S3Report, run};
use imagine_units::s3::{S3Config, S3Memory, Select};
use imagine_verif::image::Image;

use super::outputs::Outputs;
use super::waves::WaveArgs;

#[derive(Args)]
#[command(group(ArgGroup::new("input").required(true).args(["trace", "scene"])))]
#[command(after_help = "\
Scenes (--scene): a built-in scene (SPHERE, RATE-1, ADVS-1, ...) or a `.toml` scene file,
OpenGL pipeline, depth test LESS, no blending; its geometry runs on the stream machine of
--machine and its triangles are stored to DRAM and fed to S3 in drawing order.

Traces: a `.tri` file (window-space triangles, `W H` then 3 × (x y z r g b) per line; all
opaque and Z-buffered, depth test LESS) or a built-in generated game-like frame:
  game-strips  640×480: full-window background, 64 strips of 40 small triangles, 200 blended particles
  game-sky     640×480: a 92,160-pixel sky of two triangles, then strips and particles (turok3-like)

Parameters come from the machine's [s3] table (accelerators, window_per_accelerator,
split, split_height, chain_break, select, ...); the flags above override some of them.
Every run checks its frame against in-order drawing of the trace and fails if they differ.")]
pub struct S3Args {
    /// Triangle trace: a `.tri` file or a built-in (game-strips, game-sky)
    #[arg(long, value_name = "F.tri|NAME")]
    trace: Option<String>,
    /// Scene whose OpenGL geometry stage, run on the stream machine, feeds S3: a built-in
    /// name or a `.toml` scene file
    #[arg(long, value_name = "NAME|F.toml")]
    scene: Option<String>,
    /// With --scene: window side in pixels (a square window instead of the scene's)
    #[arg(long, value_name = "N")]
    size: Option<u32>,
    /// Machine name or description file (its [s3] table; with --scene also the stream
    /// machine the geometry runs on)
    #[arg(long, default_value = "gold8")]
    machine: String,
    /// Rasterizing accelerators K (default: the machine's)
    #[arg(long, value_name = "K")]
    accelerators: Option<usize>,
    /// Candidate buffers per accelerator (default: the machine's)
    #[arg(long, value_name = "N")]
    window: Option<usize>,
    /// Frame-buffer memory: `ideal` (the paper's) or `dram` (the machine's DRAM channels);
    /// default: the machine's `s3.memory`
    #[arg(long, value_name = "ideal|dram", value_parser = clap::builder::PossibleValuesParser::new(S3_MEMORY))]
    memory: Option<String>,
    /// Do not split tall triangles into slices
    #[arg(long)]
    no_split: bool,
    /// No dependence-chain breaking
    #[arg(long)]
    no_chain_break: bool,
    /// Also run K = 1 (same window per accelerator) and report the speedup over it
    #[arg(long)]
    speedup: bool,
    /// Run every K in this list (e.g. 1,2,4,8,16) and print a table with speedups over the
    /// first
    #[arg(
        long,
        value_name = "K,K,...",
        value_delimiter = ',',
        conflicts_with = "accelerators"
    )]
    sweep: Vec<usize>,
    /// Write the frame as a PNG
    #[arg(long, value_name = "F")]
    png: Option<PathBuf>,
    /// Write the statistics as JSON
    #[arg(long, value_name = "F")]
    json: Option<PathBuf>,
    /// Write the mean busy accelerators of every window of --csv-window cycles as CSV
    #[arg(long, value_name = "F")]
    csv: Option<PathBuf>,
    /// Cycles per CSV row
    #[arg(long, value_name = "N", default_value_t = 100)]
    csv_window: u64,
    #[command(flatten)]
    waves: WaveArgs,
}

/// The largest K the sweep and the flags accept: the machine description's bound.
const MAX_K: usize = imagine_units::limits::MAX_S3_ACCELERATORS;

pub fn run_cmd(a: S3Args) -> Result<ExitCode> {
    let desc = MachineDesc::resolve(&a.machine)?;
    let mut outputs = Outputs::default();
    outputs.add_opt("--png", a.png.as_ref())?;
    outputs.add_opt("--json", a.json.as_ref())?;
    outputs.add_opt("--csv", a.csv.as_ref())?;
    a.waves.check_outputs(&mut outputs)?;
    if a.csv_window == 0 {
        bail!("--csv-window 0: a window must be at least 1 cycle");
    }
    let mut cfg = S3Config::of(&desc);
    if let Some(k) = a.accelerators {
        check_k("--accelerators", k)?;
        cfg.accelerators = k;
    }
    if let Some(w) = a.window {
        if !(1..=64).contains(&w) {
            bail!("--window {w}: candidate buffers per accelerator must be 1..=64");
        }
        cfg.window_per_accelerator = w;
    }
    match a.memory.as_deref() {
        Some("ideal") => cfg.memory = S3Memory::Ideal,
        Some(_) => cfg.memory = S3Memory::Dram(Box::new(desc.clone())),
        None => {}
    }
    cfg.split &= !a.no_split;
    cfg.chain_break &= !a.no_chain_break;
    for &k in &a.sweep {
        check_k("--sweep", k)?;
    }
    if !a.sweep.is_empty() && a.waves.wants_vcd() {
        bail!("--vcd needs a single run, not --sweep");
    }
    if a.trace.is_some() && a.size.is_some() {
        bail!("--size sets a --scene's window; a --trace gives its own");
    }
    let (source, width, height, tris, geometry) = match (&a.trace, &a.scene) {
        (Some(trace), _) => {
            let (source, width, height, tris) = load_trace(trace)?;
            (source, width, height, tris, None)
        }
        (None, Some(name)) => {
            let g = scene_geometry(name, a.size, &desc)?;
            let tris = trace_triangles(&g);
            (name.clone(), g.width, g.height, tris, Some(g))
        }
        (None, None) => bail!("give --trace or --scene"),
    };
    let golden = reference_frame(&tris, width, height);
    let go = |cfg: &S3Config, waves: Option<&WaveArgs>| -> Result<S3Report> {
        let mut opts = RunOptions {
            window: a.csv_window,
            ..RunOptions::default()
        };
        if let Some(w) = waves.filter(|w| w.wants_vcd()).cloned() {
            opts.on_start = Some(Box::new(move |sim| {
                w.attach(sim).map(|_| ()).map_err(|e| format!("{e:#}"))
            }));
        }
        let r = run(cfg, width, height, &tris, opts)?;
        if r.in_flight_hazards > 0 {
            bail!(
                "K={}: two primitives in hazard were in flight in {} cycles",
                cfg.accelerators,
                r.in_flight_hazards
            );
        }
        if r.frame != golden {
            let differ = r
                .frame
                .colour
                .iter()
                .zip(&golden.colour)
                .filter(|(a, b)| a != b)
                .count();
            bail!(
                "K={}: the frame differs from in-order drawing in {differ} pixel colours",
                cfg.accelerators
            );
        }
        Ok(r)
    };
    if !a.sweep.is_empty() {
        let mut rows = Vec::new();
        for &k in &a.sweep {
            let mut c = cfg.clone();
            c.accelerators = k;
            rows.push((c.clone(), go(&c, None)?));
        }
        if let Some(g) = &geometry {
            print_geometry(g);
        }
        print_sweep(&source, &desc, &rows);
        if let Some(p) = &a.json {
            let base = rows[0].1.cycles;
            let runs: Vec<_> = rows.iter().map(|(c, r)| json(c, r, Some(base))).collect();
            let mut out =
                serde_json::json!({ "trace": source, "machine": desc.name, "runs": runs });
            if let Some(g) = &geometry {
                out["scene"] = geometry_json(g);
            }
            write(p, &serde_json::to_string_pretty(&out)?)?;
        }
        return Ok(ExitCode::SUCCESS);
    }
    let r = go(&cfg, Some(&a.waves))?;
    let base = if a.speedup {
        let mut c = cfg.clone();
        c.accelerators = 1;
        Some(go(&c, None)?.cycles)
    } else {
        None
    };
    if let Some(g) = &geometry {
        print_geometry(g);
    }
    print_report(&source, &desc, &cfg, &r, base);
    if let Some(p) = &a.png {
        png(&r.frame, p)?;
    }
    if let Some(p) = &a.json {
        let mut j = json(&cfg, &r, base);
        j["trace"] = source.clone().into();
        j["machine"] = desc.name.clone().into();
        if let Some(g) = &geometry {
            j["scene"] = geometry_json(g);
        }
        write(p, &serde_json::to_string_pretty(&j)?)?;
    }
    if let Some(p) = &a.csv {
        let mut s = String::from("cycle,mean_busy_accelerators\n");
        for (i, m) in r.windows.iter().enumerate() {
            let _ = writeln!(s, "{},{m:.4}", i as u64 * r.window);
        }
        write(p, &s)?;
    }
    Ok(ExitCode::SUCCESS)
}

fn check_k(flag: &str, k: usize) -> Result<()> {
    if !(1..=MAX_K).contains(&k) {
        bail!("{flag} {k}: accelerators must be 1..={MAX_K}");
    }
    Ok(())
}

fn write(p: &Path, text: &str) -> Result<()> {
    std::fs::write(p, text).with_context(|| format!("cannot write `{}`", p.display()))
}

fn png(frame: &Frame, p: &Path) -> Result<()> {
    Image::from_rgba8_words(frame.width, frame.height, &frame.colour)
        .write_png(p)
        .map_err(anyhow::Error::msg)
}

/// A built-in generated trace or a `.tri` file: (name, width, height, triangles).
fn load_trace(name: &str) -> Result<(String, u32, u32, Vec<TraceTriangle>)> {
    if let Some(p) = GameParams::builtin(name) {
        return Ok((name.to_string(), p.width, p.height, game::generate(&p)));
    }
    let path = Path::new(name);
    if !name.ends_with(".tri") && !path.exists() {
        bail!(
            "--trace `{name}`: no such file or built-in trace; the built-ins are {}",
            game::BUILTIN
                .iter()
                .map(|(n, _)| *n)
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let text = imagine_units::limits::read_text_file(path)
        .with_context(|| format!("cannot read trace `{name}`"))?;
    let scene =
        imagine_pipelines::scene::parse_tri(name, &text).map_err(|e| anyhow::anyhow!("{e}"))?;
    let tris = scene
        .positions
        .chunks(3)
        .zip(scene.colours.chunks(3))
        .map(|(p, c)| TraceTriangle {
            positions: [p[0], p[1], p[2]],
            colours: [c[0], c[1], c[2]],
            mode: Mode::Opaque,
        })
        .collect();
    Ok((name.to_string(), scene.width, scene.height, tris))
}

/// Scene `name`'s triangles after its geometry stage on the stream machine `desc` (see the
/// module notes); an error names the scene and what S3 cannot draw of it.
fn scene_geometry(name: &str, size: Option<u32>, desc: &MachineDesc) -> Result<Geometry> {
    if let Some(size) = size
        && (size == 0 || size > scene::MAX_WINDOW)
    {
        bail!("--size {size} is outside 1..={}", scene::MAX_WINDOW);
    }
    let opts = LoadOptions {
        size,
        ..LoadOptions::default()
    };
    // The loader's errors name the scene.
    let scene = scene::load(name, &opts)?;
    let p = &scene.pipeline;
    if p.kind != PipelineKind::OpenGl {
        bail!(
            "--scene `{name}`: S3 takes the OpenGL pipeline's geometry; this scene's pipeline.kind is not opengl"
        );
    }
    if p.depth_test != DepthTest::Less {
        bail!(
            "--scene `{name}`: S3's depth test is LESS; the scene's pipeline.depth_test is {:?}",
            p.depth_test
        );
    }
    if p.blend != Blend::None {
        bail!(
            "--scene `{name}`: S3 blends only 50/50 without depth writes; the scene's pipeline.blend is {:?}",
            p.blend
        );
    }
    let options = RenderOptions {
        cache: CompileCache::from_env(),
        ..RenderOptions::default()
    };
    render_geometry(&scene, desc, options, None, |_, _| {})
        .map_err(|e| anyhow::anyhow!("--scene `{name}` on {}: {e}", desc.name))
}

/// The geometry's triangles as S3's trace triangles: the `.tri` fields, all opaque.
fn trace_triangles(g: &Geometry) -> Vec<TraceTriangle> {
    g.triangles
        .iter()
        .map(|t| TraceTriangle {
            positions: t.positions,
            colours: t.colours,
            mode: Mode::Opaque,
        })
        .collect()
}

fn print_geometry(g: &Geometry) {
    println!(
        "scene        {}: {} triangles; geometry on the stream machine {} cycles; {} to S3, {} discarded (clip, zero area, cull), {} left out (behind the eye or out of range)",
        g.stats.scene,
        g.stats.triangles,
        g.stats.cycles,
        g.triangles.len(),
        g.discarded,
        g.unrepresentable
    );
}

fn geometry_json(g: &Geometry) -> serde_json::Value {
    serde_json::json!({
        "name": g.stats.scene,
        "machine": g.stats.machine,
        "width": g.width,
        "height": g.height,
        "scene_triangles": g.stats.triangles,
        "triangles": g.triangles.len(),
        "discarded": g.discarded,
        "unrepresentable": g.unrepresentable,
        "geometry_cycles": g.stats.cycles,
    })
}

fn json(c: &S3Config, r: &S3Report, base: Option<u64>) -> serde_json::Value {
    let causes: serde_json::Map<String, serde_json::Value> = CAUSE_NAMES
        .iter()
        .zip(r.causes)
        .map(|(n, v)| (n.to_string(), v.into()))
        .collect();
    serde_json::json!({
        "accelerators": c.accelerators,
        "candidate_buffers": c.candidates(),
        "dest_reservation_stations": c.dest_rs(),
        "issue_storage_bits": c.issue_storage_bits(),
        "split": c.split,
        "split_height": c.split_height,
        "chain_break": c.chain_break,
        "select": if c.select == Select::Oldest { "oldest" } else { "random" },
        "cycles": r.cycles,
        "mean_parallelism": r.mean_parallelism(),
        "busy_histogram": r.busy_histogram,
        "triangles": r.triangles,
        "primitives": r.primitives,
        "culled": r.culled,
        "pixels": r.pixels,
        "fragments_passed": r.fragments_passed,
        "issue_cycles": causes,
        "window_full_cycles": r.window_full,
        "memory": r.memory,
        "memory_latency": c.memory_latency,
        "memory_stall_cycles": r.mem_stall_cycles,
        "dram": r.dram.as_ref().map(|d| serde_json::json!({
            "channels": d.channels,
            "frame_buffer_reads": d.fb_reads,
            "frame_buffer_writes": d.fb_writes,
            "reads": d.reads,
            "writes": d.writes,
            "activates": d.activates,
            "row_hits": d.row_hits,
            "refreshes": d.refreshes,
            "dram_cycles": d.dram_cycles,
        })),
        "speedup_over_k1": base.map(|b| b as f64 / r.cycles as f64),
        "k1_cycles": base,
        "frame_matches_in_order": true,
    })
}

fn describe(c: &S3Config) -> String {
    format!(
        "K={}, {} candidate buffers, {} dest RS, split {}, chain breaking {}, select {}, {} memory",
        c.accelerators,
        c.candidates(),
        c.dest_rs(),
        if c.split {
            format!("{} rows", c.split_height)
        } else {
            "off".into()
        },
        if c.chain_break { "on" } else { "off" },
        if c.select == Select::Oldest {
            "oldest"
        } else {
            "random"
        },
        c.memory.name(),
    )
}

fn print_report(source: &str, desc: &MachineDesc, c: &S3Config, r: &S3Report, base: Option<u64>) {
    let (w, h) = (r.frame.width, r.frame.height);
    println!("trace        {source} ({} triangles, {w}×{h})", r.triangles);
    println!("machine      {} [s3]: {}", desc.name, describe(c));
    println!("cycles       {}", r.cycles);
    println!(
        "primitives   {} issued, {} triangles culled; {} pixels rasterized, {} passed the depth test",
        r.primitives, r.culled, r.pixels, r.fragments_passed
    );
    println!(
        "parallelism  mean {:.3} busy accelerators",
        r.mean_parallelism()
    );
    let hist: Vec<String> = r
        .busy_histogram
        .iter()
        .enumerate()
        .map(|(n, c)| format!("{n}:{:.1}%", 100.0 * *c as f64 / r.cycles.max(1) as f64))
        .collect();
    println!("histogram    {}", hist.join(" "));
    let causes: Vec<String> = CAUSE_NAMES
        .iter()
        .zip(r.causes)
        .map(|(n, v)| format!("{n} {v}"))
        .collect();
    println!(
        "issue stage  {}; window full {}",
        causes.join(", "),
        r.window_full
    );
    if let Some(d) = &r.dram {
        println!(
            "memory       dram, {} channels: {} frame-buffer reads, {} writes; {} DRAM reads, {} writes, {} activates, {} row hits, {} DRAM cycles; accelerators held {} cycles",
            d.channels,
            d.fb_reads,
            d.fb_writes,
            d.reads,
            d.writes,
            d.activates,
            d.row_hits,
            d.dram_cycles,
            r.mem_stall_cycles
        );
    }
    if let Some(b) = base {
        println!(
            "speedup      {:.3} over K=1 ({b} cycles)",
            b as f64 / r.cycles as f64
        );
    }
    println!("frame        identical to in-order drawing");
}

fn print_sweep(source: &str, desc: &MachineDesc, rows: &[(S3Config, S3Report)]) {
    let c = &rows[0].0;
    println!(
        "{source} on {} [s3]: {} candidate buffers per accelerator, split {}, chain breaking {}, {} memory",
        desc.name,
        c.window_per_accelerator,
        if c.split { "on" } else { "off" },
        if c.chain_break { "on" } else { "off" },
        c.memory.name()
    );
    println!(
        "{:>4} {:>10} {:>8} {:>8} {:>10} {:>10} {:>10}",
        "K", "cycles", "TLP", "speedup", "no_accel", "dependence", "conflict"
    );
    let base = rows[0].1.cycles as f64;
    for (c, r) in rows {
        println!(
            "{:>4} {:>10} {:>8.3} {:>8.3} {:>10} {:>10} {:>10}",
            c.accelerators,
            r.cycles,
            r.mean_parallelism(),
            base / r.cycles as f64,
            r.causes[2],
            r.causes[3],
            r.causes[4]
        );
    }
    println!("every frame identical to in-order drawing");
}
