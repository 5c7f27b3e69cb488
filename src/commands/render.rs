//! `imagine render`: a scene through the OpenGL-like pipeline on the machine, with its
//! statistics and its error against the independent reference renderer.

use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::Args;
use imagine_pipelines::compile::CompileCache;
use imagine_pipelines::opengl::render::{Frame, RenderOptions, render_with};
use imagine_pipelines::scene::{self, DEFAULT_SIZE, Scene};
use imagine_units::desc::MachineDesc;
use imagine_verif::image::{Image, Metrics, compare};
use imagine_verif::reference;

use super::waves::WaveArgs;

#[derive(Args)]
pub struct RenderArgs {
    /// Scene: SPHERE, RATE-n (n = 1, 2, 4, ..., 128) or a .tri file [default: SPHERE]
    scene: Option<String>,
    /// Machine description name or file
    #[arg(long, default_value = "gold8")]
    machine: String,
    /// Window side in pixels for the built-in scenes (.tri files give their own)
    #[arg(long, default_value_t = DEFAULT_SIZE)]
    size: u32,
    /// SPHERE's icosahedron subdivisions (6 gives the published 81,920 triangles)
    #[arg(long, default_value_t = scene::SPHERE_SUBDIVISIONS)]
    subdivisions: u32,
    /// Write the frame as PNG
    #[arg(long)]
    png: Option<PathBuf>,
    /// Write statistics as JSON
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Also write the reference renderer's frame as PNG
    #[arg(long)]
    reference_png: Option<PathBuf>,
    /// Compile every kernel afresh: neither read nor write the compile cache
    /// ($IMAGINE_CACHE_DIR, else the platform's cache directory)
    #[arg(long)]
    no_cache: bool,
    #[command(flatten)]
    waves: WaveArgs,
}

fn load_scene(a: &RenderArgs) -> Result<Scene> {
    let name = a.scene.as_deref().unwrap_or("SPHERE");
    if name.ends_with(".tri") {
        let text =
            std::fs::read_to_string(name).with_context(|| format!("cannot read scene `{name}`"))?;
        return Ok(scene::parse_tri(name, &text)?);
    }
    if a.size == 0 || a.size > scene::MAX_WINDOW {
        bail!("--size {} is outside 1..={}", a.size, scene::MAX_WINDOW);
    }
    if name.eq_ignore_ascii_case("SPHERE") {
        if a.subdivisions > 7 {
            bail!(
                "--subdivisions {} is more than 7 (1.3 M triangles)",
                a.subdivisions
            );
        }
        return Ok(scene::sphere(a.subdivisions, a.size));
    }
    Ok(scene::builtin(name, a.size)?)
}

/// The machine's frame as an image.
fn image_of(f: &Frame) -> Image {
    Image::from_rgba8_words(f.width, f.height, &f.pixels)
}

pub fn run(a: RenderArgs) -> Result<ExitCode> {
    let desc = MachineDesc::resolve(&a.machine)?;
    let scene = load_scene(&a)?;
    let on_start: Option<imagine_units::runner::OnStart> = a.waves.wants_vcd().then(|| {
        let waves = a.waves.clone();
        Box::new(move |sim: &mut imagine_hdl::Sim| {
            waves.attach(sim).map(|_| ()).map_err(|e| format!("{e:#}"))
        }) as imagine_units::runner::OnStart
    });
    let mut stderr = std::io::stderr();
    // The bar is redrawn at each whole percent, and only on a terminal (a log gets no bar).
    let terminal = stderr.is_terminal();
    let mut drawn = None;
    let options = RenderOptions {
        cache: if a.no_cache {
            CompileCache::disabled()
        } else {
            CompileCache::from_env()
        },
        ..RenderOptions::default()
    };
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
    let reference_image = reference::render(&scene);
    let metrics = compare(&image, &reference_image).map_err(anyhow::Error::msg)?;
    if let Some(p) = &a.png {
        image.write_png(p).map_err(anyhow::Error::msg)?;
    }
    if let Some(p) = &a.reference_png {
        reference_image.write_png(p).map_err(anyhow::Error::msg)?;
    }
    if let Some(p) = &a.stats {
        let json = serde_json::json!({ "frame": frame.stats, "reference_error": metrics });
        std::fs::write(p, serde_json::to_string_pretty(&json)? + "\n")
            .with_context(|| format!("cannot write `{}`", p.display()))?;
    }
    print_stats(&frame, &metrics);
    Ok(ExitCode::SUCCESS)
}

fn print_stats(f: &Frame, m: &Metrics) {
    let s = &f.stats;
    println!(
        "scene              {} ({}x{}, {} triangles)",
        s.scene, s.width, s.height, s.triangles
    );
    println!("machine            {} at {} MHz", s.machine, s.core_mhz);
    println!("cycles             {}", s.cycles);
    println!("frames/s           {:.2}", s.frames_per_second);
    println!("vertices/s         {:.2} M", s.vertices_per_second / 1e6);
    println!(
        "fragments/s        {:.2} M ({} fragments)",
        s.fragments_per_second / 1e6,
        s.fragments
    );
    println!("ops/cycle          {:.1}", s.ops_per_cycle);
    println!(
        "cluster occupancy  {:.1} % ({:.1} % without stalls)",
        100.0 * s.cluster_occupancy,
        100.0 * s.cluster_occupancy_without_stalls
    );
    println!(
        "batches            {} of {} triangles, {} spills, {} composite rounds ({} merged, \
         {} fragments dropped)",
        s.batches,
        s.batch_triangles,
        s.spills,
        s.composite_rounds,
        s.merge_rounds,
        s.merged_fragments
    );
    println!(
        "DRAM               {:.3} GB/s, row hits {:.1} %",
        s.dram_gbs,
        100.0 * s.dram_row_hit_rate
    );
    println!(
        "SRF                {:.2} words/cycle",
        s.srf_words_per_cycle
    );
    let lrf_words = s.lrf_reads_per_cycle + s.lrf_writes_per_cycle;
    println!(
        "LRF                {:.1} words/cycle ({:.1} read, {:.1} written), {:.1} GB/s",
        lrf_words,
        s.lrf_reads_per_cycle,
        s.lrf_writes_per_cycle,
        lrf_words * 4.0 * s.core_mhz * 1e6 / 1e9
    );
    println!("kernel breakdown   (share of frame cycles)");
    for k in &s.kernels {
        println!(
            "  {:<16} {:>6} calls {:>12} cycles {:>5.1} %",
            k.kernel,
            k.calls,
            k.cycles,
            100.0 * k.cycles as f64 / s.cycles.max(1) as f64
        );
    }
    println!(
        "reference error    PSNR {:.2} dB, max abs {} , {:.3} % pixels differ, {:.3} % coverage",
        m.psnr_db,
        m.max_abs_error,
        100.0 * m.differing_share,
        100.0 * m.coverage_mismatch_share
    );
    println!(
        "host               {:.2} s ({:.2} M simulated cycles/s)",
        s.host_seconds,
        s.simulated_cycles_per_second / 1e6
    );
    println!(
        "compile            {:.2} s, {} of {} kernels from the cache",
        s.compile_seconds, s.kernels_from_cache, s.kernel_programs
    );
}
