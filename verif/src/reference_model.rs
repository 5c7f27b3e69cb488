//! The f64 reference renderer for a resolved scene file ([`model::Scene`], the contract in
//! `SCENE_FORMAT.md`): the same rasterization core as [`crate::reference`] (homogeneous
//! edge functions, tie rule, near/far clipping by the fragment's depth range,
//! perspective-correct interpolation — [`reference::rasterize_triangle`]), fed by a
//! front-end that reads objects, materials and lights.
//!
//! # Vertices
//!
//! Objects are drawn in order, each object's triangles in order. A vertex goes through the
//! object's model matrix, then the view, then the projection of [`model::Scene::camera_for`]
//! (identity view and `window_to_clip` for window-space objects), each a row-major f32
//! matrix widened exactly to f64, every product in f64.
//!
//! Its colour depends on the object's material:
//!
//! * [`Shader::Unlit`]: the mesh's vertex colour, or the object's colour when the mesh has
//!   none.
//! * [`Shader::Marble`]: white at the vertices; the fragment's colour is the marble shader
//!   ([`crate::marble`]) at its perspective-correct object-space position and normal.
//! * [`Shader::BumpEnv`]: the object's colour; its vertices are displaced by the combined
//!   displacement/bump map and the fragment's colour is the environment texel along the
//!   reflection of the bumped normal, times that colour ([`crate::bump_env`]).
//! * [`Shader::Lit`]: OpenGL 1.x fixed-function lighting in eye space ([`lit_colour`]),
//!   as `glLightfv(GL_POSITION)` with the camera's view loaded leaves the lights: each
//!   light's eye position is `view · (position, 1)` with the *camera's* view (also for
//!   window-space objects, whose model-view is just their model matrix). The vertex's eye
//!   position is `modelview · (p, 1)`, its normal goes through the inverse transpose of
//!   the model-view's upper 3 × 3 and is renormalised (`GL_NORMALIZE`). With
//!   `GL_LIGHT_MODEL_LOCAL_VIEWER` true the direction to the eye is `E = normalize(−v)`;
//!   for each light `L = normalize(l − v)` and `H = normalize(L + E)`; the colour is
//!   `c = a_global·a_m + Σ_l [a_l·a_m + max(n·L, 0)·d_l·d_m + (n·L > 0 ? max(n·H, 0)^s : 0)·s_l·s_m]`,
//!   clamped to [0, 1] per channel, with `0^0 = 1` (OpenGL's value for a shininess of 0)
//!   — no attenuation, no spotlights, no emission, one-sided. A mesh without normals
//!   gets each triangle's geometric normal `(p_1 − p_0) × (p_2 − p_0)` in object space (the
//!   format's rule for OBJ faces without normals), so its corners are lit per triangle.
//!
//! # Fragments
//!
//! Culling follows `scene.pipeline.cull` (counter-clockwise in the window is front), the
//! depth test `scene.pipeline.depth_test` (`Less`, `Lequal`, `Always`; a passing fragment
//! writes its depth) against an f64 buffer cleared to 1.0, and the colour buffer clears
//! to the quantised background.
//!
//! A fragment's colour starts as its interpolated vertex colour with alpha 1. A textured
//! material then applies its textures, texture units in order (see below), and the result
//! goes through blending. The colour buffer is RGB8, as the framebuffers compared with:
//! every write is `quantise` (round half up of `clamp(c, 0, 1)·255`), and blending reads
//! the destination back as `byte / 255`.
//!
//! # Textures (OpenGL 1.2)
//!
//! **Coordinates**: `(s, t) = Σ λ_k (s_k, t_k)`, the mesh's one set of texcoords
//! interpolated perspective-correctly with the barycentrics of the colour
//! ([`reference::Sample`]). A textured material on a mesh without texcoords is an error.
//! Their exact screen-space derivatives follow from the edge functions: with
//! `E_k = A_k·X + B_k·Y + C_k` and `λ_k = E_k / ΣE`,
//! `∂s/∂X = (Σ s_k A_k − s·Σ A_k) / ΣE` and `∂s/∂Y = (Σ s_k B_k − s·Σ B_k) / ΣE`, the same
//! for `t` ([`texcoord_derivatives`]).
//!
//! **Texels**: level 0 is the texture, `W × H`; texel `(i, j)` of a level is
//! `texels[j·W + i]`, row 0 at the bottom (t = 0), RGBA8 with red in the low byte, each
//! channel `byte / 255`. Wrap `repeat` takes `i mod W` (the non-negative remainder), `clamp`
//! (`GL_CLAMP_TO_EDGE`) `clamp(i, 0, W − 1)`; the same for `j` with `H`. With `u = s·W`
//! and `v = t·H` ([`sample`]):
//!
//! * `nearest`: texel `(⌊u⌋, ⌊v⌋)` of level 0 ([`nearest`]);
//! * `linear` (bilinear, [`bilinear`]): `i0 = ⌊u − ½⌋`, `α = (u − ½) − i0`, likewise `j0`
//!   and `β`; `(1−α)(1−β)·T(i0, j0) + α(1−β)·T(i0+1, j0) + (1−α)β·T(i0, j0+1) +
//!   αβ·T(i0+1, j0+1)`, each index wrapped;
//! * `trilinear` (`GL_LINEAR_MIPMAP_LINEAR` over [`mipmap::pyramid`]'s levels): the scale
//!   factor `ρ = max(√(u_x² + v_x²), √(u_y² + v_y²))` with `u_x = W·∂s/∂X` etc. at the
//!   pixel centre, and `λ = log2 ρ`. When `λ ≤ 0` (magnification) the result is bilinear
//!   on level 0. Otherwise, with `q` the last level's index, `d = min(λ, q)`,
//!   `d1 = ⌊d⌋`, `d2 = min(d1 + 1, q)`, `f = d − d1`:
//!   `(1 − f)·bilinear(level d1) + f·bilinear(level d2)`, level `k` sampled at
//!   `(s·W_k, t·H_k)`.
//!
//! **Environment**: each texture of the material, in unit order, turns the fragment's
//! `rgba` into `rgba ⊙ texel` (`modulate`, alpha too) or `texel` (`replace`).
//!
//! # Blending
//!
//! A fragment that passes the depth test (and writes its depth) is blended with the colour
//! buffer as it stands, in drawing order, per RGB channel, its `rgba` clamped to [0, 1]:
//! `none` writes `src`; `alpha` (`GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA`) writes
//! `src·a + dst·(1 − a)`; `add` (`GL_ONE, GL_ONE`) writes `min(1, src + dst)`. Alpha is
//! never stored: the framebuffer is RGB.

use crate::bump_env::BumpEnvShading;
use crate::image::{Image, quantise};
use crate::marble::MarbleShading;
use crate::reference::{self, Fragment, Sample, TieRule, V3, cross, dot, normalize, widen};
use imagine_pipelines::scene::SceneError;
use imagine_pipelines::scene::mipmap::{self, Level};
use imagine_pipelines::scene::model::{
    self, Blend, Filter, Material, Object, Shader, Texture, TextureMode, TriangleId, Wrap,
};

/// A row-major 4 × 4 matrix in f64.
pub type Matrix = [f64; 16];

/// An f32 row-major matrix widened exactly.
pub fn widen_matrix(m: &[f32; 16]) -> Matrix {
    m.map(f64::from)
}

/// `a · b`, row-major, in f64.
pub fn mat_mul(a: &Matrix, b: &Matrix) -> Matrix {
    std::array::from_fn(|k| {
        let (i, j) = (k / 4, k % 4);
        (0..4).map(|t| a[i * 4 + t] * b[t * 4 + j]).sum()
    })
}

/// `m · v` for a homogeneous `v`.
pub fn transform(m: &Matrix, v: [f64; 4]) -> [f64; 4] {
    std::array::from_fn(|i| (0..4).map(|j| m[i * 4 + j] * v[j]).sum())
}

/// `m · (p, 1)` without the w row: the 3-D image of a point under an affine matrix.
fn transform_point(m: &Matrix, p: V3) -> V3 {
    let v = transform(m, [p[0], p[1], p[2], 1.0]);
    [v[0], v[1], v[2]]
}

/// The normal matrix of a model-view: the inverse transpose of its upper-left 3 × 3
/// (row-major). A singular matrix gives non-finite entries.
pub fn normal_matrix(modelview: &Matrix) -> [[f64; 3]; 3] {
    let a = |i: usize, j: usize| modelview[i * 4 + j];
    // The cofactor matrix divided by the determinant is the inverse transpose.
    let cof = |i: usize, j: usize| {
        let (r0, r1) = ((i + 1) % 3, (i + 2) % 3);
        let (c0, c1) = ((j + 1) % 3, (j + 2) % 3);
        a(r0, c0) * a(r1, c1) - a(r0, c1) * a(r1, c0)
    };
    let det = a(0, 0) * cof(0, 0) + a(0, 1) * cof(0, 1) + a(0, 2) * cof(0, 2);
    std::array::from_fn(|i| std::array::from_fn(|j| cof(i, j) / det))
}

fn apply3(m: &[[f64; 3]; 3], v: V3) -> V3 {
    std::array::from_fn(|i| dot(m[i], v))
}

/// `v / |v|`, or `v` itself when it has no length (GL leaves such a normal unlit).
fn normalize_or_zero(v: V3) -> V3 {
    if dot(v, v) > 0.0 { normalize(v) } else { v }
}

/// The scene's lights in eye space: `camera.view · (position, 1)`.
pub fn eye_lights(scene: &model::Scene) -> Vec<V3> {
    let view = widen_matrix(&scene.camera.view);
    scene
        .lights
        .iter()
        .map(|l| transform_point(&view, widen(l.position)))
        .collect()
}

/// The fixed-function colour (see the module comment) of a vertex at eye position
/// `vertex` with eye-space normal `normal` (renormalised here), for `material` under the
/// scene's global ambient and lights, whose eye positions are `lights` ([`eye_lights`]).
pub fn lit_colour(
    scene: &model::Scene,
    material: &Material,
    lights: &[V3],
    vertex: V3,
    normal: V3,
) -> [f64; 3] {
    let n = normalize_or_zero(normal);
    let e = normalize_or_zero(vertex.map(|c| -c));
    let (a_m, d_m, s_m) = (
        widen(material.ambient),
        widen(material.diffuse),
        widen(material.specular),
    );
    let shininess = f64::from(material.shininess);
    let global = widen(scene.ambient);
    let mut c: V3 = std::array::from_fn(|k| global[k] * a_m[k]);
    for (light, &position) in scene.lights.iter().zip(lights) {
        let l = normalize_or_zero(std::array::from_fn(|k| position[k] - vertex[k]));
        let h = normalize_or_zero(std::array::from_fn(|k| l[k] + e[k]));
        let n_dot_l = dot(n, l);
        let diffuse = n_dot_l.max(0.0);
        // f64::powf has 0^0 = 1, as OpenGL has it for a shininess of 0.
        let specular = if n_dot_l > 0.0 {
            dot(n, h).max(0.0).powf(shininess)
        } else {
            0.0
        };
        let (a_l, d_l, s_l) = (
            widen(light.ambient),
            widen(light.diffuse),
            widen(light.specular),
        );
        for k in 0..3 {
            c[k] += a_l[k] * a_m[k] + diffuse * d_l[k] * d_m[k] + specular * s_l[k] * s_m[k];
        }
    }
    c.map(|x| x.clamp(0.0, 1.0))
}

fn error(scene: &model::Scene, message: String) -> SceneError {
    SceneError {
        scene: scene.name.clone(),
        line: None,
        message,
    }
}

/// Checks that the reference can draw `scene`: a window of 1..=4096 pixels a side, at
/// most 8 lights, valid material and vertex indices, per-vertex arrays of the right
/// length, texture indices in range and texcoords on every textured object.
pub fn check(scene: &model::Scene) -> Result<(), SceneError> {
    let max = imagine_pipelines::scene::MAX_WINDOW;
    if !(1..=max).contains(&scene.width) || !(1..=max).contains(&scene.height) {
        return Err(error(
            scene,
            format!(
                "window {}x{}: each side must be 1..={max}",
                scene.width, scene.height
            ),
        ));
    }
    if scene.lights.len() > model::MAX_LIGHTS {
        return Err(error(
            scene,
            format!(
                "{} lights: at most {} are supported",
                scene.lights.len(),
                model::MAX_LIGHTS
            ),
        ));
    }
    if let Some(m) = scene
        .materials
        .iter()
        .find(|m| m.textures.iter().any(|&t| t >= scene.textures.len()))
    {
        return Err(error(
            scene,
            format!(
                "material `{}` names texture {:?} but the scene has {} textures",
                m.name,
                m.textures,
                scene.textures.len()
            ),
        ));
    }
    for object in &scene.objects {
        let bad = |m: String| Err(error(scene, format!("object `{}`: {m}", object.name)));
        if object.material >= scene.materials.len() {
            return bad(format!(
                "material index {} but the scene has {} materials",
                object.material,
                scene.materials.len()
            ));
        }
        let mesh = &object.mesh;
        let n = mesh.positions.len();
        for (what, len) in [
            ("normals", mesh.normals.len()),
            ("colours", mesh.colours.len()),
            ("texcoords", mesh.texcoords.len()),
        ] {
            if len != 0 && len != n {
                return bad(format!("{len} {what} for {n} positions"));
            }
        }
        let textured = scene
            .materials
            .get(object.material)
            .is_some_and(|m| !m.textures.is_empty());
        if textured && mesh.texcoords.is_empty() {
            return bad(format!(
                "material `{}` has textures but the mesh has no texture coordinates",
                scene.materials[object.material].name
            ));
        }
        let marble = matches!(scene.materials[object.material].shader, Shader::Marble(_));
        if marble && mesh.normals.len() != n {
            return bad(format!(
                "marble needs normals: {} for {n} positions",
                mesh.normals.len()
            ));
        }
        if let Shader::BumpEnv(_) = scene.materials[object.material].shader {
            let m = &scene.materials[object.material];
            if mesh.normals.len() != n || mesh.tangents.len() != n {
                return bad(format!(
                    "bump_env needs normals and tangents: {} and {} for {n} positions",
                    mesh.normals.len(),
                    mesh.tangents.len()
                ));
            }
            if m.textures.len() != 1 {
                return bad(format!(
                    "bump_env material `{}` needs exactly one texture (its environment map)",
                    m.name
                ));
            }
        }
        if let Some(t) = mesh
            .triangles
            .iter()
            .find(|t| t.iter().any(|&i| i as usize >= n))
        {
            return bad(format!(
                "triangle {t:?} names a vertex beyond the {n} positions"
            ));
        }
    }
    Ok(())
}

/// The model-view an object is drawn with: its camera's view times its model matrix.
pub fn modelview(scene: &model::Scene, object: &Object) -> Matrix {
    let camera = scene.camera_for(object);
    mat_mul(&widen_matrix(&camera.view), &widen_matrix(&object.model))
}

/// Clip-space positions of an object's vertices: model, then view, then projection, in
/// f64.
pub fn clip_positions(scene: &model::Scene, object: &Object) -> Vec<[f64; 4]> {
    let camera = scene.camera_for(object);
    let (model, view, projection) = (
        widen_matrix(&object.model),
        widen_matrix(&camera.view),
        widen_matrix(&camera.projection),
    );
    object
        .mesh
        .positions
        .iter()
        .map(|&p| {
            let p = widen(p);
            let world = transform(&model, [p[0], p[1], p[2], 1.0]);
            transform(&projection, transform(&view, world))
        })
        .collect()
}

/// The object-space normal of each corner of triangle `t`: the mesh's normals, or the
/// triangle's geometric normal when the mesh has none.
pub fn corner_normals(mesh: &model::Mesh, t: [u32; 3]) -> [V3; 3] {
    if mesh.normals.is_empty() {
        let [p0, p1, p2] = t.map(|i| widen(mesh.positions[i as usize]));
        let g = cross(
            std::array::from_fn(|k| p1[k] - p0[k]),
            std::array::from_fn(|k| p2[k] - p0[k]),
        );
        [g; 3]
    } else {
        t.map(|i| widen(mesh.normals[i as usize]))
    }
}

/// The colours of the three corners of every triangle of `scene.objects[index]`, in
/// triangle order (see the module comment). Corners sharing a vertex share its colour,
/// except for lit meshes without normals (lit per triangle).
pub fn corner_colours(
    scene: &model::Scene,
    index: usize,
) -> Result<Vec<[[f64; 3]; 3]>, SceneError> {
    check(scene)?;
    let object = scene
        .objects
        .get(index)
        .ok_or_else(|| error(scene, format!("no object {index}")))?;
    Ok(object_corner_colours(scene, object, &eye_lights(scene)))
}

fn object_corner_colours(
    scene: &model::Scene,
    object: &Object,
    lights: &[V3],
) -> Vec<[[f64; 3]; 3]> {
    let mesh = &object.mesh;
    let material = &scene.materials[object.material];
    match material.shader {
        Shader::Unlit => {
            let colour = |i: u32| widen(*mesh.colours.get(i as usize).unwrap_or(&object.colour));
            mesh.triangles.iter().map(|t| t.map(colour)).collect()
        }
        Shader::Marble(_) => vec![[[1.0; 3]; 3]; mesh.triangles.len()],
        Shader::BumpEnv(_) => vec![[widen(object.colour); 3]; mesh.triangles.len()],
        Shader::Lit => {
            let mv = modelview(scene, object);
            let nm = normal_matrix(&mv);
            let eye: Vec<V3> = mesh
                .positions
                .iter()
                .map(|&p| transform_point(&mv, widen(p)))
                .collect();
            let shade = |i: u32, n: V3| {
                lit_colour(scene, material, lights, eye[i as usize], apply3(&nm, n))
            };
            if mesh.normals.is_empty() {
                mesh.triangles
                    .iter()
                    .map(|&t| {
                        let n = corner_normals(mesh, t);
                        [shade(t[0], n[0]), shade(t[1], n[1]), shade(t[2], n[2])]
                    })
                    .collect()
            } else {
                // Shared vertices: light each once.
                let colours: Vec<[f64; 3]> = (0..mesh.positions.len() as u32)
                    .map(|i| shade(i, widen(mesh.normals[i as usize])))
                    .collect();
                mesh.triangles
                    .iter()
                    .map(|t| t.map(|i| colours[i as usize]))
                    .collect()
            }
        }
    }
}

/// The colour of every vertex of `scene.objects[index]`, one per position (for unlit
/// meshes and lit meshes with normals; a lit mesh without normals has no per-vertex
/// colour: use [`corner_colours`]).
pub fn vertex_colours(scene: &model::Scene, index: usize) -> Result<Vec<[f64; 3]>, SceneError> {
    check(scene)?;
    let object = scene
        .objects
        .get(index)
        .ok_or_else(|| error(scene, format!("no object {index}")))?;
    let mesh = &object.mesh;
    let material = &scene.materials[object.material];
    match material.shader {
        Shader::Unlit => Ok((0..mesh.positions.len())
            .map(|i| widen(*mesh.colours.get(i).unwrap_or(&object.colour)))
            .collect()),
        Shader::Marble(_) => Ok(vec![[1.0; 3]; mesh.positions.len()]),
        Shader::BumpEnv(_) => Ok(vec![widen(object.colour); mesh.positions.len()]),
        Shader::Lit if mesh.normals.is_empty() => Err(error(
            scene,
            format!(
                "object `{}` is lit without normals: its colours are per triangle",
                object.name
            ),
        )),
        Shader::Lit => {
            let lights = eye_lights(scene);
            let mv = modelview(scene, object);
            let nm = normal_matrix(&mv);
            Ok(mesh
                .positions
                .iter()
                .zip(&mesh.normals)
                .map(|(&p, &n)| {
                    lit_colour(
                        scene,
                        material,
                        &lights,
                        transform_point(&mv, widen(p)),
                        apply3(&nm, widen(n)),
                    )
                })
                .collect())
        }
    }
}

/// A texture ready to sample: its filter and wrap, and its levels (level 0 alone unless
/// trilinear, then [`mipmap::pyramid`]'s).
#[derive(Clone, Debug, PartialEq)]
pub struct Sampler {
    pub filter: Filter,
    pub wrap: Wrap,
    pub levels: Vec<Level>,
}

impl Sampler {
    pub fn new(texture: &Texture) -> Sampler {
        let levels = match texture.filter {
            Filter::Trilinear => mipmap::pyramid(texture),
            Filter::Nearest | Filter::Linear => vec![Level {
                width: texture.width,
                height: texture.height,
                texels: texture.texels.clone(),
            }],
        };
        Sampler {
            filter: texture.filter,
            wrap: texture.wrap,
            levels,
        }
    }
}

fn wrap_index(wrap: Wrap, i: i64, size: u32) -> i64 {
    let size = i64::from(size);
    match wrap {
        Wrap::Repeat => i.rem_euclid(size),
        Wrap::Clamp => i.clamp(0, size - 1),
    }
}

/// Texel `(i, j)` of `level`, each index wrapped, as RGBA in [0, 1].
pub fn texel(level: &Level, wrap: Wrap, i: i64, j: i64) -> [f64; 4] {
    let (i, j) = (
        wrap_index(wrap, i, level.width),
        wrap_index(wrap, j, level.height),
    );
    let word = level.texels[(j * i64::from(level.width) + i) as usize];
    word.to_le_bytes().map(|b| f64::from(b) / 255.0)
}

/// `floor` to an index, saturating (texture coordinates far outside [0, 1] stay finite
/// indices; repeat then wraps them).
fn index(x: f64) -> i64 {
    x.floor() as i64
}

/// The texel of `level` that contains `(u, v)` (in texels).
pub fn nearest(level: &Level, wrap: Wrap, u: f64, v: f64) -> [f64; 4] {
    texel(level, wrap, index(u), index(v))
}

/// The bilinear blend of the 2 × 2 texels of `level` around `(u, v)` (in texels).
pub fn bilinear(level: &Level, wrap: Wrap, u: f64, v: f64) -> [f64; 4] {
    let (i0, j0) = (index(u - 0.5), index(v - 0.5));
    let (a, b) = ((u - 0.5) - i0 as f64, (v - 0.5) - j0 as f64);
    let t = |di: i64, dj: i64| texel(level, wrap, i0.saturating_add(di), j0.saturating_add(dj));
    let (t00, t10, t01, t11) = (t(0, 0), t(1, 0), t(0, 1), t(1, 1));
    std::array::from_fn(|k| {
        (1.0 - a) * (1.0 - b) * t00[k]
            + a * (1.0 - b) * t10[k]
            + (1.0 - a) * b * t01[k]
            + a * b * t11[k]
    })
}

/// The level of detail `λ = log2 ρ` at texture coordinates whose screen-space derivatives
/// are `ds = (∂s/∂X, ∂s/∂Y)` and `dt`, for a `width × height` level 0.
pub fn level_of_detail(width: u32, height: u32, ds: [f64; 2], dt: [f64; 2]) -> f64 {
    let (w, h) = (f64::from(width), f64::from(height));
    let x = (w * ds[0]).hypot(h * dt[0]);
    let y = (w * ds[1]).hypot(h * dt[1]);
    x.max(y).log2()
}

/// The filtered texel at `(s, t)` (see the module comment); `ds` and `dt` are the
/// screen-space derivatives (used by trilinear filtering only).
pub fn sample(sampler: &Sampler, s: f64, t: f64, ds: [f64; 2], dt: [f64; 2]) -> [f64; 4] {
    let at = |k: usize| {
        let level = &sampler.levels[k];
        (
            level,
            s * f64::from(level.width),
            t * f64::from(level.height),
        )
    };
    let wrap = sampler.wrap;
    match sampler.filter {
        Filter::Nearest => {
            let (level, u, v) = at(0);
            nearest(level, wrap, u, v)
        }
        Filter::Linear => {
            let (level, u, v) = at(0);
            bilinear(level, wrap, u, v)
        }
        Filter::Trilinear => {
            let base = &sampler.levels[0];
            let lambda = level_of_detail(base.width, base.height, ds, dt);
            if lambda.is_nan() || lambda <= 0.0 {
                let (level, u, v) = at(0);
                return bilinear(level, wrap, u, v);
            }
            let q = sampler.levels.len() - 1;
            let d = lambda.min(q as f64);
            let d1 = d.floor() as usize;
            let d2 = (d1 + 1).min(q);
            let f = d - d1 as f64;
            let (l1, u1, v1) = at(d1);
            let (l2, u2, v2) = at(d2);
            let (c1, c2) = (bilinear(l1, wrap, u1, v1), bilinear(l2, wrap, u2, v2));
            std::array::from_fn(|k| (1.0 - f) * c1[k] + f * c2[k])
        }
    }
}

/// The interpolated value of a per-corner attribute `a` at a sample and its exact
/// screen-space derivatives `(∂a/∂X, ∂a/∂Y)` (see the module comment).
pub fn texcoord_derivatives(sample: &Sample, a: [f64; 3]) -> (f64, [f64; 2]) {
    let l = sample.barycentrics;
    let value = l[0] * a[0] + l[1] * a[1] + l[2] * a[2];
    let d = |axis: usize| {
        let weighted: f64 = (0..3).map(|k| a[k] * sample.edges[k][axis]).sum();
        let total: f64 = (0..3).map(|k| sample.edges[k][axis]).sum();
        (weighted - value * total) / sample.sum
    };
    (value, [d(0), d(1)])
}

/// The texture environment (see the module comment): `colour` (alpha 1) through each of
/// `samplers` in order, sampled at the sample's texcoords `(s_k, t_k)` per corner.
fn textured_colour(
    colour: [f64; 3],
    samplers: &[&Sampler],
    mode: TextureMode,
    sample: &Sample,
    texcoords: &[[f64; 2]; 3],
) -> [f64; 4] {
    let mut rgba = [colour[0], colour[1], colour[2], 1.0];
    if samplers.is_empty() {
        return rgba;
    }
    let (s, ds) = texcoord_derivatives(sample, texcoords.map(|c| c[0]));
    let (t, dt) = texcoord_derivatives(sample, texcoords.map(|c| c[1]));
    for sampler in samplers {
        let texel = self::sample(sampler, s, t, ds, dt);
        rgba = match mode {
            TextureMode::Modulate => std::array::from_fn(|k| rgba[k] * texel[k]),
            TextureMode::Replace => texel,
        };
    }
    rgba
}

/// One fragment of a scene file's object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjectFragment {
    /// Index of the object in the scene.
    pub object: usize,
    /// The fragment; its `triangle` is the index within the object's mesh, its `colour`
    /// the RGB after the texture environment.
    pub fragment: Fragment,
    /// Its alpha after the texture environment (1 without textures).
    pub alpha: f64,
}

/// Every fragment of the scene in drawing order (object by object, triangle by triangle,
/// bottom row up, left to right), culled, clipped and textured but without the depth
/// test.
pub fn for_each_fragment(
    scene: &model::Scene,
    rule: TieRule,
    mut f: impl FnMut(&ObjectFragment),
) -> Result<(), SceneError> {
    check(scene)?;
    let lights = eye_lights(scene);
    let mut samplers: Vec<Option<Sampler>> = vec![None; scene.textures.len()];
    for m in &scene.materials {
        for &t in &m.textures {
            samplers[t].get_or_insert_with(|| Sampler::new(&scene.textures[t]));
        }
    }
    for (index, object) in scene.objects.iter().enumerate() {
        // Bump_env displaces its vertices and shades from eye-space frames.
        let bump_env = BumpEnvShading::of(scene, object);
        let clip = match &bump_env {
            Some(b) => b.clip.clone(),
            None => clip_positions(scene, object),
        };
        let colours = object_corner_colours(scene, object, &lights);
        let material = &scene.materials[object.material];
        let units: Vec<&Sampler> = material
            .textures
            .iter()
            .filter_map(|&t| samplers[t].as_ref())
            .collect();
        let mesh = &object.mesh;
        // Marble shades from the perspective-correct barycentrics.
        let marble = MarbleShading::of(scene, object);
        for (triangle, (t, col)) in mesh.triangles.iter().zip(&colours).enumerate() {
            let c = t.map(|i| clip[i as usize]);
            let texcoords = if units.is_empty() {
                [[0.0; 2]; 3]
            } else {
                t.map(|i| mesh.texcoords[i as usize].map(f64::from))
            };
            reference::rasterize_samples(
                &c,
                (scene.width, scene.height),
                scene.pipeline.cull,
                rule,
                |sample| {
                    let l = sample.barycentrics;
                    let [r, g, b, a] = match (&marble, &bump_env) {
                        (_, Some(shading)) => shading.colour(*t, l),
                        (Some(m), None) => {
                            let at = |v: &[[f32; 3]]| -> V3 {
                                std::array::from_fn(|k| {
                                    (0..3)
                                        .map(|corner| {
                                            l[corner] * f64::from(v[t[corner] as usize][k])
                                        })
                                        .sum()
                                })
                            };
                            let [r, g, b] = m.colour(at(&mesh.positions), at(&mesh.normals));
                            [r, g, b, 1.0]
                        }
                        (None, None) => {
                            let colour = std::array::from_fn(|k| {
                                l[0] * col[0][k] + l[1] * col[1][k] + l[2] * col[2][k]
                            });
                            let mode = material.texture_mode;
                            textured_colour(colour, &units, mode, sample, &texcoords)
                        }
                    };
                    f(&ObjectFragment {
                        object: index,
                        fragment: Fragment {
                            triangle,
                            x: sample.x,
                            y: sample.y,
                            depth: sample.depth,
                            colour: [r, g, b],
                        },
                        alpha: a,
                    })
                },
            );
        }
    }
    Ok(())
}

/// The colour written for a fragment `src` with alpha `alpha` over the stored `dst`
/// under `blend` (see the module comment).
pub fn blend(blend: Blend, src: [f64; 3], alpha: f64, dst: [u8; 4]) -> [u8; 4] {
    let src = src.map(|c| c.clamp(0.0, 1.0));
    let a = alpha.clamp(0.0, 1.0);
    let dst = [dst[0], dst[1], dst[2]].map(|b| f64::from(b) / 255.0);
    let out: [f64; 3] = match blend {
        Blend::None => src,
        Blend::Alpha => std::array::from_fn(|k| src[k] * a + dst[k] * (1.0 - a)),
        Blend::Add => std::array::from_fn(|k| (src[k] + dst[k]).min(1.0)),
    };
    let [r, g, b] = out.map(quantise);
    [r, g, b, 255]
}

/// Renders a scene file's scene (see the module comment) with the default tie rule.
pub fn render(scene: &model::Scene) -> Result<Image, SceneError> {
    render_with(scene, TieRule::TopLeft)
}

/// [`render`] with a choice of tie rule.
pub fn render_with(scene: &model::Scene, rule: TieRule) -> Result<Image, SceneError> {
    render_triangles(scene, rule).map(|(image, _)| image)
}

/// [`render`], and for every pixel (row 0 at the bottom) the triangle it shows: the last
/// whose fragment passed the depth test there, `None` where none did.
pub fn render_visible(
    scene: &model::Scene,
) -> Result<(Image, Vec<Option<TriangleId>>), SceneError> {
    render_triangles(scene, TieRule::TopLeft)
}

fn render_triangles(
    scene: &model::Scene,
    rule: TieRule,
) -> Result<(Image, Vec<Option<TriangleId>>), SceneError> {
    check(scene)?;
    let [r, g, b] = scene.background.map(|c| quantise(f64::from(c)));
    let mut image = Image::new(scene.width, scene.height);
    image.pixels.fill([r, g, b, 255]);
    let mut depth = vec![1.0f64; image.pixels.len()];
    let mut visible = vec![None; image.pixels.len()];
    let width = scene.width as usize;
    let test = scene.pipeline.depth_test;
    let mode = scene.pipeline.blend;
    for_each_fragment(scene, rule, |of| {
        let f = &of.fragment;
        let i = f.y as usize * width + f.x as usize;
        if reference::depth_passes(test, f.depth, depth[i]) {
            depth[i] = f.depth;
            image.pixels[i] = blend(mode, f.colour, of.alpha, image.pixels[i]);
            visible[i] = Some(TriangleId {
                object: of.object,
                triangle: f.triangle,
            });
        }
    })?;
    Ok((image, visible))
}

#[cfg(test)]
mod tests {
    use super::*;
    use imagine_pipelines::scene::model::{
        Camera, Cull, DepthTest, Light, Mesh, PipelineKind, PipelineSettings, Space,
    };
    use imagine_pipelines::scene::{IDENTITY, parse_tri};

    fn translate(x: f32, y: f32, z: f32) -> [f32; 16] {
        let mut m = IDENTITY;
        (m[3], m[7], m[11]) = (x, y, z);
        m
    }

    fn scale(x: f32, y: f32, z: f32) -> [f32; 16] {
        let mut m = IDENTITY;
        (m[0], m[5], m[10]) = (x, y, z);
        m
    }

    fn material(shader: Shader) -> Material {
        Material {
            name: format!("{shader:?}"),
            shader,
            ambient: [0.2; 3],
            diffuse: [0.8; 3],
            specular: [0.0; 3],
            shininess: 0.0,
            textures: Vec::new(),
            texture_mode: TextureMode::Modulate,
        }
    }

    /// A scene with an unlit material (0) and a lit one (1), no objects, no lights.
    fn empty_scene(width: u32, height: u32) -> model::Scene {
        model::Scene {
            name: "test".into(),
            source: None,
            width,
            height,
            background: [0.0; 3],
            ambient: [0.0; 3],
            camera: Camera {
                view: IDENTITY,
                projection: IDENTITY,
            },
            pipeline: PipelineSettings {
                kind: PipelineKind::OpenGl,
                depth_test: DepthTest::Less,
                cull: Cull::Back,
                blend: Blend::None,
                stop_length: 1.5,
                batch: None,
                normalise_clip: false,
                reference_depth: false,
                newton_raphson: 0,
            },
            lights: Vec::new(),
            textures: Vec::new(),
            materials: vec![material(Shader::Unlit), material(Shader::Lit)],
            objects: Vec::new(),
        }
    }

    /// A window-space unlit object of separate triangles, `(x, y, z)` in pixels.
    fn window_object(triangles: &[[[f32; 3]; 3]], colour: [f32; 3]) -> Object {
        Object {
            name: "window".into(),
            material: 0,
            model: IDENTITY,
            colour,
            space: Space::Window,
            patches: Vec::new(),
            mesh: Mesh {
                positions: triangles.iter().flatten().copied().collect(),
                triangles: (0..triangles.len() as u32)
                    .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
                    .collect(),
                separate: true,
                ..Mesh::default()
            },
        }
    }

    const RED: [f32; 3] = [1.0, 0.0, 0.0];
    const GREEN: [f32; 3] = [0.0, 1.0, 0.0];

    fn count(image: &Image, rgba: [u8; 4]) -> usize {
        image.pixels.iter().filter(|&&p| p == rgba).count()
    }

    /// The scene of `lit_colour_matches_a_hand_computation`: a camera 5 units up +z
    /// looking down −z, one light at world (3, 0, 4).
    fn one_light_scene() -> model::Scene {
        let mut scene = empty_scene(8, 8);
        scene.ambient = [0.5, 0.5, 0.5];
        scene.camera.view = translate(0.0, 0.0, -5.0);
        scene.lights.push(Light {
            position: [3.0, 0.0, 4.0],
            ambient: [0.1, 0.2, 0.0],
            diffuse: [1.0, 1.0, 0.5],
            specular: [1.0, 0.5, 1.0],
        });
        scene.materials[1] = Material {
            ambient: [0.2, 0.4, 0.1],
            diffuse: [0.5, 0.25, 1.0],
            specular: [0.25, 0.5, 0.0],
            shininess: 2.0,
            ..material(Shader::Lit)
        };
        scene
    }

    // The materials' and lights' f32 values (0.1, 0.2, …) are not exact: compare within
    // 1e-7.
    #[test]
    fn lit_colour_matches_a_hand_computation() {
        // The vertex at the world origin is at eye (0, 0, −5), normal +z: E = +z. The
        // light is at eye (3, 0, −1): L = (3, 0, 4)/5, n·L = 0.8; H ∝ (0.6, 0, 1.8),
        // n·H = 3/√10, (n·H)² = 0.9. So
        //   r = 0.5·0.2 + 0.1·0.2 + 0.8·1·0.5  + 0.9·1·0.25   = 0.745
        //   g = 0.5·0.4 + 0.2·0.4 + 0.8·1·0.25 + 0.9·0.5·0.5  = 0.705
        //   b = 0.5·0.1 + 0·0.1   + 0.8·0.5·1  + 0.9·1·0      = 0.45
        let mut scene = one_light_scene();
        let lights = eye_lights(&scene);
        assert_eq!(lights, vec![[3.0, 0.0, -1.0]]);
        let want = [0.745, 0.705, 0.45];
        let c = lit_colour(
            &scene,
            &scene.materials[1],
            &lights,
            [0.0, 0.0, -5.0],
            [0.0, 0.0, 2.0],
        );
        for k in 0..3 {
            assert!((c[k] - want[k]).abs() < 1e-7, "{c:?} vs {want:?}");
        }
        // Through an object: a non-uniform scale along z turns the normal (0, 0, 7) into
        // (0, 0, 7/3) in eye space, renormalised to +z; a second vertex faces away from
        // the light (n·L < 0): ambient only, no specular.
        scene.objects.push(Object {
            name: "lit".into(),
            material: 1,
            model: scale(1.0, 1.0, 3.0),
            colour: [1.0; 3],
            space: Space::World,
            patches: Vec::new(),
            mesh: Mesh {
                positions: vec![[0.0; 3], [0.0; 3], [1.0, 0.0, 0.0]],
                normals: vec![[0.0, 0.0, 7.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
                triangles: vec![[0, 1, 2]],
                ..Mesh::default()
            },
        });
        let colours = vertex_colours(&scene, 0).unwrap();
        for k in 0..3 {
            assert!((colours[0][k] - want[k]).abs() < 1e-7, "{colours:?}");
        }
        let ambient_only = [0.5 * 0.2 + 0.1 * 0.2, 0.5 * 0.4 + 0.2 * 0.4, 0.5 * 0.1];
        for k in 0..3 {
            assert!(
                (colours[1][k] - ambient_only[k]).abs() < 1e-7,
                "{colours:?}"
            );
        }
        assert_eq!(
            corner_colours(&scene, 0).unwrap(),
            vec![[colours[0], colours[1], colours[2]]]
        );
        // Clamped to [0, 1].
        scene.ambient = [10.0; 3];
        assert_eq!(vertex_colours(&scene, 0).unwrap()[0], [1.0; 3]);
    }

    #[test]
    fn normal_matrix_is_the_inverse_transpose() {
        // A shear plus translation: M = [[1, 2, 0], [0, 1, 0], [0, 0, 4]].
        let mut m = IDENTITY.map(f64::from);
        (m[1], m[10], m[3]) = (2.0, 4.0, 7.0);
        let n = normal_matrix(&m);
        // (M⁻¹)ᵀ = [[1, 0, 0], [−2, 1, 0], [0, 0, 1/4]].
        assert_eq!(n, [[1.0, 0.0, 0.0], [-2.0, 1.0, 0.0], [0.0, 0.0, 0.25]]);
        // A normal stays perpendicular to a transformed tangent.
        let (t, normal) = ([1.0, 1.0, 0.0], [1.0, -1.0, 0.0]);
        let t2 = [m[0] * t[0] + m[1] * t[1], m[5] * t[1], 0.0];
        assert_eq!(dot(t2, apply3(&n, normal)), 0.0);
    }

    #[test]
    fn a_lit_mesh_without_normals_uses_geometric_normals() {
        let mut scene = one_light_scene();
        // A triangle in the z = 0 plane, counter-clockwise seen from +z: normal +z, the
        // vertex at the origin lit as in the hand computation.
        scene.objects.push(Object {
            name: "flat".into(),
            material: 1,
            model: IDENTITY,
            colour: [1.0; 3],
            space: Space::World,
            patches: Vec::new(),
            mesh: Mesh {
                positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
                triangles: vec![[0, 1, 2]],
                ..Mesh::default()
            },
        });
        let corners = corner_colours(&scene, 0).unwrap();
        let want = [0.745, 0.705, 0.45];
        for k in 0..3 {
            assert!((corners[0][0][k] - want[k]).abs() < 1e-7, "{corners:?}");
        }
        assert!(vertex_colours(&scene, 0).is_err());
    }

    #[test]
    fn unlit_colours_background_and_the_old_reference_agree() {
        let mut scene = empty_scene(16, 16);
        scene.background = [0.0, 0.0, 0.5];
        // Per-vertex colours win over the object's colour.
        let mut object = window_object(
            &[[[1.0, 1.0, 0.5], [15.0, 1.0, 0.5], [1.0, 15.0, 0.5]]],
            GREEN,
        );
        object.mesh.colours = vec![RED, RED, RED];
        scene.objects.push(object);
        scene.objects.push(window_object(
            &[[[15.0, 15.0, 0.25], [5.0, 15.0, 0.25], [15.0, 5.0, 0.25]]],
            GREEN,
        ));
        let image = render(&scene).unwrap();
        let (red, green, blue) = (
            count(&image, [255, 0, 0, 255]),
            count(&image, [0, 255, 0, 255]),
            count(&image, [0, 0, 128, 255]),
        );
        assert!(red > 50 && green > 20, "{red} {green}");
        assert_eq!(red + green + blue, 256);
        assert_eq!(image.pixel(15, 0), [0, 0, 128, 255]);

        // The same triangles as an old `.tri` scene render identically (black background).
        scene.background = [0.0; 3];
        scene.pipeline.cull = Cull::None;
        let tri = parse_tri(
            "t",
            "16 16\n\
             1 1 0.5 1 0 0  15 1 0.5 1 0 0  1 15 0.5 1 0 0\n\
             15 15 0.25 0 1 0  5 15 0.25 0 1 0  15 5 0.25 0 1 0\n",
        )
        .unwrap();
        assert_eq!(render(&scene).unwrap(), reference::render(&tri));
    }

    #[test]
    fn culling_follows_the_pipeline_setting() {
        let ccw = [[0.0, 0.0, 0.5], [8.0, 0.0, 0.5], [0.0, 8.0, 0.5]];
        let cw = [ccw[0], ccw[2], ccw[1]];
        let drawn = |triangle: [[f32; 3]; 3], cull: Cull| {
            let mut scene = empty_scene(8, 8);
            scene.pipeline.cull = cull;
            scene.objects.push(window_object(&[triangle], RED));
            count(&render(&scene).unwrap(), [255, 0, 0, 255])
        };
        // px + py + 1 < 8: 1 + 2 + … + 7.
        assert_eq!(drawn(ccw, Cull::Back), 28);
        assert_eq!(drawn(cw, Cull::Back), 0);
        assert_eq!(drawn(ccw, Cull::Front), 0);
        assert_eq!(drawn(cw, Cull::Front), 28);
        assert_eq!(drawn(ccw, Cull::None), 28);
        assert_eq!(drawn(cw, Cull::None), 28);
    }

    #[test]
    fn depth_test_follows_the_pipeline_setting() {
        let square = |z: f32| {
            [
                [[0.0, 0.0, z], [4.0, 0.0, z], [4.0, 4.0, z]],
                [[0.0, 0.0, z], [4.0, 4.0, z], [0.0, 4.0, z]],
            ]
        };
        let winner = |test: DepthTest, first: f32, second: f32| {
            let mut scene = empty_scene(4, 4);
            scene.pipeline.depth_test = test;
            scene.objects.push(window_object(&square(first), RED));
            scene.objects.push(window_object(&square(second), GREEN));
            let image = render(&scene).unwrap();
            let p = image.pixels[0];
            assert!(image.pixels.iter().all(|&q| q == p), "{test:?}");
            p
        };
        let (red, green) = ([255, 0, 0, 255], [0, 255, 0, 255]);
        assert_eq!(winner(DepthTest::Less, 0.5, 0.5), red);
        assert_eq!(winner(DepthTest::Lequal, 0.5, 0.5), green);
        assert_eq!(winner(DepthTest::Always, 0.5, 0.5), green);
        assert_eq!(winner(DepthTest::Less, 0.5, 0.25), green);
        assert_eq!(winner(DepthTest::Lequal, 0.5, 0.75), red);
        assert_eq!(winner(DepthTest::Always, 0.25, 0.75), green);
        // Depth 1.0 fails LESS against the cleared buffer but passes LEQUAL.
        assert_eq!(winner(DepthTest::Less, 1.0, 1.0), [0, 0, 0, 255]);
        assert_eq!(winner(DepthTest::Lequal, 1.0, 1.0), green);
    }

    #[test]
    fn bad_indices_and_textures_without_texcoords_are_errors() {
        let mut scene = empty_scene(4, 4);
        scene.objects.push(window_object(
            &[[[0.0, 0.0, 0.5], [4.0, 0.0, 0.5], [0.0, 4.0, 0.5]]],
            RED,
        ));
        assert!(render(&scene).is_ok());
        let mut textured = scene.clone();
        textured.materials[0].textures.push(0);
        let e = render(&textured).unwrap_err().to_string();
        assert!(e.contains("scene has 0 textures"), "{e}");
        textured.textures.push(texture(
            1,
            1,
            vec![0xFFFF_FFFF],
            Filter::Nearest,
            Wrap::Repeat,
        ));
        let e = render(&textured).unwrap_err().to_string();
        assert!(
            e.contains("object `window`") && e.contains("no texture coordinates"),
            "{e}"
        );
        let mut bad = scene.clone();
        bad.objects[0].mesh.triangles[0][2] = 3;
        let e = render(&bad).unwrap_err().to_string();
        assert!(e.contains("beyond"), "{e}");
        let mut bad = scene;
        bad.objects[0].material = 2;
        assert!(render(&bad).is_err());
    }

    fn texture(width: u32, height: u32, texels: Vec<u32>, filter: Filter, wrap: Wrap) -> Texture {
        Texture {
            name: "t".into(),
            width,
            height,
            texels,
            filter,
            wrap,
        }
    }

    fn rgba(r: u8, g: u8, b: u8, a: u8) -> u32 {
        u32::from_le_bytes([r, g, b, a])
    }

    /// A window-filling square of two triangles with texcoords (0, 0) at the bottom left
    /// to (1, 1) at the top right, white, drawn with material 0 and texture 0.
    fn textured_scene(size: u32, texture: Texture, mode: TextureMode) -> model::Scene {
        let mut scene = empty_scene(size, size);
        let n = size as f32;
        let mut square = window_object(
            &[
                [[0.0, 0.0, 0.5], [n, 0.0, 0.5], [n, n, 0.5]],
                [[0.0, 0.0, 0.5], [n, n, 0.5], [0.0, n, 0.5]],
            ],
            [1.0; 3],
        );
        square.mesh.texcoords = square
            .mesh
            .positions
            .iter()
            .map(|p| [p[0] / n, p[1] / n])
            .collect();
        scene.objects.push(square);
        scene.textures.push(texture);
        scene.materials[0].textures = vec![0];
        scene.materials[0].texture_mode = mode;
        scene
    }

    /// Red, green (bottom row), blue, white (top row).
    fn two_by_two(filter: Filter, wrap: Wrap) -> Texture {
        let texels = vec![
            rgba(255, 0, 0, 255),
            rgba(0, 255, 0, 255),
            rgba(0, 0, 255, 255),
            rgba(255, 255, 255, 255),
        ];
        texture(2, 2, texels, filter, wrap)
    }

    #[test]
    fn nearest_picks_exact_texels() {
        let scene = textured_scene(
            4,
            two_by_two(Filter::Nearest, Wrap::Repeat),
            TextureMode::Modulate,
        );
        let image = render(&scene).unwrap();
        let texels = [
            [255, 0, 0, 255],
            [0, 255, 0, 255],
            [0, 0, 255, 255],
            [255; 4],
        ];
        for y in 0..4 {
            for x in 0..4 {
                assert_eq!(
                    image.pixel(x, y),
                    texels[(y / 2 * 2 + x / 2) as usize],
                    "({x}, {y})"
                );
            }
        }
    }

    #[test]
    fn bilinear_blends_and_wraps_at_the_edges() {
        // Pixel centres at u = (x + ½)/2 texels: 0.25, 0.75, 1.25, 1.75. Pixel 1 has
        // i0 = 0, α = ¼; pixel 0 has i0 = −1, α = ¾, which repeat takes from texel 1 and
        // clamp from texel 0.
        let red_at = |wrap: Wrap, x: u32| {
            let scene = textured_scene(4, two_by_two(Filter::Linear, wrap), TextureMode::Replace);
            render(&scene).unwrap().pixel(x, 0)
        };
        // Row 0: v = 0.25, j0 = −1, β = ¾: repeat mixes in row 1 (blue, white) by ¼.
        // Pixel (1, 0), repeat: red ¾·(¾·255 + ¼·0) + ¼·(¾·0 + ¼·255) = 159.375 → 159,
        // green ¾·¼·255 + ¼·¼·255 = 63.75 → 64, blue ¼·(¾ + ¼)·255 → 64.
        assert_eq!(red_at(Wrap::Repeat, 1), [159, 64, 64, 255]);
        // Clamp: row 0 twice; red ¾·255 = 191.25 → 191, green ¼·255 = 63.75 → 64.
        assert_eq!(red_at(Wrap::Clamp, 1), [191, 64, 0, 255]);
        // Pixel (0, 0), clamp: texel (0, 0) alone.
        assert_eq!(red_at(Wrap::Clamp, 0), [255, 0, 0, 255]);
        // Repeat: texel −1 is texel 1, weighing ¼ against texel 0's ¾: the same as pixel 1.
        assert_eq!(red_at(Wrap::Repeat, 0), [159, 64, 64, 255]);
        // At a midpoint between texel centres each of the four weighs ¼.
        let level = Sampler::new(&two_by_two(Filter::Linear, Wrap::Clamp))
            .levels
            .remove(0);
        assert_eq!(
            bilinear(&level, Wrap::Clamp, 1.0, 1.0),
            [0.5, 0.5, 0.5, 1.0]
        );
        assert_eq!(
            nearest(&level, Wrap::Repeat, -0.5, 2.5),
            texel(&level, Wrap::Clamp, 1, 0)
        );
    }

    /// A 4 × 4 texture, texel (i, j) = (64·i, 64·j, 0, 255).
    fn ramp(filter: Filter) -> Texture {
        let texels = (0..16)
            .map(|k| rgba(64 * (k % 4) as u8, 64 * (k / 4) as u8, 0, 255))
            .collect();
        texture(4, 4, texels, filter, Wrap::Clamp)
    }

    #[test]
    fn trilinear_picks_and_blends_levels_by_the_derivatives() {
        let sampler = Sampler::new(&ramp(Filter::Trilinear));
        assert_eq!(sampler.levels.len(), 3);
        let (l0, l1, l2) = (&sampler.levels[0], &sampler.levels[1], &sampler.levels[2]);
        let (s, t) = (0.3, 0.6);
        let at = |l: &Level| {
            bilinear(
                l,
                Wrap::Clamp,
                s * f64::from(l.width),
                t * f64::from(l.height),
            )
        };
        let mix = |a: [f64; 4], b: [f64; 4], f: f64| -> [f64; 4] {
            std::array::from_fn(|k| (1.0 - f) * a[k] + f * b[k])
        };
        let close = |a: [f64; 4], b: [f64; 4]| a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-12);
        // ρ = |(u_x, v_x)| = 4·(ds, dt) per pixel, the larger of the two axes.
        let lod = |rho: f64| sample(&sampler, s, t, [rho / 4.0, 0.0], [0.0, rho / 8.0]);
        // Magnification and λ = 0: level 0, bilinear.
        assert_eq!(lod(0.5), at(l0));
        assert_eq!(lod(1.0), at(l0));
        // λ = 1 and 2: exactly levels 1 and 2.
        assert!(close(lod(2.0), at(l1)));
        assert!(close(lod(4.0), at(l2)));
        // λ = 1.5 (ρ = 2√2): half of each.
        assert!(
            close(lod(8f64.sqrt()), mix(at(l1), at(l2), 0.5)),
            "{:?}",
            lod(8f64.sqrt())
        );
        // λ = 0.5: levels 0 and 1.
        assert!(close(lod(2f64.sqrt()), mix(at(l0), at(l1), 0.5)));
        // Past the last level: the 1 × 1 level.
        assert!(close(lod(100.0), at(l2)));
        // The y axis counts when it is the larger.
        assert!(close(
            sample(&sampler, s, t, [0.0, 0.5], [0.0, 0.0]),
            at(l1)
        ));
    }

    #[test]
    fn trilinear_renders_a_minified_texture_from_the_next_level() {
        // The 4 × 4 ramp on a 2 × 2 window: ∂s/∂X = ½, u_x = 2, λ = 1: level 1 exactly,
        // each pixel centre on a texel centre of it.
        let scene = textured_scene(2, ramp(Filter::Trilinear), TextureMode::Replace);
        let image = render(&scene).unwrap();
        let level = &mipmap::pyramid(&scene.textures[0])[1];
        for y in 0..2 {
            for x in 0..2 {
                let want = level.texels[(y * 2 + x) as usize].to_le_bytes();
                assert_eq!(image.pixel(x, y), [want[0], want[1], want[2], 255]);
            }
        }
    }

    #[test]
    fn texcoord_derivatives_are_exact_under_perspective() {
        // A triangle at varying depth through a perspective projection (rows of
        // glFrustum(−1, 1, −1, 1, 1, 10)), its edge functions differenced numerically.
        let projection = [
            1.0,
            0.0,
            0.0,
            0.0,
            0.0,
            1.0,
            0.0,
            0.0,
            0.0,
            0.0,
            -11.0 / 9.0,
            -20.0 / 9.0,
            0.0,
            0.0,
            -1.0,
            0.0,
        ];
        let corner = |p: [f64; 3]| transform(&projection, [p[0], p[1], p[2], 1.0]);
        let clip = [
            corner([-1.0, -1.0, -2.0]),
            corner([2.0, -1.0, -6.0]),
            corner([0.0, 2.0, -3.0]),
        ];
        let s = [0.1, 0.9, 0.3];
        let mut samples = Vec::new();
        reference::rasterize_samples(&clip, (64, 64), Cull::None, TieRule::TopLeft, |x| {
            samples.push(*x)
        });
        assert!(samples.len() > 100);
        let at = |sample: &Sample, x: f64, y: f64| {
            let e: [f64; 3] = sample.edges.map(|[a, b, c]| a * x + b * y + c);
            (0..3).map(|k| s[k] * e[k]).sum::<f64>() / e.iter().sum::<f64>()
        };
        for sample in samples.iter().step_by(37) {
            let (value, d) = texcoord_derivatives(sample, s);
            let (x, y) = (f64::from(sample.x) + 0.5, f64::from(sample.y) + 0.5);
            assert!((value - at(sample, x, y)).abs() < 1e-12);
            let h = 1e-5;
            let dx = (at(sample, x + h, y) - at(sample, x - h, y)) / (2.0 * h);
            let dy = (at(sample, x, y + h) - at(sample, x, y - h)) / (2.0 * h);
            assert!(
                (d[0] - dx).abs() < 1e-7 && (d[1] - dy).abs() < 1e-7,
                "{d:?} vs {dx} {dy}"
            );
            assert!(
                d[0].abs() > 1e-4,
                "perspective: the derivative is not constant"
            );
        }
    }

    #[test]
    fn modulate_multiplies_the_vertex_colour_and_replace_ignores_it() {
        let texels = vec![rgba(255, 128, 0, 255)];
        let one = || texture(1, 1, texels.clone(), Filter::Nearest, Wrap::Repeat);
        let mut scene = textured_scene(2, one(), TextureMode::Modulate);
        scene.objects[0].colour = [0.5, 1.0, 1.0];
        // 0.5·1 → 127.5 → 128; 1·128/255 → 128.
        assert_eq!(render(&scene).unwrap().pixel(0, 0), [128, 128, 0, 255]);
        scene.materials[0].texture_mode = TextureMode::Replace;
        assert_eq!(render(&scene).unwrap().pixel(0, 0), [255, 128, 0, 255]);
        // Two units in order: modulate by the second texture too.
        scene.materials[0].texture_mode = TextureMode::Modulate;
        scene.textures.push(texture(
            1,
            1,
            vec![rgba(255, 255, 51, 255)],
            Filter::Nearest,
            Wrap::Clamp,
        ));
        scene.materials[0].textures = vec![0, 1, 1];
        assert_eq!(render(&scene).unwrap().pixel(1, 1), [128, 128, 0, 255]);
    }

    #[test]
    fn alpha_and_add_blending_over_the_background() {
        // A texture of alpha 0x40 (≈ ¼) replaced onto a quad over a grey background.
        let texels = vec![rgba(255, 0, 200, 64)];
        let mut scene = textured_scene(
            2,
            texture(1, 1, texels, Filter::Nearest, Wrap::Repeat),
            TextureMode::Replace,
        );
        scene.background = [0.4, 0.4, 0.4];
        let dst = quantise(0.4); // 102
        let a = 64.0 / 255.0;
        let want = |src: f64| quantise(src * a + f64::from(dst) / 255.0 * (1.0 - a));
        scene.pipeline.blend = Blend::Alpha;
        let p = render(&scene).unwrap().pixel(0, 0);
        assert_eq!(p, [want(1.0), want(0.0), want(200.0 / 255.0), 255]);
        assert_eq!(p, [140, 76, 127, 255]);
        scene.pipeline.blend = Blend::Add;
        // 1 + 0.4 clamps to 1; 0 + 0.4; 200/255 + 102/255 = 302/255 clamps.
        assert_eq!(render(&scene).unwrap().pixel(1, 0), [255, 102, 255, 255]);
        // Drawn twice with LEQUAL: the second blends over the first (quantised) result.
        scene.pipeline.depth_test = DepthTest::Lequal;
        scene.pipeline.blend = Blend::Alpha;
        let first = scene.objects[0].clone();
        scene.objects.push(first);
        let q = |src: f64, d: u8| quantise(src * a + f64::from(d) / 255.0 * (1.0 - a));
        assert_eq!(
            render(&scene).unwrap().pixel(1, 1),
            [q(1.0, 140), q(0.0, 76), q(200.0 / 255.0, 127), 255]
        );
        // The depth test still applies: LESS keeps the first layer only.
        scene.pipeline.depth_test = DepthTest::Less;
        assert_eq!(render(&scene).unwrap().pixel(1, 1), [140, 76, 127, 255]);
    }
}
