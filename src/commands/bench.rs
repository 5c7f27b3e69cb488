//! Benchmarks: `imagine machine bench`, the simulator's throughput on a compute-dense
//! microcode loop, and `imagine bench`, whole frames: simulated cycles per host second,
//! host seconds per frame, and the pipeline's compile time cold and from the cache.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use imagine_pipelines::compile::CompileCache;
use imagine_pipelines::opengl::render::{RenderOptions, render_with};
use imagine_pipelines::scene::{self, LoadOptions};
use imagine_units::desc::MachineDesc;
use imagine_units::limits::MAX_DEMO_CYCLES;
use imagine_units::ops::Datapath;
use imagine_units::runner::{RunOptions, run_kernel};
use imagine_units::workloads::compute_dense;

/// Runs the compute-dense loop on `machine` for about `cycles` core cycles (VCD off) and
/// reports simulated cycles per host second and the op rate it implies.
pub fn machine(machine: &str, cycles: u64, datapath: Datapath) -> Result<ExitCode> {
    if !(1..=MAX_DEMO_CYCLES).contains(&cycles) {
        bail!("--cycles {cycles}: must be 1..={MAX_DEMO_CYCLES} (MAX_DEMO_CYCLES)");
    }
    let desc = MachineDesc::resolve(machine)?;
    let body = desc.latency.divsqrt_issue_interval.max(8) as u64;
    let iterations = u32::try_from((cycles / body).max(1)).context("--cycles is too large")?;
    let program = compute_dense(&desc, iterations)?;
    let start = Instant::now();
    let run = run_kernel(
        &desc,
        &program,
        &[],
        RunOptions {
            max_cycles: cycles * 2 + 1000,
            on_start: None,
            datapath,
        },
    )?;
    let host = start.elapsed().as_secs_f64();
    let s = &run.stats;
    let lanes = desc.cluster.count as f64;
    let ops: u64 = s.fu_ops.iter().sum();
    let rate = s.cycles as f64 / host;
    println!("machine            {}", desc.name);
    println!("datapath           {datapath}");
    println!("build              {}", build_kind());
    println!("simulated cycles   {}", s.cycles);
    println!("host time          {host:.3} s");
    println!("simulated rate     {:.2} M cycles/s", rate / 1e6);
    println!(
        "ops per cycle      {:.1} (all clusters)",
        s.ops_per_cycle(desc.cluster.count)
    );
    println!(
        "simulated op rate  {:.0} M cluster-ops/s",
        ops as f64 * lanes / host / 1e6
    );
    Ok(ExitCode::SUCCESS)
}

#[derive(Args)]
pub struct BenchArgs {
    /// Scenes to render (names or files); the default is an untextured, a fill-rate and a
    /// textured scene
    #[arg(default_values_t = ["SPHERE".to_string(), "RATE-8".into(), "ADVS-1".into()])]
    scenes: Vec<String>,
    /// Machine name or description file
    #[arg(long, default_value = "gold8")]
    machine: String,
    /// Frames rendered per scene with the kernels in the compile cache (medians are reported)
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=100))]
    runs: u32,
    /// Also write the results as JSON
    #[arg(long)]
    json: Option<PathBuf>,
}

/// One scene's measurements, in host seconds unless named otherwise.
#[derive(serde::Serialize)]
struct SceneBench {
    scene: String,
    machine: String,
    /// Core cycles simulated per frame (load, clear, frame and read-back).
    simulated_cycles: u64,
    /// Compiling the pipeline's kernels with an empty cache.
    compile_cold: f64,
    /// The same kernels read back from the cache (median).
    compile_warm: f64,
    /// Simulating the frame (median of the warm runs).
    simulate: f64,
    /// Everything a warm frame takes: building, compiling, simulating, comparing (median).
    host_per_frame: f64,
    simulated_cycles_per_second: f64,
    /// How the simulator was built (see `build_kind`): rows of two builds compare only
    /// with that said.
    build: &'static str,
}

/// How this binary was built: `scripts/build-pgo` sets `IMAGINE_BUILD=pgo` for its
/// profile-guided build; a plain `cargo build` leaves it unset.
fn build_kind() -> &'static str {
    match option_env!("IMAGINE_BUILD") {
        Some("pgo") => "profile-guided (scripts/build-pgo)",
        Some("pgo-instrumented") => "instrumented for profiling (slow)",
        _ if cfg!(debug_assertions) => "debug",
        _ => "release",
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// `imagine bench`: each scene rendered once with a cold compile cache, then `runs` times
/// with the kernels in it; every run must simulate the same cycles.
pub fn frames(a: BenchArgs) -> Result<ExitCode> {
    let desc = MachineDesc::resolve(&a.machine)?;
    let dir = std::env::temp_dir().join(format!("imagine-bench-{}", std::process::id()));
    let result = bench_scenes(&a, &desc, &dir);
    // The cache was the bench's own: it goes, whatever happened.
    let _ = std::fs::remove_dir_all(&dir);
    let rows = result?;
    println!(
        "{:<10} {:>12} {:>13} {:>13} {:>12} {:>12} {:>13}",
        "scene", "cycles", "compile cold", "compile warm", "simulate", "M cycles/s", "host/frame"
    );
    for r in &rows {
        println!(
            "{:<10} {:>12} {:>11.2} s {:>11.2} s {:>10.2} s {:>12.2} {:>11.2} s",
            r.scene,
            r.simulated_cycles,
            r.compile_cold,
            r.compile_warm,
            r.simulate,
            r.simulated_cycles_per_second / 1e6,
            r.host_per_frame
        );
    }
    println!(
        "machine {}; {} warm run(s) per scene, medians; host: {} logical CPUs; build: {}",
        desc.name,
        a.runs,
        std::thread::available_parallelism().map_or(1, |n| n.get()),
        build_kind()
    );
    if let Some(path) = &a.json {
        std::fs::write(path, serde_json::to_string_pretty(&rows)? + "\n")
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(ExitCode::SUCCESS)
}

fn bench_scenes(
    a: &BenchArgs,
    desc: &MachineDesc,
    dir: &std::path::Path,
) -> Result<Vec<SceneBench>> {
    let mut rows = Vec::new();
    for name in &a.scenes {
        let scene = scene::load(name, &LoadOptions::default())?;
        let frame = |cache: CompileCache| -> Result<(u64, f64, f64, f64)> {
            let start = Instant::now();
            let options = RenderOptions {
                cache,
                ..RenderOptions::default()
            };
            let f = render_with(&scene, desc, options, None, |_, _| {})?;
            let host = start.elapsed().as_secs_f64();
            let s = &f.stats;
            let p = &s.phases;
            let cycles = p.load_cycles + p.frame_plus_clear_cycles + p.readback_cycles;
            Ok((cycles, s.compile_seconds, s.simulate_seconds, host))
        };
        // Each scene compiles into a cache of its own, so the first frame is cold.
        let cache = || CompileCache::at(dir.join(&scene.name));
        eprintln!("{name}: cold compile and frame");
        let (cycles, compile_cold, _, _) = frame(cache())?;
        let mut warm = Vec::new();
        for run in 1..=a.runs {
            eprintln!("{name}: warm frame {run}/{}", a.runs);
            let w = frame(cache())?;
            if w.0 != cycles {
                bail!(
                    "{name}: a warm frame simulated {} cycles, the cold one {cycles}",
                    w.0
                );
            }
            warm.push(w);
        }
        let simulate = median(warm.iter().map(|w| w.2).collect());
        rows.push(SceneBench {
            scene: scene.name.clone(),
            machine: desc.name.clone(),
            simulated_cycles: cycles,
            compile_cold,
            compile_warm: median(warm.iter().map(|w| w.1).collect()),
            simulate,
            host_per_frame: median(warm.iter().map(|w| w.3).collect()),
            simulated_cycles_per_second: cycles as f64 / simulate.max(1e-9),
            build: build_kind(),
        });
    }
    Ok(rows)
}
