//! Generated geometry for scene files: the icosphere of SPHERE, a latitude-longitude
//! sphere, the window-space strips of RATE-n, and the procedural checker texture.

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
/// normals equal to the positions, counter-clockwise seen from outside.
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
        triangles: (0..m.triangles.len() as u32)
            .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect(),
        separate: true,
    }
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

    #[test]
    fn scene_primitives_checker_corners() {
        let t = checker(4, 2, [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]);
        assert_eq!(t[0], 0xff00_00ff);
        assert_eq!(t[2], 0xffff_0000);
        assert_eq!(t[2 * 4 + 2], 0xff00_00ff);
    }
}
