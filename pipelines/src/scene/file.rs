//! Scene files (`../shared/SCENE_FORMAT.md`): TOML read into a [`model::Scene`], every
//! default applied, every name resolved, every asset read.
//!
//! Choices the format leaves open (the README lists them):
//! * `[camera]` may be left out (view and projection are then the identity); `up` defaults
//!   to `[0, 1, 0]`; the view comes from `eye`/`target`/`up` or `modelview`, the
//!   projection from `fov_y`/`near`/`far`, `ortho` or `projection`, one of each.
//! * `[pipeline]`: `kind = "opengl"`, `depth_test = "less"`, `cull = "none"` (OpenGL's
//!   initial state), `blend = "none"`, `stop_length = 1.5`; `batch` (the most triangles per
//!   batch, an addition to the format) defaults to the pipeline's choice, and
//!   `normalise_clip` (an addition: scale each triangle's clip corners by a power of two,
//!   exactly, so that clip coordinates of any magnitude rasterize) to false, and
//!   `reference_depth` (an addition: interpolate the depth from each triangle's own, for
//!   precision at any depth range) to false, and `newton_raphson` (an addition: `irast`'s
//!   reciprocal by 1 to 3 Newton–Raphson steps instead of the divide unit) to 0.
//! * `[window] background` defaults to black; a material's `shader` is required.
//! * A texture's `filter` defaults to `"nearest"` and `wrap` to `"repeat"`; a procedural
//!   checker defaults to `size = 256`, `cells = 8`, `colours = [[1,1,1], [0,0,0]]`. A
//!   texture's sides (image or `procedural.size`) must be powers of two, as OpenGL 1.2's are.
//! * An object may have a `name` (default: its mesh or patch file's name, or its primitive's
//!   kind) and `triangles = "shared" | "separate"` (default shared; separate gives every
//!   triangle three vertices of its own, as SPHERE's published vertex count has it).
//! * `tessellate` defaults to 20 (TEAPOT's OpenGL dicing), `basis` to `"bezier"`.
//! * `stitch = true` (patches only, an addition to the format; default false) sends each
//!   row of a diced patch as a strip joined to the next by two degenerate triangles, as the
//!   papers did: TEAPOT-N's `56·N·(N + 1)` triangles (see `bpt`).
//! * `cage = "x.obj"` (a closed polygon mesh) is its Catmull-Clark limit surface as
//!   bicubic Bezier patches, a patch per quad after one Catmull-Clark step (see `cage`),
//!   diced by `tessellate` (and `stitch`) for OpenGL like `.bpt` patches; `basis` is
//!   refused with it.
//! * `shader = "marble"` (MARBLE's procedural shader, per fragment; no textures, and the
//!   mesh needs normals, as for `lit`) takes three optional keys: `frequency` (default 4)
//!   and `turbulence_scale` (default 5), in `sin(x·frequency +
//!   turbulence(p)·turbulence_scale)` over object-space positions `p`, and `noise`, the
//!   noise under the turbulence: `"perlin"` (default; Perlin's improved noise) or `"ward"`
//!   (Greg Ward's implementation of Perlin's noise, the publication's, whose kernel the
//!   compiler takes minutes to schedule); of the other
//!   material keys it uses the means of `ambient` and `specular` (see
//!   `crate::opengl::render`'s notes on marble).
//!
//! Keys beyond the contract, for the analogs of the thesis's published scenes (Table 5.1;
//! the geometry is [`primitives`]'s, where each is documented):
//! * `primitive = { kind = "pin", rings, segments }`: a bowling pin of `rings` bands, each
//!   a closed strip of `segments` quads with its own two rows of vertices (V = T =
//!   2·rings·segments; PIN, PIN-8 and MARBLE's 200 × 200 is 80,000), base at y = 0, tip at
//!   y = 1, normals, s round and t up;
//! * `{ kind = "banded_sphere", rings, segments }`: the unit sphere in the same banded form
//!   (VERONA's geometry);
//! * `{ kind = "boxes", count, seed }` (`seed` defaults to 0): boxes on [−1, 1]² of y = 0,
//!   every face a quad of four vertices of its own with the whole texture (24 vertices, 12
//!   triangles a box); `{ kind = "tiles", columns, rows }`: a floor of such quads;
//!   `{ kind = "torus", rings, segments, minor }` (`minor`, the tube's radius against a
//!   major radius of 1, defaults to 0.25, in (0, 1)) — ADVS's parts;
//! * a texture's `procedural = { kind = "rectangles", size, rectangles = [[s0, t0, s1, t1],
//!   ...], colours = [background, fill] }`: the texels whose centres lie in a rectangle
//!   take the fill colour (`size` defaults to 256, `colours` to white and black).

use std::path::{Path, PathBuf};

use imagine_units::limits::{MAX_BATCH, MAX_NEWTON_STEPS, read_file, read_text_file};

use glam::dcamera::rh::proj::opengl;
use glam::{DMat4, DVec3};
use serde::Deserialize;

use super::bpt::{self, Basis};
use super::cage;
use super::model::{self, Mesh, Noise, Space};
use super::obj::{self, AssetError};
use super::{IDENTITY, MAX_WINDOW, SceneError, primitives, window_to_clip};

/// How to load a scene, beyond what its file says.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoadOptions {
    /// Draw into a `size × size` window instead of the file's (RATE-n's strips follow the
    /// window; the camera's aspect ratio is recomputed).
    pub size: Option<u32>,
    /// Subdivide every icosphere this many times instead (at most
    /// [`primitives::MAX_SUBDIVISIONS`]).
    pub subdivisions: Option<u32>,
    /// Filter every texture this way instead of as its `filter` says (to measure what a
    /// filter costs and what it changes; a `bump_env` environment map still must be
    /// `nearest`).
    pub filter: Option<model::Filter>,
}

/// The built-in scenes: (name, file text), the files of the source tree's `scenes/`.
pub const BUILTIN: &[(&str, &str)] = &[
    ("SPHERE", include_str!("../../../scenes/SPHERE.toml")),
    ("RATE-1", include_str!("../../../scenes/RATE-1.toml")),
    ("RATE-2", include_str!("../../../scenes/RATE-2.toml")),
    ("RATE-4", include_str!("../../../scenes/RATE-4.toml")),
    ("RATE-8", include_str!("../../../scenes/RATE-8.toml")),
    ("RATE-16", include_str!("../../../scenes/RATE-16.toml")),
    ("RATE-32", include_str!("../../../scenes/RATE-32.toml")),
    ("RATE-64", include_str!("../../../scenes/RATE-64.toml")),
    ("RATE-128", include_str!("../../../scenes/RATE-128.toml")),
    (
        "SPHERE-FULL",
        include_str!("../../../scenes/SPHERE-FULL.toml"),
    ),
    ("ADVS-1", include_str!("../../../scenes/ADVS-1.toml")),
    ("ADVS-8", include_str!("../../../scenes/ADVS-8.toml")),
    ("PIN", include_str!("../../../scenes/PIN.toml")),
    ("PIN-8", include_str!("../../../scenes/PIN-8.toml")),
    ("MARBLE", include_str!("../../../scenes/MARBLE.toml")),
    ("VERONA", include_str!("../../../scenes/VERONA.toml")),
    ("TEAPOT-20", include_str!("../../../scenes/TEAPOT-20.toml")),
    ("TEAPOT-30", include_str!("../../../scenes/TEAPOT-30.toml")),
    ("TEAPOT-40", include_str!("../../../scenes/TEAPOT-40.toml")),
    ("TEAPOT-64", include_str!("../../../scenes/TEAPOT-64.toml")),
    (
        "PIN-PATCHES",
        include_str!("../../../scenes/PIN-PATCHES.toml"),
    ),
    ("SPOT-CAGE", include_str!("../../../scenes/SPOT-CAGE.toml")),
];

/// The source tree's `scenes/` directory, where built-in scenes find their assets.
pub fn builtin_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the pipelines crate sits in the workspace")
        .join("scenes")
}

/// The first comment line of a built-in scene's file (its one-line description).
pub fn builtin_description(text: &str) -> &str {
    text.lines()
        .map(str::trim)
        .find_map(|l| l.strip_prefix('#'))
        .map(str::trim)
        .unwrap_or("")
}

/// A scene by built-in name (case-insensitive, see [`BUILTIN`]) or by path: `.toml` scene
/// files and `.tri` triangle files are read from disk, assets relative to the file.
pub fn load(name_or_path: &str, opts: &LoadOptions) -> Result<model::Scene, SceneError> {
    let lower = name_or_path.to_ascii_lowercase();
    if lower.ends_with(".tri") {
        return load_tri(Path::new(name_or_path));
    }
    if lower.ends_with(".toml") {
        return load_file(Path::new(name_or_path), opts);
    }
    match BUILTIN
        .iter()
        .find(|(name, _)| name.eq_ignore_ascii_case(name_or_path))
    {
        Some((name, text)) => parse(text, &builtin_dir().join(format!("{name}.toml")), opts),
        None => Err(SceneError::new(
            name_or_path,
            None,
            format!(
                "unknown scene: the built-in scenes are {}; scene files end in .toml, \
                 triangle files in .tri",
                BUILTIN
                    .iter()
                    .map(|(n, _)| *n)
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )),
    }
}

/// Reads a scene file.
pub fn load_file(path: &Path, opts: &LoadOptions) -> Result<model::Scene, SceneError> {
    let text = read_text_file(path).map_err(|e| {
        SceneError::new(
            &path.display().to_string(),
            None,
            format!("cannot read the file: {e}"),
        )
    })?;
    parse(&text, path, opts)
}

/// Reads a `.tri` file (see [`super::parse_tri`]) as a scene of one window-space object:
/// separate unlit triangles with their own colours, depth test less, no culling, black
/// background.
pub fn load_tri(path: &Path) -> Result<model::Scene, SceneError> {
    let shown = path.display().to_string();
    let text = read_text_file(path)
        .map_err(|e| SceneError::new(&shown, None, format!("cannot read the file: {e}")))?;
    let old = super::parse_tri(&shown, &text)?;
    let mut scene = window_scene(old);
    scene.name = stem(path);
    scene.objects[0].name = scene.name.clone();
    scene.source = Some(path.to_path_buf());
    Ok(scene)
}

/// A scene of window-space triangles (the `.tri` format's: unlit, per-vertex colours,
/// depth test LESS, no culling) as a scene model: one window-space object of separate
/// triangles.
pub fn window_scene(old: super::Scene) -> model::Scene {
    let triangles = (0..old.triangles() as u32)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    model::Scene {
        name: old.name.clone(),
        source: None,
        width: old.width,
        height: old.height,
        background: [0.0; 3],
        ambient: [0.0; 3],
        camera: model::Camera {
            view: IDENTITY,
            projection: window_to_clip(old.width, old.height),
        },
        pipeline: model::PipelineSettings {
            kind: model::PipelineKind::OpenGl,
            depth_test: model::DepthTest::Less,
            cull: model::Cull::None,
            blend: model::Blend::None,
            stop_length: 1.5,
            batch: None,
            normalise_clip: false,
            reference_depth: false,
            newton_raphson: 0,
        },
        lights: Vec::new(),
        textures: Vec::new(),
        materials: vec![default_material()],
        objects: vec![model::Object {
            name: old.name,
            material: 0,
            model: IDENTITY,
            colour: [1.0; 3],
            space: Space::Window,
            patches: Vec::new(),
            mesh: Mesh {
                positions: old.positions,
                normals: Vec::new(),
                colours: old.colours,
                texcoords: Vec::new(),
                tangents: Vec::new(),
                triangles,
                separate: true,
            },
        }],
    }
}

fn stem(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string())
}

/// The material of objects that name none: unlit, white (the object's colour).
fn default_material() -> model::Material {
    model::Material {
        name: "(default)".into(),
        shader: model::Shader::Unlit,
        ambient: [0.2, 0.2, 0.2],
        diffuse: [0.8, 0.8, 0.8],
        specular: [0.0; 3],
        shininess: 0.0,
        textures: Vec::new(),
        texture_mode: model::TextureMode::Modulate,
    }
}

// ---- the file's shape ----

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    name: Option<String>,
    ambient: Option<[f64; 3]>,
    window: WindowFile,
    camera: Option<CameraFile>,
    #[serde(default)]
    pipeline: PipelineFile,
    #[serde(default)]
    light: Vec<LightFile>,
    #[serde(default)]
    texture: Vec<TextureFile>,
    #[serde(default)]
    material: Vec<MaterialFile>,
    #[serde(default)]
    object: Vec<ObjectFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct WindowFile {
    width: u32,
    height: u32,
    background: Option<[f64; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraFile {
    eye: Option<[f64; 3]>,
    target: Option<[f64; 3]>,
    up: Option<[f64; 3]>,
    fov_y: Option<f64>,
    near: Option<f64>,
    far: Option<f64>,
    ortho: Option<[f64; 6]>,
    modelview: Option<[f64; 16]>,
    projection: Option<[f64; 16]>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct PipelineFile {
    kind: Option<KindFile>,
    depth_test: Option<DepthFile>,
    cull: Option<CullFile>,
    blend: Option<BlendFile>,
    stop_length: Option<f64>,
    batch: Option<i64>,
    normalise_clip: Option<bool>,
    reference_depth: Option<bool>,
    newton_raphson: Option<i64>,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum KindFile {
    OpenGl,
    Reyes,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum DepthFile {
    Less,
    Lequal,
    Always,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum CullFile {
    Back,
    Front,
    None,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum BlendFile {
    None,
    Alpha,
    Add,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightFile {
    position: [f64; 3],
    ambient: Option<[f64; 3]>,
    diffuse: Option<[f64; 3]>,
    specular: Option<[f64; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TextureFile {
    name: String,
    image: Option<String>,
    procedural: Option<ProceduralFile>,
    filter: Option<FilterFile>,
    wrap: Option<WrapFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ProceduralFile {
    kind: ProceduralKind,
    size: Option<u32>,
    cells: Option<u32>,
    colours: Option<[[f64; 3]; 2]>,
    rectangles: Option<Vec<[f64; 4]>>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
enum ProceduralKind {
    Checker,
    Rectangles,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum FilterFile {
    Nearest,
    Linear,
    Trilinear,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum WrapFile {
    Repeat,
    Clamp,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialFile {
    name: String,
    shader: ShaderFile,
    ambient: Option<[f64; 3]>,
    diffuse: Option<[f64; 3]>,
    specular: Option<[f64; 3]>,
    shininess: Option<f64>,
    #[serde(default)]
    textures: Vec<String>,
    texture_mode: Option<TextureModeFile>,
    frequency: Option<f64>,
    turbulence_scale: Option<f64>,
    displacement: Option<f64>,
    bump_size: Option<u32>,
    bump_cells: Option<u32>,
    bump_scale: Option<f64>,
    noise: Option<NoiseFile>,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum NoiseFile {
    Ward,
    Perlin,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum ShaderFile {
    Unlit,
    Lit,
    Marble,
    #[serde(rename = "bump_env")]
    BumpEnv,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum TextureModeFile {
    Modulate,
    Replace,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ObjectFile {
    name: Option<String>,
    mesh: Option<String>,
    primitive: Option<PrimitiveFile>,
    patches: Option<String>,
    basis: Option<BasisFile>,
    cage: Option<String>,
    material: Option<String>,
    colour: Option<[f64; 3]>,
    translate: Option<[f64; 3]>,
    rotate: Option<[f64; 4]>,
    scale: Option<[f64; 3]>,
    tessellate: Option<u32>,
    stitch: Option<bool>,
    triangles: Option<TrianglesFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PrimitiveFile {
    kind: PrimitiveKind,
    subdivisions: Option<u32>,
    rings: Option<u32>,
    segments: Option<u32>,
    size: Option<u32>,
    count: Option<u32>,
    seed: Option<u64>,
    columns: Option<u32>,
    rows: Option<u32>,
    minor: Option<f64>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
enum PrimitiveKind {
    Icosphere,
    UvSphere,
    Rate,
    Pin,
    BandedSphere,
    Boxes,
    Tiles,
    Torus,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum BasisFile {
    Bezier,
    Bspline,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
enum TrianglesFile {
    Shared,
    Separate,
}

// ---- resolving ----

pub use imagine_units::limits::{MAX_SPHERE_DIVISIONS, MAX_TESSELLATE, MAX_TRIANGLES};

/// Reads a scene file's text; `path` names it in errors and locates its assets.
pub fn parse(text: &str, path: &Path, opts: &LoadOptions) -> Result<model::Scene, SceneError> {
    let cx = Cx {
        file: path.display().to_string(),
        dir: path.parent().map(Path::to_path_buf).unwrap_or_default(),
    };
    let f: SceneFile = toml::from_str(text).map_err(|e| cx.toml(text, e))?;
    cx.resolve(f, path, opts)
}

struct Cx {
    file: String,
    dir: PathBuf,
}

type R<T> = Result<T, SceneError>;

impl Cx {
    fn err(&self, key: &str, message: impl std::fmt::Display) -> SceneError {
        SceneError::new(&self.file, None, format!("`{key}`: {message}"))
    }

    fn toml(&self, text: &str, e: toml::de::Error) -> SceneError {
        let line = e
            .span()
            .map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1);
        // Without its input, the error prints the key path it was raised under.
        let mut bare = e.clone();
        bare.set_input(None);
        let shown = bare.to_string();
        let keys = shown
            .lines()
            .find_map(|l| l.strip_prefix("in `")?.strip_suffix('`'));
        let message = match keys {
            Some(k) => format!("`{}`: {}", index_tables(text, k, line), e.message()),
            None => e.message().to_string(),
        };
        SceneError::new(&self.file, line, message)
    }

    fn asset(&self, key: &str, path: &Path, e: AssetError) -> SceneError {
        let at = match e.line {
            Some(l) => format!("`{}` line {l}", path.display()),
            None => format!("`{}`", path.display()),
        };
        self.err(key, format!("{at}: {}", e.message))
    }

    fn read(&self, key: &str, file: &str) -> R<(PathBuf, Vec<u8>)> {
        let path = self.dir.join(file);
        // A device or a pipe is not read: `/dev/zero` never ends, a FIFO waits for a writer.
        if std::fs::metadata(&path).is_ok_and(|m| !m.is_file()) {
            return Err(self.err(key, format!("cannot read `{}`: not a file", path.display())));
        }
        let bytes = read_file(&path)
            .map_err(|e| self.err(key, format!("cannot read `{}`: {e}", path.display())))?;
        Ok((path, bytes))
    }

    fn finite(&self, key: &str, v: &[f64]) -> R<()> {
        if let Some(x) = v.iter().find(|x| !x.is_finite()) {
            return Err(self.err(key, format!("{x} is not a finite number")));
        }
        Ok(())
    }

    fn vec3(&self, key: &str, v: [f64; 3]) -> R<[f32; 3]> {
        self.finite(key, &v)?;
        Ok(v.map(|c| c as f32))
    }

    fn colour(&self, key: &str, v: Option<[f64; 3]>, default: f32) -> R<[f32; 3]> {
        let Some(v) = v else {
            return Ok([default; 3]);
        };
        self.finite(key, &v)?;
        if let Some(x) = v.iter().find(|x| !(0.0..=1.0).contains(*x)) {
            return Err(self.err(
                key,
                format!("{x} is outside [0, 1] (colours are linear RGB)"),
            ));
        }
        Ok(v.map(|c| c as f32))
    }

    fn matrix(&self, key: &str, m: DMat4) -> R<[f32; 16]> {
        // `+ 0.0` turns the -0 entries of a look-at into 0.
        let rows = m.transpose().to_cols_array().map(|x| x as f32 + 0.0);
        if rows.iter().any(|x| !x.is_finite()) {
            return Err(self.err(
                key,
                "the matrix has an entry that is not a finite fp32 number",
            ));
        }
        Ok(rows)
    }

    fn resolve(&self, f: SceneFile, path: &Path, opts: &LoadOptions) -> R<model::Scene> {
        let (width, height) = match opts.size {
            Some(s) => (s, s),
            None => (f.window.width, f.window.height),
        };
        for (key, v) in [("window.width", width), ("window.height", height)] {
            if !(1..=MAX_WINDOW).contains(&v) {
                return Err(self.err(key, format!("{v} is outside 1..={MAX_WINDOW} pixels")));
            }
        }
        if let Some(s) = opts.subdivisions
            && s > primitives::MAX_SUBDIVISIONS
        {
            return Err(self.err(
                "primitive.subdivisions",
                format!(
                    "the override {s} is beyond {}",
                    primitives::MAX_SUBDIVISIONS
                ),
            ));
        }
        let background = self.colour("window.background", f.window.background, 0.0)?;
        let ambient = self.colour("ambient", f.ambient, 0.0)?;
        let camera = match &f.camera {
            Some(c) => self.camera(c, width, height)?,
            None => model::Camera {
                view: IDENTITY,
                projection: IDENTITY,
            },
        };
        let pipeline = self.pipeline(&f.pipeline)?;
        if f.light.len() > model::MAX_LIGHTS {
            return Err(self.err(
                "light",
                format!(
                    "{} lights; a scene has at most {}",
                    f.light.len(),
                    model::MAX_LIGHTS
                ),
            ));
        }
        let lights = f
            .light
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let key = |k: &str| format!("light[{i}].{k}");
                Ok(model::Light {
                    position: self.vec3(&key("position"), l.position)?,
                    ambient: self.colour(&key("ambient"), l.ambient, 0.0)?,
                    diffuse: self.colour(&key("diffuse"), l.diffuse, 1.0)?,
                    specular: self.colour(&key("specular"), l.specular, 1.0)?,
                })
            })
            .collect::<R<Vec<_>>>()?;
        let mut textures = Vec::new();
        for (i, t) in f.texture.iter().enumerate() {
            if textures.iter().any(|u: &model::Texture| u.name == t.name) {
                return Err(self.err(
                    &format!("texture[{i}].name"),
                    format!("a texture named `{}` comes before", t.name),
                ));
            }
            let mut texture = self.texture(i, t)?;
            if let Some(filter) = opts.filter {
                texture.filter = filter;
            }
            textures.push(texture);
        }
        let mut materials = Vec::new();
        for (i, m) in f.material.iter().enumerate() {
            if materials.iter().any(|u: &model::Material| u.name == m.name) {
                return Err(self.err(
                    &format!("material[{i}].name"),
                    format!("a material named `{}` comes before", m.name),
                ));
            }
            materials.push(self.material(i, m, &textures)?);
        }
        if f.object.is_empty() {
            return Err(self.err("object", "the scene has no [[object]]"));
        }
        let mut default = None;
        let mut objects = Vec::new();
        // Triangles the objects still to come may have.
        let mut left = MAX_TRIANGLES;
        for (i, o) in f.object.iter().enumerate() {
            let material = match &o.material {
                Some(name) => materials
                    .iter()
                    .position(|m| &m.name == name)
                    .ok_or_else(|| {
                        self.err(
                            &format!("object[{i}].material"),
                            format!(
                                "no [[material]] is named `{name}` (the materials are: {})",
                                names(materials.iter().map(|m| m.name.as_str()))
                            ),
                        )
                    })?,
                None => *default.get_or_insert_with(|| {
                    materials.push(default_material());
                    materials.len() - 1
                }),
            };
            // Lit and marble materials shade with normals.
            let lit = materials[material].shader != model::Shader::Unlit;
            let object = self.object(i, o, material, lit, width, height, left, opts)?;
            let bump_env = matches!(materials[material].shader, model::Shader::BumpEnv(_));
            if bump_env && object.mesh.tangents.len() != object.mesh.positions.len() {
                return Err(self.err(
                    &format!("object[{i}].material"),
                    format!(
                        "`{}` is a `bump_env` material, which needs tangents: of the meshes \
                         only the uv_sphere, banded_sphere and pin primitives carry them",
                        materials[material].name
                    ),
                ));
            }
            left -= object.mesh.triangles.len();
            objects.push(object);
        }
        Ok(model::Scene {
            name: f.name.unwrap_or_else(|| stem(path)),
            source: Some(path.to_path_buf()),
            width,
            height,
            background,
            ambient,
            camera,
            pipeline,
            lights,
            textures,
            materials,
            objects,
        })
    }

    fn camera(&self, c: &CameraFile, width: u32, height: u32) -> R<model::Camera> {
        let view = match (c.modelview, c.eye, c.target) {
            (Some(m), None, None) if c.up.is_none() => {
                self.finite("camera.modelview", &m)?;
                DMat4::from_cols_array(&m).transpose()
            }
            (Some(_), ..) => {
                return Err(self.err(
                    "camera.modelview",
                    "give either `modelview` or `eye`, `target` and `up`, not both",
                ));
            }
            (None, Some(eye), Some(target)) => {
                let up = c.up.unwrap_or([0.0, 1.0, 0.0]);
                for (k, v) in [("eye", eye), ("target", target), ("up", up)] {
                    self.finite(&format!("camera.{k}"), &v)?;
                }
                let (eye, target, up) = (DVec3::from(eye), DVec3::from(target), DVec3::from(up));
                let forward = target - eye;
                if forward.length_squared() == 0.0 {
                    return Err(self.err("camera.target", "the target is the eye"));
                }
                if forward.cross(up).length_squared() == 0.0 {
                    return Err(self.err("camera.up", "`up` is parallel to the view direction"));
                }
                glam::dcamera::rh::view::look_at_mat4(eye, target, up)
            }
            (None, None, _) => {
                return Err(self.err("camera.eye", "missing (or give `modelview`)"));
            }
            (None, Some(_), None) => return Err(self.err("camera.target", "missing")),
        };
        let aspect = f64::from(width) / f64::from(height);
        let projection = match (c.fov_y, c.ortho, c.projection) {
            (Some(fov), None, None) => {
                self.finite("camera.fov_y", &[fov])?;
                if !(fov > 0.0 && fov < 180.0) {
                    return Err(
                        self.err("camera.fov_y", format!("{fov} is outside (0, 180) degrees"))
                    );
                }
                let near = c
                    .near
                    .ok_or_else(|| self.err("camera.near", "missing (fov_y needs near and far)"))?;
                let far = c
                    .far
                    .ok_or_else(|| self.err("camera.far", "missing (fov_y needs near and far)"))?;
                self.finite("camera.near", &[near])?;
                self.finite("camera.far", &[far])?;
                if near <= 0.0 {
                    return Err(self.err("camera.near", format!("{near} is not positive")));
                }
                if far <= near {
                    return Err(
                        self.err("camera.far", format!("{far} is not beyond near = {near}"))
                    );
                }
                opengl::perspective(fov.to_radians(), aspect, near, far)
            }
            (None, Some(o), None) => {
                self.finite("camera.ortho", &o)?;
                if c.near.is_some() || c.far.is_some() {
                    return Err(self.err(
                        if c.near.is_some() {
                            "camera.near"
                        } else {
                            "camera.far"
                        },
                        "`ortho` gives near and far itself",
                    ));
                }
                let [l, r, b, t, n, f] = o;
                if l == r || b == t || n == f {
                    return Err(
                        self.err("camera.ortho", "left = right, bottom = top or near = far")
                    );
                }
                opengl::orthographic(l, r, b, t, n, f)
            }
            (None, None, Some(p)) => {
                self.finite("camera.projection", &p)?;
                if c.near.is_some() || c.far.is_some() {
                    return Err(self.err(
                        if c.near.is_some() {
                            "camera.near"
                        } else {
                            "camera.far"
                        },
                        "only with `fov_y`",
                    ));
                }
                DMat4::from_cols_array(&p).transpose()
            }
            (None, None, None) => {
                return Err(self.err(
                    "camera.fov_y",
                    "missing: give `fov_y`, `near` and `far`, or `ortho`, or `projection`",
                ));
            }
            _ => {
                return Err(self.err(
                    "camera.projection",
                    "give one of `fov_y`, `ortho` and `projection`",
                ));
            }
        };
        Ok(model::Camera {
            view: self.matrix("camera.modelview", view)?,
            projection: self.matrix("camera.projection", projection)?,
        })
    }

    fn pipeline(&self, p: &PipelineFile) -> R<model::PipelineSettings> {
        let stop_length = p.stop_length.unwrap_or(1.5);
        self.finite("pipeline.stop_length", &[stop_length])?;
        if stop_length <= 0.0 {
            return Err(self.err(
                "pipeline.stop_length",
                format!("{stop_length} is not a positive length"),
            ));
        }
        Ok(model::PipelineSettings {
            kind: match p.kind.unwrap_or(KindFile::OpenGl) {
                KindFile::OpenGl => model::PipelineKind::OpenGl,
                KindFile::Reyes => model::PipelineKind::Reyes,
            },
            depth_test: match p.depth_test.unwrap_or(DepthFile::Less) {
                DepthFile::Less => model::DepthTest::Less,
                DepthFile::Lequal => model::DepthTest::Lequal,
                DepthFile::Always => model::DepthTest::Always,
            },
            cull: match p.cull.unwrap_or(CullFile::None) {
                CullFile::Back => model::Cull::Back,
                CullFile::Front => model::Cull::Front,
                CullFile::None => model::Cull::None,
            },
            blend: match p.blend.unwrap_or(BlendFile::None) {
                BlendFile::None => model::Blend::None,
                BlendFile::Alpha => model::Blend::Alpha,
                BlendFile::Add => model::Blend::Add,
            },
            stop_length: stop_length as f32,
            normalise_clip: p.normalise_clip.unwrap_or(false),
            reference_depth: p.reference_depth.unwrap_or(false),
            newton_raphson: match p.newton_raphson {
                None => 0,
                Some(n) if (0..=i64::from(MAX_NEWTON_STEPS)).contains(&n) => n as u8,
                Some(n) => {
                    return Err(self.err(
                        "pipeline.newton_raphson",
                        format!("{n} is outside 0..={MAX_NEWTON_STEPS} steps (0: the divide unit)"),
                    ));
                }
            },
            batch: match p.batch {
                None => None,
                Some(n) if (1..=i64::from(MAX_BATCH)).contains(&n) => Some(n as u32),
                Some(n) => {
                    return Err(self.err(
                        "pipeline.batch",
                        format!("{n} is outside 1..={MAX_BATCH} triangles"),
                    ));
                }
            },
        })
    }

    fn texture(&self, i: usize, t: &TextureFile) -> R<model::Texture> {
        let key = |k: &str| format!("texture[{i}].{k}");
        let (width, height, texels) = match (&t.image, &t.procedural) {
            (Some(file), None) => {
                let (path, bytes) = self.read(&key("image"), file)?;
                // The size is checked from the header, before a hostile file's declared
                // gigapixels are allocated.
                let mut reader = image::ImageReader::with_format(
                    std::io::Cursor::new(&bytes),
                    image::ImageFormat::Png,
                );
                let mut limits = image::Limits::default();
                limits.max_image_width = Some(MAX_WINDOW);
                limits.max_image_height = Some(MAX_WINDOW);
                reader.limits(limits);
                let img = reader.decode().map_err(|e| {
                    let problem = match e {
                        image::ImageError::Limits(_) => {
                            format!("is larger than {MAX_WINDOW} texels a side")
                        }
                        e => format!("is not a PNG image: {e}"),
                    };
                    self.err(&key("image"), format!("`{}` {problem}", path.display()))
                })?;
                use image::ColorType as C;
                if !matches!(img.color(), C::L8 | C::La8 | C::Rgb8 | C::Rgba8) {
                    return Err(self.err(
                        &key("image"),
                        format!(
                            "`{}` has {:?} pixels; textures are 8-bit grey, RGB or RGBA",
                            path.display(),
                            img.color()
                        ),
                    ));
                }
                let rgba = img.to_rgba8();
                let (w, h) = rgba.dimensions();
                if w > MAX_WINDOW || h > MAX_WINDOW {
                    return Err(self.err(
                        &key("image"),
                        format!(
                            "`{}` is {w}x{h}, beyond {MAX_WINDOW} texels a side",
                            path.display()
                        ),
                    ));
                }
                if !(w.is_power_of_two() && h.is_power_of_two()) {
                    return Err(self.err(
                        &key("image"),
                        format!(
                            "`{}` is {w}x{h}: OpenGL 1.2 textures have power-of-two sides",
                            path.display()
                        ),
                    ));
                }
                // Row 0 of the file is the top; row 0 of the texture is the bottom.
                let texels = (0..h)
                    .rev()
                    .flat_map(|row| (0..w).map(move |col| (col, row)))
                    .map(|(col, row)| u32::from_le_bytes(rgba.get_pixel(col, row).0))
                    .collect();
                (w, h, texels)
            }
            (None, Some(p)) => {
                let size = p.size.unwrap_or(256);
                let cells = p.cells.unwrap_or(8);
                if !(1..=MAX_WINDOW).contains(&size) {
                    return Err(self.err(
                        &key("procedural.size"),
                        format!("{size} is outside 1..={MAX_WINDOW} texels"),
                    ));
                }
                if !size.is_power_of_two() {
                    return Err(self.err(
                        &key("procedural.size"),
                        format!("{size} is not a power of two (OpenGL 1.2 textures need one)"),
                    ));
                }
                let colours = match p.colours {
                    Some([a, b]) => [
                        self.colour(&key("procedural.colours"), Some(a), 0.0)?,
                        self.colour(&key("procedural.colours"), Some(b), 0.0)?,
                    ],
                    None => [[1.0; 3], [0.0; 3]],
                };
                let rectangles = p.kind == ProceduralKind::Rectangles;
                if p.cells.is_some() && rectangles {
                    return Err(self.err(&key("procedural.cells"), "only for `checker`"));
                }
                if let Some(r) = &p.rectangles {
                    if !rectangles {
                        return Err(
                            self.err(&key("procedural.rectangles"), "only for `rectangles`")
                        );
                    }
                    self.finite(&key("procedural.rectangles"), r.as_flattened())?;
                    let texels = primitives::rectangles(size, r, colours);
                    return Self::finish_texture(t, (size, size), texels);
                }
                if rectangles {
                    return Err(self.err(&key("procedural.rectangles"), "missing"));
                }
                if !(1..=size).contains(&cells) {
                    return Err(self.err(
                        &key("procedural.cells"),
                        format!("{cells} is outside 1..={size} (the texture's size)"),
                    ));
                }
                (size, size, primitives::checker(size, cells, colours))
            }
            (Some(_), Some(_)) => {
                return Err(self.err(&key("procedural"), "give `image` or `procedural`, not both"));
            }
            (None, None) => {
                return Err(self.err(&key("image"), "missing (or give `procedural`)"));
            }
        };
        Self::finish_texture(t, (width, height), texels)
    }

    /// A texture of `texels` with the file's name, filter and wrap.
    fn finish_texture(
        t: &TextureFile,
        (width, height): (u32, u32),
        texels: Vec<u32>,
    ) -> R<model::Texture> {
        Ok(model::Texture {
            name: t.name.clone(),
            width,
            height,
            texels,
            filter: match t.filter.unwrap_or(FilterFile::Nearest) {
                FilterFile::Nearest => model::Filter::Nearest,
                FilterFile::Linear => model::Filter::Linear,
                FilterFile::Trilinear => model::Filter::Trilinear,
            },
            wrap: match t.wrap.unwrap_or(WrapFile::Repeat) {
                WrapFile::Repeat => model::Wrap::Repeat,
                WrapFile::Clamp => model::Wrap::Clamp,
            },
        })
    }

    /// A `bump_env` material's parameters (`None` for other shaders, which may not have
    /// its keys): `displacement` (required, finite), `bump_size` (a power of two in
    /// 2..=2048, default 256), `bump_cells` (1..=bump_size/2, default 8), `bump_scale`
    /// (0..=8, default 1), and exactly one texture, the environment map, point-sampled.
    fn bump_env(
        &self,
        i: usize,
        m: &MaterialFile,
        textures: &[usize],
        scene_textures: &[model::Texture],
    ) -> R<Option<model::BumpEnv>> {
        let key = |k: &str| format!("material[{i}].{k}");
        if !matches!(m.shader, ShaderFile::BumpEnv) {
            let given = [
                ("displacement", m.displacement.is_some()),
                ("bump_size", m.bump_size.is_some()),
                ("bump_cells", m.bump_cells.is_some()),
                ("bump_scale", m.bump_scale.is_some()),
            ];
            if let Some((k, _)) = given.iter().find(|(_, given)| *given) {
                return Err(self.err(&key(k), "only a `bump_env` material has it"));
            }
            return Ok(None);
        }
        let displacement = m.displacement.ok_or_else(|| {
            self.err(
                &key("displacement"),
                "a `bump_env` material needs it (object-space distance at height 1)",
            )
        })?;
        self.finite(&key("displacement"), &[displacement])?;
        let bump_size = m.bump_size.unwrap_or(256);
        if !(2..=2048).contains(&bump_size) || !bump_size.is_power_of_two() {
            return Err(self.err(
                &key("bump_size"),
                format!("{bump_size} is not a power of two in 2..=2048"),
            ));
        }
        let bump_cells = m.bump_cells.unwrap_or(8);
        if !(1..=bump_size / 2).contains(&bump_cells) {
            return Err(self.err(
                &key("bump_cells"),
                format!(
                    "{bump_cells} is outside 1..={} (bump_size / 2)",
                    bump_size / 2
                ),
            ));
        }
        let bump_scale = m.bump_scale.unwrap_or(1.0);
        self.finite(&key("bump_scale"), &[bump_scale])?;
        if !(0.0..=8.0).contains(&bump_scale) {
            return Err(self.err(&key("bump_scale"), format!("{bump_scale} is outside 0..=8")));
        }
        match textures {
            [t] if scene_textures[*t].filter == model::Filter::Nearest => {}
            [t] => {
                return Err(self.err(
                    &key("textures"),
                    format!(
                        "the environment map `{}` must be point-sampled (filter = \"nearest\")",
                        scene_textures[*t].name
                    ),
                ));
            }
            _ => {
                return Err(self.err(
                    &key("textures"),
                    format!(
                        "a `bump_env` material takes exactly one texture, its environment \
                         (sphere) map; it names {}",
                        textures.len()
                    ),
                ));
            }
        }
        Ok(Some(model::BumpEnv {
            displacement: displacement as f32,
            bump_size,
            bump_cells,
            bump_scale: bump_scale as f32,
        }))
    }

    fn material(
        &self,
        i: usize,
        m: &MaterialFile,
        scene_textures: &[model::Texture],
    ) -> R<model::Material> {
        let key = |k: &str| format!("material[{i}].{k}");
        let shininess = m.shininess.unwrap_or(0.0);
        self.finite(&key("shininess"), &[shininess])?;
        if !(0.0..=128.0).contains(&shininess) {
            return Err(self.err(&key("shininess"), format!("{shininess} is outside 0..=128")));
        }
        let textures = m
            .textures
            .iter()
            .map(|name| {
                scene_textures
                    .iter()
                    .position(|t| &t.name == name)
                    .ok_or_else(|| {
                        self.err(
                            &key("textures"),
                            format!(
                                "no [[texture]] is named `{name}` (the textures are: {})",
                                names(scene_textures.iter().map(|t| t.name.as_str()))
                            ),
                        )
                    })
            })
            .collect::<R<Vec<_>>>()?;
        let marble = |k: &str, v: Option<f64>, default: f32| -> R<f32> {
            match (m.shader, v) {
                (ShaderFile::Marble, None) => Ok(default),
                (ShaderFile::Marble, Some(v)) => {
                    self.finite(&key(k), &[v])?;
                    Ok(v as f32)
                }
                (_, None) => Ok(0.0),
                (_, Some(_)) => Err(self.err(&key(k), "only a `marble` material has it")),
            }
        };
        let frequency = marble("frequency", m.frequency, model::Marble::DEFAULT.frequency)?;
        let turbulence_scale = marble(
            "turbulence_scale",
            m.turbulence_scale,
            model::Marble::DEFAULT.turbulence_scale,
        )?;
        let bump_env = self.bump_env(i, m, &textures, scene_textures)?;
        let noise = match (m.shader, m.noise) {
            (ShaderFile::Marble, None) => model::Marble::DEFAULT.noise,
            (ShaderFile::Marble, Some(NoiseFile::Ward)) => Noise::Ward,
            (ShaderFile::Marble, Some(NoiseFile::Perlin)) => Noise::Perlin,
            (_, None) => Noise::default(),
            (_, Some(_)) => return Err(self.err(&key("noise"), "only a `marble` material has it")),
        };
        if matches!(m.shader, ShaderFile::Marble) && !textures.is_empty() {
            return Err(self.err(
                &key("textures"),
                "a `marble` material is procedural and takes no textures",
            ));
        }
        Ok(model::Material {
            name: m.name.clone(),
            shader: match m.shader {
                ShaderFile::Unlit => model::Shader::Unlit,
                ShaderFile::Lit => model::Shader::Lit,
                ShaderFile::Marble => model::Shader::Marble(model::Marble {
                    frequency,
                    turbulence_scale,
                    noise,
                }),
                ShaderFile::BumpEnv => model::Shader::BumpEnv(bump_env.expect("checked")),
            },
            ambient: self.colour(&key("ambient"), m.ambient, 0.2)?,
            diffuse: self.colour(&key("diffuse"), m.diffuse, 0.8)?,
            specular: self.colour(&key("specular"), m.specular, 0.0)?,
            shininess: shininess as f32,
            textures,
            texture_mode: match m.texture_mode.unwrap_or(TextureModeFile::Modulate) {
                TextureModeFile::Modulate => model::TextureMode::Modulate,
                TextureModeFile::Replace => model::TextureMode::Replace,
            },
        })
    }

    #[allow(clippy::too_many_arguments)]
    fn object(
        &self,
        i: usize,
        o: &ObjectFile,
        material: usize,
        lit: bool,
        width: u32,
        height: u32,
        left: usize,
        opts: &LoadOptions,
    ) -> R<model::Object> {
        let key = |k: &str| format!("object[{i}].{k}");
        // `triangles` more than the scene has room for (`left` of MAX_TRIANGLES).
        let room = |k: &str, triangles: u64| {
            if triangles <= left as u64 {
                return Ok(());
            }
            Err(self.err(
                &key(k),
                format!(
                    "{triangles} triangles; a scene has at most {MAX_TRIANGLES}{}",
                    if left < MAX_TRIANGLES {
                        format!(" ({left} left after the objects before it)")
                    } else {
                        String::new()
                    }
                ),
            ))
        };
        let sources = [
            o.mesh.is_some(),
            o.primitive.is_some(),
            o.patches.is_some(),
            o.cage.is_some(),
        ];
        match sources.iter().filter(|&&s| s).count() {
            0 => {
                return Err(self.err(
                    &key("mesh"),
                    "missing: give one of `mesh`, `primitive`, `patches` and `cage`",
                ));
            }
            1 => {}
            _ => {
                return Err(self.err(
                    &key("mesh"),
                    "give only one of `mesh`, `primitive`, `patches` and `cage`",
                ));
            }
        }
        if o.patches.is_none() {
            if o.basis.is_some() {
                return Err(self.err(&key("basis"), "only for `patches`"));
            }
            if o.cage.is_none() {
                if o.tessellate.is_some() {
                    return Err(self.err(&key("tessellate"), "only for `patches` and `cage`"));
                }
                if o.stitch.is_some() {
                    return Err(self.err(&key("stitch"), "only for `patches` and `cage`"));
                }
            }
        }
        let mut space = Space::World;
        let mut bezier = Vec::new();
        let (name, mesh) = if let Some(file) = &o.mesh {
            let (path, bytes) = self.read(&key("mesh"), file)?;
            let text = String::from_utf8(bytes).map_err(|_| {
                self.err(
                    &key("mesh"),
                    format!("`{}` is not UTF-8 text", path.display()),
                )
            })?;
            let mesh = obj::parse(&text, lit).map_err(|e| self.asset(&key("mesh"), &path, e))?;
            (file.clone(), mesh)
        } else if let Some((file, source)) = o
            .patches
            .as_ref()
            .map(|f| (f, "patches"))
            .or(o.cage.as_ref().map(|f| (f, "cage")))
        {
            let (path, bytes) = self.read(&key(source), file)?;
            let text = String::from_utf8(bytes).map_err(|_| {
                self.err(
                    &key(source),
                    format!("`{}` is not UTF-8 text", path.display()),
                )
            })?;
            let patches = if source == "cage" {
                cage::patches(&text)
            } else {
                bpt::parse(&text)
            }
            .map_err(|e| self.asset(&key(source), &path, e))?;
            let n = o.tessellate.unwrap_or(20);
            if !(1..=MAX_TESSELLATE).contains(&n) {
                return Err(self.err(
                    &key("tessellate"),
                    format!("{n} is outside 1..={MAX_TESSELLATE}"),
                ));
            }
            let stitch = o.stitch.unwrap_or(false);
            let per_row = 2 * u64::from(n) + 2 * u64::from(stitch);
            room("tessellate", patches.len() as u64 * per_row * u64::from(n))?;
            // A cage's patches are Bezier; `basis` is for `.bpt` files.
            let basis = match o.basis.unwrap_or(BasisFile::Bezier) {
                BasisFile::Bezier => Basis::Bezier,
                BasisFile::Bspline => Basis::BSpline,
            };
            bezier = patches.iter().map(|p| bpt::to_bezier(p, basis)).collect();
            (file.clone(), bpt::tessellate(&patches, basis, n, stitch))
        } else {
            let p = o.primitive.as_ref().expect("one source");
            let pkey = |k: &str| key(&format!("primitive.{k}"));
            let allowed: &[&str] = match p.kind {
                PrimitiveKind::Icosphere => &["subdivisions"],
                PrimitiveKind::UvSphere | PrimitiveKind::Pin | PrimitiveKind::BandedSphere => {
                    &["rings", "segments"]
                }
                PrimitiveKind::Rate => &["size"],
                PrimitiveKind::Boxes => &["count", "seed"],
                PrimitiveKind::Tiles => &["columns", "rows"],
                PrimitiveKind::Torus => &["rings", "segments", "minor"],
            };
            // Keys with a default: `seed` (0) and `minor` (0.25).
            let optional = ["seed", "minor"];
            for (k, given) in [
                ("subdivisions", p.subdivisions.is_some()),
                ("rings", p.rings.is_some()),
                ("segments", p.segments.is_some()),
                ("size", p.size.is_some()),
                ("count", p.count.is_some()),
                ("seed", p.seed.is_some()),
                ("columns", p.columns.is_some()),
                ("rows", p.rows.is_some()),
                ("minor", p.minor.is_some()),
            ] {
                if given && !allowed.contains(&k) {
                    return Err(self.err(&pkey(k), "not a key of this primitive's kind"));
                }
                if !given && allowed.contains(&k) && !optional.contains(&k) {
                    return Err(self.err(&pkey(k), "missing"));
                }
            }
            // A count of divisions in `lo..=MAX_SPHERE_DIVISIONS`.
            let divisions = |k: &str, v: Option<u32>, lo: u32| {
                let v = v.expect("checked");
                if (lo..=MAX_SPHERE_DIVISIONS).contains(&v) {
                    Ok(v)
                } else {
                    Err(self.err(
                        &pkey(k),
                        format!("{v} is outside {lo}..={MAX_SPHERE_DIVISIONS}"),
                    ))
                }
            };
            match p.kind {
                PrimitiveKind::Icosphere => {
                    let s = opts.subdivisions.or(p.subdivisions).expect("checked");
                    if s > primitives::MAX_SUBDIVISIONS {
                        return Err(self.err(
                            &pkey("subdivisions"),
                            format!("{s} is beyond {}", primitives::MAX_SUBDIVISIONS),
                        ));
                    }
                    room("primitive", 20 << (2 * s))?;
                    ("icosphere".into(), primitives::icosphere(s))
                }
                PrimitiveKind::UvSphere | PrimitiveKind::Pin | PrimitiveKind::BandedSphere => {
                    let r = divisions("rings", p.rings, 2)?;
                    let s = divisions("segments", p.segments, 3)?;
                    room("primitive", 2 * u64::from(r) * u64::from(s))?;
                    match p.kind {
                        PrimitiveKind::UvSphere => {
                            ("uv_sphere".into(), primitives::uv_sphere(r, s))
                        }
                        PrimitiveKind::Pin => ("pin".into(), primitives::pin(r, s)),
                        _ => ("banded_sphere".into(), primitives::banded_sphere(r, s)),
                    }
                }
                PrimitiveKind::Torus => {
                    let r = divisions("rings", p.rings, 3)?;
                    let s = divisions("segments", p.segments, 3)?;
                    let minor = p.minor.unwrap_or(0.25);
                    if !(minor > 0.0 && minor < 1.0) {
                        return Err(self.err(
                            &pkey("minor"),
                            format!("{minor} is outside (0, 1) (the major radius is 1)"),
                        ));
                    }
                    room("primitive", 2 * u64::from(r) * u64::from(s))?;
                    ("torus".into(), primitives::torus(r, s, minor))
                }
                PrimitiveKind::Boxes => {
                    let n = p.count.expect("checked");
                    if n == 0 {
                        return Err(self.err(&pkey("count"), "no boxes"));
                    }
                    room("primitive", 12 * u64::from(n))?;
                    let mesh = primitives::boxes(n, p.seed.unwrap_or(0));
                    ("boxes".into(), mesh)
                }
                PrimitiveKind::Tiles => {
                    let c = divisions("columns", p.columns, 1)?;
                    let r = divisions("rows", p.rows, 1)?;
                    room("primitive", 2 * u64::from(c) * u64::from(r))?;
                    ("tiles".into(), primitives::tiles(c, r))
                }
                PrimitiveKind::Rate => {
                    if lit {
                        return Err(self.err(&key("material"), "the rate primitive is unlit"));
                    }
                    for (k, given) in [
                        ("translate", o.translate.is_some()),
                        ("rotate", o.rotate.is_some()),
                        ("scale", o.scale.is_some()),
                    ] {
                        if given {
                            return Err(self.err(
                                &key(k),
                                "the rate primitive is in window pixels: it has no model matrix",
                            ));
                        }
                    }
                    space = Space::Window;
                    let n = p.size.expect("checked");
                    if (1..=128).contains(&n) && n.is_power_of_two() {
                        let (w, h) = super::rate_cell(n);
                        room(
                            "primitive",
                            2 * u64::from(width / w) * u64::from(height / h),
                        )?;
                    }
                    let mesh = primitives::rate(n, width, height)
                        .map_err(|e| self.err(&pkey("size"), e))?;
                    (format!("rate-{n}"), mesh)
                }
            }
        };
        let mesh = match o.triangles.unwrap_or(TrianglesFile::Shared) {
            TrianglesFile::Shared => mesh,
            TrianglesFile::Separate => primitives::separate(&mesh),
        };
        self.check_mesh(&key("mesh"), &mesh)?;
        room("mesh", mesh.triangles.len() as u64)?;
        let model = match space {
            Space::Window => IDENTITY,
            Space::World => self.model_matrix(i, o)?,
        };
        Ok(model::Object {
            name: o.name.clone().unwrap_or(name),
            material,
            model,
            colour: self.colour(&key("colour"), o.colour, 1.0)?,
            space,
            mesh,
            patches: bezier,
        })
    }

    fn model_matrix(&self, i: usize, o: &ObjectFile) -> R<[f32; 16]> {
        let key = |k: &str| format!("object[{i}].{k}");
        let t = o.translate.unwrap_or([0.0; 3]);
        let r = o.rotate.unwrap_or([0.0, 0.0, 0.0, 1.0]);
        let s = o.scale.unwrap_or([1.0; 3]);
        self.finite(&key("translate"), &t)?;
        self.finite(&key("rotate"), &r)?;
        self.finite(&key("scale"), &s)?;
        let axis = DVec3::new(r[1], r[2], r[3]);
        let rotation = if r[0] == 0.0 {
            DMat4::IDENTITY
        } else if axis.length_squared() == 0.0 {
            return Err(self.err(&key("rotate"), "the rotation axis is zero"));
        } else {
            DMat4::from_axis_angle(axis.normalize(), r[0].to_radians())
        };
        let m =
            DMat4::from_translation(DVec3::from(t)) * rotation * DMat4::from_scale(DVec3::from(s));
        self.matrix(&key("scale"), m)
    }

    fn check_mesh(&self, key: &str, m: &Mesh) -> R<()> {
        if m.triangles.is_empty() {
            return Err(self.err(key, "the mesh has no triangles"));
        }
        let n = m.positions.len();
        for (what, len) in [
            ("normals", m.normals.len()),
            ("colours", m.colours.len()),
            ("texture coordinates", m.texcoords.len()),
        ] {
            if len != 0 && len != n {
                return Err(self.err(key, format!("{len} {what} for {n} vertices")));
            }
        }
        if let Some(t) = m
            .triangles
            .iter()
            .find(|t| t.iter().any(|&i| i as usize >= n))
        {
            return Err(self.err(key, format!("triangle {t:?} names a vertex beyond the {n}")));
        }
        let finite = |v: &[f32]| v.iter().all(|c| c.is_finite());
        if let Some(i) = m.positions.iter().position(|p| !finite(p)) {
            return Err(self.err(key, format!("vertex {i} is not at a finite position")));
        }
        Ok(())
    }
}

/// A key path with the index of the `[[light]]`, `[[texture]]`, `[[material]]` or
/// `[[object]]` entry that holds `line` (toml's key paths leave it out): `object` →
/// `object[1]`.
fn index_tables(text: &str, keys: &str, line: Option<usize>) -> String {
    let (table, rest) = keys.split_once('.').unwrap_or((keys, ""));
    let Some(line) = line else {
        return keys.into();
    };
    if !["light", "texture", "material", "object"].contains(&table) {
        return keys.into();
    }
    let header = format!("[[{table}]]");
    let seen = text
        .lines()
        .take(line)
        .filter(|l| l.trim_start().starts_with(&header))
        .count();
    if seen == 0 {
        return keys.into();
    }
    let dot = if rest.is_empty() { "" } else { "." };
    format!("{table}[{}]{dot}{rest}", seen - 1)
}

fn names<'a>(it: impl Iterator<Item = &'a str>) -> String {
    let v: Vec<String> = it.map(|n| format!("`{n}`")).collect();
    if v.is_empty() {
        "none".into()
    } else {
        v.join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::model::{
        Blend, Cull, DepthTest, Filter, PipelineKind, Shader, TextureMode, Wrap,
    };

    /// A fresh directory for one test's files.
    fn dir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("imagine-scene-{}-{tag}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn parse_in(d: &Path, text: &str) -> Result<model::Scene, SceneError> {
        let path = d.join("test.toml");
        std::fs::write(&path, text).unwrap();
        load(path.to_str().unwrap(), &LoadOptions::default())
    }

    fn text(text: &str) -> Result<model::Scene, SceneError> {
        parse(
            text,
            Path::new("/nowhere/test.toml"),
            &LoadOptions::default(),
        )
    }

    const WINDOW: &str = "[window]\nwidth = 64\nheight = 32\n";
    const BALL: &str = "[[object]]\nprimitive = { kind = \"icosphere\", subdivisions = 0 }\n";

    #[test]
    fn scene_file_defaults() {
        let s = text(&format!(
            "{WINDOW}[[light]]\nposition = [1, 2, 3]\n[[texture]]\nname = \"c\"\n\
             procedural = {{ kind = \"checker\" }}\n[[material]]\nname = \"m\"\nshader = \"lit\"\n\
             {BALL}material = \"m\"\n{BALL}"
        ))
        .unwrap();
        assert_eq!(s.name, "test");
        assert_eq!((s.width, s.height), (64, 32));
        assert_eq!((s.background, s.ambient), ([0.0; 3], [0.0; 3]));
        assert_eq!(s.camera.view, IDENTITY);
        assert_eq!(s.camera.projection, IDENTITY);
        let p = s.pipeline;
        assert_eq!(
            (
                p.kind,
                p.depth_test,
                p.cull,
                p.blend,
                p.stop_length,
                p.batch
            ),
            (
                PipelineKind::OpenGl,
                DepthTest::Less,
                Cull::None,
                Blend::None,
                1.5,
                None
            )
        );
        let l = s.lights[0];
        assert_eq!(l.position, [1.0, 2.0, 3.0]);
        assert_eq!(
            (l.ambient, l.diffuse, l.specular),
            ([0.0; 3], [1.0; 3], [1.0; 3])
        );
        let t = &s.textures[0];
        assert_eq!(
            (t.width, t.height, t.filter, t.wrap),
            (256, 256, Filter::Nearest, Wrap::Repeat)
        );
        assert_eq!((t.texels[0], t.texels[32]), (0xffff_ffff, 0xff00_0000));
        let m = &s.materials[0];
        assert_eq!(
            (m.ambient, m.diffuse, m.specular),
            ([0.2; 3], [0.8; 3], [0.0; 3])
        );
        assert_eq!((m.shininess, m.texture_mode), (0.0, TextureMode::Modulate));
        assert!(m.textures.is_empty());
        let d = &s.materials[s.objects[1].material];
        assert_eq!((d.shader, s.materials.len()), (Shader::Unlit, 2));
        let o = &s.objects[1];
        assert_eq!(
            (o.name.as_str(), o.colour, o.model, o.space),
            ("icosphere", [1.0; 3], IDENTITY, Space::World)
        );
        assert_eq!(
            (
                o.mesh.positions.len(),
                o.mesh.triangles.len(),
                o.mesh.separate
            ),
            (12, 20, false)
        );
        assert_eq!(s.objects[0].material, 0);
    }

    #[test]
    fn scene_file_camera_and_model_matrices() {
        let s = text(&format!(
            "{WINDOW}[camera]\neye = [0, 0, 3]\ntarget = [0, 0, 0]\nfov_y = 90\nnear = 1\nfar = 3\n\
             [[object]]\nprimitive = {{ kind = \"icosphere\", subdivisions = 0 }}\n\
             translate = [1, 2, 3]\nrotate = [90, 0, 0, 2]\nscale = [2, 2, 2]\n"
        ))
        .unwrap();
        let v = s.camera.view;
        assert_eq!(
            v,
            [
                1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, -3.0, 0.0, 0.0, 0.0, 1.0
            ]
        );
        let p = s.camera.projection;
        assert!(
            (p[0] - 0.5).abs() < 1e-7 && (p[5] - 1.0).abs() < 1e-7,
            "{p:?}"
        );
        assert_eq!((p[10], p[11], p[14]), (-2.0, -3.0, -1.0));
        let m = s.objects[0].model;
        let want = [
            0.0, -2.0, 0.0, 1.0, 2.0, 0.0, 0.0, 2.0, 0.0, 0.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0,
        ];
        for (a, b) in m.iter().zip(want) {
            assert!((a - b).abs() < 1e-6, "{m:?}");
        }
        let s = text(&format!(
            "{WINDOW}[camera]\nmodelview = [1,0,0,5, 0,1,0,0, 0,0,1,0, 0,0,0,1]\n\
             ortho = [-1, 1, -1, 1, 1, 3]\n{BALL}"
        ))
        .unwrap();
        assert_eq!(s.camera.view[3], 5.0);
        assert_eq!(s.camera.projection[10], -1.0);
    }

    fn assert_error(result: Result<model::Scene, SceneError>, wants: &[&str]) {
        let e = result.expect_err("the scene loaded").to_string();
        for w in wants {
            assert!(e.contains(w), "`{w}` missing from: {e}");
        }
    }

    #[test]
    fn scene_file_errors_name_the_file_and_key() {
        let cases: Vec<(String, Vec<&str>)> = vec![
            (format!("{WINDOW}colr = 1\n{BALL}"), vec!["colr", "line 4"]),
            (format!("{WINDOW}{BALL}{BALL}colr = [1, 1, 1]\n"), vec!["`object[1]`", "unknown field `colr`", "line 8"]),
            (format!("{WINDOW}{BALL}{BALL}colour = \"red\"\n"), vec!["`object[1].colour`", "line 8"]),
            (BALL.to_string(), vec!["missing field `window`"]),
            ("[window]\nwidth = \"wide\"\nheight = 1\n".into(), vec!["window.width", "line 2"]),
            (format!("ambient = [nan, 0, 0]\n{WINDOW}{BALL}"), vec!["`ambient`", "finite"]),
            (format!("{WINDOW}[[light]]\nposition = [inf, 0, 0]\n{BALL}"), vec!["`light[0].position`", "finite"]),
            (format!("{WINDOW}background = [2, 0, 0]\n{BALL}"), vec!["`window.background`", "outside [0, 1]"]),
            (format!("{WINDOW}{BALL}material = \"nope\"\n"), vec!["`object[0].material`", "`nope`"]),
            (format!("{WINDOW}{}{BALL}", "[[light]]\nposition = [0, 0, 0]\n".repeat(9)), vec!["`light`", "at most 8"]),
            (format!("{WINDOW}[[material]]\nname = \"m\"\nshader = \"lit\"\nshininess = 200\n{BALL}"), vec!["`material[0].shininess`"]),
            (format!("{WINDOW}[[material]]\nname = \"m\"\n{BALL}"), vec!["shader"]),
            (format!("{WINDOW}[[material]]\nname = \"m\"\nshader = \"unlit\"\ntextures = [\"t\"]\n{BALL}"), vec!["`material[0].textures`", "`t`"]),
            ("[window]\nwidth = 0\nheight = 1\n[[object]]\nprimitive = { kind = \"icosphere\", subdivisions = 0 }\n".into(), vec!["`window.width`", "1..=4096"]),
            (WINDOW.into(), vec!["no [[object]]"]),
            (format!("{WINDOW}[[object]]\ncage = \"a.obj\"\n"), vec!["`object[0].cage`", "a.obj"]),
            (format!("{WINDOW}[[object]]\nprimitive = {{ kind = \"icosphere\" }}\n"), vec!["`object[0].primitive.subdivisions`", "missing"]),
            (format!("{WINDOW}[[object]]\nprimitive = {{ kind = \"rate\", size = 3 }}\n"), vec!["`object[0].primitive.size`", "power of two"]),
            (format!("{WINDOW}[pipeline]\ncull = \"sideways\"\n{BALL}"), vec!["pipeline.cull", "sideways"]),
            (format!("{WINDOW}[pipeline]\nbatch = 0\n{BALL}"), vec!["`pipeline.batch`", "1..=65536"]),
            (format!("{WINDOW}[pipeline]\nbatch = 70000\n{BALL}"), vec!["`pipeline.batch`", "70000"]),
            (format!("{WINDOW}[pipeline]\nbatch = 6.5\n{BALL}"), vec!["pipeline.batch"]),
            (
                format!("{WINDOW}[pipeline]\nnewton_raphson = 4\n{BALL}"),
                vec!["`pipeline.newton_raphson`", "0..=3"],
            ),
            (format!("{WINDOW}[camera]\neye = [0, 0, 1]\ntarget = [0, 0, 0]\n{BALL}"), vec!["`camera.fov_y`", "missing"]),
            (format!("{WINDOW}[camera]\nmodelview = [1, 2]\northo = [-1, 1, -1, 1, -1, 1]\n{BALL}"), vec!["camera.modelview", "16"]),
        ];
        for (t, wants) in cases {
            let mut wants = wants.clone();
            wants.push("/nowhere/test.toml");
            assert_error(text(&t), &wants);
        }
    }

    /// A `bump_env` material: its environment map, the sphere it needs tangents on, then
    /// the material keys in `material` (each case replaces the defaults).
    fn bump_env_scene(material: &str, texture: &str, primitive: &str) -> String {
        format!(
            "{WINDOW}[[texture]]\nname = \"env\"\nprocedural = {{ kind = \"checker\" }}\n{texture}\
             [[material]]\nname = \"b\"\nshader = \"bump_env\"\n{material}\
             [[object]]\nprimitive = {primitive}\nmaterial = \"b\"\n"
        )
    }

    #[test]
    fn bump_env_materials_are_checked() {
        let sphere = "{ kind = \"uv_sphere\", rings = 4, segments = 6 }";
        let env = "textures = [\"env\"]\n";
        let good = bump_env_scene(&format!("{env}displacement = 0.1\n"), "", sphere);
        let s = text(&good).unwrap();
        let Shader::BumpEnv(b) = s.materials[0].shader else {
            panic!("{:?}", s.materials[0].shader);
        };
        assert_eq!(
            (b.displacement, b.bump_size, b.bump_cells, b.bump_scale),
            (0.1, 256, 8, 1.0)
        );
        let cases: Vec<(String, Vec<&str>)> = vec![
            (
                bump_env_scene(env, "", sphere),
                vec!["`material[0].displacement`", "needs it"],
            ),
            (
                bump_env_scene(&format!("{env}displacement = \"far\"\n"), "", sphere),
                vec!["`material[0].displacement`"],
            ),
            (
                bump_env_scene(&format!("{env}displacement = nan\n"), "", sphere),
                vec!["`material[0].displacement`"],
            ),
            (
                bump_env_scene(
                    &format!("{env}displacement = 0.1\nbump_size = 100\n"),
                    "",
                    sphere,
                ),
                vec!["`material[0].bump_size`", "power of two"],
            ),
            (
                bump_env_scene(
                    &format!("{env}displacement = 0.1\nbump_size = 16\nbump_cells = 9\n"),
                    "",
                    sphere,
                ),
                vec!["`material[0].bump_cells`", "1..=8"],
            ),
            (
                bump_env_scene(
                    &format!("{env}displacement = 0.1\nbump_scale = -1\n"),
                    "",
                    sphere,
                ),
                vec!["`material[0].bump_scale`", "0..=8"],
            ),
            (
                bump_env_scene("displacement = 0.1\n", "", sphere),
                vec!["`material[0].textures`", "exactly one texture"],
            ),
            (
                bump_env_scene(
                    &format!("{env}displacement = 0.1\n"),
                    "filter = \"linear\"\n",
                    sphere,
                ),
                vec!["`material[0].textures`", "`env`", "nearest"],
            ),
            (
                bump_env_scene(
                    &format!("{env}displacement = 0.1\n"),
                    "",
                    "{ kind = \"icosphere\", subdivisions = 0 }",
                ),
                vec!["`object[0].material`", "tangents"],
            ),
            (
                format!(
                    "{WINDOW}[[material]]\nname = \"m\"\nshader = \"lit\"\ndisplacement = 0.1\n{BALL}"
                ),
                vec!["`material[0].displacement`", "only a `bump_env` material"],
            ),
        ];
        for (t, wants) in cases {
            let mut wants = wants.clone();
            wants.push("/nowhere/test.toml");
            assert_error(text(&t), &wants);
        }
    }

    #[test]
    fn scene_file_assets_are_read_and_bad_ones_named() {
        let d = dir("assets");
        std::fs::write(
            d.join("quad.obj"),
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n",
        )
        .unwrap();
        std::fs::write(
            d.join("bad.obj"),
            "v 0 0 0\nv 1 0 0\nv 1 1 0\n# comment\nf 1 2 7\n",
        )
        .unwrap();
        std::fs::write(d.join("bad.png"), "not a png").unwrap();
        let mut img = image::RgbImage::new(2, 2);
        img.put_pixel(0, 0, image::Rgb([255, 0, 0])); // top left
        img.put_pixel(1, 1, image::Rgb([0, 0, 255])); // bottom right
        img.save(d.join("t.png")).unwrap();
        let s = parse_in(
            &d,
            &format!(
                "{WINDOW}[[texture]]\nname = \"t\"\nimage = \"t.png\"\nfilter = \"trilinear\"\n\
                 [[material]]\nname = \"m\"\nshader = \"lit\"\ntextures = [\"t\"]\n\
                 [[object]]\nmesh = \"quad.obj\"\nmaterial = \"m\"\n"
            ),
        )
        .unwrap();
        let t = &s.textures[0];
        assert_eq!((t.width, t.height, t.filter), (2, 2, Filter::Trilinear));
        assert_eq!(
            t.texels,
            vec![0xff00_0000, 0xffff_0000, 0xff00_00ff, 0xff00_0000]
        );
        let m = &s.objects[0].mesh;
        assert_eq!(
            (m.positions.len(), m.triangles.len()),
            (6, 2),
            "lit: geometric normals"
        );
        assert!(m.normals.iter().all(|&n| n == [0.0, 0.0, 1.0]));
        assert_eq!(s.objects[0].name, "quad.obj");
        assert_eq!(s.materials[0].textures, vec![0]);

        assert_error(
            parse_in(&d, &format!("{WINDOW}[[object]]\nmesh = \"bad.obj\"\n")),
            &[
                "test.toml",
                "`object[0].mesh`",
                "bad.obj` line 5",
                "index 7 is out of range",
            ],
        );
        assert_error(
            parse_in(&d, &format!("{WINDOW}[[object]]\nmesh = \"gone.obj\"\n")),
            &["`object[0].mesh`", "cannot read", "gone.obj"],
        );
        assert_error(
            parse_in(
                &d,
                &format!("{WINDOW}[[texture]]\nname = \"t\"\nimage = \"bad.png\"\n{BALL}"),
            ),
            &["`texture[0].image`", "bad.png` is not a PNG image"],
        );
        image::RgbImage::new(4, 3).save(d.join("odd.png")).unwrap();
        assert_error(
            parse_in(
                &d,
                &format!("{WINDOW}[[texture]]\nname = \"t\"\nimage = \"odd.png\"\n{BALL}"),
            ),
            &["`texture[0].image`", "odd.png` is 4x3", "power-of-two"],
        );
        assert_error(
            text(&format!(
                "{WINDOW}[[texture]]\nname = \"t\"\n\
                 procedural = {{ kind = \"checker\", size = 96 }}\n{BALL}"
            )),
            &["`texture[0].procedural.size`", "96 is not a power of two"],
        );
        assert_error(
            parse_in(&d, &format!("{WINDOW}[[object]]\npatches = \"gone.bpt\"\n")),
            &["`object[0].patches`", "gone.bpt"],
        );
        let _ = std::fs::remove_dir_all(&d);
    }

    /// Out of memory in the `scene_toml` fuzz target (2 GB): a scene of a few lines asked
    /// for a 33.5 M-triangle sphere and the loader built it.
    #[test]
    fn scene_file_refuses_more_triangles_than_a_scene_may_have() {
        assert_error(
            text(
                "[window]\nwidth = 64\nheight = 64\n[[object]]\n\
                 primitive = { kind = \"uv_sphere\", rings = 4096, segments = 4096 }\n\
                 triangles = \"separate\"\n",
            ),
            &[
                "`object[0].primitive`",
                "33554432 triangles",
                "at most 4194304",
            ],
        );
        assert_error(
            text(
                "[window]\nwidth = 4096\nheight = 4096\n[[object]]\n\
                 primitive = { kind = \"rate\", size = 1 }\n",
            ),
            &["`object[0].primitive`", "16777216 triangles"],
        );
        // The limit is the scene's: what the objects before have taken is not left.
        let full =
            "[[object]]\nprimitive = { kind = \"uv_sphere\", rings = 2048, segments = 1024 }\n";
        assert_eq!(
            text(&format!("{WINDOW}{full}")).unwrap().triangles(),
            MAX_TRIANGLES
        );
        assert_error(
            text(&format!("{WINDOW}{full}{BALL}")),
            &[
                "`object[1].primitive`",
                "20 triangles",
                "(0 left after the objects before it)",
            ],
        );
        // Patches are counted before they are diced.
        let d = dir("too-many-triangles");
        let mut bpt = String::from("33\n");
        for _ in 0..33 {
            bpt += "3 3\n";
            for row in 0..4 {
                for col in 0..4 {
                    bpt += &format!("{col} {row} 0\n");
                }
            }
        }
        std::fs::write(d.join("many.bpt"), bpt).unwrap();
        assert_error(
            parse_in(
                &d,
                &format!("{WINDOW}[[object]]\npatches = \"many.bpt\"\ntessellate = 256\n"),
            ),
            &["`object[0].tessellate`", "4325376 triangles"],
        );
        let _ = std::fs::remove_dir_all(&d);
    }

    /// Out of memory in the `scene_toml` fuzz target too: an asset naming a device was read
    /// without end. A directory is refused the same way.
    #[test]
    fn scene_file_assets_must_be_files() {
        #[cfg(unix)]
        assert_error(
            text("[window]\nwidth = 8\nheight = 8\n[[object]]\nmesh = \"/dev/zero\"\n"),
            &["`object[0].mesh`", "cannot read `/dev/zero`: not a file"],
        );
        let d = dir("not-a-file");
        std::fs::create_dir_all(d.join("sub.obj")).unwrap();
        assert_error(
            parse_in(&d, &format!("{WINDOW}[[object]]\nmesh = \"sub.obj\"\n")),
            &["`object[0].mesh`", "sub.obj`: not a file"],
        );
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn scene_file_patches_and_uv_spheres() {
        let d = dir("patches");
        let mut bpt = String::from("1\n3 3\n");
        for row in 0..4 {
            for col in 0..4 {
                bpt += &format!("{col} {row} 0\n");
            }
        }
        std::fs::write(d.join("flat.bpt"), bpt).unwrap();
        let s = parse_in(
            &d,
            &format!(
                "{WINDOW}[[object]]\npatches = \"flat.bpt\"\ntessellate = 2\n\
                 [[object]]\npatches = \"flat.bpt\"\nbasis = \"bspline\"\n\
                 [[object]]\nprimitive = {{ kind = \"uv_sphere\", rings = 4, segments = 8 }}\ntriangles = \"separate\"\n"
            ),
        )
        .unwrap();
        assert_eq!(
            (
                s.objects[0].mesh.positions.len(),
                s.objects[0].mesh.triangles.len()
            ),
            (9, 8)
        );
        assert_eq!(s.objects[1].mesh.triangles.len(), 2 * 20 * 20);
        let u = &s.objects[2].mesh;
        assert_eq!(
            (u.positions.len(), u.triangles.len(), u.separate),
            (3 * 64, 64, true)
        );
        assert_eq!(u.triangles[5], [15, 16, 17]);
        // Stitching is for patches alone.
        let e = parse_in(
            &d,
            &format!("{WINDOW}[[object]]\nprimitive = {{ kind = \"icosphere\" }}\nstitch = true\n"),
        );
        assert_error(e, &["`object[0].stitch`", "only for `patches`"]);
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn scene_file_published_primitives_and_rectangles() {
        let s = text(&format!(
            "{WINDOW}[[texture]]\nname = \"r\"\nprocedural = {{ kind = \"rectangles\", size = 4, \
             rectangles = [[0.0, 0.5, 1.0, 0.75]], colours = [[1, 1, 1], [1, 0, 0]] }}\n\
             [[object]]\nprimitive = {{ kind = \"pin\", rings = 4, segments = 6 }}\n\
             [[object]]\nprimitive = {{ kind = \"banded_sphere\", rings = 4, segments = 6 }}\n\
             [[object]]\nprimitive = {{ kind = \"boxes\", count = 5, seed = 3 }}\n\
             [[object]]\nprimitive = {{ kind = \"tiles\", columns = 3, rows = 2 }}\n\
             [[object]]\nprimitive = {{ kind = \"torus\", rings = 3, segments = 4 }}\n\
             triangles = \"separate\"\n"
        ))
        .unwrap();
        let t = &s.textures[0];
        assert_eq!(
            (t.width, t.height, t.texels[8], t.texels[0]),
            (4, 4, 0xff00_00ff, !0)
        );
        let counts: Vec<(usize, usize, &str)> = s
            .objects
            .iter()
            .map(|o| {
                (
                    o.mesh.positions.len(),
                    o.mesh.triangles.len(),
                    o.name.as_str(),
                )
            })
            .collect();
        assert_eq!(
            counts,
            [
                (48, 48, "pin"),
                (48, 48, "banded_sphere"),
                (120, 60, "boxes"),
                (24, 12, "tiles"),
                (72, 24, "torus"),
            ]
        );
        assert_eq!(s.objects[2].mesh, primitives::boxes(5, 3));
        assert_eq!(
            s.objects[4].mesh,
            primitives::separate(&primitives::torus(3, 4, 0.25))
        );
        let pin = "[[object]]\nprimitive = { kind = \"pin\", rings = 4 ";
        for (t, wants) in [
            (format!("{pin}}}\n"), ["`object[0].primitive.segments`", "missing"]),
            (format!("{pin}, segments = 2 }}\n"), ["`object[0].primitive.segments`", "outside 3..="]),
            (format!("{pin}, segments = 4, seed = 1 }}\n"), ["`object[0].primitive.seed`", "not a key"]),
            ("[[object]]\nprimitive = { kind = \"torus\", rings = 4, segments = 4, minor = 1.5 }\n".into(), ["`object[0].primitive.minor`", "outside (0, 1)"]),
            ("[[object]]\nprimitive = { kind = \"boxes\", count = 0 }\n".into(), ["`object[0].primitive.count`", "no boxes"]),
            ("[[object]]\nprimitive = { kind = \"boxes\", count = 400000 }\n".into(), ["`object[0].primitive`", "4800000 triangles"]),
            (format!("[[texture]]\nname = \"r\"\nprocedural = {{ kind = \"rectangles\" }}\n{BALL}"), ["`texture[0].procedural.rectangles`", "missing"]),
            (format!("[[texture]]\nname = \"r\"\nprocedural = {{ kind = \"checker\", rectangles = [] }}\n{BALL}"), ["`texture[0].procedural.rectangles`", "only for"]),
            (format!("[[texture]]\nname = \"r\"\nprocedural = {{ kind = \"rectangles\", cells = 2, rectangles = [] }}\n{BALL}"), ["`texture[0].procedural.cells`", "only for"]),
        ] {
            assert_error(text(&format!("{WINDOW}{t}")), &wants);
        }
    }

    #[test]
    fn scene_file_builtin_sphere_is_the_old_sphere() {
        let s = load("sphere-full", &LoadOptions::default()).unwrap();
        assert_eq!(s.name, "SPHERE-FULL");
        assert_eq!((s.triangles(), s.vertices()), (81_920, 245_760));
        let old = crate::scene::sphere(6, 720);
        let o = &s.objects[0];
        assert!(o.mesh.separate);
        assert_eq!(o.mesh.positions, old.positions);
        assert_eq!(o.mesh.normals, old.normals);
        assert_eq!(s.camera.view, old.modelview);
        for (a, b) in s.camera.projection.iter().zip(old.projection) {
            assert!(
                (a - b).abs() <= 1e-6 * b.abs(),
                "{:?} vs {:?}",
                s.camera.projection,
                old.projection
            );
        }
        assert_eq!(s.pipeline.cull, Cull::Back);
        assert_eq!(s.lights.len(), 3);
        assert_eq!(s.lights[1].diffuse, [0.5, 0.3, 0.2]);
        assert_eq!(s.materials[o.material].shininess, 16.0);
        assert_eq!(s.ambient, [1.0; 3]);
        assert!(
            s.source
                .as_ref()
                .unwrap()
                .ends_with("scenes/SPHERE-FULL.toml")
        );
        // SPHERE is the same scene seen with a wider field of view.
        let mut published = load("SPHERE", &LoadOptions::default()).unwrap();
        assert!(published.camera.projection[5] < s.camera.projection[5]);
        published.name = s.name.clone();
        published.source = s.source.clone();
        published.camera.projection = s.camera.projection;
        assert_eq!(published, s);
        let small = load(
            "SPHERE",
            &LoadOptions {
                size: Some(64),
                subdivisions: Some(2),
                filter: None,
            },
        )
        .unwrap();
        assert_eq!((small.width, small.triangles()), (64, 320));
        assert!(
            load(
                "SPHERE",
                &LoadOptions {
                    size: None,
                    subdivisions: Some(8),
                    filter: None,
                }
            )
            .is_err()
        );
    }

    #[test]
    fn scene_file_builtin_rate_is_the_old_rate() {
        for n in [1, 2, 4, 8, 16, 32, 64, 128] {
            let s = load(
                &format!("rate-{n}"),
                &LoadOptions {
                    size: Some(64),
                    subdivisions: None,
                    filter: None,
                },
            )
            .unwrap();
            let old = crate::scene::rate(n, 64).unwrap();
            let o = &s.objects[0];
            assert_eq!(o.space, Space::Window);
            assert_eq!(o.mesh.positions, old.positions, "RATE-{n}");
            assert_eq!(o.mesh.colours, old.colours, "RATE-{n}");
            assert_eq!(s.materials[o.material].shader, Shader::Unlit);
            assert_eq!(
                (s.pipeline.cull, s.pipeline.depth_test),
                (Cull::None, DepthTest::Less)
            );
            let c = s.camera_for(o);
            assert_eq!(c.projection, window_to_clip(64, 64));
        }
        let s = load("RATE-8", &LoadOptions::default()).unwrap();
        assert_eq!((s.width, s.triangles()), (720, 720 * 720 / 8));
        for (name, text) in BUILTIN {
            assert!(!builtin_description(text).is_empty(), "{name}");
        }
        // TEAPOT-N: the papers' 56·N·(N + 1) triangles, 28 patches of (N + 1)² vertices.
        for n in [20u64, 30, 40, 64] {
            let s = load(&format!("teapot-{n}"), &LoadOptions::default()).unwrap();
            let mesh = &s.objects[0].mesh;
            assert_eq!(s.triangles() as u64, 56 * n * (n + 1), "TEAPOT-{n}");
            assert_eq!(mesh.positions.len() as u64, 28 * (n + 1) * (n + 1));
        }
        assert_error(
            load("TEAPOT-9", &LoadOptions::default()),
            &["unknown scene", "SPHERE", "RATE-8"],
        );
    }

    #[test]
    fn scene_file_tri_files_load() {
        let d = dir("tri");
        let path = d.join("two.tri");
        std::fs::write(&path, "4 3\n0 0 0.5 1 0 0  4 0 0.5 0 1 0  0 3 0.5 0 0 1\n").unwrap();
        let s = load(path.to_str().unwrap(), &LoadOptions::default()).unwrap();
        assert_eq!(
            (s.name.as_str(), s.width, s.height, s.triangles()),
            ("two", 4, 3, 1)
        );
        let o = &s.objects[0];
        assert_eq!(
            (o.space, o.mesh.separate, o.mesh.triangles[0]),
            (Space::Window, true, [0, 1, 2])
        );
        assert_eq!(o.mesh.colours[1], [0.0, 1.0, 0.0]);
        assert_eq!(s.materials[o.material].shader, Shader::Unlit);
        std::fs::write(&path, "4 3\n1 2 3\n").unwrap();
        assert_error(
            load(path.to_str().unwrap(), &LoadOptions::default()),
            &["two.tri", "line 2"],
        );
        let _ = std::fs::remove_dir_all(&d);
    }
}
