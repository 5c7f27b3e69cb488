//! Cases in world space, through a camera: subnormal and near-underflow coordinates and
//! texture coordinates, flush-to-zero on and off, texture coordinates of 10⁶ repeats,
//! triangles crossing the eye plane (w → 0, w < 0), depth ranges of 10⁻³/10⁶ and
//! 1/1.0001, and cancellation 10⁶ from the origin.
//!
//! Each scene is a scene file's text (window, camera, materials, textures) with one
//! placeholder object whose mesh the case then replaces by one built here, so that every
//! number the case depends on is in this file.

use std::path::Path;

use anyhow::{Result, anyhow};
use imagine_pipelines::scene::model::{Blend, DepthTest, Mesh, Scene};
use imagine_pipelines::scene::{LoadOptions, file};

use super::case::{Case, Expect};
use super::check::Bound;
use super::window_space::TILE_LEVEL;

/// A scene file's text; its objects' meshes replaced by `meshes` in order (as many as it
/// has objects).
pub fn scene(name: &str, text: &str, meshes: Vec<Mesh>) -> Result<Scene> {
    let path = Path::new("stress").join(format!("{name}.toml"));
    let mut scene =
        file::parse(text, &path, &LoadOptions::default()).map_err(|e| anyhow!("{e}"))?;
    if scene.objects.len() != meshes.len() {
        return Err(anyhow!(
            "{name}: {} objects for {} meshes",
            scene.objects.len(),
            meshes.len()
        ));
    }
    for (object, mesh) in scene.objects.iter_mut().zip(meshes) {
        object.mesh = mesh;
    }
    Ok(scene)
}

/// A placeholder object (its mesh is replaced) of `material`.
fn object(material: &str) -> String {
    format!(
        "[[object]]\nprimitive = {{ kind = \"icosphere\", subdivisions = 0 }}\nmaterial = \"{material}\"\n"
    )
}

/// Separate triangles of the given corners, one colour per corner.
pub fn triangles(corners: &[[f32; 3]], colours: &[[f32; 3]]) -> Mesh {
    Mesh {
        positions: corners.to_vec(),
        colours: colours.to_vec(),
        triangles: (0..corners.len() as u32 / 3)
            .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect(),
        separate: true,
        ..Mesh::default()
    }
}

/// Colours for `n` corners, varied.
pub fn rainbow(n: usize) -> Vec<[f32; 3]> {
    (0..n)
        .map(|i| {
            let k = i as f32;
            [
                (k * 0.37).fract(),
                (0.2 + k * 0.61).fract(),
                (0.5 + k * 0.23).fract(),
            ]
        })
        .collect()
}

/// A quad `[x0, x1] × [y0, y1]` at z = 0 with texture coordinates `s0..s1`, `t0..t1`.
fn textured_quad(xy: [f32; 4], st: [f32; 4]) -> Mesh {
    let [x0, x1, y0, y1] = xy;
    let [s0, s1, t0, t1] = st;
    Mesh {
        positions: vec![[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]],
        texcoords: vec![[s0, t0], [s1, t0], [s1, t1], [s0, t1]],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
        ..Mesh::default()
    }
}

/// A `n × n` grid over `[-1, 1]²` at z = 0 (interior vertices jittered, border vertices on
/// the border), shared vertices, counter-clockwise; with `degenerate`, each cell also
/// holds faces of no area: a collapsed corner `[a, a, b]`, a collinear `[a, m, b]` with
/// `m` the midpoint of an edge, and a single point `[a, a, a]`.
pub fn grid(n: u32, degenerate: bool) -> Mesh {
    let mut m = Mesh::default();
    let step = 2.0 / n as f32;
    for j in 0..=n {
        for i in 0..=n {
            let jitter = |k: u32, inner: bool| {
                if inner {
                    ((k * 7919 + 13) % 17) as f32 / 17.0 * 0.6 - 0.3
                } else {
                    0.0
                }
            };
            let x = -1.0 + step * (i as f32 + jitter(i * 31 + j, i > 0 && i < n));
            let y = -1.0 + step * (j as f32 + jitter(j * 17 + i, j > 0 && j < n));
            m.positions.push([x, y, 0.0]);
        }
    }
    let at = |i: u32, j: u32| j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            if (i + j) % 2 == 0 {
                m.triangles.extend([[a, b, c], [a, c, d]]);
            } else {
                m.triangles.extend([[a, b, d], [b, c, d]]);
            }
            if degenerate {
                let p = |v: u32| m.positions[v as usize];
                let (pa, pb) = (p(a), p(b));
                let mid = [(pa[0] + pb[0]) / 2.0, (pa[1] + pb[1]) / 2.0, 0.0];
                let mid_index = m.positions.len() as u32;
                m.positions.push(mid);
                m.triangles
                    .extend([[a, a, b], [a, mid_index, b], [c, c, c], [d, b, d]]);
            }
        }
    }
    m
}

const ORTHO_64: &str = "[window]\nwidth = 64\nheight = 64\n";

fn render(
    name: &'static str,
    about: &'static str,
    flush_to_zero: bool,
    scene: impl Fn() -> Result<Scene> + Send + Sync + 'static,
    expect: Vec<Expect>,
) -> Case {
    Case::render("world", name, about, flush_to_zero, scene, expect)
}

/// Triangles at subnormal fp32 coordinates (below 1.18e-38) seen through an orthographic
/// camera 6.4e-38 wide: one spans the view, one lies wholly in the subnormal range.
fn subnormal_coordinates() -> Result<Scene> {
    let text = format!(
        "{ORTHO_64}[camera]\nmodelview = [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]\n\
         ortho = [-3.2e-38, 3.2e-38, -3.2e-38, 3.2e-38, -1.0, 1.0]\n\
         [[material]]\nname = \"m\"\nshader = \"unlit\"\n{}",
        object("m")
    );
    // Corners chosen so that no pixel centre lies within rounding of an edge (the ties are
    // the pixel-centre cases' subject, not this one's).
    let corners = [
        [-2.93e-38, -3.07e-38, 0.5],
        [3.01e-38, -2.47e-38, 0.5],
        [5.3e-39, 2.97e-38, 0.5],
        [1.0e-39, 1.0e-39, 0.0],
        [1.1e-38, 2.0e-39, 0.0],
        [3.0e-39, 1.0e-38, 0.0],
    ];
    scene(
        "subnormal-coordinates",
        &text,
        vec![triangles(&corners, &rainbow(6))],
    )
}

/// A projection scaled by `s` (clip = s · orthographic): the same picture for every `s`
/// (the divide by w removes it), but the homogeneous edge functions multiply three clip
/// coordinates, so their products scale by s³.
fn scaled_clip(s: f32) -> Result<Scene> {
    let p = |v: f32| v * s;
    let text = format!(
        "{ORTHO_64}[camera]\nmodelview = [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]\n\
         projection = [{:e}, 0, 0, 0,  0, {:e}, 0, 0,  0, 0, {:e}, 0,  0, 0, 0, {:e}]\n\
         [[material]]\nname = \"m\"\nshader = \"unlit\"\n{}",
        p(1.0 / 32.0),
        p(1.0 / 32.0),
        p(-0.5),
        p(1.0),
        object("m")
    );
    let corners = [
        [-30.0, -28.0, 0.5],
        [29.0, -20.0, 0.5],
        [3.0, 31.0, 0.5],
        [-20.0, 5.0, 0.2],
        [25.0, 10.0, 0.8],
        [-5.0, 25.0, -0.4],
    ];
    scene("scaled-clip", &text, vec![triangles(&corners, &rainbow(6))])
}

/// [`scaled_clip`] with the pipeline's `normalise_clip` on: `assemble_clip` scales each
/// triangle's corners back near 1 (exactly) before the edge functions.
fn normalised_clip(s: f32) -> Result<Scene> {
    let mut scene = scaled_clip(s)?;
    scene.pipeline.normalise_clip = true;
    Ok(scene)
}

/// A quad filling the view, textured by a nearest checker of red and blue, `replace`d:
/// every covered pixel shows a texel.
fn textured(name: &str, filter: &str, wrap: &str, st: [f32; 4]) -> Result<Scene> {
    let text = format!(
        "{ORTHO_64}[camera]\nmodelview = [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]\n\
         ortho = [-1, 1, -1, 1, -1, 1]\n\
         [[texture]]\nname = \"checker\"\n\
         procedural = {{ kind = \"checker\", size = 16, cells = 4, colours = [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]] }}\n\
         filter = \"{filter}\"\nwrap = \"{wrap}\"\n\
         [[material]]\nname = \"m\"\nshader = \"unlit\"\ntextures = [\"checker\"]\n\
         texture_mode = \"replace\"\n{}",
        object("m")
    );
    scene(
        name,
        &text,
        vec![textured_quad([-0.9, 0.95, -0.85, 0.9], st)],
    )
}

/// Seen from 1 above a floor of 200 × 200 (y = 0) that reaches behind the eye, whose
/// corners behind it have w < 0, Gouraud-coloured and checker-textured.
fn floor_through_eye_plane(textured: bool) -> Result<Scene> {
    let texture = if textured {
        "[[texture]]\nname = \"checker\"\n\
         procedural = { kind = \"checker\", size = 64, cells = 8, colours = [[0.9, 0.8, 0.2], [0.1, 0.3, 0.7]] }\n\
         filter = \"trilinear\"\n\
         [[material]]\nname = \"m\"\nshader = \"unlit\"\ntextures = [\"checker\"]\n"
    } else {
        "[[material]]\nname = \"m\"\nshader = \"unlit\"\n"
    };
    let text = format!(
        "[window]\nwidth = 64\nheight = 48\n[camera]\neye = [0.0, 1.0, 0.0]\n\
         target = [0.3, 0.7, -4.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 70.0\nnear = 0.1\nfar = 300.0\n\
         {texture}{}",
        object("m")
    );
    let mut floor = Mesh {
        positions: vec![
            [-100.0, 0.0, 100.0],
            [100.0, 0.0, 100.0],
            [100.0, 0.0, -100.0],
            [-100.0, 0.0, -100.0],
        ],
        colours: vec![
            [1.0, 0.2, 0.2],
            [0.2, 1.0, 0.2],
            [0.2, 0.2, 1.0],
            [1.0, 1.0, 0.2],
        ],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
        ..Mesh::default()
    };
    if textured {
        floor.texcoords = vec![[0.0, 0.0], [50.0, 0.0], [50.0, 50.0], [0.0, 50.0]];
    }
    scene("eye-plane-floor", &text, vec![floor])
}

/// A perspective camera at the origin looking down −z (near 0.1), and triangles with the
/// given eye-space corners (the view is the identity, so w = −z).
fn perspective(name: &str, corners: &[[f32; 3]]) -> Result<Scene> {
    let text = format!(
        "{ORTHO_64}[camera]\nmodelview = [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]\n\
         fov_y = 60.0\nnear = 0.1\nfar = 100.0\n\
         [[material]]\nname = \"m\"\nshader = \"unlit\"\n{}",
        object("m")
    );
    scene(
        name,
        &text,
        vec![triangles(corners, &rainbow(corners.len()))],
    )
}

/// Two lit balls that interpenetrate, and a third far behind them, seen with near and far
/// planes `near`, `far`.
fn depth_range_balls(near: f64, far: f64) -> Result<Scene> {
    let text = format!(
        "{ORTHO_64}[camera]\neye = [0.0, 0.0, 4.0]\ntarget = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\n\
         fov_y = 40.0\nnear = {near}\nfar = {far}\n\
         [[light]]\nposition = [4.0, 6.0, 8.0]\n\
         [[material]]\nname = \"a\"\nshader = \"lit\"\ndiffuse = [0.9, 0.3, 0.2]\n\
         specular = [0.5, 0.5, 0.5]\nshininess = 20.0\n\
         [[material]]\nname = \"b\"\nshader = \"lit\"\ndiffuse = [0.2, 0.5, 0.9]\n\
         [[object]]\nprimitive = {{ kind = \"icosphere\", subdivisions = 2 }}\nmaterial = \"a\"\n\
         translate = [-0.4, 0.0, 0.0]\n\
         [[object]]\nprimitive = {{ kind = \"icosphere\", subdivisions = 2 }}\nmaterial = \"b\"\n\
         translate = [0.5, 0.2, -0.3]\nscale = [0.9, 0.9, 0.9]\n"
    );
    let path = Path::new("stress").join("depth-range.toml");
    file::parse(&text, &path, &LoadOptions::default()).map_err(|e| anyhow!("{e}"))
}

/// Triangles that cross each other inside a depth slab of 10⁻⁴ (near 1, far 1.0001).
fn thin_depth_slab() -> Result<Scene> {
    let text = format!(
        "{ORTHO_64}[camera]\nmodelview = [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]\n\
         fov_y = 60.0\nnear = 1.0\nfar = 1.0001\n\
         [[material]]\nname = \"m\"\nshader = \"unlit\"\n{}",
        object("m")
    );
    let corners = [
        [-0.5, -0.5, -1.00001],
        [0.5, -0.4, -1.00009],
        [0.0, 0.5, -1.00001],
        [-0.5, 0.3, -1.00009],
        [0.5, 0.4, -1.00001],
        [0.1, -0.5, -1.00005],
        [-0.3, -0.3, -1.00003],
        [0.4, 0.0, -1.00003],
        [-0.2, 0.45, -1.00003],
    ];
    scene(
        "thin-depth-slab",
        &text,
        vec![triangles(&corners, &rainbow(9))],
    )
}

/// A grid 2·10⁻² wide (cells of 2.5·10⁻³) at 10⁶ from the origin in x and y, seen from 0.1
/// away: the view's translation cancels the model's in fp32.
fn far_from_origin(tiles: bool) -> Result<Scene> {
    let text = format!(
        "{ORTHO_64}[camera]\neye = [1000000.0, 1000000.0, 0.1]\n\
         target = [1000000.0, 1000000.0, 0.0]\nup = [0.0, 1.0, 0.0]\n\
         fov_y = 5.0\nnear = 0.01\nfar = 1.0\n\
         [[material]]\nname = \"m\"\nshader = \"unlit\"\n\
         [[object]]\nprimitive = {{ kind = \"icosphere\", subdivisions = 0 }}\nmaterial = \"m\"\n\
         translate = [1000000.0, 1000000.0, 0.0]\nscale = [0.01, 0.01, 0.01]\n"
    );
    let mut mesh = grid(8, false);
    mesh.colours = if tiles {
        vec![[0.25; 3]; mesh.positions.len()]
    } else {
        rainbow(mesh.positions.len())
    };
    let mut s = scene("far-from-origin", &text, vec![mesh])?;
    if tiles {
        s.pipeline.blend = Blend::Add;
        s.pipeline.depth_test = DepthTest::Always;
    }
    Ok(s)
}

/// A strip from x = −10⁶ to +10⁶, 2·10⁻² tall, seen in perspective from 0.05 in front of
/// its middle: its far corners are 10⁷ times the view's width away.
fn long_strip() -> Result<Scene> {
    let text = format!(
        "{ORTHO_64}[camera]\neye = [0.0, 0.0, 0.05]\ntarget = [0.0, 0.0, 0.0]\n\
         up = [0.0, 1.0, 0.0]\nfov_y = 30.0\nnear = 0.001\nfar = 10.0\n\
         [[material]]\nname = \"m\"\nshader = \"unlit\"\n{}",
        object("m")
    );
    let corners = [
        [-1.0e6, -0.01, 0.0],
        [1.0e6, -0.01, 0.0],
        [1.0e6, 0.01, 0.0],
        [-1.0e6, -0.01, 0.0],
        [1.0e6, 0.01, 0.0],
        [-1.0e6, 0.01, 0.0],
        [-1.0e6, 0.004, 0.001],
        [0.003, 0.009, 0.001],
        [0.004, 0.0, 0.001],
    ];
    scene("long-strip", &text, vec![triangles(&corners, &rainbow(9))])
}

/// The lit balls (normal numbers throughout) for the flush-to-zero comparison.
fn lit_balls() -> Result<Scene> {
    depth_range_balls(1.0, 20.0)
}

const RED_BLUE: &[[u8; 3]] = &[[255, 0, 0], [0, 0, 255]];

const UNNORMALISED: &str = "without `pipeline.normalise_clip` the rasterizer's determinant, a \
    product of three clip coordinates, underflows to 0 at w ~ 1e-17 (1e-46) and both \
    triangles are dropped as degenerate; normalising costs about 1 % of SPHERE's cycles, so \
    it is the scene's choice, off by default";

pub fn cases() -> Vec<Case> {
    vec![
        render(
            "subnormal-coordinates",
            "vertices at subnormal fp32 coordinates (1e-39..3e-38): the reference's image",
            false,
            subnormal_coordinates,
            vec![Expect::Reference(Bound::TIGHT)],
        ),
        render(
            "subnormal-coordinates-ftz",
            "the same with flush-to-zero: subnormal inputs become 0, no invalid value, deterministic",
            true,
            subnormal_coordinates,
            vec![],
        ),
        render(
            "clip-scale-1",
            "two triangles through an orthographic camera, clip coordinates unscaled: the reference's image",
            false,
            || scaled_clip(1.0),
            vec![Expect::Reference(Bound {
                coverage: 0.001,
                visibility: 0.0,
                levels: 1,
            })],
        ),
        render(
            "clip-scale-2^-40",
            "clip coordinates scaled by 2^-40 (w ~ 1e-12, edge products ~1e-21, det ~1e-31): the unscaled frame",
            false,
            || scaled_clip(2f32.powi(-40)),
            vec![Expect::SameFrameAs(|| scaled_clip(1.0))],
        ),
        render(
            "clip-scale-2^-40-ftz",
            "the same with flush-to-zero: the same frame (no subnormal reached)",
            true,
            || scaled_clip(2f32.powi(-40)),
            vec![Expect::SameWithFlushToZeroSwitched],
        ),
        render(
            "clip-scale-2^33",
            "clip coordinates scaled by 2^33 (w ~ 1e10, det ~1e35, near fp32's largest): the unscaled frame",
            false,
            || scaled_clip(2f32.powi(33)),
            vec![Expect::SameFrameAs(|| scaled_clip(1.0))],
        ),
        render(
            "clip-scale-2^-56",
            "clip coordinates scaled by 2^-56 (w ~ 1e-17), normalise_clip on: the unscaled frame",
            false,
            || normalised_clip(2f32.powi(-56)),
            vec![Expect::SameFrameAs(|| scaled_clip(1.0))],
        ),
        render(
            "clip-scale-2^-56-unnormalised",
            "the same with normalise_clip off (the default): the unscaled frame",
            false,
            || scaled_clip(2f32.powi(-56)),
            vec![Expect::SameFrameAs(|| scaled_clip(1.0))],
        )
        .known(UNNORMALISED),
        render(
            "clip-scale-2^-100",
            "clip coordinates scaled by 2^-100 (w ~ 1e-30), normalise_clip on: the unscaled frame",
            false,
            || normalised_clip(2f32.powi(-100)),
            vec![Expect::SameFrameAs(|| scaled_clip(1.0))],
        ),
        render(
            "clip-scale-2^100",
            "clip coordinates scaled by 2^100 (w ~ 1e30), normalise_clip on: the unscaled frame",
            false,
            || normalised_clip(2f32.powi(100)),
            vec![Expect::SameFrameAs(|| scaled_clip(1.0))],
        ),
        render(
            "subnormal-texcoords",
            "texture coordinates in [0, 1e-39] (subnormal): texel (0, 0) everywhere, as the reference",
            false,
            || {
                textured(
                    "subnormal-texcoords",
                    "nearest",
                    "repeat",
                    [0.0, 1e-39, 0.0, 1e-39],
                )
            },
            vec![Expect::Reference(Bound::TIGHT)],
        ),
        render(
            "subnormal-texcoords-ftz",
            "the same with flush-to-zero: the same frame",
            true,
            || {
                textured(
                    "subnormal-texcoords",
                    "nearest",
                    "repeat",
                    [0.0, 1e-39, 0.0, 1e-39],
                )
            },
            vec![Expect::SameWithFlushToZeroSwitched],
        ),
        render(
            "texcoords-1e6-repeats-nearest",
            "texture coordinates 0..1e6 (1e6 repeats): every pixel a texel of the texture",
            false,
            || textured("repeats-nearest", "nearest", "repeat", [0.0, 1e6, 0.0, 1e6]),
            vec![Expect::OnlyColours(RED_BLUE), Expect::Covers(0.8)],
        ),
        render(
            "texcoords-1e6-clamp",
            "texture coordinates -1e6..1e6 clamped: every pixel an edge texel",
            false,
            || textured("repeats-clamp", "nearest", "clamp", [-1e6, 1e6, -1e6, 1e6]),
            vec![Expect::OnlyColours(RED_BLUE), Expect::Covers(0.8)],
        ),
        render(
            "texcoords-1e6-repeats-trilinear",
            "1e6 repeats, mipmapped: the smallest level (the texture's mean) everywhere, as the reference",
            false,
            || {
                textured(
                    "repeats-trilinear",
                    "trilinear",
                    "repeat",
                    [0.0, 1e6, 0.0, 1e6],
                )
            },
            vec![Expect::Reference(Bound::TIGHT)],
        ),
        render(
            "eye-plane-floor",
            "a floor reaching behind the eye (w < 0 at two corners): the reference's image",
            false,
            || floor_through_eye_plane(false),
            vec![Expect::Reference(Bound::TIGHT)],
        ),
        render(
            "eye-plane-floor-textured",
            "the floor checker-textured (trilinear): the reference's image",
            false,
            || floor_through_eye_plane(true),
            vec![Expect::Reference(Bound::TIGHT)],
        ),
        render(
            "w-zero-vertex",
            "a vertex exactly on the eye plane (w = 0) and one at w = 1e-30: the reference's image",
            false,
            || {
                perspective(
                    "w-zero",
                    &[
                        [0.5, -0.4, 0.0],
                        [0.6, 0.5, -2.0],
                        [-0.8, -0.2, -1.5],
                        [-0.3, 0.2, -1e-30],
                        [0.4, -0.6, -1.0],
                        [0.3, 0.3, -3.0],
                    ],
                )
            },
            vec![Expect::Reference(Bound::TIGHT)],
        ),
        render(
            "behind-the-eye",
            "triangles wholly behind the eye (w < 0) or on its plane: nothing drawn",
            false,
            || {
                perspective(
                    "behind",
                    &[
                        [-1.0, -1.0, 1.0],
                        [1.0, -1.0, 1.0],
                        [0.0, 1.0, 2.0],
                        [-1.0, -1.0, 0.0],
                        [1.0, -1.0, 0.0],
                        [0.0, 1.0, 0.0],
                        [-0.01, -0.01, 1e-30],
                        [0.01, -0.01, 1e-30],
                        [0.0, 0.01, 1e-30],
                    ],
                )
            },
            vec![Expect::Empty],
        ),
        render(
            "depth-range-1e-3-1e6",
            "interpenetrating lit balls, near 1e-3, far 1e6: the reference's visibility",
            false,
            || depth_range_balls(1e-3, 1e6),
            // With near 1e-3 the fp32 depth at distance 4 resolves about 1e-3 of depth
            // (the reference's f64, 1e-12): where the balls' surfaces cross, within that,
            // the depth test picks either (0.7 % of the window measured).
            vec![Expect::Reference(Bound {
                coverage: 0.0,
                visibility: 0.01,
                levels: 1,
            })],
        ),
        render(
            "depth-range-1-1.0001",
            "triangles crossing inside a slab of 1e-4, near 1, far 1.0001: the reference's visibility",
            false,
            thin_depth_slab,
            vec![Expect::Reference(Bound::TIGHT)],
        ),
        render(
            "far-from-origin-1e6",
            "a mesh of 1e-2 features 1e6 from the origin (fp32 cancellation): the reference's image",
            false,
            || far_from_origin(false),
            vec![Expect::Reference(Bound::TIGHT)],
        ),
        render(
            "far-from-origin-1e6-tiles",
            "that mesh, grey and blended: tiles its part of the window once",
            false,
            || far_from_origin(true),
            vec![Expect::TilesOnce { level: TILE_LEVEL }],
        ),
        render(
            "long-strip-1e6",
            "a strip 2e6 long and 2e-2 tall seen from 0.05: the reference's image",
            false,
            long_strip,
            vec![Expect::Reference(Bound::TIGHT)],
        ),
        render(
            "flush-to-zero-lit",
            "lit balls with flush-to-zero on: the same frame as with it off",
            true,
            lit_balls,
            vec![Expect::SameWithFlushToZeroSwitched],
        ),
    ]
}
