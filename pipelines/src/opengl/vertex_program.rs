//! The vertex stage, generated for each material of a scene: `perbegin` (the per-`glBegin`
//! state work, once per object) and the vertex program it feeds.
//!
//! **perbegin** reads the OpenGL state as the host wrote it — the view, model and
//! projection matrices, then the material and light words below — and writes the vertex
//! program's parameters: the model-view `MV = V·M`, `MVP = P·MV`, and for `lit` materials
//! the normal matrix (the inverse transpose of MV's upper 3×3, its cofactors over its
//! determinant), each light's position in eye space (`V·l`), and the light-times-material
//! products OpenGL folds once per state change: `base = a_global·a_m + Σ_l a_l·a_m`,
//! `d_l·d_m` and `s_l·s_m`. Every product of matrices sums left to right, as
//! [`crate::scene::mat_mul`]. The host composes nothing.
//!
//! **The vertex program** is `unlit` — the clip position `MVP·p` and the vertex colour
//! (from each vertex, or the object's colour as a parameter when the mesh has none, so
//! vertices carry 3 words instead of 6) — or `lit`: OpenGL 1.x fixed-function lighting per
//! vertex in eye space as `../shared/SCENE_FORMAT.md` defines it (local viewer, no
//! attenuation or spotlights, colour clamped to [0, 1]): `p_e = MV·p`,
//! `n = normalize(N·n_obj)`, `E = normalize(−p_e)`, and per light `L = normalize(l_e − p_e)`,
//! `c += max(n·L, 0)·(d_l·d_m) + (n·L > 0 ? max(n·H, 0)^s : 0)·(s_l·s_m)` with
//! `H = normalize(L + E)`. The program is built for its material: the lights unrolled, the
//! specular term only when the material and a light have one, and the exponent `s` (an
//! integer 0..=128) as squarings and multiplies. Every `normalize(v)` is
//! `v · (1 / sqrt(v·v))` (one `fsqrt`, one `fdiv`), dot products sum left to right.
//!
//! **Light passes.** One kernel holds the loop values of only a few lights (see [`SPLIT`]):
//! the first kernel transforms the vertex and adds the first lights; with more lights it
//! writes a partial record (clip x, y, z, w; the colour so far r, g, b; `p_e`; `n`; and `E`
//! with the specular term) and `…:pass1`, … each add the next lights to it. Every kernel
//! reads the whole parameter stream (parameters a kernel does not use are read and
//! dropped). The colour sums in the one-kernel order — base, then light 0, 1, … — so the
//! passes compute the very words one kernel would.
//!
//! **Marble** (`shader = "marble"`) is unlit: the clip position `MVP·p`, the colour white
//! (the fragment program computes the colour), and the object-space position and normal
//! passed through as they came, for the fragment program's noise and lighting.
//!
//! Output records (of the last kernel): clip x, y, z, w, then r, g, b — what
//! `assemble_clip` reads — then the frame's extra words ([`Varyings`](super::kernels::Varyings)):
//! the vertex record's own for `unlit` and `lit` (s, t and zeros, taken from the record),
//! the position and normal and then zeros for marble.

use imagine_units::desc::MachineDesc;

use super::kernels::finish;
use crate::kernel::{Kernel, KernelBuilder, LoopSpec, Perm, Ty, Value};
use crate::kernels::bump_env;
use crate::kernels::transform::{matrix_params, transform_point};
use crate::kernels::vertex::normalize;
use crate::kernels::{Vec3, dot};
use crate::scene::model::{Material, Mesh, Object, Scene, Shader};

/// What a vertex program is built for.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum VertexProgram {
    /// Unlit; `per_vertex_colour`: vertices carry their colour (else it is a parameter).
    /// `extras`: words vertices carry after these (texture coordinates and zeros), passed
    /// through to the shaded record.
    Unlit {
        per_vertex_colour: bool,
        extras: usize,
    },
    /// Lit by `lights` lights with the specular term (when `specular`) to an integer
    /// power `shininess`.
    Lit {
        lights: usize,
        specular: bool,
        shininess: u32,
        extras: usize,
    },
    /// Marble: the clip position, white, and the object-space position and normal then
    /// zeros, `extras` words in all.
    Marble { extras: usize },
    /// VERONA's `bump_env`: the second half of a vertex program split at its vertex
    /// texture ([`crate::kernels::bump_env::vertex_program`]; `vtexaddr` and a gather come
    /// first): the displaced clip position, the object's colour, then s, t and the
    /// eye-space position, normal and tangent, then zeros, `extras` words in all.
    BumpEnv { extras: usize },
    /// The general fixed-function program (`--no-specialize`): every vertex carries its
    /// position, normal and colour; lighting by `lights` lights with the specular term is
    /// always computed, and a parameter chooses it or the vertex colour (only the exponent
    /// is built in: the material's).
    General { lights: usize, shininess: u32 },
}

/// Whether any object of `scene` is drawn with a texture: then every vertex carries texture
/// coordinates (the shaded record has one size in a frame).
pub fn textured(scene: &Scene) -> bool {
    scene
        .objects
        .iter()
        .any(|o| !scene.materials[o.material].textures.is_empty())
}

/// Whether any object of `scene` is drawn with the marble shader.
pub fn marbled(scene: &Scene) -> bool {
    scene
        .objects
        .iter()
        .any(|o| matches!(scene.materials[o.material].shader, Shader::Marble(_)))
}

/// Whether any object of `scene` is drawn with the `bump_env` shader.
pub fn bump_mapped(scene: &Scene) -> bool {
    scene
        .objects
        .iter()
        .any(|o| matches!(scene.materials[o.material].shader, Shader::BumpEnv(_)))
}

/// Extra words every shaded vertex of `scene` carries after its colour: 11 (s, t, then the
/// eye-space position, normal and tangent) when an object is `bump_env`, else 6 (shading
/// position and normal) when one is marble, else 2 (s, t) when one is textured, else none.
/// The first two words are s and t whenever an object is textured.
pub fn extra_words(scene: &Scene) -> usize {
    if bump_mapped(scene) {
        bump_env::EXTRAS
    } else if marbled(scene) {
        6
    } else if textured(scene) {
        2
    } else {
        0
    }
}

/// The fewest lights the general program is built for.
pub const GENERAL_LIGHTS: usize = 3;

impl VertexProgram {
    /// The program an object of `scene` needs; an error for what it cannot draw yet.
    pub fn for_object(
        scene: &Scene,
        object: &Object,
        general: bool,
    ) -> Result<VertexProgram, String> {
        let m: &Material = &scene.materials[object.material];
        let extras = extra_words(scene);
        if !m.textures.is_empty() && object.mesh.texcoords.len() != object.mesh.positions.len() {
            return Err(format!(
                "object `{}` has textured material `{}` but its mesh has {} texture coordinates for {} vertices",
                object.name,
                m.name,
                object.mesh.texcoords.len(),
                object.mesh.positions.len()
            ));
        }
        if general {
            if extras > 0 {
                return Err(
                    "the general pipeline (--no-specialize) draws no textures and no marble".into(),
                );
            }
            if m.shader == Shader::Lit && object.mesh.normals.len() != object.mesh.positions.len() {
                return Err(format!(
                    "object `{}` is lit but its mesh has {} normals for {} vertices",
                    object.name,
                    object.mesh.normals.len(),
                    object.mesh.positions.len()
                ));
            }
            if m.shininess.fract() != 0.0 || !(0.0..=128.0).contains(&m.shininess) {
                return Err(format!(
                    "material `{}`: shininess {} — the vertex program raises to integer powers \
                     0..=128",
                    m.name, m.shininess
                ));
            }
            return Ok(VertexProgram::General {
                lights: scene.lights.len().max(GENERAL_LIGHTS),
                shininess: m.shininess as u32,
            });
        }
        match m.shader {
            Shader::Unlit => Ok(VertexProgram::Unlit {
                per_vertex_colour: !object.mesh.colours.is_empty(),
                extras,
            }),
            Shader::BumpEnv(_) => {
                if m.textures.len() != 1 {
                    return Err(format!(
                        "material `{}` is bump_env with {} textures: it takes exactly one, its \
                         environment map",
                        m.name,
                        m.textures.len()
                    ));
                }
                let n = object.mesh.positions.len();
                if object.mesh.normals.len() != n || object.mesh.tangents.len() != n {
                    return Err(format!(
                        "object `{}` is bump_env but its mesh has {} normals and {} tangents \
                         for {n} vertices",
                        object.name,
                        object.mesh.normals.len(),
                        object.mesh.tangents.len(),
                    ));
                }
                Ok(VertexProgram::BumpEnv { extras })
            }
            Shader::Marble(_) => {
                if object.mesh.normals.len() != object.mesh.positions.len() {
                    return Err(format!(
                        "object `{}` is marble but its mesh has {} normals for {} vertices",
                        object.name,
                        object.mesh.normals.len(),
                        object.mesh.positions.len()
                    ));
                }
                Ok(VertexProgram::Marble { extras })
            }
            Shader::Lit => {
                if m.shininess.fract() != 0.0 || !(0.0..=128.0).contains(&m.shininess) {
                    return Err(format!(
                        "material `{}`: shininess {} — the vertex program raises to integer \
                         powers 0..=128",
                        m.name, m.shininess
                    ));
                }
                if object.mesh.normals.len() != object.mesh.positions.len() {
                    return Err(format!(
                        "object `{}` is lit but its mesh has {} normals for {} vertices",
                        object.name,
                        object.mesh.normals.len(),
                        object.mesh.positions.len()
                    ));
                }
                let any_specular = m.specular.iter().any(|&c| c != 0.0)
                    && scene
                        .lights
                        .iter()
                        .any(|l| l.specular.iter().any(|&c| c != 0.0));
                Ok(VertexProgram::Lit {
                    lights: scene.lights.len(),
                    specular: any_specular,
                    shininess: m.shininess as u32,
                    extras,
                })
            }
        }
    }

    /// The name it is registered and reported under.
    pub fn name(&self) -> String {
        let base = self.base_name();
        match (self, self.extras()) {
            (_, 0)
            | (VertexProgram::Marble { .. }, 6)
            | (VertexProgram::BumpEnv { .. }, bump_env::EXTRAS) => base,
            (_, 2) => format!("{base}_tex"),
            (_, n) => format!("{base}_x{n}"),
        }
    }

    /// Words vertices carry after the colour (texture coordinates, or for marble the
    /// shading position and normal, then zeros), passed through to the shaded record.
    pub fn extras(&self) -> usize {
        match self {
            VertexProgram::Unlit { extras, .. }
            | VertexProgram::Lit { extras, .. }
            | VertexProgram::Marble { extras }
            | VertexProgram::BumpEnv { extras } => *extras,
            VertexProgram::General { .. } => 0,
        }
    }

    /// Words the vertex record carries for the extras (marble reads its position and
    /// normal and writes zeros for the rest).
    fn record_extras(&self) -> usize {
        match self {
            VertexProgram::Marble { .. } | VertexProgram::BumpEnv { .. } => 0,
            _ => self.extras(),
        }
    }

    fn base_name(&self) -> String {
        match self {
            VertexProgram::Unlit {
                per_vertex_colour: true,
                ..
            } => "vertex_unlit".into(),
            VertexProgram::Unlit {
                per_vertex_colour: false,
                ..
            } => "vertex_unlit_flat".into(),
            VertexProgram::Lit {
                lights,
                specular,
                shininess,
                ..
            } => {
                if *specular {
                    format!("vertex_lit{lights}_s{shininess}")
                } else {
                    format!("vertex_lit{lights}_diffuse")
                }
            }
            VertexProgram::General { lights, shininess } => {
                format!("vertex_general{lights}_s{shininess}")
            }
            VertexProgram::Marble { .. } => "vertex_marble".into(),
            VertexProgram::BumpEnv { .. } => "vertex_bump_env".into(),
        }
    }

    /// Whether it lights vertices (and so has `perlight` and the lit parameters).
    pub fn lit(&self) -> bool {
        !matches!(
            self,
            VertexProgram::Unlit { .. }
                | VertexProgram::Marble { .. }
                | VertexProgram::BumpEnv { .. }
        )
    }

    /// Lights it is built for, and whether with the specular term.
    pub fn lighting(&self) -> Option<(usize, bool)> {
        match self {
            VertexProgram::Unlit { .. }
            | VertexProgram::Marble { .. }
            | VertexProgram::BumpEnv { .. } => None,
            VertexProgram::Lit {
                lights, specular, ..
            } => Some((*lights, *specular)),
            VertexProgram::General { lights, .. } => Some((*lights, true)),
        }
    }

    /// The exponent of the specular term.
    fn shininess(&self) -> u32 {
        match self {
            VertexProgram::Lit { shininess, .. } | VertexProgram::General { shininess, .. } => {
                *shininess
            }
            VertexProgram::Unlit { .. }
            | VertexProgram::Marble { .. }
            | VertexProgram::BumpEnv { .. } => 0,
        }
    }

    /// Words of a vertex record in memory.
    pub fn record_words(&self) -> usize {
        self.record_extras()
            + match self {
                VertexProgram::Unlit {
                    per_vertex_colour: false,
                    ..
                } => 3,
                VertexProgram::General { .. } => 9,
                VertexProgram::BumpEnv { .. } => bump_env::VERTEX_WORDS,
                _ => 6,
            }
    }

    /// Interpolated words per fragment the program's outputs feed (colour, texture
    /// coordinates).
    pub fn interpolants(&self) -> Vec<&'static str> {
        let mut names = vec!["r", "g", "b"];
        let extras: &[&'static str] = match self {
            VertexProgram::Marble { .. } => &["x", "y", "z", "nx", "ny", "nz"],
            VertexProgram::BumpEnv { .. } => &[
                "s", "t", "ex", "ey", "ez", "enx", "eny", "enz", "etx", "ety", "etz",
            ],
            _ => &["s", "t"],
        };
        names.extend(extras.iter().take(self.extras()));
        while names.len() < 3 + self.extras() {
            names.push("0");
        }
        names
    }

    /// Vertex `v` of `object`'s mesh as the program reads it.
    pub fn vertex_words(&self, object: &Object, v: usize, out: &mut Vec<u32>) {
        let mesh: &Mesh = &object.mesh;
        out.extend(mesh.positions[v].map(f32::to_bits));
        match self {
            VertexProgram::Unlit {
                per_vertex_colour: true,
                ..
            } => {
                let c = mesh.colours.get(v).copied().unwrap_or(object.colour);
                out.extend(c.map(f32::to_bits));
            }
            VertexProgram::Unlit {
                per_vertex_colour: false,
                ..
            } => {}
            VertexProgram::Lit { .. } | VertexProgram::Marble { .. } => {
                out.extend(mesh.normals[v].map(f32::to_bits))
            }
            VertexProgram::BumpEnv { .. } => {
                let st = mesh.texcoords.get(v).copied().unwrap_or([0.0; 2]);
                let words = mesh.normals[v]
                    .into_iter()
                    .chain(mesh.tangents[v])
                    .chain(st);
                out.extend(words.map(f32::to_bits))
            }
            VertexProgram::General { .. } => {
                let n = mesh.normals.get(v).copied().unwrap_or([0.0; 3]);
                let c = mesh.colours.get(v).copied().unwrap_or(object.colour);
                out.extend(n.into_iter().chain(c).map(f32::to_bits));
            }
        }
        let extras = self.record_extras();
        if extras > 0 {
            // An object whose material has no texture still carries (0, 0).
            let st = mesh.texcoords.get(v).copied().unwrap_or([0.0; 2]);
            out.extend(st.map(f32::to_bits));
            out.extend(std::iter::repeat_n(0, extras - 2));
        }
    }

    /// The OpenGL state `perbegin` reads for `object`: view, model and projection, then,
    /// for a constant colour, the object's colour; padded to whole rows of `clusters`.
    pub fn state_words(&self, scene: &Scene, object: &Object, clusters: usize) -> Vec<u32> {
        let camera = scene.camera_for(object);
        let mut w: Vec<f32> = Vec::new();
        w.extend(camera.view);
        w.extend(object.model);
        w.extend(camera.projection);
        match self {
            VertexProgram::Unlit {
                per_vertex_colour: false,
                ..
            } => w.extend(object.colour),
            VertexProgram::BumpEnv { .. } => {
                w.extend(object.colour);
                if let Shader::BumpEnv(b) = scene.materials[object.material].shader {
                    w.push(b.displacement);
                }
            }
            _ => {}
        }
        let mut words: Vec<u32> = w.into_iter().map(f32::to_bits).collect();
        if let VertexProgram::General { .. } = self {
            let m = &scene.materials[object.material];
            words.push(u32::from(m.shader == Shader::Lit));
        }
        words.resize(words.len().div_ceil(clusters) * clusters, 0);
        words
    }

    /// The lights as `perlight` reads them: per light its position, ambient, diffuse and
    /// specular colours (12 words), each word repeated in every cluster, so that iteration
    /// `l` of every cluster reads light `l`.
    /// The general program's lights beyond the scene's are dark (no colour), far away so
    /// that their direction is well defined.
    pub fn light_words(&self, scene: &Scene, clusters: usize) -> Vec<u32> {
        let Some((lights, _)) = self.lighting() else {
            return Vec::new();
        };
        let dark = [
            1.0e6, 1.0e6, 1.0e6, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
        ];
        let words: Vec<f32> = scene
            .lights
            .iter()
            .map(|l| [l.position, l.ambient, l.diffuse, l.specular].concat())
            .chain(std::iter::repeat(dark.to_vec()))
            .take(lights)
            .flatten()
            .collect();
        words
            .into_iter()
            .flat_map(|x| std::iter::repeat_n(x.to_bits(), clusters))
            .collect()
    }

    /// `perlight`'s parameters for `object`: the view's first three rows, the material's
    /// ambient, diffuse and specular colours and the global ambient light.
    pub fn perlight_params(scene: &Scene, object: &Object) -> Vec<u32> {
        let m = &scene.materials[object.material];
        let view = scene.camera_for(object).view;
        view[..12]
            .iter()
            .chain(&m.ambient)
            .chain(&m.diffuse)
            .chain(&m.specular)
            .chain(&scene.ambient)
            .map(|x| x.to_bits())
            .collect()
    }

    /// `perbegin` for this program: the matrices (and a constant colour, passed through).
    pub fn perbegin(&self, desc: &MachineDesc) -> Kernel {
        let c = desc.cluster.count;
        let mut b = KernelBuilder::new("perbegin");
        let state_in = b.input("state");
        let params_out = b.output("params");
        let words = self.state_words_len();
        let rows: Vec<Value> = (0..words.div_ceil(c))
            .map(|_| b.read_f32(state_in))
            .collect();
        let state: Vec<Value> = (0..words)
            .map(|j| b.comm(rows[j / c], Perm::Broadcast((j % c) as u16)))
            .collect();
        let (view, model, projection) = (&state[..16], &state[16..32], &state[32..48]);
        let passed_through: Vec<Value> = state[48..].to_vec();
        let modelview = mat_mul(&mut b, view, model);
        let mvp = mat_mul(&mut b, projection, &modelview);
        for &v in &mvp {
            b.write(params_out, v);
        }
        match self {
            VertexProgram::Unlit {
                per_vertex_colour: true,
                ..
            }
            | VertexProgram::Marble { .. } => {}
            VertexProgram::Unlit {
                per_vertex_colour: false,
                ..
            } => {
                for &v in &state[48..51] {
                    b.write(params_out, v);
                }
            }
            VertexProgram::BumpEnv { .. } => {
                for &v in &modelview[..12] {
                    b.write(params_out, v);
                }
                for v in normal_matrix(&mut b, &modelview) {
                    b.write(params_out, v);
                }
                // The object's colour and the displacement, passed through.
                for &v in &passed_through[..4] {
                    b.write(params_out, v);
                }
            }
            VertexProgram::Lit { .. } | VertexProgram::General { .. } => {
                for &v in &modelview[..12] {
                    b.write(params_out, v);
                }
                for v in normal_matrix(&mut b, &modelview) {
                    b.write(params_out, v);
                }
                if let VertexProgram::General { .. } = self {
                    // The lit switch, passed through.
                    b.write(params_out, passed_through[0]);
                }
                let zero = b.word(0);
                for _ in self.perbegin_param_count()..self.perbegin_rows(desc) {
                    b.write(params_out, zero);
                }
            }
        }
        finish(b)
    }

    /// `perlight` for a lit program: one iteration per light (stream `lights`, see
    /// [`VertexProgram::light_words`]) writes the light's eye-space position `V·l` and the
    /// products `d_l·d_m` and (with the specular term) `s_l·s_m`; after the loop, `base =
    /// a_global·a_m + Σ_l a_l·a_m`. Its output follows `perbegin`'s in the vertex
    /// program's parameters. `None` for unlit programs.
    pub fn perlight(&self, _desc: &MachineDesc) -> Option<Kernel> {
        let (_, specular) = self.lighting()?;
        let specular = &specular;
        let mut b = KernelBuilder::new("perlight");
        let lights = b.input("lights");
        // Not `params`: that is the name of the kernel's own parameter stream.
        let params_out = b.output("light_params");
        let view: Vec<Value> = (0..12).map(|i| b.param_f32(&format!("view{i}"))).collect();
        let rgb = |b: &mut KernelBuilder, p: &str| {
            ["r", "g", "b"].map(|c| b.param_f32(&format!("{p}_{c}")))
        };
        let ambient = rgb(&mut b, "ambient");
        let diffuse = rgb(&mut b, "diffuse");
        let spec = rgb(&mut b, "specular");
        let global = rgb(&mut b, "global_ambient");
        let init: Vec3 = std::array::from_fn(|i| b.fmul(global[i], ambient[i]));
        b.begin_loop(LoopSpec::OverStream(lights));
        let base: Vec3 = init.map(|v| b.carried(v));
        let word: Vec<Value> = (0..12).map(|_| b.read_f32(lights)).collect();
        let mut m16 = [view[0]; 16];
        m16[..12].copy_from_slice(&view);
        let eye = transform_point(&mut b, &m16, [word[0], word[1], word[2]], None);
        for &v in &eye[..3] {
            b.write(params_out, v);
        }
        for i in 0..3 {
            let v = b.fmul(word[6 + i], diffuse[i]);
            b.write(params_out, v);
        }
        if *specular {
            for i in 0..3 {
                let v = b.fmul(word[9 + i], spec[i]);
                b.write(params_out, v);
            }
        }
        for i in 0..3 {
            let t = b.fmul(word[3 + i], ambient[i]);
            let next = b.fadd(base[i], t);
            b.set_next(base[i], next);
        }
        b.end_loop();
        for v in base {
            b.write(params_out, v);
        }
        Some(finish(b))
    }

    /// Parameters of the vertex program (the words `perbegin` and `perlight` write per
    /// cluster).
    pub fn param_count(&self, desc: &MachineDesc) -> usize {
        self.perbegin_rows(desc)
            + match self.lighting() {
                Some((lights, specular)) => 3 + lights * (6 + 3 * usize::from(specular)),
                None => 0,
            }
    }

    /// The parameter rows `perbegin` writes: its parameters, then, before `perlight`'s,
    /// padding rows to the next SRF block boundary (a stream starts on one).
    pub fn perbegin_rows(&self, desc: &MachineDesc) -> usize {
        let own = self.perbegin_param_count();
        if !self.lit() {
            return own;
        }
        own.next_multiple_of(crate::stream::srf::block_rows(desc))
    }

    /// The parameters `perbegin` computes (`perlight` writes the rest).
    fn perbegin_param_count(&self) -> usize {
        16 + match self {
            VertexProgram::Unlit {
                per_vertex_colour: true,
                ..
            }
            | VertexProgram::Marble { .. } => 0,
            VertexProgram::Unlit {
                per_vertex_colour: false,
                ..
            } => 3,
            VertexProgram::Lit { .. } => 12 + 9,
            VertexProgram::General { .. } => 12 + 9 + 1,
            VertexProgram::BumpEnv { .. } => 12 + 9 + 3 + 1,
        }
    }

    fn state_words_len(&self) -> usize {
        48 + match self {
            VertexProgram::Unlit {
                per_vertex_colour: false,
                ..
            } => 3,
            VertexProgram::General { .. } => 1,
            VertexProgram::BumpEnv { .. } => 4,
            _ => 0,
        }
    }

    /// The vertex program (for a lit program with more lights than one kernel holds, its
    /// first kernel: [`VertexProgram::passes`] follow it).
    pub fn build(&self, desc: &MachineDesc) -> Kernel {
        self.kernels_with(desc, SPLIT).swap_remove(0)
    }

    /// The light passes that follow [`VertexProgram::build`]'s kernel, in order (none for
    /// unlit programs and for lit ones the first kernel lights alone, see [`SPLIT`]).
    pub fn passes(&self, desc: &MachineDesc) -> Vec<Kernel> {
        let mut k = self.kernels_with(desc, SPLIT);
        k.remove(0);
        k
    }

    /// The names [`VertexProgram::passes`] are registered under.
    pub fn pass_names(&self) -> Vec<String> {
        (1..self.light_ranges(SPLIT).len())
            .map(|i| self.pass_name(i))
            .collect()
    }

    fn pass_name(&self, i: usize) -> String {
        format!("{}:pass{i}", self.name())
    }

    /// Words of the record a lit program's kernel hands the next pass: clip x, y, z, w,
    /// the colour so far r, g, b, the eye-space position, the unit normal and (with the
    /// specular term) the unit vector to the eye. 0 for unlit programs.
    pub fn partial_words(&self) -> usize {
        match self {
            VertexProgram::Lit {
                specular, extras, ..
            } => 13 + 3 * usize::from(*specular) + extras,
            // The vertex colour travels too, for the last kernel's choice.
            VertexProgram::General { .. } => 13 + 3 + 3,
            VertexProgram::Unlit { .. }
            | VertexProgram::Marble { .. }
            | VertexProgram::BumpEnv { .. } => 0,
        }
    }

    /// The lights each kernel of the program adds, `split.0` in the first kernel and
    /// `split.1` in each pass: one range (maybe empty) per kernel.
    fn light_ranges(&self, split: (usize, usize)) -> Vec<std::ops::Range<usize>> {
        let (first, per_pass) = (split.0.max(1), split.1.max(1));
        let lights = self.lighting().map_or(0, |(lights, _)| lights);
        let mut at = first.min(lights);
        let mut ranges: Vec<std::ops::Range<usize>> = Vec::new();
        ranges.push(0..at);
        while at < lights {
            ranges.push(at..(at + per_pass).min(lights));
            at += per_pass;
        }
        ranges
    }

    /// The program's kernels, the lights split as `split` (see
    /// [`VertexProgram::light_ranges`]): the first transforms the
    /// vertex and adds the first lights; each pass adds the next ones to the colour so far
    /// (the order of the sums is the one-kernel order: base, then light 0, 1, …); the last
    /// kernel clamps the colour and writes the shaded record. Every kernel declares the
    /// same parameters (the whole parameter stream) and reads them all.
    fn kernels_with(&self, desc: &MachineDesc, split: (usize, usize)) -> Vec<Kernel> {
        if let VertexProgram::Marble { extras } = *self {
            return vec![self.build_marble(extras)];
        }
        if let VertexProgram::BumpEnv { extras } = *self {
            return vec![bump_env::vertex_program(&self.name(), extras)];
        }
        let Some((_, specular)) = self.lighting() else {
            return vec![self.build_unlit()];
        };
        let shininess = self.shininess();
        let general = matches!(self, VertexProgram::General { .. });
        let extras = self.extras();
        let ranges = self.light_ranges(split);
        let count = ranges.len();
        ranges
            .into_iter()
            .enumerate()
            .map(|(i, lights)| {
                // Kernel names are identifiers: the pass is registered as `…:pass{i}`.
                let name = if i == 0 {
                    self.name()
                } else {
                    self.pass_name(i).replace(':', "_")
                };
                let mut b = KernelBuilder::new(&name);
                let input = b.input(if i == 0 { "vertices" } else { "partial" });
                let last = i + 1 == count;
                let output = b.output(match (last, i) {
                    (true, _) => "shaded",
                    (false, 0) => "partial",
                    (false, _) => "partial_out",
                });
                let p = self.lit_params(&mut b, desc);
                let (zero, one) = (b.f32(0.0), b.f32(1.0));
                b.begin_loop(LoopSpec::OverStream(input));
                let mut v = if i == 0 {
                    let position: Vec3 = std::array::from_fn(|_| b.read_f32(input));
                    let normal: Vec3 = std::array::from_fn(|_| b.read_f32(input));
                    let vertex_colour: Option<Vec3> =
                        general.then(|| std::array::from_fn(|_| b.read_f32(input)));
                    let mut v = transform_vertex(&mut b, &p, position, normal, specular, zero);
                    v.vertex_colour = vertex_colour;
                    v.extras = (0..extras).map(|_| b.read_f32(input)).collect();
                    v
                } else {
                    let mut w = || b.read_f32(input);
                    let clip = std::array::from_fn(|_| w());
                    let colour = std::array::from_fn(|_| w());
                    let eye_pos = std::array::from_fn(|_| w());
                    let unit_n = std::array::from_fn(|_| w());
                    let e = specular.then(|| std::array::from_fn(|_| w()));
                    let vertex_colour = general.then(|| std::array::from_fn(|_| w()));
                    let extras = (0..extras).map(|_| w()).collect();
                    LitVertex {
                        clip,
                        colour,
                        eye_pos,
                        unit_n,
                        e,
                        vertex_colour,
                        extras,
                    }
                };
                for l in lights {
                    v.colour = add_light(&mut b, &v, p.lights[l], shininess, zero, one);
                }
                for c in v.clip {
                    b.write(output, c);
                }
                if last {
                    // The general program chooses the lit colour or the vertex colour.
                    let lit = p.switch.map(|flag| {
                        let zero_i = b.i32(0);
                        b.ine(flag, zero_i)
                    });
                    for (ch, c) in v.colour.into_iter().enumerate() {
                        let above_zero = b.fmax(c, zero);
                        let clamped = b.fmin(above_zero, one);
                        let out = match (lit, v.vertex_colour) {
                            (Some(lit), Some(vc)) => b.select(lit, clamped, vc[ch]),
                            _ => clamped,
                        };
                        b.write(output, out);
                    }
                } else {
                    let rest = v.colour.into_iter().chain(v.eye_pos).chain(v.unit_n);
                    let rest = rest.chain(v.e.into_iter().flatten());
                    for c in rest.chain(v.vertex_colour.into_iter().flatten()) {
                        b.write(output, c);
                    }
                }
                for &x in &v.extras {
                    b.write(output, x);
                }
                b.end_loop();
                finish(b)
            })
            .collect()
    }

    /// A lit program's parameters, declared in stream order.
    fn lit_params(&self, b: &mut KernelBuilder, desc: &MachineDesc) -> LitParams {
        let (lights, specular) = self.lighting().expect("lit programs only");
        let mvp = matrix_params(b, "mvp");
        let mv: Vec<Value> = (0..12).map(|i| b.param_f32(&format!("mv{i}"))).collect();
        let normal: Vec<Value> = (0..9).map(|i| b.param_f32(&format!("normal{i}"))).collect();
        // The general program's switch between the lit and the vertex colour.
        let switch = matches!(self, VertexProgram::General { .. }).then(|| b.param("lit", Ty::I32));
        for i in self.perbegin_param_count()..self.perbegin_rows(desc) {
            b.param_f32(&format!("pad{i}"));
        }
        let (lights, base) = light_params(b, lights, specular);
        LitParams {
            mvp,
            mv,
            normal,
            switch,
            lights,
            base,
        }
    }

    fn build_unlit(&self) -> Kernel {
        let VertexProgram::Unlit {
            per_vertex_colour,
            extras,
        } = *self
        else {
            unreachable!("unlit programs only");
        };
        let mut b = KernelBuilder::new(&self.name());
        let vertices = b.input("vertices");
        let shaded = b.output("shaded");
        let mvp = matrix_params(&mut b, "mvp");
        let flat: Option<Vec3> = (!per_vertex_colour)
            .then(|| ["r", "g", "b"].map(|c| b.param_f32(&format!("colour_{c}"))));
        b.begin_loop(LoopSpec::OverStream(vertices));
        let position: Vec3 = std::array::from_fn(|_| b.read_f32(vertices));
        let colour: Vec3 = match flat {
            Some(c) => c,
            None => std::array::from_fn(|_| b.read_f32(vertices)),
        };
        let st: Vec<Value> = (0..extras).map(|_| b.read_f32(vertices)).collect();
        let clip = transform_point(&mut b, &mvp, position, None);
        for v in clip.into_iter().chain(colour).chain(st) {
            b.write(shaded, v);
        }
        b.end_loop();
        finish(b)
    }

    /// The marble program: the clip position, white, then the position and normal as they
    /// came and zeros up to `extras` words.
    fn build_marble(&self, extras: usize) -> Kernel {
        let mut b = KernelBuilder::new(&self.name());
        let vertices = b.input("vertices");
        let shaded = b.output("shaded");
        let mvp = matrix_params(&mut b, "mvp");
        let (zero, one) = (b.f32(0.0), b.f32(1.0));
        b.begin_loop(LoopSpec::OverStream(vertices));
        let position: Vec3 = std::array::from_fn(|_| b.read_f32(vertices));
        let normal: Vec3 = std::array::from_fn(|_| b.read_f32(vertices));
        let clip = transform_point(&mut b, &mvp, position, None);
        let passed = position.into_iter().chain(normal);
        let padding = std::iter::repeat_n(zero, extras.saturating_sub(6));
        for v in clip
            .into_iter()
            .chain([one; 3])
            .chain(passed)
            .chain(padding)
        {
            b.write(shaded, v);
        }
        b.end_loop();
        finish(b)
    }
}

/// Lights the first kernel of a lit program adds, and each pass after it. The first kernel
/// holds the matrices too: with 4 lights and the specular term its loop's values overflow
/// gold8's LRFs. A pass holds 5 (the divide/sqrt unit's bound, 32 cycles a specular light,
/// 16 a diffuse one, on gold1, gold8 and gold32), so that 8 lights take two kernels.
pub const SPLIT: (usize, usize) = (3, 5);

/// A light's parameters: eye-space position, `d_l·d_m` and (with the specular term)
/// `s_l·s_m`.
pub(crate) type LightParams = (Vec3, Vec3, Option<Vec3>);

/// Declares the parameters `perlight` writes, in its order: per light its [`LightParams`],
/// then `base`. The last parameters of every kernel that lights with them.
pub(crate) fn light_params(
    b: &mut KernelBuilder,
    lights: usize,
    specular: bool,
) -> (Vec<LightParams>, Vec3) {
    let rgb =
        |b: &mut KernelBuilder, p: &str| ["r", "g", "b"].map(|c| b.param_f32(&format!("{p}_{c}")));
    let lights = (0..lights)
        .map(|l| {
            let pos = ["x", "y", "z"].map(|c| b.param_f32(&format!("light{l}_{c}")));
            let d = rgb(b, &format!("light{l}_diffuse"));
            let s = specular.then(|| rgb(b, &format!("light{l}_specular")));
            (pos, d, s)
        })
        .collect();
    let base = rgb(b, "base");
    (lights, base)
}

/// A lit program's parameters.
struct LitParams {
    mvp: [Value; 16],
    mv: Vec<Value>,
    normal: Vec<Value>,
    /// The general program's lit switch.
    switch: Option<Value>,
    lights: Vec<LightParams>,
    base: Vec3,
}

/// A vertex being lit: what every light reads, and the colour so far.
pub(crate) struct LitVertex {
    pub clip: [Value; 4],
    pub colour: Vec3,
    pub eye_pos: Vec3,
    pub unit_n: Vec3,
    /// The unit vector to the eye (with the specular term).
    pub e: Option<Vec3>,
    /// The general program's vertex colour.
    pub vertex_colour: Option<Vec3>,
    /// Texture coordinates, passed through.
    pub extras: Vec<Value>,
}

/// The clip position, eye-space position, unit normal and (`specular`) unit vector to the
/// eye of a vertex, its colour the base colour.
fn transform_vertex(
    b: &mut KernelBuilder,
    p: &LitParams,
    position: Vec3,
    normal: Vec3,
    specular: bool,
    zero: Value,
) -> LitVertex {
    let clip = transform_point(b, &p.mvp, position, None);
    let eye_pos: Vec3 = {
        let mut m16 = [zero; 16];
        m16[..12].copy_from_slice(&p.mv);
        let e = transform_point(b, &m16, position, None);
        [e[0], e[1], e[2]]
    };
    let n_eye: Vec3 = std::array::from_fn(|row| {
        let r = &p.normal[3 * row..3 * row + 3];
        let x = b.fmul(r[0], normal[0]);
        let y = b.fmul(r[1], normal[1]);
        let s = b.fadd(x, y);
        let z = b.fmul(r[2], normal[2]);
        b.fadd(s, z)
    });
    let unit_n = normalize(b, n_eye);
    let to_eye = eye_pos.map(|c| b.fneg(c));
    let e = specular.then(|| normalize(b, to_eye));
    LitVertex {
        clip,
        colour: p.base,
        eye_pos,
        unit_n,
        e,
        vertex_colour: None,
        extras: Vec::new(),
    }
}

/// `v`'s colour plus light `(light_pos, dd, ss)`'s diffuse and specular terms, channel by
/// channel (diffuse first).
pub(crate) fn add_light(
    b: &mut KernelBuilder,
    v: &LitVertex,
    (light_pos, dd, ss): LightParams,
    shininess: u32,
    zero: Value,
    one: Value,
) -> Vec3 {
    let to_light: Vec3 = std::array::from_fn(|i| b.fsub(light_pos[i], v.eye_pos[i]));
    let l = normalize(b, to_light);
    let n_dot_l = dot(b, v.unit_n, l);
    let diffuse = b.fmax(n_dot_l, zero);
    let spec = match (v.e, ss) {
        (Some(e), Some(_)) => {
            let half: Vec3 = std::array::from_fn(|i| b.fadd(l[i], e[i]));
            let h = normalize(b, half);
            let n_dot_h = dot(b, v.unit_n, h);
            let x = b.fmax(n_dot_h, zero);
            let p = power(b, x, shininess, one);
            let lit = b.flt(zero, n_dot_l);
            Some(b.select(lit, p, zero))
        }
        _ => None,
    };
    let mut colour = v.colour;
    for ch in 0..3 {
        let d = b.fmul(diffuse, dd[ch]);
        colour[ch] = b.fadd(colour[ch], d);
        if let (Some(spec), Some(ss)) = (spec, ss) {
            let s = b.fmul(spec, ss[ch]);
            colour[ch] = b.fadd(colour[ch], s);
        }
    }
    colour
}

/// `x^n` by squaring (`x^0 = 1`, as OpenGL takes it).
fn power(b: &mut KernelBuilder, x: Value, n: u32, one: Value) -> Value {
    let mut result: Option<Value> = None;
    let mut square = x;
    let mut n = n;
    while n > 0 {
        if n & 1 == 1 {
            result = Some(match result {
                Some(r) => b.fmul(r, square),
                None => square,
            });
        }
        n >>= 1;
        if n > 0 {
            square = b.fmul(square, square);
        }
    }
    result.unwrap_or(one)
}

/// `a · b` of row-major 4×4 matrices, each entry summed left to right.
fn mat_mul(b: &mut KernelBuilder, a: &[Value], m: &[Value]) -> Vec<Value> {
    (0..16)
        .map(|k| {
            let (i, j) = (k / 4, k % 4);
            let mut sum = b.fmul(a[4 * i], m[j]);
            for t in 1..4 {
                let term = b.fmul(a[4 * i + t], m[4 * t + j]);
                sum = b.fadd(sum, term);
            }
            sum
        })
        .collect()
}

/// The inverse transpose of the upper 3×3 of `m` (row-major 4×4): its cofactors over its
/// determinant, row-major.
fn normal_matrix(b: &mut KernelBuilder, m: &[Value]) -> Vec<Value> {
    let a = |r: usize, c: usize| m[4 * r + c];
    let cofactor = |b: &mut KernelBuilder, r: usize, c: usize| {
        let (r1, r2) = ((r + 1) % 3, (r + 2) % 3);
        let (c1, c2) = ((c + 1) % 3, (c + 2) % 3);
        let p = b.fmul(a(r1, c1), a(r2, c2));
        let q = b.fmul(a(r1, c2), a(r2, c1));
        b.fsub(p, q)
    };
    let cof: Vec<Value> = (0..9).map(|k| cofactor(b, k / 3, k % 3)).collect();
    let d0 = b.fmul(a(0, 0), cof[0]);
    let d1 = b.fmul(a(0, 1), cof[1]);
    let d2 = b.fmul(a(0, 2), cof[2]);
    let s = b.fadd(d0, d1);
    let det = b.fadd(s, d2);
    let one = b.f32(1.0);
    let inv = b.fdiv(one, det);
    cof.into_iter().map(|c| b.fmul(c, inv)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::opengl::kernels::SHADED_WORDS;

    #[test]
    fn names_and_record_words_follow_the_material() {
        let lit = VertexProgram::Lit {
            lights: 3,
            specular: true,
            shininess: 16,
            extras: 0,
        };
        assert_eq!(lit.name(), "vertex_lit3_s16");
        assert_eq!(lit.record_words(), 6);
        let flat = VertexProgram::Unlit {
            per_vertex_colour: false,
            extras: 0,
        };
        assert_eq!(flat.record_words(), 3);
        let bump_env = VertexProgram::BumpEnv {
            extras: bump_env::EXTRAS,
        };
        assert_eq!(bump_env.name(), "vertex_bump_env");
        assert_eq!(bump_env.record_words(), bump_env::VERTEX_WORDS);
        let desc = MachineDesc::resolve("gold8").unwrap();
        assert_eq!(bump_env.param_count(&desc), bump_env::VERTEX_PARAMS);
        for p in [
            lit,
            flat,
            VertexProgram::Unlit {
                per_vertex_colour: true,
                extras: 0,
            },
            bump_env,
        ] {
            let k = p.build(&desc);
            let pb = p.perbegin(&desc);
            assert_eq!(k.name, p.name());
            assert_eq!(k.params.len(), p.param_count(&desc));
            assert!(!pb.streams.is_empty());
        }
    }

    /// Light counts a scene may have, with and without the specular term, compile on gold8,
    /// their kernels split into passes.
    #[test]
    fn every_light_count_compiles_on_gold8() {
        let desc = MachineDesc::resolve("gold8").unwrap();
        let mut kernels: Vec<Kernel> = Vec::new();
        // The one-kernel programs' largest, the split ones' smallest and largest: 0..=8 all
        // compile (a minute and a half of compiling).
        for lights in [0, 1, 3, 4, 8] {
            for specular in [false, true] {
                let p = VertexProgram::Lit {
                    lights,
                    specular,
                    shininess: 16,
                    extras: 0,
                };
                let passes = p.passes(&desc);
                assert_eq!(passes.len(), p.pass_names().len());
                let want = lights.saturating_sub(SPLIT.0).div_ceil(SPLIT.1);
                assert_eq!(passes.len(), want, "{}", p.name());
                kernels.push(p.build(&desc));
                kernels.extend(passes);
                for k in &kernels[kernels.len() - 1 - want..] {
                    assert_eq!(k.params.len(), p.param_count(&desc), "{}", k.name);
                }
            }
        }
        // Two at a time: each compile is a search of seconds.
        let next = std::sync::atomic::AtomicUsize::new(0);
        let mut done: Vec<(usize, Option<u32>)> = std::thread::scope(|scope| {
            let workers: Vec<_> = (0..2)
                .map(|_| {
                    scope.spawn(|| {
                        let mut mine = Vec::new();
                        loop {
                            let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                            let Some(k) = kernels.get(i) else { break };
                            let c =
                                crate::compile::compile(k, &desc).unwrap_or_else(|e| panic!("{e}"));
                            mine.push((i, c.report.ii));
                        }
                        mine
                    })
                })
                .collect();
            workers
                .into_iter()
                .flat_map(|w| w.join().expect("a compile panicked"))
                .collect()
        });
        done.sort_unstable();
        for (i, ii) in done {
            println!("{}: II {ii:?}", kernels[i].name);
        }
    }

    /// The lighting split into passes sums what one kernel sums, in the same order: the
    /// colours are bit-identical.
    #[test]
    fn passes_shade_as_one_kernel_does() {
        use crate::kernel::{KernelInputs, interpret};
        use imagine_units::arith::fp32::testgen::SplitMix64;
        let desc = MachineDesc::resolve("gold8").unwrap();
        let c = desc.cluster.count;
        let mut rng = SplitMix64::new(0x11_6475);
        let mut random = move || f32::from_bits(rng.next_u32() & 0xBFFF_FFFF) - 1.5;
        for specular in [false, true] {
            let p = VertexProgram::Lit {
                lights: 3,
                specular,
                shininess: 13,
                extras: 0,
            };
            // Matrices and light positions anywhere in (-3.5, 0.5); the colour products
            // in [0, 0.25), so that sums of a few stay below 1.
            let lights_from = p.perbegin_rows(&desc);
            let per_light = 6 + 3 * usize::from(specular);
            let params: Vec<u32> = (0..p.param_count(&desc))
                .map(|i| {
                    let x = random();
                    let light_word = i.checked_sub(lights_from).map(|j| j % per_light);
                    let base = i + 3 >= p.param_count(&desc);
                    let colour = base || light_word.is_some_and(|w| w >= 3);
                    if colour { x.abs() / 14.0 } else { x }.to_bits()
                })
                .collect();
            let vertices: Vec<u32> = (0..4 * c * 6).map(|_| random().to_bits()).collect();
            let run = |k: &Kernel, input: Vec<u32>| {
                let inputs = KernelInputs {
                    streams: vec![input, vec![]],
                    params: params.clone(),
                };
                interpret(k, &inputs, &desc).unwrap().swap_remove(1)
            };
            let whole = p.kernels_with(&desc, (3, 3));
            assert_eq!(whole.len(), 1);
            let want = run(&whole[0], vertices.clone());
            assert_eq!(want.len(), 4 * c * SHADED_WORDS);
            for (split, kernels) in [((2, 1), 2), ((1, 2), 2), ((1, 1), 3)] {
                let split_kernels = p.kernels_with(&desc, split);
                assert_eq!(split_kernels.len(), kernels);
                let mut words = vertices.clone();
                for k in &split_kernels {
                    words = run(k, words);
                }
                assert_eq!(words, want, "specular {specular}, split {split:?}");
            }
            // Some of the colours are neither clamped nor 0: the test sees the sums.
            let lit = want
                .chunks(SHADED_WORDS)
                .filter(|r| {
                    r[4..]
                        .iter()
                        .any(|&w| f32::from_bits(w) > 0.0 && f32::from_bits(w) < 1.0)
                })
                .count();
            assert!(lit > 0, "specular {specular}: every colour clamped");
        }
    }
}
