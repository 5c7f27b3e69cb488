//! `bump_env`: VERONA's shader (Owens 2002, Table 5.1 and §5.1.1: "vertex texture, bump
//! map, dependent environment-map read") as kernels, split at its texture lookups as the
//! thesis splits RTSL programs (§4.2, §4.4.4): kernels never address memory, so all the work
//! feeding the lookups of one dependence depth is one kernel that emits an address stream,
//! and the memory system gathers the texels, each written over its address in the SRF.
//! The shader's maps are a *combined displacement/bump map* of 4-word f32 texels
//! `[nx, ny, nz, h]` ([`crate::scene::bump_map`]) and an RGBA8 environment (sphere) map.
//!
//! **Vertex program** (a vertex texture: "the vertex program is split at the lookup"):
//! [`vertex_texel_address`] (`vtexaddr`) computes each vertex's texel of the combined map
//! (nearest at its (s, t), wrap repeat) and emits its 4 word addresses; the 4 words are
//! gathered; [`vertex_program`] displaces the object-space position along the normal,
//! `P' = P + displacement·h·N`, bumps the normal, `N' = nx·T + ny·B + nz·N` with
//! `B = N × T` (the mesh's unit normal and tangent), and writes the clip position `MVP·P'`,
//! the object's colour, s, t, the eye-space position `MV·P'`, normal
//! `normalize(Nmat·N')` (`Nmat` the inverse transpose of MV's 3 × 3) and tangent
//! `normalize(MV₃·T)`.
//!
//! **Fragment program** (a dependent read: 3 kernels, 2 gathers):
//! * depth 2, [`bump_address`] (`bumpaddr`): the combined map's texel at the interpolated
//!   (s, t) (nearest, repeat); the addresses of its 3 normal words;
//! * depth 1, [`environment_address`] (`envaddr`): `N̂ = normalize(N)`, `B = N̂ × T`, the
//!   bumped normal `N'' = normalize(nx·T + ny·B + nz·N̂)` from the interpolated frame,
//!   the unit view direction `V = normalize(P_eye)`, its reflection
//!   `R = V − 2(N''·V)·N''`, OpenGL's sphere-map coordinates
//!   `m = 2·sqrt(Rx² + Ry² + (Rz + 1)²)`, `s = Rx/m + ½`, `t = Ry/m + ½`
//!   (`GL_SPHERE_MAP`), and the environment texel's address (nearest, the texture's wrap);
//! * depth 0, [`shade`] (`envshade`, registered in a frame as `fragment:…`): the environment texel modulated by the interpolated
//!   vertex colour (the object's `colour`, white by default), packed RGBA8 as the texture
//!   `fragment` kernel packs.
//!
//! Per fragment 3 + 1 texel words are fetched (16 bytes), per vertex 4 (16 bytes).
//! `normalize(v)` is `v · (1 / sqrt(v·v))` (one `fsqrt`, one `fdiv`), except in `envaddr`
//! for `V` and `1/m`, which take the reciprocal square root by the bit-level guess and
//! three Newton steps ([`super::turbulence`]'s) on the multipliers, so that the loop is not
//! bound by the divide/sqrt unit; dot products sum left to right, cross products are
//! `(a₁b₂ − a₂b₁, a₂b₀ − a₀b₂, a₀b₁ − a₁b₀)`.
//!
//! **Fragment records** (`varyings`, as `irast` writes them): r, g, b, then s, t, the
//! eye-space position (3), normal (3) and tangent (3): [`EXTRAS`] words after the colour.

use imagine_units::arith::fp32::testgen::SplitMix64;
use imagine_units::desc::MachineDesc;

use super::texture::{Unit, nearest_address, pack, unpack};
use super::transform::{matrix_params, transform_point};
use super::turbulence::reciprocal_sqrt;
use super::vertex::normalize;
use super::{Vec3, dot, records_to_stream, uniform, uniform_words};
use crate::kernel::{
    Kernel, KernelBuilder, KernelInputs, LoopSpec, MachineRequirementError, Value,
};
use crate::scene::bump_map::TEXEL_WORDS;
use crate::scene::model::{Filter, Wrap};

/// Interpolated words after the colour: s, t, eye-space position, normal, tangent.
pub const EXTRAS: usize = 11;

/// Words of a vertex record: position, normal, tangent (object space), s, t.
pub const VERTEX_WORDS: usize = 11;

/// Normal words of the combined map a fragment fetches.
pub const FRAGMENT_BUMP_WORDS: usize = 3;

/// Parameters of the vertex program: MVP (16), MV's first three rows (12), the normal
/// matrix (9), the object's colour (3) and the displacement (1).
pub const VERTEX_PARAMS: usize = 16 + 12 + 9 + 3 + 1;

/// Where a `bump_env` material's maps lie in the texture buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Maps {
    /// The combined map's first word and side in texels.
    pub bump_base: u32,
    pub bump_size: u32,
    /// The environment map (point-sampled).
    pub environment: Unit,
}

impl Maps {
    /// A name unique to the maps.
    pub fn name(&self) -> String {
        let e = &self.environment;
        let wrap = match e.wrap {
            Wrap::Repeat => 'r',
            Wrap::Clamp => 'c',
        };
        format!(
            "b{}at{}_e{wrap}{}x{}at{}",
            self.bump_size, self.bump_base, e.width, e.height, e.base
        )
    }

    /// The name of the vertex texture's address kernel (one per combined map).
    pub fn vertex_kernel_name(&self) -> String {
        format!("vtexaddr:b{}at{}", self.bump_size, self.bump_base)
    }

    /// The first of the 4 words of the combined map's texel holding `(s, t)` (nearest,
    /// repeat): `base + 4·(j·size + i)`.
    fn bump_texel(&self, b: &mut KernelBuilder, s: Value, t: Value) -> Value {
        let grid = Unit {
            filter: Filter::Nearest,
            wrap: Wrap::Repeat,
            width: self.bump_size,
            height: self.bump_size,
            base: 0,
        };
        let texel = nearest_address(b, &grid, s, t);
        let words = b.i32(TEXEL_WORDS as i32);
        let offset = b.imul(texel, words);
        let base = b.i32(self.bump_base as i32);
        b.iadd(base, offset)
    }
}

/// `a × b`.
fn cross(b: &mut KernelBuilder, u: Vec3, v: Vec3) -> Vec3 {
    std::array::from_fn(|i| {
        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
        let p = b.fmul(u[j], v[k]);
        let q = b.fmul(u[k], v[j]);
        b.fsub(p, q)
    })
}

/// `x·T + y·B + z·N`, summed left to right.
fn in_frame(b: &mut KernelBuilder, [x, y, z]: Vec3, t: Vec3, bn: Vec3, n: Vec3) -> Vec3 {
    std::array::from_fn(|i| {
        let a = b.fmul(x, t[i]);
        let c = b.fmul(y, bn[i]);
        let sum = b.fadd(a, c);
        let d = b.fmul(z, n[i]);
        b.fadd(sum, d)
    })
}

/// `vtexaddr`: per vertex record ([`VERTEX_WORDS`]), the 4 word addresses of its texel of
/// the combined map.
pub fn vertex_texel_address(maps: &Maps) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("vtexaddr");
    let vertices = b.input("vertices");
    let addr = b.output("addr");
    let one = b.i32(1);
    b.begin_loop(LoopSpec::OverStream(vertices));
    let v: Vec<Value> = (0..VERTEX_WORDS).map(|_| b.read_f32(vertices)).collect();
    let mut a = maps.bump_texel(&mut b, v[9], v[10]);
    for k in 0..TEXEL_WORDS {
        if k > 0 {
            a = b.iadd(a, one);
        }
        b.write(addr, a);
    }
    b.end_loop();
    Ok(super::finish(b))
}

/// The vertex program (named `name`): vertex records and their 4 gathered texel words in,
/// shaded records out — clip x, y, z, w, r, g, b, then s, t, the eye-space position, normal
/// and tangent, then zeros up to `extras` words (see the module notes).
pub fn vertex_program(name: &str, extras: usize) -> Kernel {
    assert!(extras >= EXTRAS, "s, t, position, normal and tangent");
    let mut b = KernelBuilder::new(name);
    let vertices = b.input("vertices");
    let texels = b.input("texels");
    let shaded = b.output("shaded");
    let mvp = matrix_params(&mut b, "mvp");
    let mv: Vec<Value> = (0..12).map(|i| b.param_f32(&format!("mv{i}"))).collect();
    let normal_matrix: Vec<Value> = (0..9).map(|i| b.param_f32(&format!("normal{i}"))).collect();
    let colour: Vec3 = ["r", "g", "b"].map(|c| b.param_f32(&format!("colour_{c}")));
    let displacement = b.param_f32("displacement");
    let zero = b.f32(0.0);
    b.begin_loop(LoopSpec::OverStream(vertices));
    let position: Vec3 = std::array::from_fn(|_| b.read_f32(vertices));
    let normal: Vec3 = std::array::from_fn(|_| b.read_f32(vertices));
    let tangent: Vec3 = std::array::from_fn(|_| b.read_f32(vertices));
    let st: [Value; 2] = std::array::from_fn(|_| b.read_f32(vertices));
    let texel: [Value; 4] = std::array::from_fn(|_| b.read_f32(texels));
    let lift = b.fmul(displacement, texel[3]);
    let displaced: Vec3 = std::array::from_fn(|i| b.fmadd(lift, normal[i], position[i]));
    let binormal = cross(&mut b, normal, tangent);
    let bumped = in_frame(
        &mut b,
        [texel[0], texel[1], texel[2]],
        tangent,
        binormal,
        normal,
    );
    let clip = transform_point(&mut b, &mvp, displaced, None);
    let mut affine = [zero; 16];
    affine[..12].copy_from_slice(&mv);
    let eye = transform_point(&mut b, &affine, displaced, None);
    let times3 = |b: &mut KernelBuilder, m: &[Value], v: Vec3, stride: usize| -> Vec3 {
        std::array::from_fn(|row| {
            let r = &m[stride * row..stride * row + 3];
            dot(b, [r[0], r[1], r[2]], v)
        })
    };
    let eye_normal = times3(&mut b, &normal_matrix, bumped, 3);
    let eye_normal = normalize(&mut b, eye_normal);
    let eye_tangent = times3(&mut b, &mv, tangent, 4);
    let eye_tangent = normalize(&mut b, eye_tangent);
    let words = clip
        .into_iter()
        .chain(colour)
        .chain(st)
        .chain(eye[..3].iter().copied())
        .chain(eye_normal)
        .chain(eye_tangent)
        .chain(std::iter::repeat_n(zero, extras - EXTRAS));
    for w in words {
        b.write(shaded, w);
    }
    b.end_loop();
    super::finish(b)
}

/// Depth 2, `bumpaddr`: per fragment (`varyings` of `fragment_words` words), the addresses
/// of the 3 normal words of its combined-map texel.
pub fn bump_address(maps: &Maps, fragment_words: usize) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("bumpaddr");
    let varyings = b.input("varyings");
    let addr = b.output("addr");
    let one = b.i32(1);
    b.begin_loop(LoopSpec::OverStream(varyings));
    let v: Vec<Value> = (0..fragment_words).map(|_| b.read_f32(varyings)).collect();
    let mut a = maps.bump_texel(&mut b, v[3], v[4]);
    for k in 0..FRAGMENT_BUMP_WORDS {
        if k > 0 {
            a = b.iadd(a, one);
        }
        b.write(addr, a);
    }
    b.end_loop();
    Ok(super::finish(b))
}

/// Depth 1, `envaddr`: per fragment (`varyings`, and the 3 normal words on `texels`), the
/// address of its environment texel (see the module notes).
pub fn environment_address(
    maps: &Maps,
    fragment_words: usize,
) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("envaddr");
    let varyings = b.input("varyings");
    let texels = b.input("texels");
    let addr = b.output("addr");
    let (half, one, two) = (b.f32(0.5), b.f32(1.0), b.f32(2.0));
    b.begin_loop(LoopSpec::OverStream(varyings));
    let v: Vec<Value> = (0..fragment_words).map(|_| b.read_f32(varyings)).collect();
    let bump: Vec3 = std::array::from_fn(|_| b.read_f32(texels));
    let position: Vec3 = [v[5], v[6], v[7]];
    let normal: Vec3 = [v[8], v[9], v[10]];
    let tangent: Vec3 = [v[11], v[12], v[13]];
    let n = normalize(&mut b, normal);
    let binormal = cross(&mut b, n, tangent);
    let bumped = in_frame(&mut b, bump, tangent, binormal, n);
    let bumped = normalize(&mut b, bumped);
    // The view direction and the sphere map's 1/m by Newton's reciprocal square root, on
    // the multipliers: with all four on the divide/sqrt unit the loop waits for it.
    let view = {
        let length_squared = dot(&mut b, position, position);
        let y = reciprocal_sqrt(&mut b, length_squared);
        position.map(|c| b.fmul(c, y))
    };
    let d = dot(&mut b, bumped, view);
    let twice = b.fmul(d, two);
    let r: Vec3 = std::array::from_fn(|i| {
        let along = b.fmul(twice, bumped[i]);
        b.fsub(view[i], along)
    });
    let z1 = b.fadd(r[2], one);
    let m2 = dot(&mut b, [r[0], r[1], z1], [r[0], r[1], z1]);
    let inverse = reciprocal_sqrt(&mut b, m2);
    let inverse = b.fmul(inverse, half);
    let es = b.fmadd(r[0], inverse, half);
    let et = b.fmadd(r[1], inverse, half);
    let a = nearest_address(&mut b, &maps.environment, es, et);
    b.write(addr, a);
    b.end_loop();
    Ok(super::finish(b))
}

/// Depth 0, `envshade`: the environment texel (`texels`) times the interpolated colour
/// (`varyings`' r, g, b; alpha the texel's), packed RGBA8 to `colour`.
pub fn shade(fragment_words: usize) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("envshade");
    let varyings = b.input("varyings");
    let texels = b.input("texels");
    let colour_out = b.output("colour");
    b.begin_loop(LoopSpec::OverStream(varyings));
    let v: Vec<Value> = (0..fragment_words).map(|_| b.read_f32(varyings)).collect();
    let word = b.read(texels);
    let texel = unpack(&mut b, word);
    let rgba = [
        b.fmul(v[0], texel[0]),
        b.fmul(v[1], texel[1]),
        b.fmul(v[2], texel[2]),
        texel[3],
    ];
    let packed = pack(&mut b, rgba);
    b.write(colour_out, packed);
    b.end_loop();
    Ok(super::finish(b))
}

/// The library's example maps: a 64 × 64 combined map at word 0, a 32 × 32 environment
/// (clamp) after it.
fn example() -> Maps {
    Maps {
        bump_base: 0,
        bump_size: 64,
        environment: Unit {
            filter: Filter::Nearest,
            wrap: Wrap::Clamp,
            width: 32,
            height: 32,
            base: 4 * 64 * 64,
        },
    }
}

/// Words of the example's fragment records: r, g, b and the extras.
const EXAMPLE_WORDS: usize = 3 + EXTRAS;

/// `vtexaddr` for the example maps.
pub fn vtexaddr_example(_desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    vertex_texel_address(&example())
}

/// The vertex program for a frame of `bump_env` alone.
pub fn vertex_example(_desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    Ok(vertex_program("vertex_bump_env", EXTRAS))
}

/// `bumpaddr` for the example maps.
pub fn bumpaddr_example(_desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    bump_address(&example(), EXAMPLE_WORDS)
}

/// `envaddr` for the example maps.
pub fn envaddr_example(_desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    environment_address(&example(), EXAMPLE_WORDS)
}

/// `fragment` for a frame of `bump_env` alone.
pub fn shade_example(_desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    shade(EXAMPLE_WORDS)
}

/// A random vector of length 0.5 to 2.
fn vector(rng: &mut SplitMix64) -> Vec<u32> {
    loop {
        let v: [f32; 3] = std::array::from_fn(|_| uniform(rng, -1.0, 1.0));
        let length = v.iter().map(|c| c * c).sum::<f32>().sqrt();
        if length > 0.25 {
            let scale = uniform(rng, 0.5, 2.0) / length;
            return v.iter().map(|c| (c * scale).to_bits()).collect();
        }
    }
}

/// Fragment records: colour in [0, 1), (s, t) in [−3, 3) (the wrap reached), an eye-space
/// position in front of the eye, a normal and a tangent.
fn varyings(rng: &mut SplitMix64, n: usize) -> Vec<Vec<u32>> {
    (0..n)
        .map(|_| {
            let mut r = uniform_words(rng, 3, 0.0, 1.0);
            r.extend(uniform_words(rng, 2, -3.0, 3.0));
            r.extend(uniform_words(rng, 2, -2.0, 2.0));
            r.push(uniform(rng, -8.0, -1.0).to_bits());
            r.extend(vector(rng));
            r.extend(vector(rng));
            r
        })
        .collect()
}

/// Random unit-ish normals (z > 0) as the combined map's normal words.
fn bump_normals(rng: &mut SplitMix64, n: usize, words: usize) -> Vec<Vec<u32>> {
    (0..n)
        .map(|_| {
            let mut r = uniform_words(rng, 2, -0.6, 0.6);
            r.push(uniform(rng, 0.6, 1.0).to_bits());
            r.extend(uniform_words(rng, words - 3, 0.0, 1.0));
            r
        })
        .collect()
}

/// Random vertex records: a position, a normal and a tangent, (s, t) in [−3, 3).
fn vertex_records(rng: &mut SplitMix64, n: usize) -> Vec<Vec<u32>> {
    (0..n)
        .map(|_| {
            let mut r = uniform_words(rng, 3, -2.0, 2.0);
            r.extend(vector(rng));
            r.extend(vector(rng));
            r.extend(uniform_words(rng, 2, -3.0, 3.0));
            r
        })
        .collect()
}

/// Random inputs for `vtexaddr`.
pub fn vtexaddr_inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let c = desc.cluster.count;
    let mut rng = SplitMix64::new(seed);
    KernelInputs {
        streams: vec![
            records_to_stream(&vertex_records(&mut rng, rows * c), c),
            Vec::new(),
        ],
        params: Vec::new(),
    }
}

/// Random inputs for the vertex program: records, texels and parameters (matrices in
/// (−1, 1), the colour in [0, 1), a displacement in [0, 0.2)).
pub fn vertex_inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let c = desc.cluster.count;
    let n = rows * c;
    let mut rng = SplitMix64::new(seed);
    let records = vertex_records(&mut rng, n);
    let texels = bump_normals(&mut rng, n, TEXEL_WORDS);
    let mut params = uniform_words(&mut rng, 16 + 12 + 9, -1.0, 1.0);
    params.extend(uniform_words(&mut rng, 3, 0.0, 1.0));
    params.push(uniform(&mut rng, 0.0, 0.2).to_bits());
    KernelInputs {
        streams: vec![
            records_to_stream(&records, c),
            records_to_stream(&texels, c),
            Vec::new(),
        ],
        params,
    }
}

/// Random inputs for `bumpaddr`.
pub fn bumpaddr_inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let c = desc.cluster.count;
    let mut rng = SplitMix64::new(seed);
    KernelInputs {
        streams: vec![
            records_to_stream(&varyings(&mut rng, rows * c), c),
            Vec::new(),
        ],
        params: Vec::new(),
    }
}

/// Random inputs for `envaddr`: fragments and normal words.
pub fn envaddr_inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let c = desc.cluster.count;
    let n = rows * c;
    let mut rng = SplitMix64::new(seed);
    let fragments = varyings(&mut rng, n);
    let normals = bump_normals(&mut rng, n, FRAGMENT_BUMP_WORDS);
    KernelInputs {
        streams: vec![
            records_to_stream(&fragments, c),
            records_to_stream(&normals, c),
            Vec::new(),
        ],
        params: Vec::new(),
    }
}

/// Random inputs for the depth-0 kernel: fragments and RGBA8 texels.
pub fn shade_inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let c = desc.cluster.count;
    let n = rows * c;
    let mut rng = SplitMix64::new(seed);
    let fragments = varyings(&mut rng, n);
    let texels: Vec<Vec<u32>> = (0..n).map(|_| vec![rng.next_u32()]).collect();
    KernelInputs {
        streams: vec![
            records_to_stream(&fragments, c),
            records_to_stream(&texels, c),
            Vec::new(),
        ],
        params: Vec::new(),
    }
}
