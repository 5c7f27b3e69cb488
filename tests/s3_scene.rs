//! The S3 rasterizer fed by the OpenGL pipeline's geometry stage (`imagine s3 --scene`):
//! the stream machine's stored triangles against an independent f64 count of the triangles
//! it should keep, S3's frame against the pipeline's own frame of the scene, K = 1 against
//! K = 16 through the CLI, and the CLI's errors.

use std::collections::HashSet;
use std::process::{Command, Output};

use imagine_pipelines::compile::CompileCache;
use imagine_pipelines::opengl::render::{RenderOptions, render_geometry, render_with};
use imagine_pipelines::scene::model::{Scene, TriangleId};
use imagine_pipelines::scene::{self, LoadOptions};
use imagine_units::desc::MachineDesc;
use imagine_units::s3::S3Config;
use imagine_units::s3::raster::{CLEAR_DEPTH_WORD, Mode, TraceTriangle};
use imagine_units::s3::run::{RunOptions, run};
use imagine_verif::reference_model::clip_positions;

const CACHE: &str = concat!(env!("CARGO_TARGET_TMPDIR"), "/compile-cache");

fn imagine(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_imagine"))
        .env("IMAGINE_CACHE_DIR", CACHE)
        .args(args)
        .output()
        .expect("run imagine")
}

fn temp(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("imagine-s3-scene-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn options() -> RenderOptions {
    RenderOptions {
        cache: CompileCache::at(CACHE),
        ..RenderOptions::default()
    }
}

/// SPHERE with 1,280 triangles in a 64×64 window: lit, perspective, back faces culled.
fn small_sphere() -> Scene {
    let opts = LoadOptions {
        size: Some(64),
        subdivisions: Some(3),
        filter: None,
    };
    scene::load("SPHERE", &opts).unwrap()
}

/// The triangles the geometry stage should keep, in f64 by the reference's transform:
/// not all outside one clip plane, every w > 0 (else S3 is not given it), and
/// counter-clockwise in the window (SPHERE culls back faces).
fn front_facing(scene: &Scene) -> HashSet<TriangleId> {
    let (hw, hh) = (scene.width as f64 / 2.0, scene.height as f64 / 2.0);
    let mut kept = HashSet::new();
    for (o, object) in scene.objects.iter().enumerate() {
        let clip = clip_positions(scene, object);
        for (t, tri) in object.mesh.triangles.iter().enumerate() {
            let c = tri.map(|i| clip[i as usize]);
            let outside = |f: &dyn Fn(&[f64; 4]) -> bool| c.iter().all(f);
            if outside(&|v| v[0] < -v[3])
                || outside(&|v| v[0] > v[3])
                || outside(&|v| v[1] < -v[3])
                || outside(&|v| v[1] > v[3])
                || outside(&|v| v[2] < -v[3])
                || outside(&|v| v[2] > v[3])
                || c.iter().any(|v| v[3] <= 0.0)
            {
                continue;
            }
            let v = c.map(|p| [(p[0] + p[3]) * hw, (p[1] + p[3]) * hh, p[3]]);
            let e = [
                v[1][1] * v[2][2] - v[1][2] * v[2][1],
                v[1][2] * v[2][0] - v[1][0] * v[2][2],
                v[1][0] * v[2][1] - v[1][1] * v[2][0],
            ];
            let det = v[0][0] * e[0] + v[0][1] * e[1] + v[0][2] * e[2];
            if det > 0.0 {
                kept.insert(TriangleId {
                    object: o,
                    triangle: t,
                });
            }
        }
    }
    kept
}

#[test]
fn the_geometry_keeps_the_front_faces_and_s3_draws_the_pipelines_frame() {
    let scene = small_sphere();
    let desc = MachineDesc::resolve("gold8").unwrap();
    let g = render_geometry(&scene, &desc, options(), None, |_, _| {}).unwrap();
    let expected = front_facing(&scene);
    let got: HashSet<TriangleId> = g.ids.iter().copied().collect();
    let total = scene.triangles();
    println!(
        "{} of {total} triangles to S3 ({} discarded, {} unrepresentable), {} expected, geometry {} cycles",
        g.triangles.len(),
        g.discarded,
        g.unrepresentable,
        expected.len(),
        g.stats.cycles
    );
    assert_eq!(g.triangles.len() + g.discarded + g.unrepresentable, total);
    assert_eq!(got.len(), g.ids.len(), "a triangle stored twice");
    // fp32 against f64 may differ on the facing of an edge-on triangle at the silhouette.
    let differ = got.symmetric_difference(&expected).count();
    assert!(
        differ * 200 <= total,
        "{differ} triangles kept by one and not the other"
    );
    assert!(g.stats.cycles > 0);
    // Drawing order: the ids rise.
    assert!(
        g.ids
            .windows(2)
            .all(|w| (w[0].object, w[0].triangle) < (w[1].object, w[1].triangle))
    );

    let tris: Vec<TraceTriangle> = g
        .triangles
        .iter()
        .map(|t| TraceTriangle {
            positions: t.positions,
            colours: t.colours,
            mode: Mode::Opaque,
        })
        .collect();
    let cfg = S3Config::of(&desc);
    let s3 = run(&cfg, g.width, g.height, &tris, RunOptions::default()).unwrap();
    let frame = render_with(&scene, &desc, options(), None, |_, _| {}).unwrap();
    // Per pixel: the triangle each shows. S3's depth word holds the winner's order tag
    // (its position in the trace, from 1).
    let s3_ids: Vec<Option<TriangleId>> = s3
        .frame
        .depth
        .iter()
        .map(|&d| (d != CLEAR_DEPTH_WORD).then(|| g.ids[(d & 0xFF_FFFF) as usize - 1]))
        .collect();
    let pixels = s3_ids.len();
    let coverage_differs = s3_ids
        .iter()
        .zip(&frame.triangles)
        .filter(|(a, b)| a.is_some() != b.is_some())
        .count();
    let both: Vec<usize> = (0..pixels)
        .filter(|&i| s3_ids[i].is_some() && frame.triangles[i].is_some())
        .collect();
    let other_triangle = both
        .iter()
        .filter(|&&i| s3_ids[i] != frame.triangles[i])
        .count();
    // Colour: S3 interpolates linearly in the window, the pipeline perspective-correctly,
    // and both round to 8 bits.
    let channel_error = |i: usize| {
        (0..3)
            .map(|c| {
                let byte = |w: u32| (w >> (8 * c)) & 0xFF;
                byte(s3.frame.colour[i]).abs_diff(byte(frame.pixels[i]))
            })
            .max()
            .unwrap()
    };
    let colour_off = both.iter().filter(|&&i| channel_error(i) > 4).count();
    println!(
        "{} pixels covered in both, coverage differs on {coverage_differs}, another triangle on \
         {other_triangle}, colour off by more than 4 on {colour_off}",
        both.len()
    );
    assert!(
        both.len() * 10 > pixels,
        "the sphere covers a good part of the window"
    );
    assert!(
        coverage_differs * 50 < pixels,
        "coverage differs on ≥ 2 % of the window"
    );
    // S3 snaps corners to 1/16 pixel, which moves shared edges a little: a pixel centre
    // near one may go to the neighbour (these triangles are a few pixels across).
    assert!(
        other_triangle * 20 < both.len(),
        "another triangle on ≥ 5 % of the pixels"
    );
    assert!(
        colour_off * 50 < both.len(),
        "colours differ on ≥ 2 % of the pixels"
    );
}

#[test]
fn cli_scene_draws_the_same_frame_at_k1_and_k16_and_counts_the_renders_triangles() {
    let run_k = |k: &str| {
        let (png, json) = (temp(&format!("k{k}.png")), temp(&format!("k{k}.json")));
        let o = imagine(&[
            "s3",
            "--scene",
            "RATE-1",
            "--size",
            "32",
            "--accelerators",
            k,
            "--png",
            png.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(stdout.contains("scene        RATE-1"), "{stdout}");
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        (std::fs::read(&png).unwrap(), j)
    };
    let (png1, j1) = run_k("1");
    let (png16, j16) = run_k("16");
    assert_eq!(png1, png16, "K = 1 and K = 16 drew different frames");
    assert!(j16["cycles"].as_u64() < j1["cycles"].as_u64());
    assert_eq!(j16["scene"], j1["scene"]);

    // RATE-1 culls nothing and every triangle is in view: all of the render's triangles
    // reach S3.
    let stats = temp("render.json");
    let o = imagine(&[
        "render",
        "RATE-1",
        "--size",
        "32",
        "--stats",
        stats.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    let rendered = &r["frame"]["triangles"];
    assert_eq!(
        rendered, 1024,
        "RATE-1 at 32×32: two triangles per two pixels"
    );
    let s = &j16["scene"];
    assert_eq!(&s["scene_triangles"], rendered);
    assert_eq!(&s["triangles"], rendered);
    assert_eq!(&j16["triangles"], rendered);
    assert_eq!(s["discarded"], 0);
    assert!(s["geometry_cycles"].as_u64().unwrap() > 0);
    assert_eq!(s["name"], "RATE-1");
}

#[test]
fn cli_scene_errors_are_clear() {
    let both = imagine(&["s3", "--scene", "SPHERE", "--trace", "game-sky"]);
    assert!(!both.status.success());
    let e = String::from_utf8_lossy(&both.stderr);
    assert!(e.contains("--scene") && e.contains("--trace"), "{e}");
    let neither = imagine(&["s3"]);
    assert!(!neither.status.success());
    let e = String::from_utf8_lossy(&neither.stderr);
    assert!(e.contains("--trace") && e.contains("--scene"), "{e}");
    let unknown = imagine(&["s3", "--scene", "NO-SUCH-SCENE"]);
    assert_eq!(unknown.status.code(), Some(1));
    let e = String::from_utf8_lossy(&unknown.stderr);
    assert!(e.contains("NO-SUCH-SCENE"), "{e}");
    assert!(!e.contains("panicked"), "{e}");
    let size = imagine(&["s3", "--trace", "game-sky", "--size", "64"]);
    assert_eq!(size.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&size.stderr).contains("--size"));
    let blending = imagine(&[
        "s3",
        "--scene",
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/verif/tests/scenes/spot-alpha-blend.toml"
        ),
    ]);
    assert_eq!(blending.status.code(), Some(1));
    let e = String::from_utf8_lossy(&blending.stderr);
    assert!(
        e.contains("spot-alpha-blend") && e.contains("pipeline.blend"),
        "{e}"
    );
    let bad_size = imagine(&["s3", "--scene", "SPHERE", "--size", "0"]);
    assert_eq!(bad_size.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad_size.stderr).contains("--size 0"));
}
