//! Catmull-Clark control cages (`cage = "x.obj"`): a closed polygon mesh standing for its
//! Catmull-Clark limit surface, turned into bicubic Bezier patches when the scene loads,
//! which the Reyes pipeline subdivides and the OpenGL pipeline dices like any `.bpt`.
//!
//! 1. **One Catmull-Clark step** on the host (Catmull & Clark 1978): every face of `k`
//!    corners becomes `k` quads (face points, edge points, moved vertices). The refined
//!    mesh is all quads, and each quad has at most one extraordinary corner (valence ≠ 4).
//! 2. **A patch per quad** by Loop & Schaefer's approximation ("Approximating
//!    Catmull-Clark subdivision surfaces with bicubic patches", 2008, its geometry
//!    patches): at each corner `v` of valence `n` of quad `(v, e₁, f, e₂)` the inner point
//!    `(n·v + 2(e₁ + e₂) + f)/(n + 5)`; on each edge the mean of the two inner points
//!    beside it; at each vertex its limit position `(n²·v + 4Σeⱼ + Σfⱼ)/(n(n + 5))`. Where a
//!    quad and its neighbours are regular this is exactly the bicubic B-spline patch of
//!    the limit surface; near an extraordinary vertex it approximates it.
//!
//! **No cracks.** Every boundary curve of a patch (a vertex's limit point and an edge's two
//! points) is computed once per vertex and per edge and shared by both quads on the edge,
//! so neighbouring patches hold the same boundary control points bit for bit, which is
//! what the Reyes pipeline's crack-free subdivision needs (the papers' Catmull-Clark
//! refinement of each quad's 4 × 4 neighbourhood is regular-only; this conversion is the
//! choice here, documented in the README).
//!
//! **Orientation.** A quad's corners `a, b, c, d` (the file's order, counter-clockwise
//! seen from outside) become the patch's `(0,0)`, `(0,3)`, `(3,3)`, `(3,0)`: u from `a` to
//! `b`, v from `a` to `d`, so `∂P/∂u × ∂P/∂v` faces outward, as `.bpt` patches do.
//!
//! The cage must be closed and consistently oriented: every edge on exactly two faces, run
//! in opposite directions; anything else is an error naming the edge's vertices (1-based,
//! as the file numbers them).

use std::collections::HashMap;

use super::bpt::Patch;
use super::obj::AssetError;

/// The most faces a cage may have (each refined quad is a patch).
pub const MAX_CAGE_FACES: usize = 1 << 16;

type P = [f64; 3];

fn add(a: P, b: P) -> P {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn scale(a: P, s: f64) -> P {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// A polygon mesh: positions and faces (vertex indices, counter-clockwise from outside).
#[derive(Clone, Debug, PartialEq)]
pub struct Cage {
    pub positions: Vec<P>,
    pub faces: Vec<Vec<usize>>,
}

/// Reads an OBJ's vertices and polygons: `v x y z` and `f a b c …` (each corner `a`,
/// `a/t`, `a//n` or `a/t/n`, 1-based or negative); other statements are ignored (a patch
/// is textured over its own `(u, v)`, and normals come from the patches).
pub fn parse(text: &str) -> Result<Cage, AssetError> {
    let mut cage = Cage {
        positions: Vec::new(),
        faces: Vec::new(),
    };
    for (n, line) in text.lines().enumerate() {
        let at = |m: String| AssetError::new(Some(n + 1), m);
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let xyz: Vec<f64> = words
                    .take(3)
                    .map(|w| {
                        w.parse::<f64>()
                            .map_err(|_| at(format!("`{w}` is not a number")))
                    })
                    .collect::<Result<_, _>>()?;
                if xyz.len() != 3 || xyz.iter().any(|c| !c.is_finite()) {
                    return Err(at("a vertex needs three finite coordinates".into()));
                }
                cage.positions.push([xyz[0], xyz[1], xyz[2]]);
            }
            Some("f") => {
                let count = cage.positions.len() as i64;
                let face = words
                    .map(|w| {
                        let i: i64 = w
                            .split('/')
                            .next()
                            .and_then(|i| i.parse().ok())
                            .ok_or_else(|| at(format!("`{w}` is not a vertex index")))?;
                        let i = if i < 0 { count + i } else { i - 1 };
                        if !(0..count).contains(&i) {
                            return Err(at(format!(
                                "vertex `{w}` is not one of the {count} before this line"
                            )));
                        }
                        Ok(i as usize)
                    })
                    .collect::<Result<Vec<usize>, _>>()?;
                cage.faces.push(face);
            }
            _ => {}
        }
    }
    check(&cage)?;
    Ok(cage)
}

/// Checks that `cage` is a closed, consistently oriented 2-manifold of polygons (its
/// positions `parse` checked line by line).
fn check(cage: &Cage) -> Result<(), AssetError> {
    let err = |m: String| Err(AssetError::new(None, m));
    if cage.faces.is_empty() {
        return err("a cage needs faces (`f` lines)".into());
    }
    if cage.faces.len() > MAX_CAGE_FACES {
        return err(format!(
            "{} faces: a cage may have at most {MAX_CAGE_FACES}",
            cage.faces.len()
        ));
    }
    let mut directed: HashMap<(usize, usize), usize> = HashMap::new();
    for (f, face) in cage.faces.iter().enumerate() {
        if face.len() < 3 {
            return err(format!("face {} has {} corners", f + 1, face.len()));
        }
        for k in 0..face.len() {
            let (a, b) = (face[k], face[(k + 1) % face.len()]);
            if a == b || directed.insert((a, b), f).is_some() {
                return err(format!(
                    "edge {}–{} is run the same way by two faces, or twice by one: the cage \
                     must be a consistently oriented 2-manifold",
                    a + 1,
                    b + 1
                ));
            }
        }
    }
    let mut open: Vec<&(usize, usize)> = directed
        .keys()
        .filter(|(a, b)| !directed.contains_key(&(*b, *a)))
        .collect();
    open.sort_unstable();
    if let Some((a, b)) = open.first() {
        return err(format!(
            "edge {}–{} has a face on one side only: a cage must be closed ({} such edges)",
            a + 1,
            b + 1,
            open.len()
        ));
    }
    Ok(())
}

/// One Catmull-Clark step: every face of `k` corners into `k` quads.
pub fn refine(cage: &Cage) -> Cage {
    let n = cage.positions.len();
    let face_points: Vec<P> = cage
        .faces
        .iter()
        .map(|f| {
            let s = f.iter().fold([0.0; 3], |s, &v| add(s, cage.positions[v]));
            scale(s, 1.0 / f.len() as f64)
        })
        .collect();
    // Each undirected edge once (smaller vertex first), with its two faces.
    let mut edges: HashMap<(usize, usize), Vec<usize>> = HashMap::new();
    for (f, face) in cage.faces.iter().enumerate() {
        for k in 0..face.len() {
            let (a, b) = (face[k], face[(k + 1) % face.len()]);
            edges.entry((a.min(b), a.max(b))).or_default().push(f);
        }
    }
    let mut keys: Vec<(usize, usize)> = edges.keys().copied().collect();
    keys.sort_unstable();
    let mut positions = cage.positions.clone();
    let mut edge_index = HashMap::new();
    for &(a, b) in &keys {
        let fs = &edges[&(a, b)];
        let s = add(
            add(cage.positions[a], cage.positions[b]),
            add(face_points[fs[0]], face_points[fs[1]]),
        );
        edge_index.insert((a, b), positions.len());
        positions.push(scale(s, 0.25));
    }
    let face_base = positions.len();
    positions.extend(&face_points);
    // Moved vertices: (Q + 2R + (n − 3)·P)/n.
    let mut face_sum = vec![[0.0; 3]; n];
    let mut mid_sum = vec![[0.0; 3]; n];
    let mut valence = vec![0usize; n];
    for (f, face) in cage.faces.iter().enumerate() {
        for &v in face {
            face_sum[v] = add(face_sum[v], face_points[f]);
        }
    }
    for &(a, b) in &keys {
        let mid = scale(add(cage.positions[a], cage.positions[b]), 0.5);
        for v in [a, b] {
            mid_sum[v] = add(mid_sum[v], mid);
            valence[v] += 1;
        }
    }
    for v in 0..n {
        let k = valence[v] as f64;
        if valence[v] == 0 {
            continue;
        }
        let q = scale(face_sum[v], 1.0 / k);
        let r = scale(mid_sum[v], 2.0 / k);
        positions[v] = scale(add(add(q, r), scale(cage.positions[v], k - 3.0)), 1.0 / k);
    }
    let edge = |a: usize, b: usize| edge_index[&(a.min(b), a.max(b))];
    let mut faces = Vec::new();
    for (f, face) in cage.faces.iter().enumerate() {
        let k = face.len();
        for i in 0..k {
            let (prev, v, next) = (face[(i + k - 1) % k], face[i], face[(i + 1) % k]);
            faces.push(vec![v, edge(v, next), face_base + f, edge(prev, v)]);
        }
    }
    Cage { positions, faces }
}

/// The Bezier patches of an all-quad closed cage, one per face (see the module notes).
pub fn quad_patches(cage: &Cage) -> Vec<Patch> {
    let p = &cage.positions;
    let n = p.len();
    // Per vertex: valence, and the sums of its edge neighbours and of its quads' far
    // corners. Each edge at `v` runs `v → w` in exactly one quad, which counts it.
    let mut valence = vec![0usize; n];
    let mut edge_sum = vec![[0.0; 3]; n];
    let mut diagonal_sum = vec![[0.0; 3]; n];
    for q in &cage.faces {
        for k in 0..4 {
            let v = q[k];
            valence[v] += 1;
            edge_sum[v] = add(edge_sum[v], p[q[(k + 1) % 4]]);
            diagonal_sum[v] = add(diagonal_sum[v], p[q[(k + 2) % 4]]);
        }
    }
    let limit = |v: usize| {
        let k = valence[v] as f64;
        let s = add(
            add(scale(p[v], k * k), scale(edge_sum[v], 4.0)),
            diagonal_sum[v],
        );
        scale(s, 1.0 / (k * (k + 5.0)))
    };
    let inner = |q: &[usize], k: usize| {
        let (v, next, far, prev) = (q[k], q[(k + 1) % 4], q[(k + 2) % 4], q[(k + 3) % 4]);
        let m = valence[v] as f64;
        let s = add(
            add(scale(p[v], m), scale(add(p[next], p[prev]), 2.0)),
            p[far],
        );
        scale(s, 1.0 / (m + 5.0))
    };
    // The inner points beside each edge `v–w` at `v`: one from each quad on the edge, in
    // face order, kept so that both quads take the same mean.
    let mut beside: HashMap<(usize, usize), Vec<P>> = HashMap::new();
    for q in &cage.faces {
        for k in 0..4 {
            let i = inner(q, k);
            for w in [q[(k + 1) % 4], q[(k + 3) % 4]] {
                beside.entry((q[k], w)).or_default().push(i);
            }
        }
    }
    let edge_point = |v: usize, w: usize| {
        let s = &beside[&(v, w)];
        scale(add(s[0], s[1]), 0.5)
    };
    cage.faces
        .iter()
        .map(|q| {
            let [a, b, c, d] = [q[0], q[1], q[2], q[3]];
            [
                limit(a),
                edge_point(a, b),
                edge_point(b, a),
                limit(b),
                edge_point(a, d),
                inner(q, 0),
                inner(q, 1),
                edge_point(b, c),
                edge_point(d, a),
                inner(q, 3),
                inner(q, 2),
                edge_point(c, b),
                limit(d),
                edge_point(d, c),
                edge_point(c, d),
                limit(c),
            ]
        })
        .collect()
}

/// A cage's patches: one Catmull-Clark step, then a patch per quad.
pub fn patches(text: &str) -> Result<Vec<Patch>, AssetError> {
    Ok(quad_patches(&refine(&parse(text)?)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::bpt::{Basis, to_bezier};

    /// A torus of `nu × nv` quads, every vertex of valence 4.
    fn torus(nu: usize, nv: usize) -> String {
        let mut s = String::new();
        for j in 0..nv {
            for i in 0..nu {
                let (a, b) = (
                    std::f64::consts::TAU * i as f64 / nu as f64,
                    std::f64::consts::TAU * j as f64 / nv as f64,
                );
                let r = 2.0 + 0.7 * b.cos();
                s += &format!("v {} {} {}\n", r * a.cos(), 0.7 * b.sin(), r * a.sin());
            }
        }
        let at = |i: usize, j: usize| (j % nv) * nu + (i % nu) + 1;
        for j in 0..nv {
            for i in 0..nu {
                s += &format!(
                    "f {} {} {} {}\n",
                    at(i, j),
                    at(i, j + 1),
                    at(i + 1, j + 1),
                    at(i + 1, j)
                );
            }
        }
        s
    }

    /// On a regular cage (every vertex of valence 4) every patch is the uniform B-spline
    /// patch of its quad's 4 × 4 neighbourhood.
    #[test]
    fn scene_cage_regular_patches_are_the_b_spline_patches() {
        let (nu, nv) = (6, 5);
        let cage = parse(&torus(nu, nv)).unwrap();
        let patches = quad_patches(&cage);
        let grid = |i: usize, j: usize| cage.positions[(j % nv) * nu + (i % nu)];
        for j in 0..nv {
            for i in 0..nu {
                // Face (i, j) runs (i, j), (i, j+1), (i+1, j+1), (i+1, j): u along j, v
                // along i.
                let net: Patch = std::array::from_fn(|k| {
                    let (row, col) = (k / 4, k % 4);
                    grid(i + nu - 1 + row, j + nv - 1 + col)
                });
                let want = to_bezier(&net, Basis::BSpline);
                let got = patches[j * nu + i];
                for (w, g) in want.iter().zip(&got) {
                    for c in 0..3 {
                        assert!(
                            (f64::from(w[c]) - g[c]).abs() < 1e-6,
                            "face ({i}, {j}): {w:?} against {g:?}"
                        );
                    }
                }
            }
        }
    }

    fn cube() -> &'static str {
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
         f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n"
    }

    /// A cube (eight corners of valence 3) refines into 24 quads, and the patches of two
    /// quads on a shared edge hold the same boundary points, bit for bit.
    #[test]
    fn scene_cage_neighbours_share_their_boundaries() {
        let refined = refine(&parse(cube()).unwrap());
        assert_eq!(refined.faces.len(), 24);
        let patches = quad_patches(&refined);
        // The boundary of patch f along its edge k, from corner k to corner k + 1.
        let boundary = |f: usize, k: usize| -> [[f64; 3]; 4] {
            let idx: [[usize; 4]; 4] = [
                [0, 1, 2, 3],
                [3, 7, 11, 15],
                [15, 14, 13, 12],
                [12, 8, 4, 0],
            ];
            idx[k].map(|i| patches[f][i])
        };
        let mut shared = 0;
        for (f, q) in refined.faces.iter().enumerate() {
            for k in 0..4 {
                let (a, b) = (q[k], q[(k + 1) % 4]);
                let (g, l) = refined
                    .faces
                    .iter()
                    .enumerate()
                    .find_map(|(g, r)| {
                        (0..4)
                            .find(|&l| r[l] == b && r[(l + 1) % 4] == a)
                            .map(|l| (g, l))
                    })
                    .expect("a closed cage");
                let mut theirs = boundary(g, l);
                theirs.reverse();
                assert_eq!(boundary(f, k), theirs, "faces {f} and {g}");
                shared += 1;
            }
        }
        assert_eq!(shared, 96);
    }

    #[test]
    fn scene_cage_refuses_open_or_inconsistent_meshes() {
        let open = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
        let e = parse(open).unwrap_err().message;
        assert!(e.contains("closed"), "{e}");
        let flipped = cube().replace("f 1 4 3 2", "f 1 2 3 4");
        let e = parse(&flipped).unwrap_err().message;
        assert!(e.contains("consistently oriented"), "{e}");
        let e = parse("v 0 0 0\n").unwrap_err().message;
        assert!(e.contains("needs faces"), "{e}");
        let nan = cube().replace("v 1 1 1", "v 1 nan 1");
        assert!(parse(&nan).is_err());
    }
}
