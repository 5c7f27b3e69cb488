//! Conformance: the scene files in `verif/tests/scenes/*.toml` — public OBJ meshes nobody
//! here wrote, with and without normals, several objects with transforms, positional
//! lights, look-at cameras, back-, front- and no culling — drawn on the machine (gold8,
//! the OpenGL-like pipeline as a stream program) against Mesa's OpenGL (OSMesa, GL's own
//! fixed-function lighting) on the same file (feature `osmesa`; needs `apt-get install -y
//! libosmesa6-dev`).
//!
//! Each scene must agree with OSMesa on coverage (pixels exactly one of the two leaves at
//! the black background) on at most 0.2 % of the pixels, with a PSNR of at least 38 dB
//! (36 dB for the textured ones: nearest, bilinear and trilinear, modulate and replace,
//! two units, lit and unlit, repeat and clamp).
//! The machine is also compared with the f64 reference renderer (printed, not bounded:
//! `verif/tests/osmesa_scenes.rs` holds the reference to the same bounds against OSMesa).
//!
//! Measured: see the numbers each test prints (`cargo test --features osmesa --test
//! conformance -- --nocapture`).
#![cfg(feature = "osmesa")]

use std::path::Path;
use std::time::Instant;

use imagine_pipelines::opengl::render::render;
use imagine_pipelines::scene::{self, LoadOptions};
use imagine_units::desc::MachineDesc;
use imagine_verif::image::{Image, Metrics, compare, covered_error_histogram};
use imagine_verif::{osmesa, reference_model};

/// The largest share of pixels whose coverage may differ from OSMesa's.
const MAX_COVERAGE_MISMATCH: f64 = 0.002;

/// The lowest PSNR against OSMesa, in dB.
const MIN_PSNR_DB: f64 = 38.0;

fn line(what: &str, m: &Metrics, a: &Image, b: &Image) -> String {
    let histogram = covered_error_histogram(a, b).unwrap();
    let both: usize = histogram.iter().sum();
    let covered_max = (0..256).rev().find(|&e| histogram[e] > 0).unwrap_or(0);
    let pixels = f64::from(a.width * a.height);
    format!(
        "  {what:22} coverage mismatch {:.4} % ({} px); PSNR {:.2} dB; max error {} \
         ({covered_max} where both cover, {both} px), error > 2 on {} px",
        100.0 * m.coverage_mismatch_share,
        (m.coverage_mismatch_share * pixels).round(),
        m.psnr_db,
        m.max_abs_error,
        histogram[3..].iter().sum::<usize>(),
    )
}

/// The lowest PSNR against OSMesa for textured scenes, in dB: Mesa's level of detail is
/// one per 2 × 2 pixel block, the machine's and the reference's per pixel.
const MIN_TEXTURED_PSNR_DB: f64 = 36.0;

/// Draws `verif/tests/scenes/<file>` on gold8, with OSMesa and with the reference; prints
/// the numbers and checks the machine against OSMesa.
fn check(file: &str) {
    check_with(file, MIN_PSNR_DB);
}

/// [`check`] with the lowest PSNR against OSMesa `min_psnr_db`.
fn check_with(file: &str, min_psnr_db: f64) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("verif/tests/scenes")
        .join(file);
    let scene = scene::load(
        path.to_str().expect("a UTF-8 path"),
        &LoadOptions::default(),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let desc = MachineDesc::resolve("gold8").unwrap();
    let start = Instant::now();
    let frame = render(&scene, &desc, None, |_, _| {})
        .unwrap_or_else(|e| panic!("{} on gold8: {e}", scene.name));
    let seconds = start.elapsed().as_secs_f64();
    let machine = Image::from_rgba8_words(frame.width, frame.height, &frame.pixels);
    let gl = osmesa::render_model(&scene).unwrap_or_else(|e| panic!("{}: {e}", scene.name));
    let reference = reference_model::render(&scene).unwrap_or_else(|e| panic!("{e}"));
    if let Some(dir) = std::env::var_os("IMAGINE_OSMESA_IMAGES") {
        let dir = Path::new(&dir);
        for (image, what) in [
            (&machine, "machine"),
            (&gl, "osmesa"),
            (&reference, "reference"),
        ] {
            image
                .write_png(dir.join(format!("{}-{what}.png", scene.name)))
                .unwrap();
        }
    }
    let vs_gl = compare(&machine, &gl).unwrap();
    let vs_reference = compare(&machine, &reference).unwrap();
    let reference_vs_gl = compare(&reference, &gl).unwrap();
    println!(
        "{} ({}x{}, {} triangles): gold8 {} cycles, rendered in {seconds:.1} s\n{}\n{}\n{}",
        scene.name,
        scene.width,
        scene.height,
        scene.triangles(),
        frame.stats.cycles,
        line("machine vs OSMesa", &vs_gl, &machine, &gl),
        line("machine vs reference", &vs_reference, &machine, &reference),
        line("reference vs OSMesa", &reference_vs_gl, &reference, &gl),
    );
    let drawn = machine
        .pixels
        .iter()
        .filter(|p| p[..3] != [0, 0, 0])
        .count();
    assert!(
        drawn as f64 > 0.05 * f64::from(scene.width * scene.height),
        "{}: only {drawn} pixels drawn",
        scene.name
    );
    assert!(
        vs_gl.coverage_mismatch_share <= MAX_COVERAGE_MISMATCH,
        "{}: coverage differs from OSMesa's on {:.4} % of the pixels (> 0.2 %)",
        scene.name,
        100.0 * vs_gl.coverage_mismatch_share
    );
    assert!(
        vs_gl.psnr_db >= min_psnr_db,
        "{}: PSNR {:.2} dB against OSMesa (< {min_psnr_db} dB)",
        scene.name,
        vs_gl.psnr_db
    );
}

/// Suzanne (per-vertex normals, quads) under two positional lights with a sharp highlight;
/// back faces culled.
#[test]
fn suzanne_two_lights() {
    check("suzanne-two-lights.toml");
}

/// The Utah teapot without normals, every triangle lit with its geometric normal by three
/// coloured lights.
#[test]
fn teapot_geometric_normals() {
    check("teapot-geometric-normals.toml");
}

/// Four objects, lit and unlit, with their own transforms (one non-uniformly scaled),
/// interpenetrating under four lights; `LEQUAL`, back faces culled.
#[test]
fn several_objects() {
    check("several-objects.toml");
}

/// The gingerbread man (flat, unlit) in front of a lit Suzanne; no culling.
#[test]
fn flat_mesh_and_no_culling() {
    check("woody-no-cull.toml");
}

/// Front faces culled (the insides show, lit one-sided) and the `ALWAYS` depth test.
#[test]
fn front_culling_and_depth_always() {
    check("front-cull-depth-always.toml");
}

/// The near plane cuts Suzanne's face and the teapot reaches past the window's edges.
#[test]
fn near_plane_and_window_edges_cut_objects() {
    check("near-plane-cut.toml");
}

/// Spot (texture coordinates, no normals), unlit, point-sampled, wrap repeat.
#[test]
fn texture_nearest_unlit_repeat() {
    check_with("spot-nearest-unlit-repeat.toml", MIN_TEXTURED_PSNR_DB);
}

/// Spot lit (geometric normals), bilinear, clamp to edge.
#[test]
fn texture_linear_lit_clamp() {
    check_with("spot-linear-lit-clamp.toml", MIN_TEXTURED_PSNR_DB);
}

/// Two objects: `replace`, and two texture units modulating in order.
#[test]
fn texture_replace_and_two_units() {
    check_with("spot-replace-and-two-units.toml", MIN_TEXTURED_PSNR_DB);
}

/// Mipmapped (trilinear) Spots at several distances.
#[test]
fn texture_trilinear_lit() {
    check_with("spot-trilinear-lit.toml", MIN_TEXTURED_PSNR_DB);
}

/// `blend = "alpha"`: a translucent ball (the Tango icon's alpha) over the lit Spot.
#[test]
fn blend_alpha() {
    check_with("spot-alpha-blend.toml", MIN_TEXTURED_PSNR_DB);
}

/// `blend = "add"` with the `always` depth test (trilinear): every layer adds up.
#[test]
fn blend_add() {
    check_with("spot-add-blend.toml", MIN_TEXTURED_PSNR_DB);
}

/// A textured floor through the eye plane: its two triangles have corners behind the eye
/// (w < 0) and are clipped at the near plane; Spot stands on it, lit and textured.
#[test]
fn extreme_floor_through_eye_plane() {
    check_with("floor-through-eye-plane.toml", MIN_TEXTURED_PSNR_DB);
}

/// Near and far planes 1e-3 and 1e6: the depths of the whole scene within 2e-4 of 1.
#[test]
fn extreme_near_far_ratio() {
    check("near-far-extreme.toml");
}

/// The teapot's patches diced 3 × 3 into stitched strips: a quarter of the triangles, and
/// more at the collapsed corners, have zero area.
#[test]
fn extreme_degenerate_faces() {
    check("teapot-patches-degenerate.toml");
}
