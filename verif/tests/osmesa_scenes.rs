//! Scene-file scenes ([`model::Scene`]) drawn by the f64 reference
//! ([`imagine_verif::reference_model`]) and by OSMesa with GL's own fixed-function lighting
//! ([`osmesa::render_model`]) (feature `osmesa`; needs `apt-get install -y
//! libosmesa6-dev`).
//!
//! The meshes are public OBJ files nobody here wrote (`tests/scenes/README.md` names their
//! sources): Suzanne with per-vertex normals and quads, the Utah teapot and a gingerbread
//! man without normals (lit with their triangles' geometric normals, or drawn in window
//! space). The scenes are built in code until the scene-file parser lands: look-at
//! cameras, several objects with translate · rotate · scale model matrices, positional
//! lights, back-, front- and no culling, all three depth tests.
//!
//! Each scene must agree with OSMesa on coverage (pixels exactly one of them leaves at the
//! black background) on at most 0.2 % of the pixels, with a PSNR of at least 38 dB.
//!
//! Measured (llvmpipe, Mesa 22.3.6): coverage mismatch 0 px in every scene but one (1 px),
//! PSNR 51.8–96 dB. Where the images differ by more than 1 (at most 9 pixels a scene), the
//! reference and Mesa drew the sample from different triangles: it lies within llvmpipe's
//! 1/256-pixel vertex snapping of an edge (or of a silhouette triangle whose tiny area
//! changes sign under snapping), and the two triangles' colours differ — a lot in
//! meshes without normals, whose triangles are lit flat. Mesa's own tie rule
//! ([`osmesa::tie_rule`]) changes none of the numbers: no sample falls exactly on an edge
//! here. The lighting itself agrees to within 1 (Suzanne, lit from per-vertex normals).
#![cfg(feature = "osmesa")]

use imagine_pipelines::scene::model::{
    Blend, Camera, Cull, DepthTest, Light, Material, Mesh, Object, PipelineKind, PipelineSettings,
    Scene, Shader, Space, TextureMode,
};
use imagine_pipelines::scene::{IDENTITY, mat_mul};
use imagine_verif::image::{compare, covered_error_histogram};
use imagine_verif::{osmesa, reference_model};
use std::path::Path;

// ---------------------------------------------------------------------------------------
// A tiny Wavefront OBJ reader (v, vn, f; 1-based and negative indices; polygons fanned
// from their first corner; everything else ignored).

/// Reads `tests/scenes/<name>`: one mesh vertex per distinct (position, normal) corner.
/// Normals are kept only when every face corner names one.
fn read_obj(name: &str) -> Mesh {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/scenes")
        .join(name);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path:?}: {e}"));
    let (mut v, mut vn) = (Vec::<[f32; 3]>::new(), Vec::<[f32; 3]>::new());
    let mut faces: Vec<Vec<(usize, Option<usize>)>> = Vec::new();
    let index = |s: &str, len: usize, line: usize| -> usize {
        let i: i64 = s
            .parse()
            .unwrap_or_else(|_| panic!("{name}:{line}: bad index `{s}`"));
        let i = if i < 0 { len as i64 + i } else { i - 1 };
        assert!(
            (0..len as i64).contains(&i),
            "{name}:{line}: index {s} out of range"
        );
        i as usize
    };
    for (line, text) in text.lines().enumerate() {
        let mut words = text.split_whitespace();
        let numbers = |words: std::str::SplitWhitespace| -> [f32; 3] {
            let n: Vec<f32> = words.take(3).map(|w| w.parse().unwrap()).collect();
            [n[0], n[1], n[2]]
        };
        match words.next() {
            Some("v") => v.push(numbers(words)),
            Some("vn") => vn.push(numbers(words)),
            Some("f") => faces.push(
                words
                    .map(|corner| {
                        let mut parts = corner.split('/');
                        let p = index(parts.next().unwrap(), v.len(), line + 1);
                        let n = parts
                            .nth(1)
                            .filter(|s| !s.is_empty())
                            .map(|s| index(s, vn.len(), line + 1));
                        (p, n)
                    })
                    .collect(),
            ),
            _ => {}
        }
    }
    let with_normals = faces.iter().flatten().all(|c| c.1.is_some());
    let mut mesh = Mesh::default();
    let mut ids = std::collections::HashMap::new();
    for face in &faces {
        let mut corner = |&(p, n): &(usize, Option<usize>)| -> u32 {
            let key = (p, if with_normals { n } else { None });
            *ids.entry(key).or_insert_with(|| {
                mesh.positions.push(v[p]);
                if with_normals {
                    mesh.normals.push(vn[n.unwrap()]);
                }
                mesh.positions.len() as u32 - 1
            })
        };
        let ids: Vec<u32> = face.iter().map(&mut corner).collect();
        for k in 1..ids.len().saturating_sub(1) {
            mesh.triangles.push([ids[0], ids[k], ids[k + 1]]);
        }
    }
    mesh
}

// ---------------------------------------------------------------------------------------
// Matrices (row-major, as the scene format): gluLookAt, gluPerspective, T · R · S.

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalize(v: [f32; 3]) -> [f32; 3] {
    let l = dot(v, v).sqrt();
    v.map(|c| c / l)
}

fn look_at(eye: [f32; 3], target: [f32; 3], up: [f32; 3]) -> [f32; 16] {
    let f = normalize(sub(target, eye));
    let s = normalize(cross(f, up));
    let u = cross(s, f);
    [
        s[0],
        s[1],
        s[2],
        -dot(s, eye),
        u[0],
        u[1],
        u[2],
        -dot(u, eye),
        -f[0],
        -f[1],
        -f[2],
        dot(f, eye),
        0.0,
        0.0,
        0.0,
        1.0,
    ]
}

fn perspective(fov_y: f32, aspect: f32, near: f32, far: f32) -> [f32; 16] {
    let f = 1.0 / (fov_y.to_radians() / 2.0).tan();
    let d = near - far;
    let mut m = [0.0; 16];
    m[0] = f / aspect;
    m[5] = f;
    m[10] = (far + near) / d;
    m[11] = 2.0 * far * near / d;
    m[14] = -1.0;
    m
}

/// `T · R · S` with `rotate = [angle°, x, y, z]` as glRotate.
fn trs(translate: [f32; 3], rotate: [f32; 4], scale: [f32; 3]) -> [f32; 16] {
    let mut t = IDENTITY;
    (t[3], t[7], t[11]) = (translate[0], translate[1], translate[2]);
    let [x, y, z] = normalize([rotate[1], rotate[2], rotate[3]]);
    let (s, c) = rotate[0].to_radians().sin_cos();
    let k = 1.0 - c;
    let r = [
        x * x * k + c,
        x * y * k - z * s,
        x * z * k + y * s,
        0.0,
        y * x * k + z * s,
        y * y * k + c,
        y * z * k - x * s,
        0.0,
        x * z * k - y * s,
        y * z * k + x * s,
        z * z * k + c,
        0.0,
        0.0,
        0.0,
        0.0,
        1.0,
    ];
    let mut sc = IDENTITY;
    (sc[0], sc[5], sc[10]) = (scale[0], scale[1], scale[2]);
    mat_mul(&t, &mat_mul(&r, &sc))
}

// ---------------------------------------------------------------------------------------
// Scene building.

fn lit(name: &str, diffuse: [f32; 3], specular: [f32; 3], shininess: f32) -> Material {
    Material {
        name: name.into(),
        shader: Shader::Lit,
        ambient: [0.2, 0.2, 0.2],
        diffuse,
        specular,
        shininess,
        textures: Vec::new(),
        texture_mode: TextureMode::Modulate,
    }
}

fn unlit(name: &str) -> Material {
    Material {
        shader: Shader::Unlit,
        ..lit(name, [0.8; 3], [0.0; 3], 0.0)
    }
}

fn light(position: [f32; 3], diffuse: [f32; 3], specular: [f32; 3]) -> Light {
    Light {
        position,
        ambient: [0.05, 0.05, 0.05],
        diffuse,
        specular,
    }
}

fn object(name: &str, mesh: &Mesh, material: usize, model: [f32; 16]) -> Object {
    Object {
        name: name.into(),
        material,
        model,
        colour: [1.0, 1.0, 1.0],
        space: Space::World,
        mesh: mesh.clone(),
    }
}

struct View {
    eye: [f32; 3],
    target: [f32; 3],
    fov_y: f32,
}

#[allow(clippy::too_many_arguments)]
fn scene(
    name: &str,
    (width, height): (u32, u32),
    view: View,
    (depth_test, cull): (DepthTest, Cull),
    ambient: [f32; 3],
    lights: Vec<Light>,
    materials: Vec<Material>,
    objects: Vec<Object>,
) -> Scene {
    Scene {
        name: name.into(),
        source: None,
        width,
        height,
        background: [0.0; 3],
        ambient,
        camera: Camera {
            view: look_at(view.eye, view.target, [0.0, 1.0, 0.0]),
            projection: perspective(view.fov_y, width as f32 / height as f32, 1.0, 100.0),
        },
        pipeline: PipelineSettings {
            kind: PipelineKind::OpenGl,
            depth_test,
            cull,
            blend: Blend::None,
            stop_length: 1.5,
        },
        lights,
        textures: Vec::new(),
        materials,
        objects,
    }
}

/// Suzanne's bounding box centre (the file's head sits at x ≈ −2.5, z ≈ 4.1).
const SUZANNE_CENTRE: [f32; 3] = [-2.494, 1.252, 4.104];

/// Suzanne's model matrix: centred on the origin, then `T · R · S`.
fn suzanne_at(translate: [f32; 3], rotate: [f32; 4], scale: f32) -> [f32; 16] {
    let centre = trs(SUZANNE_CENTRE.map(|c| -c), [0.0, 0.0, 1.0, 0.0], [1.0; 3]);
    mat_mul(&trs(translate, rotate, [scale; 3]), &centre)
}

// ---------------------------------------------------------------------------------------
// Comparison.

/// Renders `scene` both ways, prints the numbers and checks the bounds.
fn check(scene: &Scene) {
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
fn obj_reader_reads_the_fixtures() {
    let suzanne = read_obj("suzanne.obj");
    assert_eq!(suzanne.normals.len(), suzanne.positions.len());
    assert!(suzanne.triangles.len() > 900, "{}", suzanne.triangles.len());
    let teapot = read_obj("teapot.obj");
    assert!(teapot.normals.is_empty());
    assert_eq!(teapot.triangles.len(), 6320);
    let woody = read_obj("woody.obj");
    assert_eq!(woody.triangles.len(), 1267);
}

/// Suzanne (per-vertex normals) lit by two white positional lights with a sharp
/// highlight, seen from above and to the side; back faces culled.
#[test]
fn suzanne_two_lights() {
    let suzanne = read_obj("suzanne.obj");
    check(&scene(
        "suzanne-two-lights",
        (320, 256),
        View {
            eye: [2.5, 1.5, 6.0],
            target: [0.0, 0.0, 0.0],
            fov_y: 30.0,
        },
        (DepthTest::Less, Cull::Back),
        [0.2, 0.2, 0.2],
        vec![
            light([4.0, 4.0, 6.0], [0.8, 0.8, 0.8], [1.0, 1.0, 1.0]),
            light([-5.0, 1.0, 2.0], [0.3, 0.3, 0.5], [0.5, 0.5, 0.5]),
        ],
        vec![lit("skin", [0.7, 0.5, 0.3], [0.6, 0.6, 0.6], 32.0)],
        vec![object(
            "suzanne",
            &suzanne,
            0,
            suzanne_at([0.0, 0.0, 0.0], [-20.0, 0.0, 1.0, 0.0], 1.0),
        )],
    ));
}

/// The Utah teapot without normals: every triangle lit with its geometric normal by three
/// coloured lights, one of them close to the spout; a look-at camera from above.
#[test]
fn teapot_geometric_normals() {
    let teapot = read_obj("teapot.obj");
    check(&scene(
        "teapot-geometric-normals",
        (256, 256),
        View {
            eye: [3.0, 5.0, 8.0],
            target: [0.0, 0.8, 0.0],
            fov_y: 40.0,
        },
        (DepthTest::Less, Cull::Back),
        [0.1, 0.1, 0.1],
        vec![
            light([5.0, 5.0, 5.0], [1.0, 0.9, 0.8], [1.0, 1.0, 1.0]),
            light([-6.0, 2.0, -1.0], [0.2, 0.3, 0.9], [0.3, 0.3, 0.6]),
            light([4.0, 2.0, 0.5], [0.6, 0.1, 0.1], [0.5, 0.2, 0.2]),
        ],
        vec![lit("china", [0.8, 0.8, 0.8], [0.5, 0.5, 0.5], 20.0)],
        vec![object(
            "teapot",
            &teapot,
            0,
            trs([0.0, 0.0, 0.0], [30.0, 0.0, 1.0, 0.0], [0.8, 0.8, 0.8]),
        )],
    ));
}

/// Several objects with their own transforms and materials (lit and unlit, a non-uniform
/// scale), interpenetrating, under four lights; `LEQUAL` depth test, back faces culled.
#[test]
fn several_objects() {
    let (suzanne, teapot) = (read_obj("suzanne.obj"), read_obj("teapot.obj"));
    let mut unlit_suzanne = object(
        "suzanne-unlit",
        &suzanne,
        2,
        suzanne_at([2.2, 1.6, -1.0], [45.0, 1.0, 1.0, 0.0], 0.7),
    );
    unlit_suzanne.colour = [0.3, 0.8, 0.4];
    check(&scene(
        "several-objects",
        (384, 288),
        View {
            eye: [-3.0, 4.0, 9.0],
            target: [0.5, 0.5, 0.0],
            fov_y: 45.0,
        },
        (DepthTest::Lequal, Cull::Back),
        [0.15, 0.15, 0.2],
        vec![
            light([6.0, 8.0, 6.0], [0.9, 0.9, 0.9], [1.0, 1.0, 1.0]),
            light([-4.0, 1.0, 4.0], [0.4, 0.2, 0.1], [0.2, 0.2, 0.2]),
            light([0.0, -3.0, 2.0], [0.1, 0.3, 0.4], [0.0, 0.0, 0.0]),
            light([2.0, 3.0, -4.0], [0.3, 0.3, 0.3], [0.8, 0.8, 0.8]),
        ],
        vec![
            lit("gold", [0.75, 0.6, 0.2], [0.9, 0.8, 0.5], 80.0),
            lit("matte", [0.4, 0.5, 0.9], [0.0, 0.0, 0.0], 0.0),
            unlit("flat"),
        ],
        vec![
            object(
                "teapot",
                &teapot,
                1,
                trs([0.0, -1.0, 0.0], [-40.0, 0.0, 1.0, 0.0], [0.9, 0.6, 0.9]),
            ),
            object(
                "suzanne-gold",
                &suzanne,
                0,
                suzanne_at([-1.5, 1.2, 1.0], [30.0, 0.0, 1.0, 0.2], 1.2),
            ),
            unlit_suzanne,
            object(
                "suzanne-small",
                &suzanne,
                1,
                suzanne_at([1.0, 0.3, 2.0], [-70.0, 0.3, 1.0, 0.0], 0.5),
            ),
        ],
    ));
}

/// A window-space object (the gingerbread man, a flat 2-D mesh in pixels, unlit) over a
/// lit world-space Suzanne; no culling (every face drawn, back faces lit one-sided).
#[test]
fn window_space_and_no_culling() {
    let (suzanne, woody) = (read_obj("suzanne.obj"), read_obj("woody.obj"));
    let mut gingerbread = object(
        "woody",
        &woody,
        1,
        trs([20.0, 10.0, 0.25], [0.0, 0.0, 0.0, 1.0], [0.5, 0.5, 1.0]),
    );
    gingerbread.space = Space::Window;
    gingerbread.colour = [0.8, 0.5, 0.2];
    check(&scene(
        "window-space-no-cull",
        (256, 256),
        View {
            eye: [0.0, 2.0, 5.0],
            target: [0.0, 0.0, 0.0],
            fov_y: 35.0,
        },
        (DepthTest::Less, Cull::None),
        [0.2, 0.2, 0.2],
        vec![light([3.0, 3.0, 3.0], [0.9, 0.9, 0.9], [0.7, 0.7, 0.7])],
        vec![
            lit("clay", [0.8, 0.3, 0.3], [0.4, 0.4, 0.4], 10.0),
            unlit("flat"),
        ],
        vec![
            object(
                "suzanne",
                &suzanne,
                0,
                suzanne_at([0.3, 0.0, 0.0], [160.0, 0.0, 1.0, 0.0], 1.0),
            ),
            gingerbread,
        ],
    ));
}

/// Front faces culled (the insides of the teapot and of Suzanne show, lit one-sided with
/// their outward normals) and the `ALWAYS` depth test: the last triangle drawn wins.
#[test]
fn front_culling_and_depth_always() {
    let (suzanne, teapot) = (read_obj("suzanne.obj"), read_obj("teapot.obj"));
    check(&scene(
        "front-cull-depth-always",
        (256, 256),
        View {
            eye: [1.0, 3.0, 7.0],
            target: [0.0, 0.5, 0.0],
            fov_y: 40.0,
        },
        (DepthTest::Always, Cull::Front),
        [0.3, 0.3, 0.3],
        vec![
            light([0.0, 1.0, 0.0], [0.9, 0.8, 0.7], [0.5, 0.5, 0.5]),
            light([-2.0, 5.0, 5.0], [0.3, 0.3, 0.3], [0.2, 0.2, 0.2]),
        ],
        vec![
            lit("inside", [0.6, 0.7, 0.8], [0.3, 0.3, 0.3], 5.0),
            lit("red", [0.9, 0.2, 0.2], [0.0, 0.0, 0.0], 1.0),
        ],
        vec![
            object(
                "teapot",
                &teapot,
                0,
                trs([0.0, 0.0, 0.0], [10.0, 0.0, 1.0, 0.0], [0.7, 0.7, 0.7]),
            ),
            object(
                "suzanne",
                &suzanne,
                1,
                suzanne_at([1.5, 1.5, 1.0], [0.0, 0.0, 1.0, 0.0], 0.6),
            ),
        ],
    ));
}

/// The camera so close that the near plane (1 unit from the eye) cuts through Suzanne's
/// face and the teapot behind reaches past the window's edges: OSMesa clips those
/// triangles, the reference keeps the samples whose depth is in [0, 1].
#[test]
fn near_plane_and_window_edges_cut_objects() {
    let (suzanne, teapot) = (read_obj("suzanne.obj"), read_obj("teapot.obj"));
    check(&scene(
        "near-plane-cut",
        (256, 192),
        View {
            eye: [0.3, 0.4, 1.6],
            target: [0.0, 0.0, 0.0],
            fov_y: 60.0,
        },
        (DepthTest::Less, Cull::Back),
        [0.2, 0.2, 0.2],
        vec![
            light([1.0, 2.0, 3.0], [0.8, 0.8, 0.8], [0.6, 0.6, 0.6]),
            light([-3.0, -1.0, 1.0], [0.2, 0.4, 0.2], [0.0, 0.0, 0.0]),
        ],
        vec![
            lit("skin", [0.7, 0.5, 0.3], [0.6, 0.6, 0.6], 24.0),
            lit("china", [0.6, 0.6, 0.8], [0.3, 0.3, 0.3], 12.0),
        ],
        vec![
            object(
                "suzanne",
                &suzanne,
                0,
                suzanne_at([0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], 0.8),
            ),
            object(
                "teapot",
                &teapot,
                1,
                trs([0.0, -1.5, -3.0], [20.0, 0.0, 1.0, 0.0], [1.2, 1.2, 1.2]),
            ),
        ],
    ));
}
