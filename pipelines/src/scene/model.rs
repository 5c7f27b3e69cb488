//! The scene a file describes (`../shared/SCENE_FORMAT.md`), resolved: every default
//! applied, every name turned into an index, every asset read, every transform a matrix.
//! Pipelines and the reference renderers read only this.
//!
//! Matrices are row-major `[f32; 16]` with `clip = projection · view · model · (x, y, z, 1)`.
//! Objects drawn in window space (the `rate` primitive, `.tri` files) keep their
//! coordinates in pixels: their view is the identity and their projection is
//! [`super::window_to_clip`] of the window, whatever the camera says.

use std::path::PathBuf;

/// A scene ready to draw.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    pub name: String,
    /// The file it came from (`None` for generated scenes).
    pub source: Option<PathBuf>,
    pub width: u32,
    pub height: u32,
    /// The colour buffer's clear colour (depth clears to 1.0).
    pub background: [f32; 3],
    /// Global ambient light (`GL_LIGHT_MODEL_AMBIENT`).
    pub ambient: [f32; 3],
    pub camera: Camera,
    pub pipeline: PipelineSettings,
    /// Positional lights in world space, at most [`MAX_LIGHTS`].
    pub lights: Vec<Light>,
    pub textures: Vec<Texture>,
    pub materials: Vec<Material>,
    /// In drawing order.
    pub objects: Vec<Object>,
}

/// Most lights a scene may have (OpenGL's minimum `GL_MAX_LIGHTS`).
pub const MAX_LIGHTS: usize = 8;

/// The world-to-eye (`view`) and eye-to-clip (`projection`) matrices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub view: [f32; 16],
    pub projection: [f32; 16],
}

impl Camera {
    /// The far plane's distance over the near plane's, when the projection is a
    /// perspective one (row-major, last row `0 0 -1 0`): with `a = P[10] = −(f+n)/(f−n)`,
    /// `f/n = (1 − a)/(−1 − a)`; infinite when fp32 rounded `a` to −1 (f/n beyond about
    /// 1e7).
    pub fn far_over_near(&self) -> Option<f64> {
        let p = self.projection.map(f64::from);
        (p[12] == 0.0 && p[13] == 0.0 && p[14] == -1.0 && p[15] == 0.0)
            .then(|| (1.0 - p[10]) / (-1.0 - p[10]))
            .filter(|r| *r > 0.0)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PipelineKind {
    OpenGl,
    Reyes,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DepthTest {
    Less,
    Lequal,
    Always,
}

/// Which window-space winding is discarded (counter-clockwise is front).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cull {
    Back,
    Front,
    None,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Blend {
    None,
    /// `src_alpha, one_minus_src_alpha`.
    Alpha,
    /// `one, one`.
    Add,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PipelineSettings {
    pub kind: PipelineKind,
    pub depth_test: DepthTest,
    pub cull: Cull,
    pub blend: Blend,
    /// Reyes: the largest micropolygon side, in pixels.
    pub stop_length: f32,
    /// OpenGL: the most triangles per batch (the pipeline takes the largest batch up to
    /// this that the machine holds), or the pipeline's default.
    pub batch: Option<u32>,
    /// OpenGL: scale each triangle's clip corners by a power of two in `assemble_clip`
    /// (exact), so that the rasterizer's edge functions and determinant stay within fp32's
    /// range at any scale of clip space. Off by default: it costs about 1 % of SPHERE's
    /// cycles, and only clip coordinates beyond about 2^±40 need it.
    pub normalise_clip: bool,
    /// OpenGL: interpolate the depth from each triangle's own depth (`assemble_clip`'s
    /// reference depth ζ) rather than from 0, so that the edge functions' rounding is not
    /// multiplied by the depth itself. Off by default: it costs about 1 % of SPHERE's
    /// cycles (a word more per fragment), and depth ranges far beyond the published
    /// scenes' need it (near 1e-3 and far 1e6 lose silhouette pixels past depth 1).
    pub reference_depth: bool,
    /// OpenGL: `irast` takes a fragment's `1/ΣE` by this many Newton–Raphson steps on the
    /// multipliers and adders (1 to 3) instead of the divide unit (0, the default): fewer
    /// cycles, colours and varyings off by the steps' error.
    pub newton_raphson: u8,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// World space.
    pub position: [f32; 3],
    pub ambient: [f32; 3],
    pub diffuse: [f32; 3],
    pub specular: [f32; 3],
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Filter {
    Nearest,
    Linear,
    Trilinear,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Wrap {
    Repeat,
    Clamp,
}

/// A texture's base level: `texels[row * width + col]` as RGBA8 words (red in the low
/// byte), row 0 at the bottom (t = 0), as OpenGL stores it.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub texels: Vec<u32>,
    pub filter: Filter,
    pub wrap: Wrap,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shader {
    /// The vertex colour, Gouraud-interpolated.
    Unlit,
    /// OpenGL 1.x fixed-function lighting per vertex (the format's `lit`).
    Lit,
    /// MARBLE's procedural shader, per fragment: turbulence, a marble colour ramp, lit by
    /// the scene's first light (see `crate::kernels::turbulence`).
    Marble(Marble),
    /// VERONA's shader: the object displaced and its normal bumped by a combined
    /// displacement/bump map, coloured by a sphere-mapped environment texture read along
    /// the reflection of the bumped normal (see `crate::kernels::bump_env`).
    BumpEnv(BumpEnv),
}

/// The parameters of a `bump_env` material: the combined displacement/bump map it builds
/// ([`crate::scene::bump_map`]) and how far the map's height moves the surface. Its one
/// texture is the environment map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BumpEnv {
    /// Object-space distance along the normal a height of 1 moves a vertex.
    pub displacement: f32,
    /// The map's side in texels (a power of two).
    pub bump_size: u32,
    /// Bumps across the map in s and in t.
    pub bump_cells: u32,
    /// The slope of the bumps in the tangent-space normal (0: a flat map).
    pub bump_scale: f32,
}

/// The parameters of a `marble` material: `colour = ramp(sin(x·frequency +
/// turbulence(p)·turbulence_scale))` over object-space positions `p`, the turbulence over
/// `noise`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Marble {
    pub frequency: f32,
    pub turbulence_scale: f32,
    pub noise: Noise,
}

impl Marble {
    pub const DEFAULT: Marble = Marble {
        frequency: 4.0,
        turbulence_scale: 5.0,
        noise: Noise::Perlin,
    };
}

/// The noise under the marble's turbulence (a `marble` material's `noise`). Perlin's is
/// the default: Ward's, the publication's, is twice the ops, and the compiler takes about
/// 4 minutes to schedule it (far from its bound, II 626 against 418 on gold8).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Noise {
    /// Greg Ward's implementation of Perlin's noise (`crate::kernels::ward_noise`), the one the
    /// publication's MARBLE used.
    Ward,
    /// Perlin's improved noise (2002) over his permutation table in the scratchpad.
    #[default]
    Perlin,
}

impl Noise {
    /// The name in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Noise::Ward => "ward",
            Noise::Perlin => "perlin",
        }
    }

    /// Whether the shader reads Perlin's permutation table (a `perm` input stream).
    pub fn uses_table(self) -> bool {
        self == Noise::Perlin
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TextureMode {
    Modulate,
    Replace,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub shader: Shader,
    pub ambient: [f32; 3],
    pub diffuse: [f32; 3],
    pub specular: [f32; 3],
    pub shininess: f32,
    /// Indices into [`Scene::textures`], texture units in order.
    pub textures: Vec<usize>,
    pub texture_mode: TextureMode,
}

/// Where an object's coordinates live.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Space {
    /// Object coordinates, through the model matrix and the camera.
    World,
    /// Window pixels (x, y) and depth in [0, 1] (z): identity view, `window_to_clip`.
    Window,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    pub name: String,
    /// Index into [`Scene::materials`].
    pub material: usize,
    /// Object to world (`T · R · S`).
    pub model: [f32; 16],
    /// Vertex colour where the mesh has none.
    pub colour: [f32; 3],
    pub space: Space,
    pub mesh: Mesh,
    /// A patch object's patches as Bezier control points in object space (B-spline
    /// patches converted, [`super::bpt::to_bezier`]), for the Reyes pipeline; empty for
    /// other objects. `mesh` is their tessellation, for the OpenGL pipeline.
    pub patches: Vec<[[f32; 3]; 16]>,
}

/// A triangle of the scene, as a frame's pixel names the one it shows: the object's index
/// in [`Scene::objects`] and the triangle's in its [`Mesh::triangles`]. The machine's
/// framebuffer and the reference renderer both say which triangle each pixel shows, so the
/// two frames' visibility can be compared pixel by pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TriangleId {
    pub object: usize,
    pub triangle: usize,
}

/// Indexed triangles. Vertices are shared between the triangles that name them, unless
/// `separate` says each triangle has its own three (then `triangles[i] = [3i, 3i+1, 3i+2]`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<[f32; 3]>,
    /// One per position, or empty.
    pub normals: Vec<[f32; 3]>,
    /// One per position, or empty (then the object's colour).
    pub colours: Vec<[f32; 3]>,
    /// One per position, or empty.
    pub texcoords: Vec<[f32; 2]>,
    /// One per position, or empty: unit `∂P/∂s`, the direction of increasing s (the
    /// primitives of revolution carry them; `bump_env` needs them).
    pub tangents: Vec<[f32; 3]>,
    /// Counter-clockwise front faces, in drawing order.
    pub triangles: Vec<[u32; 3]>,
    pub separate: bool,
}

impl Scene {
    pub fn triangles(&self) -> usize {
        self.objects.iter().map(|o| o.mesh.triangles.len()).sum()
    }

    pub fn vertices(&self) -> usize {
        self.objects.iter().map(|o| o.mesh.positions.len()).sum()
    }

    /// The view and projection an object is drawn with.
    pub fn camera_for(&self, object: &Object) -> Camera {
        match object.space {
            Space::World => self.camera,
            Space::Window => Camera {
                view: super::IDENTITY,
                projection: super::window_to_clip(self.width, self.height),
            },
        }
    }
}
