//! `imagine sweep`: error against run time. Renders a scene at every combination of the
//! knobs' values (the grid) through the path `imagine render` takes, compares each frame
//! with the reference renderer (`reference_error`), and writes one CSV row per point —
//! its knob values, cycles, modelled frames/s, host seconds and the error metrics — and,
//! with `--plot`, PSNR against cycles with the Pareto frontier.
//!
//! Points run in parallel (`--jobs`). Each finished point is appended at once to a
//! JSON-lines file beside the CSV (`F.csv` → `F.points.jsonl`), keyed by everything that
//! decides its frame: the scene file's content, the window, the whole machine description
//! and the render options. A sweep run again, interrupted or with more values, renders
//! only the points it has no record of; a changed scene file or machine file changes the
//! key, so old records are not reused for it. The CSV is written at the end from the
//! records, in grid order (the first knob varies slowest), whatever order the points
//! finished in.

mod batch_model;
mod knobs;
mod plot;

use std::collections::HashMap;
use std::fs::OpenOptions;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Mutex;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use imagine_pipelines::compile::CompileCache;
use imagine_pipelines::opengl::render::{Rasterizer, RenderOptions, render_with};
use imagine_pipelines::reyes::{self, frame::ReyesOptions};
use imagine_pipelines::scene::model::Filter;
use imagine_pipelines::scene::{self, LoadOptions, file::BUILTIN};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use self::batch_model::BatchModel;
use self::knobs::{Axis, Knob, KnobValue, Setup};
use super::outputs::Outputs;
use super::reference_error;
use imagine_verif::image::Metrics;

#[derive(Args)]
pub struct SweepArgs {
    /// Scene: a built-in name (`imagine scene list`) or a `.toml` scene file or `.tri`
    /// triangle file
    scene: String,
    /// A knob and its values, NAME=V1,V2,…: machine (a built-in name or a TOML file),
    /// batch (triangles per batch), filter (nearest, bilinear, trilinear: every texture's),
    /// flush_to_zero, normalise_clip and reference_depth (true, false: the machine's
    /// arithmetic and the scene's pipeline settings), newton_raphson (0 to 3: irast's
    /// reciprocal, 0 the divide unit), stop_length (pixels: the point renders the scene's
    /// patches through the Reyes pipeline; with machine and flush_to_zero only), rasterizer
    /// (kernels, hardware: the thesis's hardware rasterizer added to the machine); repeat
    /// for a grid of every combination
    #[arg(long = "knob", value_name = "NAME=V1,V2,…", required = true)]
    knobs: Vec<String>,
    /// The CSV to write, one row per point in grid order; finished points are kept in
    /// F.points.jsonl beside it, from which a rerun resumes
    #[arg(long, value_name = "F.csv")]
    csv: PathBuf,
    /// Also plot PSNR against cycles, the Pareto frontier marked, as PNG
    #[arg(long, value_name = "F.png")]
    plot: Option<PathBuf>,
    /// Points rendered at once [default: the host's logical CPUs]
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=256))]
    jobs: Option<u32>,
    /// The machine of every point, unless the `machine` knob varies it [default: gold8]
    #[arg(long, value_name = "M")]
    machine: Option<String>,
    /// Window side in pixels: overrides the scene's window with a square one
    #[arg(long, value_name = "N")]
    size: Option<u32>,
}

/// One point's measurements, as kept in the JSON-lines file and written to the CSV.
#[derive(Clone, Debug, Serialize, Deserialize)]
struct PointResult {
    /// Core cycles of the frame.
    cycles: u64,
    /// Modelled frames per second at the machine's core clock.
    frames_per_second: f64,
    /// Host seconds for the point: scene, render and reference.
    host_seconds: f64,
    /// Share of the frame's cycles a kernel ran (0 to 1).
    cluster_occupancy: f64,
    /// The most triangles per batch the pipeline took, and the frame's batches.
    batch_triangles: usize,
    batches: u64,
    /// DRAM bandwidth over the frame, 10⁹ bytes per second.
    dram_gbs: f64,
    /// PSNR against the reference over the window, dB; `None` when identical.
    psnr_db: Option<f64>,
    /// Largest RGB channel difference, levels of 255.
    max_abs_error: u8,
    differing_pixels_share: f64,
    /// Pixels that are background (black) in one frame only, share of the window.
    coverage_differences_share: f64,
    covered_in_both_pixels: usize,
    /// PSNR over the pixels both frames cover, dB; `None` when identical there.
    covered_psnr_db: Option<f64>,
    covered_max_abs_error_levels: u8,
    wrongly_covered_share: f64,
    missed_share: f64,
    visibility_differing_share: Option<f64>,
    /// The texture cache's hits over texel references, on a machine that has one.
    texture_cache_hit_rate: Option<f64>,
    /// Reyes points: the quads `subdiv` wrote.
    #[serde(default)]
    quads: Option<u64>,
}

/// A line of the JSON-lines file.
#[derive(Serialize, Deserialize)]
struct PointRecord {
    key: String,
    /// The point's knob values (for a person reading the file; the key decides).
    knobs: Vec<(String, String)>,
    result: PointResult,
}

/// A point of the grid.
struct Point {
    /// The index of its value on each axis.
    values: Vec<usize>,
    setup: Setup,
    key: String,
}

const CSV_METRICS: [&str; 19] = [
    "cycles",
    "frames_per_second",
    "host_seconds",
    "cluster_occupancy",
    "batch_triangles",
    "batches",
    "dram_gbs",
    "psnr_db",
    "max_abs_error",
    "differing_pixels_share",
    "coverage_differences_share",
    "covered_in_both_pixels",
    "covered_psnr_db",
    "covered_max_abs_error_levels",
    "wrongly_covered_share",
    "missed_share",
    "visibility_differing_share",
    "texture_cache_hit_rate",
    "quads",
];

impl PointResult {
    /// The CSV fields, in the order of [`CSV_METRICS`]; an infinite PSNR is `inf`, an
    /// unknown share is empty.
    fn csv_fields(&self) -> [String; 19] {
        let psnr = |p: Option<f64>| p.map_or("inf".to_string(), |v| format!("{v:.4}"));
        [
            self.cycles.to_string(),
            format!("{:.4}", self.frames_per_second),
            format!("{:.3}", self.host_seconds),
            format!("{:.4}", self.cluster_occupancy),
            self.batch_triangles.to_string(),
            self.batches.to_string(),
            format!("{:.3}", self.dram_gbs),
            psnr(self.psnr_db),
            self.max_abs_error.to_string(),
            format!("{:.6}", self.differing_pixels_share),
            format!("{:.6}", self.coverage_differences_share),
            self.covered_in_both_pixels.to_string(),
            psnr(self.covered_psnr_db),
            self.covered_max_abs_error_levels.to_string(),
            format!("{:.6}", self.wrongly_covered_share),
            format!("{:.6}", self.missed_share),
            self.visibility_differing_share
                .map_or(String::new(), |v| format!("{v:.6}")),
            self.texture_cache_hit_rate
                .map_or(String::new(), |v| format!("{v:.4}")),
            self.quads.map_or(String::new(), |q| q.to_string()),
        ]
    }
}

/// The JSON-lines file beside the CSV: `F.csv` → `F.points.jsonl`.
fn records_path(csv: &Path) -> PathBuf {
    csv.with_extension("points.jsonl")
}

/// The scene's text (a built-in's embedded file, or the file on disk), hashed: part of
/// every point's key. Assets the file names (meshes, images) are not hashed.
fn scene_content_hash(name_or_path: &str) -> Result<blake3::Hash> {
    let lower = name_or_path.to_ascii_lowercase();
    if lower.ends_with(".toml") || lower.ends_with(".tri") {
        let bytes = std::fs::read(name_or_path)
            .with_context(|| format!("cannot read the scene `{name_or_path}`"))?;
        return Ok(blake3::hash(&bytes));
    }
    match BUILTIN
        .iter()
        .find(|(name, _)| name.eq_ignore_ascii_case(name_or_path))
    {
        Some((_, text)) => Ok(blake3::hash(text.as_bytes())),
        // Loading it gives the error that lists the scenes.
        None => {
            scene::load(name_or_path, &LoadOptions::default())?;
            bail!("unknown scene `{name_or_path}`")
        }
    }
}

/// A point's key: every input that decides its frame and cycles.
fn point_key(scene_hash: &blake3::Hash, size: Option<u32>, setup: &Setup) -> String {
    let mut h = blake3::Hasher::new();
    h.update(b"imagine sweep point 5\n");
    h.update(scene_hash.as_bytes());
    h.update(
        format!(
            "{size:?}\n{:?}\n{:?}\n{:?}\n{:?}\n{:?}\n{:?}\n{:?}",
            setup.machine,
            setup.batch,
            setup.filter,
            setup.normalise_clip,
            setup.reference_depth,
            setup.newton_raphson,
            setup.stop_length
        )
        .as_bytes(),
    );
    // (Only a point on the scanline kernels says so, so the records of points from
    // before the knob had that value stay valid.)
    if setup.rasterizer != Rasterizer::Barycentric {
        h.update(format!("\nrasterizer {}", setup.rasterizer).as_bytes());
    }
    h.finalize().to_hex().to_string()
}

/// Every combination of the axes' value indices, the first axis varying slowest.
fn grid(axes: &[Axis]) -> Vec<Vec<usize>> {
    let mut points = vec![Vec::new()];
    for axis in axes {
        points = points
            .into_iter()
            .flat_map(|p| {
                (0..axis.values.len()).map(move |v| {
                    let mut p = p.clone();
                    p.push(v);
                    p
                })
            })
            .collect();
    }
    points
}

/// The records already in the JSON-lines file, by key. A line that does not parse (a
/// write cut short when a sweep was stopped) is skipped.
fn read_records(path: &Path) -> Result<HashMap<String, PointResult>> {
    let file = match std::fs::File::open(path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(HashMap::new()),
        Err(e) => bail!("cannot read `{}`: {e}", path.display()),
    };
    let mut records = HashMap::new();
    for line in BufReader::new(file).lines() {
        let line = line.with_context(|| format!("cannot read `{}`", path.display()))?;
        if let Ok(r) = serde_json::from_str::<PointRecord>(&line) {
            records.insert(r.key, r.result);
        }
    }
    Ok(records)
}

/// The point's knob values as (name, value text) pairs.
fn knob_values<'a>(axes: &'a [Axis], point: &Point) -> Vec<(&'static str, &'a str)> {
    axes.iter()
        .zip(&point.values)
        .map(|(axis, &v)| (axis.knob.name(), axis.values[v].0.as_str()))
        .collect()
}

/// A point as a person reads it: `batch=64 machine=gold16`.
fn point_label(axes: &[Axis], point: &Point) -> String {
    knob_values(axes, point)
        .iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect::<Vec<_>>()
        .join(" ")
}

pub fn run(a: SweepArgs) -> Result<ExitCode> {
    let axes: Vec<Axis> = a
        .knobs
        .iter()
        .map(|k| knobs::parse_axis(k))
        .collect::<Result<_>>()?;
    for (i, axis) in axes.iter().enumerate() {
        if axes[..i].iter().any(|b| b.knob == axis.knob) {
            bail!(
                "--knob {} is given twice: give its values in one --knob",
                axis.knob.name()
            );
        }
    }
    knobs::check_pipeline(&axes)?;
    if a.machine.is_some() && axes.iter().any(|x| x.knob == Knob::Machine) {
        bail!("--machine and --knob machine=…: give the machines as the knob's values");
    }
    if let Some(size) = a.size
        && (size == 0 || size > scene::MAX_WINDOW)
    {
        bail!("--size {size} is outside 1..={}", scene::MAX_WINDOW);
    }
    let records_file = records_path(&a.csv);
    let mut outputs = Outputs::default();
    outputs.add("--csv", &a.csv)?;
    outputs.add("the points file", &records_file)?;
    outputs.add_opt("--plot", a.plot.as_ref())?;
    let base_machine = a.machine.as_deref().unwrap_or("gold8");

    // Every scene the grid loads, loaded once now: a filter the scene refuses (a
    // `bump_env` environment map must be `nearest`) fails before any point renders.
    let scene_hash = scene_content_hash(&a.scene)?;
    let load_options = |filter: Option<Filter>| LoadOptions {
        size: a.size,
        subdivisions: None,
        filter,
    };
    let filters: Vec<Option<Filter>> = match axes.iter().find(|x| x.knob == Knob::Filter) {
        Some(axis) => axis
            .values
            .iter()
            .map(|(_, v)| match v {
                KnobValue::Filter(f) => Some(*f),
                _ => unreachable!("a filter axis holds filters"),
            })
            .collect(),
        None => vec![None],
    };
    let mut scene_name = String::new();
    for filter in &filters {
        let scene = scene::load(&a.scene, &load_options(*filter))
            .with_context(|| format!("the scene with --knob filter={}", filter_name(*filter)))?;
        scene_name = scene.name;
    }

    let points: Vec<Point> = grid(&axes)
        .into_iter()
        .map(|values| {
            let chosen: Vec<&KnobValue> = axes
                .iter()
                .zip(&values)
                .map(|(axis, &v)| &axis.values[v].1)
                .collect();
            let setup = Setup::of(base_machine, &chosen)?;
            let key = point_key(&scene_hash, a.size, &setup);
            Ok(Point { values, setup, key })
        })
        .collect::<Result<_>>()?;
    let done = read_records(&records_file)?;
    let pending: Vec<&Point> = points
        .iter()
        .filter(|p| !done.contains_key(&p.key))
        .collect();
    eprintln!(
        "{scene_name}: {} points, {} already in `{}`, {} to render",
        points.len(),
        points.len() - pending.len(),
        records_file.display(),
        pending.len()
    );

    let jobs = a.jobs.map_or_else(
        || std::thread::available_parallelism().map_or(1, |n| n.get()),
        |j| j as usize,
    );
    let (new_records, failed) =
        render_points(&a, &axes, &pending, jobs, &records_file, &load_options)?;
    let mut results = done;
    results.extend(new_records);

    write_csv(&a.csv, &axes, &points, &results, &failed)?;
    // The plot, the table and the batch model are of the points that rendered.
    let points: Vec<Point> = points
        .into_iter()
        .filter(|p| results.contains_key(&p.key))
        .collect();
    let (plot_points, frontier) = summary(&axes, &points, &results);
    if let Some(path) = &a.plot {
        let title = format!(
            "{scene_name}: error against cycles ({})",
            axes.iter()
                .map(|x| x.knob.name())
                .collect::<Vec<_>>()
                .join(", ")
        );
        plot::write(path, &title, &plot_points)?;
    }
    println!(
        "{:<40} {:>12} {:>12} {:>10}",
        "point", "cycles", "frames/s", "PSNR dB"
    );
    for (i, (p, point)) in plot_points.iter().zip(&points).enumerate() {
        let r = &results[&point.key];
        println!(
            "{:<40} {:>12} {:>12.2} {:>10} {}",
            p.label,
            p.cycles,
            r.frames_per_second,
            p.psnr_db.map_or("inf".into(), |v| format!("{v:.2}")),
            if frontier.contains(&i) {
                "frontier"
            } else {
                ""
            }
        );
    }
    print_batch_models(&axes, &points, &results);
    println!(
        "wrote `{}` ({} rows)",
        a.csv.display(),
        points.len() + failed.len()
    );
    if failed.is_empty() {
        return Ok(ExitCode::SUCCESS);
    }
    eprintln!(
        "{} points failed (their rows hold the error; a rerun tries them again):",
        failed.len()
    );
    let mut failed: Vec<_> = failed.into_iter().collect();
    failed.sort();
    for (_, message) in &failed {
        eprintln!("  {message}");
    }
    Ok(ExitCode::FAILURE)
}

/// With `batch` among the knobs: the fit of `r = c∞ + c_b / b` for each combination of the
/// other knobs, `b` the triangles per batch the pipeline took (which may be fewer than
/// asked for: the SRF and `xyrast`'s scratchpad bound it).
fn print_batch_models(axes: &[Axis], points: &[Point], results: &HashMap<String, PointResult>) {
    let Some(batch_axis) = axes
        .iter()
        .position(|x| x.knob == Knob::Batch && x.values.len() > 1)
    else {
        return;
    };
    // (the other knobs' value indices, that group's (batch, cycles) points)
    type Group = (Vec<usize>, Vec<(f64, f64)>);
    let mut groups: Vec<Group> = Vec::new();
    for p in points {
        let mut others = p.values.clone();
        others.remove(batch_axis);
        let r = &results[&p.key];
        let point = (r.batch_triangles as f64, r.cycles as f64);
        match groups.iter_mut().find(|(o, _)| *o == others) {
            Some((_, g)) => g.push(point),
            None => groups.push((others, vec![point])),
        }
    }
    println!("batch model r = c∞ + c_b/b (b: triangles per batch taken; cycles per frame)");
    for (others, group) in &groups {
        let label = axes
            .iter()
            .enumerate()
            .filter(|&(i, _)| i != batch_axis)
            .zip(others)
            .map(|((_, axis), &v)| format!("{}={}", axis.knob.name(), axis.values[v].0))
            .collect::<Vec<_>>()
            .join(" ");
        let label = if label.is_empty() {
            "(all points)".to_string()
        } else {
            label
        };
        match BatchModel::fit(group) {
            Some(m) => println!(
                "  {:<30} c∞ {:.3} M, c_b {:.1} M, b½ {:.1}, R² {:.3}",
                label,
                m.c_inf / 1e6,
                m.c_b / 1e6,
                m.b_half(),
                m.r_squared
            ),
            None => println!("  {label:<30} (needs two batch sizes the pipeline took)"),
        }
    }
}

fn filter_name(filter: Option<Filter>) -> &'static str {
    match filter {
        None => "(the scene's)",
        Some(Filter::Nearest) => "nearest",
        Some(Filter::Linear) => "bilinear",
        Some(Filter::Trilinear) => "trilinear",
    }
}

/// Renders the points `jobs` at a time, appending each one's record to `records_file` as
/// it finishes: the new records by key, and the points that failed (a render error:
/// the others go on) with their error, by key.
fn render_points(
    a: &SweepArgs,
    axes: &[Axis],
    pending: &[&Point],
    jobs: usize,
    records_file: &Path,
    load_options: &(dyn Fn(Option<Filter>) -> LoadOptions + Sync),
) -> Result<(HashMap<String, PointResult>, HashMap<String, String>)> {
    if pending.is_empty() {
        return Ok((HashMap::new(), HashMap::new()));
    }
    let file = OpenOptions::new()
        .create(true)
        .append(true)
        .open(records_file)
        .with_context(|| format!("cannot write `{}`", records_file.display()))?;
    let file = Mutex::new(file);
    let finished = Mutex::new(HashMap::new());
    let failed = Mutex::new(HashMap::new());
    // indicatif draws nothing when stderr is not a terminal.
    let bar = ProgressBar::new(pending.len() as u64).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} points, {elapsed} {msg}")
            .expect("a valid template"),
    );
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .build()
        .context("cannot start the sweep's threads")?;
    let result = pool.install(|| {
        pending.par_iter().try_for_each(|point| -> Result<()> {
            let knobs = knob_values(axes, point);
            let label = point_label(axes, point);
            bar.set_message(label.clone());
            let result = match render_point(a, point, load_options) {
                Ok(result) => result,
                Err(e) => {
                    failed
                        .lock()
                        .expect("no writer panicked")
                        .insert(point.key.clone(), format!("point {label}: {e:#}"));
                    bar.inc(1);
                    return Ok(());
                }
            };
            let record = PointRecord {
                key: point.key.clone(),
                knobs: knobs
                    .iter()
                    .map(|(k, v)| (k.to_string(), v.to_string()))
                    .collect(),
                result,
            };
            let line = serde_json::to_string(&record)? + "\n";
            {
                let mut file = file.lock().expect("no writer panicked");
                file.write_all(line.as_bytes())
                    .and_then(|()| file.flush())
                    .with_context(|| format!("cannot write `{}`", records_file.display()))?;
            }
            finished
                .lock()
                .expect("no writer panicked")
                .insert(record.key, record.result);
            bar.inc(1);
            Ok(())
        })
    });
    bar.finish_and_clear();
    result?;
    Ok((
        finished.into_inner().expect("no writer panicked"),
        failed.into_inner().expect("no writer panicked"),
    ))
}

/// Renders one point and measures its error.
fn render_point(
    a: &SweepArgs,
    point: &Point,
    load_options: &(dyn Fn(Option<Filter>) -> LoadOptions + Sync),
) -> Result<PointResult> {
    let start = Instant::now();
    let mut scene = scene::load(&a.scene, &load_options(point.setup.filter))?;
    if let Some(stop_length) = point.setup.stop_length {
        return render_reyes_point(&scene, &point.setup.machine, stop_length, start);
    }
    if let Some(on) = point.setup.normalise_clip {
        scene.pipeline.normalise_clip = on;
    }
    if let Some(on) = point.setup.reference_depth {
        scene.pipeline.reference_depth = on;
    }
    if let Some(n) = point.setup.newton_raphson {
        scene.pipeline.newton_raphson = n;
    }
    let options = RenderOptions {
        cache: CompileCache::from_env(),
        batch: point.setup.batch,
        rasterizer: point.setup.rasterizer,
        ..RenderOptions::default()
    };
    let frame = render_with(&scene, &point.setup.machine, options, None, |_, _| {})?;
    let error = reference_error::measure(&scene, &frame)?;
    Ok(measured(
        FrameNumbers {
            cycles: frame.stats.cycles,
            frames_per_second: frame.stats.frames_per_second,
            cluster_occupancy: frame.stats.cluster_occupancy,
            batch_triangles: frame.stats.batch_triangles,
            batches: frame.stats.batches,
            dram_gbs: frame.stats.dram_gbs,
            texture_cache_hit_rate: frame.stats.texture_cache.as_ref().map(|t| t.hit_rate),
            quads: None,
        },
        &error.metrics,
        start,
    ))
}

/// What a point's frame measured of itself (the rest of its [`PointResult`] is its error).
struct FrameNumbers {
    cycles: u64,
    frames_per_second: f64,
    cluster_occupancy: f64,
    batch_triangles: usize,
    batches: u64,
    dram_gbs: f64,
    texture_cache_hit_rate: Option<f64>,
    quads: Option<u64>,
}

/// A point's result: its frame's numbers, its error `m` against the reference, and the
/// host seconds since `start`.
fn measured(f: FrameNumbers, m: &Metrics, start: Instant) -> PointResult {
    let finite = |v: f64| v.is_finite().then_some(v);
    PointResult {
        cycles: f.cycles,
        frames_per_second: f.frames_per_second,
        host_seconds: start.elapsed().as_secs_f64(),
        cluster_occupancy: f.cluster_occupancy,
        batch_triangles: f.batch_triangles,
        batches: f.batches,
        dram_gbs: f.dram_gbs,
        psnr_db: finite(m.psnr_db),
        max_abs_error: m.max_abs_error,
        differing_pixels_share: m.differing_share,
        coverage_differences_share: m.coverage_mismatch_share,
        covered_in_both_pixels: m.covered_in_both_pixels,
        covered_psnr_db: finite(m.covered_psnr_db),
        covered_max_abs_error_levels: m.covered_max_abs_error_levels,
        wrongly_covered_share: m.wrongly_covered_share,
        missed_share: m.missed_share,
        visibility_differing_share: m.visibility_differing_share,
        texture_cache_hit_rate: f.texture_cache_hit_rate,
        quads: f.quads,
    }
}

/// Renders one point through the Reyes pipeline and measures its error against the
/// patches diced densely. Reyes has no batches, and its DRAM traffic is not counted
/// (0 in the CSV).
fn render_reyes_point(
    scene: &scene::model::Scene,
    machine: &imagine_units::desc::MachineDesc,
    stop_length: f32,
    start: Instant,
) -> Result<PointResult> {
    let options = ReyesOptions {
        stop_length,
        cache: CompileCache::from_env(),
        ..ReyesOptions::default()
    };
    let frame = reyes::frame::render(scene, machine, &options)?;
    let error = reference_error::measure_reyes(scene, &frame)?;
    let s = &frame.stats;
    let busy: u64 = s.kernels.iter().map(|k| k.cycles).sum();
    Ok(measured(
        FrameNumbers {
            cycles: s.cycles,
            frames_per_second: machine.clocks.core_mhz as f64 * 1e6 / s.cycles.max(1) as f64,
            cluster_occupancy: busy as f64 / s.cycles.max(1) as f64,
            batch_triangles: 0,
            batches: 0,
            dram_gbs: 0.0,
            texture_cache_hit_rate: None,
            quads: Some(s.quads),
        },
        &error.metrics,
        start,
    ))
}

/// Writes the CSV: a column per knob, then [`CSV_METRICS`], a row per point in grid order.
fn write_csv(
    path: &Path,
    axes: &[Axis],
    points: &[Point],
    results: &HashMap<String, PointResult>,
    failed: &HashMap<String, String>,
) -> Result<()> {
    let mut w = csv::Writer::from_path(path)
        .with_context(|| format!("cannot write `{}`", path.display()))?;
    let header: Vec<&str> = axes
        .iter()
        .map(|x| x.knob.name())
        .chain(CSV_METRICS)
        .chain(["error"])
        .collect();
    w.write_record(&header)?;
    for point in points {
        // A point that failed: its knobs, empty measurements and the error.
        let (fields, error) = match (results.get(&point.key), failed.get(&point.key)) {
            (Some(result), _) => (result.csv_fields().to_vec(), String::new()),
            (None, error) => (
                vec![String::new(); CSV_METRICS.len()],
                error.cloned().unwrap_or_default(),
            ),
        };
        let row: Vec<String> = knob_values(axes, point)
            .into_iter()
            .map(|(_, v)| v.to_string())
            .chain(fields)
            .chain([error])
            .collect();
        w.write_record(&row)?;
    }
    w.flush()
        .with_context(|| format!("cannot write `{}`", path.display()))?;
    Ok(())
}

/// The points as the plot draws them (in grid order) and the Pareto frontier's indices.
fn summary(
    axes: &[Axis],
    points: &[Point],
    results: &HashMap<String, PointResult>,
) -> (Vec<plot::PlotPoint>, Vec<usize>) {
    let plot_points: Vec<plot::PlotPoint> = points
        .iter()
        .map(|point| {
            let r = &results[&point.key];
            plot::PlotPoint {
                label: point_label(axes, point),
                cycles: r.cycles,
                psnr_db: r.psnr_db,
            }
        })
        .collect();
    let frontier = plot::pareto_frontier(&plot_points);
    (plot_points, frontier)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rasterizer_kernels_are_part_of_a_points_key() {
        let hash = blake3::hash(b"scene");
        let value = |text: &str| knobs::parse_axis(&format!("rasterizer={text}")).unwrap();
        let key = |text: &str| {
            let axis = value(text);
            let setup = Setup::of("gold8", &[&axis.values[0].1]).unwrap();
            point_key(&hash, None, &setup)
        };
        assert_eq!(key("barycentric"), key("kernels"));
        assert_ne!(key("barycentric"), key("scanline"));
    }
}
