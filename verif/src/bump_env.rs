//! The `bump_env` shader (VERONA's) in f64 for the reference renderer
//! ([`crate::reference_model`]), written from its definition in the `bump_env` kernels'
//! notes, not from the kernels: the same rules, none of the f32 datapath's roundings.
//!
//! The combined displacement/bump map is the material's ([`bump_map::build`], the words the
//! machine's DRAM holds, widened); its texel at `(s, t)` is `(⌊s·size⌋, ⌊t·size⌋)`, each
//! index wrapped (repeat).
//!
//! **Per vertex** (object space, mesh position `P`, unit normal `N` and tangent `T`, the
//! texel at the vertex's `(s, t)`): `P' = P + displacement·h·N`, `B = N × T`,
//! `N' = nx·T + ny·B + nz·N`. `P'` goes through the model, view and projection as any
//! vertex; the eye-space position is `MV·P'`, the normal `normalize(Nmat·N')` (`Nmat` the
//! inverse transpose of MV's 3 × 3), the tangent `normalize(MV₃·T)`.
//!
//! **Per fragment** (the eye-space position `P`, normal `N`, tangent `T` and `(s, t)`
//! interpolated perspective-correctly, the texel at `(s, t)`): `N̂ = N/|N|`, `B = N̂ × T`,
//! `N'' = normalize(nx·T + ny·B + nz·N̂)`, `V = P/|P|`, `R = V − 2(N''·V)·N''`,
//! `m = 2·sqrt(Rx² + Ry² + (Rz + 1)²)`, the environment map's texel at
//! `(Rx/m + ½, Ry/m + ½)` (nearest, its wrap), times the object's colour.

use imagine_pipelines::scene::bump_map;
use imagine_pipelines::scene::model::{self, Object, Shader};

use crate::reference::{V3, cross, dot, normalize, widen};
use crate::reference_model::{Matrix, Sampler, modelview, nearest, normal_matrix, transform};

/// One object's `bump_env` shading: its vertices displaced and their eye-space frames, and
/// its maps.
pub struct BumpEnvShading {
    /// Per vertex: clip position of the displaced vertex.
    pub clip: Vec<[f64; 4]>,
    /// Per vertex: s, t, the eye-space position, normal and tangent.
    varyings: Vec<[f64; 11]>,
    bump: Vec<u32>,
    size: u32,
    environment: Sampler,
    colour: V3,
}

impl BumpEnvShading {
    /// The shading of `object`, or `None` when its material is not `bump_env` (the caller
    /// has checked normals, tangents, texcoords and the one texture).
    pub fn of(scene: &model::Scene, object: &Object) -> Option<BumpEnvShading> {
        let material = &scene.materials[object.material];
        let Shader::BumpEnv(b) = material.shader else {
            return None;
        };
        let bump = bump_map::build(&b);
        let size = b.bump_size;
        let mesh = &object.mesh;
        let mv = modelview(scene, object);
        let nm = normal_matrix(&mv);
        let projection: Matrix = scene.camera_for(object).projection.map(f64::from);
        let mut clip = Vec::with_capacity(mesh.positions.len());
        let mut varyings = Vec::with_capacity(mesh.positions.len());
        for v in 0..mesh.positions.len() {
            let [s, t] = mesh.texcoords[v].map(f64::from);
            let [nx, ny, nz, h] = texel(&bump, size, s, t);
            let (p, n, tangent) = (
                widen(mesh.positions[v]),
                widen(mesh.normals[v]),
                widen(mesh.tangents[v]),
            );
            let lift = f64::from(b.displacement) * h;
            let displaced: V3 = std::array::from_fn(|k| p[k] + lift * n[k]);
            let binormal = cross(n, tangent);
            let bumped: V3 =
                std::array::from_fn(|k| nx * tangent[k] + ny * binormal[k] + nz * n[k]);
            let eye = transform(&mv, [displaced[0], displaced[1], displaced[2], 1.0]);
            clip.push(transform(&projection, eye));
            let eye_normal = normalize(std::array::from_fn(|k| dot(nm[k], bumped)));
            let eye_tangent = normalize(std::array::from_fn(|k| {
                dot([mv[4 * k], mv[4 * k + 1], mv[4 * k + 2]], tangent)
            }));
            let mut record = [0.0; 11];
            record[..2].copy_from_slice(&[s, t]);
            record[2..5].copy_from_slice(&eye[..3]);
            record[5..8].copy_from_slice(&eye_normal);
            record[8..].copy_from_slice(&eye_tangent);
            varyings.push(record);
        }
        let environment = Sampler::new(&scene.textures[material.textures[0]]);
        Some(BumpEnvShading {
            clip,
            varyings,
            bump,
            size,
            environment,
            colour: widen(object.colour),
        })
    }

    /// The colour (and alpha) of a fragment of triangle `corners` with perspective-correct
    /// barycentrics `l`.
    pub fn colour(&self, corners: [u32; 3], l: [f64; 3]) -> [f64; 4] {
        let v: [f64; 11] = std::array::from_fn(|k| {
            (0..3)
                .map(|c| l[c] * self.varyings[corners[c] as usize][k])
                .sum()
        });
        let [nx, ny, nz, _] = texel(&self.bump, self.size, v[0], v[1]);
        let position: V3 = [v[2], v[3], v[4]];
        let n = normalize([v[5], v[6], v[7]]);
        let tangent: V3 = [v[8], v[9], v[10]];
        let binormal = cross(n, tangent);
        let bumped = normalize(std::array::from_fn(|k| {
            nx * tangent[k] + ny * binormal[k] + nz * n[k]
        }));
        let view = normalize(position);
        let d = dot(bumped, view);
        let r: V3 = std::array::from_fn(|k| view[k] - 2.0 * d * bumped[k]);
        let m = 2.0 * (r[0] * r[0] + r[1] * r[1] + (r[2] + 1.0) * (r[2] + 1.0)).sqrt();
        let level = &self.environment.levels[0];
        let (u, w) = (
            (r[0] / m + 0.5) * f64::from(level.width),
            (r[1] / m + 0.5) * f64::from(level.height),
        );
        let e = nearest(level, self.environment.wrap, u, w);
        [
            self.colour[0] * e[0],
            self.colour[1] * e[1],
            self.colour[2] * e[2],
            e[3],
        ]
    }
}

/// The combined map's texel holding `(s, t)` (repeat), widened.
fn texel(words: &[u32], size: u32, s: f64, t: f64) -> [f64; 4] {
    let index = |x: f64| (x * f64::from(size)).floor().rem_euclid(f64::from(size)) as u32;
    bump_map::texel(words, size, index(s), index(t)).map(f64::from)
}
