//! The reference renderer against Mesa's OSMesa (feature `osmesa`; needs
//! `apt-get install -y libosmesa6-dev`; Debian 12's OSMesa renders with llvmpipe, no
//! environment variable needed).
//!
//! Coverage mismatch: share of pixels that exactly one renderer leaves black. Colour error:
//! over the pixels both cover, the largest RGB channel difference, and the share of those
//! pixels where it exceeds 2 (a different triangle won: interpenetrating triangles whose
//! depths are equal within OSMesa's 24-bit depth buffer, or a sliver's sample decided
//! differently by llvmpipe's 8-bit sub-pixel snapping). The bounds are several times what
//! was measured (llvmpipe, Mesa 22.3.6; `GALLIUM_DRIVER=softpipe` stays within them too).
#![cfg(feature = "osmesa")]

use imagine_pipelines::scene::{Scene, parse_tri, sphere};
use imagine_verif::image::{compare, covered_error_histogram};
use imagine_verif::reference::TieRule;
use imagine_verif::{osmesa, reference, stress};

struct Bounds {
    coverage_mismatch: f64,
    covered_max_error: u8,
    covered_over_2: f64,
}

/// Renders `scene` both ways, prints the numbers and checks them against `bounds`.
fn check(scene: &Scene, bounds: &Bounds) {
    let ours = reference::render(scene);
    let gl = osmesa::render(scene).unwrap_or_else(|e| panic!("{}: {e}", scene.name));
    let m = compare(&ours, &gl).unwrap();
    let histogram = covered_error_histogram(&ours, &gl).unwrap();
    let both: usize = histogram.iter().sum();
    let over_2 = histogram[3..].iter().sum::<usize>() as f64 / both.max(1) as f64;
    let max = (0..256).rev().find(|&e| histogram[e] > 0).unwrap_or(0) as u8;
    let pixels = f64::from(scene.width * scene.height);
    println!(
        "{:28} coverage mismatch {:.4} % ({} px); both cover {both} px: max error {max}, \
         error > 2 on {:.4} %; PSNR {:.1} dB",
        scene.name,
        100.0 * m.coverage_mismatch_share,
        (m.coverage_mismatch_share * pixels).round(),
        100.0 * over_2,
        m.psnr_db
    );
    assert!(both > 0, "{}: nothing drawn", scene.name);
    assert!(
        m.coverage_mismatch_share <= bounds.coverage_mismatch,
        "{}: coverage mismatch {} > {}",
        scene.name,
        m.coverage_mismatch_share,
        bounds.coverage_mismatch
    );
    assert!(
        max <= bounds.covered_max_error,
        "{}: colour error {max} > {}",
        scene.name,
        bounds.covered_max_error
    );
    assert!(
        over_2 <= bounds.covered_over_2,
        "{}: colour error > 2 on a share {over_2} > {}",
        scene.name,
        bounds.covered_over_2
    );
}

/// A hand-written `.tri` scene in a 64 × 64 window (a power of two, so that
/// `window_to_clip` is exact and ties on pixel centres survive): a background triangle,
/// overlapping triangles at different depths (one clockwise, one with an edge through
/// pixel centres), one half off-screen, and a square of two triangles with its corners on
/// pixel centres (horizontal and vertical edges through rows and columns of centres).
const HAND_TRI: &str = "\
# hand-written conformance scene
64 64
# background, far; Mesa clips it (it leaves the view volume), which moves its edges by
# rounding, so they avoid pixel centres
-10.3 -10.1 0.9  0.2 0.2 0.2   80.7 -10.2 0.9  0.2 0.2 0.3   20.1 90.3 0.9  0.3 0.2 0.2
# overlapping pair, the second one nearer and clockwise
4 4 0.5  1 0 0   40 6 0.5  1 1 0   10 40 0.5  1 0 1
30 44 0.25  0 1 0   50 8 0.25  0 1 1   20 10 0.25  0 0 1
# half off-screen (and so clipped by Mesa: no ties on its edges)
50 20.1 0.1  1 1 1   90 30 0.1  0.5 0.5 0.5   55 60 0.1  0.1 0.2 0.1
# two triangles sharing a diagonal, corners on pixel centres
40.5 30.5 0.05  1 0.5 0   60.5 30.5 0.05  0 0.5 1   60.5 45.5 0.05  0.5 1 0.5
40.5 30.5 0.05  1 0.5 0   60.5 45.5 0.05  0.5 1 0.5   40.5 45.5 0.05  0.25 0.25 1
";

#[test]
fn osmesa_is_available() {
    let name = osmesa::renderer().unwrap();
    println!("OSMesa renderer: {name}");
    assert!(name.contains("Mesa"), "{name}");
}

#[test]
fn hand_written_tri_scene_matches_with_mesas_tie_rule() {
    let scene = parse_tri("hand.tri", HAND_TRI).unwrap();
    let gl = osmesa::render(&scene).unwrap();
    // With the tie rule of Mesa's driver (llvmpipe: bottom-left in GL window
    // coordinates), the images agree exactly in coverage and within 1 in colour
    // (measured: max error 1).
    let rule = osmesa::tie_rule().unwrap();
    let ours = reference::render_with(&scene, rule).unwrap();
    let m = compare(&ours, &gl).unwrap();
    println!("hand.tri, {rule:?} rule: {m:?}");
    assert_eq!(m.coverage_mismatch_share, 0.0);
    assert!(m.max_abs_error <= 1, "{m:?}");
    // With the default top-left rule exactly the rows of centres on the square's
    // horizontal edges differ under llvmpipe: y = 30.5 (bottom, Mesa's) and y = 45.5
    // (top, ours); the ties on the clockwise triangle's sloped edges agree.
    if rule == TieRule::BottomLeft {
        let ours = reference::render(&scene);
        let mut rows = Vec::new();
        for y in 0..64 {
            for x in 0..64 {
                let d = (0..3)
                    .map(|k| ours.pixel(x, y)[k].abs_diff(gl.pixel(x, y)[k]))
                    .max()
                    .unwrap();
                if d > 1 {
                    assert!((40..=60).contains(&x), "({x}, {y}) differs by {d}");
                    rows.push(y);
                }
            }
        }
        rows.dedup();
        assert_eq!(rows, [30, 45]);
    }
    // And the bounds the other scenes use hold for the default rule too.
    check(
        &scene,
        &Bounds {
            coverage_mismatch: 0.01,
            covered_max_error: 255,
            covered_over_2: 0.02,
        },
    );
}

#[test]
fn stress_scenes_match() {
    for seed in [100u64, 200, 300] {
        for scene in stress::all(seed, 256, 256) {
            let bounds = if scene.name.starts_with("stress-slivers") {
                // Measured up to 0.093 % coverage mismatch, > 2 on 0.043 %.
                Bounds {
                    coverage_mismatch: 0.005,
                    covered_max_error: 255,
                    covered_over_2: 0.005,
                }
            } else if scene.name.starts_with("stress-overlapping") {
                // Measured up to 0.0076 % (5 px) coverage mismatch, > 2 on 0.012 %.
                Bounds {
                    coverage_mismatch: 0.0005,
                    covered_max_error: 255,
                    covered_over_2: 0.001,
                }
            } else if scene.name.starts_with("stress-huge") {
                // Measured: identical coverage, error ≤ 1.
                Bounds {
                    coverage_mismatch: 0.0001,
                    covered_max_error: 2,
                    covered_over_2: 0.0,
                }
            } else {
                // Meshes, measured: identical coverage, error ≤ 1 (llvmpipe); softpipe
                // differs on 1 pixel in coverage and a handful in colour.
                Bounds {
                    coverage_mismatch: 0.0001,
                    covered_max_error: 255,
                    covered_over_2: 0.0005,
                }
            };
            check(&scene, &bounds);
        }
    }
}

#[test]
fn lit_spheres_match() {
    // Vertex colours come from the reference's lighting: this checks rasterization,
    // perspective-correct interpolation, depth and culling. Measured: identical coverage,
    // error ≤ 1.
    for (subdivisions, size) in [(6, 256), (3, 720)] {
        check(
            &sphere(subdivisions, size),
            &Bounds {
                coverage_mismatch: 0.0001,
                covered_max_error: 2,
                covered_over_2: 0.0,
            },
        );
    }
}
