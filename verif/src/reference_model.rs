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
//! to the quantised background. Textures and blending are not supported yet: a scene
//! with a textured material or `blend ≠ None` is an error.

use crate::image::{Image, quantise};
use crate::marble::MarbleShading;
use crate::reference::{self, Fragment, TieRule, V3, cross, dot, normalize, widen};
use imagine_pipelines::scene::SceneError;
use imagine_pipelines::scene::model::{self, Blend, Material, Object, Shader};

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
/// length, and no textures or blending (not supported yet).
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
    if scene.pipeline.blend != Blend::None {
        return Err(error(
            scene,
            format!(
                "blend {:?}: blending is not supported yet by the reference renderer",
                scene.pipeline.blend
            ),
        ));
    }
    if let Some(m) = scene.materials.iter().find(|m| !m.textures.is_empty()) {
        return Err(error(
            scene,
            format!(
                "material `{}` has textures: textures are not supported yet by the reference renderer",
                m.name
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
        let marble = matches!(scene.materials[object.material].shader, Shader::Marble(_));
        if marble && mesh.normals.len() != n {
            return bad(format!(
                "marble needs normals: {} for {n} positions",
                mesh.normals.len()
            ));
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

/// One fragment of a scene file's object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjectFragment {
    /// Index of the object in the scene.
    pub object: usize,
    /// The fragment; its `triangle` is the index within the object's mesh.
    pub fragment: Fragment,
}

/// Every fragment of the scene in drawing order (object by object, triangle by triangle,
/// bottom row up, left to right), culled and clipped but without the depth test.
pub fn for_each_fragment(
    scene: &model::Scene,
    rule: TieRule,
    mut f: impl FnMut(&ObjectFragment),
) -> Result<(), SceneError> {
    check(scene)?;
    let lights = eye_lights(scene);
    for (index, object) in scene.objects.iter().enumerate() {
        let clip = clip_positions(scene, object);
        let colours = object_corner_colours(scene, object, &lights);
        // Marble: the rasterizer interpolates the unit vectors, that is, gives the
        // perspective-correct barycentrics, and the shader runs on them.
        let marble = MarbleShading::of(scene, object);
        const BARYCENTRIC: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        for (triangle, (t, col)) in object.mesh.triangles.iter().zip(&colours).enumerate() {
            let c = t.map(|i| clip[i as usize]);
            let shade = |colour: [f64; 3]| match &marble {
                Some(m) => {
                    let at = |v: &[[f32; 3]]| -> V3 {
                        std::array::from_fn(|k| {
                            (0..3)
                                .map(|corner| colour[corner] * f64::from(v[t[corner] as usize][k]))
                                .sum()
                        })
                    };
                    m.colour(at(&object.mesh.positions), at(&object.mesh.normals))
                }
                None => colour,
            };
            reference::rasterize_triangle(
                &c,
                if marble.is_some() { &BARYCENTRIC } else { col },
                (scene.width, scene.height),
                scene.pipeline.cull,
                rule,
                |x, y, depth, colour| {
                    f(&ObjectFragment {
                        object: index,
                        fragment: Fragment {
                            triangle,
                            x,
                            y,
                            depth,
                            colour: shade(colour),
                        },
                    })
                },
            );
        }
    }
    Ok(())
}

/// Renders a scene file's scene (see the module comment) with the default tie rule.
pub fn render(scene: &model::Scene) -> Result<Image, SceneError> {
    render_with(scene, TieRule::TopLeft)
}

/// [`render`] with a choice of tie rule.
pub fn render_with(scene: &model::Scene, rule: TieRule) -> Result<Image, SceneError> {
    check(scene)?;
    let [r, g, b] = scene.background.map(|c| quantise(f64::from(c)));
    let mut image = Image::new(scene.width, scene.height);
    image.pixels.fill([r, g, b, 255]);
    let mut depth = vec![1.0f64; image.pixels.len()];
    let width = scene.width as usize;
    let test = scene.pipeline.depth_test;
    for_each_fragment(scene, rule, |of| {
        let f = &of.fragment;
        let i = f.y as usize * width + f.x as usize;
        if reference::depth_passes(test, f.depth, depth[i]) {
            depth[i] = f.depth;
            let [r, g, b] = f.colour.map(quantise);
            image.pixels[i] = [r, g, b, 255];
        }
    })?;
    Ok(image)
}

#[cfg(test)]
mod tests {
    use super::*;
    use imagine_pipelines::scene::model::{
        Camera, Cull, DepthTest, Light, Mesh, PipelineKind, PipelineSettings, Space, TextureMode,
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
    fn textures_blending_and_bad_indices_are_errors() {
        let mut scene = empty_scene(4, 4);
        scene.objects.push(window_object(
            &[[[0.0, 0.0, 0.5], [4.0, 0.0, 0.5], [0.0, 4.0, 0.5]]],
            RED,
        ));
        assert!(render(&scene).is_ok());
        let mut blended = scene.clone();
        blended.pipeline.blend = Blend::Alpha;
        let e = render(&blended).unwrap_err().to_string();
        assert!(e.contains("not supported yet"), "{e}");
        let mut textured = scene.clone();
        textured.materials[0].textures.push(0);
        let e = render(&textured).unwrap_err().to_string();
        assert!(e.contains("not supported yet"), "{e}");
        let mut bad = scene.clone();
        bad.objects[0].mesh.triangles[0][2] = 3;
        let e = render(&bad).unwrap_err().to_string();
        assert!(e.contains("beyond"), "{e}");
        let mut bad = scene;
        bad.objects[0].material = 2;
        assert!(render(&bad).is_err());
    }
}
