//! The independent f64 reference renderer (ARCHITECTURE §6, layer 3): what a [`Scene`]
//! should look like, computed in double precision by code that shares nothing with the
//! pipeline's kernels or compiler — only the scene types.
//!
//! # Vertices
//!
//! Every vertex is transformed in f64: `clip = mvp · (x, y, z, 1)` with the scene's
//! row-major matrix (its f32 entries widened exactly). Its colour is
//!
//! * [`Shading::Unlit`]: the scene's vertex colour;
//! * [`Shading::Lit`]: the `vertex` kernel's model (Blinn-Phong, three positional lights,
//!   specular exponent 16), in f64:
//!   `clamp(ambient + Σ_l light_l ⊙ (diffuse·max(N·L, 0) + specular·max(N·H, 0)^16), 0, 1)`
//!   per channel, with `N` the normalized normal, `V = normalize(eye − p)`,
//!   `L = normalize(light_l − p)` and `H = normalize(L + V)` ([`lit_colour`]).
//!
//! # Triangles
//!
//! Triangles are drawn in order, each rasterized with homogeneous edge functions (Olano and
//! Greer, "Triangle Scan Conversion using 2D Homogeneous Coordinates", Graphics Hardware
//! 1997), so that triangles crossing `w = 0` need no clipping:
//!
//! 1. **Trivial reject**: a triangle whose three vertices are all outside the same clip
//!    plane (`x < −w`, `x > w`, `y < −w`, `y > w`, `z < −w` or `z > w`) is dropped, and so
//!    is one with every `w ≤ 0` (the view volume lies in `w ≥ 0`, so such a triangle is
//!    invisible; the edge functions would find no sample for it either, up to rounding).
//! 2. **Homogeneous window coordinates**: `v_i = ((x_i + w_i)·W/2, (y_i + w_i)·H/2, w_i)`
//!    for a `W × H` window: dividing by `w_i` gives the window position.
//! 3. **Edge functions** `E_0 = (v_1 × v_2)·p`, `E_1 = (v_2 × v_0)·p`,
//!    `E_2 = (v_0 × v_1)·p` at `p = (X, Y, 1)`, each `A·X + B·Y + C` with `(A, B, C)` the
//!    cross product, and `det = v_0·(v_1 × v_2)`. `det > 0` means counter-clockwise in the
//!    window (y up) — for a triangle crossing `w = 0`, its visible part is — so
//!    front-facing. With `cull_back`, triangles with `det ≤ 0` are dropped;
//!    otherwise those with `det = 0` are, and when `det < 0` all three edge functions are
//!    negated (sign-normalised) so that the inside is where all are non-negative.
//! 4. **Samples**: pixel `(px, py)` samples at `(px + 0.5, py + 0.5)` and is covered when
//!    every sign-normalised `E_i ≥ 0`, a sample exactly on an edge (`E_i = 0`) counting only
//!    for a *top* or *left* edge: with the edge's sign-normalised `(A, B)`, when `A > 0`
//!    (a left edge: the inside is to its right) or `A = 0 ∧ B < 0` (a horizontal top edge:
//!    the inside is below it): [`TieRule::TopLeft`]. A shared edge has exactly negated
//!    functions in its two triangles (the cross product of swapped vectors is the exact
//!    negation, and so is the rounded evaluation `(A·X + B·Y) + C`), so a mesh covers each
//!    sample once, with no holes.
//!    All three `E_i ≥ 0` also means the pixel's ray meets the triangle at `w > 0`: the
//!    part of a triangle behind the eye never shows.
//! 5. **Interpolation**: perspective-correct barycentrics `λ_i = E_i / (E_0 + E_1 + E_2)`
//!    (a sample whose sum is 0 is skipped); colour `Σ λ_i c_i`; window depth
//!    `z_w = (z_ndc + 1) / 2` with `z_ndc = (Σ λ_i z_i) / (Σ λ_i w_i)`. A fragment is kept
//!    only when `0 ≤ z_w ≤ 1`: this is the near and far clipping.
//! 6. **Bounding box**: the pixels whose centres can lie inside the projected triangle, one
//!    pixel of margin on each side for rounding, clamped to the window; the whole window
//!    when any `w ≤ 0` (the projection is then unbounded).
//! 7. **Depth test** `LESS` against an f64 depth buffer cleared to 1.0; the colour buffer
//!    clears to black. A passing fragment writes its depth and `quantise(colour)` per
//!    channel (round half up of `clamp(c, 0, 1)·255`) with alpha 255.
//!
//! [`for_each_fragment`] exposes steps 1–6 without the depth test (for coverage tests);
//! [`render`] adds step 7. Steps 1–6 for one triangle are [`rasterize_triangle`], which
//! the scene-file renderer ([`crate::reference_model`]) shares, with culling of back, front
//! or no faces and the depth tests of [`depth_passes`].
//!
//! # Other tie rules
//!
//! OpenGL does not fix which of two triangles sharing an edge owns a sample on it. Under
//! OSMesa (whose buffer has row 0 at the bottom) Mesa's llvmpipe owns left edges and
//! *bottom* horizontal edges in GL window coordinates — the top-left rule applied to its
//! own y-down rows — and softpipe owns *right* edges and top ones. [`TieRule::BottomLeft`]
//! and [`TieRule::TopRight`] reproduce those ([`render_with`], [`for_each_fragment_with`])
//! so that comparisons with OSMesa can be exact; [`TieRule::TopLeft`] is the default.
//! (Exact only for triangles Mesa does not clip: a triangle reaching outside the view
//! volume is clipped in f32 and its edges move by rounding.)

use crate::image::{Image, quantise};
use imagine_pipelines::scene::model::{Cull, DepthTest};
use imagine_pipelines::scene::{Lighting, Scene, SceneError, Shading};

pub(crate) type V3 = [f64; 3];

pub(crate) fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(crate) fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn normalize(v: V3) -> V3 {
    let length = dot(v, v).sqrt();
    v.map(|c| c / length)
}

pub(crate) fn widen(v: [f32; 3]) -> V3 {
    v.map(f64::from)
}

/// `projection · (modelview · (x, y, z, 1))` in f64, both row-major.
pub fn clip_position(projection: &[f32; 16], modelview: &[f32; 16], p: [f32; 3]) -> [f64; 4] {
    let times = |m: &[f32; 16], v: [f64; 4]| -> [f64; 4] {
        std::array::from_fn(|i| (0..4).map(|j| f64::from(m[i * 4 + j]) * v[j]).sum())
    };
    let p = widen(p);
    times(projection, times(modelview, [p[0], p[1], p[2], 1.0]))
}

/// The colour of a vertex at `p` with normal `n` under `lighting` (the `vertex` kernel's
/// model, in f64; see the module comment), clamped to [0, 1].
pub fn lit_colour(lighting: &Lighting, p: [f32; 3], n: [f32; 3]) -> [f64; 3] {
    let p = widen(p);
    let n = normalize(widen(n));
    let to = |q: [f32; 3]| {
        let q = widen(q);
        normalize([q[0] - p[0], q[1] - p[1], q[2] - p[2]])
    };
    let v = to(lighting.eye);
    let (diffuse, specular) = (widen(lighting.diffuse), widen(lighting.specular));
    let mut sum = widen(lighting.ambient);
    for &(position, colour) in &lighting.lights {
        let l = to(position);
        let h = normalize([l[0] + v[0], l[1] + v[1], l[2] + v[2]]);
        let n_dot_l = dot(n, l).max(0.0);
        let spec = dot(n, h).max(0.0).powi(16);
        for k in 0..3 {
            sum[k] += f64::from(colour[k]) * (diffuse[k] * n_dot_l + specular[k] * spec);
        }
    }
    sum.map(|c| c.clamp(0.0, 1.0))
}

/// The colour of every vertex of a valid scene, in f64.
pub fn vertex_colours(scene: &Scene) -> Vec<[f64; 3]> {
    match &scene.shading {
        Shading::Unlit => scene.colours.iter().map(|&c| widen(c)).collect(),
        Shading::Lit(lighting) => scene
            .positions
            .iter()
            .zip(&scene.normals)
            .map(|(&p, &n)| lit_colour(lighting, p, n))
            .collect(),
    }
}

/// Which samples exactly on an edge a triangle owns (see the module comment), by the
/// edge's sign-normalised coefficients `(A, B)`: a *left* edge has `A > 0` (the inside to
/// its right), a *right* edge `A < 0`, a *top* edge `A = 0 ∧ B < 0` (horizontal, the
/// inside below) and a *bottom* edge `A = 0 ∧ B > 0`, in window coordinates with y up.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum TieRule {
    /// Left and top edges (the top of the displayed image): the reference's rule.
    #[default]
    TopLeft,
    /// Left and bottom edges: Mesa's llvmpipe under OSMesa.
    BottomLeft,
    /// Right and top edges: Mesa's softpipe under OSMesa.
    TopRight,
}

impl TieRule {
    /// Whether a sample on the edge with sign-normalised coefficients `(a, b)` is covered.
    pub fn owns(self, a: f64, b: f64) -> bool {
        match self {
            TieRule::TopLeft => a > 0.0 || (a == 0.0 && b < 0.0),
            TieRule::BottomLeft => a > 0.0 || (a == 0.0 && b > 0.0),
            TieRule::TopRight => a < 0.0 || (a == 0.0 && b < 0.0),
        }
    }
}

/// One sample of one triangle that survived rasterization and depth clipping.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fragment {
    /// Index of the triangle in the scene.
    pub triangle: usize,
    pub x: u32,
    pub y: u32,
    /// Window depth in [0, 1].
    pub depth: f64,
    /// Interpolated colour (not clamped).
    pub colour: [f64; 3],
}

/// Whether all three clip-space vertices are outside one clip plane.
fn trivially_rejected(c: &[[f64; 4]; 3]) -> bool {
    let all = |f: &dyn Fn(&[f64; 4]) -> bool| c.iter().all(f);
    all(&|v| v[0] < -v[3])
        || all(&|v| v[0] > v[3])
        || all(&|v| v[1] < -v[3])
        || all(&|v| v[1] > v[3])
        || all(&|v| v[2] < -v[3])
        || all(&|v| v[2] > v[3])
        || all(&|v| v[3] <= 0.0)
}

/// Pixel range `lo..=hi` whose centres `p + 0.5` may lie in `[min, max]`, with one pixel
/// of margin, clamped to `0..size`; `None` when empty.
fn pixel_range(min: f64, max: f64, size: u32) -> Option<(u32, u32)> {
    // `as` saturates (and maps NaN to 0), so huge or infinite bounds are safe.
    let lo = ((min - 0.5).ceil() as i64).saturating_sub(1).max(0);
    let hi = ((max - 0.5).floor() as i64)
        .saturating_add(1)
        .min(i64::from(size) - 1);
    (lo <= hi).then_some((lo as u32, hi as u32))
}

/// Steps 1–6 of the module comment for one triangle: `clip` holds its clip-space vertices
/// and `colours` their colours, in a `width × height` window. Triangles of the winding
/// `cull` names are dropped (counter-clockwise in the window, `det > 0`, is front;
/// zero-area ones always are). Calls `f(x, y, depth, colour)` for every covered sample
/// with `0 ≤ depth ≤ 1`, bottom row up, left to right; no depth test. Both the old scene's
/// renderer and [`crate::reference_model`] draw through this ([`rasterize_samples`]).
pub fn rasterize_triangle(
    clip: &[[f64; 4]; 3],
    colours: &[[f64; 3]; 3],
    size: (u32, u32),
    cull: Cull,
    rule: TieRule,
    mut f: impl FnMut(u32, u32, f64, [f64; 3]),
) {
    rasterize_samples(clip, size, cull, rule, |s| {
        let l = s.barycentrics;
        let col = colours;
        let colour =
            std::array::from_fn(|k| l[0] * col[0][k] + l[1] * col[1][k] + l[2] * col[2][k]);
        f(s.x, s.y, s.depth, colour);
    });
}

/// A covered sample of one triangle ([`rasterize_samples`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub x: u32,
    pub y: u32,
    /// Window depth in [0, 1].
    pub depth: f64,
    /// The perspective-correct `λ_i = E_i / (E_0 + E_1 + E_2)`.
    pub barycentrics: [f64; 3],
    /// The sign-normalised edge functions' `(A_i, B_i, C_i)`: `E_i = A_i·X + B_i·Y + C_i`
    /// in window pixels, so that attributes' screen-space derivatives are exact.
    pub edges: [V3; 3],
    /// `E_0 + E_1 + E_2` at the sample (positive).
    pub sum: f64,
}

/// Steps 1–6 of the module comment for one triangle, as [`rasterize_triangle`], giving each
/// covered sample's barycentrics and edge functions instead of an interpolated colour.
pub fn rasterize_samples(
    clip: &[[f64; 4]; 3],
    (width, height): (u32, u32),
    cull: Cull,
    rule: TieRule,
    mut f: impl FnMut(&Sample),
) {
    let c = clip;
    if width == 0 || height == 0 || trivially_rejected(c) {
        return;
    }
    let (half_w, half_h) = (f64::from(width) / 2.0, f64::from(height) / 2.0);
    let v: [V3; 3] = c.map(|p| [(p[0] + p[3]) * half_w, (p[1] + p[3]) * half_h, p[3]]);
    let mut edges = [cross(v[1], v[2]), cross(v[2], v[0]), cross(v[0], v[1])];
    let det = dot(v[0], edges[0]);
    let culled = match cull {
        Cull::Back => det < 0.0,
        Cull::Front => det > 0.0,
        Cull::None => false,
    };
    if det == 0.0 || !det.is_finite() || culled || !edges.iter().flatten().all(|e| e.is_finite()) {
        return;
    }
    if det < 0.0 {
        for e in &mut edges {
            *e = e.map(|k| -k);
        }
    }
    let owns_ties = edges.map(|[a, b, _]| rule.owns(a, b));

    let bounds = if v.iter().all(|p| p[2] > 0.0) {
        let xs = v.map(|p| p[0] / p[2]);
        let ys = v.map(|p| p[1] / p[2]);
        let min = |a: [f64; 3]| a[0].min(a[1]).min(a[2]);
        let max = |a: [f64; 3]| a[0].max(a[1]).max(a[2]);
        pixel_range(min(xs), max(xs), width).zip(pixel_range(min(ys), max(ys), height))
    } else {
        Some(((0, width - 1), (0, height - 1)))
    };
    let Some(((x0, x1), (y0, y1))) = bounds else {
        return;
    };

    for py in y0..=y1 {
        let y = f64::from(py) + 0.5;
        'pixel: for px in x0..=x1 {
            let x = f64::from(px) + 0.5;
            let mut e = [0.0; 3];
            for i in 0..3 {
                let [a, b, k] = edges[i];
                let value = a * x + b * y + k;
                if value < 0.0 || (value == 0.0 && !owns_ties[i]) {
                    continue 'pixel;
                }
                e[i] = value;
            }
            let sum = e[0] + e[1] + e[2];
            if sum <= 0.0 {
                continue;
            }
            let l = e.map(|ei| ei / sum);
            let z = l[0] * c[0][2] + l[1] * c[1][2] + l[2] * c[2][2];
            let w = l[0] * c[0][3] + l[1] * c[1][3] + l[2] * c[2][3];
            let depth = (z / w + 1.0) / 2.0;
            if !(0.0..=1.0).contains(&depth) {
                continue;
            }
            f(&Sample {
                x: px,
                y: py,
                depth,
                barycentrics: l,
                edges,
                sum,
            });
        }
    }
}

/// Whether a fragment at `depth` passes `test` against the stored depth `stored` (step 7,
/// generalised: the old scenes always use [`DepthTest::Less`]).
pub fn depth_passes(test: DepthTest, depth: f64, stored: f64) -> bool {
    match test {
        DepthTest::Less => depth < stored,
        DepthTest::Lequal => depth <= stored,
        DepthTest::Always => true,
    }
}

/// Runs steps 1–6 of the module comment over a scene, calling `f` for every fragment in
/// drawing order (triangle by triangle, then bottom row up, left to right). No depth test.
pub fn for_each_fragment(scene: &Scene, f: impl FnMut(&Fragment)) -> Result<(), SceneError> {
    for_each_fragment_with(scene, TieRule::TopLeft, f)
}

/// [`for_each_fragment`] with a choice of tie rule.
pub fn for_each_fragment_with(
    scene: &Scene,
    rule: TieRule,
    mut f: impl FnMut(&Fragment),
) -> Result<(), SceneError> {
    scene.validate()?;
    let clip: Vec<[f64; 4]> = scene
        .positions
        .iter()
        .map(|&p| clip_position(&scene.projection, &scene.modelview, p))
        .collect();
    let colours = vertex_colours(scene);
    let cull = if scene.cull_back {
        Cull::Back
    } else {
        Cull::None
    };
    for (triangle, (c, col)) in clip
        .chunks_exact(3)
        .zip(colours.chunks_exact(3))
        .enumerate()
    {
        let c: [[f64; 4]; 3] = [c[0], c[1], c[2]];
        let col: [[f64; 3]; 3] = [col[0], col[1], col[2]];
        rasterize_triangle(
            &c,
            &col,
            (scene.width, scene.height),
            cull,
            rule,
            |x, y, depth, colour| {
                f(&Fragment {
                    triangle,
                    x,
                    y,
                    depth,
                    colour,
                })
            },
        );
    }
    Ok(())
}

/// Renders a scene (see the module comment); an error when the scene does not validate.
pub fn try_render(scene: &Scene) -> Result<Image, SceneError> {
    render_with(scene, TieRule::TopLeft)
}

/// [`try_render`] with a choice of tie rule.
pub fn render_with(scene: &Scene, rule: TieRule) -> Result<Image, SceneError> {
    let mut image = Image::new(scene.width, scene.height);
    let mut depth = vec![1.0f64; image.pixels.len()];
    let width = scene.width as usize;
    for_each_fragment_with(scene, rule, |f| {
        let i = f.y as usize * width + f.x as usize;
        if depth_passes(DepthTest::Less, f.depth, depth[i]) {
            depth[i] = f.depth;
            let [r, g, b] = f.colour.map(quantise);
            image.pixels[i] = [r, g, b, 255];
        }
    })?;
    Ok(image)
}

/// Renders a scene (see the module comment).
///
/// # Panics
/// When the scene does not pass [`Scene::validate`]; use [`try_render`] for scenes from
/// outside.
pub fn render(scene: &Scene) -> Image {
    try_render(scene).unwrap_or_else(|e| panic!("reference renderer: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::BACKGROUND;
    use imagine_pipelines::scene::{IDENTITY, parse_tri, window_to_clip};

    /// A window-space, unlit scene from `(x, y, z, [r, g, b])` vertices.
    fn window_scene(
        width: u32,
        height: u32,
        vertices: &[([f32; 3], [f32; 3])],
        cull_back: bool,
    ) -> Scene {
        Scene {
            name: "test".into(),
            width,
            height,
            positions: vertices.iter().map(|v| v.0).collect(),
            normals: Vec::new(),
            colours: vertices.iter().map(|v| v.1).collect(),
            modelview: IDENTITY,
            projection: window_to_clip(width, height),
            shading: Shading::Unlit,
            cull_back,
        }
    }

    fn covered(image: &Image) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        for y in 0..image.height {
            for x in 0..image.width {
                if image.pixel(x, y) != BACKGROUND {
                    out.push((x, y));
                }
            }
        }
        out
    }

    /// How many fragments each pixel gets.
    fn hits(scene: &Scene) -> Vec<u32> {
        let mut count = vec![0; (scene.width * scene.height) as usize];
        for_each_fragment(scene, |f| {
            count[(f.y * scene.width + f.x) as usize] += 1;
        })
        .unwrap();
        count
    }

    const RED: [f32; 3] = [1.0, 0.0, 0.0];
    const GREEN: [f32; 3] = [0.0, 1.0, 0.0];
    const BLUE: [f32; 3] = [0.0, 0.0, 1.0];

    #[test]
    fn a_ccw_triangle_covers_the_hand_computed_pixels() {
        // Legs along x = 0.5 and y = 0.5, hypotenuse x + y = 7: all three pass through
        // pixel centres. The left edge x = 0.5 is included, the bottom edge y = 0.5 (inside
        // above: not a top edge) and the hypotenuse (inside to its left) are not. So:
        // px ≥ 0, py ≥ 1, (px + 0.5) + (py + 0.5) < 7.
        let scene = window_scene(
            8,
            8,
            &[
                ([0.5, 0.5, 0.5], RED),
                ([6.5, 0.5, 0.5], GREEN),
                ([0.5, 6.5, 0.5], BLUE),
            ],
            true,
        );
        let image = render(&scene);
        let mut want = Vec::new();
        for py in 1..8 {
            for px in 0..8 {
                if px + py < 6 {
                    want.push((px, py));
                }
            }
        }
        assert_eq!(want.len(), 15);
        assert_eq!(covered(&image), want);
        // Linear barycentrics (w = 1) at (2.5, 1.5): λ = (3/6, 2/6, 1/6).
        let p = image.pixel(2, 1);
        let expect = [3.0 / 6.0, 2.0 / 6.0, 1.0 / 6.0].map(|c: f64| c * 255.0);
        for k in 0..3 {
            assert!(
                (f64::from(p[k]) - expect[k]).abs() <= 0.5 + 1e-9,
                "{p:?} vs {expect:?}"
            );
        }
        assert_eq!(p[3], 255);
    }

    #[test]
    fn other_tie_rules_own_other_edges() {
        // The triangle of the test above: now the bottom edge y = 0.5 is in as well.
        let scene = window_scene(
            8,
            8,
            &[
                ([0.5, 0.5, 0.5], RED),
                ([6.5, 0.5, 0.5], GREEN),
                ([0.5, 6.5, 0.5], BLUE),
            ],
            true,
        );
        let image = render_with(&scene, TieRule::BottomLeft).unwrap();
        let want: Vec<(u32, u32)> = (0..8)
            .flat_map(|py| (0..8).map(move |px| (px, py)))
            .filter(|&(px, py)| px + py < 6)
            .collect();
        assert_eq!(want.len(), 21);
        assert_eq!(covered(&image), want);
        // Upside down, the top edge y = 7.5 is out and nothing else changes.
        let flipped = window_scene(
            8,
            8,
            &[
                ([0.5, 7.5, 0.5], RED),
                ([0.5, 1.5, 0.5], BLUE),
                ([6.5, 7.5, 0.5], GREEN),
            ],
            true,
        );
        let image = render_with(&flipped, TieRule::BottomLeft).unwrap();
        let want: Vec<(u32, u32)> = (0..8)
            .flat_map(|py| (0..8).map(move |px| (px, py)))
            .filter(|&(px, py)| py < 7 && px + (7 - py) < 6)
            .collect();
        assert_eq!(covered(&image), want);
        assert_eq!(TieRule::default(), TieRule::TopLeft);
        // Top-right: the hypotenuse (a right edge) is in, the left edge x = 0.5 is out,
        // and so is the bottom edge: px ≥ 1, py ≥ 1, px + py ≤ 6.
        let image = render_with(&scene, TieRule::TopRight).unwrap();
        let want: Vec<(u32, u32)> = (1..8)
            .flat_map(|py| (1..8).map(move |px| (px, py)))
            .filter(|&(px, py)| px + py <= 6)
            .collect();
        assert_eq!(covered(&image), want);
    }

    #[test]
    fn an_interior_triangle_without_ties() {
        // (1, 1), (7, 1), (1, 7): centres with px ≥ 1, py ≥ 1 and px + py + 1 < 8 — the
        // hypotenuse ties at px + py = 7 are excluded (a right edge).
        let scene = window_scene(
            8,
            8,
            &[
                ([1.0, 1.0, 0.5], RED),
                ([7.0, 1.0, 0.5], RED),
                ([1.0, 7.0, 0.5], RED),
            ],
            false,
        );
        let got = covered(&render(&scene));
        let want: Vec<(u32, u32)> = (1..8)
            .flat_map(|py| (1..8).map(move |px| (px, py)))
            .filter(|&(px, py)| px + py <= 6)
            .collect();
        assert_eq!(got, want);
    }

    #[test]
    fn triangles_sharing_edges_cover_each_pixel_once() {
        // A square with corners on pixel centres, cut along both diagonals into four
        // triangles: every edge passes through pixel centres. (A power-of-two window keeps
        // window_to_clip exact, so the ties survive the transform.)
        let (a, b, c, d, m) = (
            [1.5, 1.5, 0.5],
            [9.5, 1.5, 0.5],
            [9.5, 9.5, 0.5],
            [1.5, 9.5, 0.5],
            [5.5, 5.5, 0.5],
        );
        let triangles = [[a, b, m], [b, c, m], [c, d, m], [d, a, m]];
        let mut union = vec![0u32; 16 * 16];
        for (t, tri) in triangles.iter().enumerate() {
            // Alternate the vertex order within each triangle (still CCW).
            let tri = [tri[t % 3], tri[(t + 1) % 3], tri[(t + 2) % 3]];
            let scene = window_scene(16, 16, &tri.map(|p| (p, RED)), true);
            let one = hits(&scene);
            assert!(one.contains(&1), "triangle {t} covers nothing");
            for (u, h) in union.iter_mut().zip(one) {
                *u += h;
            }
        }
        // The square [1.5, 9.5]²: its left and top sides are in, right and bottom out:
        // px in 1..=8, py in 2..=9.
        for py in 0..16 {
            for px in 0..16 {
                let inside = (1..=8).contains(&px) && (2..=9).contains(&py);
                assert_eq!(
                    union[(py * 16 + px) as usize],
                    u32::from(inside),
                    "pixel ({px}, {py})"
                );
            }
        }
    }

    #[test]
    fn shared_edges_are_exact_in_perspective_too() {
        // Two triangles sharing a diagonal, seen in perspective (w varies per vertex).
        let mvp = [
            1.0, 0.0, 0.0, 0.0, //
            0.0, 1.0, 0.0, 0.0, //
            0.0, 0.0, 0.0, 0.0, //
            0.3, -0.2, 0.0, 1.7,
        ];
        let quad = [
            [-1.1f32, -0.9, 0.0],
            [1.3, -1.2, 0.0],
            [0.9, 1.4, 0.0],
            [-1.2, 1.1, 0.0],
        ];
        let mut scene = window_scene(64, 64, &[], false);
        scene.projection = mvp;
        let mut union = vec![0u32; 64 * 64];
        for tri in [[0, 1, 2], [0, 2, 3]] {
            scene.positions = tri.map(|i| quad[i]).to_vec();
            scene.colours = vec![RED; 3];
            for (u, h) in union.iter_mut().zip(hits(&scene)) {
                *u += h;
            }
        }
        scene.positions = [0, 1, 2, 0, 2, 3].map(|i| quad[i]).to_vec();
        scene.colours = vec![RED; 6];
        assert!(union.iter().all(|&h| h <= 1), "a pixel is hit twice");
        assert_eq!(union, hits(&scene));
        // No holes: every pixel centre clearly inside the projected quad is hit, none
        // clearly outside.
        let corners: Vec<[f64; 2]> = quad
            .iter()
            .map(|&p| {
                let c = clip_position(&mvp, &IDENTITY, p);
                [(c[0] / c[3] + 1.0) * 32.0, (c[1] / c[3] + 1.0) * 32.0]
            })
            .collect();
        let mut inside_count = 0;
        for py in 0..64u32 {
            for px in 0..64u32 {
                let (x, y) = (f64::from(px) + 0.5, f64::from(py) + 0.5);
                let margin = (0..4)
                    .map(|i| {
                        let ([ax, ay], [bx, by]) = (corners[i], corners[(i + 1) % 4]);
                        let (dx, dy) = (bx - ax, by - ay);
                        (dx * (y - ay) - dy * (x - ax)) / dx.hypot(dy)
                    })
                    .fold(f64::INFINITY, f64::min);
                if margin.abs() > 1e-6 {
                    let hit = union[(py * 64 + px) as usize];
                    assert_eq!(hit, u32::from(margin > 0.0), "pixel ({px}, {py})");
                    inside_count += hit;
                }
            }
        }
        assert!(inside_count > 1000, "{inside_count}");
    }

    #[test]
    fn depth_test_is_less_so_the_first_of_equal_depths_wins() {
        let square = |z: f32, colour| {
            [
                ([0.0, 0.0, z], colour),
                ([4.0, 0.0, z], colour),
                ([4.0, 4.0, z], colour),
                ([0.0, 0.0, z], colour),
                ([4.0, 4.0, z], colour),
                ([0.0, 4.0, z], colour),
            ]
        };
        let both = |first: [([f32; 3], [f32; 3]); 6], second: [([f32; 3], [f32; 3]); 6]| {
            let v: Vec<_> = first.into_iter().chain(second).collect();
            render(&window_scene(4, 4, &v, false))
        };
        let equal = both(square(0.5, RED), square(0.5, GREEN));
        assert!(equal.pixels.iter().all(|&p| p == [255, 0, 0, 255]));
        let nearer_second = both(square(0.5, RED), square(0.25, GREEN));
        assert!(nearer_second.pixels.iter().all(|&p| p == [0, 255, 0, 255]));
        let farther_second = both(square(0.5, RED), square(0.75, GREEN));
        assert!(farther_second.pixels.iter().all(|&p| p == [255, 0, 0, 255]));
        // Depth 1.0 fails LESS against the cleared buffer; depth 0 passes.
        assert!(
            render(&window_scene(4, 4, &square(1.0, RED), false))
                .pixels
                .iter()
                .all(|&p| p == BACKGROUND)
        );
        assert!(
            render(&window_scene(4, 4, &square(0.0, RED), false))
                .pixels
                .iter()
                .all(|&p| p == [255, 0, 0, 255])
        );
    }

    #[test]
    fn back_faces_are_culled_only_when_asked() {
        let ccw = [
            ([0.0, 0.0, 0.5], RED),
            ([8.0, 0.0, 0.5], RED),
            ([0.0, 8.0, 0.5], RED),
        ];
        let cw = [ccw[0], ccw[2], ccw[1]];
        let count =
            |v: &[([f32; 3], [f32; 3])], cull| covered(&render(&window_scene(8, 8, v, cull))).len();
        // px + py + 1 < 8 (the hypotenuse's ties are on a right edge): 1 + 2 + … + 7.
        assert_eq!(count(&ccw, true), 28);
        assert_eq!(count(&ccw, false), 28);
        assert_eq!(count(&cw, true), 0);
        assert_eq!(count(&cw, false), 28);
        // Degenerate (zero area) triangles draw nothing.
        let flat = [ccw[0], ccw[1], ([4.0, 0.0, 0.5], RED)];
        assert_eq!(count(&flat, false), 0);
    }

    #[test]
    fn a_triangle_crossing_w_zero_shows_its_visible_wedge() {
        // clip = (x, y, 0, z): the first two vertices have w = 1, the third w = −1 and
        // x = y = 0. Points between v0 (or v1) and v2 with w > 0 project to
        // (x, y)·(1 − s)/(1 − 2s): rays from the origin through v0 and v1, outward. The
        // visible part is the wedge beyond the segment v0 v1 between those rays:
        // y_ndc ≤ −0.5 and |x_ndc| ≤ −y_ndc, at depth 0.5.
        let mvp = [
            1.0, 0.0, 0.0, 0.0, //
            0.0, 1.0, 0.0, 0.0, //
            0.0, 0.0, 0.0, 0.0, //
            0.0, 0.0, 1.0, 0.0,
        ];
        let mut scene = window_scene(
            64,
            64,
            &[
                ([-0.5, -0.5, 1.0], RED),
                ([0.5, -0.5, 1.0], GREEN),
                ([0.0, 0.0, -1.0], BLUE),
            ],
            false,
        );
        scene.projection = mvp;
        let image = render(&scene);
        let mut checked = 0;
        for py in 0..64 {
            for px in 0..64 {
                let (x, y) = (
                    (px as f64 + 0.5) / 32.0 - 1.0,
                    (py as f64 + 0.5) / 32.0 - 1.0,
                );
                let margin = (-y - x.abs()).min(-0.5 - y);
                if margin.abs() < 1e-9 {
                    continue; // on the boundary: decided by the tie rule
                }
                let p = image.pixel(px, py);
                assert_eq!(p != BACKGROUND, margin > 0.0, "pixel ({px}, {py})");
                checked += 1;
                if margin > 0.0 {
                    // Solving b0·v0 + b1·v1 + b2·v2 = t·(x, y, 1) with Σ b = 1:
                    // t = −1 / (4y + 1), b = (−t(x + y), t(x − y), −t(2y + 1)).
                    let t = -1.0 / (4.0 * y + 1.0);
                    let b = [-t * (x + y), t * (x - y), -t * (2.0 * y + 1.0)];
                    for k in 0..3 {
                        let want = b[k] * 255.0;
                        assert!(
                            (f64::from(p[k]) - want).abs() <= 0.5 + 1e-6,
                            "pixel ({px}, {py}): {p:?} vs {b:?}"
                        );
                    }
                }
            }
        }
        assert!(checked > 4000);
        assert!(covered(&image).len() > 200);
        // The wedge runs v0 → v1 → down to infinity: clockwise, det < 0, so it is culled
        // as a back face.
        let mut culled = scene.clone();
        culled.cull_back = true;
        assert!(covered(&render(&culled)).is_empty());
    }

    #[test]
    fn near_and_far_clipping_and_w_near_zero_do_not_panic() {
        // A perspective view (near 1, far 10) of a floor-like triangle reaching behind the
        // eye, plus vertices at w = 0 and tiny w.
        let (n, f) = (1.0f32, 10.0f32);
        let mvp = [
            1.0,
            0.0,
            0.0,
            0.0, //
            0.0,
            1.0,
            0.0,
            0.0, //
            0.0,
            0.0,
            (f + n) / (n - f),
            2.0 * f * n / (n - f), //
            0.0,
            0.0,
            -1.0,
            0.0,
        ];
        for third in [
            [0.0, 3.0, 5.0],
            [0.0, 0.3, 0.0],
            [0.0, 0.3, -1e-30],
            [0.0, 0.3, 1e-30],
        ] {
            let mut scene = window_scene(
                32,
                32,
                &[
                    ([-3.0, -0.5, -4.0], RED),
                    ([3.0, -0.5, -4.0], GREEN),
                    (third, BLUE),
                ],
                false,
            );
            scene.projection = mvp;
            let mut depths = Vec::new();
            for_each_fragment(&scene, |f| depths.push(f.depth)).unwrap();
            assert!(depths.iter().all(|d| (0.0..=1.0).contains(d)));
            let image = render(&scene);
            assert!(!covered(&image).is_empty(), "{third:?}");
        }
        // A triangle entirely beyond the far plane, and one entirely behind the eye.
        for z in [-20.0, 2.0] {
            let mut scene = window_scene(
                32,
                32,
                &[
                    ([-3.0, -0.5, z], RED),
                    ([3.0, -0.5, z], GREEN),
                    ([0.0, 3.0, z], BLUE),
                ],
                false,
            );
            scene.projection = mvp;
            assert!(covered(&render(&scene)).is_empty(), "z = {z}");
        }
    }

    #[test]
    fn lighting_follows_the_documented_model() {
        // At p = (0, 0, 1) with N = +z, seen from the eye at (0, 0, 5): V = +z.
        // Light 0 head-on: N·L = N·H = 1. Lights 1 and 2 graze the surface from ±y:
        // N·L = 0, H = normalize(0, ±1, 1), N·H = 1/√2, (N·H)^16 = 1/256.
        let lighting = Lighting {
            eye: [0.0, 0.0, 5.0],
            lights: [
                ([0.0, 0.0, 5.0], [1.0, 1.0, 1.0]),
                ([0.0, 4.0, 1.0], [1.0, 0.0, 0.0]),
                ([0.0, -4.0, 1.0], [0.0, 0.0, 0.5]),
            ],
            diffuse: [0.5, 0.25, 0.125],
            specular: [0.25, 0.25, 0.25],
            ambient: [0.0625, 0.0, 0.0],
        };
        // The normal need not be unit length.
        let c = lit_colour(&lighting, [0.0, 0.0, 1.0], [0.0, 0.0, 2.0]);
        let want = [
            0.0625 + (0.5 + 0.25) + 0.25 / 256.0,
            0.25 + 0.25,
            0.125 + 0.25 + 0.5 * 0.25 / 256.0,
        ];
        for k in 0..3 {
            assert!((c[k] - want[k]).abs() < 1e-12, "{c:?} vs {want:?}");
        }
        // Clamped to [0, 1].
        let bright = Lighting {
            ambient: [2.0, 2.0, 2.0],
            ..lighting.clone()
        };
        assert_eq!(
            lit_colour(&bright, [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]),
            [1.0; 3]
        );
        let dark = Lighting {
            ambient: [-2.0, -2.0, -2.0],
            ..lighting
        };
        assert_eq!(
            lit_colour(&dark, [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]),
            [0.0; 3]
        );
    }

    #[test]
    fn the_small_sphere_renders_lit_and_culled() {
        let scene = imagine_pipelines::scene::sphere(2, 64);
        let image = render(&scene);
        let lit = covered(&image);
        // The sphere fills most of the window: a disc of radius ≈ 0.87·32 pixels.
        assert!(lit.len() > 1500 && lit.len() < 3000, "{}", lit.len());
        assert_eq!(image.pixel(0, 0), BACKGROUND);
        assert_ne!(image.pixel(32, 32), BACKGROUND);
        // Culling changes nothing for a closed convex mesh.
        let mut no_cull = scene.clone();
        no_cull.cull_back = false;
        assert_eq!(render(&no_cull), image);
    }

    #[test]
    fn invalid_scenes_are_errors_not_panics() {
        let mut scene = parse_tri("t", "4 4\n0 0 0.5 1 0 0 4 0 0.5 0 1 0 0 4 0.5 0 0 1\n").unwrap();
        scene.colours.pop();
        let e = try_render(&scene).unwrap_err().to_string();
        assert!(e.contains("colours"), "{e}");
    }
}
