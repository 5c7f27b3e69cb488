//! Wavefront OBJ meshes (`v`, `vn`, `vt`, `f`) through `tobj`: polygons fanned from their
//! first corner, 1-based and negative indices, one index per vertex (a vertex is a distinct
//! `v/vt/vn` triple, shared by the faces that name it). Other statements are ignored.

use super::model::Mesh;

/// A problem in an asset file, at a line where one is known.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AssetError {
    pub line: Option<usize>,
    pub message: String,
}

impl AssetError {
    pub fn new(line: Option<usize>, message: impl Into<String>) -> Self {
        AssetError {
            line,
            message: message.into(),
        }
    }
}

/// Reads an OBJ's text. With `lit`, faces without normals get their geometric normal (their
/// vertices are then repeated per face, so that each face keeps its own normal); without,
/// the mesh has normals only where the file gives them for every face.
pub fn parse(text: &str, lit: bool) -> Result<Mesh, AssetError> {
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    check_indices(text)?;
    let (models, _) = tobj::load_obj_buf(&mut text.as_bytes(), &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| locate(text, e))?;
    let mut mesh = Mesh::default();
    for model in &models {
        let m = &model.mesh;
        let count = m.positions.len() / 3;
        let group = if model.name.is_empty() || model.name == "unnamed_object" {
            String::new()
        } else {
            format!("group `{}`: ", model.name)
        };
        let mixed = |what: &str, have: usize| {
            AssetError::new(
                None,
                format!(
                    "{group}{have} of {count} vertices have {what}: give them on every face \
                     of a group or on none"
                ),
            )
        };
        let has_normals = !m.normals.is_empty();
        if has_normals && m.normals.len() != m.positions.len() {
            return Err(mixed("normals", m.normals.len() / 3));
        }
        let has_texcoords = !m.texcoords.is_empty();
        if has_texcoords && m.texcoords.len() / 2 != count {
            return Err(mixed("texture coordinates", m.texcoords.len() / 2));
        }
        let base = mesh.positions.len() as u32;
        let three = |v: &[f32], i: usize| [v[3 * i], v[3 * i + 1], v[3 * i + 2]];
        let tris = m.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]);
        if lit && !has_normals {
            // Each face its own three vertices, with the face's normal.
            for t in tris {
                let p = t.map(|i| three(&m.positions, i as usize));
                let n = geometric_normal(p);
                let first = mesh.positions.len() as u32;
                for (k, &i) in t.iter().enumerate() {
                    mesh.positions.push(p[k]);
                    mesh.normals.push(n);
                    if has_texcoords {
                        let i = i as usize;
                        mesh.texcoords
                            .push([m.texcoords[2 * i], m.texcoords[2 * i + 1]]);
                    }
                }
                mesh.triangles.push([first, first + 1, first + 2]);
            }
        } else {
            for i in 0..count {
                mesh.positions.push(three(&m.positions, i));
                if has_normals {
                    mesh.normals.push(three(&m.normals, i));
                }
                if has_texcoords {
                    mesh.texcoords
                        .push([m.texcoords[2 * i], m.texcoords[2 * i + 1]]);
                }
            }
            mesh.triangles.extend(tris.map(|t| t.map(|i| base + i)));
        }
        // Groups must agree: all with normals (texture coordinates) or none.
        for (what, have) in [
            ("normals", mesh.normals.len()),
            ("texture coordinates", mesh.texcoords.len()),
        ] {
            if have != 0 && have != mesh.positions.len() {
                return Err(AssetError::new(
                    None,
                    format!(
                        "{group}some groups have {what} and others do not: give them on every \
                         face or on none"
                    ),
                ));
            }
        }
    }
    if mesh.triangles.is_empty() {
        return Err(AssetError::new(None, "the mesh has no faces (`f` lines)"));
    }
    for (what, v) in [("position", &mesh.positions), ("normal", &mesh.normals)] {
        if let Some(i) = v.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(AssetError::new(
                None,
                format!("vertex {i}'s {what} is not a finite number"),
            ));
        }
    }
    if let Some(i) = mesh
        .texcoords
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(AssetError::new(
            None,
            format!("vertex {i}'s texture coordinate is not a finite number"),
        ));
    }
    Ok(mesh)
}

/// The unit normal of a counter-clockwise triangle (+z for a degenerate one).
pub fn geometric_normal(p: [[f32; 3]; 3]) -> [f32; 3] {
    let e1: [f64; 3] = std::array::from_fn(|k| f64::from(p[1][k]) - f64::from(p[0][k]));
    let e2: [f64; 3] = std::array::from_fn(|k| f64::from(p[2][k]) - f64::from(p[0][k]));
    let n = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    let l = n.iter().map(|c| c * c).sum::<f64>().sqrt();
    if l > 0.0 && l.is_finite() {
        n.map(|c| (c / l) as f32)
    } else {
        [0.0, 0.0, 1.0]
    }
}

/// Every face index in range (1-based, or negative counting back from the last element
/// defined before the face), with the line of the first that is not: `tobj` wraps some
/// negative indices round instead of refusing them, and reports no lines.
fn check_indices(text: &str) -> Result<(), AssetError> {
    let (mut v, mut vt, mut vn) = (0i64, 0i64, 0i64);
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => v += 1,
            Some("vt") => vt += 1,
            Some("vn") => vn += 1,
            Some("f") => {
                for corner in words {
                    for (k, field) in corner.split('/').enumerate() {
                        let (count, what) = match k {
                            0 => (v, "vertex"),
                            1 => (vt, "texture coordinate"),
                            _ => (vn, "normal"),
                        };
                        let Ok(i) = field.parse::<i64>() else {
                            continue;
                        };
                        if i == 0 || i > count || i < -count {
                            return Err(AssetError::new(
                                Some(n + 1),
                                format!(
                                    "face {what} index {i} is out of range: {count} {what}s \
                                     are defined before this line"
                                ),
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// A `tobj` error with the line it most likely comes from: `tobj` reports no lines, so the
/// text is scanned for the first statement of the kind that failed.
fn locate(text: &str, e: tobj::LoadError) -> AssetError {
    use tobj::LoadError as E;
    let statement = match e {
        E::PositionParseError | E::ScalingByZeroError | E::ColorParseError => Some("v"),
        E::NormalParseError => Some("vn"),
        E::TexcoordParseError => Some("vt"),
        E::FaceParseError | E::InvalidPolygon => Some("f"),
        _ => None,
    };
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let Some(head) = words.next() else { continue };
        let rest: Vec<&str> = words.collect();
        if statement == Some(head) {
            let bad = match head {
                "v" => {
                    !(3..=7).contains(&rest.len()) || rest.iter().any(|w| w.parse::<f64>().is_err())
                }
                "vn" => rest.len() != 3 || rest.iter().any(|w| w.parse::<f64>().is_err()),
                "vt" => {
                    rest.is_empty()
                        || rest.len() > 3
                        || rest.iter().any(|w| w.parse::<f64>().is_err())
                }
                _ => {
                    rest.len() < 3
                        || rest.iter().any(|c| {
                            c.split('/').count() > 3
                                || c.split('/')
                                    .any(|f| !f.is_empty() && f.parse::<i64>().is_err())
                        })
                }
            };
            if bad {
                return AssetError::new(Some(n + 1), format!("{e}: `{}`", line.trim()));
            }
        }
    }
    AssetError::new(None, e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_obj_quad_is_fanned_into_two_triangles() {
        let m = parse("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n", false).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert!(m.normals.is_empty());
        let m = parse(
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 2 0\nf 1 2 3 4 5\n",
            false,
        )
        .unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
    }

    #[test]
    fn scene_obj_grid_shares_vertices() {
        let mut s = String::new();
        for y in 0..3 {
            for x in 0..3 {
                s += &format!("v {x} {y} 0\nvn 0 0 1\n");
            }
        }
        s += "vt 0 0\n";
        for y in 0..2 {
            for x in 0..2 {
                let v = |dx: i32, dy: i32| (y + dy) * 3 + x + dx + 1;
                s += &format!(
                    "f {}/1/1 {}/1/1 {}/1/1 {}/1/1\n",
                    v(0, 0),
                    v(1, 0),
                    v(1, 1),
                    v(0, 1)
                );
            }
        }
        let m = parse(&s, true).unwrap();
        assert_eq!((m.positions.len(), m.triangles.len()), (9, 8));
        assert_eq!(m.normals.len(), 9);
        assert_eq!(m.texcoords.len(), 9);
    }

    #[test]
    fn scene_obj_negative_indices_count_back() {
        let m = parse(
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 5 5 5\nf 1 -3 -2\n",
            false,
        )
        .unwrap();
        assert_eq!(m.triangles.len(), 2);
        let t = m.triangles[1].map(|i| m.positions[i as usize]);
        assert_eq!(t, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    }

    #[test]
    fn scene_obj_face_without_normals_gets_its_geometric_normal() {
        let text = "v 0 0 0\nv 0 0 1\nv 0 1 0\nv 0 1 1\nf 1 4 2\nf 1 3 4\n";
        let m = parse(text, true).unwrap();
        assert_eq!(m.positions.len(), 6, "vertices repeated per face");
        assert!(
            m.normals.iter().all(|&n| n == [1.0, 0.0, 0.0]),
            "{:?}",
            m.normals
        );
        let m = parse(text, false).unwrap();
        assert_eq!((m.positions.len(), m.normals.len()), (4, 0));
    }

    #[test]
    fn scene_obj_errors_name_the_line() {
        for (text, want) in [
            ("v 0 0 0\nv 1 0 0\n\nf 1 2 4\n", "line 4"),
            (
                "v 0 0 0\nv 1 0 0\nv 1 1 1\nf 1 2 -4\n",
                "index -4 is out of range",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 1 1 1\nf 1/1 2/1 3/1\n",
                "texture coordinate index 1",
            ),
            ("v 0 0 0\nv 1 x 0\n", "line 2"),
            ("v 0 0 0\n", "no faces"),
        ] {
            let e = parse(text, false).unwrap_err();
            let s = match e.line {
                Some(l) => format!("line {l}: {}", e.message),
                None => e.message.clone(),
            };
            assert!(s.contains(want), "{text:?}: {s}");
        }
    }
}
