//! The `marble` shader in f64 for the reference renderer ([`crate::reference_model`]),
//! written from the definition in the `turbulence` kernel's notes and the scene format's
//! README, not from the kernel: the same formula, none of the machine's approximations.
//!
//! Per fragment, at the object-space position `p` and normal `n` interpolated
//! perspective-correctly from the corners:
//!
//! * `noise` is the material's: Greg Ward's implementation of Perlin's noise ([`ward_noise`],
//!   Graphics Gems II ch. VIII.10, as Radiance's `noise3.c` has it: Ward's recursion over
//!   the axes with his Hermite cubics and his `frand` in 32-bit wrapping integers, the
//!   value component, unscaled), or Perlin's improved noise (SIGGRAPH 2002) over Perlin's
//!   permutation ([`PERLIN_PERMUTATION`], data shared with the machine): the fade
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
use imagine_pipelines::scene::model::{self, Marble, Noise, Object};

use crate::reference::{V3, dot, normalize, widen};

/// The marble shading of one object: its material's parameters and its lighting.
pub struct MarbleShading {
    frequency: f64,
    turbulence_scale: f64,
    noise: Noise,
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
            noise,
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
            noise,
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
                let q = p.map(|c| c * scale);
                let n = match self.noise {
                    Noise::Ward => ward_noise(q),
                    Noise::Perlin => noise(q),
                };
                n.abs() / scale
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

/// Ward's `frand(s)`: `s = (s << 13) ^ s`, then `1 − ((s·(s·s·15731 + 789221) +
/// 1376312589) & 0x7fffffff) / 2^30`, in 32-bit wrapping integers as the original's `long`.
pub fn frand(seed: i32) -> f64 {
    let s = (seed << 13) ^ seed;
    let t = s
        .wrapping_mul(s.wrapping_mul(s).wrapping_mul(15731).wrapping_add(789_221))
        .wrapping_add(1_376_312_589);
    1.0 - f64::from(t & 0x7fff_ffff) / 1_073_741_824.0
}

/// Ward's noise at `p` in f64: his `noise3` (the lattice cell, the offsets, then his
/// recursive `interpolate(f, 0, 3)`), the value `f[D]`.
pub fn ward_noise(p: V3) -> f64 {
    let floor = p.map(f64::floor);
    let corner = |c: usize, axis: usize| floor[axis] as i32 + ((c >> axis) & 1) as i32;
    let offset: V3 = std::array::from_fn(|axis| p[axis] - floor[axis]);
    // f[0..3]: the gradient (rand3a, rand3b, rand3c), f[3]: the value (rand3d).
    fn interpolate(i: usize, n: usize, corner: &dyn Fn(usize, usize) -> i32, t: &V3) -> [f64; 4] {
        if n == 0 {
            let (x, y, z) = (corner(i, 0), corner(i, 1), corner(i, 2));
            let seed = |a: i32, b: i32, c: i32| {
                a.wrapping_mul(x)
                    .wrapping_add(b.wrapping_mul(y))
                    .wrapping_add(c.wrapping_mul(z))
            };
            return [
                frand(seed(67, 59, 71)),
                frand(seed(73, 79, 83)),
                frand(seed(89, 97, 101)),
                frand(seed(103, 107, 109)),
            ];
        }
        let n = n - 1;
        let f0 = interpolate(i, n, corner, t);
        let f1 = interpolate(i | 1 << n, n, corner, t);
        let t = t[n];
        let hp1 = (2.0 * t - 3.0) * t * t + 1.0;
        let hp2 = (-2.0 * t + 3.0) * t * t;
        let hp3 = ((t - 2.0) * t + 1.0) * t;
        let hp4 = (t - 1.0) * t * t;
        let mut f: [f64; 4] = std::array::from_fn(|j| f0[j] * hp1 + f1[j] * hp2);
        f[3] += f0[n] * hp3 + f1[n] * hp4;
        f
    }
    interpolate(0, 3, &corner, &offset)[3]
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

    /// `frand`'s 32-bit wrap against values worked out independently (Python's unbounded
    /// integers, reduced to signed 32 bits after each step).
    #[test]
    fn frand_wraps_at_32_bits() {
        let v = |bits: f64| 1.0 - bits / 1_073_741_824.0;
        // s = 0: only the offset.
        assert_eq!(frand(0), v(1_376_312_589.0));
        // s = 1: s' = 8193, s'² = 67125249, ·15731 wraps to −614662797, + 789221 =
        // −613873576, ·8193 wraps to −59504552, + 1376312589 = 1316808037.
        assert_eq!(frand(1), v(1_316_808_037.0));
        assert_eq!(frand(12345), v(2_032_478_005.0));
        // s = −1: s' = (−8192) ^ (−1) = 8191; the sum wraps negative and the mask drops the
        // sign.
        assert_eq!(frand(-1), v(107_238_581.0));
        for seed in [-1, 12345, -987_654, i32::MAX, i32::MIN] {
            let f = frand(seed);
            assert!((-1.0..=1.0).contains(&f), "frand({seed}) = {f}");
        }
    }

    #[test]
    fn ward_noise_is_the_lattice_values_at_the_corners_and_bounded() {
        // At a lattice point every offset is 0: hpoly1 = 1, the others 0, so the noise is
        // that corner's rand3d.
        let (x, y, z) = (3, -7, 12);
        let want = frand(103 * x + 107 * y + 109 * z);
        assert_eq!(ward_noise([3.0, -7.0, 12.0]), want);
        for i in 0..1000 {
            let t = f64::from(i) * 0.137;
            let n = ward_noise([t, 2.0 * t - 5.0, 0.5 * t + 1.3]);
            assert!(n.abs() <= 2.0, "{n}");
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
