//! The kernels of the Reyes pipeline (Owens et al. 2002 §4; thesis §8.2), built with the
//! kernel builder and compiled to microcode like every other kernel.
//!
//! | kernel | per element | streams |
//! |---|---|---|
//! | [`project`] | patch: its 16 control points to window space | patches ([`PATCH_WORDS`]) → patches |
//! | [`subdiv_split`] | patch: its four children (a breadth-first level) | patches → 4 patches |
//! | [`subdiv`] | iteration: one quad of a depth-first walk of each cluster's patch | resume ([`STATE_WORDS`]), patches, tickets → quads ([`SUBDIV_QUAD_WORDS`]), state |
//! | [`shade`] | quad: its colour from the material ([`Shading`]) | quads → shaded ([`QUAD_WORDS`]), varyings (textured, marble) |
//! | [`sample`] | quad: the pixel centres of its box against its four edges | quads → addr, z, colour (conditional), covered |
//!
//! **Records.** A patch record is the 16 Bezier control points, row by row with u fastest
//! (`x, y, z` each: object space into `project`, window space out of it: x, y in pixels, z
//! the window depth `(z_ndc + 1)/2`), then its colour (packed RGBA8) and 1 for a patch, 0
//! for padding. A quad record is: flags (bit 0 a quad, bit 1 the stack overflowed), its
//! subdivision level, its four edge equations `A, B, C` (`E = A·x + B·y + C ≥ 0` inside),
//! its corners' box `x0, y0, x1, y1`, its depth and its colour.
//!
//! **Choices the papers leave open** (documented here and in the README):
//!
//! * *Bezier subdivided directly*: de Casteljau halving in u and in v gives the four
//!   children's 4×4 nets; a Bezier patch interpolates its corners, so a quad's corners are
//!   points of the (window-space) surface. The teapot is Bezier; the papers' Catmull-Clark
//!   refinement of B-spline neighbourhoods is not built.
//! * *Window space*: the control points are projected once and subdivided as a polynomial
//!   patch in window coordinates (the papers' "subdivision in screen space"); this is the
//!   projected surface's approximation, not the rational patch (exact only for an affine
//!   camera).
//! * *Edge equations*: fp32 `A, B, C` of the line through the edge's two corners, computed
//!   from the corners in a canonical order (the lexicographically smaller `(x, y)` first)
//!   and negated for the other direction, so the two quads that share an edge hold exactly
//!   opposite equations (negation is exact) and each pixel centre on the line goes to one
//!   of them (the tie rule in [`sample`]). Lengths are the corners' distance, compared
//!   squared with the stop length squared, the same from both sides.
//! * *Edge freezing*: a child's side that lies on its parent's side inherits the parent's
//!   equation if the parent's was frozen; otherwise it is frozen when its length falls
//!   below the stop length. A quad is done when all four are frozen. A shared patch
//!   boundary is halved by the same arithmetic from both sides (the midpoint is
//!   commutative, so a reversed curve splits into the mirrored halves bit for bit).
//! * *Orientation*: a quad's equations are signed so that its inside is positive, by the
//!   sign of the cross product of its corner diagonals (back faces are kept: the scene's
//!   cull mode is not applied to quads).
//! * *Depth per sample*: the quad's, the mean of its corners' window depths (flat, as the
//!   colour).
//! * *Colour of a quad*: one per quad, flat ([`shade`]): its patch's colour for an unlit
//!   material, lit at its centre for a lit one, or the material's fragment program's on
//!   the quad's `varyings` record (textured, marble).
//! * *Patch-to-cluster mapping*: patch `p` of a group of `C` runs in cluster `p mod C`,
//!   one patch per cluster until it is done (the walk's stack is the cluster's).
//! * *Stack*: depth-first, in the scratchpad: a frame per quad with children left to
//!   visit (its net, its edges, its frozen mask, the next child, its level); the last
//!   child replaces its parent's frame instead of being pushed on it. [`STACK_FRAMES`]
//!   frames fit 512 words; a push past them sets the overflow flag, which the host turns
//!   into an error naming `subdiv` and the scratchpad.
//! * *Resuming*: a call runs one iteration per ticket (one quad per cluster) and writes its
//!   stack out (`state`); the next call reads it back (`resume`). So the host bounds the
//!   SRF a call's quads take, and calls again until every cluster's stack is empty.

use imagine_units::desc::MachineDesc;

use crate::kernel::{Kernel, KernelBuilder, LoopSpec, MachineRequirementError, Needs, Ty, Value};
use crate::opengl::kernels::{NULL_DEPTH, null_row};

/// Words of a patch record: 16 points × 3, colour, active.
pub const PATCH_WORDS: usize = 50;
const COLOUR_AT: usize = 48;
const ACTIVE_AT: usize = 49;

/// Words of a quad record.
pub const QUAD_WORDS: usize = 20;
/// Where the words of a quad record are.
pub const Q_FLAGS: usize = 0;
pub const Q_LEVEL: usize = 1;
pub const Q_EDGES: usize = 2;
pub const Q_BOX: usize = 14;
pub const Q_DEPTH: usize = 18;
pub const Q_COLOUR: usize = 19;
/// Words of a quad record as `subdiv` writes it: a quad record, then its four corners
/// (`x, y, z` in window space each, in the edges' order) for [`shade`], which writes
/// [`QUAD_WORDS`]-word records without them.
pub const SUBDIV_QUAD_WORDS: usize = QUAD_WORDS + 12;
pub const Q_CORNERS: usize = QUAD_WORDS;

/// The shape of a frame's patch, stack-frame and `subdiv` quad records. With `places`
/// (frames whose material is textured) each of them carries one more word, last: its
/// *place*, where it lies in its patch's parameter square, `u_i | v_i << 16` with `(u_i,
/// v_i)` its cell on the grid of `2^level` cells a side (a root patch is cell (0, 0) at
/// level 0; child (row, col) of cell `(u, v)` is `(2u + col, 2v + row)`), from which
/// [`shade`] finds the texture coordinates `(s, t) = (u, v)` of the quad's centre. Without
/// them the records and every kernel's microcode are those of an untextured frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Records {
    pub places: bool,
}

impl Records {
    /// Words of a patch record: [`PATCH_WORDS`], then the place.
    pub const fn patch_words(self) -> usize {
        PATCH_WORDS + self.places as usize
    }

    /// Words of a stack frame: [`FRAME_WORDS`], then the place.
    pub const fn frame_words(self) -> usize {
        FRAME_WORDS + self.places as usize
    }

    /// Words of a cluster's saved walk ([`STATE_WORDS`] with these frames).
    pub const fn state_words(self) -> usize {
        STACK_FRAMES * self.frame_words() + 3
    }

    /// Words of a quad record as `subdiv` writes it: [`SUBDIV_QUAD_WORDS`], then the place.
    pub const fn subdiv_quad_words(self) -> usize {
        SUBDIV_QUAD_WORDS + self.places as usize
    }
}

/// The deepest level a place can name: 15 bits a coordinate (a level-15 cell is a
/// 32,768th of its patch's side, far below a pixel for any patch a window can hold).
pub const MAX_PLACE_LEVEL: usize = 15;
/// Bits of a quad record's flags.
pub const FLAG_QUAD: u32 = 1;
pub const FLAG_OVERFLOW: u32 = 2;

/// Words of a stack frame: net (48), edges (12), frozen mask, next child, level.
pub const FRAME_WORDS: usize = 63;
const F_EDGES: usize = 48;
const F_MASK: usize = 60;
const F_NEXT: usize = 61;
const F_LEVEL: usize = 62;
/// A frame's place, in frames of [`Records::places`].
const F_PLACE: usize = FRAME_WORDS;
/// Frames of the stack: 7 live frames and a spare that takes the writes of iterations
/// that push nothing (`8 × 63 = 504` of 512 words).
pub const STACK_FRAMES: usize = 7;
const SLOTS: usize = STACK_FRAMES + 1;

/// Words of a cluster's saved walk: depth, flags (bit 0 the stack overflowed, bit 1
/// [`STARTED`]), colour, then the frames. All zeros is a walk not started: the first call
/// takes its patch.
pub const STATE_WORDS: usize = STACK_FRAMES * FRAME_WORDS + 3;

/// A saved walk's flag: its patch was taken (a walk whose stack is empty is done, not
/// fresh).
pub const STARTED: u32 = 2;

/// The margin (pixels) around a quad's corner box in which [`sample`] tests pixel
/// centres: a quad's region is bounded by its edge lines, which may come from coarser
/// levels and so pass a little outside its current corners.
pub const BOX_MARGIN: f32 = 0.25;

/// Pixel centres per axis [`sample`] tests for a stop length: a quad's sides are shorter
/// than `stop`, so its corners span less than `2·stop`, plus the margins.
pub fn stamp(stop: f32) -> usize {
    (2.0 * stop + 2.0 * BOX_MARGIN).floor() as usize + 1
}

/// The largest stop length the sampler is built for (a stamp of 16×16 centres).
pub const MAX_STOP_LENGTH: f32 = 7.0;

/// A condition as an int32 flag (a compare's result is 1 or 0: the same word).
fn flag(b: &mut KernelBuilder, cc: Value) -> Value {
    b.cast(cc, Ty::I32)
}

/// An int32 flag (1 or 0) as a condition.
fn cond(b: &mut KernelBuilder, flag: Value) -> Value {
    b.cast(flag, Ty::Cc)
}

/// Flags `a AND b`, `a OR b`, `NOT a` (flags are 1 or 0).
fn both(b: &mut KernelBuilder, x: Value, y: Value) -> Value {
    let (x, y) = (flag(b, x), flag(b, y));
    b.and(x, y)
}

fn either(b: &mut KernelBuilder, x: Value, y: Value) -> Value {
    let (x, y) = (flag(b, x), flag(b, y));
    b.or(x, y)
}

fn negate(b: &mut KernelBuilder, x: Value) -> Value {
    let x = flag(b, x);
    let one = b.i32(1);
    b.xor(x, one)
}

fn finish(b: KernelBuilder) -> Kernel {
    match b.finish() {
        Ok(k) => k,
        Err(e) => panic!("Reyes kernel does not verify: {e}"),
    }
}

/// `project`: each patch's control points through the model-view-projection matrix
/// (params `m0..m15`, row-major) to window space: `x = (x_c/w_c + 1)·W/2`, `y = (y_c/w_c
/// + 1)·H/2`, `z = (z_c/w_c + 1)/2`, one reciprocal of `w` per point. The colour and the
/// active word pass through. Points with `w ≤ 0` (behind the eye) are not clipped.
pub fn project(_desc: &MachineDesc, records: Records) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("project");
    let input = b.input("patches");
    let output = b.output("window");
    let m: [Value; 16] = std::array::from_fn(|i| b.param_f32(&format!("m{i}")));
    let half_w = b.param_f32("half_width");
    let half_h = b.param_f32("half_height");
    let (one, half) = (b.f32(1.0), b.f32(0.5));
    b.begin_loop(LoopSpec::OverStream(input));
    let words: Vec<Value> = (0..records.patch_words())
        .map(|_| b.read_f32(input))
        .collect();
    for k in 0..16 {
        let p = [words[3 * k], words[3 * k + 1], words[3 * k + 2]];
        let clip: [Value; 4] = std::array::from_fn(|row| {
            let r = &m[4 * row..4 * row + 4];
            let mx = b.fmul(r[0], p[0]);
            let my = b.fmul(r[1], p[1]);
            let s = b.fadd(mx, my);
            let mz = b.fmul(r[2], p[2]);
            let s = b.fadd(s, mz);
            b.fadd(s, r[3])
        });
        let rw = b.fdiv(one, clip[3]);
        for (axis, scale) in [(0, half_w), (1, half_h), (2, half)] {
            let ndc = b.fmul(clip[axis], rw);
            let shifted = b.fadd(ndc, one);
            let v = b.fmul(shifted, scale);
            b.write(output, v);
        }
    }
    for &w in &words[COLOUR_AT..] {
        b.write(output, w);
    }
    b.end_loop();
    Ok(finish(b))
}

/// The place of child `(row, col)` of `place` (see [`Records`]): `place << 1 | col |
/// row << 16`, `row` and `col` 0 or 1.
fn child_place(b: &mut KernelBuilder, place: Value, row: Value, col: Value) -> Value {
    let one = b.i32(1);
    let sixteen = b.i32(16);
    let doubled = b.shl(place, one);
    let with_col = b.or(doubled, col);
    let row_bit = b.shl(row, sixteen);
    b.or(with_col, row_bit)
}

/// `subdiv_split`: every patch split into its four children (de Casteljau halving in u
/// and v), children in the order (row half, column half) = (0,0), (0,1), (1,0), (1,1): a
/// breadth-first level before `subdiv`'s depth-first walk, so that a walk needs fewer
/// stack frames (and the clusters get more, smaller patches to share). Edges are not
/// frozen here: a patch side already shorter than the stop length is split too (both
/// patches that share it split it the same way, so no crack opens; only quads are spent).
pub fn subdiv_split(
    _desc: &MachineDesc,
    records: Records,
) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("subdiv_split");
    let input = b.input("patches");
    let output = b.output("children");
    let half = b.f32(0.5);
    let (zero, one) = (b.i32(0), b.i32(1));
    let halves = [b.ine(zero, zero), b.ieq(one, one)];
    b.begin_loop(LoopSpec::OverStream(input));
    let words: Vec<Value> = (0..records.patch_words()).map(|_| b.read(input)).collect();
    let net: [P3; 16] =
        std::array::from_fn(|k| std::array::from_fn(|c| b.cast(words[3 * k + c], Ty::F32)));
    for row in 0..2 {
        for col in 0..2 {
            let child = quadrant(&mut b, half, &net, halves[row], halves[col]);
            for p in &child {
                for &v in p {
                    b.write(output, v);
                }
            }
            b.write(output, words[COLOUR_AT]);
            b.write(output, words[ACTIVE_AT]);
            if records.places {
                let place = b.cast(words[PATCH_WORDS], Ty::I32);
                let bits = [zero, one];
                let child = child_place(&mut b, place, bits[row], bits[col]);
                b.write(output, child);
            }
        }
    }
    b.end_loop();
    Ok(finish(b))
}

/// A point of a net: x, y, z.
type P3 = [Value; 3];

/// `(a + b)·0.5`, per coordinate (commutative, so a reversed curve splits the same).
fn mid(b: &mut KernelBuilder, half: Value, p: P3, q: P3) -> P3 {
    std::array::from_fn(|c| {
        let s = b.fadd(p[c], q[c]);
        b.fmul(s, half)
    })
}

/// One half of a cubic Bezier curve by de Casteljau: the first half where `second` is
/// false, the second where it holds.
fn half_curve(b: &mut KernelBuilder, half: Value, second: Value, p: [P3; 4]) -> [P3; 4] {
    let m01 = mid(b, half, p[0], p[1]);
    let m12 = mid(b, half, p[1], p[2]);
    let m23 = mid(b, half, p[2], p[3]);
    let m012 = mid(b, half, m01, m12);
    let m123 = mid(b, half, m12, m23);
    let m = mid(b, half, m012, m123);
    let first = [p[0], m01, m012, m];
    let last = [m, m123, m23, p[3]];
    std::array::from_fn(|i| std::array::from_fn(|c| b.select(second, last[i][c], first[i][c])))
}

/// Child `(row_half, col_half)` of a net (`net[4·row + col]`): each row halved in u, then
/// each column in v.
fn quadrant(
    b: &mut KernelBuilder,
    half: Value,
    net: &[P3; 16],
    row_half: Value,
    col_half: Value,
) -> [P3; 16] {
    let mut rows = [[[half; 3]; 4]; 4];
    for (r, row) in rows.iter_mut().enumerate() {
        *row = half_curve(b, half, col_half, std::array::from_fn(|c| net[4 * r + c]));
    }
    let mut out = [[half; 3]; 16];
    for c in 0..4 {
        let col = half_curve(b, half, row_half, std::array::from_fn(|r| rows[r][c]));
        for r in 0..4 {
            out[4 * r + c] = col[r];
        }
    }
    out
}

/// The corners of a net in edge order: (0,0), (0,3), (3,3), (3,0); edge `k` runs from
/// corner `k` to corner `k + 1`.
fn corners(net: &[P3; 16]) -> [P3; 4] {
    [net[0], net[3], net[15], net[12]]
}

/// The line through `a` and `b` as `[A, B, C]`, positive left of `a → b` (x right, y up),
/// computed in the canonical order of the two points so that `b → a` gives exactly the
/// negated equation.
fn edge_equation(b: &mut KernelBuilder, a: P3, e: P3) -> [Value; 3] {
    let x_lt = b.flt(a[0], e[0]);
    let x_eq = b.feq(a[0], e[0]);
    let y_lt = b.flt(a[1], e[1]);
    let tie = both(b, x_eq, y_lt);
    let forward = either(b, x_lt, tie);
    let forward = cond(b, forward);
    let p: [Value; 2] = std::array::from_fn(|c| b.select(forward, a[c], e[c]));
    let q: [Value; 2] = std::array::from_fn(|c| b.select(forward, e[c], a[c]));
    let ca = b.fsub(p[1], q[1]);
    let cb = b.fsub(q[0], p[0]);
    let t0 = b.fmul(q[1], p[0]);
    let t1 = b.fmul(q[0], p[1]);
    let cc = b.fsub(t0, t1);
    [ca, cb, cc].map(|v| {
        let n = b.fneg(v);
        b.select(forward, v, n)
    })
}

/// Whether the side `a → e` is shorter than the stop length (squared lengths compared).
fn short_side(b: &mut KernelBuilder, stop2: Value, a: P3, e: P3) -> Value {
    let dx = b.fsub(e[0], a[0]);
    let dy = b.fsub(e[1], a[1]);
    let xx = b.fmul(dx, dx);
    let yy = b.fmul(dy, dy);
    let l2 = b.fadd(xx, yy);
    b.flt(l2, stop2)
}

/// What a quad's test gives: its edges, frozen mask and whether it is done.
struct Tested {
    edges: [[Value; 3]; 4],
    mask: Value,
    done: Value,
}

/// Tests a quad with corners `c`: edge `k` keeps `inherited[k]` (a frozen parent edge it
/// lies on) where `inherit[k]` holds, else is frozen when shorter than the stop length.
fn test_quad(
    b: &mut KernelBuilder,
    stop2: Value,
    c: [P3; 4],
    inherit: [Option<(Value, [Value; 3])>; 4],
) -> Tested {
    let zero = b.i32(0);
    let mut mask = zero;
    let mut all = None;
    let mut edges = [[zero; 3]; 4];
    for k in 0..4 {
        let (a, e) = (c[k], c[(k + 1) % 4]);
        let own = edge_equation(b, a, e);
        let short = short_side(b, stop2, a, e);
        let (eq, frozen) = match inherit[k] {
            Some((keep, parent)) => {
                let eq = std::array::from_fn(|i| b.select(keep, parent[i], own[i]));
                (eq, either(b, keep, short))
            }
            None => (own, flag(b, short)),
        };
        let f = frozen;
        let bit = b.i32(k as i32);
        let shifted = b.shl(f, bit);
        mask = b.or(mask, shifted);
        all = Some(match all {
            None => f,
            Some(x) => b.and(x, f),
        });
        edges[k] = eq;
    }
    let all = all.expect("four edges");
    let done = b.ine(all, zero);
    Tested { edges, mask, done }
}

/// The quad record's words other than flags and level: the edges signed so the inside is
/// positive, the corner box, the depth and the colour.
fn quad_words(b: &mut KernelBuilder, c: [P3; 4], edges: &[[Value; 3]; 4]) -> Vec<Value> {
    let d1: [Value; 2] = std::array::from_fn(|i| b.fsub(c[2][i], c[0][i]));
    let d2: [Value; 2] = std::array::from_fn(|i| b.fsub(c[3][i], c[1][i]));
    let u = b.fmul(d1[0], d2[1]);
    let v = b.fmul(d1[1], d2[0]);
    let area = b.fsub(u, v);
    let zero_f = b.f32(0.0);
    let clockwise = b.flt(area, zero_f);
    let mut out = Vec::with_capacity(QUAD_WORDS);
    for eq in edges {
        for &w in eq {
            let n = b.fneg(w);
            out.push(b.select(clockwise, n, w));
        }
    }
    for axis in [0, 1] {
        let lo01 = b.fmin(c[0][axis], c[1][axis]);
        let lo23 = b.fmin(c[2][axis], c[3][axis]);
        let hi01 = b.fmax(c[0][axis], c[1][axis]);
        let hi23 = b.fmax(c[2][axis], c[3][axis]);
        out.push(b.fmin(lo01, lo23));
        out.push(b.fmax(hi01, hi23));
    }
    // [x0, x1, y0, y1] → x0, y0, x1, y1.
    let n = out.len();
    out.swap(n - 3, n - 2);
    let s01 = b.fadd(c[0][2], c[1][2]);
    let s23 = b.fadd(c[2][2], c[3][2]);
    let s = b.fadd(s01, s23);
    let quarter = b.f32(0.25);
    out.push(b.fmul(s, quarter));
    out
}

/// `subdiv`: the depth-first subdivision of one patch per cluster (see the module doc).
///
/// Streams: `resume` (one saved walk per cluster, [`STATE_WORDS`]), `patches` (one
/// window-space patch record per cluster; used by a cluster whose saved walk is empty),
/// `tickets` (one iteration per row). Outputs: `quads`, a [`QUAD_WORDS`] record per
/// cluster per iteration plus one for the root (flag bit 0 marks a finished quad; the
/// others are the walk's inner nodes and idle clusters), and `state`, the walk to resume.
/// Param: `stop2`, the stop length squared.
pub fn subdiv(desc: &MachineDesc, records: Records) -> Result<Kernel, MachineRequirementError> {
    let frame_words = records.frame_words();
    Needs::new("subdiv", desc).scratchpad_words(
        SLOTS * frame_words,
        &format!("a depth-first stack of {STACK_FRAMES} frames of {frame_words} words and a spare"),
        false,
    )?;
    let mut b = KernelBuilder::new("subdiv");
    let resume = b.input("resume");
    let patches = b.input("patches");
    let tickets = b.input("tickets");
    let quads = b.output("quads");
    let state = b.output("state");
    let stop2 = b.param_f32("stop2");
    let half = b.f32(0.5);
    let (zero, one, three) = (b.i32(0), b.i32(1), b.i32(3));
    let frame = b.i32(frame_words as i32);
    let spare = b.i32((STACK_FRAMES * frame_words) as i32);
    let max_depth = b.i32(STACK_FRAMES as i32);

    // ---- Before the loop: the patch's root, then the saved walk back into the
    // scratchpad word by word (the root's frame over slot 0 where the walk is fresh).
    let patch: Vec<Value> = (0..records.patch_words())
        .map(|_| b.read(patches))
        .collect();
    let root_place = records.places.then(|| b.cast(patch[PATCH_WORDS], Ty::I32));
    let saved_depth = b.read_i32(resume);
    let saved_flags = b.read_i32(resume);
    let saved_colour = b.read(resume);
    // A walk never started (the first call) has flags 0; one started, even if done since,
    // has `STARTED` set and keeps its (maybe empty) stack.
    let started = b.i32(STARTED as i32);
    let was_started = b.and(saved_flags, started);
    let fresh = b.ieq(was_started, zero);
    let saved_overflow = b.and(saved_flags, one);
    let active = b.cast(patch[ACTIVE_AT], Ty::I32);
    let active = b.ine(active, zero);
    let start = both(&mut b, fresh, active);
    let start = cond(&mut b, start);
    let root: [P3; 16] =
        std::array::from_fn(|k| std::array::from_fn(|c| b.cast(patch[3 * k + c], Ty::F32)));
    let rc = corners(&root);
    let rt = test_quad(&mut b, stop2, rc, [None; 4]);
    let mut root_words = quad_words(&mut b, rc, &rt.edges);
    root_words.push(patch[COLOUR_AT]);
    // A root already small enough is a quad at level 0; otherwise it is frame 0.
    let root_quad = both(&mut b, start, rt.done);
    let root_quad = cond(&mut b, root_quad);
    let flag_quad = b.i32(FLAG_QUAD as i32);
    let root_flags = b.select(root_quad, flag_quad, zero);
    b.write(quads, root_flags);
    b.write(quads, zero);
    for &w in &root_words {
        b.write(quads, w);
    }
    for v in rc.into_iter().flatten() {
        b.write(quads, v);
    }
    if let Some(place) = root_place {
        b.write(quads, place);
    }
    let root_frame = negate(&mut b, rt.done);
    let root_depth = b.select(start, root_frame, zero);
    let depth0 = b.select(fresh, root_depth, saved_depth);
    let colour0 = b.select(fresh, patch[COLOUR_AT], saved_colour);
    let overflow0 = b.select(fresh, zero, saved_overflow);
    for slot in 0..STACK_FRAMES {
        for i in 0..frame_words {
            let w = b.read(resume);
            let w = if slot == 0 {
                let r = match i {
                    _ if i < F_EDGES => root[i / 3][i % 3],
                    _ if i < F_MASK => rt.edges[(i - F_EDGES) / 3][(i - F_EDGES) % 3],
                    F_MASK => rt.mask,
                    F_PLACE => root_place.expect("a frame with a place"),
                    _ => zero, // next child 0, level 0
                };
                b.select(fresh, r, w)
            } else {
                w
            };
            b.sp_write((slot * frame_words + i) as u16, None, w);
        }
    }

    // ---- The walk: one quad per cluster per iteration.
    b.begin_loop(LoopSpec::OverStream(tickets));
    let depth = b.carried(depth0);
    let overflow = b.carried(overflow0);
    let colour = b.carried(colour0);
    let _ticket = b.read(tickets);
    let idle = b.ieq(depth, zero);
    let top = b.isub(depth, one);
    let top = b.imax(top, zero);
    let base = b.imul(top, frame);
    // The frame's words are read in the order they are used (the scratchpad keeps program
    // order), so that none waits long in its register: the child index and frozen mask,
    // the net, the parent's edges, and its level last.
    let next = b.sp_read(F_NEXT as u16, Some(base));
    let next = b.cast(next, Ty::I32);
    let parent_mask = b.sp_read(F_MASK as u16, Some(base));
    let parent_mask = b.cast(parent_mask, Ty::I32);
    let level = b.sp_read(F_LEVEL as u16, Some(base));
    let level = b.cast(level, Ty::I32);
    let place = records.places.then(|| {
        let w = b.sp_read(F_PLACE as u16, Some(base));
        b.cast(w, Ty::I32)
    });
    let net: [P3; 16] = std::array::from_fn(|k| {
        std::array::from_fn(|c| {
            let w = b.sp_read((3 * k + c) as u16, Some(base));
            b.cast(w, Ty::F32)
        })
    });
    let row_bit = b.shr(next, one);
    let row_bit = b.and(row_bit, one);
    let col_bit = b.and(next, one);
    let row_half = b.ine(row_bit, zero);
    let col_half = b.ine(col_bit, zero);
    let child = quadrant(&mut b, half, &net, row_half, col_half);
    let cc = corners(&child);
    // Edge k of the child lies on its parent's edge k when: 0 (top) in the first row half,
    // 1 (right) in the second column half, 2 (bottom) in the second row half, 3 (left) in
    // the first column half.
    let on_parent = [
        b.ieq(row_bit, zero),
        b.ine(col_bit, zero),
        b.ine(row_bit, zero),
        b.ieq(col_bit, zero),
    ];
    let parent_edges: [[Value; 3]; 4] = std::array::from_fn(|k| {
        std::array::from_fn(|i| {
            let w = b.sp_read((F_EDGES + 3 * k + i) as u16, Some(base));
            b.cast(w, Ty::F32)
        })
    });
    let inherit: [Option<(Value, [Value; 3])>; 4] = std::array::from_fn(|k| {
        let shift = b.i32(k as i32);
        let bit = b.shr(parent_mask, shift);
        let bit = b.and(bit, one);
        let frozen = b.ine(bit, zero);
        let keep = both(&mut b, on_parent[k], frozen);
        let keep = cond(&mut b, keep);
        Some((keep, parent_edges[k]))
    });
    let t = test_quad(&mut b, stop2, cc, inherit);
    let mut qw = quad_words(&mut b, cc, &t.edges);
    qw.push(colour);
    let busy = negate(&mut b, idle);
    let emit = both(&mut b, busy, t.done);
    let emit = cond(&mut b, emit);
    let busy = cond(&mut b, busy);

    // The stack: the parent's next child, then the child's frame where it goes.
    let last = b.ieq(next, three);
    let not_done = negate(&mut b, t.done);
    let split = both(&mut b, busy, not_done);
    let not_last = negate(&mut b, last);
    let push = both(&mut b, split, not_last);
    let room = b.ilt(depth, max_depth);
    let pushed = both(&mut b, push, room);
    let pushed = cond(&mut b, pushed);
    let full = negate(&mut b, room);
    let lost = both(&mut b, push, full);
    let overflow_next = b.or(overflow, lost);
    b.set_next(overflow, overflow_next);
    b.set_next(colour, colour);
    let child_level = b.iadd(level, one);
    let next_child = b.iadd(next, one);
    b.sp_write(F_NEXT as u16, Some(base), next_child);
    // Where the child's frame goes depends only on the depth and the child index, so
    // that its words can be written as they are computed: the last child over its
    // parent's frame (a finished last child leaves junk there, and the parent is popped),
    // another one above the top (junk there is above the stack; at full depth, the spare).
    let push_base = b.imul(depth, frame);
    let target = b.select(room, push_base, spare);
    let target = b.select(last, base, target);
    for (k, p) in child.iter().enumerate() {
        for (c, &v) in p.iter().enumerate() {
            b.sp_write((3 * k + c) as u16, Some(target), v);
        }
    }
    for k in 0..4 {
        for i in 0..3 {
            b.sp_write((F_EDGES + 3 * k + i) as u16, Some(target), t.edges[k][i]);
        }
    }
    b.sp_write(F_MASK as u16, Some(target), t.mask);
    b.sp_write(F_NEXT as u16, Some(target), zero);
    b.sp_write(F_LEVEL as u16, Some(target), child_level);
    let child_place = place.map(|p| child_place(&mut b, p, row_bit, col_bit));
    if let Some(p) = child_place {
        b.sp_write(F_PLACE as u16, Some(target), p);
    }
    // The depth: a finished last child pops its parent; a pushed child adds a frame.
    let popped = b.isub(depth, one);
    let grown = b.iadd(depth, one);
    let after_done = b.select(last, popped, depth);
    let after_split = b.select(pushed, grown, depth);
    let depth_next = b.select(t.done, after_done, after_split);
    let depth_next = b.select(busy, depth_next, zero);
    b.set_next(depth, depth_next);

    let overflow_flag = b.i32(FLAG_OVERFLOW as i32);
    let quad_flag = b.select(emit, flag_quad, zero);
    let lost_flag = b.imul(lost, overflow_flag);
    let flags = b.or(quad_flag, lost_flag);
    b.write(quads, flags);
    b.write(quads, child_level);
    for &w in &qw {
        b.write(quads, w);
    }
    // The corners (and the place), for `shade`.
    for v in cc.into_iter().flatten() {
        b.write(quads, v);
    }
    if let Some(p) = child_place {
        b.write(quads, p);
    }
    b.end_loop();

    // ---- After the loop: the walk saved for the next call.
    b.write(state, depth);
    let flags = b.or(overflow, started);
    b.write(state, flags);
    b.write(state, colour);
    for i in 0..STACK_FRAMES * frame_words {
        let w = b.sp_read(i as u16, None);
        b.write(state, w);
    }
    Ok(finish(b))
}

/// How [`shade`] colours a quad.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Shading {
    /// The patch's colour, as `subdiv` carried it (an unlit material).
    Flat,
    /// OpenGL's fixed-function lighting of the vertex program ([`crate::opengl::vertex_program`]):
    /// `lights` lights, the specular term when `specular`, to the integer power `shininess`.
    /// With `textured`, the lit colour and the quad's texture coordinates go to the
    /// material's fragment program instead (a `varyings` record per quad, as `irast`
    /// writes one per fragment), which colours the quad.
    Lit {
        lights: usize,
        specular: bool,
        shininess: u32,
        textured: bool,
    },
    /// The marble shader ([`crate::kernels::turbulence::build_fragment`], the OpenGL
    /// pipeline's fragment program for `shader = "marble"`), which lights the quad
    /// itself: `shade` writes the quad's centre and normal in object space as a
    /// `varyings` record ([`crate::kernels::turbulence::MARBLE_RECORD_WORDS`]), as
    /// `irast` writes one per fragment.
    Marble,
}

impl Shading {
    /// Whether the quads go through a fragment program (their records carry places).
    pub fn textured(self) -> bool {
        matches!(self, Shading::Lit { textured: true, .. })
    }

    /// Whether a fragment program colours the quads (from `shade`'s `varyings`).
    pub fn fragment_program(self) -> bool {
        self.textured() || self == Shading::Marble
    }

    /// Words of a `varyings` record `shade` writes per quad ([`Shading::fragment_program`]).
    pub fn varyings_words(self) -> usize {
        match self {
            Shading::Marble => crate::kernels::turbulence::MARBLE_RECORD_WORDS,
            _ if self.textured() => SHADE_VARYINGS,
            _ => 0,
        }
    }

    /// The records of a frame shaded so.
    pub fn records(self) -> Records {
        Records {
            places: self.textured(),
        }
    }
}

/// A lit or marble [`shade`]'s own parameters: `2/W`, `2/H`, `P₀₀`, `P₁₁`, `P₂₂`, `P₂₃`;
/// when textured the frame's breadth-first levels (an int32: `subdiv`'s levels count from
/// the patches it walks, places from the scene's patches); for marble the inverse of the
/// model-view matrix, its top three rows ([`TO_OBJECT_WORDS`]).
pub fn shade_own_params(shading: Shading) -> usize {
    match shading {
        Shading::Flat => 0,
        Shading::Lit { textured, .. } => 6 + usize::from(textured),
        Shading::Marble => 6 + TO_OBJECT_WORDS,
    }
}

/// Words of the eye-to-object transform a marble [`shade`] takes: the inverse model-view
/// matrix's top three rows, row-major (its last row is `0 0 0 1`).
pub const TO_OBJECT_WORDS: usize = 12;

/// Rows of a lit [`shade`]'s own parameters: [`shade_own_params`] padded so that
/// `perlight`'s words after them start on an SRF block.
pub fn shade_own_rows(desc: &MachineDesc, shading: Shading) -> usize {
    shade_own_params(shading).next_multiple_of(crate::stream::srf::block_rows(desc))
}

/// The words of a textured quad's `varyings` record: r, g, b (the lit colour, clamped),
/// s, t.
pub const SHADE_VARYINGS: usize = 5;

/// A lit or marble [`shade`]'s parameters: the camera's, then the shader's.
struct ShadeParams {
    two_over: [Value; 2],
    inv_p00: Value,
    inv_p11: Value,
    p22: Value,
    p23: Value,
    shader: ShaderParams,
}

enum ShaderParams {
    Lit {
        lights: Vec<crate::opengl::vertex_program::LightParams>,
        base: [Value; 3],
        specular: bool,
        shininess: u32,
        /// Textured: the frame's breadth-first levels.
        split_levels: Option<Value>,
    },
    /// The inverse model-view matrix's top three rows.
    Marble { to_object: [Value; TO_OBJECT_WORDS] },
}

/// `shade`: per quad record of `subdiv` ([`SUBDIV_QUAD_WORDS`]), the record `sample`
/// reads ([`QUAD_WORDS`]) with the quad's colour from its material: Reyes's shading
/// stage, once per quad, with the vertex and fragment frequencies collapsed (the quads
/// are flat-shaded).
///
/// **Lit** quads are lit as the OpenGL pipeline lights a vertex, at the quad's centre with
/// the quad's own normal: each corner goes back from window space to eye space through
/// the camera's perspective projection (`x_n = x·(2/W) − 1`, `y_n = y·(2/H) − 1`, `z_n =
/// 2z − 1`; `z_e = −P₂₃/(z_n + P₂₂)`, `x_e = x_n·(−z_e)/P₀₀`, `y_e = y_n·(−z_e)/P₁₁`: a
/// symmetric frustum, which the host checks), the position is the mean of the four
/// corners, and the normal the cross product of the diagonals, turned to face the eye
/// (two-sided: the quad's orientation follows its patch's parametrisation, which no file
/// format fixes; a quad with no area faces the eye). Then `base + Σ` lights exactly as
/// [`add_light`](crate::opengl::vertex_program::add_light) sums them, clamped to [0, 1]
/// and packed as RGBA8 rounded to nearest, alpha 1.
///
/// **Textured** lit quads (records with places, [`Records`]) write a colour word of 0 and,
/// on `varyings`, the clamped lit colour and the texture coordinates of the quad's
/// centre in its patch's parameter square: a place `(u_i, v_i)` at level `l` (the record's
/// level plus the frame's breadth-first levels) is the cell of side `2^-l` whose centre is
/// `s = (u_i + ½)·2^-l`, `t = (v_i + ½)·2^-l` (exact in fp32), the parameters at which
/// the OpenGL pipeline's tessellation gives a patch's vertices their texture coordinates.
///
/// **Marble** quads write a colour word of 0 and, on `varyings`, white (which the marble
/// program drops) and the quad's centre and normal in object space: the eye-space corners
/// go through the inverse model-view matrix (a parameter: the host inverts the matrix
/// once per frame), and the centre and the normal facing the eye (the inverse applied to
/// the eye-space origin) are found from them as lit quads' are in eye space. The normal
/// is not normalised: the marble program does that.
///
/// Parameters: `2/W`, `2/H`, `P₀₀`, `P₁₁`, `P₂₂`, `P₂₃` (when textured the frame's
/// breadth-first levels, for marble the inverse model-view's top rows; padded to
/// [`shade_own_rows`]), then when lit `perlight`'s words (the lights in eye space and
/// their colour products, and `base`): the vertex program's `perlight` runs on the
/// machine to write them.
pub fn shade(desc: &MachineDesc, shading: Shading) -> Result<Kernel, MachineRequirementError> {
    use crate::kernels::vertex::normalize;
    use crate::opengl::vertex_program::{LitVertex, add_light, light_params};

    let mut b = KernelBuilder::new("shade");
    let quads = b.input("quads");
    let shaded = b.output("shaded");
    let varyings = shading.fragment_program().then(|| b.output("varyings"));
    let (zero, one) = (b.f32(0.0), b.f32(1.0));
    let params = (shading != Shading::Flat).then(|| {
        let [two_over_w, two_over_h, p00, p11, p22, p23] =
            ["two_over_w", "two_over_h", "p00", "p11", "p22", "p23"].map(|n| b.param_f32(n));
        let split_levels = shading.textured().then(|| b.param("split_levels", Ty::I32));
        let to_object = (shading == Shading::Marble)
            .then(|| std::array::from_fn(|i| b.param_f32(&format!("to_object{i}"))));
        for i in shade_own_params(shading)..shade_own_rows(desc, shading) {
            b.param_f32(&format!("pad{i}"));
        }
        let shader = match (shading, to_object) {
            (
                Shading::Lit {
                    lights,
                    specular,
                    shininess,
                    ..
                },
                _,
            ) => {
                let (lights, base) = light_params(&mut b, lights, specular);
                ShaderParams::Lit {
                    lights,
                    base,
                    specular,
                    shininess,
                    split_levels,
                }
            }
            (_, to_object) => ShaderParams::Marble {
                to_object: to_object.expect("a marble shade's transform"),
            },
        };
        // The projection's reciprocals, once per call.
        let (inv_p00, inv_p11) = (b.fdiv(one, p00), b.fdiv(one, p11));
        ShadeParams {
            two_over: [two_over_w, two_over_h],
            inv_p00,
            inv_p11,
            p22,
            p23,
            shader,
        }
    });
    b.begin_loop(LoopSpec::OverStream(quads));
    let rec: Vec<Value> = (0..shading.records().subdiv_quad_words())
        .map(|_| b.read(quads))
        .collect();
    for &w in &rec[..Q_COLOUR] {
        b.write(shaded, w);
    }
    let colour = match &params {
        None => rec[Q_COLOUR],
        Some(p) => {
            let eye: [[Value; 3]; 4] = std::array::from_fn(|k| {
                let at = Q_CORNERS + 3 * k;
                let [x, y, z] = std::array::from_fn(|i| b.cast(rec[at + i], Ty::F32));
                let xs = b.fmul(x, p.two_over[0]);
                let xn = b.fsub(xs, one);
                let ys = b.fmul(y, p.two_over[1]);
                let yn = b.fsub(ys, one);
                let zz = b.fadd(z, z);
                let zn = b.fsub(zz, one);
                let d = b.fadd(zn, p.p22);
                // −z_e = P₂₃/(z_n + P₂₂): the clip w.
                let w = b.fdiv(p.p23, d);
                let ze = b.fneg(w);
                let xw = b.fmul(xn, w);
                let yw = b.fmul(yn, w);
                [b.fmul(xw, p.inv_p00), b.fmul(yw, p.inv_p11), ze]
            });
            match &p.shader {
                ShaderParams::Lit {
                    lights,
                    base,
                    specular,
                    shininess,
                    split_levels,
                } => {
                    let (position, normal, to_eye) = facing_quad(&mut b, eye, None, zero);
                    let unit_n = normalize(&mut b, normal);
                    let e = specular.then(|| normalize(&mut b, to_eye));
                    let mut v = LitVertex {
                        clip: [zero; 4],
                        colour: *base,
                        eye_pos: position,
                        unit_n,
                        e,
                        vertex_colour: None,
                        extras: Vec::new(),
                    };
                    for &light in lights {
                        v.colour = add_light(&mut b, &v, light, *shininess, zero, one);
                    }
                    let [r, g, bl] = v.colour;
                    match (varyings, split_levels) {
                        (Some(out), Some(split_levels)) => {
                            for c in v.colour {
                                let above_zero = b.fmax(c, zero);
                                let clamped = b.fmin(above_zero, one);
                                b.write(out, clamped);
                            }
                            let place = b.cast(rec[SUBDIV_QUAD_WORDS], Ty::I32);
                            for t in place_centre(&mut b, place, rec[Q_LEVEL], *split_levels) {
                                b.write(out, t);
                            }
                            b.word(0)
                        }
                        _ => crate::kernels::texture::pack(&mut b, [r, g, bl, one]),
                    }
                }
                ShaderParams::Marble { to_object } => {
                    let m = to_object;
                    let row = |b: &mut KernelBuilder, r: usize, v: [Value; 3]| {
                        let x = b.fmul(m[4 * r], v[0]);
                        let y = b.fmul(m[4 * r + 1], v[1]);
                        let z = b.fmul(m[4 * r + 2], v[2]);
                        let xy = b.fadd(x, y);
                        let xyz = b.fadd(xy, z);
                        b.fadd(xyz, m[4 * r + 3])
                    };
                    let object = eye.map(|v| std::array::from_fn(|r| row(&mut b, r, v)));
                    let eye_at = [m[3], m[7], m[11]];
                    let (position, normal, _) = facing_quad(&mut b, object, Some(eye_at), zero);
                    let out = varyings.expect("a marble shade's varyings");
                    for w in [one, one, one].into_iter().chain(position).chain(normal) {
                        b.write(out, w);
                    }
                    b.word(0)
                }
            }
        }
    };
    b.write(shaded, colour);
    b.end_loop();
    Ok(finish(b))
}

/// A quad's centre (the mean of its `corners`), its normal (the cross product of its
/// diagonals) turned to face the eye at `eye` (the origin when `None`), and the direction
/// to the eye: flipped where it points away, the direction to the eye where the quad has
/// no area.
fn facing_quad(
    b: &mut KernelBuilder,
    corners: [[Value; 3]; 4],
    eye: Option<[Value; 3]>,
    zero: Value,
) -> ([Value; 3], [Value; 3], [Value; 3]) {
    use crate::kernels::dot;
    let quarter = b.f32(0.25);
    let position: [Value; 3] = std::array::from_fn(|i| {
        let s01 = b.fadd(corners[0][i], corners[1][i]);
        let s23 = b.fadd(corners[2][i], corners[3][i]);
        let s = b.fadd(s01, s23);
        b.fmul(s, quarter)
    });
    let d1: [Value; 3] = std::array::from_fn(|i| b.fsub(corners[2][i], corners[0][i]));
    let d2: [Value; 3] = std::array::from_fn(|i| b.fsub(corners[3][i], corners[1][i]));
    let cross: [Value; 3] = std::array::from_fn(|i| {
        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
        let u = b.fmul(d1[j], d2[k]);
        let v = b.fmul(d1[k], d2[j]);
        b.fsub(u, v)
    });
    let to_eye: [Value; 3] = std::array::from_fn(|i| match eye {
        None => b.fneg(position[i]),
        Some(e) => b.fsub(e[i], position[i]),
    });
    let facing = dot(b, cross, to_eye);
    let away = b.flt(facing, zero);
    let area = dot(b, cross, cross);
    let none = b.feq(area, zero);
    let normal = std::array::from_fn(|i| {
        let flipped = b.fneg(cross[i]);
        let n = b.select(away, flipped, cross[i]);
        b.select(none, to_eye[i], n)
    });
    (position, normal, to_eye)
}

/// The centre `(u, v)` of the cell `place` names at `level + split_levels` (see
/// [`Records`]): `((u_i + ½)·2^-l, (v_i + ½)·2^-l)`, `2^-l` built from its exponent bits.
fn place_centre(
    b: &mut KernelBuilder,
    place: Value,
    level: Value,
    split_levels: Value,
) -> [Value; 2] {
    let level = b.cast(level, Ty::I32);
    let l = b.iadd(level, split_levels);
    let bias = b.i32(127);
    let exponent = b.isub(bias, l);
    let mantissa_bits = b.i32(23);
    let bits = b.shl(exponent, mantissa_bits);
    let cell = b.cast(bits, Ty::F32);
    let (mask, sixteen, half) = (b.i32(0xFFFF), b.i32(16), b.f32(0.5));
    let u_i = b.and(place, mask);
    let v_i = b.shr(place, sixteen);
    [u_i, v_i].map(|i| {
        let f = b.itof(i);
        let centre = b.fadd(f, half);
        b.fmul(centre, cell)
    })
}

/// `sample`: each quad's pixel centres against its four edges, flat: for every centre of
/// the [`stamp`]`(stop)`² block from its box's corner that lies in the box (widened by
/// [`BOX_MARGIN`]), in the window and inside all four edges, a fragment `addr` (`y·W +
/// x`), `z` (the quad's depth), `colour` and `prim` (1); per quad record the number of
/// fragments (`covered`, 0 for records that are not quads); after the loop a row of null
/// fragments (the trash pixel `W·H`, a NaN depth), as the OpenGL pipeline's rasterizer
/// ends its fragments, so that they can be read in whole rows.
///
/// Tie rule: a centre on an edge (`E = 0`) is inside where `A > 0`, or `A = 0` and `B ≥
/// 0`: of two quads that share the edge (exactly opposite equations) just one takes it. A
/// zero-length edge (`A = B = 0`, `E = 0` everywhere) takes every centre: the quad is
/// bounded by its other edges.
///
/// With `colours` (textured frames) each quad's colour is the next word of the `colours`
/// input (the fragment program's, one per quad record) instead of its record's.
pub fn sample(
    _desc: &MachineDesc,
    width: u32,
    height: u32,
    stop: f32,
    colours: bool,
) -> Result<Kernel, MachineRequirementError> {
    let n = stamp(stop);
    let mut b = KernelBuilder::new("sample");
    let quads = b.input("quads");
    let colours = colours.then(|| b.input("colours"));
    let addr_out = b.output("addr");
    let z_out = b.output("z");
    let colour_out = b.output("colour");
    let prim_out = b.output("prim");
    let covered_out = b.output("covered");
    // Every quad is primitive 1 for `zcompare` (which keeps the earlier of two equal
    // depths): a pixel never drawn is primitive 0.
    let prim = b.i32(1);
    let (zero, one) = (b.i32(0), b.i32(1));
    let zero_f = b.f32(0.0);
    let half = b.f32(0.5);
    let margin = b.f32(BOX_MARGIN);
    let reach = b.f32(BOX_MARGIN + 0.5);
    let w_i = b.i32(width as i32);
    let h_i = b.i32(height as i32);
    b.begin_loop(LoopSpec::OverStream(quads));
    let rec: Vec<Value> = (0..QUAD_WORDS).map(|_| b.read(quads)).collect();
    let flags = b.cast(rec[Q_FLAGS], Ty::I32);
    let is_quad = b.and(flags, one);
    let edges: [[Value; 3]; 4] =
        std::array::from_fn(|k| std::array::from_fn(|i| b.cast(rec[Q_EDGES + 3 * k + i], Ty::F32)));
    let bx: [Value; 4] = std::array::from_fn(|i| b.cast(rec[Q_BOX + i], Ty::F32));
    let z = rec[Q_DEPTH];
    let colour = match colours {
        Some(c) => b.read(c),
        None => rec[Q_COLOUR],
    };
    // Per axis: the first centre X0 + 0.5 ≥ lo − margin (X0 = ceil(lo − margin − 0.5)),
    // the box's widened bounds.
    let axis = |b: &mut KernelBuilder, lo: Value, hi: Value| {
        let t = b.fsub(lo, reach);
        let r = b.ftoi(t);
        let rf = b.itof(r);
        let below = b.flt(rf, t);
        let below = flag(b, below);
        let first = b.iadd(r, below);
        let lo_m = b.fsub(lo, margin);
        let hi_m = b.fadd(hi, margin);
        (first, lo_m, hi_m)
    };
    let (x0, xlo, xhi) = axis(&mut b, bx[0], bx[2]);
    let (y0, ylo, yhi) = axis(&mut b, bx[1], bx[3]);
    // Tie-rule thresholds per edge: on-edge centres pass where A > 0, or A = 0 and B ≥ 0.
    let ties: [Value; 4] = std::array::from_fn(|k| {
        let [a, bb, _] = edges[k];
        let a_pos = b.flt(zero_f, a);
        let a_zero = b.feq(a, zero_f);
        let b_nonneg = b.fle(zero_f, bb);
        let t = both(&mut b, a_zero, b_nonneg);
        let a_pos = flag(&mut b, a_pos);
        b.or(a_pos, t)
    });
    let mut count = zero;
    for j in 0..n {
        let jj = b.i32(j as i32);
        let y = b.iadd(y0, jj);
        let fy = b.itof(y);
        let fy = b.fadd(fy, half);
        let y_in_lo = b.fle(ylo, fy);
        let y_in_hi = b.fle(fy, yhi);
        let y_win_lo = b.ile(zero, y);
        let y_win_hi = b.ilt(y, h_i);
        let mut row_ok = is_quad;
        for c in [y_in_lo, y_in_hi, y_win_lo, y_win_hi] {
            let c = flag(&mut b, c);
            row_ok = b.and(row_ok, c);
        }
        let by: [Value; 4] = std::array::from_fn(|k| {
            let p = b.fmul(edges[k][1], fy);
            b.fadd(p, edges[k][2])
        });
        let row_addr = b.imul(y, w_i);
        for i in 0..n {
            let ii = b.i32(i as i32);
            let x = b.iadd(x0, ii);
            let fx = b.itof(x);
            let fx = b.fadd(fx, half);
            let mut inside = row_ok;
            let tests = [
                b.fle(xlo, fx),
                b.fle(fx, xhi),
                b.ile(zero, x),
                b.ilt(x, w_i),
            ];
            for c in tests {
                let c = flag(&mut b, c);
                inside = b.and(inside, c);
            }
            for k in 0..4 {
                // E = A·x + (B·y + C).
                let ax = b.fmul(edges[k][0], fx);
                let e = b.fadd(ax, by[k]);
                let pos = b.flt(zero_f, e);
                let on = b.feq(e, zero_f);
                let on = flag(&mut b, on);
                let on = b.and(on, ties[k]);
                let pos = flag(&mut b, pos);
                let ok = b.or(pos, on);
                inside = b.and(inside, ok);
            }
            let inside_i = inside;
            count = b.iadd(count, inside_i);
            let cover = b.ine(inside_i, zero);
            let addr = b.iadd(row_addr, x);
            b.write_if(addr_out, cover, addr);
            b.write_if(z_out, cover, z);
            b.write_if(colour_out, cover, colour);
            b.write_if(prim_out, cover, prim);
        }
    }
    b.write(covered_out, count);
    b.end_loop();
    null_row(
        &mut b,
        &[
            (addr_out, width * height),
            (z_out, NULL_DEPTH),
            (colour_out, 0),
            (prim_out, 0),
        ],
    );
    Ok(finish(b))
}
