//! Deterministic stress scenes in window space (the `.tri` format's conventions, ARCHITECTURE
//! §8: "sliver and huge triangles"): x and y in pixels with the origin bottom-left, z and
//! colours in [0, 1], smooth shading, depth test LESS, no culling. Each generator takes a
//! seed for a SplitMix64 stream, so the same arguments always give the same scene.
//!
//! * [`overlapping`]: random triangles of many sizes, partly off-screen, overlapping, with
//!   random per-vertex depths (so they also interpenetrate) and colours.
//! * [`slivers`]: long thin triangles (a vertex within 0.001–1 px of the opposite edge) and
//!   needles (two vertices within 0.01 px of each other).
//! * [`huge`]: triangles with vertices up to ±10⁵ px away: some contain the whole window,
//!   others have a long edge crossing it.
//! * [`shared_edge_mesh`]: a jittered grid of triangles sharing edges and vertices that
//!   tiles the window exactly once, with random diagonals, random first vertices and a
//!   random mix of windings; optionally with vertices on half-pixel positions so that many
//!   edges pass exactly through pixel centres (the tie rule decides).
//!
//! [`to_tri`] writes a scene from here as a `.tri` file that `parse_tri` reads back
//! exactly.

use imagine_pipelines::scene::{IDENTITY, Scene, Shading, window_to_clip};
use imagine_units::arith::fp32::testgen::SplitMix64;
use std::fmt::Write;

/// Uniform in [0, 1).
fn unit(rng: &mut SplitMix64) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

fn uniform(rng: &mut SplitMix64, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * unit(rng)
}

/// Log-uniform in [lo, hi] (both positive).
fn log_uniform(rng: &mut SplitMix64, lo: f64, hi: f64) -> f64 {
    (lo.ln() + (hi.ln() - lo.ln()) * unit(rng)).exp()
}

fn colour(rng: &mut SplitMix64) -> [f32; 3] {
    std::array::from_fn(|_| unit(rng) as f32)
}

/// A depth strictly inside (0, 1), so that the vertex itself passes LESS against 1.0.
fn depth(rng: &mut SplitMix64) -> f32 {
    uniform(rng, 0.02, 0.98) as f32
}

/// Collects window-space triangles into a scene.
struct Builder {
    scene: Scene,
}

impl Builder {
    fn new(name: String, width: u32, height: u32) -> Builder {
        Builder {
            scene: Scene {
                name,
                width,
                height,
                positions: Vec::new(),
                normals: Vec::new(),
                colours: Vec::new(),
                modelview: IDENTITY,
                projection: window_to_clip(width, height),
                shading: Shading::Unlit,
                cull_back: false,
            },
        }
    }

    /// Adds a triangle of (x, y) positions; depth and colour random per vertex.
    fn triangle(&mut self, rng: &mut SplitMix64, xy: [[f64; 2]; 3]) {
        for [x, y] in xy {
            self.vertex([x as f32, y as f32, depth(rng)], colour(rng));
        }
    }

    fn vertex(&mut self, position: [f32; 3], colour: [f32; 3]) {
        self.scene.positions.push(position);
        self.scene.colours.push(colour);
    }
}

/// `count` random triangles of radius 2 px to a third of the window, centred anywhere in
/// the window extended by 10 % on each side, in random windings.
pub fn overlapping(seed: u64, width: u32, height: u32, count: usize) -> Scene {
    let mut rng = SplitMix64::new(seed);
    let mut b = Builder::new(format!("stress-overlapping-{seed}"), width, height);
    let (w, h) = (f64::from(width), f64::from(height));
    for _ in 0..count {
        let centre = [
            uniform(&mut rng, -0.1 * w, 1.1 * w),
            uniform(&mut rng, -0.1 * h, 1.1 * h),
        ];
        let radius = log_uniform(&mut rng, 2.0, w.min(h) / 3.0);
        let xy = std::array::from_fn(|_| {
            let angle = uniform(&mut rng, 0.0, std::f64::consts::TAU);
            let r = radius * uniform(&mut rng, 0.3, 1.0);
            [centre[0] + r * angle.cos(), centre[1] + r * angle.sin()]
        });
        b.triangle(&mut rng, xy);
    }
    b.scene
}

/// `count` slivers: three in four are long triangles (an edge of a quarter of the window
/// or more) whose third vertex lies 0.001–1 px off that edge; the rest are needles, two of
/// whose vertices are within 0.01 px of each other.
pub fn slivers(seed: u64, width: u32, height: u32, count: usize) -> Scene {
    let mut rng = SplitMix64::new(seed);
    let mut b = Builder::new(format!("stress-slivers-{seed}"), width, height);
    let (w, h) = (f64::from(width), f64::from(height));
    let point = |rng: &mut SplitMix64| [uniform(rng, 0.0, w), uniform(rng, 0.0, h)];
    for _ in 0..count {
        let a = point(&mut rng);
        let mut c = point(&mut rng);
        while (c[0] - a[0]).hypot(c[1] - a[1]) < w.min(h) / 4.0 {
            c = point(&mut rng);
        }
        let (dx, dy) = (c[0] - a[0], c[1] - a[1]);
        let length = dx.hypot(dy);
        let xy = if rng.below(4) < 3 {
            let u = uniform(&mut rng, 0.0, 1.0);
            let off = log_uniform(&mut rng, 1e-3, 1.0) * if rng.below(2) == 0 { 1.0 } else { -1.0 };
            let third = [
                a[0] + u * dx - off * dy / length,
                a[1] + u * dy + off * dx / length,
            ];
            [a, third, c]
        } else {
            let angle = uniform(&mut rng, 0.0, std::f64::consts::TAU);
            let r = log_uniform(&mut rng, 1e-4, 1e-2);
            [a, [a[0] + r * angle.cos(), a[1] + r * angle.sin()], c]
        };
        b.triangle(&mut rng, xy);
    }
    b.scene
}

/// Largest distance of a [`huge`] vertex from the window, in pixels.
pub const HUGE_REACH: f64 = 1.0e5;

/// `count` huge triangles: those of even index contain the whole window (vertices
/// 10³–10⁵ px, and at least five window diagonals, from a point inside it, 120° ± 17°
/// apart: each edge then passes at least 0.22 of that distance from the point), the others have an edge through two random points of the
/// window extended to 10³–10⁵ px on both sides, the third vertex as far off to one side.
pub fn huge(seed: u64, width: u32, height: u32, count: usize) -> Scene {
    let mut rng = SplitMix64::new(seed);
    let mut b = Builder::new(format!("stress-huge-{seed}"), width, height);
    let (w, h) = (f64::from(width), f64::from(height));
    let near = (5.0 * w.hypot(h)).max(1e3);
    for t in 0..count {
        let p = [uniform(&mut rng, 0.0, w), uniform(&mut rng, 0.0, h)];
        let xy = if t % 2 == 0 {
            let start = uniform(&mut rng, 0.0, std::f64::consts::TAU);
            std::array::from_fn(|k| {
                let angle =
                    start + k as f64 * std::f64::consts::TAU / 3.0 + uniform(&mut rng, -0.3, 0.3);
                let r = log_uniform(&mut rng, near, HUGE_REACH);
                [p[0] + r * angle.cos(), p[1] + r * angle.sin()]
            })
        } else {
            let q = [uniform(&mut rng, 0.0, w), uniform(&mut rng, 0.0, h)];
            let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
            let length = dx.hypot(dy).max(1e-3);
            let (ux, uy) = (dx / length, dy / length);
            let (ra, rb, rc) = (
                log_uniform(&mut rng, 1e3, HUGE_REACH),
                log_uniform(&mut rng, 1e3, HUGE_REACH),
                log_uniform(&mut rng, 1e3, HUGE_REACH),
            );
            let side = if rng.below(2) == 0 { 1.0 } else { -1.0 };
            let along = uniform(&mut rng, -1.0, 1.0) * HUGE_REACH;
            [
                [p[0] - ra * ux, p[1] - ra * uy],
                [p[0] + rb * ux, p[1] + rb * uy],
                [
                    p[0] + along * ux - side * rc * uy,
                    p[1] + along * uy + side * rc * ux,
                ],
            ]
        };
        b.triangle(&mut rng, xy);
    }
    b.scene
}

/// A `cols × rows` grid of cells tiling the window exactly, each cut into two triangles
/// along a random diagonal. Interior grid vertices are jittered by up to 0.35 of a cell
/// (rounded to multiples of half a pixel when `half_pixel_vertices`); vertices on the
/// window's border stay on it. Positions, depths and colours belong to grid vertices, so
/// neighbouring triangles share them exactly. Each triangle starts at a random vertex and
/// is wound clockwise or counter-clockwise at random. Drawn with LESS and no culling, it
/// covers every pixel exactly once.
pub fn shared_edge_mesh(
    seed: u64,
    width: u32,
    height: u32,
    cols: u32,
    rows: u32,
    half_pixel_vertices: bool,
) -> Scene {
    let mut rng = SplitMix64::new(seed);
    let kind = if half_pixel_vertices {
        "half-pixel-mesh"
    } else {
        "mesh"
    };
    let mut b = Builder::new(format!("stress-{kind}-{seed}"), width, height);
    let (cols, rows) = (cols.max(1), rows.max(1));
    let (cell_w, cell_h) = (
        f64::from(width) / f64::from(cols),
        f64::from(height) / f64::from(rows),
    );
    let snap = |v: f64| {
        if half_pixel_vertices {
            (v * 2.0).round() / 2.0
        } else {
            v
        }
    };
    let mut grid = Vec::new();
    for j in 0..=rows {
        for i in 0..=cols {
            let mut x = f64::from(i) * cell_w;
            let mut y = f64::from(j) * cell_h;
            if i > 0 && i < cols {
                x = snap(x + uniform(&mut rng, -0.35, 0.35) * cell_w);
            }
            if j > 0 && j < rows {
                y = snap(y + uniform(&mut rng, -0.35, 0.35) * cell_h);
            }
            grid.push(([x as f32, y as f32, depth(&mut rng)], colour(&mut rng)));
        }
    }
    let at = |i: u32, j: u32| grid[(j * (cols + 1) + i) as usize];
    for j in 0..rows {
        for i in 0..cols {
            let (p00, p10, p11, p01) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            let halves = if rng.below(2) == 0 {
                [[p00, p10, p11], [p00, p11, p01]]
            } else {
                [[p00, p10, p01], [p10, p11, p01]]
            };
            for mut tri in halves {
                if rng.below(2) == 0 {
                    tri.swap(1, 2);
                }
                tri.rotate_left(rng.below(3) as usize);
                for (position, colour) in tri {
                    b.vertex(position, colour);
                }
            }
        }
    }
    b.scene
}

/// The standard stress set for a `width × height` window: overlapping (200), slivers
/// (300), huge (12), a 12 × 12 mesh and a 16 × 16 half-pixel mesh.
pub fn all(seed: u64, width: u32, height: u32) -> Vec<Scene> {
    vec![
        overlapping(seed, width, height, 200),
        slivers(seed.wrapping_add(1), width, height, 300),
        huge(seed.wrapping_add(2), width, height, 12),
        shared_edge_mesh(seed.wrapping_add(3), width, height, 12, 12, false),
        shared_edge_mesh(seed.wrapping_add(4), width, height, 16, 16, true),
    ]
}

/// The `.tri` text of a window-space, unlit scene (one made here or read by `parse_tri`):
/// an error for other scenes.
pub fn to_tri(scene: &Scene) -> Result<String, String> {
    if scene.shading != Shading::Unlit
        || scene.modelview != IDENTITY
        || scene.projection != window_to_clip(scene.width, scene.height)
        || scene.cull_back
    {
        return Err(format!(
            "scene `{}` is not an unlit, unculled window-space scene",
            scene.name
        ));
    }
    scene.validate().map_err(|e| e.to_string())?;
    let mut text = format!("# {}\n{} {}\n", scene.name, scene.width, scene.height);
    for (p, c) in scene.positions.chunks(3).zip(scene.colours.chunks(3)) {
        let fields: Vec<String> = (0..3)
            .flat_map(|k| [p[k][0], p[k][1], p[k][2], c[k][0], c[k][1], c[k][2]])
            .map(|v| v.to_string())
            .collect();
        writeln!(text, "{}", fields.join(" ")).expect("writing to a String");
    }
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference;
    use imagine_pipelines::scene::parse_tri;

    #[test]
    fn generators_are_deterministic_valid_and_tri_compatible() {
        for scene in all(7, 96, 80) {
            scene.validate().unwrap();
            assert!(scene.triangles() > 0);
            let again = all(7, 96, 80)
                .into_iter()
                .find(|s| s.name == scene.name)
                .unwrap();
            assert_eq!(again, scene);
            let text = to_tri(&scene).unwrap();
            let mut back = parse_tri(&scene.name, &text).unwrap_or_else(|e| panic!("{e}"));
            back.name = scene.name.clone();
            assert_eq!(back, scene, "{}", scene.name);
        }
        assert_ne!(overlapping(1, 64, 64, 10), overlapping(2, 64, 64, 10));
        assert!(to_tri(&imagine_pipelines::scene::sphere(1, 64)).is_err());
    }

    #[test]
    fn huge_triangles_reach_far_and_cover_the_window() {
        let scene = huge(3, 64, 64, 12);
        let far = scene
            .positions
            .iter()
            .map(|p| p[0].abs().max(p[1].abs()))
            .fold(0f32, f32::max);
        assert!(far > 1e4 && f64::from(far) < 2.0 * HUGE_REACH, "{far}");
        // The window-containing ones (even indices) cover every pixel.
        let mut hits = vec![0u32; 64 * 64];
        reference::for_each_fragment(&scene, |f| {
            if f.triangle % 2 == 0 {
                hits[(f.y * 64 + f.x) as usize] += 1;
            }
        })
        .unwrap();
        assert!(hits.iter().all(|&h| h == 6), "{:?}", &hits[..8]);
    }

    #[test]
    fn meshes_cover_every_pixel_exactly_once() {
        for half_pixel in [false, true] {
            for (seed, (w, h), (cols, rows)) in [
                (1, (64, 48), (8, 6)),
                (2, (100, 100), (16, 16)),
                (3, (37, 53), (5, 9)),
                // Power-of-two sides keep window_to_clip exact: half-pixel ties survive.
                (4, (64, 64), (8, 8)),
                (5, (128, 32), (16, 4)),
            ] {
                let scene = shared_edge_mesh(seed, w, h, cols, rows, half_pixel);
                let mut hits = vec![0u32; (w * h) as usize];
                reference::for_each_fragment(&scene, |f| hits[(f.y * w + f.x) as usize] += 1)
                    .unwrap();
                let bad: Vec<usize> = (0..hits.len()).filter(|&i| hits[i] != 1).collect();
                assert!(
                    bad.is_empty(),
                    "{}: {} pixels not covered once, first at ({}, {})",
                    scene.name,
                    bad.len(),
                    bad[0] as u32 % w,
                    bad[0] as u32 / w
                );
            }
        }
    }

    #[test]
    fn half_pixel_meshes_put_edges_through_pixel_centres() {
        // Count samples exactly on an edge (some E_i == 0 at a covered sample): the tie
        // rule must be exercised for the mesh test to mean something.
        let scene = shared_edge_mesh(5, 64, 64, 8, 8, true);
        let mut on_edge = 0;
        for t in scene.positions.chunks(3) {
            for py in 0..64 {
                for px in 0..64 {
                    let (x, y) = (px as f32 + 0.5, py as f32 + 0.5);
                    for k in 0..3 {
                        let (a, b) = (t[k], t[(k + 1) % 3]);
                        let e = (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]);
                        let within = |v: f32, p: f32, q: f32| v >= p.min(q) && v <= p.max(q);
                        if e == 0.0 && within(x, a[0], b[0]) && within(y, a[1], b[1]) {
                            on_edge += 1;
                        }
                    }
                }
            }
        }
        assert!(on_edge > 20, "{on_edge}");
    }

    #[test]
    fn slivers_are_thin() {
        let scene = slivers(9, 128, 128, 100);
        let thin = scene
            .positions
            .chunks(3)
            .filter(|t| {
                let (a, b, c) = (t[0], t[1], t[2]);
                let area2 = ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])).abs();
                let longest = [(a, b), (b, c), (c, a)]
                    .iter()
                    .map(|(p, q)| (q[0] - p[0]).hypot(q[1] - p[1]))
                    .fold(0f32, f32::max);
                area2 / longest <= 1.01 // height ≤ 1 px
            })
            .count();
        assert_eq!(thin, 100);
    }
}
