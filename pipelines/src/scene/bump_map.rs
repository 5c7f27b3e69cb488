//! The combined displacement/bump map of a `bump_env` material (VERONA's shader), built by
//! the host when the scene loads, as mipmap pyramids are: a `size × size` grid of 4-word
//! f32 texels `[nx, ny, nz, h]`, a unit tangent-space normal and a height in [0, 1], row 0
//! at t = 0, texel `(i, j)` at words `4·(j·size + i)`…`+3`.
//!
//! The thesis does not publish VERONA's maps (Owens 2002, §5.1.1 names the shader only:
//! vertex texture, bump map, dependent environment-map read), so the height field is our
//! choice, smooth and periodic so that `repeat` has no seam: `cells × cells` round bumps,
//! `h(s, t) = ½ + ½·sin(2π·cells·s)·sin(2π·cells·t)`, sampled at the texel centres
//! `((i + ½)/size, (j + ½)/size)`. Its normal is the height field's, `normalize(−k·∂h/∂s,
//! −k·∂h/∂t, 1)` with `k = scale / (π·cells)`, that is
//! `normalize(−scale·cos a·sin b, −scale·sin a·cos b, 1)` for `a = 2π·cells·s`,
//! `b = 2π·cells·t` — `scale` is the largest slope. Computed in f64, stored as f32; the
//! machine and the reference read the same words.

use super::model::BumpEnv;

/// Words of a texel: the normal's three, then the height.
pub const TEXEL_WORDS: usize = 4;

/// The map's words (f32 bits), texel after texel, row 0 (t = 0) first.
pub fn build(b: &BumpEnv) -> Vec<u32> {
    let size = b.bump_size;
    let cells = f64::from(b.bump_cells);
    let scale = f64::from(b.bump_scale);
    let mut words = Vec::with_capacity(TEXEL_WORDS * (size * size) as usize);
    for j in 0..size {
        let t = (f64::from(j) + 0.5) / f64::from(size);
        let (sin_b, cos_b) = (std::f64::consts::TAU * cells * t).sin_cos();
        for i in 0..size {
            let s = (f64::from(i) + 0.5) / f64::from(size);
            let (sin_a, cos_a) = (std::f64::consts::TAU * cells * s).sin_cos();
            let n = [-scale * cos_a * sin_b, -scale * sin_a * cos_b, 1.0];
            let length = n.iter().map(|c| c * c).sum::<f64>().sqrt();
            let h = 0.5 + 0.5 * sin_a * sin_b;
            for w in [n[0] / length, n[1] / length, n[2] / length, h] {
                words.push((w as f32).to_bits());
            }
        }
    }
    words
}

/// Texel `(i, j)` of `words` (a map of side `size`) as `[nx, ny, nz, h]`.
pub fn texel(words: &[u32], size: u32, i: u32, j: u32) -> [f32; 4] {
    let at = TEXEL_WORDS * (j * size + i) as usize;
    std::array::from_fn(|k| f32::from_bits(words[at + k]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normals_are_unit_and_heights_in_range() {
        let b = BumpEnv {
            displacement: 0.1,
            bump_size: 16,
            bump_cells: 2,
            bump_scale: 1.5,
        };
        let words = build(&b);
        assert_eq!(words.len(), 4 * 16 * 16);
        let mut tilted = 0;
        for j in 0..16 {
            for i in 0..16 {
                let [x, y, z, h] = texel(&words, 16, i, j);
                assert!(((x * x + y * y + z * z).sqrt() - 1.0).abs() < 1e-6);
                assert!(z > 0.0 && (0.0..=1.0).contains(&h));
                tilted += usize::from(z < 0.99);
            }
        }
        assert!(tilted > 100, "the bumps tilt most normals");
    }
}
