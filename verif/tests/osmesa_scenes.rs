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
//!
//! # Textures and blending
//!
//! Six more scene files draw Keenan Crane's cow Spot (an OBJ with texture coordinates) with
//! her texture (PNG, 256 × 256) and, for RGBA, the Tango address-book icon: `nearest`,
//! `linear` and `trilinear` filtering; `modulate` and `replace`; lit and unlit; `repeat`
//! and `clamp`; two texture units on one material (GL 1.3 multitexture); `blend = "alpha"`
//! and `"add"`, the latter with the `always` depth test. [`osmesa::render_model`] draws
//! them with GL's own texturing and blending (Mesa is given the same mipmap levels). Each
//! is drawn by llvmpipe and, in a child process of this test binary with
//! `GALLIUM_DRIVER=softpipe` (Mesa picks its driver once per process), by softpipe; the
//! closer of the two (by PSNR) must agree with the reference to a coverage mismatch of at
//! most 0.2 % of the pixels and a PSNR of at least 36 dB.
//!
//! Measured (Mesa 22.3.6, `cargo test -p imagine-verif --features osmesa --test
//! osmesa_scenes spot_ -- --nocapture`), coverage mismatch (pixels) and PSNR:
//!
//! | Scene | llvmpipe | softpipe |
//! |---|---|---|
//! | `spot-nearest-unlit-repeat` | 0, ∞ (identical) | 0, ∞ (identical) |
//! | `spot-linear-lit-clamp` | 8 px (0.039 %), 61.2 dB | 0, 90.0 dB (max error 1) |
//! | `spot-trilinear-lit` | 0, 58.6 dB | 0, 52.5 dB |
//! | `spot-replace-and-two-units` | 1 px (0.006 %), 66.4 dB | 0, 90.7 dB (max error 1) |
//! | `spot-alpha-blend` | 2 px (0.012 %), 61.6 dB | 0, 71.9 dB (max error 1) |
//! | `spot-add-blend` (trilinear) | 0, 59.5 dB | 0, 53.0 dB |
//!
//! Softpipe agrees with the reference to within 1 wherever the level of detail does not
//! matter: its sampling, texture environment and blending follow the same rules. Under
//! trilinear filtering both drivers differ by up to 15–22 on a few per cent of the pixels
//! (softpipe) or a fraction of one per cent (llvmpipe): they take one level of detail per
//! 2 × 2 quad from differences of its texture coordinates, the reference the exact
//! derivative at each pixel centre. Llvmpipe's other differences are its 8-bit filter
//! weights and its 1/256-pixel vertex snapping (the coverage pixels).
#![cfg(feature = "osmesa")]

use imagine_pipelines::scene::model::Scene;
use imagine_pipelines::scene::{self, LoadOptions};
use imagine_verif::image::{Image, Metrics, compare, covered_error_histogram};
use imagine_verif::{osmesa, reference_model};
use std::path::{Path, PathBuf};

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

/// The environment variables through which [`textured`] asks a copy of this test binary,
/// run with `GALLIUM_DRIVER=softpipe`, to draw a scene with softpipe ([`softpipe_child`]):
/// Mesa picks its driver once per process.
const CHILD_SCENE: &str = "IMAGINE_SOFTPIPE_SCENE";
const CHILD_OUT: &str = "IMAGINE_SOFTPIPE_OUT";

/// In a child run by [`softpipe_image`]: draws the scene it names with OSMesa and writes
/// the image; otherwise nothing.
#[test]
fn softpipe_child() {
    let (Some(file), Some(out)) = (std::env::var_os(CHILD_SCENE), std::env::var_os(CHILD_OUT))
    else {
        return;
    };
    let scene = load(file.to_str().unwrap());
    let image = osmesa::render_model(&scene).unwrap_or_else(|e| panic!("{e}"));
    image.write_png(out).unwrap();
}

/// `file` drawn by softpipe in a child process, with the renderer's name.
fn softpipe_image(file: &str) -> (Image, String) {
    let out: PathBuf = std::env::temp_dir().join(format!(
        "imagine-softpipe-{}-{file}.png",
        std::process::id()
    ));
    let status = std::process::Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "softpipe_child", "--test-threads=1", "--quiet"])
        .env("GALLIUM_DRIVER", "softpipe")
        .env(CHILD_SCENE, file)
        .env(CHILD_OUT, &out)
        .stdout(std::process::Stdio::null())
        .status()
        .unwrap();
    assert!(status.success(), "{file}: the softpipe child failed");
    let image = Image::read_png(&out).unwrap_or_else(|e| panic!("{e}"));
    let _ = std::fs::remove_file(&out);
    (image, "softpipe".into())
}

/// Renders a textured or blended `scene` with the reference, with OSMesa's default driver
/// (llvmpipe) and with softpipe, prints both comparisons and checks the bounds against the
/// closer of the two (by PSNR): coverage mismatch ≤ 0.2 %, PSNR ≥ 36 dB.
fn textured(file: &str) {
    let scene = &load(file);
    let ours = reference_model::render(scene).unwrap_or_else(|e| panic!("{e}"));
    let default = osmesa::render_model(scene).unwrap_or_else(|e| panic!("{}: {e}", scene.name));
    let default_name = osmesa::renderer().unwrap();
    let mut drivers = vec![(default, default_name.clone())];
    if !default_name.starts_with("softpipe") {
        drivers.push(softpipe_image(file));
    }
    let pixels = f64::from(scene.width * scene.height);
    let mut best: Option<Metrics> = None;
    for (gl, name) in &drivers {
        let short = name.split([' ', ';']).next().unwrap_or("");
        if let Some(dir) = std::env::var_os("IMAGINE_OSMESA_IMAGES") {
            let dir = Path::new(&dir);
            ours.write_png(dir.join(format!("{}-reference.png", scene.name)))
                .unwrap();
            gl.write_png(dir.join(format!("{}-{short}.png", scene.name)))
                .unwrap();
        }
        let m = compare(&ours, gl).unwrap();
        let histogram = covered_error_histogram(&ours, gl).unwrap();
        let both: usize = histogram.iter().sum();
        assert!(
            both as f64 > 0.05 * pixels,
            "{}: only {both} pixels drawn",
            scene.name
        );
        println!(
            "{:28} {short:9} coverage mismatch {:.4} % ({} px); max error {}, error > 2 on \
             {:.3} % of {both} px; PSNR {:.2} dB",
            scene.name,
            100.0 * m.coverage_mismatch_share,
            (m.coverage_mismatch_share * pixels).round(),
            m.max_abs_error,
            100.0 * histogram[3..].iter().sum::<usize>() as f64 / both.max(1) as f64,
            m.psnr_db
        );
        if best.is_none_or(|b| m.psnr_db > b.psnr_db) {
            best = Some(m);
        }
    }
    let m = best.unwrap();
    assert!(
        m.coverage_mismatch_share <= 0.002,
        "{}: coverage mismatch {:.4} % > 0.2 %",
        scene.name,
        100.0 * m.coverage_mismatch_share
    );
    assert!(
        m.psnr_db >= 36.0,
        "{}: PSNR {:.2} dB < 36 dB",
        scene.name,
        m.psnr_db
    );
}

#[test]
fn spot_reads_her_texcoords_and_textures() {
    let s = load("spot-nearest-unlit-repeat.toml");
    let spot = &s.objects[0].mesh;
    assert_eq!(spot.triangles.len(), 5856);
    assert_eq!(spot.texcoords.len(), spot.positions.len());
    assert!(spot.normals.is_empty());
    let t = &s.textures[0];
    assert_eq!((t.width, t.height), (256, 256));
    let a = load("spot-alpha-blend.toml");
    let icon = &a.textures[1];
    assert_eq!((icon.width, icon.height), (128, 128));
    let alphas = icon.texels.iter().map(|&w| w >> 24);
    assert!(alphas.clone().any(|a| a == 0) && alphas.clone().any(|a| a == 255));
    assert!(alphas.into_iter().any(|a| a > 0 && a < 255));
}

/// Spot unlit, her texture `nearest`, `repeat`, modulating white.
#[test]
fn spot_nearest_unlit_repeat() {
    textured("spot-nearest-unlit-repeat.toml");
}

/// Spot's face magnified, lit, `linear`, `clamp`, modulating the lit colour.
#[test]
fn spot_linear_lit_clamp() {
    textured("spot-linear-lit-clamp.toml");
}

/// Three Spots and a checkered ball minified, lit, `trilinear`, `repeat`.
#[test]
fn spot_trilinear_lit() {
    textured("spot-trilinear-lit.toml");
}

/// `replace` on one Spot; two texture units modulating on another (multitexture).
#[test]
fn spot_replace_and_two_units() {
    textured("spot-replace-and-two-units.toml");
}

/// `blend = "alpha"`: a ball wearing an RGBA icon over an opaque Spot.
#[test]
fn spot_alpha_blend() {
    textured("spot-alpha-blend.toml");
}

/// `blend = "add"` with `depth_test = "always"`: three coloured Spots summed.
#[test]
fn spot_add_blend() {
    textured("spot-add-blend.toml");
}
