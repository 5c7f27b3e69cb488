//! A Reyes frame as a stream program on the clocked processor, through the stream-program
//! layer ([`crate::stream`]) as the OpenGL pipeline runs ([`crate::opengl::render`]): the
//! patches through `project`, `subdiv_split`, `subdiv` and `sample`, and the fragments
//! through the OpenGL pipeline's composite (`hash`, `zcompare`, `compact_recycle`), every
//! kernel compiled to microcode and invoked by a stream instruction through the stream
//! controller.
//!
//! **Phases** (as the OpenGL frame's): the host loads the patch records (object space,
//! each run of patches that share a matrix padded to whole cluster rows with inactive
//! records) into DRAM over the host interface; the machine clears the framebuffer (the
//! OpenGL pipeline's `clear` and stores); then the frame, whose cycles are the frame's
//! cycles (every kernel call, its dispatch, the memory operations and the host's waits);
//! then the host reads the colour buffer back.
//!
//! **The frame.** Each run of patches is projected in chunks of [`CHUNK_ROWS`] rows: loaded
//! into the SRF, `project`, and scattered by record number into a DRAM buffer that holds
//! the real patches one after another (inactive records go to a trash record past them),
//! so that the groups below are those of consecutive patches whatever the runs. Each
//! breadth-first level (`subdiv_split`) loads the buffer in chunks and stores the children
//! into the next level's buffer (four per patch, in place of their parent; the rows past
//! the last patch are zeros, inactive). Then groups of `C` patches (patch `p` in cluster
//! `p mod C`) are walked: the group is loaded with a cleared walk (zeros loaded from a
//! DRAM buffer nothing writes), and `subdiv` is called, each call walking
//! [`ReyesOptions::iterations`] quads per cluster and saving its stacks to the other of
//! two state streams; the host reads back each cluster's stack depth and flags (two rows
//! of the saved walks: whether the group is done, whether a stack overflowed). The call's
//! quads are sampled in pieces whose fragments surely fit their streams (`sample` writes
//! at most `stamp²` per quad and a row of nulls), and each piece's fragments composited in
//! the OpenGL pipeline's chunks, before the next call.
//!
//! **Statistics.** Cycles and the kernel breakdown come from the stream controller's
//! records. The quads, their levels, the zero-pixel quads and the fragments are counted
//! from the streams the machine wrote (the quads and `sample`'s per-quad counts), read
//! through the SRF's backdoor when the host has waited for the call anyway: they cost no
//! simulated cycle, as the OpenGL frame's visible-triangle map is read after the frame.
//! The depths and visible pixels come from the framebuffer through the DRAM's backdoor
//! after the read-back.

use glam::DMat4;
use imagine_units::desc::MachineDesc;
use imagine_units::limits::MAX_RUN_CYCLES;
use imagine_units::machine::StreamBinding;
use imagine_units::ops::Datapath;
use imagine_units::processor;
use imagine_units::stream_controller::StreamInstr;

use super::kernels::{
    self, FLAG_QUAD, MAX_PLACE_LEVEL, MAX_STOP_LENGTH, Q_FLAGS, Q_LEVEL, QUAD_WORDS, STACK_FRAMES,
    Shading, stamp,
};
use crate::compile::CompileCache;
use crate::kernel::{Kernel, MachineRequirementError};
use crate::kernels::texture::FragmentProgram;
use crate::kernels::{stream_to_records, turbulence};
use crate::opengl::fragment_program::{self, TextureMemory};
use crate::opengl::kernels::{self as gl, FrameShape, NULL_DEPTH, PIXEL_WORDS};
use crate::opengl::render::{
    Composite, CompositeCounts, CompositeKernels, clear_framebuffer, composite_chunk, pack_rgb,
    plan_composite, plan_phases,
};
pub use crate::opengl::stats::KernelShare;
use crate::opengl::vertex_program::VertexProgram;
use crate::scene::mat_mul;
use crate::scene::model::{Blend, Cull, DepthTest, Filter, Scene, Shader};
use crate::stream::{
    DramMap, HostError, KernelLibrary, Layout, Lifetime, PARAMS, PlanError, SrfPlanner, StreamHost,
    live,
};

/// Patch rows (of `C` patches) per `project` and `subdiv_split` call: the split's children
/// take four times their words.
pub const CHUNK_ROWS: usize = 4;

/// A Bezier patch's 16 control points, `points[4·row + col]`, col along u.
pub type BezierPatch = [[f32; 3]; 16];

/// A Reyes frame's options.
#[derive(Clone, Debug)]
pub struct ReyesOptions {
    /// The largest quad side, in pixels.
    pub stop_length: f32,
    /// Quads each cluster walks per `subdiv` call (`None`: [`iterations_for`]): bounds
    /// the SRF its quads and their fragments take (`(iterations + 1) · C · 20` words of
    /// quads).
    pub iterations: Option<usize>,
    /// Breadth-first levels (`subdiv_split` calls) before the depth-first walks (`None`:
    /// [`split_levels_for`]).
    pub split_levels: Option<u32>,
    /// Give up the run (load, clear, frame and read-back) after this many core cycles.
    pub max_cycles: u64,
    pub cache: CompileCache,
    /// What computes the clusters' fp32 ops (the same frame either way).
    pub datapath: Datapath,
}

impl Default for ReyesOptions {
    fn default() -> Self {
        ReyesOptions {
            stop_length: 1.5,
            iterations: None,
            split_levels: None,
            max_cycles: MAX_RUN_CYCLES,
            cache: CompileCache::disabled(),
            datapath: Datapath::Host,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ReyesError(pub String);

impl std::fmt::Display for ReyesError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ReyesError {}

impl From<HostError> for ReyesError {
    fn from(e: HostError) -> Self {
        ReyesError(e.0)
    }
}

impl From<PlanError> for ReyesError {
    fn from(e: PlanError) -> Self {
        ReyesError(e.0)
    }
}

impl From<crate::opengl::render::RenderError> for ReyesError {
    fn from(e: crate::opengl::render::RenderError) -> Self {
        ReyesError(e.0)
    }
}

/// What a Reyes frame counted.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ReyesStats {
    pub patches: usize,
    /// Finished quads (micropolygons) `subdiv` wrote.
    pub quads: u64,
    /// Quads whose box held no pixel centre inside their four edges.
    pub zero_pixel_quads: u64,
    /// Fragments `sample` wrote (pixel centres covered, before the depth test).
    pub fragments: u64,
    /// Pixels drawn in the final image.
    pub visible_pixels: u64,
    /// Quads per subdivision level (index = level; the patch is level 0, the
    /// breadth-first levels counted).
    pub levels: Vec<u64>,
    /// Per kernel (by the name the frame registered it under), in first-call order.
    pub kernels: Vec<KernelShare>,
    /// The frame's cycles: the whole machine's, from the cleared framebuffer to the last
    /// scatter (kernels, their dispatch, memory operations, the host's waits).
    pub cycles: u64,
    /// Cycles of the phases around the frame: the patches' upload, the clear, the colour
    /// buffer's read-back.
    pub load_cycles: u64,
    pub clear_cycles: u64,
    pub readback_cycles: u64,
    /// Composite rounds (a round per `hash` call).
    pub rounds: u64,
    /// Texel words gathered from DRAM (textured frames: the fragment program's, per
    /// quad record `shade` wrote).
    pub texel_words: u64,
}

impl ReyesStats {
    pub fn zero_pixel_share(&self) -> f64 {
        self.zero_pixel_quads as f64 / self.quads.max(1) as f64
    }

    pub fn quads_per_visible_pixel(&self) -> f64 {
        self.quads as f64 / self.visible_pixels.max(1) as f64
    }

    pub fn kernel_cycles(&self, prefix: &str) -> u64 {
        self.kernels
            .iter()
            .filter(|k| k.kernel.starts_with(prefix))
            .map(|k| k.cycles)
            .sum()
    }
}

/// A rendered frame: packed RGBA8 colours and window depths, row 0 at the bottom.
#[derive(Clone, Debug)]
pub struct ReyesFrame {
    pub width: u32,
    pub height: u32,
    pub colour: Vec<u32>,
    pub depth: Vec<f32>,
    pub stats: ReyesStats,
}

/// The scene's patch objects as Bezier patches in object space, each with its
/// model-view-projection matrix and its colour (the material's diffuse colour).
pub fn scene_patches(scene: &Scene) -> Result<Vec<(BezierPatch, [f32; 16], u32)>, ReyesError> {
    let mut out = Vec::new();
    for object in &scene.objects {
        if object.patches.is_empty() {
            return Err(ReyesError(format!(
                "object `{}`: the Reyes pipeline draws patch objects only (`patches = \"...\"`)",
                object.name
            )));
        }
        let camera = scene.camera_for(object);
        let mvp = mat_mul(&camera.projection, &mat_mul(&camera.view, &object.model));
        let colour = pack_rgb(scene.materials[object.material].diffuse);
        out.extend(object.patches.iter().map(|p| (*p, mvp, colour)));
    }
    Ok(out)
}

/// How a frame's quads are shaded ([`kernels::shade`]) and what the machine reads to
/// shade them.
#[derive(Clone, Debug, PartialEq)]
pub struct ShadeSetup {
    pub shading: Shading,
    /// `shade`'s own parameters (lit): `2/W`, `2/H` and the projection's `P₀₀`, `P₁₁`,
    /// `P₂₂`, `P₂₃`.
    pub params: Vec<u32>,
    /// Lit: the vertex program whose `perlight` writes the lights' words, with its
    /// parameters and its input (the scene's OpenGL state, as the OpenGL pipeline hands
    /// them to the same kernel).
    pub perlight: Option<(VertexProgram, Vec<u32>, Vec<u32>)>,
    /// Textured or marble: the material's fragment program and what it reads.
    pub texturing: Option<Texturing>,
}

/// A textured or marble frame's fragment program (the OpenGL pipeline's, run on quads),
/// where its textures lie, and a marble's parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct Texturing {
    pub program: FragmentProgram,
    pub memory: TextureMemory,
    /// Marble: [`fragment_program::marble_params`] (empty otherwise).
    pub marble_params: Vec<u32>,
}

impl Texturing {
    /// The name the frame registers the program's colour kernel under: `fragment`, or for
    /// marble the kernel's own (`marble`, `marble_ward`).
    pub fn kernel_name(&self) -> &'static str {
        self.program
            .marble
            .map_or("fragment", turbulence::fragment_name)
    }

    /// The program's colour kernel, reading `shade`'s `varyings` records of
    /// `varyings_words` (no derivatives: nothing mipmapped).
    fn kernel(
        &self,
        desc: &MachineDesc,
        varyings_words: usize,
    ) -> Result<Kernel, MachineRequirementError> {
        match self.program.marble {
            Some(noise) => turbulence::build_fragment(desc, varyings_words, noise),
            None => self.program.fragment(varyings_words),
        }
    }
}

impl ShadeSetup {
    /// Each quad its patch's colour.
    pub fn flat() -> ShadeSetup {
        ShadeSetup {
            shading: Shading::Flat,
            params: Vec::new(),
            perlight: None,
            texturing: None,
        }
    }

    /// The shading of `scene`'s patch objects on a machine of `clusters` clusters: their
    /// material's, which they must share, with one camera (and for marble one model
    /// matrix). `lit`, `unlit` and `marble` materials are built, and `lit` ones with
    /// point-sampled or bilinear textures; mipmapped textures (no screen-space derivatives
    /// on quads), textured `unlit` materials and the bump-mapped shader are not (an
    /// error).
    pub fn of(scene: &Scene, clusters: usize) -> Result<ShadeSetup, ReyesError> {
        let Some(first) = scene.objects.first() else {
            return Ok(ShadeSetup::flat());
        };
        for o in &scene.objects {
            if o.material != first.material || scene.camera_for(o) != scene.camera_for(first) {
                return Err(ReyesError(format!(
                    "objects `{}` and `{}`: the Reyes pipeline shades one material through \
                     one camera per frame",
                    first.name, o.name
                )));
            }
        }
        let material = &scene.materials[first.material];
        let mipmapped = material
            .textures
            .iter()
            .map(|&t| &scene.textures[t])
            .find(|t| t.filter == Filter::Trilinear);
        if let Some(t) = mipmapped {
            return Err(ReyesError(format!(
                "material `{}`: texture `{}` is mipmapped (`trilinear`): the Reyes pipeline's \
                 quads have no screen-space derivatives; use `nearest` or `linear`",
                material.name, t.name
            )));
        }
        let program = VertexProgram::for_object(scene, first, false).map_err(ReyesError)?;
        match program {
            VertexProgram::Lit { .. } | VertexProgram::Marble { .. } => {}
            VertexProgram::Unlit { .. } if !material.textures.is_empty() => {
                return Err(ReyesError(format!(
                    "material `{}`: the Reyes pipeline textures lit materials only",
                    material.name
                )));
            }
            VertexProgram::Unlit { .. } => return Ok(ShadeSetup::flat()),
            _ => {
                return Err(ReyesError(format!(
                    "material `{}`: the Reyes pipeline shades lit, unlit and marble materials \
                     only",
                    material.name
                )));
            }
        }
        let camera = scene.camera_for(first);
        let p = camera.projection;
        // `shade` inverts a symmetric perspective projection (row-major): only P₀₀, P₁₁,
        // P₂₂ and P₂₃ and the last row `0 0 −1 0`.
        let symmetric = [1, 2, 3, 4, 6, 7, 8, 9, 12, 13, 15]
            .iter()
            .all(|&i| p[i] == 0.0)
            && p[14] == -1.0;
        if !symmetric {
            return Err(ReyesError(
                "the Reyes shader needs the camera's symmetric perspective projection".into(),
            ));
        }
        let mut params = [
            2.0 / scene.width as f32,
            2.0 / scene.height as f32,
            p[0],
            p[5],
            p[10],
            p[11],
        ]
        .map(f32::to_bits)
        .to_vec();
        if let Shader::Marble(marble) = material.shader {
            if let Some(o) = scene.objects.iter().find(|o| o.model != first.model) {
                return Err(ReyesError(format!(
                    "objects `{}` and `{}`: the Reyes pipeline's marble shades in one object \
                     space per frame (one model matrix)",
                    first.name, o.name
                )));
            }
            params.extend(to_object(&mat_mul(&camera.view, &first.model)));
            return Ok(ShadeSetup {
                shading: Shading::Marble,
                params,
                perlight: None,
                texturing: Some(Texturing {
                    program: FragmentProgram::marble(marble.noise),
                    memory: TextureMemory::new(scene, None),
                    marble_params: fragment_program::marble_params(scene, first, &marble),
                }),
            });
        }
        let VertexProgram::Lit {
            lights,
            specular,
            shininess,
            ..
        } = program
        else {
            unreachable!("lit or marble, checked above");
        };
        let texturing = (!material.textures.is_empty()).then(|| {
            let memory = TextureMemory::new(scene, None);
            Texturing {
                program: fragment_program::for_material(
                    scene,
                    &material.textures,
                    material.texture_mode,
                    &memory,
                ),
                memory,
                marble_params: Vec::new(),
            }
        });
        Ok(ShadeSetup {
            shading: Shading::Lit {
                lights,
                specular,
                shininess,
                textured: texturing.is_some(),
            },
            params,
            perlight: Some((
                program.clone(),
                VertexProgram::perlight_params(scene, first),
                program.light_words(scene, clusters),
            )),
            texturing,
        })
    }
}

/// The top three rows of the inverse of `model_view` (row-major), computed in f64 and
/// rounded: what a marble [`kernels::shade`] takes eye space to object space with.
fn to_object(model_view: &[f32; 16]) -> Vec<u32> {
    let m = DMat4::from_cols_array(&model_view.map(f64::from)).transpose();
    let rows = m.inverse().transpose().to_cols_array();
    rows[..kernels::TO_OBJECT_WORDS]
        .iter()
        .map(|&x| (x as f32).to_bits())
        .collect()
}

/// Quads per cluster per `subdiv` call that keep a call's streams within the SRF space a
/// kernel's output gets here (an eighth of the SRF): the quads (32 words each as `subdiv`
/// writes them, 20 as `shade` does, and in a frame with a fragment program
/// ([`ShadeSetup::texturing`]) a place, the varyings, the texel addresses and weights and
/// the colour), and their
/// fragments, at most about `(L + 1)²` per quad of side `L`. At most 64.
pub fn iterations_for(desc: &MachineDesc, stop: f32, shading: &ShadeSetup) -> usize {
    let c = desc.cluster.count.max(1);
    let share = desc.srf.words / 8;
    let per_quad = (f64::from(stop) + 1.0).powi(2).ceil() as usize;
    let by_fragments = share / (c * per_quad);
    let quad_words = shading.shading.records().subdiv_quad_words()
        + QUAD_WORDS
        + shading.texturing.as_ref().map_or(0, |t| {
            shading.shading.varyings_words()
                + t.program.direct_fetches()
                + t.program.direct_weights()
                + 1
        });
    let by_quads = share * 2 / (c * quad_words);
    by_fragments.min(by_quads).min(65).saturating_sub(1).max(1)
}

/// Breadth-first levels for a window: each spares the walk a stack frame. The teapot's
/// largest patches need 9 or 10 levels at 720×720 and the stack holds 7 frames, so
/// windows over 256 pixels a side get two, over 128 one.
pub fn split_levels_for(width: u32, height: u32) -> u32 {
    match width.max(height) {
        0..=128 => 0,
        129..=256 => 1,
        _ => 2,
    }
}

/// Checks a stop length: positive, finite, and within what `sample` is built for.
pub fn check_stop_length(stop: f32) -> Result<(), ReyesError> {
    if !(stop.is_finite() && stop > 0.0 && stop <= MAX_STOP_LENGTH) {
        return Err(ReyesError(format!(
            "stop length {stop}: must be a positive number of pixels up to {MAX_STOP_LENGTH} \
             (kernel `subdiv` splits quads until their sides are shorter)"
        )));
    }
    Ok(())
}

/// The composite's frame shape: every quad's fragments depth-tested LESS, nothing culled
/// or blended.
fn frame_shape(desc: &MachineDesc, width: u32, height: u32) -> FrameShape {
    let c = desc.cluster.count;
    FrameShape {
        width,
        height,
        clusters: c,
        cull: Cull::None,
        depth_test: DepthTest::Less,
        batch: c,
        blend: Blend::None,
    }
}

/// A frame's kernels by the names it calls them under (its kernel breakdown's): for a
/// `width × height` window, stop length `stop` and `shading` (`perlight` only when lit,
/// `texaddr` and `fragment` only when textured, `marble` or `marble_ward` for marble).
pub fn frame_kernels(
    desc: &MachineDesc,
    width: u32,
    height: u32,
    stop: f32,
    shading: &ShadeSetup,
) -> Result<Vec<(&'static str, Kernel)>, MachineRequirementError> {
    frame_kernel_results(desc, width, height, stop, shading)
        .into_iter()
        .map(|(name, k)| Ok((name, k?)))
        .collect()
}

/// [`frame_kernels`], each kernel built or refused on its own (`subdiv` needs a larger
/// scratchpad than gold8's; the others do not).
pub fn frame_kernel_results(
    desc: &MachineDesc,
    width: u32,
    height: u32,
    stop: f32,
    shading: &ShadeSetup,
) -> Vec<(&'static str, Result<Kernel, MachineRequirementError>)> {
    let shape = frame_shape(desc, width, height);
    let records = shading.shading.records();
    let mut k = vec![
        ("project", kernels::project(desc, records)),
        ("subdiv_split", kernels::subdiv_split(desc, records)),
        ("subdiv", kernels::subdiv(desc, records)),
    ];
    if let Some((program, ..)) = &shading.perlight {
        let perlight = program.perlight(desc).expect("a lit program has perlight");
        k.push(("perlight", Ok(perlight)));
    }
    k.push(("shade", kernels::shade(desc, shading.shading)));
    if let Some(t) = &shading.texturing {
        // The fragment program on quads: `shade`'s `varyings` records (r, g, b, then s, t
        // or the object-space position and normal), no derivatives (nothing mipmapped).
        let words = shading.shading.varyings_words();
        if !t.program.units.is_empty() {
            k.push(("texaddr", t.program.texaddr(words, words)));
        }
        k.push((t.kernel_name(), t.kernel(desc, words)));
    }
    k.extend([
        (
            "sample",
            kernels::sample(desc, width, height, stop, shading.texturing.is_some()),
        ),
        ("hash", gl::hash(desc, shape)),
        ("zcompare", gl::zcompare(desc, shape)),
        (
            "compact_recycle:z,colour",
            gl::compact_recycle(desc, [NULL_DEPTH, 0]),
        ),
        (
            "compact_recycle:addr,prim",
            gl::compact_recycle(desc, [shape.trash(), 0]),
        ),
        ("clear", gl::clear(desc)),
    ]);
    k
}

/// Renders a scene's patch objects through the Reyes pipeline on `desc`.
pub fn render(
    scene: &Scene,
    desc: &MachineDesc,
    options: &ReyesOptions,
) -> Result<ReyesFrame, ReyesError> {
    let patches = scene_patches(scene)?;
    let shading = ShadeSetup::of(scene, desc.cluster.count)?;
    render_patches(
        &patches,
        &shading,
        scene.width,
        scene.height,
        pack_rgb(scene.background),
        desc,
        options,
    )
}

/// Renders `patches` (object-space Bezier patches, each with its model-view-projection
/// matrix and colour) into a `width × height` window cleared to `background`.
pub fn render_patches(
    patches: &[(BezierPatch, [f32; 16], u32)],
    shading: &ShadeSetup,
    width: u32,
    height: u32,
    background: u32,
    desc: &MachineDesc,
    options: &ReyesOptions,
) -> Result<ReyesFrame, ReyesError> {
    check_stop_length(options.stop_length)?;
    let c = desc.cluster.count;
    let iterations = options
        .iterations
        .unwrap_or_else(|| iterations_for(desc, options.stop_length, shading));
    if iterations == 0 {
        return Err(ReyesError(
            "iterations per `subdiv` call must be at least 1".into(),
        ));
    }
    let levels = options
        .split_levels
        .unwrap_or_else(|| split_levels_for(width, height)) as usize;
    let records = shading.shading.records();
    let (patch_words, state_words) = (records.patch_words(), records.state_words());
    // The deepest quad: the breadth-first levels, then a full stack and its child.
    if records.places && levels + STACK_FRAMES + 1 > MAX_PLACE_LEVEL {
        return Err(ReyesError(format!(
            "kernel `shade`: {levels} breadth-first levels and a stack of {STACK_FRAMES} \
             frames reach level {}, deeper than the {MAX_PLACE_LEVEL} a quad's place (its \
             texture coordinates) can name",
            levels + STACK_FRAMES + 1
        )));
    }

    // The kernels, registered by name and compiled up front.
    let mut lib = KernelLibrary::new(desc, options.cache.clone());
    let mut ids = std::collections::HashMap::new();
    for (name, kernel) in frame_kernels(desc, width, height, options.stop_length, shading)
        .map_err(|e| ReyesError(e.to_string()))?
    {
        ids.insert(name, lib.register(name, kernel));
    }
    let id = |name: &str| ids[name];
    let texaddr = ids.get("texaddr").copied();
    let fragment = (shading.texturing.as_ref()).map(|t| ids[t.kernel_name()]);
    let (project, split, subdiv, shade, sample, clear) = (
        id("project"),
        id("subdiv_split"),
        id("subdiv"),
        id("shade"),
        id("sample"),
        id("clear"),
    );
    let perlight = ids.get("perlight").copied();
    let ck = CompositeKernels {
        hash: id("hash"),
        zcompare: id("zcompare"),
        recycle_zc: id("compact_recycle:z,colour"),
        recycle_ap: id("compact_recycle:addr,prim"),
        merge: None,
    };
    let mut eager = vec![project, subdiv, shade, sample, clear];
    eager.extend(perlight);
    eager.extend(texaddr.into_iter().chain(fragment));
    eager.extend([ck.hash, ck.zcompare, ck.recycle_zc, ck.recycle_ap]);
    if levels > 0 {
        eager.push(split);
    }
    lib.compile_now(&eager)
        .map_err(|e| ReyesError(format!("cannot compile the Reyes pipeline: {e}")))?;

    // The SRF: the projection's and the splits' chunks, then what the walks of a group
    // hold from call to call, `sample`'s fragments (what is left, equally) and the
    // composite's streams.
    let (phase_plan, ps) = plan_phases(desc)?;
    let mut pl = SrfPlanner::new(desc, &["project", "subdiv", "sample", "composite"]);
    let words = Layout::words();
    let chunk_records = CHUNK_ROWS * c;
    let patch_in = pl.stream(
        "patch_in",
        Layout::records(patch_words),
        chunk_records,
        live("project", "project"),
    );
    let patch_out = pl.stream(
        "patch_out",
        Layout::records(4 * patch_words),
        chunk_records,
        live("project", "project"),
    );
    let project_params = pl.stream("project_params", words, 18 * c, live("project", "project"));
    let index = pl.stream(
        "patch_index",
        words,
        chunk_records,
        live("project", "project"),
    );
    let walk_live = live("subdiv", "composite");
    let walk = pl.stream("walk", Layout::records(patch_words), c, walk_live);
    let state = pl.buffers::<2>("state", Layout::records(state_words), c, walk_live);
    let tickets = pl.stream("tickets", words, iterations * c, walk_live);
    let stop_params = pl.stream("stop2", words, c, Lifetime::Always);
    let quad_records = (iterations + 1) * c;
    let quads = pl.stream(
        "quads",
        Layout::records(records.subdiv_quad_words()),
        quad_records,
        walk_live,
    );
    let shaded = pl.stream(
        "shaded",
        Layout::records(QUAD_WORDS),
        quad_records,
        walk_live,
    );
    // `shade`'s parameters: its own, then the words `perlight` writes per cluster.
    let perlight_out = shading.perlight.as_ref().map_or(0, |(program, ..)| {
        program.param_count(desc) - program.perbegin_rows(desc)
    });
    let own_params: Vec<u32> = match shading.shading {
        Shading::Flat => Vec::new(),
        Shading::Lit { .. } | Shading::Marble => {
            let mut p = shading.params.clone();
            if shading.shading.textured() {
                p.push(levels as u32);
            }
            p.resize(kernels::shade_own_rows(desc, shading.shading), 0);
            p
        }
    };
    let shade_params = pl.stream(
        "shade_params",
        words,
        ((own_params.len() + perlight_out) * c).max(c),
        Lifetime::Always,
    );
    let (perlight_params, perlight_in) = match &shading.perlight {
        Some((_, params, lights)) => (params.len() * c, lights.len()),
        None => (0, 0),
    };
    // (At least a row each: the planner places no empty stream.)
    let perlight_params = pl.stream(
        "perlight_params",
        words,
        perlight_params.max(c),
        live("project", "project"),
    );
    let lights = pl.stream(
        "lights",
        words,
        perlight_in.max(c),
        live("project", "project"),
    );
    // A textured or marble frame's fragment program on the quads: `shade`'s varyings,
    // the texel addresses (each texel gathered over its address) and bilinear weights,
    // and the colours `sample` takes; a marble's parameters and (Perlin's noise) his
    // permutation table, each word once per cluster.
    let textured = shading.texturing.as_ref().map(|t| {
        let mut per_quad = |name: &str, words: usize| {
            (words > 0).then(|| pl.stream(name, Layout::records(words), quad_records, walk_live))
        };
        (
            per_quad("varyings", shading.shading.varyings_words()).expect("varyings"),
            per_quad("texels", t.program.direct_fetches()),
            per_quad("weights", t.program.direct_weights()),
            per_quad("colours", 1).expect("colours"),
        )
    });
    let marble_noise = shading.texturing.as_ref().and_then(|t| t.program.marble);
    let marble_params = marble_noise.map(|_| {
        let n = turbulence::SCALAR_PARAMS * c;
        pl.stream("marble_params", words, n, Lifetime::Always)
    });
    let perm_words = marble_noise
        .filter(|n| n.uses_table())
        .map(|_| turbulence::perlin_perm_stream(c));
    let perm = perm_words
        .as_ref()
        .map(|w| pl.stream("perm", words, w.len(), Lifetime::Always));
    let covered = pl.stream("covered", words, quad_records, walk_live);
    let frag_live = live("sample", "composite");
    let [f_addr, f_z, f_colour, f_prim] = ["frag_addr", "frag_z", "frag_colour", "frag_prim"]
        .map(|n| pl.elastic(n, words, frag_live));
    let cs = plan_composite(&mut pl, desc, composite_chunk(desc));
    let plan = pl.place()?;
    // `sample` writes at most `stamp²` fragments per quad record, then a row of nulls.
    let per_quad = stamp(options.stop_length).pow(2);
    let frag_capacity = plan.capacity(f_addr);
    // Pieces start on SRF blocks: whole blocks of `covered`'s one word per quad (and so of
    // the quads' 20).
    let unit = crate::stream::srf::block_rows(desc);
    let fit_rows = frag_capacity.saturating_sub(c) / (per_quad * c);
    let piece_rows = if fit_rows > iterations {
        iterations + 1
    } else {
        fit_rows / unit * unit
    };
    if piece_rows == 0 {
        return Err(ReyesError(format!(
            "kernel `sample`: machine `{}`: the SRF leaves {frag_capacity} fragments per \
             stream, fewer than {unit} rows of quads may write ({} at stop length {})",
            desc.name,
            unit * per_quad * c + c,
            options.stop_length
        )));
    }

    // DRAM: the patch records as loaded, each level's window-space patches, the cleared
    // walk, the framebuffer.
    let mut runs: Vec<(usize, usize)> = Vec::new();
    let mut at = 0;
    while at < patches.len() {
        let mvp = patches[at].1;
        let end = (at..patches.len())
            .find(|&i| patches[i].1 != mvp)
            .unwrap_or(patches.len());
        runs.push((at, end));
        at = end;
    }
    let mut upload: Vec<u32> = Vec::new();
    for &(a, e) in &runs {
        for (p, _, colour) in &patches[a..e] {
            upload.extend(p.iter().flatten().map(|v| v.to_bits()));
            upload.extend([*colour, 1]);
            if records.places {
                upload.push(0); // the patch's place: cell (0, 0) at level 0
            }
        }
        upload.resize(upload.len().next_multiple_of(c * patch_words), 0);
    }
    let mut dram = DramMap::new(desc);
    let input = dram.buffer("patches", upload.len().max(1) as u64)?;
    // Level `l` holds `real[l]` patches in `rows[l]` rows; level 0 also a trash record.
    let mut real = vec![patches.len()];
    for l in 0..levels {
        real.push(4 * real[l]);
    }
    let rows: Vec<usize> = real.iter().map(|r| r.div_ceil(c)).collect();
    let mut window = Vec::new();
    for l in 0..=levels {
        let records = if l == 0 {
            rows[0] * c + 1
        } else {
            4 * rows[l - 1] * c
        };
        window.push(dram.buffer(
            &format!("window[{l}]"),
            (records * patch_words).max(1) as u64,
        )?);
    }
    let zeros = dram.buffer("walk_zeros", (state_words * c) as u64)?;
    // A textured frame's textures, read-only (what a texture cache may hold); none in an
    // untextured frame, whose DRAM is laid out as it was before textures. A Perlin
    // marble's permutation table, as the OpenGL frame holds it.
    let perm_buffer = match &perm_words {
        Some(w) => Some(dram.read_only_buffer("perm", w.len() as u64)?),
        None => None,
    };
    let textures = match &shading.texturing {
        Some(t) if !t.memory.words.is_empty() => {
            let words = t.memory.words.len() as u64;
            Some((dram.read_only_buffer("textures", words)?, words))
        }
        _ => None,
    };
    let pixels = (width * height) as usize + 1;
    let fb_pixels = pixels.div_ceil(c) * c;
    let framebuffer = dram.buffer("framebuffer", (fb_pixels * PIXEL_WORDS) as u64)?;

    let mut h = StreamHost::new(desc, lib, dram, None, options.max_cycles)?;
    let processor = processor::processor_mut(h.sim_mut());
    processor.set_skip_idle(true);
    processor.set_datapath(options.datapath);
    let mut stats = ReyesStats {
        patches: patches.len(),
        ..ReyesStats::default()
    };

    // Load, then clear.
    let staging = phase_plan.whole(ps.staging);
    h.upload(&upload, input, 0, staging);
    if let (Some(t), Some((buffer, _))) = (&shading.texturing, textures) {
        h.upload(&t.memory.words, buffer, 0, staging);
    }
    if let (Some(w), Some(buffer)) = (&perm_words, perm_buffer) {
        h.upload(w, buffer, 0, staging);
    }
    h.drain()?;
    let loaded = h.cycles();
    clear_framebuffer(
        &mut h,
        clear,
        (&phase_plan, &ps),
        framebuffer,
        fb_pixels,
        background,
    )?;
    h.drain()?;
    let cleared = h.cycles();

    // A marble's parameters and table (loaded once, as the OpenGL frame loads it).
    if let (Some(t), Some(params)) = (&shading.texturing, marble_params) {
        h.write_params(plan.whole(params), &t.marble_params);
    }
    if let (Some(w), Some(buffer), Some(perm)) = (&perm_words, perm_buffer, perm) {
        h.load(buffer, 0, Layout::words(), w.len(), plan.whole(perm));
    }

    // The shader's parameters: its own, then the lights `perlight` writes from the OpenGL
    // state.
    let shade_b = plan.whole(shade_params);
    let own = plan.words(shade_params, own_params.len() * c);
    if !own_params.is_empty() {
        h.write_params(own, &own_params);
    }
    if let (Some(perlight), Some((_, params, light_words))) = (perlight, &shading.perlight) {
        let pb = plan.words(perlight_params, params.len() * c);
        h.write_params(pb, params);
        let lb = plan.words(lights, light_words.len());
        h.write(lb, light_words.clone());
        let out = plan.word_range(shade_params, own.words, shade_b.words - own.words);
        h.call(
            perlight,
            &[("lights", lb), ("light_params", out), (PARAMS, pb)],
        )?;
    }

    // Projection: each run in chunks, scattered to the real patches' record numbers.
    let trash = (rows[0] * c) as u64;
    let mut run_first = 0; // the run's first record in `input`
    let mut real_first = 0; // its first patch's record in `window[0]`
    for &(a, e) in &runs {
        let n_real = e - a;
        let mut params: Vec<u32> = patches[a].1.iter().map(|v| v.to_bits()).collect();
        params.push((width as f32 / 2.0).to_bits());
        params.push((height as f32 / 2.0).to_bits());
        let pb = plan.whole(project_params);
        h.write_params(pb, &params);
        let run_rows = n_real.div_ceil(c);
        for r0 in (0..run_rows).step_by(CHUNK_ROWS) {
            let n = CHUNK_ROWS.min(run_rows - r0) * c;
            let first = r0 * c;
            let from = plan.first(patch_in, n);
            h.load(
                input,
                (run_first + first) as u64,
                Layout::records(patch_words),
                n,
                from,
            );
            let out = plan.words(patch_out, n * patch_words);
            h.call(project, &[("patches", from), ("window", out), (PARAMS, pb)])?;
            let idx: Vec<u32> = (first..first + n)
                .map(|i| {
                    if i < n_real {
                        (real_first + i) as u32
                    } else {
                        trash as u32
                    }
                })
                .collect();
            let ib = plan.first(index, n);
            h.write(ib, idx);
            h.scatter(
                out,
                ib,
                trash + 1,
                Layout::records(patch_words),
                n,
                window[0],
            );
        }
        run_first += run_rows * c;
        real_first += n_real;
    }

    // Breadth-first levels: every patch into four, in place of their parent.
    for l in 0..levels {
        for r0 in (0..rows[l]).step_by(CHUNK_ROWS) {
            let n = CHUNK_ROWS.min(rows[l] - r0) * c;
            let from = plan.first(patch_in, n);
            h.load(
                window[l],
                (r0 * c) as u64,
                Layout::records(patch_words),
                n,
                from,
            );
            let out = plan.first(patch_out, n);
            h.call(split, &[("patches", from), ("children", out)])?;
            h.store(
                out,
                Layout::records(4 * patch_words),
                n,
                window[l + 1],
                (r0 * c) as u64,
            );
        }
    }

    // The walks, a group of `C` patches at a time.
    let stop2 = options.stop_length * options.stop_length;
    let stop_b = plan.whole(stop_params);
    h.write_params(stop_b, &[stop2.to_bits()]);
    let composite = Composite {
        k: &ck,
        plan: &plan,
        s: &cs,
        framebuffer,
        pixels: pixels as u64,
        merge_min_conflicts: None,
    };
    let mut counts = CompositeCounts::default();
    let top = window[levels];
    let groups = rows[levels];
    let quad_stream = plan.first(quads, quad_records);
    for g in 0..groups {
        h.load(
            zeros,
            0,
            Layout::records(state_words),
            c,
            plan.first(state[0], c),
        );
        let walk_b = plan.first(walk, c);
        h.load(top, (g * c) as u64, Layout::records(patch_words), c, walk_b);
        let mut cur = 0;
        let mut calls = 0u64;
        loop {
            calls += 1;
            let saved = plan.first(state[1 - cur], c);
            h.call(
                subdiv,
                &[
                    ("resume", plan.first(state[cur], c)),
                    ("patches", walk_b),
                    ("tickets", plan.first(tickets, iterations * c)),
                    ("quads", quad_stream),
                    ("state", saved),
                    (PARAMS, stop_b),
                ],
            )?;
            // Each cluster's stack depth and flags: the first two rows of the saved walks.
            let head = h.read_back(plan.words(state[1 - cur], 2 * c))?;
            if head[c..2 * c].iter().any(|f| f & 1 != 0) {
                let first = g * c;
                return Err(ReyesError(format!(
                    "kernel `subdiv`: a patch of group {g} (patches {first}..{}) needs a \
                     deeper stack than the {STACK_FRAMES} frames of {} words that \
                     `scratchpad.words` = {} holds; raise the stop length or the scratchpad",
                    (first + c).min(real[levels]),
                    records.frame_words(),
                    desc.scratchpad.words
                )));
            }
            let mut streams = vec![
                ("quads", quad_stream),
                ("shaded", plan.first(shaded, quad_records)),
            ];
            if shading.shading != Shading::Flat {
                streams.push((PARAMS, shade_b));
            }
            if let Some((varyings, ..)) = textured {
                streams.push(("varyings", plan.first(varyings, quad_records)));
            }
            h.call(shade, &streams)?;
            if let (Some((varyings, texels, weights, colours)), Some(t)) =
                (textured, &shading.texturing)
            {
                // The fragment program, as the OpenGL pipeline runs it on fragments.
                let fp = &t.program;
                let varyings = plan.first(varyings, quad_records);
                let texels = texels.map(|s| plan.first(s, quad_records));
                let weights = weights.map(|s| plan.first(s, quad_records));
                if let Some(texaddr) = texaddr {
                    let mut bindings = vec![("varyings", varyings)];
                    bindings.extend(texels.map(|b| ("addr", b)));
                    bindings.extend(weights.map(|b| ("weights", b)));
                    h.call(texaddr, &bindings)?;
                }
                if let Some(index) = texels {
                    let n = quad_records * fp.direct_fetches();
                    let (buffer, words) = textures.expect("a textured frame's texture buffer");
                    h.gather(buffer, index, words, Layout::words(), n, index);
                    stats.texel_words += n as u64;
                }
                let mut bindings = vec![("varyings", varyings)];
                bindings.extend(perm.map(|s| ("perm", plan.whole(s))));
                bindings.extend(marble_params.map(|s| (PARAMS, plan.whole(s))));
                bindings.extend(texels.map(|b| ("texels", b)));
                bindings.extend(weights.map(|b| ("weights", b)));
                bindings.push(("colour", plan.first(colours, quad_records)));
                h.call(fragment.expect("a fragment program's kernel"), &bindings)?;
            }
            let quad_words = records.subdiv_quad_words();
            for r in stream_to_records(&peek(&h, quad_stream), quad_words, c) {
                if r[Q_FLAGS] & FLAG_QUAD != 0 {
                    stats.quads += 1;
                    let level = r[Q_LEVEL] as usize + levels;
                    if stats.levels.len() <= level {
                        stats.levels.resize(level + 1, 0);
                    }
                    stats.levels[level] += 1;
                }
            }
            // The quads, sampled a piece at a time, each piece's fragments composited.
            let mut r0 = 0;
            while r0 <= iterations {
                let n = piece_rows.min(iterations + 1 - r0) * c;
                let outs = [f_addr, f_z, f_colour, f_prim].map(|s| plan.whole(s));
                let mut bindings = vec![("quads", plan.slice(shaded, r0 * c, n))];
                if let Some((.., colours)) = textured {
                    bindings.push(("colours", plan.slice(colours, r0 * c, n)));
                }
                bindings.extend([
                    ("addr", outs[0]),
                    ("z", outs[1]),
                    ("colour", outs[2]),
                    ("prim", outs[3]),
                    ("covered", plan.slice(covered, r0 * c, n)),
                ]);
                let call = h.call(sample, &bindings)?;
                h.wait(call)?;
                // Whole rows of fragments (the null row `sample` ends with pads the last).
                let len = h.written(call, "addr")? / c * c;
                let chunk = cs.chunk;
                for start in (0..len).step_by(chunk) {
                    composite.run(
                        &mut h,
                        [
                            (f_z, start),
                            (f_colour, start),
                            (f_addr, start),
                            (f_prim, start),
                        ],
                        chunk.min(len - start),
                        &mut counts,
                    )?;
                }
                r0 += n / c;
            }
            let quad_recs = stream_to_records(&peek(&h, quad_stream), quad_words, c);
            for (r, &n) in quad_recs
                .iter()
                .zip(&peek(&h, plan.first(covered, quad_records)))
            {
                if r[Q_FLAGS] & FLAG_QUAD != 0 && n == 0 {
                    stats.zero_pixel_quads += 1;
                }
                stats.fragments += u64::from(n);
            }
            if head[..c].iter().all(|&d| d == 0) {
                break;
            }
            if calls > 1 << 20 {
                return Err(ReyesError(format!(
                    "kernel `subdiv`: group {g} did not finish in {calls} calls"
                )));
            }
            cur = 1 - cur;
        }
    }
    h.drain()?;
    let rendered = h.cycles();

    // Read-back: the colour words of the framebuffer.
    let n = (width * height) as usize;
    let colour = h.download(framebuffer, 0, PIXEL_WORDS as u64, n, staging)?;
    h.drain()?;
    let read = h.cycles();
    h.finish()?;
    let records = processor::read_dram(h.sim(), desc, h.dram.base(framebuffer), n * PIXEL_WORDS);
    let depth: Vec<f32> = records
        .chunks(PIXEL_WORDS)
        .map(|r| f32::from_bits(r[1]))
        .collect();
    stats.visible_pixels = records.chunks(PIXEL_WORDS).filter(|r| r[2] != 0).count() as u64;
    stats.rounds = counts.rounds;
    stats.cycles = rendered - cleared;
    stats.load_cycles = loaded;
    stats.clear_cycles = cleared - loaded;
    stats.readback_cycles = read - rendered;
    stats.kernels = kernel_shares(&h);
    Ok(ReyesFrame {
        width,
        height,
        colour,
        depth,
        stats,
    })
}

/// The words of `b` as the SRF holds them now, through its backdoor (no cycle): for
/// statistics, once the host has waited for what wrote them.
fn peek(h: &StreamHost, b: StreamBinding) -> Vec<u32> {
    processor::processor(h.sim())
        .machine()
        .srf()
        .read_back(b.start, b.words)
        .expect("a planned stream lies in the SRF")
}

/// Each kernel's calls, cycles, stalls and ops from the stream controller's records, by the name the
/// frame registered it under, in first-call order (the clear is not the frame's).
fn kernel_shares(h: &StreamHost) -> Vec<KernelShare> {
    let mut shares: Vec<KernelShare> = Vec::new();
    for r in h.records() {
        let (StreamInstr::Kernel { program, .. }, Some(st)) = (&r.instr, &r.kernel_stats) else {
            continue;
        };
        let name = h.kernels.name_of_program(*program).unwrap_or("?");
        if name == "clear" {
            continue;
        }
        let share = KernelShare::of(&mut shares, name);
        share.calls += 1;
        share.cycles += st.cycles;
        share.stall_cycles += st.stall_cycles;
        share.ops += st.fu_ops.iter().sum::<u64>() * h.clusters() as u64;
    }
    shares
}
