//! The `marble` shader in f64 for the reference renderer ([`crate::reference_model`]),
//! written from the definition in the `turbulence` kernel's notes and the scene format's
//! README, not from the kernel: the same formula, none of the machine's approximations.
//!
//! Per fragment, at the object-space position `p` and normal `n` interpolated
//! perspective-correctly from the corners:
//!
//! * `noise` is Perlin's improved noise (SIGGRAPH 2002) over Perlin's permutation
//!   ([`PERLIN_PERMUTATION`], data shared with the machine): the fade
//!   `6t⁵ − 15t⁴ + 10t³`, his 12 gradients, nested linear interpolation;
//! * `turbulence = Σ_{i<4} |noise(2^i·p)| / 2^i`;
//! * `u = (sin(x·frequency + turbulence·turbulence_scale) + 1) / 2` (the library `sin`);
//! * the base colour is the degree-7 Bézier curve of [`RAMP_COLOURS`] at `u`;
//! * `colour = clamp(base·(ambient + max(n̂·L, 0)) + specular·max(n̂·H, 0)^16, 0, 1)`,
//!   `n̂ = n/|n|`, with the light `L`, half vector `H` and intensities as the OpenGL
//!   pipeline's fragment program notes define them (object space; the scene's first
//!   light and the eye seen from the object's origin; means of the material's ambient and
//!   specular colours).

use imagine_pipelines::kernels::turbulence::{PERLIN_PERMUTATION, RAMP_COLOURS};
use imagine_pipelines::scene::model::{self, Marble, Object};

use crate::reference::{V3, dot, normalize, widen};

/// The marble shading of one object: its material's parameters and its lighting.
pub struct MarbleShading {
    frequency: f64,
    turbulence_scale: f64,
    light: V3,
    half: V3,
    ambient: f64,
    specular: f64,
}

impl MarbleShading {
    /// The shading of `object`, or `None` when its material is not marble.
    pub fn of(scene: &model::Scene, object: &Object) -> Option<MarbleShading> {
        let material = &scene.materials[object.material];
        let model::Shader::Marble(Marble {
            frequency,
            turbulence_scale,
        }) = material.shader
        else {
            return None;
        };
        let m = object.model.map(f64::from);
        let a: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| m[4 * i + j]));
        let origin = [m[3], m[7], m[11]];
        let view = scene.camera_for(object).view.map(f64::from);
        let v: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| view[4 * i + j]));
        // The eye in the world: solve V·e + t = 0.
        let eye = solve(&v, [-view[3], -view[7], -view[11]]);
        // A direction d in the world is A⁻¹·d in object space.
        let towards = |point: V3| unit(solve(&a, std::array::from_fn(|k| point[k] - origin[k])));
        let (light, half) = match scene.lights.first() {
            Some(l) => {
                let light = towards(widen(l.position));
                let viewer = towards(eye);
                (light, unit(std::array::from_fn(|k| light[k] + viewer[k])))
            }
            None => ([0.0; 3], [0.0; 3]),
        };
        let mean = |c: [f32; 3]| c.iter().map(|&x| f64::from(x)).sum::<f64>() / 3.0;
        Some(MarbleShading {
            frequency: f64::from(frequency),
            turbulence_scale: f64::from(turbulence_scale),
            light,
            half,
            ambient: mean(material.ambient),
            specular: mean(material.specular),
        })
    }

    /// The colour at object-space position `p` with normal `n`.
    pub fn colour(&self, p: V3, n: V3) -> [f64; 3] {
        let turbulence: f64 = (0..4)
            .map(|octave| {
                let scale = f64::from(1u32 << octave);
                noise(p.map(|c| c * scale)).abs() / scale
            })
            .sum();
        let u = ((p[0] * self.frequency + turbulence * self.turbulence_scale).sin() + 1.0) / 2.0;
        let base: [f64; 3] = std::array::from_fn(|ch| {
            (0..8)
                .map(|i| {
                    let weight = binomial(7, i) * u.powi(i as i32) * (1.0 - u).powi(7 - i as i32);
                    weight * f64::from(RAMP_COLOURS[i][ch])
                })
                .sum()
        });
        let n = if dot(n, n) > 0.0 { normalize(n) } else { n };
        let lit = self.ambient + dot(n, self.light).max(0.0);
        let highlight = self.specular * dot(n, self.half).max(0.0).powi(16);
        base.map(|c| (c * lit + highlight).clamp(0.0, 1.0))
    }
}

fn binomial(n: u32, k: usize) -> f64 {
    (0..k as u32).fold(1.0, |acc, j| acc * f64::from(n - j) / f64::from(j + 1))
}

/// `v / |v|`, or zero.
fn unit(v: V3) -> V3 {
    if dot(v, v) > 0.0 {
        normalize(v)
    } else {
        [0.0; 3]
    }
}

/// `x` with `a·x = b` (Cramer's rule).
fn solve(a: &[[f64; 3]; 3], b: V3) -> V3 {
    let det3 = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let det = det3(a);
    std::array::from_fn(|col| {
        let mut m = *a;
        for (row, &value) in b.iter().enumerate() {
            m[row][col] = value;
        }
        det3(&m) / det
    })
}

/// Perlin's improved noise, his reference code in f64.
pub fn noise(p: V3) -> f64 {
    let perm = |i: usize| usize::from(PERLIN_PERMUTATION[i & 255]);
    let fade = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let lerp = |t: f64, a: f64, b: f64| a + t * (b - a);
    let grad = |hash: usize, x: f64, y: f64, z: f64| {
        let h = hash & 15;
        let u = if h < 8 { x } else { y };
        let v = match h {
            0..=3 => y,
            12 | 14 => x,
            _ => z,
        };
        (if h & 1 == 0 { u } else { -u }) + (if h & 2 == 0 { v } else { -v })
    };
    let cell = p.map(|c| (c.floor() as i64 & 255) as usize);
    let [x, y, z] = p.map(|c| c - c.floor());
    let (u, v, w) = (fade(x), fade(y), fade(z));
    let [cx, cy, cz] = cell;
    let a = perm(cx) + cy;
    let (aa, ab) = (perm(a) + cz, perm(a + 1) + cz);
    let b = perm(cx + 1) + cy;
    let (ba, bb) = (perm(b) + cz, perm(b + 1) + cz);
    lerp(
        w,
        lerp(
            v,
            lerp(u, grad(perm(aa), x, y, z), grad(perm(ba), x - 1.0, y, z)),
            lerp(
                u,
                grad(perm(ab), x, y - 1.0, z),
                grad(perm(bb), x - 1.0, y - 1.0, z),
            ),
        ),
        lerp(
            v,
            lerp(
                u,
                grad(perm(aa + 1), x, y, z - 1.0),
                grad(perm(ba + 1), x - 1.0, y, z - 1.0),
            ),
            lerp(
                u,
                grad(perm(ab + 1), x, y - 1.0, z - 1.0),
                grad(perm(bb + 1), x - 1.0, y - 1.0, z - 1.0),
            ),
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_vanishes_on_the_lattice_and_stays_in_range() {
        assert_eq!(noise([3.0, -7.0, 12.0]), 0.0);
        for i in 0..1000 {
            let t = f64::from(i) * 0.137;
            let n = noise([t, 2.0 * t - 5.0, 0.5 * t + 1.3]);
            assert!(n.abs() <= 1.1, "{n}");
        }
    }

    #[test]
    fn solve_inverts() {
        let a = [[2.0, 0.0, 1.0], [0.0, 3.0, 0.0], [1.0, 0.0, 1.0]];
        let x = solve(&a, [3.0, 6.0, 2.0]);
        assert!(
            x.iter()
                .zip([1.0, 2.0, 1.0])
                .all(|(a, b)| (a - b).abs() < 1e-12)
        );
    }
}
