//! Scenes (ARCHITECTURE §5): what the OpenGL-like pipeline draws.
//!
//! A [`Scene`] is a list of separate triangles (three vertices each, no sharing, drawn in
//! order), a model-view-projection matrix, a window and a shading mode:
//!
//! * **SPHERE-FULL** ([`sphere`]): a unit icosphere subdivided six times (20·4⁶ = 81,920
//!   triangles) seen in perspective, lit per vertex by three positional lights (diffuse and
//!   specular), back faces culled — the scene of Owens et al., "Polygon Rendering on a
//!   Stream Architecture" (Graphics Hardware 2000), filling the window (the scene file
//!   SPHERE is it smaller, at the thesis's fragment count).
//! * **RATE-n** ([`rate`]): long horizontal strips of identical unlit Gouraud triangles,
//!   each covering `n` pixels (half of a `w × h` cell with `w·h = 2n`), tiling the window
//!   once (depth complexity 1). It measures vertex and fragment rates against triangle
//!   size.
//! * **`.tri` files** ([`parse_tri`]): window-space triangles for conformance tests against
//!   other OpenGL implementations. First line `W H`, then one triangle per line as
//!   3 × (x y z r g b): x and y in window pixels, origin bottom-left; z and colours in
//!   [0, 1]. Depth test LESS, smooth shading, no culling. `#` starts a comment.
//!
//! All scenes use OpenGL's conventions: clip space → normalized device coordinates by the
//! divide by w, the viewport maps x, y ∈ [-1, 1] onto the window and z ∈ [-1, 1] onto depth
//! [0, 1]; counter-clockwise triangles in the window are front-facing; pixel centres sit at
//! (x + 0.5, y + 0.5); the depth buffer clears to 1.0 and the colour buffer to black.

pub mod bpt;
pub mod bump_map;
pub mod cage;
pub mod file;
pub mod mipmap;
pub mod model;
pub mod obj;
pub mod primitives;

pub use file::{LoadOptions, load, load_tri, window_scene};

use std::fmt;

pub use imagine_units::limits::{MAX_TRI_COORDINATE, MAX_WINDOW};

/// The three positional lights and the material of a lit scene. Positions are in object
/// space (the space of the vertices), like the eye.
#[derive(Clone, Debug, PartialEq)]
pub struct Lighting {
    pub eye: [f32; 3],
    /// (position, colour) of each light.
    pub lights: [([f32; 3], [f32; 3]); 3],
    pub diffuse: [f32; 3],
    pub specular: [f32; 3],
    pub ambient: [f32; 3],
}

/// How vertices get their colour.
#[derive(Clone, Debug, PartialEq)]
pub enum Shading {
    /// Per-vertex colours ([`Scene::colours`]), interpolated (Gouraud).
    Unlit,
    /// Per-vertex lighting of the normals ([`Scene::normals`]) by three lights
    /// (the `vertex` kernel's model: Blinn-Phong with a specular exponent of 16).
    Lit(Lighting),
}

/// A scene: separate triangles in drawing order.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// Object-space positions, three per triangle.
    pub positions: Vec<[f32; 3]>,
    /// One per position for [`Shading::Lit`], else empty.
    pub normals: Vec<[f32; 3]>,
    /// One per position for [`Shading::Unlit`] (r, g, b in [0, 1]), else empty.
    pub colours: Vec<[f32; 3]>,
    /// The model-view and projection matrices, row-major: clip = projection · modelview ·
    /// (x, y, z, 1). The machine composes them (the `perbegin` kernel); see [`Scene::mvp`].
    pub modelview: [f32; 16],
    pub projection: [f32; 16],
    pub shading: Shading,
    /// Discard clockwise (back-facing) triangles.
    pub cull_back: bool,
}

impl Scene {
    /// The model-view-projection matrix `projection · modelview`, as `perbegin` composes it.
    pub fn mvp(&self) -> [f32; 16] {
        mat_mul(&self.projection, &self.modelview)
    }

    pub fn triangles(&self) -> usize {
        self.positions.len() / 3
    }

    /// Whether the scene's arrays agree with each other and the window is drawable.
    pub fn validate(&self) -> Result<(), SceneError> {
        let bad = |m: String| Err(SceneError::new(&self.name, None, m));
        if self.width == 0
            || self.height == 0
            || self.width > MAX_WINDOW
            || self.height > MAX_WINDOW
        {
            return bad(format!(
                "window {}x{} is outside 1..={MAX_WINDOW} pixels per side",
                self.width, self.height
            ));
        }
        if !self.positions.len().is_multiple_of(3) {
            return bad(format!(
                "{} vertices do not make whole triangles",
                self.positions.len()
            ));
        }
        let (want, have, what) = match self.shading {
            Shading::Lit(_) => (self.positions.len(), self.normals.len(), "normals"),
            Shading::Unlit => (self.positions.len(), self.colours.len(), "colours"),
        };
        if want != have {
            return bad(format!("{have} {what} for {want} vertices"));
        }
        let finite = |v: &[f32]| v.iter().all(|c| c.is_finite());
        if let Some(i) = self.positions.iter().position(|p| !finite(p)) {
            return bad(format!(
                "vertex {i} has a coordinate that is not a finite number"
            ));
        }
        for (m, name) in [
            (&self.modelview, "model-view"),
            (&self.projection, "projection"),
        ] {
            if !finite(m) {
                return bad(format!(
                    "the {name} matrix has an entry that is not a finite number"
                ));
            }
        }
        if !finite(&self.mvp()) {
            return bad("the model-view-projection matrix overflows".into());
        }
        Ok(())
    }
}

/// A scene that cannot be built or read, with where the problem is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SceneError {
    pub scene: String,
    pub line: Option<usize>,
    pub message: String,
}

impl SceneError {
    fn new(scene: &str, line: Option<usize>, message: String) -> Self {
        SceneError {
            scene: scene.into(),
            line,
            message,
        }
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(l) => write!(f, "scene `{}` line {l}: {}", self.scene, self.message),
            None => write!(f, "scene `{}`: {}", self.scene, self.message),
        }
    }
}

impl std::error::Error for SceneError {}

/// The default window side of the published scenes.
pub const DEFAULT_SIZE: u32 = 720;

/// Subdivisions of SPHERE's icosahedron: 20·4⁶ = 81,920 triangles.
pub const SPHERE_SUBDIVISIONS: u32 = 6;

/// A built-in scene by name: `SPHERE-FULL` (the framing of [`sphere`], as
/// `scenes/SPHERE-FULL.toml`; `scenes/SPHERE.toml` is smaller on screen) or `RATE-n` (n in
/// 1..=128), in a `size × size` window.
pub fn builtin(name: &str, size: u32) -> Result<Scene, SceneError> {
    let upper = name.to_ascii_uppercase();
    if upper == "SPHERE-FULL" {
        return Ok(sphere(SPHERE_SUBDIVISIONS, size));
    }
    if upper.starts_with("RATE-") {
        let n = &name[5..];
        let n: u32 = n.parse().map_err(|_| {
            SceneError::new(
                name,
                None,
                format!("`{n}` is not a triangle size in pixels"),
            )
        })?;
        return rate(n, size);
    }
    Err(SceneError::new(
        name,
        None,
        "unknown scene: built-in scenes are SPHERE-FULL and RATE-n (n = 1..128); files end in .tri"
            .into(),
    ))
}

/// Row-major 4×4 product `a · b`.
/// The product `a · b` of row-major 4×4 matrices, each entry summed left to right
/// (`((a_i0·b_0j + a_i1·b_1j) + a_i2·b_2j) + a_i3·b_3j`), as the `perbegin` kernel does.
pub fn mat_mul(a: &[f32; 16], b: &[f32; 16]) -> [f32; 16] {
    std::array::from_fn(|k| {
        let (i, j) = (k / 4, k % 4);
        (1..4).fold(a[i * 4] * b[j], |sum, t| sum + a[i * 4 + t] * b[t * 4 + j])
    })
}

/// The identity matrix.
pub const IDENTITY: [f32; 16] = [
    1.0, 0.0, 0.0, 0.0, //
    0.0, 1.0, 0.0, 0.0, //
    0.0, 0.0, 1.0, 0.0, //
    0.0, 0.0, 0.0, 1.0,
];

/// `gluPerspective(fovy, aspect, near, far)`, row-major.
fn perspective(fovy_degrees: f32, aspect: f32, near: f32, far: f32) -> [f32; 16] {
    let f = 1.0 / (fovy_degrees.to_radians() / 2.0).tan();
    let depth = near - far;
    [
        f / aspect,
        0.0,
        0.0,
        0.0, //
        0.0,
        f,
        0.0,
        0.0, //
        0.0,
        0.0,
        (far + near) / depth,
        2.0 * far * near / depth, //
        0.0,
        0.0,
        -1.0,
        0.0,
    ]
}

/// A translation by `-eye_z` along z (the camera on the +z axis looking at the origin).
fn look_down_z(eye_z: f32) -> [f32; 16] {
    [
        1.0, 0.0, 0.0, 0.0, //
        0.0, 1.0, 0.0, 0.0, //
        0.0, 0.0, 1.0, -eye_z, //
        0.0, 0.0, 0.0, 1.0,
    ]
}

/// Window-space to clip-space for a `width × height` window: x, y in pixels and z in
/// [0, 1] map to clip coordinates with w = 1 (the inverse of the viewport transform).
pub fn window_to_clip(width: u32, height: u32) -> [f32; 16] {
    [
        2.0 / width as f32,
        0.0,
        0.0,
        -1.0, //
        0.0,
        2.0 / height as f32,
        0.0,
        -1.0, //
        0.0,
        0.0,
        2.0,
        -1.0, //
        0.0,
        0.0,
        0.0,
        1.0,
    ]
}

fn normalized(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|c| c / l)
}

/// The triangles of a unit icosphere: an icosahedron whose faces are split in four
/// `subdivisions` times, every new vertex pushed out to the sphere. Counter-clockwise seen
/// from outside.
pub fn icosphere(subdivisions: u32) -> Vec<[[f32; 3]; 3]> {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let v: Vec<[f64; 3]> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .map(normalized)
    .to_vec();
    const FACES: [[usize; 3]; 20] = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let mut tris: Vec<[[f64; 3]; 3]> = FACES.iter().map(|f| f.map(|i| v[i])).collect();
    for _ in 0..subdivisions {
        let mid =
            |a: [f64; 3], b: [f64; 3]| normalized(std::array::from_fn(|k| (a[k] + b[k]) / 2.0));
        tris = tris
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    tris.iter()
        .map(|t| t.map(|p| p.map(|c| c as f32)))
        .collect()
}

/// SPHERE-FULL with `subdivisions` levels in a `size × size` window: the unit sphere seen
/// from (0, 0, 3) with a 45° field of view (it fills most of the window; SPHERE's 55.9°
/// gives the published fragment count), three white-ish lights around the eye, a
/// blue-grey diffuse and white specular material.
pub fn sphere(subdivisions: u32, size: u32) -> Scene {
    let tris = icosphere(subdivisions);
    let positions: Vec<[f32; 3]> = tris.iter().flatten().copied().collect();
    let eye_z = 3.0;
    Scene {
        name: if subdivisions == SPHERE_SUBDIVISIONS {
            "SPHERE-FULL".into()
        } else {
            format!("SPHERE-{subdivisions}")
        },
        width: size,
        height: size,
        normals: positions.clone(),
        positions,
        colours: Vec::new(),
        modelview: look_down_z(eye_z),
        projection: perspective(45.0, 1.0, 1.0, 10.0),
        shading: Shading::Lit(Lighting {
            eye: [0.0, 0.0, eye_z],
            lights: [
                ([4.0, 4.0, 6.0], [0.8, 0.8, 0.8]),
                ([-5.0, 1.0, 4.0], [0.5, 0.3, 0.2]),
                ([0.0, -6.0, 3.0], [0.2, 0.3, 0.5]),
            ],
            diffuse: [0.4, 0.5, 0.8],
            specular: [0.6, 0.6, 0.6],
            ambient: [0.05, 0.05, 0.08],
        }),
        cull_back: true,
    }
}

/// The cell of a RATE-n triangle: `w × h` pixels with `w·h = 2n`, as square as powers of
/// two allow (1 → 2×1, 2 → 2×2, 4 → 4×2, 8 → 4×4, …).
pub fn rate_cell(n: u32) -> (u32, u32) {
    let cells = 2 * n;
    let mut h = 1;
    while h * h * 4 <= cells && cells.is_multiple_of(h * 2) {
        h *= 2;
    }
    (cells / h, h)
}

/// RATE-n in a `size × size` window: rows of `w × h` cells (see [`rate_cell`]), each cut
/// into two counter-clockwise triangles, coloured by position, all at depth 0.5. `n` must
/// be a power of two in 1..=128 and the cell must tile the window.
pub fn rate(n: u32, size: u32) -> Result<Scene, SceneError> {
    let name = format!("RATE-{n}");
    if !(1..=128).contains(&n) || !n.is_power_of_two() {
        return Err(SceneError::new(
            &name,
            None,
            "the triangle size must be a power of two from 1 to 128 pixels".into(),
        ));
    }
    let (w, h) = rate_cell(n);
    if size == 0 || size > MAX_WINDOW || !size.is_multiple_of(w) || !size.is_multiple_of(h) {
        return Err(SceneError::new(
            &name,
            None,
            format!("{w}x{h}-pixel cells do not tile a {size}x{size} window"),
        ));
    }
    let mut positions = Vec::new();
    let mut colours = Vec::new();
    let colour = |x: u32, y: u32| [x as f32 / size as f32, y as f32 / size as f32, 0.5];
    for row in 0..size / h {
        for col in 0..size / w {
            let (x0, y0) = (col * w, row * h);
            let (x1, y1) = (x0 + w, y0 + h);
            for [(ax, ay), (bx, by), (cx, cy)] in [
                [(x0, y0), (x1, y0), (x1, y1)],
                [(x0, y0), (x1, y1), (x0, y1)],
            ] {
                for (x, y) in [(ax, ay), (bx, by), (cx, cy)] {
                    positions.push([x as f32, y as f32, 0.5]);
                    colours.push(colour(x, y));
                }
            }
        }
    }
    Ok(Scene {
        name,
        width: size,
        height: size,
        positions,
        normals: Vec::new(),
        colours,
        modelview: IDENTITY,
        projection: window_to_clip(size, size),
        shading: Shading::Unlit,
        cull_back: false,
    })
}

/// Reads a `.tri` file's text (see the module comment); `name` is used in errors.
pub fn parse_tri(name: &str, text: &str) -> Result<Scene, SceneError> {
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.split('#').next().unwrap_or("").trim()))
        .filter(|(_, l)| !l.is_empty());
    let err = |line: usize, m: String| SceneError::new(name, Some(line), m);
    let Some((first, header)) = lines.next() else {
        return Err(SceneError::new(
            name,
            None,
            "the file is empty: expected `W H`".into(),
        ));
    };
    let size: Vec<&str> = header.split_whitespace().collect();
    let parse_side = |s: &str| {
        s.parse::<u32>()
            .ok()
            .filter(|&v| (1..=MAX_WINDOW).contains(&v))
    };
    let (width, height) = match size.as_slice() {
        [w, h] => match (parse_side(w), parse_side(h)) {
            (Some(w), Some(h)) => (w, h),
            _ => {
                return Err(err(
                    first,
                    format!("window `{header}`: W and H must be integers in 1..={MAX_WINDOW}"),
                ));
            }
        },
        _ => return Err(err(first, format!("expected `W H`, found `{header}`"))),
    };
    let mut positions = Vec::new();
    let mut colours = Vec::new();
    for (line, text) in lines {
        let fields: Vec<&str> = text.split_whitespace().collect();
        if fields.len() != 18 {
            return Err(err(
                line,
                format!(
                    "expected 18 numbers (3 × x y z r g b), found {}",
                    fields.len()
                ),
            ));
        }
        let mut v = [0f32; 18];
        for (k, f) in fields.iter().enumerate() {
            let x: f32 = f
                .parse()
                .map_err(|_| err(line, format!("`{f}` is not a number")))?;
            let what = ["x", "y", "z", "r", "g", "b"][k % 6];
            if !x.is_finite() {
                return Err(err(
                    line,
                    format!("vertex {} {what} is `{f}`, not a finite number", k / 6),
                ));
            }
            if k % 6 < 2 && x.abs() > MAX_TRI_COORDINATE {
                return Err(err(
                    line,
                    format!(
                        "vertex {} {what} = {x} is beyond ±{MAX_TRI_COORDINATE} pixels",
                        k / 6
                    ),
                ));
            }
            if k % 6 >= 2 && !(0.0..=1.0).contains(&x) {
                return Err(err(
                    line,
                    format!("vertex {} {what} = {x} is outside [0, 1]", k / 6),
                ));
            }
            v[k] = x;
        }
        for vertex in v.chunks(6) {
            positions.push([vertex[0], vertex[1], vertex[2]]);
            colours.push([vertex[3], vertex[4], vertex[5]]);
        }
    }
    if positions.is_empty() {
        return Err(SceneError::new(
            name,
            None,
            "the file has no triangles".into(),
        ));
    }
    Ok(Scene {
        name: name.into(),
        width,
        height,
        positions,
        normals: Vec::new(),
        colours,
        modelview: IDENTITY,
        projection: window_to_clip(width, height),
        shading: Shading::Unlit,
        cull_back: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn far_over_near_comes_from_a_perspective_projection_only() {
        let camera = |projection| model::Camera {
            view: IDENTITY,
            projection,
        };
        let r = camera(perspective(45.0, 1.0, 2.0, 600.0))
            .far_over_near()
            .unwrap();
        assert!((r - 300.0).abs() < 0.1, "{r}");
        // fp32 rounds −(f+n)/(f−n) to −1: beyond its resolution.
        let r = camera(perspective(45.0, 1.0, 1e-3, 1e6)).far_over_near();
        assert_eq!(r, Some(f64::INFINITY));
        assert_eq!(camera(window_to_clip(64, 64)).far_over_near(), None);
    }

    #[test]
    fn sphere_has_the_published_triangle_count_and_faces_outwards() {
        let s = sphere(SPHERE_SUBDIVISIONS, 720);
        assert_eq!(s.triangles(), 81_920);
        s.validate().unwrap();
        for t in s.positions.chunks(3).step_by(997) {
            let e1: [f32; 3] = std::array::from_fn(|k| t[1][k] - t[0][k]);
            let e2: [f32; 3] = std::array::from_fn(|k| t[2][k] - t[0][k]);
            let n = [
                e1[1] * e2[2] - e1[2] * e2[1],
                e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0],
            ];
            let outward: f32 = (0..3).map(|k| n[k] * t[0][k]).sum();
            assert!(
                outward > 0.0,
                "a triangle winds clockwise seen from outside"
            );
        }
    }

    #[test]
    fn rate_tiles_the_window_once() {
        for n in [1, 2, 4, 8, 16, 32, 64, 128] {
            let s = rate(n, 64).unwrap();
            let (w, h) = rate_cell(n);
            assert_eq!(w * h, 2 * n);
            assert_eq!(s.triangles() as u32 * n, 64 * 64, "RATE-{n}");
            s.validate().unwrap();
        }
        assert!(rate(3, 64).is_err());
        assert!(rate(128, 100).is_err(), "16x16 cells do not tile 100");
        assert!(rate(128, 720).is_ok());
    }

    #[test]
    fn tri_files_are_read_and_bad_ones_named() {
        let s = parse_tri(
            "t",
            "# a comment\n4 3\n0 0 0.5 1 0 0  4 0 0.5 0 1 0  0 3 0.5 0 0 1\n",
        )
        .unwrap();
        assert_eq!((s.width, s.height, s.triangles()), (4, 3, 1));
        assert_eq!(s.colours[1], [0.0, 1.0, 0.0]);
        for (text, want) in [
            ("", "empty"),
            ("4\n", "expected `W H`"),
            ("0 4\n", "W and H"),
            ("4 4\n", "no triangles"),
            ("4 4\n1 2 3\n", "line 2: expected 18 numbers"),
            (
                "4 4\n0 0 0 1 1 1 1 0 0 1 1 1 0 1 0 1 1 nan\n",
                "not a finite number",
            ),
            ("4 4\n0 0 0 1 1 1 1 0 0 1 1 1 0 1e9 0 1 1 1\n", "beyond"),
            (
                "4 4\n0 0 2 1 1 1 1 0 0 1 1 1 0 1 0 1 1 1\n",
                "outside [0, 1]",
            ),
            (
                "4 4\n0 0 x 1 1 1 1 0 0 1 1 1 0 1 0 1 1 1\n",
                "`x` is not a number",
            ),
        ] {
            let e = parse_tri("t", text).unwrap_err().to_string();
            assert!(e.contains(want), "{text:?}: {e}");
        }
    }

    #[test]
    fn builtin_names() {
        assert_eq!(builtin("sphere-full", 64).unwrap().triangles(), 81_920);
        assert_eq!(builtin("RATE-8", 64).unwrap().triangles(), 512);
        assert!(
            builtin("RATE-x", 64)
                .unwrap_err()
                .to_string()
                .contains("`x`")
        );
        assert!(
            builtin("TEAPOT", 64)
                .unwrap_err()
                .to_string()
                .contains("unknown scene")
        );
    }
}
