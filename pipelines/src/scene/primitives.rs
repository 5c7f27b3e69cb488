//! Generated geometry for scene files: the icosphere of SPHERE, a latitude-longitude
//! sphere, the window-space strips of RATE-n, the procedural checker and rectangles
//! textures, and the geometry of the analogs of the thesis's published scenes (Owens 2002,
//! Table 5.1):
//!
//! * [`pin`] (PIN, PIN-8, MARBLE): a bowling pin as a surface of revolution, diced into
//!   `rings` bands of `segments` quads, each band a closed strip with two rows of vertices
//!   of its own, as the thesis's 200 × 200 pin has V = T = 80,000. The profile is a
//!   plausible tenpin after the USBC specification (15 in tall, 4.766 in at the belly, 4.5 in
//!   up; 1.797 in at the neck; 2.547 in at the head; 2.03 in at the base); the UNC "Textbook
//!   Strike" model itself is not public.
//! * [`banded_sphere`] (VERONA): the unit sphere in the same banded form (200 × 200: V = T =
//!   80,000, the thesis's "200×200 tessellated sphere").
//! * [`boxes`], [`tiles`] and [`torus`] (ADVS-1, ADVS-8): boxes and floor tiles whose every
//!   face is a quad of four vertices of its own (each face carries the whole texture), and
//!   a torus for the curved parts. SPECviewperf's "Advanced Visualizer" frame is not public;
//!   `scenes/ADVS-1.toml` builds one with the published counts from these.
//!
//! Closed strips wrap round: their last quad joins the row's last vertex to its first, so
//! `s` runs from `(segments − 1)/segments` back to 0 across it (the seam). Scenes turn the
//! seam away from the camera, where it is culled.

use std::collections::HashMap;

use super::model::Mesh;

pub use imagine_units::limits::MAX_SUBDIVISIONS;

/// The unit icosphere of [`super::icosphere`] as an indexed mesh: the same vertex
/// positions and triangle order, each distinct position stored once (in order of first
/// use), normals equal to the positions.
pub fn icosphere(subdivisions: u32) -> Mesh {
    let tris = super::icosphere(subdivisions);
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let triangles = tris
        .iter()
        .map(|t| {
            t.map(|p| {
                *index.entry(p.map(f32::to_bits)).or_insert_with(|| {
                    positions.push(p);
                    positions.len() as u32 - 1
                })
            })
        })
        .collect();
    Mesh {
        normals: positions.clone(),
        positions,
        triangles,
        ..Mesh::default()
    }
}

/// A unit sphere of `rings` latitude bands (pole to pole, from +y) by `segments`
/// longitude slices: `(rings + 1)·(segments + 1)` vertices (the seam and the poles are
/// repeated so that texture coordinates run s = 0..1 round the sphere from +z towards +x
/// and t = 0..1 from the south pole to the north), `2·rings·segments` triangles (those
/// touching a pole have zero area, as a diced 200 × 200 sphere has 80,000 triangles),
/// normals equal to the positions, tangents the unit `∂P/∂φ` `(cos φ, 0, −sin φ)`,
/// counter-clockwise seen from outside.
pub fn uv_sphere(rings: u32, segments: u32) -> Mesh {
    let mut m = Mesh::default();
    for i in 0..=rings {
        let theta = std::f64::consts::PI * f64::from(i) / f64::from(rings);
        for j in 0..=segments {
            let phi = 2.0 * std::f64::consts::PI * f64::from(j) / f64::from(segments);
            let p = [
                theta.sin() * phi.sin(),
                theta.cos(),
                theta.sin() * phi.cos(),
            ];
            let p = p.map(|c| c as f32);
            m.positions.push(p);
            m.normals.push(p);
            m.tangents
                .push([phi.cos(), 0.0, -phi.sin()].map(|c| c as f32));
            m.texcoords.push([
                (f64::from(j) / f64::from(segments)) as f32,
                (1.0 - f64::from(i) / f64::from(rings)) as f32,
            ]);
        }
    }
    let at = |i: u32, j: u32| i * (segments + 1) + j;
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            m.triangles.push([a, b, c]);
            m.triangles.push([a, c, d]);
        }
    }
    m
}

/// RATE-n's geometry in a `width × height` window, in pixels: rows of
/// [`super::rate_cell`] cells from the bottom left, each cut into the two
/// counter-clockwise triangles `(x0,y0) (x1,y0) (x1,y1)` and `(x0,y0) (x1,y1) (x0,y1)`, all
/// at depth 0.5, coloured `(x / width, y / height, 0.5)`. Grid corners are shared; made
/// separate ([`separate`]) it is exactly the old [`super::rate`].
pub fn rate(n: u32, width: u32, height: u32) -> Result<Mesh, String> {
    if !(1..=128).contains(&n) || !n.is_power_of_two() {
        return Err(format!(
            "size = {n}: the triangle size must be a power of two from 1 to 128 pixels"
        ));
    }
    let (w, h) = super::rate_cell(n);
    if !width.is_multiple_of(w) || !height.is_multiple_of(h) {
        return Err(format!(
            "size = {n}: {w}x{h}-pixel cells do not tile a {width}x{height} window"
        ));
    }
    let (cols, rows) = (width / w, height / h);
    let mut m = Mesh::default();
    for row in 0..=rows {
        for col in 0..=cols {
            let (x, y) = (col * w, row * h);
            m.positions.push([x as f32, y as f32, 0.5]);
            m.colours
                .push([x as f32 / width as f32, y as f32 / height as f32, 0.5]);
        }
    }
    let at = |col: u32, row: u32| row * (cols + 1) + col;
    for row in 0..rows {
        for col in 0..cols {
            let (a, b) = (at(col, row), at(col + 1, row));
            let (c, d) = (at(col + 1, row + 1), at(col, row + 1));
            m.triangles.push([a, b, c]);
            m.triangles.push([a, c, d]);
        }
    }
    Ok(m)
}

/// The same triangles with three vertices of their own each (`triangles[i] = [3i, 3i+1,
/// 3i+2]`, [`Mesh::separate`]).
pub fn separate(m: &Mesh) -> Mesh {
    fn expand<T: Copy>(v: &[T], tris: &[[u32; 3]]) -> Vec<T> {
        if v.is_empty() {
            return Vec::new();
        }
        tris.iter().flatten().map(|&i| v[i as usize]).collect()
    }
    Mesh {
        positions: expand(&m.positions, &m.triangles),
        normals: expand(&m.normals, &m.triangles),
        colours: expand(&m.colours, &m.triangles),
        texcoords: expand(&m.texcoords, &m.triangles),
        tangents: expand(&m.tangents, &m.triangles),
        triangles: (0..m.triangles.len() as u32)
            .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect(),
        separate: true,
    }
}

/// Appends a quad of four vertices of its own: `o`, `o + u`, `o + u + v`, `o + v`, with
/// texture coordinates (0, 0), (1, 0), (1, 1), (0, 1), the normal `u × v` normalised, and
/// the triangles `[0, 1, 2]`, `[0, 2, 3]` (counter-clockwise seen from where `u × v` points).
fn push_quad(m: &mut Mesh, o: [f64; 3], u: [f64; 3], v: [f64; 3]) {
    let n = super::normalized([
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]);
    let base = m.positions.len() as u32;
    let corners = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)];
    for (a, b) in corners {
        let p: [f64; 3] = std::array::from_fn(|k| o[k] + a * u[k] + b * v[k]);
        m.positions.push(p.map(|c| c as f32));
        m.normals.push(n.map(|c| c as f32));
        m.texcoords.push([a as f32, b as f32]);
    }
    m.triangles.push([base, base + 1, base + 2]);
    m.triangles.push([base, base + 2, base + 3]);
}

/// SplitMix64 (Steele, Lea and Flood 2014): the boxes' deterministic random numbers.
struct SplitMix(u64);

impl SplitMix {
    /// A uniform number in [lo, hi).
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        lo + (hi - lo) * ((z >> 11) as f64 / (1u64 << 53) as f64)
    }
}

/// `count` boxes standing on the square [−1, 1]² of the plane y = 0, one to a cell of the
/// smallest square lattice that holds them (filled row by row from x = −1, z = −1), each
/// with a random footprint of 30–90 % of its cell a side, placed at random within it, and a
/// random height of 0.2–2.5 cells (`seed` picks them). Each box is six quads of four
/// vertices of their own ([`push_quad`]: 24 vertices, 12 triangles), in the order +x, −x,
/// +z, −z, +y, −y, with face normals and the whole texture on every face.
pub fn boxes(count: u32, seed: u64) -> Mesh {
    let n = (1..).find(|&n: &u32| u64::from(n) * u64::from(n) >= u64::from(count));
    let n = n.expect("a lattice holds them");
    let cell = 2.0 / f64::from(n);
    let mut rng = SplitMix(seed);
    let mut m = Mesh::default();
    for i in 0..count {
        let (cx, cz) = (
            -1.0 + cell * f64::from(i % n),
            -1.0 + cell * f64::from(i / n),
        );
        let (w, d) = (rng.uniform(0.3, 0.9) * cell, rng.uniform(0.3, 0.9) * cell);
        let x0 = cx + rng.uniform(0.0, cell - w);
        let z0 = cz + rng.uniform(0.0, cell - d);
        let h = rng.uniform(0.2, 2.5) * cell;
        let (x1, z1) = (x0 + w, z0 + d);
        let (x, y, z) = ([w, 0.0, 0.0], [0.0, h, 0.0], [0.0, 0.0, d]);
        let neg = |v: [f64; 3]| v.map(|c| -c);
        push_quad(&mut m, [x1, 0.0, z1], neg(z), y);
        push_quad(&mut m, [x0, 0.0, z0], z, y);
        push_quad(&mut m, [x0, 0.0, z1], x, y);
        push_quad(&mut m, [x1, 0.0, z0], neg(x), y);
        push_quad(&mut m, [x0, h, z1], x, neg(z));
        push_quad(&mut m, [x0, 0.0, z0], x, z);
    }
    m
}

/// A floor of `columns × rows` tiles covering [−1, 1]² of the plane y = 0, facing +y, row
/// by row from z = +1: each tile a quad of four vertices of its own ([`push_quad`]), the
/// whole texture on each.
pub fn tiles(columns: u32, rows: u32) -> Mesh {
    let (dx, dz) = (2.0 / f64::from(columns), 2.0 / f64::from(rows));
    let mut m = Mesh::default();
    for r in 0..rows {
        for c in 0..columns {
            let (x0, z1) = (-1.0 + dx * f64::from(c), 1.0 - dz * f64::from(r));
            push_quad(&mut m, [x0, 0.0, z1], [dx, 0.0, 0.0], [0.0, 0.0, -dz]);
        }
    }
    m
}

/// A torus round the y axis: major radius 1, tube radius `minor`, `rings` quads round the
/// tube by `segments` round the axis, two triangles each (`2·rings·segments`), the seam
/// vertices repeated (`(rings + 1)·(segments + 1)` vertices) so that s = 0..1 runs round
/// the axis from +z towards +x and t = 0..1 round the tube from its outer equator, upwards.
/// Counter-clockwise seen from outside.
pub fn torus(rings: u32, segments: u32, minor: f64) -> Mesh {
    use std::f64::consts::TAU;
    let mut m = Mesh::default();
    for i in 0..=rings {
        let theta = TAU * f64::from(i) / f64::from(rings);
        for j in 0..=segments {
            let phi = TAU * f64::from(j) / f64::from(segments);
            let out = [phi.sin(), 0.0, phi.cos()];
            let n = [theta.cos() * out[0], theta.sin(), theta.cos() * out[2]];
            let p: [f64; 3] = std::array::from_fn(|k| out[k] + minor * n[k]);
            m.positions.push(p.map(|c| c as f32));
            m.normals.push(n.map(|c| c as f32));
            m.texcoords.push([
                (f64::from(j) / f64::from(segments)) as f32,
                (f64::from(i) / f64::from(rings)) as f32,
            ]);
        }
    }
    let at = |i: u32, j: u32| i * (segments + 1) + j;
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j));
            m.triangles.push([a, b, c]);
            m.triangles.push([a, c, d]);
        }
    }
    m
}

/// One point of a profile revolved about the y axis: radius, height, the outward unit
/// normal in the (r, y) plane, and the texture coordinate t.
#[derive(Clone, Copy, Debug)]
struct ProfilePoint {
    r: f64,
    y: f64,
    nr: f64,
    ny: f64,
    t: f64,
}

/// The profile (`bands + 1` points, upwards) revolved about y into `bands` closed strips
/// of `segments` quads: band `k` has its own row of `segments` vertices at point `k` then
/// its own row at point `k + 1` (`2·segments` vertices, `2·segments` triangles), quad `j`
/// being `[U_j, L_j, L_{j+1}]`, `[U_j, L_{j+1}, U_{j+1}]` with `j + 1` taken mod
/// `segments`. Angle φ_j = 2πj/segments from +z towards +x, s = j/segments; the tangent
/// is the unit `∂P/∂φ` direction `(cos φ, 0, −sin φ)` (defined at the poles too).
fn banded_revolution(profile: &[ProfilePoint], segments: u32) -> Mesh {
    let mut m = Mesh::default();
    for band in profile.windows(2) {
        let base = m.positions.len() as u32;
        for p in band {
            for j in 0..segments {
                let phi = std::f64::consts::TAU * f64::from(j) / f64::from(segments);
                let (s, c) = phi.sin_cos();
                m.positions.push([p.r * s, p.y, p.r * c].map(|v| v as f32));
                m.normals.push([p.nr * s, p.ny, p.nr * c].map(|v| v as f32));
                m.tangents.push([c, 0.0, -s].map(|v| v as f32));
                m.texcoords
                    .push([(f64::from(j) / f64::from(segments)) as f32, p.t as f32]);
            }
        }
        for j in 0..segments {
            let j1 = (j + 1) % segments;
            let (l, u) = (|j| base + j, |j| base + segments + j);
            m.triangles.push([u(j), l(j), l(j1)]);
            m.triangles.push([u(j), l(j1), u(j1)]);
        }
    }
    m
}

/// The unit sphere as `rings` banded closed strips of `segments` quads
/// ([`banded_revolution`]): `2·rings·segments` vertices and as many triangles (200 × 200:
/// the thesis's V = T = 80,000), from the south pole (t = 0) to the north (t = 1), normals
/// equal to the positions. The bands at the poles have a row of coincident vertices, so
/// half their triangles have zero area.
pub fn banded_sphere(rings: u32, segments: u32) -> Mesh {
    let profile: Vec<ProfilePoint> = (0..=rings)
        .map(|k| {
            let t = f64::from(k) / f64::from(rings);
            let theta = std::f64::consts::PI * (1.0 - t);
            let (r, y) = (theta.sin(), theta.cos());
            ProfilePoint {
                r,
                y,
                nr: r,
                ny: y,
                t,
            }
        })
        .collect();
    banded_revolution(&profile, segments)
}

/// The tenpin's outline as (radius, height) in inches, base centre to tip: a rounded base
/// edge (2.1 in across), the belly (4.766 in at 4.5 in), the neck (1.8 in near 10.2 in), the
/// head (2.547 in at 13.5 in) and a rounded top at 15 in.
const PIN_OUTLINE: [(f64, f64); 20] = [
    (0.0, 0.0),
    (0.6, 0.0),
    (0.95, 0.03),
    (1.06, 0.18),
    (1.45, 0.75),
    (1.9, 1.75),
    (2.22, 3.0),
    (2.383, 4.5),
    (2.28, 6.0),
    (1.9, 7.5),
    (1.35, 8.9),
    (0.97, 9.8),
    (0.9, 10.3),
    (0.98, 11.2),
    (1.2, 12.4),
    (1.273, 13.4),
    (1.16, 14.3),
    (0.82, 14.78),
    (0.42, 14.96),
    (0.0, 15.0),
];

/// Height of the pin in [`PIN_OUTLINE`]'s inches.
const PIN_HEIGHT: f64 = 15.0;

/// A point of the centripetal Catmull-Rom spline through `p` (Barry and Goldman's
/// pyramid), at `u ∈ [0, 1]` along segment `i` (from `p[i]` to `p[i + 1]`); the end points
/// are reflected to make the missing neighbours.
fn catmull_rom(p: &[(f64, f64)], i: usize, u: f64) -> (f64, f64) {
    let at = |k: isize| -> (f64, f64) {
        let n = p.len() as isize;
        if k < 0 {
            (2.0 * p[0].0 - p[1].0, 2.0 * p[0].1 - p[1].1)
        } else if k >= n {
            let (a, b) = (p[(n - 1) as usize], p[(n - 2) as usize]);
            (2.0 * a.0 - b.0, 2.0 * a.1 - b.1)
        } else {
            p[k as usize]
        }
    };
    let i = i as isize;
    let q = [at(i - 1), at(i), at(i + 1), at(i + 2)];
    let dist = |a: (f64, f64), b: (f64, f64)| ((a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)).sqrt();
    let mut t = [0.0; 4];
    for k in 1..4 {
        t[k] = t[k - 1] + dist(q[k - 1], q[k]).sqrt().max(1e-9);
    }
    let lerp = |a: (f64, f64), b: (f64, f64), ta: f64, tb: f64, x: f64| {
        let w = (x - ta) / (tb - ta);
        (a.0 + w * (b.0 - a.0), a.1 + w * (b.1 - a.1))
    };
    let x = t[1] + u * (t[2] - t[1]);
    let a1 = lerp(q[0], q[1], t[0], t[1], x);
    let a2 = lerp(q[1], q[2], t[1], t[2], x);
    let a3 = lerp(q[2], q[3], t[2], t[3], x);
    let b1 = lerp(a1, a2, t[0], t[2], x);
    let b2 = lerp(a2, a3, t[1], t[3], x);
    lerp(b1, b2, t[1], t[2], x)
}

/// The pin's profile as `rings + 1` points spaced evenly along its arc (the spline through
/// [`PIN_OUTLINE`], measured on a polyline of 64 steps per span), scaled to height 1:
/// radius and height, the outward normal of the outline there (its tangent, by central
/// differences, turned clockwise), and t = height (0 at the base, 1 at the tip). Heights
/// are clamped at 0 (the spline dips a hair below the base near its edge).
fn pin_profile(rings: u32) -> Vec<ProfilePoint> {
    const STEPS: usize = 64;
    let spans = PIN_OUTLINE.len() - 1;
    let mut dense = vec![PIN_OUTLINE[0]];
    for i in 0..spans {
        for k in 1..=STEPS {
            dense.push(catmull_rom(&PIN_OUTLINE, i, k as f64 / STEPS as f64));
        }
    }
    let mut arc = vec![0.0];
    for w in dense.windows(2) {
        let d = ((w[1].0 - w[0].0).powi(2) + (w[1].1 - w[0].1).powi(2)).sqrt();
        arc.push(arc.last().unwrap() + d);
    }
    let total = *arc.last().unwrap();
    // The outline's point at arc length `s`, linear between the dense points.
    let point = |s: f64| -> (f64, f64) {
        let s = s.clamp(0.0, total);
        let k = arc.partition_point(|&a| a < s).clamp(1, arc.len() - 1);
        let w = (s - arc[k - 1]) / (arc[k] - arc[k - 1]).max(1e-12);
        let (a, b) = (dense[k - 1], dense[k]);
        (a.0 + w * (b.0 - a.0), a.1 + w * (b.1 - a.1))
    };
    let step = total / f64::from(rings);
    (0..=rings)
        .map(|k| {
            let s = step * f64::from(k);
            let (r, y) = point(s);
            let y = y.max(0.0);
            let (a, b) = (point(s - step / 2.0), point(s + step / 2.0));
            let (dr, dy) = (b.0 - a.0, b.1 - a.1);
            let len = (dr * dr + dy * dy).sqrt();
            let r = if k == 0 || k == rings { 0.0 } else { r };
            ProfilePoint {
                r: r / PIN_HEIGHT,
                y: y / PIN_HEIGHT,
                nr: dy / len,
                ny: -dr / len,
                t: y / PIN_HEIGHT,
            }
        })
        .collect()
}

/// The bowling pin: [`pin_profile`] revolved ([`banded_revolution`]) into `rings` bands of
/// `segments` quads, `2·rings·segments` vertices and as many triangles (200 × 200: the
/// thesis's PIN, V = T = 80,000). It stands on y = 0 with its tip at y = 1 (its radius at
/// the belly is 0.159); s runs round it from +z towards +x, t up it (t = y).
pub fn pin(rings: u32, segments: u32) -> Mesh {
    banded_revolution(&pin_profile(rings), segments)
}

/// An RGBA8 word, red in the low byte, from a colour in [0, 1] (alpha 1).
pub fn rgba8(c: [f32; 3]) -> u32 {
    let b = c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u32);
    b[0] | (b[1] << 8) | (b[2] << 16) | (255 << 24)
}

/// A `size × size` checkerboard of `cells × cells` squares, texel `(col, row)` (row 0 at
/// the bottom) in `colours[(col·cells/size + row·cells/size) mod 2]`: the bottom-left
/// square has the first colour.
pub fn checker(size: u32, cells: u32, colours: [[f32; 3]; 2]) -> Vec<u32> {
    let words = colours.map(rgba8);
    let mut texels = Vec::with_capacity((size * size) as usize);
    for row in 0..size {
        for col in 0..size {
            let k = (u64::from(col) * u64::from(cells) / u64::from(size)
                + u64::from(row) * u64::from(cells) / u64::from(size))
                % 2;
            texels.push(words[k as usize]);
        }
    }
    texels
}

/// A `size × size` texture of `background` with the `rectangles` `[s0, t0, s1, t1]` (in
/// texture coordinates, t = 0 at the bottom) in `fill`: texel `(col, row)` is filled when
/// its centre ((col + 0.5)/size, (row + 0.5)/size) lies in `[s0, s1) × [t0, t1)` of one.
pub fn rectangles(size: u32, rectangles: &[[f64; 4]], colours: [[f32; 3]; 2]) -> Vec<u32> {
    let [background, fill] = colours.map(rgba8);
    let mut texels = Vec::with_capacity((size * size) as usize);
    for row in 0..size {
        let t = (f64::from(row) + 0.5) / f64::from(size);
        for col in 0..size {
            let s = (f64::from(col) + 0.5) / f64::from(size);
            let inside = rectangles
                .iter()
                .any(|&[s0, t0, s1, t1]| (s0..s1).contains(&s) && (t0..t1).contains(&t));
            texels.push(if inside { fill } else { background });
        }
    }
    texels
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    }

    fn outward(m: &Mesh) {
        for t in &m.triangles {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            let n = cross(
                std::array::from_fn(|k| b[k] - a[k]),
                std::array::from_fn(|k| c[k] - a[k]),
            );
            let area: f32 = n.iter().map(|c| c * c).sum();
            if area > 1e-12 {
                let dot: f32 = (0..3).map(|k| n[k] * (a[k] + b[k] + c[k])).sum();
                assert!(
                    dot > 0.0,
                    "triangle {t:?} winds clockwise seen from outside"
                );
            }
        }
    }

    #[test]
    fn scene_primitives_icosphere_shares_the_old_positions() {
        let m = icosphere(2);
        let old = crate::scene::icosphere(2);
        assert_eq!(m.triangles.len(), old.len());
        assert_eq!(m.positions.len(), 10 * 16 + 2);
        for (t, o) in m.triangles.iter().zip(&old) {
            assert_eq!(t.map(|i| m.positions[i as usize]), *o);
        }
        outward(&m);
        let s = separate(&m);
        assert_eq!(
            s.positions,
            old.iter().flatten().copied().collect::<Vec<_>>()
        );
    }

    #[test]
    fn scene_primitives_uv_sphere_counts_and_winding() {
        let m = uv_sphere(4, 8);
        assert_eq!(m.positions.len(), 5 * 9);
        assert_eq!(m.triangles.len(), 2 * 4 * 8);
        assert_eq!(m.texcoords.len(), m.positions.len());
        outward(&m);
    }

    /// Every triangle of positive area winds counter-clockwise seen from where the mesh's
    /// normals point (its geometric normal agrees with its corners' normals).
    fn agrees_with_normals(m: &Mesh) {
        for t in &m.triangles {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            let n = cross(
                std::array::from_fn(|k| b[k] - a[k]),
                std::array::from_fn(|k| c[k] - a[k]),
            );
            let len: f32 = n.iter().map(|c| c * c).sum::<f32>().sqrt();
            let edge: f32 = (0..3).map(|k| (b[k] - a[k]).abs()).sum();
            if len > 1e-5 * edge * edge {
                for i in t {
                    let v = m.normals[*i as usize];
                    let dot: f32 = (0..3).map(|k| n[k] * v[k]).sum();
                    assert!(dot > 0.0, "triangle {t:?} winds against its normals");
                }
            }
        }
    }

    #[test]
    fn scene_primitives_published_counts() {
        for m in [pin(200, 200), banded_sphere(200, 200)] {
            assert_eq!((m.positions.len(), m.triangles.len()), (80_000, 80_000));
            assert_eq!(m.normals.len(), m.positions.len());
            assert_eq!(m.texcoords.len(), m.positions.len());
            agrees_with_normals(&m);
        }
        let b = boxes(1078, 1);
        assert_eq!(
            (b.positions.len(), b.triangles.len()),
            (1078 * 24, 1078 * 12)
        );
        let f = tiles(32, 25);
        assert_eq!((f.positions.len(), f.triangles.len()), (800 * 4, 800 * 2));
        let t = torus(36, 84, 0.3);
        assert_eq!(
            (t.positions.len(), t.triangles.len()),
            (37 * 85, 2 * 36 * 84)
        );
        for m in [&b, &f, &t] {
            agrees_with_normals(m);
        }
        outward(&banded_sphere(8, 12));
    }

    #[test]
    fn scene_primitives_pin_shape() {
        let m = pin(200, 200);
        let ys = m.positions.iter().map(|p| p[1]);
        let (lo, hi) = ys.fold((f32::MAX, f32::MIN), |(a, b), y| (a.min(y), b.max(y)));
        assert_eq!((lo, hi), (0.0, 1.0));
        let radius = |p: &[f32; 3]| (p[0] * p[0] + p[2] * p[2]).sqrt();
        let widest = m
            .positions
            .iter()
            .max_by(|a, b| radius(a).total_cmp(&radius(b)));
        let widest = widest.unwrap();
        // The belly: 4.766 in across, 4.5 in up a 15 in pin.
        assert!((radius(widest) - 2.383 / 15.0).abs() < 0.002, "{widest:?}");
        assert!((widest[1] - 0.3).abs() < 0.02, "{widest:?}");
        // Each band's rows are its own: band 1 starts where band 0's top row is repeated.
        assert_eq!(m.positions[400], m.positions[200]);
        assert!(m.texcoords.iter().all(|t| (0.0..=1.0).contains(&t[1])));
        let s = banded_sphere(4, 6);
        assert!(
            s.positions
                .iter()
                .all(|p| (p.iter().map(|c| c * c).sum::<f32>() - 1.0).abs() < 1e-6)
        );
    }

    #[test]
    fn scene_primitives_rectangles() {
        let t = rectangles(4, &[[0.0, 0.5, 1.0, 0.75]], [[1.0; 3], [1.0, 0.0, 0.0]]);
        assert_eq!(t[0], 0xffff_ffff);
        assert_eq!(t[2 * 4 + 3], 0xff00_00ff);
        assert_eq!(t[3 * 4], 0xffff_ffff);
    }

    #[test]
    fn scene_primitives_checker_corners() {
        let t = checker(4, 2, [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]);
        assert_eq!(t[0], 0xff00_00ff);
        assert_eq!(t[2], 0xffff_0000);
        assert_eq!(t[2 * 4 + 2], 0xff00_00ff);
    }
}
