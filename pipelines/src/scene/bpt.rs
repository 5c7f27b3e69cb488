//! Bicubic patches (`.bpt`): the patch count, then per patch a line `3 3` and 16 control
//! points `x y z`, row by row with u varying fastest. Drawn by the OpenGL pipeline, each
//! patch is diced into `n × n` quads of two triangles, its `(n + 1)²` vertices shared
//! within the patch, normals `∂P/∂u × ∂P/∂v`, texture coordinates `(u, v)`.
//!
//! Stitched (`stitch = true`), each row of quads is sent as the papers sent it, a strip
//! whose end is joined to the next by two degenerate triangles: `2n + 2` triangles a row,
//! `2n(n + 1)` a patch — the count behind TEAPOT-N's `56·N·(N + 1)` triangles in Owens et
//! al. 2002 and the thesis's Table 8.1. The stitch triangles have zero area: the pipeline
//! assembles and culls them, as it would a strip's, and they draw nothing.

use super::model::{Mesh, Scene};
use super::obj::AssetError;

/// What the 16 points of a patch are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Basis {
    /// Bernstein polynomials: the patch interpolates its four corner points.
    Bezier,
    /// Uniform cubic B-spline: the points are the 4 × 4 control points of one span.
    BSpline,
}

/// One patch's control points, `points[4·row + col]`, col along u.
pub type Patch = [[f64; 3]; 16];

/// A patch's control points in the Bezier basis, as fp32: a B-spline span's 4×4 points
/// are converted exactly (per direction, Bezier points = `S · B` with `S = [1 4 1 0; 0 4 2
/// 0; 0 2 4 0; 0 1 4 1] / 6`), Bezier points are copied. The Reyes pipeline subdivides
/// Bezier nets (de Casteljau halving).
pub fn to_bezier(p: &Patch, b: Basis) -> [[f32; 3]; 16] {
    let s: [[f64; 4]; 4] = [
        [1.0, 4.0, 1.0, 0.0],
        [0.0, 4.0, 2.0, 0.0],
        [0.0, 2.0, 4.0, 0.0],
        [0.0, 1.0, 4.0, 1.0],
    ];
    let m = |i: usize, k: usize| match b {
        Basis::Bezier => f64::from(u8::from(i == k)),
        Basis::BSpline => s[i][k] / 6.0,
    };
    std::array::from_fn(|idx| {
        let (row, col) = (idx / 4, idx % 4);
        std::array::from_fn(|c| {
            let mut v = 0.0;
            for r in 0..4 {
                for q in 0..4 {
                    v += m(row, r) * m(col, q) * p[4 * r + q][c];
                }
            }
            v as f32
        })
    })
}

/// Reads a `.bpt` file's text.
pub fn parse(text: &str) -> Result<Vec<Patch>, AssetError> {
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let end = |what: &str| AssetError::new(None, format!("the file ends before {what}"));
    let (n, first) = lines.next().ok_or_else(|| end("the patch count"))?;
    let count: usize = first.parse().map_err(|_| {
        AssetError::new(
            Some(n),
            format!("expected the patch count, found `{first}`"),
        )
    })?;
    if count == 0 {
        return Err(AssetError::new(Some(n), "the file has no patches"));
    }
    let mut patches = Vec::with_capacity(count.min(1 << 16));
    for p in 0..count {
        let (n, degrees) = lines
            .next()
            .ok_or_else(|| end(&format!("patch {p} of {count}")))?;
        let d: Vec<&str> = degrees.split_whitespace().collect();
        if d != ["3", "3"] {
            return Err(AssetError::new(
                Some(n),
                format!("patch {p}: expected the degrees `3 3`, found `{degrees}`"),
            ));
        }
        let mut patch = [[0.0; 3]; 16];
        for (k, point) in patch.iter_mut().enumerate() {
            let (n, l) = lines
                .next()
                .ok_or_else(|| end(&format!("point {k} of patch {p}")))?;
            let xyz: Vec<&str> = l.split_whitespace().collect();
            let bad = || {
                AssetError::new(
                    Some(n),
                    format!(
                        "patch {p} point {k}: expected three finite numbers `x y z`, found `{l}`"
                    ),
                )
            };
            if xyz.len() != 3 {
                return Err(bad());
            }
            for (c, w) in point.iter_mut().zip(&xyz) {
                *c = w
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(bad)?;
            }
        }
        patches.push(patch);
    }
    if let Some((n, l)) = lines.next() {
        return Err(AssetError::new(
            Some(n),
            format!("`{l}` after the {count} patches the first line announces"),
        ));
    }
    Ok(patches)
}

/// The four cubic basis functions and their derivatives at `t`.
fn basis(b: Basis, t: f64) -> ([f64; 4], [f64; 4]) {
    let s = 1.0 - t;
    match b {
        Basis::Bezier => (
            [s * s * s, 3.0 * t * s * s, 3.0 * t * t * s, t * t * t],
            [
                -3.0 * s * s,
                3.0 * s * s - 6.0 * t * s,
                6.0 * t * s - 3.0 * t * t,
                3.0 * t * t,
            ],
        ),
        Basis::BSpline => (
            [
                s * s * s / 6.0,
                (3.0 * t * t * t - 6.0 * t * t + 4.0) / 6.0,
                (-3.0 * t * t * t + 3.0 * t * t + 3.0 * t + 1.0) / 6.0,
                t * t * t / 6.0,
            ],
            [
                -s * s / 2.0,
                (3.0 * t * t - 4.0 * t) / 2.0,
                (-3.0 * t * t + 2.0 * t + 1.0) / 2.0,
                t * t / 2.0,
            ],
        ),
    }
}

/// The point and the two partial derivatives at `(u, v)`.
fn eval(p: &Patch, b: Basis, u: f64, v: f64) -> [[f64; 3]; 3] {
    let (bu, du) = basis(b, u);
    let (bv, dv) = basis(b, v);
    let mut out = [[0.0; 3]; 3];
    for row in 0..4 {
        for col in 0..4 {
            let q = p[4 * row + col];
            let w = [bu[col] * bv[row], du[col] * bv[row], bu[col] * dv[row]];
            for (o, w) in out.iter_mut().zip(w) {
                for k in 0..3 {
                    o[k] += w * q[k];
                }
            }
        }
    }
    out
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn length(a: [f64; 3]) -> f64 {
    a.iter().map(|c| c * c).sum::<f64>().sqrt()
}

/// The unit normal at `(u, v)`. Where a derivative vanishes (a pole, where a whole row of
/// points coincides, like the top of the teapot's lid), the normal is the limit from
/// inside the patch: taken at a point moved a little towards the patch's centre.
fn normal(p: &Patch, b: Basis, u: f64, v: f64, scale: f64) -> [f64; 3] {
    let tiny = 1e-10 * scale * scale;
    for step in [0.0, 1e-6, 1e-4, 1e-3, 1e-2, 1e-1] {
        let (uu, vv) = (u + (0.5 - u) * step, v + (0.5 - v) * step);
        let [_, pu, pv] = eval(p, b, uu, vv);
        let n = cross(pu, pv);
        let l = length(n);
        if l > tiny {
            return n.map(|c| c / l);
        }
    }
    [0.0, 0.0, 1.0]
}

/// `scene` with every patch object's mesh replaced by its patches diced `n × n` (from the
/// same Bezier nets the Reyes pipeline subdivides), normals from the patches: the limit
/// surface the reference renderer draws a Reyes frame's patches as.
pub fn densely_diced(scene: &Scene, n: u32) -> Scene {
    let mut dense = scene.clone();
    for object in &mut dense.objects {
        if object.patches.is_empty() {
            continue;
        }
        let patches: Vec<Patch> = object
            .patches
            .iter()
            .map(|p| p.map(|q| q.map(f64::from)))
            .collect();
        object.mesh = tessellate(&patches, Basis::Bezier, n, false);
    }
    dense
}

/// Dices each patch into `n × n` quads: `(n + 1)²` vertices per patch (u fastest), quads
/// `(i, j) (i+1, j) (i+1, j+1) (i, j+1)` cut into two counter-clockwise triangles; with
/// `stitch`, each row followed by two degenerate triangles joining its last vertex to the
/// next row's first (the last row's to its own first).
pub fn tessellate(patches: &[Patch], b: Basis, n: u32, stitch: bool) -> Mesh {
    let mut m = Mesh::default();
    let side = n + 1;
    for p in patches {
        let scale = p
            .iter()
            .flat_map(|q| q.iter())
            .fold(0f64, |a, c| a.max(c.abs()))
            .max(f64::MIN_POSITIVE);
        let base = m.positions.len() as u32;
        for j in 0..side {
            let v = f64::from(j) / f64::from(n);
            for i in 0..side {
                let u = f64::from(i) / f64::from(n);
                let [pos, _, _] = eval(p, b, u, v);
                m.positions.push(pos.map(|c| c as f32));
                m.normals.push(normal(p, b, u, v, scale).map(|c| c as f32));
                m.texcoords.push([u as f32, v as f32]);
            }
        }
        let at = |i: u32, j: u32| base + j * side + i;
        for j in 0..n {
            for i in 0..n {
                let (a, bb, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                m.triangles.push([a, bb, c]);
                m.triangles.push([a, c, d]);
            }
            if stitch {
                let (end, next) = (at(n, j + 1), at(0, (j + 2).min(n)));
                m.triangles.push([end, end, next]);
                m.triangles.push([end, next, next]);
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat() -> String {
        let mut s = String::from("1\n3 3\n");
        for row in 0..4 {
            for col in 0..4 {
                s += &format!("{col} {row} 0\n");
            }
        }
        s
    }

    #[test]
    fn scene_bpt_flat_patch_tessellated_2x2() {
        let patches = parse(&flat()).unwrap();
        for b in [Basis::Bezier, Basis::BSpline] {
            let m = tessellate(&patches, b, 2, false);
            assert_eq!((m.positions.len(), m.triangles.len()), (9, 8));
            for n in &m.normals {
                assert!((n[2] - 1.0).abs() < 1e-6 && n[0].abs() < 1e-6, "{n:?}");
            }
        }
        let m = tessellate(&patches, Basis::Bezier, 2, false);
        assert_eq!(m.positions[4], [1.5, 1.5, 0.0]);
        assert_eq!(m.positions[8], [3.0, 3.0, 0.0]);
        // Counter-clockwise seen from +z.
        for t in &m.triangles {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            let z = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
            assert!(z > 0.0);
        }
    }

    #[test]
    fn scene_bpt_stitched_rows_add_two_degenerate_triangles_each() {
        let patches = parse(&flat()).unwrap();
        for n in [1, 2, 5] {
            let plain = tessellate(&patches, Basis::Bezier, n, false);
            let m = tessellate(&patches, Basis::Bezier, n, true);
            assert_eq!(m.triangles.len() as u32, 2 * n * (n + 1));
            assert_eq!(m.positions, plain.positions);
            // The plain triangles, in order, plus stitches of zero area.
            let degenerate = |t: &[u32; 3]| t[0] == t[1] || t[1] == t[2] || t[0] == t[2];
            let drawn: Vec<_> = m.triangles.iter().filter(|t| !degenerate(t)).collect();
            assert_eq!(drawn, plain.triangles.iter().collect::<Vec<_>>());
        }
    }

    #[test]
    fn scene_bpt_pole_normals_come_from_inside() {
        // A row of coincident points at v = 0 (a pole): ∂P/∂u vanishes there.
        let mut s = String::from("1\n3 3\n");
        for row in 0..4 {
            for col in 0..4 {
                let r = f64::from(row);
                s += &format!("{} {} {}\n", f64::from(col) * r, r, 0.0);
            }
        }
        let m = tessellate(&parse(&s).unwrap(), Basis::Bezier, 4, false);
        for n in &m.normals {
            assert!((n[2] - 1.0).abs() < 1e-3, "{n:?}");
        }
    }

    #[test]
    fn scene_bpt_errors_name_the_line() {
        let mut bad = flat();
        bad = bad.replace("2 1 0\n", "2 x 0\n");
        let e = parse(&bad).unwrap_err();
        assert_eq!(e.line, Some(9), "{e:?}");
        let e = parse("2\n3 3\n").unwrap_err();
        assert!(
            e.message.contains("ends before point 0 of patch 0"),
            "{e:?}"
        );
        let e = parse("1\n3 2\n").unwrap_err();
        assert_eq!(e.line, Some(2));
    }
}
