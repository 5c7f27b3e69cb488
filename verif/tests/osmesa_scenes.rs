//! The conformance scene files in `tests/scenes/*.toml` drawn by the f64 reference
//! ([`imagine_verif::reference_model`]) and by OSMesa with GL's own fixed-function lighting
//! ([`osmesa::render_model`]) (feature `osmesa`; needs `apt-get install -y
//! libosmesa6-dev`).
//!
//! The meshes are public OBJ files nobody here wrote (`tests/scenes/README.md` names their
//! sources): Suzanne with per-vertex normals and quads, the Utah teapot and a gingerbread
//! man without normals (lit with their triangles' geometric normals, or unlit). The scenes
//! are files read by the scene loader ([`scene::load`], `../shared/SCENE_FORMAT.md`):
//! look-at cameras, several objects with translate · rotate · scale model matrices,
//! positional lights, back-, front- and no culling, all three depth tests. The workspace's
//! `tests/conformance.rs` draws the same files on the machine.
//!
//! Each scene must agree with OSMesa on coverage (pixels exactly one of them leaves at the
//! black background) on at most 0.2 % of the pixels, with a PSNR of at least 38 dB.
//!
//! Measured (llvmpipe, Mesa 22.3.6, the files' 96–128-pixel windows): coverage mismatch
//! 0–2 px a scene (at most 0.012 %), PSNR 48.1–71.1 dB, more than 1 apart on at most 4
//! pixels a scene. Where the images differ by more than 1, the reference and Mesa drew
//! the sample from different triangles: it lies within llvmpipe's 1/256-pixel vertex
//! snapping of an edge (or of a silhouette triangle whose tiny area changes sign under
//! snapping), and the two triangles' colours differ — a lot in meshes without normals,
//! whose triangles are lit flat. Mesa's own tie rule ([`osmesa::tie_rule`]) changes
//! neither the coverage nor the PSNR: no sample falls exactly on an edge here. The
//! lighting itself agrees to within 1 (Suzanne, lit from per-vertex normals).
#![cfg(feature = "osmesa")]

use imagine_pipelines::scene::model::Scene;
use imagine_pipelines::scene::{self, LoadOptions};
use imagine_verif::image::{compare, covered_error_histogram};
use imagine_verif::{osmesa, reference_model};
use std::path::Path;

/// Loads `tests/scenes/<file>`.
fn load(file: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/scenes")
        .join(file);
    scene::load(
        path.to_str().expect("a UTF-8 path"),
        &LoadOptions::default(),
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

/// Renders `scene` both ways, prints the numbers and checks the bounds.
fn check(file: &str) {
    let scene = &load(file);
    let ours = reference_model::render(scene).unwrap_or_else(|e| panic!("{e}"));
    let gl = osmesa::render_model(scene).unwrap_or_else(|e| panic!("{}: {e}", scene.name));
    if let Some(dir) = std::env::var_os("IMAGINE_OSMESA_IMAGES") {
        let dir = Path::new(&dir);
        ours.write_png(dir.join(format!("{}-reference.png", scene.name)))
            .unwrap();
        gl.write_png(dir.join(format!("{}-osmesa.png", scene.name)))
            .unwrap();
    }
    let m = compare(&ours, &gl).unwrap();
    let histogram = covered_error_histogram(&ours, &gl).unwrap();
    let both: usize = histogram.iter().sum();
    let over_2 = histogram[3..].iter().sum::<usize>() as f64 / both.max(1) as f64;
    let max = (0..256).rev().find(|&e| histogram[e] > 0).unwrap_or(0);
    let pixels = f64::from(scene.width * scene.height);
    println!(
        "{:26} {} triangles; coverage mismatch {:.4} % ({} px); both cover {both} px: \
         max error {max}, error > 2 on {:.4} %; PSNR {:.2} dB",
        scene.name,
        scene.triangles(),
        100.0 * m.coverage_mismatch_share,
        (m.coverage_mismatch_share * pixels).round(),
        100.0 * over_2,
        m.psnr_db
    );
    // The same with the tie rule of Mesa's driver: what is left is not about which of two
    // triangles owns a sample on their shared edge.
    let rule = osmesa::tie_rule().unwrap();
    let same_rule = reference_model::render_with(scene, rule).unwrap();
    let r = compare(&same_rule, &gl).unwrap();
    let h = covered_error_histogram(&same_rule, &gl).unwrap();
    println!(
        "{:26} with the {rule:?} rule: coverage mismatch {:.4} %, max error {}, \
         error > 2 on {} px; PSNR {:.2} dB",
        "",
        100.0 * r.coverage_mismatch_share,
        r.max_abs_error,
        h[3..].iter().sum::<usize>(),
        r.psnr_db
    );
    assert!(
        both as f64 > 0.05 * pixels,
        "{}: only {both} pixels drawn",
        scene.name
    );
    assert!(
        m.coverage_mismatch_share <= 0.002,
        "{}: coverage mismatch {:.4} % > 0.2 %",
        scene.name,
        100.0 * m.coverage_mismatch_share
    );
    assert!(
        m.psnr_db >= 38.0,
        "{}: PSNR {:.2} dB < 38 dB",
        scene.name,
        m.psnr_db
    );
}

#[test]
fn the_scene_files_read_their_meshes() {
    // Suzanne keeps her per-vertex normals; the teapot, lit without normals, gets a vertex
    // per triangle corner with the triangle's normal; the unlit gingerbread man shares his.
    let s = load("suzanne-two-lights.toml");
    let suzanne = &s.objects[0].mesh;
    assert_eq!(suzanne.normals.len(), suzanne.positions.len());
    assert!(suzanne.triangles.len() > 900, "{}", suzanne.triangles.len());
    let t = load("teapot-geometric-normals.toml");
    let teapot = &t.objects[0].mesh;
    assert_eq!(teapot.triangles.len(), 6320);
    assert_eq!(teapot.positions.len(), 3 * 6320);
    let w = load("woody-no-cull.toml");
    let woody = &w.objects[1].mesh;
    assert_eq!(woody.triangles.len(), 1267);
    assert!(woody.normals.is_empty());
    assert_eq!(woody.positions.len(), 694);
}

/// Suzanne (per-vertex normals) lit by two white positional lights with a sharp
/// highlight, seen from above and to the side; back faces culled.
#[test]
fn suzanne_two_lights() {
    check("suzanne-two-lights.toml");
}

/// The Utah teapot without normals: every triangle lit with its geometric normal by three
/// coloured lights, one of them close to the spout; a look-at camera from above.
#[test]
fn teapot_geometric_normals() {
    check("teapot-geometric-normals.toml");
}

/// Several objects with their own transforms and materials (lit and unlit, a non-uniform
/// scale), interpenetrating, under four lights; `LEQUAL` depth test, back faces culled.
#[test]
fn several_objects() {
    check("several-objects.toml");
}

/// The gingerbread man (flat, unlit) held up in front of the camera over a lit Suzanne; no
/// culling (every face drawn, back faces lit one-sided).
#[test]
fn flat_mesh_and_no_culling() {
    check("woody-no-cull.toml");
}

/// Front faces culled (the insides of the teapot and of Suzanne show, lit one-sided with
/// their outward normals) and the `ALWAYS` depth test: the last triangle drawn wins.
#[test]
fn front_culling_and_depth_always() {
    check("front-cull-depth-always.toml");
}

/// The camera so close that the near plane (1 unit from the eye) cuts through Suzanne's
/// face and the teapot behind reaches past the window's edges: OSMesa clips those
/// triangles, the reference keeps the samples whose depth is in [0, 1].
#[test]
fn near_plane_and_window_edges_cut_objects() {
    check("near-plane-cut.toml");
}
