//! `vertex`: the vertex program of the SPHERE scene — a clip-space transform and per-vertex
//! lighting by three positional lights (Owens et al., "Polygon Rendering on a Stream
//! Architecture", Graphics Hardware 2000; the lighting model is OpenGL's, with Blinn's
//! half-vector specular term: Blinn, "Models of Light Reflection for Computer Synthesized
//! Pictures", SIGGRAPH 1977).
//!
//! Input `vertices`: records (x, y, z, nx, ny, nz), six words per element: a position and a
//! normal, not necessarily unit length. Parameters, in order: the model-view-projection
//! matrix `mvp0..mvp15` (row-major); the eye position `eye_x, eye_y, eye_z`; for each light
//! `l` of 0..3 its position `light{l}_x, _y, _z` and colour `light{l}_r, _g, _b`; the
//! material's diffuse, specular and ambient colours (`diffuse_r, _g, _b`, `specular_*`,
//! `ambient_*`). Lighting is computed in the space of the input positions (the eye and
//! lights are given in that space).
//!
//! Output `shaded`: records (x, y, z, w, r, g, b), seven words per element:
//!
//! * clip position `mvp · (x, y, z, 1)` (row `i`: `((m_i0·x + m_i1·y) + m_i2·z) + m_i3`);
//! * colour `clamp(ambient + Σ_l light_l ⊙ (diffuse·max(N·L, 0) + specular·max(N·H, 0)^16),
//!   0, 1)` per channel, where `N` is the unit normal, `V = normalize(eye − p)`,
//!   `L = normalize(light_l − p)` and `H = normalize(L + V)`. The specular exponent is fixed
//!   at 16: four squarings.
//!
//! Every `normalize(v)` is `v · (1 / sqrt((v_x² + v_y²) + v_z²))`: one `fsqrt` and one
//! `fdiv` (the reciprocal), then three multiplies. Dot products sum left to right. The
//! colour sums are accumulated light by light, each term `(diffuse·ndl + specular·spec) ·
//! light colour`. The eight normalizations make 16 divide/sqrt ops per vertex, which bound
//! the loop at 8 cycles each on the baseline machine.

use imagine_units::arith::fp32::testgen::SplitMix64;
use imagine_units::desc::MachineDesc;

use super::transform::{matrix_params, transform_point};
use super::{finish, records_to_stream, uniform};
use crate::kernel::{Kernel, KernelBuilder, KernelInputs, LoopSpec, MachineRequirementError};

/// Lights of the SPHERE vertex program.
pub const LIGHTS: usize = 3;

/// Words of a parameter list: 16 matrix, 3 eye, 6 per light, 9 material.
pub const PARAMS: usize = 16 + 3 + 6 * LIGHTS + 9;

use super::{Vec3, dot};

/// `v · (1 / sqrt(v·v))`: one `fsqrt`, one `fdiv`, three multiplies.
pub(crate) fn normalize(b: &mut KernelBuilder, v: Vec3) -> Vec3 {
    let length_squared = dot(b, v, v);
    let length = b.fsqrt(length_squared);
    let one = b.f32(1.0);
    let inverse = b.fdiv(one, length);
    v.map(|c| b.fmul(c, inverse))
}

fn sub3(b: &mut KernelBuilder, u: Vec3, v: Vec3) -> Vec3 {
    std::array::from_fn(|i| b.fsub(u[i], v[i]))
}

fn rgb_params(b: &mut KernelBuilder, prefix: &str) -> Vec3 {
    ["r", "g", "b"].map(|c| b.param_f32(&format!("{prefix}_{c}")))
}

/// Any machine serves it (any cluster count; the units every description has).
pub fn build(_desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("vertex");
    let vertices = b.input("vertices");
    let shaded = b.output("shaded");
    let mvp = matrix_params(&mut b, "mvp");
    let eye = ["x", "y", "z"].map(|c| b.param_f32(&format!("eye_{c}")));
    let lights: Vec<(Vec3, Vec3)> = (0..LIGHTS)
        .map(|l| {
            let position = ["x", "y", "z"].map(|c| b.param_f32(&format!("light{l}_{c}")));
            (position, rgb_params(&mut b, &format!("light{l}")))
        })
        .collect();
    let diffuse = rgb_params(&mut b, "diffuse");
    let specular = rgb_params(&mut b, "specular");
    let ambient = rgb_params(&mut b, "ambient");
    let (zero, one) = (b.f32(0.0), b.f32(1.0));

    b.begin_loop(LoopSpec::OverStream(vertices));
    let position: Vec3 = std::array::from_fn(|_| b.read_f32(vertices));
    let normal: Vec3 = std::array::from_fn(|_| b.read_f32(vertices));
    let clip = transform_point(&mut b, &mvp, position, None);

    let n = normalize(&mut b, normal);
    let to_eye = sub3(&mut b, eye, position);
    let v = normalize(&mut b, to_eye);
    let mut colour = ambient;
    for &(light_position, light_colour) in &lights {
        let to_light = sub3(&mut b, light_position, position);
        let l = normalize(&mut b, to_light);
        let n_dot_l = dot(&mut b, n, l);
        let diffuse_factor = b.fmax(n_dot_l, zero);
        let half: Vec3 = std::array::from_fn(|i| b.fadd(l[i], v[i]));
        let h = normalize(&mut b, half);
        let n_dot_h = dot(&mut b, n, h);
        let mut specular_factor = b.fmax(n_dot_h, zero);
        for _ in 0..4 {
            specular_factor = b.fmul(specular_factor, specular_factor);
        }
        for ch in 0..3 {
            let d = b.fmul(diffuse[ch], diffuse_factor);
            let s = b.fmul(specular[ch], specular_factor);
            let reflected = b.fadd(d, s);
            let term = b.fmul(reflected, light_colour[ch]);
            colour[ch] = b.fadd(colour[ch], term);
        }
    }
    for c in clip {
        b.write(shaded, c);
    }
    for c in colour {
        let above_zero = b.fmax(c, zero);
        let clamped = b.fmin(above_zero, one);
        b.write(shaded, clamped);
    }
    b.end_loop();
    Ok(finish(b))
}

/// `rows × C` vertices on and around the unit sphere, with normals of length 0.5 to 2
/// (never near zero); a random matrix with entries in [-2, 2); the eye and lights outside
/// the sphere (at least 3 units away along z); colours in [0, 1).
pub fn inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let mut rng = SplitMix64::new(seed);
    let n = rows * desc.cluster.count;
    let records: Vec<Vec<u32>> = (0..n)
        .map(|_| {
            let p: [f32; 3] = std::array::from_fn(|_| uniform(&mut rng, -1.0, 1.0));
            let normal = loop {
                let v: [f32; 3] = std::array::from_fn(|_| uniform(&mut rng, -2.0, 2.0));
                let length_squared = v.iter().map(|c| c * c).sum::<f32>();
                if (0.25..=4.0).contains(&length_squared) {
                    break v;
                }
            };
            p.iter().chain(&normal).map(|c| c.to_bits()).collect()
        })
        .collect();
    let mut params = Vec::with_capacity(PARAMS);
    params.extend((0..16).map(|_| uniform(&mut rng, -2.0, 2.0).to_bits()));
    // The eye and the lights: x, y in [-5, 5), z in [3, 8) (or its negative).
    let outside = |rng: &mut SplitMix64| -> [u32; 3] {
        let z = uniform(rng, 3.0, 8.0);
        let z = if rng.next_u32() & 1 == 0 { z } else { -z };
        [uniform(rng, -5.0, 5.0), uniform(rng, -5.0, 5.0), z].map(f32::to_bits)
    };
    params.extend(outside(&mut rng));
    for _ in 0..LIGHTS {
        params.extend(outside(&mut rng));
        params.extend((0..3).map(|_| uniform(&mut rng, 0.0, 1.0).to_bits()));
    }
    params.extend((0..9).map(|_| uniform(&mut rng, 0.0, 1.0).to_bits()));
    KernelInputs {
        streams: vec![records_to_stream(&records, desc.cluster.count), Vec::new()],
        params,
    }
}
