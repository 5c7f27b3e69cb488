//! Degenerate geometry: meshes full of faces of no area (collapsed corners, collinear
//! corners, single points) among good ones, lit (their geometric normal is zero) and
//! blended (the good faces must still tile), and bicubic patches with repeated control
//! points (a corner row collapsed to a pole, a whole patch one point, a patch flat onto a
//! line, inner points on the corners), diced as the OpenGL pipeline draws patches.

use anyhow::Result;
use imagine_pipelines::scene::bpt::{self, Basis, Patch};
use imagine_pipelines::scene::model::{Blend, DepthTest, Mesh, Scene};
use imagine_pipelines::scene::obj;

use super::case::{Case, Expect};
use super::check::Bound;
use super::window_space::TILE_LEVEL;
use super::world_space::{grid, scene};

const ORTHO: &str = "[window]\nwidth = 64\nheight = 64\n[camera]\n\
    modelview = [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]\northo = [-1, 1, -1, 1, -1, 1]\n";

/// The degenerate grid, grey and blended (`tiles`) or lit without normals.
fn degenerate_grid(tiles: bool) -> Result<Scene> {
    let mut mesh = grid(6, true);
    if !tiles {
        mesh = with_face_normals(&mesh);
    }
    let material = if tiles {
        mesh.colours = vec![[0.25; 3]; mesh.positions.len()];
        "[[material]]\nname = \"m\"\nshader = \"unlit\"\n"
    } else {
        "[[light]]\nposition = [0.5, 0.8, 2.0]\n\
         [[material]]\nname = \"m\"\nshader = \"lit\"\ndiffuse = [0.8, 0.6, 0.3]\n\
         specular = [0.4, 0.4, 0.4]\nshininess = 10.0\n"
    };
    let text = format!(
        "{ORTHO}{material}[[object]]\nprimitive = {{ kind = \"icosphere\", subdivisions = 0 }}\n\
         material = \"m\"\n"
    );
    let mut s = scene("degenerate-grid", &text, vec![mesh])?;
    if tiles {
        s.pipeline.blend = Blend::Add;
        s.pipeline.depth_test = DepthTest::Always;
    }
    Ok(s)
}

/// The mesh's triangles as separate triangles, each corner with the face's geometric
/// normal, as an OBJ without normals is read for `lit` (+z for a face of no area).
fn with_face_normals(m: &Mesh) -> Mesh {
    let mut out = Mesh {
        separate: true,
        ..Mesh::default()
    };
    for t in &m.triangles {
        let p = t.map(|i| m.positions[i as usize]);
        let n = obj::geometric_normal(p);
        let first = out.positions.len() as u32;
        out.positions.extend(p);
        out.normals.extend([n; 3]);
        out.triangles.push([first, first + 1, first + 2]);
    }
    out
}

/// A Bezier patch over `[x0, x0 + 0.8] × [y0, y0 + 0.8]`, bulging towards the eye.
fn patch(x0: f64, y0: f64) -> Patch {
    std::array::from_fn(|k| {
        let (i, j) = ((k % 4) as f64, (k / 4) as f64);
        let bulge = if (1.0..3.0).contains(&i) && (1.0..3.0).contains(&j) {
            0.3
        } else {
            0.0
        };
        [x0 + 0.8 * i / 3.0, y0 + 0.8 * j / 3.0, bulge]
    })
}

/// Four degenerate patches: the top row collapsed to one point (a pole, like the teapot
/// lid's), every point the same, every row the same (a patch flat onto a curve), and the
/// inner points on the corners (repeated control points).
fn degenerate_patches() -> Vec<Patch> {
    let mut pole = patch(-0.95, 0.1);
    for k in 12..16 {
        pole[k] = pole[13];
    }
    let point = [[0.5, 0.5, 0.1]; 16];
    let mut line = patch(0.1, -0.9);
    for k in 4..16 {
        line[k] = line[k % 4];
    }
    let mut repeated = patch(-0.9, -0.9);
    for (inner, corner) in [(5, 0), (6, 3), (9, 12), (10, 15)] {
        repeated[inner] = repeated[corner];
    }
    vec![pole, point, line, repeated]
}

fn patches_scene(tessellate: u32) -> Result<Scene> {
    let mesh: Mesh = bpt::tessellate(&degenerate_patches(), Basis::Bezier, tessellate, false);
    let text = format!(
        "{ORTHO}[[light]]\nposition = [0.5, 0.8, 2.0]\n\
         [[material]]\nname = \"m\"\nshader = \"lit\"\ndiffuse = [0.3, 0.7, 0.8]\n\
         specular = [0.6, 0.6, 0.6]\nshininess = 30.0\n\
         [[object]]\nprimitive = {{ kind = \"icosphere\", subdivisions = 0 }}\nmaterial = \"m\"\n"
    );
    scene("degenerate-patches", &text, vec![mesh])
}

fn render(
    name: &'static str,
    about: &'static str,
    scene: impl Fn() -> Result<Scene> + Send + Sync + 'static,
    expect: Vec<Expect>,
) -> Case {
    Case::render("degenerate", name, about, false, scene, expect)
}

pub fn cases() -> Vec<Case> {
    vec![
        render(
            "degenerate-faces-tile",
            "a grid with collapsed-corner, collinear and one-point faces among its cells: tiles once",
            || degenerate_grid(true),
            vec![Expect::TilesOnce { level: TILE_LEVEL }],
        ),
        render(
            "degenerate-faces-lit",
            "that grid lit, +z normals on the degenerate faces: the reference's image",
            || degenerate_grid(false),
            // The coplanar faces share depth 0: where rounding leaves a pixel to a collinear
            // face (its midpoint rounded off the line) or to the other side of an edge,
            // another face of the same colour shows; the images are identical.
            vec![Expect::Reference(Bound {
                coverage: 0.0,
                visibility: 0.005,
                levels: 1,
            })],
        ),
        render(
            "degenerate-patches",
            "patches with a pole, one point, one curve, repeated control points, diced 6x6: the reference's image",
            || patches_scene(6),
            vec![Expect::Reference(Bound::TIGHT)],
        ),
    ]
}
