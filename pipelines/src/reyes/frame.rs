//! A Reyes frame: the patches through `project`, `subdiv` and `sample`, and the
//! fragments through the OpenGL pipeline's composite kernels (`hash`, `zcompare`,
//! `compact_recycle`), every kernel compiled to microcode and run on the clocked machine.
//!
//! **What is modelled.** Each kernel call runs on a machine built from the description
//! (clusters, LRFs, scratchpad, stream buffers, microcontroller), with its input streams
//! given and its output streams taken whole; the frame's cycles are the sum of the calls'
//! cycles. The stream controller, the SRF's allocation and the memory system are not in
//! this driver yet: the framebuffer's gathers and scatters by pixel address (which the
//! OpenGL pipeline issues to DRAM) are done here as the memory would do them, and take no
//! cycles. So the cycles are the kernels' alone, without kernel dispatch or memory time.
//!
//! **Order of calls.** The patches are projected in one call. Then groups of `C` patches
//! (patch `p` in cluster `p mod C`) are subdivided: each `subdiv` call walks
//! [`ReyesOptions::iterations`] quads per cluster and saves its stacks; its quads are
//! sampled and composited at once (`sample`, then rounds of `hash` / `zcompare` /
//! `compact_recycle` until no fragment conflicts), and `subdiv` is called again with the
//! saved stacks until every cluster's is empty.

use imagine_units::desc::MachineDesc;
use imagine_units::runner::RunOptions;

use super::kernels::{
    self, FLAG_OVERFLOW, FLAG_QUAD, FRAME_WORDS, MAX_STOP_LENGTH, PATCH_WORDS, Q_FLAGS, Q_LEVEL,
    QUAD_WORDS, STACK_FRAMES, STATE_WORDS,
};
use crate::compile::{CompileCache, Compiled};
use crate::kernel::{Kernel, KernelInputs};
use crate::kernels::{records_to_stream, stream_to_records};
use crate::opengl::kernels::{self as gl, FrameShape, NULL_DEPTH, PIXEL_WORDS};
use crate::opengl::render::pack_rgb;
use crate::run::run_on_machine;
use crate::scene::mat_mul;
use crate::scene::model::{Blend, Cull, DepthTest, Scene};

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
    /// Give up a kernel call after this many cycles.
    pub max_call_cycles: u64,
    pub cache: CompileCache,
}

impl Default for ReyesOptions {
    fn default() -> Self {
        ReyesOptions {
            stop_length: 1.5,
            iterations: None,
            split_levels: None,
            max_call_cycles: 50_000_000,
            cache: CompileCache::disabled(),
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

/// One kernel's share of a frame.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct KernelShare {
    pub name: String,
    pub calls: u64,
    pub cycles: u64,
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
    /// Per kernel, in first-call order.
    pub kernels: Vec<KernelShare>,
    /// The sum of the kernels' cycles.
    pub cycles: u64,
    /// Composite rounds (a round per `hash` call).
    pub rounds: u64,
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
            .filter(|k| k.name.starts_with(prefix))
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

/// The kernels of a frame, compiled.
struct Compiledset {
    list: Vec<(Kernel, Compiled)>,
}

impl Compiledset {
    fn get(&self, name: &str) -> &(Kernel, Compiled) {
        self.list
            .iter()
            .find(|(k, _)| k.name == name)
            .expect("compiled kernel")
    }
}

/// Runs one kernel call, counting its cycles.
struct Runner<'a> {
    desc: &'a MachineDesc,
    set: &'a Compiledset,
    stats: &'a mut ReyesStats,
    max_cycles: u64,
}

impl Runner<'_> {
    fn call(
        &mut self,
        name: &str,
        streams: Vec<Vec<u32>>,
        params: Vec<u32>,
    ) -> Result<Vec<Vec<u32>>, ReyesError> {
        let (kernel, compiled) = self.set.get(name);
        let inputs = KernelInputs { streams, params };
        let options = RunOptions {
            max_cycles: self.max_cycles,
            ..RunOptions::default()
        };
        let run = run_on_machine(kernel, compiled, self.desc, &inputs, options)
            .map_err(|e| ReyesError(format!("kernel `{name}`: {e}")))?;
        let share = match self.stats.kernels.iter_mut().find(|k| k.name == name) {
            Some(s) => s,
            None => {
                self.stats.kernels.push(KernelShare {
                    name: name.into(),
                    ..KernelShare::default()
                });
                self.stats.kernels.last_mut().expect("pushed")
            }
        };
        share.calls += 1;
        share.cycles += run.stats.cycles;
        self.stats.cycles += run.stats.cycles;
        Ok(run.streams)
    }
}

/// Quads per cluster per `subdiv` call that keep a call's streams within the SRF space a
/// kernel's output gets here (an eighth of the SRF): the quads (20 words each), and their
/// fragments, at most about `(L + 1)²` per quad of side `L`. At most 64.
pub fn iterations_for(desc: &MachineDesc, stop: f32) -> usize {
    let c = desc.cluster.count.max(1);
    let share = desc.srf.words / 8;
    let per_quad = (f64::from(stop) + 1.0).powi(2).ceil() as usize;
    let by_fragments = share / (c * per_quad);
    let by_quads = share * 2 / (c * QUAD_WORDS);
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

/// Renders a scene's patch objects through the Reyes pipeline on `desc`.
pub fn render(
    scene: &Scene,
    desc: &MachineDesc,
    options: &ReyesOptions,
) -> Result<ReyesFrame, ReyesError> {
    let patches = scene_patches(scene)?;
    render_patches(
        &patches,
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
        .unwrap_or_else(|| iterations_for(desc, options.stop_length));
    if iterations == 0 {
        return Err(ReyesError(
            "iterations per `subdiv` call must be at least 1".into(),
        ));
    }
    let shape = FrameShape {
        width,
        height,
        clusters: c,
        cull: Cull::None,
        depth_test: DepthTest::Less,
        batch: c,
        blend: Blend::None,
    };
    let trash = shape.trash();
    let built: Vec<Kernel> = vec![
        kernels::project(desc),
        kernels::subdiv_split(desc),
        kernels::subdiv(desc),
        kernels::sample(desc, width, height, options.stop_length),
        gl::hash(desc, shape),
        gl::zcompare(desc, shape),
        gl::compact_recycle(desc, [trash, NULL_DEPTH]),
    ]
    .into_iter()
    .collect::<Result<_, _>>()
    .map_err(|e| ReyesError(e.to_string()))?;
    let mut list = Vec::new();
    for k in built {
        let compiled = options
            .cache
            .compile(&k, desc)
            .map_err(|e| ReyesError(e.to_string()))?;
        list.push((k, compiled));
    }
    let set = Compiledset { list };
    let mut stats = ReyesStats {
        patches: patches.len(),
        ..ReyesStats::default()
    };
    let mut run = Runner {
        desc,
        set: &set,
        stats: &mut stats,
        max_cycles: options.max_call_cycles,
    };

    // The framebuffer: colour, depth, primitive per pixel, and the trash pixel.
    let pixels = (width * height) as usize + 1;
    let mut fb = vec![0u32; pixels * PIXEL_WORDS];
    for p in 0..pixels {
        fb[p * PIXEL_WORDS] = background;
        fb[p * PIXEL_WORDS + 1] = 1.0f32.to_bits();
    }

    // Project every patch: one call per matrix run (objects share one).
    let mut window: Vec<Vec<u32>> = Vec::with_capacity(patches.len());
    let mut at = 0;
    while at < patches.len() {
        let mvp = patches[at].1;
        let end = (at..patches.len())
            .find(|&i| patches[i].1 != mvp)
            .unwrap_or(patches.len());
        let mut records: Vec<Vec<u32>> = patches[at..end]
            .iter()
            .map(|(p, _, colour)| {
                let mut r: Vec<u32> = p.iter().flatten().map(|v| v.to_bits()).collect();
                r.push(*colour);
                r.push(1);
                r
            })
            .collect();
        let real = records.len();
        records.resize(real.div_ceil(c) * c, inactive_patch());
        let mut params: Vec<u32> = mvp.iter().map(|v| v.to_bits()).collect();
        params.push((width as f32 / 2.0).to_bits());
        params.push((height as f32 / 2.0).to_bits());
        let out = run.call(
            "project",
            vec![records_to_stream(&records, c), Vec::new()],
            params,
        )?;
        window.extend(
            stream_to_records(&out[1], PATCH_WORDS, c)
                .into_iter()
                .take(real),
        );
        at = end;
    }

    // Breadth-first levels: every patch into four, the children in place of their parent.
    let levels = options
        .split_levels
        .unwrap_or_else(|| split_levels_for(width, height));
    for _ in 0..levels {
        let real = window.len();
        let mut records = window.clone();
        records.resize(real.div_ceil(c) * c, inactive_patch());
        let out = run.call(
            "subdiv_split",
            vec![records_to_stream(&records, c), Vec::new()],
            vec![],
        )?;
        window = stream_to_records(&out[1], 4 * PATCH_WORDS, c)
            .into_iter()
            .take(real)
            .flat_map(|four| {
                four.chunks(PATCH_WORDS)
                    .map(<[u32]>::to_vec)
                    .collect::<Vec<_>>()
            })
            .collect();
    }
    let split_levels = levels as usize;

    let stop2 = (options.stop_length * options.stop_length).to_bits();
    let tickets = vec![0u32; iterations * c];
    for (g, group) in window.chunks(c).enumerate() {
        let mut records: Vec<Vec<u32>> = group.to_vec();
        records.resize(c, inactive_patch());
        let patch_stream = records_to_stream(&records, c);
        let mut resume = vec![0u32; STATE_WORDS * c];
        let mut calls = 0u64;
        loop {
            calls += 1;
            let out = run.call(
                "subdiv",
                vec![
                    resume,
                    patch_stream.clone(),
                    tickets.clone(),
                    Vec::new(),
                    Vec::new(),
                ],
                vec![stop2],
            )?;
            let quads = &out[3];
            let state = &out[4];
            // The stack's overflow, and the quads' counts.
            for r in stream_to_records(quads, QUAD_WORDS, c) {
                let flags = r[Q_FLAGS];
                if flags & FLAG_OVERFLOW != 0 {
                    return Err(ReyesError(format!(
                        "kernel `subdiv`: a patch of group {g} (patches {}..{}) needs a deeper \
                         stack than the {STACK_FRAMES} frames of {FRAME_WORDS} words that \
                         `scratchpad.words` = {} holds; raise the stop length or the scratchpad",
                        g * c,
                        g * c + group.len(),
                        desc.scratchpad.words
                    )));
                }
                if flags & FLAG_QUAD != 0 {
                    run.stats.quads += 1;
                    let level = r[Q_LEVEL] as usize + split_levels;
                    if run.stats.levels.len() <= level {
                        run.stats.levels.resize(level + 1, 0);
                    }
                    run.stats.levels[level] += 1;
                }
            }
            let sampled = run.call(
                "sample",
                vec![
                    quads.clone(),
                    Vec::new(),
                    Vec::new(),
                    Vec::new(),
                    Vec::new(),
                    Vec::new(),
                ],
                vec![],
            )?;
            for (r, &n) in stream_to_records(quads, QUAD_WORDS, c)
                .iter()
                .zip(&sampled[5])
            {
                if r[Q_FLAGS] & FLAG_QUAD != 0 && n == 0 {
                    run.stats.zero_pixel_quads += 1;
                }
                run.stats.fragments += u64::from(n);
            }
            // Whole rows of fragments (the null row `sample` ends with pads the last).
            let rows = sampled[1].len() / c;
            let take = |s: &[u32]| s[..rows * c].to_vec();
            let frags = [
                take(&sampled[1]),
                take(&sampled[2]),
                take(&sampled[3]),
                take(&sampled[4]),
            ];
            composite(&mut run, &mut fb, frags)?;
            // Word 0 of each cluster's saved walk is its depth.
            let done = (0..c).all(|l| state[l] == 0);
            if done {
                break;
            }
            if calls > 1 << 20 {
                return Err(ReyesError(format!(
                    "kernel `subdiv`: group {g} did not finish in {calls} calls"
                )));
            }
            resume = state.clone();
        }
    }

    let n = (width * height) as usize;
    let colour: Vec<u32> = (0..n).map(|p| fb[p * PIXEL_WORDS]).collect();
    let depth: Vec<f32> = (0..n)
        .map(|p| f32::from_bits(fb[p * PIXEL_WORDS + 1]))
        .collect();
    stats.visible_pixels = (0..n).filter(|&p| fb[p * PIXEL_WORDS + 2] != 0).count() as u64;
    Ok(ReyesFrame {
        width,
        height,
        colour,
        depth,
        stats,
    })
}

fn inactive_patch() -> Vec<u32> {
    vec![0; PATCH_WORDS]
}

/// The composite of one call's fragments `[addr, z, colour, prim]` (whole rows): rounds of
/// `hash` and `zcompare` over the pixels gathered by address, the passing pixels scattered
/// back, and the fragments `hash` held back recycled by `compact_recycle`.
fn composite(run: &mut Runner<'_>, fb: &mut [u32], frags: [Vec<u32>; 4]) -> Result<(), ReyesError> {
    let c = run.desc.cluster.count;
    let [mut addr, mut z, mut colour, mut prim] = frags;
    while !addr.is_empty() {
        run.stats.rounds += 1;
        // The gather of the fragments' pixels (records in the cluster-row layout).
        let gathered: Vec<Vec<u32>> = addr
            .iter()
            .map(|&a| fb[a as usize * PIXEL_WORDS..(a as usize + 1) * PIXEL_WORDS].to_vec())
            .collect();
        let pixel = records_to_stream(&gathered, c);
        let hashed = run.call("hash", vec![addr.clone(), Vec::new(), Vec::new()], vec![])?;
        let conflict = hashed[1][..addr.len()].to_vec();
        let conflicts = hashed[2].first().copied().unwrap_or(0);
        let zc = run.call(
            "zcompare",
            vec![
                z.clone(),
                colour.clone(),
                addr.clone(),
                prim.clone(),
                pixel,
                conflict.clone(),
                Vec::new(),
                Vec::new(),
            ],
            vec![],
        )?;
        // The scatter of the new pixels.
        let new = stream_to_records(&zc[6], PIXEL_WORDS, c);
        for (p, &a) in new.iter().zip(&zc[7]) {
            let a = a as usize;
            fb[a * PIXEL_WORDS..(a + 1) * PIXEL_WORDS].copy_from_slice(p);
        }
        if conflicts == 0 {
            break;
        }
        let kept_az = run.call(
            "compact_recycle",
            vec![conflict.clone(), addr, z, Vec::new(), Vec::new()],
            vec![],
        )?;
        let kept_cp = run.call(
            "compact_recycle",
            vec![conflict, colour, prim, Vec::new(), Vec::new()],
            vec![],
        )?;
        let rows = kept_az[3].len() / c;
        let take = |s: &[u32]| s[..rows * c].to_vec();
        addr = take(&kept_az[3]);
        z = take(&kept_az[4]);
        colour = take(&kept_cp[3]);
        prim = take(&kept_cp[4]);
    }
    Ok(())
}
