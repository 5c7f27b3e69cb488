//! `imagine render --pipeline reyes`: a scene's patch objects through the Reyes pipeline
//! ([`imagine_pipelines::reyes`]) on the machine, its statistics, and its coverage against
//! `verif`'s f64 reference renderer drawing the same patches evaluated densely.

use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use imagine_pipelines::compile::CompileCache;
use imagine_pipelines::reyes::frame::{self, ReyesFrame, ReyesOptions};
use imagine_pipelines::scene::model::Scene;
use imagine_units::desc::MachineDesc;
use imagine_verif::image::Image;

use super::reference_error::{REFERENCE_DICE, measure_reyes};
use super::render::RenderArgs;

/// Pixels one frame covers and the other does not.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Coverage {
    /// Covered by the reference, not by the machine (holes, cracks, a shrunken silhouette).
    pub missing: u64,
    /// Covered by the machine, not by the reference.
    pub extra: u64,
    /// Pixels the reference covers.
    pub reference: u64,
}

/// The machine frame's coverage against the reference's (`triangles` per pixel).
pub fn coverage(
    frame: &ReyesFrame,
    triangles: &[Option<imagine_pipelines::scene::model::TriangleId>],
) -> Coverage {
    let mut c = Coverage {
        missing: 0,
        extra: 0,
        reference: 0,
    };
    for (p, t) in triangles.iter().enumerate() {
        // A drawn pixel passed the LESS test against the cleared depth, 1.0.
        let drawn = frame.depth[p] < 1.0;
        let reference = t.is_some();
        c.reference += u64::from(reference);
        c.missing += u64::from(reference && !drawn);
        c.extra += u64::from(drawn && !reference);
    }
    c
}

pub fn run(a: &RenderArgs, desc: &MachineDesc, scene: &Scene) -> Result<ExitCode> {
    let stop = a.stop_length.unwrap_or(scene.pipeline.stop_length);
    frame::check_stop_length(stop).context("--stop-length")?;
    let options = ReyesOptions {
        stop_length: stop,
        cache: if a.no_cache {
            CompileCache::disabled()
        } else {
            CompileCache::from_env()
        },
        datapath: a.datapath.datapath,
        ..ReyesOptions::default()
    };
    let start = Instant::now();
    let f = frame::render(scene, desc, &options)?;
    let seconds = start.elapsed().as_secs_f64();
    let image = Image::from_rgba8_words(f.width, f.height, &f.colour);
    if let Some(p) = &a.png {
        image.write_png(p).map_err(anyhow::Error::msg)?;
    }
    let error = measure_reyes(scene, &f)?;
    if let Some(p) = &a.reference_png {
        error.reference.write_png(p).map_err(anyhow::Error::msg)?;
    }
    let cov = coverage(&f, &error.triangles);
    let m = &error.metrics;
    let s = &f.stats;
    let mhz = desc.clocks.core_mhz as f64;
    let fps = mhz * 1e6 / s.cycles.max(1) as f64;
    if let Some(p) = &a.stats {
        let json = serde_json::json!({
            "scene": scene.name,
            "pipeline": "reyes",
            "machine": desc.name,
            "stop_length": stop,
            "cycles": s.cycles,
            "load_cycles": s.load_cycles,
            "clear_cycles": s.clear_cycles,
            "readback_cycles": s.readback_cycles,
            "fps": fps,
            "patches": s.patches,
            "quads": s.quads,
            "zero_pixel_quads": s.zero_pixel_quads,
            "zero_pixel_share": s.zero_pixel_share(),
            "fragments": s.fragments,
            "visible_pixels": s.visible_pixels,
            "quads_per_visible_pixel": s.quads_per_visible_pixel(),
            "levels": s.levels,
            "composite_rounds": s.rounds,
            "texel_words": s.texel_words,
            "kernels": s.kernels.iter().map(|k| serde_json::json!({
                "name": k.kernel, "calls": k.calls, "cycles": k.cycles, "ops": k.ops,
                "ops_per_cycle": k.ops_per_cycle(),
            })).collect::<Vec<_>>(),
            "reference": {
                "dice": REFERENCE_DICE,
                "missing_pixels": cov.missing,
                "extra_pixels": cov.extra,
                "reference_pixels": cov.reference,
                "psnr_db": m.psnr_db.is_finite().then_some(m.psnr_db),
                "max_abs_error": m.max_abs_error,
                "covered_psnr_db": m.covered_psnr_db.is_finite().then_some(m.covered_psnr_db),
                "differing_share": m.differing_share,
            },
        });
        std::fs::write(p, serde_json::to_string_pretty(&json)? + "\n")
            .with_context(|| format!("cannot write `{}`", p.display()))?;
    }
    println!(
        "{} through Reyes on {} (stop length {stop} px), {}x{}",
        scene.name, desc.name, f.width, f.height
    );
    println!(
        "  cycles      {} (the frame: kernels, dispatch, memory), {fps:.2} fps at {} MHz; \
         load {}, clear {}, read-back {}",
        s.cycles, desc.clocks.core_mhz, s.load_cycles, s.clear_cycles, s.readback_cycles
    );
    println!("  patches     {}", s.patches);
    println!(
        "  quads       {} ({} zero-pixel, {:.1}%), {:.2} per visible pixel",
        s.quads,
        s.zero_pixel_quads,
        100.0 * s.zero_pixel_share(),
        s.quads_per_visible_pixel()
    );
    println!(
        "  fragments   {} sampled, {} pixels visible, {} composite rounds",
        s.fragments, s.visible_pixels, s.rounds
    );
    if s.texel_words > 0 {
        println!(
            "  texels      {} words gathered (the fragment program's, per quad record)",
            s.texel_words
        );
    }
    let levels: Vec<String> = s
        .levels
        .iter()
        .enumerate()
        .filter(|(_, n)| **n > 0)
        .map(|(l, n)| format!("{l}: {n}"))
        .collect();
    println!("  levels      {}", levels.join(", "));
    println!("  kernel                      calls        cycles   share  ops/cycle");
    for k in &s.kernels {
        println!(
            "    {:<26}{:>7}{:>14}{:>7.1}%{:>11.1}",
            k.kernel,
            k.calls,
            k.cycles,
            100.0 * k.cycles as f64 / s.cycles.max(1) as f64,
            k.ops_per_cycle()
        );
    }
    println!(
        "  reference   the patches diced {REFERENCE_DICE}x{REFERENCE_DICE} (f64): {} of its {} pixels \
         not covered, {} covered beyond it; PSNR {:.2} dB ({:.2} dB on the pixels both cover), \
         max error {:.3}",
        cov.missing, cov.reference, cov.extra, m.psnr_db, m.covered_psnr_db, m.max_abs_error
    );
    println!("  host        {seconds:.1} s");
    Ok(ExitCode::SUCCESS)
}
