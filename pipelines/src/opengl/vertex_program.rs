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
//! `H = normalize(L + E)`. The program is built for its material: one pass per light, the
//! specular term only when the material and a light have one, and the exponent `s` (an
//! integer 0..=128) as squarings and multiplies. Every `normalize(v)` is
//! `v · (1 / sqrt(v·v))` (one `fsqrt`, one `fdiv`), dot products sum left to right.
//!
//! Output records: clip x, y, z, w, then r, g, b — what `assemble_clip` reads.

use imagine_units::desc::MachineDesc;

use super::kernels::finish;
use crate::kernel::{Kernel, KernelBuilder, LoopSpec, Perm, Ty, Value};
use crate::kernels::transform::{matrix_params, transform_point};
use crate::kernels::vertex::normalize;
use crate::kernels::{Vec3, dot};
use crate::scene::model::{Material, Mesh, Object, Scene, Shader};

/// Words of a shaded vertex.
pub const SHADED_WORDS: usize = 7;

/// What a vertex program is built for.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum VertexProgram {
    /// Unlit; `per_vertex_colour`: vertices carry their colour (else it is a parameter).
    Unlit { per_vertex_colour: bool },
    /// Lit by `lights` lights with the specular term (when `specular`) to an integer
    /// power `shininess`.
    Lit {
        lights: usize,
        specular: bool,
        shininess: u32,
    },
    /// The general fixed-function program (`--no-specialize`): every vertex carries its
    /// position, normal and colour; lighting by `lights` lights with the specular term is
    /// always computed, and a parameter chooses it or the vertex colour (only the exponent
    /// is built in: the material's).
    General { lights: usize, shininess: u32 },
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
        if general {
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
            }),
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
                })
            }
        }
    }

    /// The name it is registered and reported under.
    pub fn name(&self) -> String {
        match self {
            VertexProgram::Unlit {
                per_vertex_colour: true,
            } => "vertex_unlit".into(),
            VertexProgram::Unlit {
                per_vertex_colour: false,
            } => "vertex_unlit_flat".into(),
            VertexProgram::Lit {
                lights,
                specular,
                shininess,
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
        }
    }

    /// Whether it lights vertices (and so has `perlight` and the lit parameters).
    pub fn lit(&self) -> bool {
        !matches!(self, VertexProgram::Unlit { .. })
    }

    /// Lights it is built for, and whether with the specular term.
    pub fn lighting(&self) -> Option<(usize, bool)> {
        match self {
            VertexProgram::Unlit { .. } => None,
            VertexProgram::Lit {
                lights, specular, ..
            } => Some((*lights, *specular)),
            VertexProgram::General { lights, .. } => Some((*lights, true)),
        }
    }

    /// Words of a vertex record in memory.
    pub fn record_words(&self) -> usize {
        match self {
            VertexProgram::Unlit {
                per_vertex_colour: false,
            } => 3,
            VertexProgram::General { .. } => 9,
            _ => 6,
        }
    }

    /// Interpolated words per fragment the program's outputs feed (colour).
    pub fn interpolants(&self) -> Vec<&'static str> {
        vec!["r", "g", "b"]
    }

    /// Vertex `v` of `object`'s mesh as the program reads it.
    pub fn vertex_words(&self, object: &Object, v: usize, out: &mut Vec<u32>) {
        let mesh: &Mesh = &object.mesh;
        out.extend(mesh.positions[v].map(f32::to_bits));
        match self {
            VertexProgram::Unlit {
                per_vertex_colour: true,
            } => {
                let c = mesh.colours.get(v).copied().unwrap_or(object.colour);
                out.extend(c.map(f32::to_bits));
            }
            VertexProgram::Unlit {
                per_vertex_colour: false,
            } => {}
            VertexProgram::Lit { .. } => out.extend(mesh.normals[v].map(f32::to_bits)),
            VertexProgram::General { .. } => {
                let n = mesh.normals.get(v).copied().unwrap_or([0.0; 3]);
                let c = mesh.colours.get(v).copied().unwrap_or(object.colour);
                out.extend(n.into_iter().chain(c).map(f32::to_bits));
            }
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
        if let VertexProgram::Unlit {
            per_vertex_colour: false,
        } = self
        {
            w.extend(object.colour);
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
        let rows_general: Vec<Value> = state[48..].to_vec();
        let modelview = mat_mul(&mut b, view, model);
        let mvp = mat_mul(&mut b, projection, &modelview);
        for &v in &mvp {
            b.write(params_out, v);
        }
        match self {
            VertexProgram::Unlit {
                per_vertex_colour: true,
            } => {}
            VertexProgram::Unlit {
                per_vertex_colour: false,
            } => {
                for &v in &state[48..51] {
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
                    // The lit flag, passed through.
                    b.write(params_out, rows_general[0]);
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
        let (c, block) = (desc.cluster.count, desc.srf.block_words.max(1));
        let gcd = |mut a: usize, mut b: usize| {
            while b != 0 {
                (a, b) = (b, a % b);
            }
            a
        };
        own.next_multiple_of(block / gcd(c, block))
    }

    /// The parameters `perbegin` computes (`perlight` writes the rest).
    fn perbegin_param_count(&self) -> usize {
        16 + match self {
            VertexProgram::Unlit {
                per_vertex_colour: true,
            } => 0,
            VertexProgram::Unlit {
                per_vertex_colour: false,
            } => 3,
            VertexProgram::Lit { .. } => 12 + 9,
            VertexProgram::General { .. } => 12 + 9 + 1,
        }
    }

    fn state_words_len(&self) -> usize {
        48 + match self {
            VertexProgram::Unlit {
                per_vertex_colour: false,
            } => 3,
            VertexProgram::General { .. } => 1,
            _ => 0,
        }
    }

    /// The vertex program.
    pub fn build(&self, desc: &MachineDesc) -> Kernel {
        let mut b = KernelBuilder::new(&self.name());
        let vertices = b.input("vertices");
        let shaded = b.output("shaded");
        let mvp = matrix_params(&mut b, "mvp");
        match self {
            VertexProgram::Unlit { per_vertex_colour } => {
                let flat: Option<Vec3> = (!per_vertex_colour)
                    .then(|| ["r", "g", "b"].map(|c| b.param_f32(&format!("colour_{c}"))));
                b.begin_loop(LoopSpec::OverStream(vertices));
                let position: Vec3 = std::array::from_fn(|_| b.read_f32(vertices));
                let colour: Vec3 = match flat {
                    Some(c) => c,
                    None => std::array::from_fn(|_| b.read_f32(vertices)),
                };
                let clip = transform_point(&mut b, &mvp, position, None);
                for v in clip.into_iter().chain(colour) {
                    b.write(shaded, v);
                }
                b.end_loop();
            }
            VertexProgram::Lit { .. } | VertexProgram::General { .. } => {
                let (lights, specular) = self.lighting().expect("lit");
                let shininess = match self {
                    VertexProgram::Lit { shininess, .. }
                    | VertexProgram::General { shininess, .. } => *shininess,
                    VertexProgram::Unlit { .. } => 0,
                };
                let (lights, specular) = (&lights, &specular);
                let general = matches!(self, VertexProgram::General { .. });
                let mv: Vec<Value> = (0..12).map(|i| b.param_f32(&format!("mv{i}"))).collect();
                let n: Vec<Value> = (0..9).map(|i| b.param_f32(&format!("normal{i}"))).collect();
                // The general program's switch between lit and vertex colours.
                let switch = general.then(|| b.param("lit", Ty::I32));
                for i in self.perbegin_param_count()..self.perbegin_rows(desc) {
                    b.param_f32(&format!("pad{i}"));
                }
                let rgb = |b: &mut KernelBuilder, p: &str| {
                    ["r", "g", "b"].map(|c| b.param_f32(&format!("{p}_{c}")))
                };
                let light_params: Vec<(Vec3, Vec3, Option<Vec3>)> = (0..*lights)
                    .map(|l| {
                        let pos = ["x", "y", "z"].map(|c| b.param_f32(&format!("light{l}_{c}")));
                        let d = rgb(&mut b, &format!("light{l}_diffuse"));
                        let s = specular.then(|| rgb(&mut b, &format!("light{l}_specular")));
                        (pos, d, s)
                    })
                    .collect();
                let base = rgb(&mut b, "base");
                let (zero, one) = (b.f32(0.0), b.f32(1.0));
                b.begin_loop(LoopSpec::OverStream(vertices));
                let position: Vec3 = std::array::from_fn(|_| b.read_f32(vertices));
                let normal: Vec3 = std::array::from_fn(|_| b.read_f32(vertices));
                let vertex_colour: Option<Vec3> =
                    general.then(|| std::array::from_fn(|_| b.read_f32(vertices)));
                let clip = transform_point(&mut b, &mvp, position, None);
                let eye_pos: Vec3 = {
                    let mut m16 = [zero; 16];
                    m16[..12].copy_from_slice(&mv);
                    let p = transform_point(&mut b, &m16, position, None);
                    [p[0], p[1], p[2]]
                };
                let n_eye: Vec3 = std::array::from_fn(|row| {
                    let r = &n[3 * row..3 * row + 3];
                    let x = b.fmul(r[0], normal[0]);
                    let y = b.fmul(r[1], normal[1]);
                    let s = b.fadd(x, y);
                    let z = b.fmul(r[2], normal[2]);
                    b.fadd(s, z)
                });
                let unit_n = normalize(&mut b, n_eye);
                let to_eye = eye_pos.map(|c| b.fneg(c));
                let e = specular.then(|| normalize(&mut b, to_eye));
                let mut colour = base;
                for &(light_pos, dd, ss) in &light_params {
                    let to_light: Vec3 = std::array::from_fn(|i| b.fsub(light_pos[i], eye_pos[i]));
                    let l = normalize(&mut b, to_light);
                    let n_dot_l = dot(&mut b, unit_n, l);
                    let diffuse = b.fmax(n_dot_l, zero);
                    let spec = match (e, ss) {
                        (Some(e), Some(_)) => {
                            let half: Vec3 = std::array::from_fn(|i| b.fadd(l[i], e[i]));
                            let h = normalize(&mut b, half);
                            let n_dot_h = dot(&mut b, unit_n, h);
                            let x = b.fmax(n_dot_h, zero);
                            let p = power(&mut b, x, shininess, one);
                            let lit = b.flt(zero, n_dot_l);
                            Some(b.select(lit, p, zero))
                        }
                        _ => None,
                    };
                    for ch in 0..3 {
                        let d = b.fmul(diffuse, dd[ch]);
                        colour[ch] = b.fadd(colour[ch], d);
                        if let (Some(spec), Some(ss)) = (spec, ss) {
                            let s = b.fmul(spec, ss[ch]);
                            colour[ch] = b.fadd(colour[ch], s);
                        }
                    }
                }
                for v in clip {
                    b.write(shaded, v);
                }
                let lit = switch.map(|flag| {
                    let zero_i = b.i32(0);
                    b.ine(flag, zero_i)
                });
                for (ch, c) in colour.into_iter().enumerate() {
                    let above_zero = b.fmax(c, zero);
                    let clamped = b.fmin(above_zero, one);
                    let out = match (lit, vertex_colour) {
                        (Some(lit), Some(v)) => b.select(lit, clamped, v[ch]),
                        _ => clamped,
                    };
                    b.write(shaded, out);
                }
                b.end_loop();
            }
        }
        finish(b)
    }
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

    #[test]
    fn names_and_record_words_follow_the_material() {
        let lit = VertexProgram::Lit {
            lights: 3,
            specular: true,
            shininess: 16,
        };
        assert_eq!(lit.name(), "vertex_lit3_s16");
        assert_eq!(lit.record_words(), 6);
        let flat = VertexProgram::Unlit {
            per_vertex_colour: false,
        };
        assert_eq!(flat.record_words(), 3);
        let desc = MachineDesc::resolve("gold8").unwrap();
        for p in [
            lit,
            flat,
            VertexProgram::Unlit {
                per_vertex_colour: true,
            },
        ] {
            let k = p.build(&desc);
            let pb = p.perbegin(&desc);
            assert_eq!(k.name, p.name());
            assert_eq!(k.params.len(), p.param_count(&desc));
            assert!(!pb.streams.is_empty());
        }
    }
}
