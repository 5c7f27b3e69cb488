//! The kernels of the OpenGL-like pipeline (ARCHITECTURE §5), built per frame: the window
//! size, the cluster count and the cull mode are compile-time constants of the microcode.
//!
//! | kernel | per element | streams |
//! |---|---|---|
//! | [`perbegin`](super::vertex_program) | once per object: the vertex program's parameters from the OpenGL state | state → params |
//! | `vertex_*` ([`super::vertex_program`]) | vertex: clip position and colour | 3 or 6 words → 7 words |
//! | `vtexaddr`, then `vertex_bump_env` ([`crate::kernels::bump_env`]) | vertex: a vertex texture's addresses; the texels gathered; displacement, bumped normal, eye-space frame | 11 words → 4 addresses; 11 words, 4 texels → 18 words |
//! | [`clear`] | pixel: the clear colour and depth | tickets → pixels |
//! | [`assemble_clip`] | triangle: its three vertices gathered into one cluster (comms), trivial reject | shaded vertices → clipped (10), attribs (12) |
//! | [`viewport_cull`] | triangle: window-homogeneous corners, edge functions, facing, cull, bounding box, top-left flags | clipped → window (14), \|det\| |
//! | [`baryprep`] | triangle: the interpolation record | attribs, \|det\| → interp (13) |
//! | [`xyprep`] | triangle, per scissor tile: box clamped to the tile, the raster record, `xyrast`'s cost | window → raster (12), counts |
//! | [`xyrast`] | run of 4 candidate pixels: coverage by three edge functions (in primitive order when blending) | raster → addr, tri, E0, E1, E2 (conditional) |
//! | [`irast`] | fragment: perspective-correct colour and depth (with a fragment program: the interpolated values and texture-coordinate derivatives instead of the packed colour) | E0..E2, interp → z, colour or varyings, prim |
//! | `texaddr`, `filter8`, `fragment`, `marble` ([`crate::kernels::texture`], [`crate::kernels::turbulence`]) | fragment: the object's fragment program, split at its texture lookups (texels gathered between `texaddr` and the rest) | varyings → colour |
//! | `bumpaddr`, `envaddr`, `fragment` ([`crate::kernels::bump_env`]) | fragment: `bump_env`'s dependent read, 3 kernels and 2 gathers (bump-map normal; environment texel along the reflection) | varyings → 3 addresses; varyings, 3 texels → 1 address; varyings, 1 texel → colour |
//! | [`hash`] | fragment: conflict with an earlier fragment of the round (32×32 stamp) | addr → conflict |
//! | [`zcompare`] | fragment: the depth test (LESS, LEQUAL, ALWAYS) with primitive-order ties, and the blend | z, colour, addr, prim, pixel, conflict → new pixel, its address |
//! | [`compact_recycle`] | fragment: keeps the conflicting fragments for the next round | conflict, a, b → a', b' (conditional) |
//! | [`sort32`](super::mergefrag::sort32) | group of 32 fragments: the conflicting ones sorted by address | conflict, addr, z, prim → key, z, prim |
//! | [`mergefrag`](super::mergefrag::mergefrag) | sorted group: one fragment per address, the one `zcompare` would keep | key, z, prim, colour → z, colour, addr, prim (conditional) |
//!
//! **Rasterization** is homogeneous (Olano and Greer, "Triangle Scan Conversion using 2D
//! Homogeneous Coordinates", Graphics Hardware 1997): with `v_k = ((x_k + w_k)·W/2,
//! (y_k + w_k)·H/2, w_k)` the edge functions of a pixel centre `p = (X, Y, 1)` are
//! `E_0 = (v_1 × v_2)·p`, `E_1 = (v_2 × v_0)·p`, `E_2 = (v_0 × v_1)·p` and
//! `det = v_0·(v_1 × v_2)`; `det > 0` is front-facing. After flipping the signs of
//! clockwise triangles, a pixel is covered when every `E_i > 0`, or `E_i = 0` on a top or
//! left edge (`A > 0`, or `A = 0` and `B < 0`, for `E = A·X + B·Y + C`). The perspective-
//! correct barycentrics are `λ_i = E_i / ΣE` and the depth is
//! `z_ndc = ζ + Σ E_i·(z_i − ζ·w_i) / |det|` for any `ζ` (as `Σ E_i·w_i = |det|`, it is
//! `Σ E_i·z_i / |det|`): no divide by w per vertex, and triangles that cross w = 0 need no
//! clipping. Fragments outside depth [0, 1] are discarded (near and far clipping).
//! With the scene's `pipeline.reference_depth`, `assemble_clip` takes the triangle's own
//! depth for `ζ`, corner 0's `z_0/w_0` clamped to [−1, 1]; without it, `ζ = 0` (and no
//! word carries it). Why: the rounding of the edge functions, which grows as a triangle
//! turns edge-on, is multiplied by what is interpolated — with `ζ = 0` by `z_i`, which is
//! about `w_i` wherever far/near is large (near 1e-3 and far 1e6 pushed 0.8 % of a lit
//! mesh's pixels, along its silhouettes, past depth 1), with the triangle's own `ζ` by the
//! depth differences across the triangle, small at any depth range. It costs 5 adder ops
//! in `assemble_clip` (the clamp and the subtracts) and a word of the `attribs` and
//! interpolation records, which every fragment gathers (SPHERE 0.9 %, VERONA 3.3 % more
//! cycles), so it is the scene's choice, off by default. (Taking `ζ = 1`, the far plane,
//! for no ops and no word, fixed that case but lost 2.3 dB on ADVS-8, whose depths fill
//! [−1, 1].)
//!
//! **Layouts.** Multi-word records in the SRF are in the cluster-row layout the kernels
//! read (see [`crate::kernel`]); conditional outputs are one-word streams. Vertices are in
//! drawing order (triangle `t` is vertices `3t..3t + 3`); from `assemble_clip` on, a
//! batch's triangle `t` is in cluster `t mod C`. Conditional outputs end with one row of
//! null records (`C` of them) so that the host can read them back in whole rows.
//!
//! **xyrast** keeps a batch's raster records in the scratchpads: cluster `c` copies its own
//! (triangles `c`, `c + C`, …; empty boxes left out) before the loop, then walks their
//! bounding boxes one after another, [`XYRAST_RUN`] pixels of a box row per iteration. The
//! clusters need not agree on when to move to the next triangle, so there are no
//! conditional reads and no loop-carried decision that waits for the data it fetches (the
//! recurrences are the position's and the record pointer's, a few integer ops each); the
//! loop's interval is set by the scratchpad port, which the twelve record words and the
//! conditional writes share. The loop runs over a `tickets` stream whose length the host
//! takes from `xyprep`'s count: the most runs any cluster has, exactly what the busiest
//! cluster needs. The scratchpad bounds the batch: [`xyrast_rows`] triangles per cluster.

use imagine_units::arith::fp32::RECIPROCAL_GUESS;
use imagine_units::desc::MachineDesc;
use imagine_units::ops::Op;

use crate::kernel::{
    Kernel, KernelBuilder, LoopSpec, MachineRequirementError, Needs, Perm, StreamId, Ty, Value,
};
use crate::kernels::or_channel;
use crate::scene::model::{Blend, Cull, DepthTest};

/// Words of a raster record (`xyprep` → `xyrast`): the bounding box's first and last pixel (`lo`, `hi`,
/// packed `y·2^16 + x`), the tag (the triangle's index in the batch and its three top-left
/// flags) and the nine edge coefficients.
pub const RASTER_WORDS: usize = 12;
/// Where the words of a raster record are (the edge coefficients follow the tag).
const LO: u16 = 0;
const HI: u16 = 1;
const TAG: u16 = 2;
/// Words of an interpolation record without a reference depth: z_k / |det| (3), r, g, b per
/// corner (9), primitive (see [`Varyings::interp_words`]).
pub const INTERP_WORDS: usize = 13;
/// Words of a framebuffer pixel in DRAM (gathered and written back whole): colour, depth,
/// primitive.
pub const PIXEL_WORDS: usize = 3;
/// Bits of the triangle's index in a raster record's tag (the top three hold the top-left
/// flags).
pub const TRI_BITS: u32 = 29;
/// Pixels of one box row `xyrast` tests per iteration (a power of two).
pub const XYRAST_RUN: usize = 4;
const _: () = assert!(XYRAST_RUN.is_power_of_two());
/// A null fragment's depth: NaN fails every depth test.
pub const NULL_DEPTH: u32 = 0x7FC0_0000;

/// What the kernels of one frame are built for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameShape {
    pub width: u32,
    pub height: u32,
    pub clusters: usize,
    /// The winding `viewport_cull` discards.
    pub cull: Cull,
    /// The depth test `zcompare` applies.
    pub depth_test: DepthTest,
    /// Triangles per batch (a multiple of `clusters`): `xyrast` keeps a batch's raster
    /// records in the scratchpad.
    pub batch: usize,
    /// The blend `zcompare` applies; blending also makes `xyrast` write the fragments in
    /// primitive order ([`FrameShape::ordered`]).
    pub blend: Blend,
}

impl FrameShape {
    /// Whether `xyrast` must write a batch's fragments in primitive order: a blend is not
    /// an extremum over (depth, primitive), so a pixel's fragments must reach the composite
    /// in the order OpenGL draws them.
    pub fn ordered(&self) -> bool {
        in_primitive_order(self.blend)
    }

    /// The pixel address null fragments go to: one past the window.
    pub fn trash(&self) -> u32 {
        self.width * self.height
    }
}

/// Whether a frame blending by `blend` rasterizes in primitive order (see
/// [`FrameShape::ordered`]).
pub fn in_primitive_order(blend: Blend) -> bool {
    blend != Blend::None
}

/// What a frame's vertices carry beyond the clip position and the colour: `extras` words
/// per vertex, interpolated perspective-correctly for the fragment program (when any
/// object has one) — texture coordinates s, t (2 words) for textured objects, the
/// object-space shading position and normal x, y, z, nx, ny, nz (6 words) for marble ones,
/// each object's padded with zeros to the frame's count — and with them the per-triangle
/// sums the screen-space derivatives of the first two (s, t) need (when any texture is
/// mipmapped).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Varyings {
    pub extras: usize,
    pub derivatives: bool,
    /// Whether each triangle's records carry its reference depth ζ (the scene's
    /// `pipeline.reference_depth`; see the module notes).
    pub reference_depth: bool,
}

impl Varyings {
    /// Whether fragments go through a fragment program (`irast` hands it their values).
    pub fn fragment_program(self) -> bool {
        self.extras > 0
    }

    /// Words of a shaded vertex: [`SHADED_WORDS`], then the extras.
    pub fn shaded_words(self) -> usize {
        SHADED_WORDS + self.extras
    }

    /// Words of an `attribs` record: ζ if the frame has it, [`ATTRIB_WORDS`], then the
    /// extras of each corner.
    pub fn attrib_words(self) -> usize {
        usize::from(self.reference_depth) + ATTRIB_WORDS + 3 * self.extras
    }

    /// Words of an interpolation record before its colours: ζ if the frame has it, then
    /// the three corners' depths.
    pub fn depth_words(self) -> usize {
        usize::from(self.reference_depth) + 3
    }

    /// Where an interpolation record's extras start: after ζ if the frame has it and the
    /// [`INTERP_WORDS`].
    pub fn extras_at(self) -> usize {
        usize::from(self.reference_depth) + INTERP_WORDS
    }

    /// Where an interpolation record's primitive number is (its last word before the
    /// extras).
    pub fn prim_at(self) -> usize {
        self.extras_at() - 1
    }

    /// Words of an interpolation record: ζ if the frame has it, [`INTERP_WORDS`], then the
    /// extras of each corner,
    /// then the derivative sums `ΣA, ΣB, Σs·A, Σs·B, Σt·A, Σt·B` over the edge functions
    /// `E_k = A_k·X + B_k·Y + C_k`.
    pub fn interp_words(self) -> usize {
        self.extras_at() + 3 * self.extras + 6 * usize::from(self.derivatives)
    }

    /// Words `irast` writes per fragment to `varyings` (frames with a fragment program):
    /// r, g, b, the extras, then ∂s/∂X, ∂s/∂Y, ∂t/∂X, ∂t/∂Y.
    pub fn fragment_words(self) -> usize {
        3 + self.extras + 4 * usize::from(self.derivatives)
    }

    /// Where the derivatives start in a `varyings` record.
    pub fn derivatives_at(self) -> usize {
        3 + self.extras
    }
}

/// The most triangles per cluster `xyrast` can hold in `desc`'s scratchpad: its raster
/// records, a sentinel and the word read past it, below the words conditional streams keep.
pub fn xyrast_rows(desc: &MachineDesc) -> usize {
    let reserved = 2 * desc.srf.conditional_words_per_cycle;
    let words = desc.scratchpad.words.saturating_sub(reserved);
    words.saturating_sub(RASTER_WORDS + 1) / RASTER_WORDS
}

pub(crate) fn finish(b: KernelBuilder) -> Kernel {
    match b.finish() {
        Ok(k) => k,
        Err(e) => panic!("pipeline kernel does not verify: {e}"),
    }
}

/// `cc ? 1 : 0` as an int32.
fn flag(b: &mut KernelBuilder, cc: Value) -> Value {
    let (one, zero) = (b.i32(1), b.i32(0));
    b.select(cc, one, zero)
}

/// An int32 flag as a condition.
fn cond(b: &mut KernelBuilder, flag: Value) -> Value {
    let zero = b.i32(0);
    b.ine(flag, zero)
}

/// Combines `x` across the clusters with `op` by butterfly exchanges (log2 C comms).
pub(crate) fn all_reduce(
    b: &mut KernelBuilder,
    clusters: usize,
    mut x: Value,
    op: fn(&mut KernelBuilder, Value, Value) -> Value,
) -> Value {
    let mut d = 1;
    while d < clusters {
        let other = b.comm(x, Perm::Xor(d as u16));
        x = op(b, x, other);
        d *= 2;
    }
    x
}

/// One row of null records after a conditional output: every cluster writes `nulls[i]` to
/// stream `outs[i]`.
pub(crate) fn null_row(b: &mut KernelBuilder, outs: &[(StreamId, u32)]) {
    let zero = b.i32(0);
    let all = b.ieq(zero, zero);
    for &(s, null) in outs {
        let v = b.word(null);
        b.write_if(s, all, v);
    }
}

/// `clear`: the framebuffer clear, done by the machine: one pixel record (the clear colour,
/// the clear depth, primitive 0) per element of `tickets` (whose words are not read for
/// their values; they set the length). The host stores the records over the framebuffer.
pub fn clear(_desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("clear");
    let tickets = b.input("tickets");
    let pixels = b.output("pixels");
    let colour = b.param("colour", Ty::Word);
    let depth = b.param("depth", Ty::Word);
    let zero = b.word(0);
    b.begin_loop(LoopSpec::OverStream(tickets));
    let ticket = b.read(tickets);
    // Primitive 0 ("never drawn"), taken through the ticket so the read is used.
    let prim = b.and(ticket, zero);
    for w in [colour, depth, prim] {
        b.write(pixels, w);
    }
    b.end_loop();
    Ok(finish(b))
}

/// Words of a shaded vertex (a vertex program's output, `assemble_clip`'s input): clip x,
/// y, z, w, then r, g, b.
pub const SHADED_WORDS: usize = 7;
/// Words of a `clipped` record (`assemble_clip` → `viewport_cull`): clip-space x, y and w
/// of each corner, then 1 if no clip plane rejects the triangle, else 0.
pub const CLIPPED_WORDS: usize = 10;
/// Words of an `attribs` record (`assemble_clip` → `baryprep`) without a reference depth:
/// clip-space z of each corner, then r, g, b of each (see [`Varyings::attrib_words`]).
pub const ATTRIB_WORDS: usize = 12;
/// Words of a `window` record (`viewport_cull` → `xyprep`): the nine edge coefficients
/// (counter-clockwise), the bounding box's first and last pixel `x0, y0, x1, y1` (int32,
/// `i32::MIN`/`MAX` where a corner has w ≤ 0), and flags: bit 0 keep, the top bits the
/// edges' top-left flags as in a raster record's tag.
pub const WINDOW_WORDS: usize = 14;

/// `assemble_clip`: triangle assembly and trivial reject. Input `shaded`: vertices in
/// drawing order (7 words each: clip x, y, z, w, then r, g, b), so triangle `t` is vertices
/// `3t..3t + 3`, spread over the clusters; each iteration reads three rows of vertices and
/// assembles the `C` triangles they hold, triangle `c` of the row in cluster `c`. Its corner
/// `k` (vertex `3c + k` of the three rows) sits in row `⌊(3c + k)/C⌋` of cluster
/// `(3c + k) mod C`; since 3 is invertible modulo `C`, the map from `c` to that cluster is
/// a permutation, so each corner word is one comm (the sender picks the row its receiver
/// needs). Trivial reject: all three corners outside one of the six clip planes (what is
/// left is rasterized homogeneously, with no clipping). With `normalise_clip` (the scene's
/// `pipeline.normalise_clip`) the corners then go out scaled by a power of two for the
/// triangle that brings the largest x, y or w near 1 (exact; it keeps the rasterizer's
/// products within fp32's range at any scale of clip space, for about 1 % of SPHERE's
/// cycles, so it is the scene's choice).
///
/// Outputs per triangle: `clipped` ([`CLIPPED_WORDS`]) and `attribs`
/// ([`Varyings::attrib_words`]), whose depths are taken from the triangle's reference
/// depth when the frame has one (see the module notes).
///
/// Needs a power-of-two cluster count (a vertex's row is its index shifted right by
/// `log2 C`).
pub fn assemble_clip(
    desc: &MachineDesc,
    varyings: Varyings,
    normalise_clip: bool,
) -> Result<Kernel, MachineRequirementError> {
    Needs::new("assemble_clip", desc).power_of_two_clusters(None)?;
    let clusters = desc.cluster.count;
    let mut b = KernelBuilder::new("assemble_clip");
    let shaded = b.input("shaded");
    let clipped = b.output("clipped");
    let attribs = b.output("attribs");
    // 3⁻¹ mod C (C is a power of two).
    let inverse_of_3 = (0..clusters).find(|x| 3 * x % clusters == 1 % clusters);
    let inverse_of_3 = b.i32(inverse_of_3.unwrap_or(0) as i32);
    let mask = b.i32(clusters as i32 - 1);
    let log2_c = b.i32(clusters.trailing_zeros() as i32);
    let (zero, one, three) = (b.i32(0), b.i32(1), b.i32(3));
    let zero_f = b.f32(0.0);
    let cluster = b.cluster_id();
    let three_c = b.imul(cluster, three);
    // Per corner k: the cluster this one receives from, and the row this one sends (that of
    // the cluster whose corner k it holds, (s - k)·3⁻¹ mod C), as two conditions.
    let corners: Vec<(Value, Value, Value)> = (0..3)
        .map(|k| {
            let k = b.i32(k);
            let vertex = b.iadd(three_c, k);
            let source = b.and(vertex, mask);
            let d = b.isub(cluster, k);
            let d = b.imul(d, inverse_of_3);
            let receiver = b.and(d, mask);
            let v = b.imul(receiver, three);
            let v = b.iadd(v, k);
            let v = b.isub(v, cluster);
            let row = b.shr(v, log2_c);
            (source, b.ieq(row, zero), b.ieq(row, one))
        })
        .collect();

    b.begin_loop(LoopSpec::OverStream(shaded));
    let words = varyings.shaded_words();
    let rows: Vec<Vec<Value>> = (0..3)
        .map(|_| (0..words).map(|_| b.read_f32(shaded)).collect())
        .collect();
    let v: Vec<Vec<Value>> = corners
        .iter()
        .map(|&(source, row0, row1)| {
            (0..words)
                .map(|j| {
                    let later = b.select(row1, rows[1][j], rows[2][j]);
                    let sent = b.select(row0, rows[0][j], later);
                    b.comm(sent, Perm::PerCluster(source))
                })
                .collect()
        })
        .collect();
    // Trivial reject: all three corners outside one clip plane.
    let mut worst = None;
    for (axis, negate) in [
        (0, false),
        (0, true),
        (1, false),
        (1, true),
        (2, false),
        (2, true),
    ] {
        let mut m = None;
        for c in &v {
            // Inside the plane iff w - x >= 0 (x <= w) or w + x >= 0 (x >= -w).
            let d = if negate {
                b.fadd(c[3], c[axis])
            } else {
                b.fsub(c[3], c[axis])
            };
            m = Some(m.map_or(d, |m| b.fmax(m, d)));
        }
        let m = m.expect("three corners");
        worst = Some(worst.map_or(m, |w| b.fmin(w, m)));
    }
    let outside = b.flt(worst.expect("six planes"), zero_f);
    let not_rejected = {
        let f = flag(&mut b, outside);
        b.xor(f, one)
    };
    // The corners' x, y, z, w scaled by one power of two for the triangle, 2^-k with k
    // half the exponent of the largest square of an x, y or w: their largest magnitude
    // then lies in [1, 2) (up to the square's rounding). Exact, and the same triangle (clip space is
    // homogeneous; `irast`'s depth Σ E·((z − ζw)/det) has z − ζw scaling once (ζ not at all), the edge functions E
    // twice and the determinant three times), but `viewport_cull`'s edge functions
    // (products of two coordinates) and determinant (of three) then neither underflow
    // nor overflow at any scale of clip space, which the divide by w of other OpenGLs
    // removes and a homogeneous rasterizer otherwise keeps: clip coordinates of 1e-17
    // had a determinant of 1e-46, zero, and the triangle was dropped as degenerate. The
    // squares go to the multipliers, which this kernel leaves idle; a square that
    // overflows or underflows still gives a scale within [2^-64, 2^64].
    let v: Vec<Vec<Value>> = if !normalise_clip {
        v
    } else {
        let largest = v
            .iter()
            .flat_map(|c| [c[0], c[1], c[3]])
            .collect::<Vec<_>>()
            .into_iter()
            .map(|x| b.fmul(x, x))
            .collect::<Vec<_>>()
            .into_iter()
            .reduce(|m, q| b.fmax(m, q))
            .expect("nine coordinates");
        // With e the square's biased exponent, 2^-k has the exponent field
        // 127 - ⌊(e - 127) / 2⌋ = ⌊(382 - e) / 2⌋.
        let bits = b.cast(largest, Ty::Word);
        let field = b.i32(23);
        let e = b.shr(bits, field);
        let c382 = b.i32(382);
        let down = b.isub(c382, e);
        let down = b.shr(down, one);
        let down = b.shl(down, field);
        let scale = b.cast(down, Ty::F32);
        v.iter()
            .map(|c| {
                let mut c = c.clone();
                for x in &mut c[..4] {
                    *x = b.fmul(*x, scale);
                }
                c
            })
            .collect()
    };
    for c in &v {
        for w in [c[0], c[1], c[3]] {
            b.write(clipped, w);
        }
    }
    b.write(clipped, not_rejected);
    // The reference depth ζ and each corner's depth from it (see the module notes): a
    // divide the divider, idle here, takes, and 3 multiplies on idle multipliers.
    if varyings.reference_depth {
        let zeta = {
            let q = b.fdiv(v[0][2], v[0][3]);
            let minus_one = b.f32(-1.0);
            let q = b.fmax(q, minus_one);
            let one_f = b.f32(1.0);
            b.fmin(q, one_f)
        };
        b.write(attribs, zeta);
        for c in &v {
            let on_zeta = b.fmul(zeta, c[3]);
            let d = b.fsub(c[2], on_zeta);
            b.write(attribs, d);
        }
    } else {
        for c in &v {
            b.write(attribs, c[2]);
        }
    }
    for c in &v {
        for &channel in &c[4..7] {
            b.write(attribs, channel);
        }
    }
    for c in &v {
        for &st in &c[7..] {
            b.write(attribs, st);
        }
    }
    b.end_loop();
    Ok(finish(b))
}

/// `viewport_cull`: per `clipped` record — the viewport transform to window-homogeneous
/// corners, the edge functions and the determinant (whose sign is the facing), culling
/// (degenerate triangles, and back faces when the frame culls them), and the window
/// position of each corner when every w > 0 (for the bounding box).
///
/// Outputs per triangle: `window` ([`WINDOW_WORDS`]) and `det` (`|det|`, one word).
pub fn viewport_cull(
    _desc: &MachineDesc,
    shape: FrameShape,
) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("viewport_cull");
    let clipped = b.input("clipped");
    let window = b.output("window");
    let det_out = b.output("det");
    let (zero_f, one_f) = (b.f32(0.0), b.f32(1.0));
    let one = b.i32(1);
    let (lo_clamp, hi_clamp) = (b.f32(-2.0), b.f32(8192.0));
    let half_w = b.f32(shape.width as f32 / 2.0);
    let half_h = b.f32(shape.height as f32 / 2.0);

    b.begin_loop(LoopSpec::OverStream(clipped));
    // Clip x, y, w per corner.
    let v: Vec<[Value; 3]> = (0..3)
        .map(|_| std::array::from_fn(|_| b.read_f32(clipped)))
        .collect();
    let not_rejected = b.read_i32(clipped);
    // Window-homogeneous corners and the edge functions.
    let hv: Vec<[Value; 3]> = v
        .iter()
        .map(|c| {
            let x = b.fadd(c[0], c[2]);
            let x = b.fmul(x, half_w);
            let y = b.fadd(c[1], c[2]);
            let y = b.fmul(y, half_h);
            [x, y, c[2]]
        })
        .collect();
    let cross = |b: &mut KernelBuilder, p: [Value; 3], q: [Value; 3]| -> [Value; 3] {
        let term = |b: &mut KernelBuilder, i: usize, j: usize| {
            let l = b.fmul(p[i], q[j]);
            let r = b.fmul(p[j], q[i]);
            b.fsub(l, r)
        };
        [term(b, 1, 2), term(b, 2, 0), term(b, 0, 1)]
    };
    let edges = [
        cross(&mut b, hv[1], hv[2]),
        cross(&mut b, hv[2], hv[0]),
        cross(&mut b, hv[0], hv[1]),
    ];
    let det = {
        let a = b.fmul(hv[0][0], edges[0][0]);
        let c = b.fmul(hv[0][1], edges[0][1]);
        let s = b.fadd(a, c);
        let d = b.fmul(hv[0][2], edges[0][2]);
        b.fadd(s, d)
    };
    let front = b.flt(zero_f, det);
    // Counter-clockwise: a clockwise triangle's edges change sign (a multiply by -1 is
    // exact, and leaves the adders to the rest).
    let sign = {
        let minus_one = b.f32(-1.0);
        b.select(front, one_f, minus_one)
    };
    let edges: Vec<[Value; 3]> = edges.iter().map(|e| e.map(|c| b.fmul(c, sign))).collect();
    let abs_det = b.fabs(det);
    let degenerate = b.feq(det, zero_f);
    let mut keep = {
        let d = flag(&mut b, degenerate);
        let nd = b.xor(d, one);
        b.and(not_rejected, nd)
    };
    match shape.cull {
        Cull::None => {}
        Cull::Back => {
            let f = flag(&mut b, front);
            keep = b.and(keep, f);
        }
        Cull::Front => {
            let f = flag(&mut b, front);
            let back = b.xor(f, one);
            keep = b.and(keep, back);
        }
    }
    // Bounding box: the window corners (X/w, Y/w, one divide for all three) when every
    // w > 0, else unbounded (the scissor rectangle bounds it in `xyprep`).
    let w = [v[0][2], v[1][2], v[2][2]];
    let w01 = b.fmul(w[0], w[1]);
    let w012 = b.fmul(w01, w[2]);
    let inv_w012 = b.fdiv(one_f, w012);
    let w12 = b.fmul(w[1], w[2]);
    let w02 = b.fmul(w[0], w[2]);
    let inv_w = [
        b.fmul(w12, inv_w012),
        b.fmul(w02, inv_w012),
        b.fmul(w01, inv_w012),
    ];
    let w_min = {
        let m = b.fmin(w[0], w[1]);
        b.fmin(m, w[2])
    };
    let all_in_front = b.flt(zero_f, w_min);
    let (unbounded_lo, unbounded_hi) = (b.i32(i32::MIN), b.i32(i32::MAX));
    let mut bounds = [unbounded_lo; 4];
    for axis in 0..2 {
        let p: Vec<Value> = hv
            .iter()
            .zip(inv_w)
            .map(|(h, i)| b.fmul(h[axis], i))
            .collect();
        let lo = {
            let m = b.fmin(p[0], p[1]);
            b.fmin(m, p[2])
        };
        let hi = {
            let m = b.fmax(p[0], p[1]);
            b.fmax(m, p[2])
        };
        for (slot, value) in [(axis, lo), (axis + 2, hi)] {
            // Pixel centres at +0.5: the first and last candidate are near
            // trunc(v - 0.5); a 1/64-pixel margin keeps the box conservative against
            // rounding. Clamped before conversion (NaN and huge values included).
            let margin = b.f32(if slot < 2 {
                -0.5 - 1.0 / 64.0
            } else {
                -0.5 + 1.0 / 64.0
            });
            let c = b.fadd(value, margin);
            let c = b.fmax(c, lo_clamp);
            let c = b.fmin(c, hi_clamp);
            let i = b.ftoi_trunc(c);
            let unbounded = if slot < 2 { unbounded_lo } else { unbounded_hi };
            bounds[slot] = b.select(all_in_front, i, unbounded);
        }
    }
    // Top-left flags: A > 0, or A = 0 and B < 0.
    let mut flags = keep;
    for (i, e) in edges.iter().enumerate() {
        let a_pos = b.flt(zero_f, e[0]);
        let a_zero = b.feq(e[0], zero_f);
        let b_neg = b.flt(e[1], zero_f);
        let bn = flag(&mut b, b_neg);
        let az = flag(&mut b, a_zero);
        let horizontal_top = b.and(az, bn);
        let t = b.select(a_pos, one, horizontal_top);
        let shift = b.i32((TRI_BITS + i as u32) as i32);
        let t = b.shl(t, shift);
        flags = b.or(flags, t);
    }
    for w in edges.iter().flatten().chain(&bounds) {
        b.write(window, *w);
    }
    b.write(window, flags);
    b.write(det_out, abs_det);
    b.end_loop();
    Ok(finish(b))
}

/// `xyprep`: per `window` record and scissor tile (parameters `sx0, sy0, sx1, sy1`,
/// inclusive) — the triangle's box clamped to the tile, its raster record and what
/// `xyrast` will cost.
///
/// Outputs: `raster` ([`RASTER_WORDS`] per triangle, every triangle: one not kept, or whose
/// box misses the tile, gets an empty box) and, after the loop, `rows`: a row of the
/// iterations `xyrast` needs (the most runs of [`XYRAST_RUN`] box pixels of any cluster, at
/// least one; the same word in every cluster; in primitive order the sum over the
/// triangles of their runs of `XYRAST_RUN·C` pixels, 1 for an empty box), then a row of
/// each cluster's candidate pixels, whose sum bounds the fragments `xyrast` writes.
///
/// Needs a power-of-two cluster count (the busiest cluster is found by butterfly
/// exchanges).
pub fn xyprep(desc: &MachineDesc, shape: FrameShape) -> Result<Kernel, MachineRequirementError> {
    Needs::new("xyprep", desc).power_of_two_clusters(None)?;
    let mut b = KernelBuilder::new("xyprep");
    let window = b.input("window");
    let raster = b.output("raster");
    let rows_out = b.output("rows");
    let scissor: [Value; 4] = ["sx0", "sy0", "sx1", "sy1"].map(|n| b.param(n, Ty::I32));
    let clusters = shape.clusters;
    let (zero, one) = (b.i32(0), b.i32(1));
    let row_c = b.i32(clusters as i32);
    let top_left_bits = b.word(!((1 << TRI_BITS) - 1));
    let cluster = b.cluster_id();

    b.begin_loop(LoopSpec::OverStream(window));
    let index0 = b.carried(cluster);
    let candidates0 = b.carried(zero);
    let runs0 = b.carried(zero);
    let edges: [Value; 9] = std::array::from_fn(|_| b.read(window));
    let bounds: [Value; 4] = std::array::from_fn(|slot| {
        let v = b.read_i32(window);
        if slot < 2 {
            b.imax(v, scissor[slot])
        } else {
            b.imin(v, scissor[slot])
        }
    });
    let flags = b.read_i32(window);
    let [x0, y0, x1, y1] = bounds;
    let x_ok = b.ile(x0, x1);
    let y_ok = b.ile(y0, y1);
    let nonempty = {
        let a = flag(&mut b, x_ok);
        let c = flag(&mut b, y_ok);
        b.and(a, c)
    };
    let keep = {
        let k = b.and(flags, one);
        b.and(k, nonempty)
    };
    let kept = cond(&mut b, keep);
    let sixteen = b.i32(16);
    let pack = |b: &mut KernelBuilder, x: Value, y: Value| {
        let y = b.shl(y, sixteen);
        b.or(x, y)
    };
    let lo = pack(&mut b, x0, y0);
    let hi = pack(&mut b, x1, y1);
    let empty_lo = b.i32(1 | 1 << 16);
    let lo = b.select(kept, lo, empty_lo);
    let hi = b.select(kept, hi, zero);
    // Candidates: the box's area (0 when not kept).
    let width = {
        let d = b.isub(x1, x0);
        b.iadd(d, one)
    };
    let height = {
        let d = b.isub(y1, y0);
        b.iadd(d, one)
    };
    let area = b.imul(width, height);
    let candidates = b.select(kept, area, zero);
    let candidates_total = b.iadd(candidates0, candidates);
    b.set_next(candidates0, candidates_total);
    // xyrast's iterations: runs of XYRAST_RUN pixels, ⌈width / RUN⌉ per box row; in
    // primitive order, runs of RUN·C pixels (one per cluster side by side), and one
    // iteration for a box not kept, which every cluster steps over together.
    let run = if shape.ordered() {
        XYRAST_RUN * clusters
    } else {
        XYRAST_RUN
    };
    let runs = {
        let r = b.i32(run as i32 - 1);
        let w = b.iadd(width, r);
        let shift = b.i32(run.trailing_zeros() as i32);
        let per_row = b.shr(w, shift);
        let n = b.imul(per_row, height);
        let skipped = if shape.ordered() { one } else { zero };
        b.select(kept, n, skipped)
    };
    let runs_total = b.iadd(runs0, runs);
    b.set_next(runs0, runs_total);
    // The tag: the triangle's index and the top-left flags.
    let top_left = b.and(flags, top_left_bits);
    let tag = b.or(index0, top_left);
    for w in [lo, hi, tag].into_iter().chain(edges) {
        b.write(raster, w);
    }
    let next_index = b.iadd(index0, row_c);
    b.set_next(index0, next_index);
    b.end_loop();
    // Each cluster walks its own boxes in `xyrast`: the busiest one sets the iterations;
    // in primitive order all walk every box together.
    let reduce = if shape.ordered() {
        KernelBuilder::iadd
    } else {
        KernelBuilder::imax
    };
    let most = all_reduce(&mut b, clusters, runs0, reduce);
    let iterations = b.imax(most, one);
    b.write(rows_out, iterations);
    b.write(rows_out, candidates0);
    Ok(finish(b))
}

/// `baryprep`: per triangle, the interpolation record `irast` reads
/// ([`Varyings::interp_words`]):
/// the reference depth ζ, `(z_k − ζ·w_k) / |det|` of each corner, the corners' colours and
/// the primitive number
/// `prim_base + index + 1` (parameter `prim_base`). Inputs: `attribs` and `det`.
pub fn baryprep(desc: &MachineDesc, varyings: Varyings) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("baryprep");
    let attribs = b.input("attribs");
    let det = b.input("det");
    let window = varyings.derivatives.then(|| b.input("window"));
    let interp = b.output("interp");
    let prim_base = b.param("prim_base", Ty::I32);
    let one_f = b.f32(1.0);
    let one = b.i32(1);
    let row_c = b.i32(desc.cluster.count as i32);
    let cluster = b.cluster_id();
    b.begin_loop(LoopSpec::OverStream(attribs));
    let index0 = b.carried(cluster);
    let zeta = varyings.reference_depth.then(|| b.read_f32(attribs));
    let z: [Value; 3] = std::array::from_fn(|_| b.read_f32(attribs));
    let colours: [Value; 9] = std::array::from_fn(|_| b.read_f32(attribs));
    let extras: Vec<Value> = (0..3 * varyings.extras)
        .map(|_| b.read_f32(attribs))
        .collect();
    // The edge functions' A and B (sign-normalised, as `xyrast` evaluates them).
    let edges: Option<Vec<Value>> = window.map(|w| {
        let words: Vec<Value> = (0..WINDOW_WORDS).map(|_| b.read_f32(w)).collect();
        words[..9].to_vec()
    });
    let abs_det = b.read_f32(det);
    let inv_det = b.fdiv(one_f, abs_det);
    if let Some(zeta) = zeta {
        b.write(interp, zeta);
    }
    for z in z {
        let q = b.fmul(z, inv_det);
        b.write(interp, q);
    }
    for c in colours {
        b.write(interp, c);
    }
    let prim = {
        let p = b.iadd(prim_base, index0);
        b.iadd(p, one)
    };
    b.write(interp, prim);
    for &x in &extras {
        b.write(interp, x);
    }
    if let Some(e) = edges {
        // ΣA, ΣB, Σs·A, Σs·B, Σt·A, Σt·B: with them `irast` finds s's derivative
        // ∂s/∂X = (Σs·A − s·ΣA)/ΣE (λ_k = E_k/ΣE), and likewise for Y and t.
        let sum = |b: &mut KernelBuilder, terms: [Value; 3]| {
            let s = b.fadd(terms[0], terms[1]);
            b.fadd(s, terms[2])
        };
        for coefficient in 0..2 {
            let c: [Value; 3] = std::array::from_fn(|k| e[3 * k + coefficient]);
            let total = sum(&mut b, c);
            b.write(interp, total);
        }
        for channel in 0..2 {
            for coefficient in 0..2 {
                let terms: [Value; 3] = std::array::from_fn(|k| {
                    b.fmul(
                        extras[varyings.extras * k + channel],
                        e[3 * k + coefficient],
                    )
                });
                let total = sum(&mut b, terms);
                b.write(interp, total);
            }
        }
    }
    let next_index = b.iadd(index0, row_c);
    b.set_next(index0, next_index);
    b.end_loop();
    Ok(finish(b))
}

/// `xyrast`: walks each cluster's triangles' bounding boxes, [`XYRAST_RUN`] pixels of a box
/// row per iteration, and writes the covered ones: `addr` (`y·W + x`), `tri` (the
/// triangle's index in the batch) and its edge values `e0`, `e1`, `e2`, then a row of nulls
/// (address one past the window).
///
/// Before the loop each cluster copies its own raster records (triangles `c`, `c + C`, …
/// of the batch) into its scratchpad, leaving out empty boxes, and ends them with a
/// sentinel; the loop reads the current record from there. So every cluster walks its own
/// boxes at its own pace: no conditional reads, and no cluster waits for the largest box
/// of a row. The loop runs for as many iterations as the busiest cluster needs (`xyprep`
/// counts them); a cluster that is done sits on the sentinel, which covers nothing.
///
/// **In primitive order** (blending frames, [`FrameShape::ordered`]) the fragments must
/// come out triangle by triangle. Then every record keeps its place (record `t` in row
/// `t / C` of cluster `t mod C`, empty or not), and the clusters walk the boxes together:
/// each iteration the cluster holding the current record sends its words to all
/// (`Perm::PerCluster` of the owner, the same in every cluster), and the run is `4·C`
/// pixels of a box row, cluster `c` testing pixels `4c … 4c + 3` of it. The walk's
/// decisions are the same in every cluster, so they move to the next triangle together; an
/// empty box (`lo > hi`) covers nothing and costs one iteration. `xyprep` counts the
/// iterations as the sum over the triangles.
///
/// Needs a scratchpad that holds the batch's `batch / C` records per cluster (see
/// [`xyrast_rows`]).
pub fn xyrast(desc: &MachineDesc, shape: FrameShape) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("xyrast");
    let raster = b.input("raster");
    let tickets = b.input("tickets");
    let addr_out = b.output("addr");
    let tri_out = b.output("tri");
    let e_out: [StreamId; 3] = ["e0", "e1", "e2"].map(|n| b.output(n));
    let rows = shape.batch / shape.clusters;
    Needs::new("xyrast", desc).scratchpad_words(
        (rows + 1) * RASTER_WORDS + 1,
        &format!("{rows} raster records, a sentinel and the word read past it"),
        true,
    )?;
    let ordered = shape.ordered();
    let clusters = shape.clusters;
    let record = b.i32(RASTER_WORDS as i32);
    let zero = b.i32(0);

    // The records, compacted: an empty box (lo > hi) is overwritten by the next record. In
    // primitive order every record keeps its place, record `t` of the batch in row
    // `t / C` of cluster `t mod C`, where the others find it.
    let mut at = zero;
    for _ in 0..rows {
        let words: Vec<Value> = (0..RASTER_WORDS).map(|_| b.read(raster)).collect();
        for (i, &w) in words.iter().enumerate() {
            b.sp_write(i as u16, Some(at), w);
        }
        let size = if ordered {
            record
        } else {
            let nonempty = b.op(Op::ILeU, &[words[LO as usize], words[HI as usize]]);
            b.select(nonempty, record, zero)
        };
        at = b.iadd(at, size);
    }
    // The sentinel: from lo = 0 the position only creeps on (hi = 2^32 - 1 would take 2^30
    // iterations), and C0 = -inf makes E0 -inf or NaN, which fails edge 0.
    for (word, value) in [
        (LO, 0),
        (HI, u32::MAX),
        (TAG + 3, f32::NEG_INFINITY.to_bits()),
    ] {
        let v = b.word(value);
        b.sp_write(word, Some(at), v);
    }
    let first = b.sp_read(LO, None);
    let first = if ordered {
        b.comm(first, Perm::Broadcast(0))
    } else {
        first
    };
    let first = b.cast(first, Ty::I32);
    // In primitive order the clusters walk one box together, cluster `c` taking pixels
    // `4c .. 4c + 3` of a run of `4·C`.
    let step = if ordered {
        XYRAST_RUN * clusters
    } else {
        XYRAST_RUN
    };
    let offset = ordered.then(|| {
        let lane = b.cluster_id();
        let run = b.i32(XYRAST_RUN as i32);
        b.imul(lane, run)
    });

    let run = b.i32(step as i32);
    let run_end = b.i32(step as i32 - 1);
    let down = b.i32(1 << 16);
    let low16 = b.i32(0xFFFF);
    let up16 = b.word(1 << 16);
    let tri_mask = b.i32((1 << TRI_BITS) - 1);
    let width = b.i32(shape.width as i32);
    let (zero_f, half) = (b.f32(0.0), b.f32(0.5));
    let edge_test = EdgeTest::new(&mut b, desc, zero_f);

    b.begin_loop(LoopSpec::OverStream(tickets));
    // The current record's first word, or in primitive order the triangle's index.
    let at0 = b.carried(zero);
    let pos0 = b.carried(first);
    let row0 = b.carried(first);
    let _ticket = b.read(tickets);
    let (rec, next_lo, at_moved) = if ordered {
        // Record `t`'s words from the cluster that holds it, to every cluster.
        let lane_mask = b.i32(clusters as i32 - 1);
        let log2_c = b.i32(clusters.trailing_zeros() as i32);
        let place = |b: &mut KernelBuilder, t: Value| {
            let owner = b.and(t, lane_mask);
            let row = b.shr(t, log2_c);
            (owner, b.imul(row, record))
        };
        let (owner, slot) = place(&mut b, at0);
        let rec: Vec<Value> = (HI..RASTER_WORDS as u16)
            .map(|i| {
                let w = b.sp_read(i, Some(slot));
                b.comm(w, Perm::PerCluster(owner))
            })
            .collect();
        let one = b.i32(1);
        let next = b.iadd(at0, one);
        let (next_owner, next_slot) = place(&mut b, next);
        let lo = b.sp_read(LO, Some(next_slot));
        let next_lo = b.comm(lo, Perm::PerCluster(next_owner));
        (rec, next_lo, Some(next))
    } else {
        let rec: Vec<Value> = (HI..RASTER_WORDS as u16)
            .map(|i| b.sp_read(i, Some(at0)))
            .collect();
        let next_lo = b.sp_read(RASTER_WORDS as u16 + LO, Some(at0));
        (rec, next_lo, None)
    };
    let (hi, tag) = (b.cast(rec[0], Ty::I32), b.cast(rec[1], Ty::I32));
    let coefficient = |edge: usize, k: usize| rec[2 + 3 * edge + k];
    // Positions are packed y·2^16 + x (`xyprep` clamps both to the scissor tile, inside the window). This run is pixels
    // pos .. pos + RUN - 1, `row0` the first pixel of its box row. When the run reaches x1
    // the next run starts the next row, or, on row y1 (hi <= end), the next record's box.
    let end = b.iadd(pos0, run_end);
    let hi16 = b.cast(hi, Ty::P16);
    let end16 = b.cast(end, Ty::P16);
    let wrap = b.op(Op::Le16x2U, &[hi16, end16]);
    let wrap = b.cast(wrap, Ty::Cc);
    let done = b.op(Op::ILeU, &[hi, end]);
    let next_row = b.iadd(row0, down);
    let right = b.iadd(pos0, run);
    let moved = b.select(wrap, next_row, right);
    let pos_next = b.select(done, next_lo, moved);
    b.set_next(pos0, pos_next);
    let row_moved = b.select(wrap, next_row, row0);
    let row_next = b.select(done, next_lo, row_moved);
    b.set_next(row0, row_next);
    let at_moved = at_moved.unwrap_or_else(|| b.iadd(at0, record));
    let at_next = b.select(done, at_moved, at0);
    b.set_next(at0, at_next);

    let thresholds = edge_test.thresholds(&mut b, tag);
    let tri = b.and(tag, tri_mask);
    // Pixel centres, exact: x + 0.5 + j and y + 0.5. The multipliers, which have room,
    // take the shifts (`imul_hi_u` by 2^16 is a shift right by 16) off the adders.
    let x = b.and(pos0, low16);
    let x = match offset {
        Some(o) => b.iadd(x, o),
        None => x,
    };
    let fx0 = b.itof(x);
    let fx0 = b.fadd(fx0, half);
    let y = b.op(Op::IMulHiU, &[pos0, up16]);
    let fy = b.itof(y);
    let fy = b.fadd(fy, half);
    let x1 = {
        let h = b.imul(hi, up16);
        b.op(Op::IMulHiU, &[h, up16])
    };
    let room = b.isub(x1, x);
    let addr0 = {
        let r = b.imul(y, width);
        b.iadd(r, x)
    };
    for j in 0..XYRAST_RUN {
        let (fx, addr, mut inside) = if j == 0 && !ordered {
            (fx0, addr0, None)
        } else {
            let ij = b.i32(j as i32);
            let (fx, addr) = if j == 0 {
                (fx0, addr0)
            } else {
                let fj = b.f32(j as f32);
                (b.fadd(fx0, fj), b.iadd(addr0, ij))
            };
            // Pixel j of the run is in the box while j <= x1 - x (always the first pixel
            // of a run, unless the clusters share the run).
            let in_box = b.ile(ij, room);
            (fx, addr, Some(b.cast(in_box, Ty::I32)))
        };
        let mut e_values = [zero_f; 3];
        for (i, e_value) in e_values.iter_mut().enumerate() {
            // B·fy is the same for the run's pixels but is made per pixel: one product
            // read by all of them would have to wait in its register for the last.
            let e = EdgeTest::value(&mut b, std::array::from_fn(|k| coefficient(i, k)), fx, fy);
            *e_value = e;
            let ok = edge_test.passes(&mut b, thresholds[i], e);
            // Bit 0 of a product is the AND of the factors' bits 0.
            let ok = b.cast(ok, Ty::I32);
            inside = Some(match inside {
                None => ok,
                Some(v) => b.imul(v, ok),
            });
        }
        let covered = b.cast(inside.expect("three edges"), Ty::Cc);
        b.write_if(addr_out, covered, addr);
        b.write_if(tri_out, covered, tri);
        for (&s, e) in e_out.iter().zip(e_values) {
            b.write_if(s, covered, e);
        }
    }
    b.end_loop();
    let mut nulls = vec![(addr_out, shape.trash()), (tri_out, 0)];
    nulls.extend(e_out.iter().map(|&s| (s, 0)));
    null_row(&mut b, &nulls);
    Ok(finish(b))
}

/// The coverage test of an edge value under OpenGL's rules (`xyrast`, `spanrast`): top-left
/// edges pass at E >= 0, the others at E > 0 — as one compare, E > -2^-149 (the negative
/// subnormal next to -0) or E > +0. Flushing inputs to zero would turn the first into
/// E > 0, so such machines select between two compares instead.
pub(crate) struct EdgeTest {
    flush: bool,
    zero_f: Value,
    below_zero: Value,
    zero_word: Value,
}

impl EdgeTest {
    /// Before the loop (`zero_f` is +0.0).
    pub(crate) fn new(b: &mut KernelBuilder, desc: &MachineDesc, zero_f: Value) -> EdgeTest {
        EdgeTest {
            flush: desc.arithmetic.flush_to_zero,
            zero_f,
            below_zero: b.word(0x8000_0001),
            zero_word: b.word(0),
        }
    }

    /// The three edges' thresholds from a tag's top-left flags (bits `TRI_BITS + i`).
    pub(crate) fn thresholds(&self, b: &mut KernelBuilder, tag: Value) -> Vec<Value> {
        (0..3)
            .map(|i| {
                let shift = b.i32((TRI_BITS + i) as i32);
                let top_left = b.shr(tag, shift);
                let top_left = b.cast(top_left, Ty::Cc);
                if self.flush {
                    top_left
                } else {
                    let t = b.select(top_left, self.below_zero, self.zero_word);
                    b.cast(t, Ty::F32)
                }
            })
            .collect()
    }

    /// The edge value `E = (A·X + B·Y) + C` of pixel centre `(x, y)`, for `[A, B, C]`,
    /// rounded in this order: the one expression both rasterizers' coverage rests on.
    pub(crate) fn value(b: &mut KernelBuilder, abc: [Value; 3], x: Value, y: Value) -> Value {
        let by = b.fmul(abc[1], y);
        let ax = b.fmul(abc[0], x);
        let s = b.fadd(ax, by);
        b.fadd(s, abc[2])
    }

    /// Whether edge value `e` passes its `threshold` (a condition).
    pub(crate) fn passes(&self, b: &mut KernelBuilder, threshold: Value, e: Value) -> Value {
        if self.flush {
            let positive = b.flt(self.zero_f, e);
            let non_negative = b.fle(self.zero_f, e);
            b.select(threshold, non_negative, positive)
        } else {
            b.flt(threshold, e)
        }
    }
}

/// `1/x` by `steps` Newton–Raphson steps on the multipliers and adders from the bit-level
/// guess ([`RECIPROCAL_GUESS`]).
fn newton_reciprocal(b: &mut KernelBuilder, x: Value, steps: u8) -> Value {
    let magic = b.constant(RECIPROCAL_GUESS, Ty::I32);
    let bits = b.cast(x, Ty::I32);
    let guess = b.isub(magic, bits);
    let mut y = b.cast(guess, Ty::F32);
    let two = b.f32(2.0);
    for _ in 0..steps {
        let xy = b.fmul(x, y);
        let t = b.fsub(two, xy);
        y = b.fmul(y, t);
    }
    y
}

/// `irast`: a fragment's perspective-correct colour (packed RGBA8, alpha 255) and window
/// depth from its edge values and its triangle's interpolation record (gathered from
/// memory by triangle index), and the triangle's primitive number. The barycentrics'
/// `1/ΣE` is the divide unit's, or `newton_steps` Newton–Raphson steps' (the scene's
/// `pipeline.newton_raphson`, at most [`imagine_units::limits::MAX_NEWTON_STEPS`]): fewer cycles where the
/// divider bounds the loop, and colours and varyings a little off (the depth does not use
/// it).
pub fn irast(
    _desc: &MachineDesc,
    varyings: Varyings,
    newton_steps: u8,
) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("irast");
    let e_in: [StreamId; 3] = ["e0", "e1", "e2"].map(|n| b.input(n));
    let interp = b.input("interp");
    let z_out = b.output("z");
    // Frames with a fragment program hand it the interpolated values instead of packing
    // the colour here.
    let (colour_out, varyings_out) = if varyings.fragment_program() {
        (None, Some(b.output("varyings")))
    } else {
        (Some(b.output("colour")), None)
    };
    let prim_out = b.output("prim");
    let (zero_f, half, one_f) = (b.f32(0.0), b.f32(0.5), b.f32(1.0));
    let scale = b.f32(255.0);
    let alpha = b.word(0xFF00_0000);
    b.begin_loop(LoopSpec::OverStream(e_in[0]));
    let e: Vec<Value> = e_in.iter().map(|&s| b.read_f32(s)).collect();
    let rec: Vec<Value> = (0..varyings.interp_words())
        .map(|_| b.read_f32(interp))
        .collect();
    let sum = b.fadd(e[0], e[1]);
    let sum = b.fadd(sum, e[2]);
    let inv = if newton_steps == 0 {
        b.fdiv(one_f, sum)
    } else {
        newton_reciprocal(&mut b, sum, newton_steps)
    };
    let lambda: Vec<Value> = e.iter().map(|&x| b.fmul(x, inv)).collect();
    let weighted = |b: &mut KernelBuilder, w: &[Value], v: [Value; 3]| {
        let a = b.fmul(w[0], v[0]);
        let c = b.fmul(w[1], v[1]);
        let s = b.fadd(a, c);
        let d = b.fmul(w[2], v[2]);
        b.fadd(s, d)
    };
    // z_ndc = ζ + Σ E_k·(z_k − ζ·w_k)/|det| (see the module notes).
    let depth = varyings.depth_words();
    let from_zeta = weighted(&mut b, &e, [rec[depth - 3], rec[depth - 2], rec[depth - 1]]);
    let z_ndc = if varyings.reference_depth {
        b.fadd(rec[0], from_zeta)
    } else {
        from_zeta
    };
    let z = b.fmul(z_ndc, half);
    let z = b.fadd(z, half);
    let channel = |b: &mut KernelBuilder, ch: usize| {
        let corners = std::array::from_fn(|k| rec[depth + 3 * k + ch]);
        let c = weighted(b, &lambda, corners);
        let c = b.fmax(c, zero_f);
        b.fmin(c, one_f)
    };
    if let Some(out) = colour_out {
        let mut colour = alpha;
        for ch in 0..3 {
            let c = channel(&mut b, ch);
            colour = or_channel(&mut b, colour, c, ch, (half, scale));
        }
        b.write(z_out, z);
        b.write(out, colour);
    }
    if let Some(out) = varyings_out {
        b.write(z_out, z);
        let channels: Vec<Value> = (0..3).map(|ch| channel(&mut b, ch)).collect();
        for &c in &channels {
            b.write(out, c);
        }
        let n = varyings.extras;
        let extras: Vec<Value> = (0..n)
            .map(|ch| {
                let corners = std::array::from_fn(|k| rec[varyings.extras_at() + n * k + ch]);
                weighted(&mut b, &lambda, corners)
            })
            .collect();
        for &v in &extras {
            b.write(out, v);
        }
        if varyings.derivatives {
            // ∂s/∂X = (Σs·A − s·ΣA)/ΣE, and so on (4 multiplies and 4 subtracts, then the
            // 4 multiplies by 1/ΣE).
            let sums = varyings.extras_at() + 3 * n;
            let (sum_a, sum_b) = (rec[sums], rec[sums + 1]);
            for (ch, &value) in extras[..2].iter().enumerate() {
                for (k, total) in [sum_a, sum_b].into_iter().enumerate() {
                    let p = b.fmul(value, total);
                    let d = b.fsub(rec[sums + 2 + 2 * ch + k], p);
                    let d = b.fmul(d, inv);
                    b.write(out, d);
                }
            }
        }
    }
    b.write(prim_out, rec[varyings.prim_at()]);
    b.end_loop();
    Ok(finish(b))
}

/// Bits of a pixel's x and y the composite's hash keeps: a 32×32 stamp.
pub const STAMP_BITS: u32 = 5;
/// Scratchpad words of the stamp (one per y row, a bit per x), and the row null fragments
/// use, which no pixel shares.
const STAMP_ROWS: u16 = 1 << STAMP_BITS;
const NULL_KEY: i32 = (STAMP_ROWS as i32) << STAMP_BITS;
/// The stamp row of pixel (x, y) is `(y + ⌊STAMP_SKEW · x / 32⌋) mod 32`: see [`hash`].
pub const STAMP_SKEW: u32 = 5;

/// `(m, s)` such that `⌊n / d⌋ = ⌊n·m / 2^32⌋ >> s` for every `n < 2^31`, for a divisor
/// `d ≥ 3` that is not a power of two (Granlund and Montgomery, "Division by Invariant
/// Integers using Multiplication", PLDI 1994): with `s = ⌊log2 d⌋` and
/// `m = ⌈2^(32+s) / d⌉ < 2^32`, the error `n·(m·d − 2^(32+s)) / (d·2^(32+s))` is below
/// `n / 2^(32+s) < 1/d`, too small to carry `n / d` past the next integer.
pub fn reciprocal(d: u32) -> (u32, u32) {
    debug_assert!(d >= 3 && !d.is_power_of_two());
    let s = 31 - d.leading_zeros();
    let m = (1u64 << (32 + s)).div_ceil(u64::from(d));
    (m as u32, s)
}

/// `hash`: the composite's conflict test (Owens et al., "Polygon Rendering on a Stream
/// Architecture", Graphics Hardware 2000). A fragment conflicts when an earlier fragment of
/// the same round (earlier in the stream) has the same key, a hash of its pixel's x and y:
/// the two might read and write back the same pixel. Outputs:
/// `conflict`, unconditional: 1 for such a fragment (it waits for the next round), else 0;
/// after the loop, `32 / C − 1` rows of zeros (so that [`sort32`](super::mergefrag::sort32)
/// can read the flags in whole groups of 32), and `count`: a row of the number of
/// conflicts (the same word in every cluster), for the host. Null fragments (the trash
/// pixel) never conflict.
///
/// The key of pixel (x, y) is row `(y + ⌊5x / 32⌋) mod 32`, bit `x mod 32` of a 32×32
/// stamp ([`STAMP_SKEW`] = 5). Within a 32×32 window the keys are those of the low five
/// bits of x and y, all different; the skew makes pixels `32m` apart in x alias only
/// `d ≡ −5m (mod 32)` rows apart, so that the pixels of a long span (one row of a wide
/// triangle, or a strip of thin ones a few rows tall) do not alias: the nearest aliases
/// in a strip are 416 pixels apart one row up and 192 apart two rows up. (With a skew of
/// 1, pixels 32 apart one row up alias, and RATE-2 and RATE-4 need recycle rounds; on
/// gold8 a skew of 5 took RATE-4 from 9,946 rounds to 6,075, as many as its chunks.) Each cluster keeps the stamp of its own earlier fragments in
/// its scratchpad (one word per row), cleared before the loop. An iteration rotates
/// every cluster's key past every other cluster (`C − 1` comms); each cluster looks the
/// keys up in its stamp, adds "the same key as mine, and I come first", and rotates the
/// answers back (`C − 1` comms). Then each cluster stamps its own key. The pixel's x and y
/// come from its address `y·W + x` by a multiply by the reciprocal of `W`.
///
/// Needs a power-of-two cluster count (the conflicts are counted by butterfly exchanges)
/// and a scratchpad that holds the stamp.
pub fn hash(desc: &MachineDesc, shape: FrameShape) -> Result<Kernel, MachineRequirementError> {
    let needs = Needs::new("hash", desc);
    needs.power_of_two_clusters(None)?;
    needs.scratchpad_words(usize::from(STAMP_ROWS) + 1, "the stamp", false)?;
    let c = desc.cluster.count;
    let mut b = KernelBuilder::new("hash");
    let addr_in = b.input("addr");
    let conflict_out = b.output("conflict");
    let count_out = b.output("count");
    let (zero, one) = (b.i32(0), b.i32(1));
    let low = b.i32((1 << STAMP_BITS) - 1);
    let row_words = b.i32(1 << STAMP_BITS);
    // `mulhi(v, 2^(32 − 5))` is `v >> 5`.
    let key_to_row = b.word(1 << (32 - STAMP_BITS));
    // `mulhi(x, SKEW · 2^(32 − 5))` is `⌊SKEW · x / 32⌋`.
    let skew_of_x = b.word(STAMP_SKEW << (32 - STAMP_BITS));
    let null_key = b.i32(NULL_KEY);
    let trash = b.i32(shape.trash() as i32);
    let width = b.i32(shape.width as i32);
    for row in 0..=STAMP_ROWS {
        b.sp_write(row, None, zero);
    }
    // Rotation t brings cluster (c + t) mod C's key to cluster c, which comes first when
    // c + t < C.
    let lane = b.cluster_id();
    let first: Vec<Value> = (1..c)
        .map(|t| {
            let bound = b.i32((c - t) as i32);
            let before = b.ilt(lane, bound);
            flag(&mut b, before)
        })
        .collect();
    b.begin_loop(LoopSpec::OverStream(addr_in));
    let count0 = b.carried(zero);
    let n = b.read_i32(addr_in);
    let y = if shape.width.is_power_of_two() {
        let s = b.i32(shape.width.trailing_zeros() as i32);
        b.shr(n, s)
    } else {
        let (m, s) = reciprocal(shape.width);
        let m = b.word(m);
        let s = b.i32(s as i32);
        let q = b.op(Op::IMulHiU, &[n, m]);
        b.shr(q, s)
    };
    let row_start = b.imul(y, width);
    let x = b.isub(n, row_start);
    // Shifts by a constant are multiplies where they can be: the adders are the busier.
    let key = {
        let span = b.op(Op::IMulHiU, &[x, skew_of_x]);
        let ky = b.iadd(y, span);
        let ky = b.and(ky, low);
        let ky = b.imul(ky, row_words);
        let kx = b.and(x, low);
        b.or(ky, kx)
    };
    let valid = b.ine(n, trash);
    let key = b.select(valid, key, null_key);
    let row_of = |b: &mut KernelBuilder, key: Value| b.op(Op::IMulHiU, &[key, key_to_row]);
    let row = row_of(&mut b, key);
    // `shr` by a key shifts by its low five bits, the x: bit 0 is then the key's stamp bit.
    let mine = b.sp_read(0, Some(row));
    let mut conflict = b.shr(mine, key);
    for t in 1..c {
        let other = b.comm(key, Perm::Rotate(t as u16));
        let other_row = row_of(&mut b, other);
        let stamped = b.sp_read(0, Some(other_row));
        let seen = b.shr(stamped, other);
        let same = b.ieq(other, key);
        let before = b.select(same, first[t - 1], zero);
        let answer = b.or(seen, before);
        let back = b.comm(answer, Perm::Rotate((c - t) as u16));
        conflict = b.or(conflict, back);
    }
    let bit = b.shl(one, key);
    let stamped = b.or(mine, bit);
    b.sp_write(0, Some(row), stamped);
    let conflict = b.and(conflict, one);
    let conflict = b.select(valid, conflict, zero);
    b.write(conflict_out, conflict);
    let count = b.iadd(count0, conflict);
    b.set_next(count0, count);
    b.end_loop();
    for _ in 1..crate::kernels::sort32::CHUNK / c {
        b.write(conflict_out, zero);
    }
    let total = all_reduce(&mut b, c, count0, KernelBuilder::iadd);
    b.write(count_out, total);
    Ok(finish(b))
}

/// `zcompare`: the scene's depth test (LESS, LEQUAL or ALWAYS) of a fragment against its
/// pixel (colour, depth, primitive), gathered from the framebuffer. A fragment `hash` found
/// in conflict waits for the next round; any other passes if its depth is in [0, 1] and it
/// wins against the pixel in OpenGL's primitive order: LESS — a smaller depth, or an equal
/// one with an earlier primitive (the later of two equal depths fails LESS); LEQUAL — a
/// smaller depth, or an equal one with a later primitive; ALWAYS — a later primitive. Each
/// test is an extremum over (depth, primitive), so the order in which the rounds reach a
/// pixel does not change the result. A blending frame's fragment that passes writes its
/// colour blended over the pixel's (`blend`), which does depend on the order: a blending
/// frame keeps it from `xyrast` on (see [`xyrast`]). Outputs,
/// unconditional: the pixel to write back (3 words) and where (`newaddr`: the fragment's
/// pixel if it passed, else the trash pixel).
pub fn zcompare(_desc: &MachineDesc, shape: FrameShape) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("zcompare");
    let z_in = b.input("z");
    let colour_in = b.input("colour");
    let addr_in = b.input("addr");
    let prim_in = b.input("prim");
    let pixel_in = b.input("pixel");
    let conflict_in = b.input("conflict");
    let pixel_out = b.output("new_pixel");
    let newaddr_out = b.output("newaddr");
    let trash = b.i32(shape.trash() as i32);
    let past_one = b.word(1.0f32.to_bits() + 1);
    b.begin_loop(LoopSpec::OverStream(z_in));
    let z = b.read(z_in);
    let colour = b.read(colour_in);
    let addr = b.read_i32(addr_in);
    let prim = b.read_i32(prim_in);
    let old: Vec<Value> = (0..PIXEL_WORDS).map(|_| b.read(pixel_in)).collect();
    let (old_colour, old_z, old_prim) = (old[0], old[1], old[2]);
    let conflict = b.read_i32(conflict_in);
    // The framebuffer holds only depths in [+0, 1], whose words order like the depths;
    // every other word (negative, above 1, NaN) is above 1.0's and so never less than the
    // pixel's nor equal to it. (depth, primitive) then compare as a pair of unsigned words.
    // A pixel never drawn has primitive 0, which no fragment precedes.
    let wins = match shape.depth_test {
        DepthTest::Less | DepthTest::Lequal => {
            let less = b.iltu(z, old_z);
            let equal = b.ieq(z, old_z);
            let tie = match shape.depth_test {
                DepthTest::Less => b.iltu(prim, old_prim),
                _ => b.iltu(old_prim, prim),
            };
            let less = flag(&mut b, less);
            let tie = flag(&mut b, tie);
            b.select(equal, tie, less)
        }
        DepthTest::Always => {
            let in_range = b.iltu(z, past_one);
            let later = b.iltu(old_prim, prim);
            let in_range = flag(&mut b, in_range);
            let later = flag(&mut b, later);
            b.and(in_range, later)
        }
    };
    // Both 0 or 1: passes when it wins and does not conflict.
    let pass = b.ilt(conflict, wins);
    let colour = blend(&mut b, shape.blend, colour, old_colour);
    let new = [
        b.select(pass, colour, old_colour),
        b.select(pass, z, old_z),
        b.select(pass, prim, old_prim),
    ];
    for w in new {
        b.write(pixel_out, w);
    }
    let where_ = b.select(pass, addr, trash);
    b.write(newaddr_out, where_);
    b.end_loop();
    Ok(finish(b))
}

/// The colour a fragment `src` leaves on a pixel `dst` (both packed RGBA8) under `mode`,
/// each of the four channels (alpha too, as OpenGL blends an RGBA buffer) in integers:
/// `alpha` (`GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA`) is `round((s·a + d·(255 − a)) / 255)`,
/// with `round(x / 255) = (x + 128 + ((x + 128) >> 8)) >> 8` exact for `x ≤ 255²` (and no
/// ties: 255 is odd); `add` (`GL_ONE, GL_ONE`) is `min(s + d, 255)`.
fn blend(b: &mut KernelBuilder, mode: Blend, src: Value, dst: Value) -> Value {
    if mode == Blend::None {
        return src;
    }
    let byte = b.i32(0xFF);
    let (eight, half) = (b.i32(8), b.i32(128));
    let channel = |b: &mut KernelBuilder, word: Value, k: i32| {
        let shift = b.i32(8 * k);
        let v = b.shr(word, shift);
        b.and(v, byte)
    };
    let alpha = channel(b, src, 3);
    let keep = b.isub(byte, alpha);
    let mut out = None;
    for k in 0..4 {
        let (s, d) = (channel(b, src, k), channel(b, dst, k));
        let c = match mode {
            Blend::Add => {
                let sum = b.iadd(s, d);
                b.imin(sum, byte)
            }
            _ => {
                let sa = b.imul(s, alpha);
                let dk = b.imul(d, keep);
                let x = b.iadd(sa, dk);
                let x = b.iadd(x, half);
                let high = b.shr(x, eight);
                let x = b.iadd(x, high);
                b.shr(x, eight)
            }
        };
        let shift = b.i32(8 * k);
        let c = b.shl(c, shift);
        out = Some(match out {
            None => c,
            Some(w) => b.or(w, c),
        });
    }
    out.expect("four channels")
}

/// `compact_recycle`: keeps the words of streams `a` and `b` whose `conflict` flag is set,
/// in order, then a row of nulls (`nulls`): the fragments `hash` held back, for the next
/// round.
pub fn compact_recycle(
    _desc: &MachineDesc,
    nulls: [u32; 2],
) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("compact_recycle");
    let conflict_in = b.input("conflict");
    let a_in = b.input("a");
    let b_in = b.input("b");
    let a_out = b.output("a_kept");
    let b_out = b.output("b_kept");
    b.begin_loop(LoopSpec::OverStream(conflict_in));
    let conflict = b.read_i32(conflict_in);
    let a = b.read(a_in);
    let c = b.read(b_in);
    let keep = cond(&mut b, conflict);
    b.write_if(a_out, keep, a);
    b.write_if(b_out, keep, c);
    b.end_loop();
    null_row(&mut b, &[(a_out, nulls[0]), (b_out, nulls[1])]);
    Ok(finish(b))
}
