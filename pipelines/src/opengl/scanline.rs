//! The scanline rasterizer (thesis §4.4.1): `spanprep`, `spangen`, `spanpack` and
//! `spanrast`, in place of `xyprep` and `xyrast`, with the same fragments out (`addr`,
//! `tri`, `e0`, `e1`, `e2`), so `irast` and the composite follow unchanged.
//!
//! | kernel | per element | streams |
//! |---|---|---|
//! | [`spanprep`] | triangle, per scissor tile: 2 half-triangles (a top and a bottom one, split at the middle corner; one of them empty when an edge is parallel to x, both when the triangle is not drawn), its edge record, `spangen`'s iterations | window → halves (2 × 7), edges (10), rows |
//! | [`spangen`] | half-triangle, taken by load-balanced record input: [`SPANGEN_ROWS`] spans (rows) per iteration | halves → pos, end, tri (conditional) |
//! | [`spanpack`] | span: the conditional streams side by side as 3-word records with `spanrast`'s iterations on each; `spanrast`'s iterations and candidate pixels | pos, end → spans, counts |
//! | [`spanrast`] | span with its edge record (gathered by triangle), taken by load-balanced record input: [`SPANRAST_PIXELS`] pixels per iteration | spans, edges → addr, tri, e0, e1, e2 (conditional) |
//!
//! **Coverage is the barycentric rasterizer's, bit for bit.** A half-triangle bounds each
//! row by a left and a right edge's line, `x = s·(y + ½) + o` (`s = −B/A`, `o = −C/A`), with
//! a margin of [`SPAN_MARGIN`] pixel: any subset of a triangle's edge constraints holds
//! every pixel the three hold, so a span is a superset of the row's covered pixels, and
//! `spanrast` tests each of its pixels with `xyrast`'s expression `(A·X + B·Y) + C` for the
//! three edges and the same top-left thresholds. An edge is used for bounds only where its
//! line is well conditioned (`|s| ≤` [`MAX_SLOPE`], `|o| <` [`FAR`]); there, the lines'
//! rounding and the edge values' stay far inside the margin at window coordinates below
//! 8192. The others (near-horizontal edges, those of triangles that cross w = 0 at
//! infinity) leave the bound to the box and the scissor tile. Why not the thesis's
//! incremental spans: a span's start values and per-pixel deltas round differently from
//! `xyrast`'s, so coverage and colours would differ from the barycentric frame's.
//!
//! **Record input.** Half-triangles and spans are multi-word records taken by the
//! clusters that have finished theirs ([`RecordInput`], which buffers two rows of each
//! stream in every cluster's scratchpad). Each cluster works on one record and holds the
//! next ahead, so the decision to take waits on no take of the iteration before. The
//! machine's conditional streams are one word per cluster, so `spangen` writes a span's
//! words to three streams and `spanpack` puts them side by side; `spanprep` writes the
//! top and the bottom half of every triangle (an empty one costs `spangen` one iteration
//! of one cluster), as a conditional output of 7-word records would need 7 streams, more
//! than a kernel has. After the last real record come sentinels, records no cluster
//! finishes, so a cluster takes at most two of them ([`SENTINEL_ROWS`]: those and the two
//! rows read ahead).
//!
//! **Iterations.** With `W` iterations of work over `C` clusters and the longest record
//! `w`, every cluster is busy until the last record is taken, after which it finishes its
//! own record and the one it holds: `⌈W / C⌉ + 2·w + 2` iterations do all the work, and
//! the kernels count them on the machine (`spanprep` for `spangen`, `spanpack` for
//! `spanrast`).

use imagine_units::desc::MachineDesc;

use super::kernels::{EdgeTest, FrameShape, TRI_BITS, all_reduce, finish, null_row};
use crate::kernel::{Kernel, KernelBuilder, LoopSpec, MachineRequirementError, Needs, Ty, Value};
use crate::kernels::record_input::RecordInput;

/// Words of a half-triangle (`spanprep` → `spangen`): its first row and its row count
/// (`y | rows·2^16`), the box's columns (`x0 | x1·2^16`), the triangle's index in the batch
/// ([`SENTINEL`] for a sentinel), then the left and the right line, `s` and `o` each (the
/// margin and the pixel centre folded into `o`).
pub const HALF_WORDS: usize = 7;
/// Words of an edge record (`spanprep` → DRAM → `spanrast`): the nine edge coefficients and
/// the tag (the triangle's index and its top-left flags, as in a raster record).
pub const EDGE_WORDS: usize = 10;
/// Words of a span record (`spanpack` → `spanrast`): `y·2^16 + x` of its first pixel, `x`
/// of its last, and `spanrast`'s iterations on it ([`SENTINEL_END`] for a sentinel; the
/// triangle's index goes with the gathered edge record).
pub const SPAN_WORDS: usize = 3;
/// How far beyond its bounding lines a span reaches, in pixels.
pub const SPAN_MARGIN: f32 = 0.25;
/// The steepest line (in x per row) a half-triangle is bounded by.
pub const MAX_SLOPE: f32 = 32.0;
/// Lines whose offset is this far out bound nothing (and stand for "no line").
pub const FAR: f32 = 4_194_304.0;
/// The triangle index of a sentinel half-triangle.
pub const SENTINEL: u32 = u32::MAX;
/// A sentinel span's last pixel: so far on that no bound reaches its end.
pub const SENTINEL_END: u32 = 1 << 30;
/// Rows of sentinels after a stream's real records: a cluster takes at most two (it holds
/// one ahead when it starts the other), and the input reads two rows ahead.
pub const SENTINEL_ROWS: usize = 4;
/// Rows `spangen` makes per cluster and iteration (the thesis's 2 spans a loop).
pub const SPANGEN_ROWS: usize = 2;
/// Pixels `spanrast` tests per cluster and iteration: 4, where the thesis's made 2. Each
/// iteration pays for a take (the ranking, the routing of a 13-word record, its
/// scratchpad buffers), whether a cluster takes or not; at 2 pixels that cost is spread
/// over 2.
pub const SPANRAST_PIXELS: usize = 4;

/// Whether every condition in `conditions` holds: conditions are bit 0 of a word, and bit 0
/// of a product is the AND of the factors' bits 0, so the multipliers, which have room,
/// take the ANDs off the adders.
fn all(b: &mut KernelBuilder, conditions: &[Value]) -> Value {
    let mut words = conditions
        .iter()
        .map(|&c| b.cast(c, Ty::I32))
        .collect::<Vec<_>>()
        .into_iter();
    let first = words.next().expect("a condition");
    let product = words.fold(first, |p, w| b.imul(p, w));
    b.cast(product, Ty::Cc)
}

/// Iterations of a record of `units` at `run` a time (`⌈units / run⌉`, at least one, `run`
/// a power of two): `spangen`'s for a half-triangle's rows, `spanrast`'s for a span's
/// pixels.
fn iterations_of(b: &mut KernelBuilder, units: Value, run: usize) -> Value {
    let one = b.i32(1);
    let round = b.i32(run as i32 - 1);
    let shift = b.i32(run.trailing_zeros() as i32);
    let n = b.iadd(units, round);
    let n = b.shr(n, shift);
    b.imax(n, one)
}

/// `⌈total / C⌉ + 2·most + 2`, the iterations that do all the work (see the module notes),
/// from each cluster's total and longest record.
fn iteration_bound(b: &mut KernelBuilder, clusters: usize, total: Value, most: Value) -> Value {
    let total = all_reduce(b, clusters, total, KernelBuilder::iadd);
    let most = all_reduce(b, clusters, most, KernelBuilder::imax);
    let round = b.i32(clusters as i32 - 1);
    let t = b.iadd(total, round);
    let shift = b.i32(clusters.trailing_zeros() as i32);
    let rows = b.shr(t, shift);
    let two = b.i32(2);
    let m = b.imul(most, two);
    let bound = b.iadd(rows, m);
    b.iadd(bound, two)
}

/// A line `x = s·y + o` of a half-triangle.
#[derive(Clone, Copy)]
struct Line {
    s: Value,
    o: Value,
}

/// An edge's line, whether it bounds the left side (else the right), whether it is
/// usable, and its `x` at the top and the bottom row's centres.
struct EdgeLine {
    line: Line,
    left: Value,
    right: Value,
    usable: Value,
    at: [Value; 2],
}

/// The usable line of side `left` that bounds row `row` (0 top, 1 bottom) most tightly:
/// the largest `x` for the left side, the smallest for the right; `none` (`s = 0`, `o`
/// far out) if no line is usable.
fn tightest(b: &mut KernelBuilder, lines: &[EdgeLine], row: usize, left: bool, none: Line) -> Line {
    let mut best = none;
    let mut best_x = none.o;
    for e in lines {
        let x = e.at[row];
        let (tighter, side) = if left {
            (b.flt(best_x, x), e.left)
        } else {
            (b.flt(x, best_x), e.right)
        };
        let take = all(b, &[tighter, e.usable, side]);
        best = Line {
            s: b.select(take, e.line.s, best.s),
            o: b.select(take, e.line.o, best.o),
        };
        best_x = b.select(take, x, best_x);
    }
    best
}

/// `spanprep`: per `window` record and scissor tile (parameters `sx0, sy0, sx1, sy1`,
/// inclusive), the triangle's two half-triangles ([`HALF_WORDS`]
/// each, to `halves`) and its edge record ([`EDGE_WORDS`], to `edges`); after the loop,
/// [`SENTINEL_ROWS`] rows of sentinel half-triangles, a row of sentinel edge records (the
/// first, at index `batch`, covers nothing: C0 = −∞), and `rows`: `spangen`'s iterations
/// (the same word in every cluster), then each cluster's spans at most (rows of its
/// half-triangles).
///
/// The rows and columns are the triangle's box clamped to the tile. They split at the middle corner, where
/// the two lines of one side cross: each half is bounded by the side's line that is
/// tightest at its outer row (top or bottom), and one half is empty when both sides have
/// one line.
pub fn spanprep(desc: &MachineDesc, shape: FrameShape) -> Result<Kernel, MachineRequirementError> {
    Needs::new("spanprep", desc).power_of_two_clusters(None)?;
    let mut b = KernelBuilder::new("spanprep");
    let window = b.input("window");
    let halves = b.output("halves");
    let edges_out = b.output("edges");
    let rows_out = b.output("rows");
    let scissor: [Value; 4] = ["sx0", "sy0", "sx1", "sy1"].map(|n| b.param(n, Ty::I32));
    let clusters = shape.clusters;
    let (zero, one) = (b.i32(0), b.i32(1));
    let (zero_f, half) = (b.f32(0.0), b.f32(0.5));
    let row_c = b.i32(clusters as i32);
    let sixteen = b.i32(16);
    let top_left_bits = b.word(!((1 << TRI_BITS) - 1));
    let (max_slope, far) = (b.f32(MAX_SLOPE), b.f32(FAR));
    let minus_one_f = b.f32(-1.0);
    let (lo_clamp, hi_clamp) = (b.f32(-2.0), b.f32(8192.0));
    let left_margin = b.f32(-0.5 - SPAN_MARGIN);
    let right_margin = b.f32(-0.5 + SPAN_MARGIN);
    let cluster = b.cluster_id();
    let no_left = {
        let far_left = b.f32(-FAR);
        Line {
            s: zero_f,
            o: far_left,
        }
    };
    let no_right = Line { s: zero_f, o: far };

    b.begin_loop(LoopSpec::OverStream(window));
    let index0 = b.carried(cluster);
    let spans0 = b.carried(zero);
    let work0 = b.carried(zero);
    let most0 = b.carried(zero);
    let coefficients: [Value; 9] = std::array::from_fn(|_| b.read_f32(window));
    let bounds: [Value; 4] = std::array::from_fn(|slot| {
        let v = b.read_i32(window);
        if slot < 2 {
            b.imax(v, scissor[slot])
        } else {
            b.imin(v, scissor[slot])
        }
    });
    let flags = b.read_i32(window);
    for &c in &coefficients {
        b.write(edges_out, c);
    }
    let [x0, y0, x1, y1] = bounds;
    let kept = {
        let x_ok = b.ile(x0, x1);
        let y_ok = b.ile(y0, y1);
        all(&mut b, &[flags, x_ok, y_ok])
    };
    let centre = |b: &mut KernelBuilder, y: Value| {
        let f = b.itof(y);
        b.fadd(f, half)
    };
    let rows_at = [centre(&mut b, y0), centre(&mut b, y1)];
    // Each edge's line, and the side it bounds (A > 0: x at least the line's; A < 0: at
    // most; A = 0 has no line).
    let lines: Vec<EdgeLine> = coefficients
        .chunks(3)
        .map(|e| {
            let (a, bc, c) = (e[0], e[1], e[2]);
            let minus_inv = b.fdiv(minus_one_f, a);
            let s = b.fmul(bc, minus_inv);
            let o = b.fmul(c, minus_inv);
            let s_ok = {
                let m = b.fabs(s);
                b.fle(m, max_slope)
            };
            let o_ok = {
                let m = b.fabs(o);
                b.flt(m, far)
            };
            let at = rows_at.map(|fy| {
                let sx = b.fmul(s, fy);
                b.fadd(sx, o)
            });
            EdgeLine {
                line: Line { s, o },
                left: b.flt(zero_f, a),
                right: b.flt(a, zero_f),
                usable: all(&mut b, &[s_ok, o_ok]),
                at,
            }
        })
        .collect();
    let left_top = tightest(&mut b, &lines, 0, true, no_left);
    let left_bottom = tightest(&mut b, &lines, 1, true, no_left);
    let right_top = tightest(&mut b, &lines, 0, false, no_right);
    let right_bottom = tightest(&mut b, &lines, 1, false, no_right);
    // The middle corner's row: where the side whose line changes crosses itself.
    let crossing = |b: &mut KernelBuilder, top: Line, bottom: Line| {
        let num = b.fsub(bottom.o, top.o);
        let den = b.fsub(top.s, bottom.s);
        let y = b.fdiv(num, den);
        let (t, u) = (b.cast(top.o, Ty::I32), b.cast(bottom.o, Ty::I32));
        let changes = b.ine(t, u);
        (changes, y)
    };
    let (left_changes, left_y) = crossing(&mut b, left_top, left_bottom);
    let (right_changes, right_y) = crossing(&mut b, right_top, right_bottom);
    let split_y = {
        let y = b.select(right_changes, right_y, hi_clamp);
        let y = b.select(left_changes, left_y, y);
        // Rows whose centre is above the corner: y + ½ < corner.
        let y = b.fsub(y, half);
        let y = b.fmax(y, lo_clamp);
        let y = b.fmin(y, hi_clamp);
        let y = b.ftoi_trunc(y);
        let before_first = b.isub(y0, one);
        let y = b.imin(y, y1);
        b.imax(y, before_first)
    };
    let columns = {
        let x1 = b.imax(x1, zero);
        let x1 = b.shl(x1, sixteen);
        b.or(x0, x1)
    };
    let halves_of = [
        (y0, split_y, left_top, right_top),
        (split_y, y1, left_bottom, right_bottom),
    ];
    let mut spans = spans0;
    let mut work = work0;
    let mut most = most0;
    for (h, (from, to, left, right)) in halves_of.into_iter().enumerate() {
        // The top half is rows y0..=split, the bottom one split + 1..=y1.
        let first = if h == 0 { from } else { b.iadd(from, one) };
        let rows = {
            let r = b.isub(to, first);
            let r = b.iadd(r, one);
            let r = b.imax(r, zero);
            b.select(kept, r, zero)
        };
        let first = b.imax(first, zero);
        let packed = {
            let r = b.shl(rows, sixteen);
            b.or(first, r)
        };
        let left_o = b.fadd(left.o, left_margin);
        let right_o = b.fadd(right.o, right_margin);
        for w in [packed, columns, index0, left.s, left_o, right.s, right_o] {
            b.write(halves, w);
        }
        spans = b.iadd(spans, rows);
        let iterations = iterations_of(&mut b, rows, SPANGEN_ROWS);
        work = b.iadd(work, iterations);
        most = b.imax(most, iterations);
    }
    b.set_next(spans0, spans);
    b.set_next(work0, work);
    b.set_next(most0, most);
    let top_left = b.and(flags, top_left_bits);
    let tag = b.or(index0, top_left);
    b.write(edges_out, tag);
    let next_index = b.iadd(index0, row_c);
    b.set_next(index0, next_index);
    b.end_loop();
    let columns_empty = b.i32(1);
    let sentinel = b.word(SENTINEL);
    for _ in 0..SENTINEL_ROWS {
        for w in [
            zero,
            columns_empty,
            sentinel,
            zero_f,
            zero_f,
            zero_f,
            zero_f,
        ] {
            b.write(halves, w);
        }
    }
    // The sentinel edge record (index `batch`, the first after the batch's): edge 0's C
    // is −∞, so E0 is −∞ and no pixel is covered.
    let minus_inf = b.word(f32::NEG_INFINITY.to_bits());
    for k in 0..9 {
        b.write(edges_out, if k == 2 { minus_inf } else { zero_f });
    }
    b.write(edges_out, zero);
    let bound = iteration_bound(&mut b, clusters, work0, most0);
    b.write(rows_out, bound);
    b.write(rows_out, spans0);
    Ok(finish(b))
}

/// `spangen`: walks half-triangles, taken by load-balanced conditional input from `halves`
/// ([`HALF_WORDS`], then the sentinels), [`SPANGEN_ROWS`] rows per iteration, and writes each
/// row's span (within the half-triangle's columns, which `spanprep` clamped to the tile)
/// when it is not empty: `pos` (`y·2^16 + x` of its first pixel), `end` (`x` of its last), `tri`
/// (the triangle's index); then [`SENTINEL_ROWS`] + 1 rows of sentinel spans (end
/// [`SENTINEL_END`], triangle `batch`: the sentinel edge record). The loop runs over
/// `tickets`, as many iterations as `spanprep` counts.
pub fn spangen(desc: &MachineDesc, shape: FrameShape) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("spangen");
    let halves = b.input("halves");
    let tickets = b.input("tickets");
    let pos_out = b.output("pos");
    let end_out = b.output("end");
    let tri_out = b.output("tri");
    let input = RecordInput::in_step(&mut b, desc, "spangen", &[(halves, HALF_WORDS)], Some(0))?;
    let (zero, one) = (b.i32(0), b.i32(1));
    let (zero_f, half) = (b.f32(0.0), b.f32(0.5));
    let (lo_clamp, hi_clamp) = (b.f32(-2.0), b.f32(8192.0));
    let low16 = b.i32(0xFFFF);
    let sixteen = b.i32(16);
    let run = b.i32(SPANGEN_ROWS as i32);
    let sentinel = b.word(SENTINEL);
    let forever = b.i32(SENTINEL_END as i32);

    b.begin_loop(LoopSpec::OverStream(tickets));
    let _ticket = b.read(tickets);
    // The half-triangle being walked: its next row and last row, columns, triangle and
    // lines; and the one held ahead, taken when this one was started.
    let minus_one = b.i32(-1);
    let row0 = b.carried(zero);
    let last0 = b.carried(minus_one);
    let columns0 = b.carried(zero);
    let tri0 = b.carried(zero);
    let lines0: [Value; 4] = std::array::from_fn(|_| b.carried(zero_f));
    let held = input.take_ahead(&mut b, |b, ahead| {
        let packed = b.cast(ahead[0], Ty::I32);
        let rows = b.shr(packed, sixteen);
        let n = iterations_of(b, rows, SPANGEN_ROWS);
        let is_sentinel = b.ieq(ahead[2], sentinel);
        b.select(is_sentinel, forever, n)
    });
    let (switch, ahead) = (held.switch, &held.ahead);
    let (ahead_first, ahead_rows) = {
        let packed = b.cast(ahead[0], Ty::I32);
        (b.and(packed, low16), b.shr(packed, sixteen))
    };
    // On a switch the held record becomes the current one.
    let row = b.select(switch, ahead_first, row0);
    let last = {
        let l = b.iadd(ahead_first, ahead_rows);
        let l = b.isub(l, one);
        b.select(switch, l, last0)
    };
    let columns = b.select(switch, ahead[1], columns0);
    let tri = b.select(switch, ahead[2], tri0);
    let lines: Vec<Value> = (0..4)
        .map(|i| {
            let a = b.cast(ahead[3 + i], Ty::F32);
            b.select(switch, a, lines0[i])
        })
        .collect();
    let next_row = b.iadd(row, run);
    b.set_next(row0, next_row);
    b.set_next(last0, last);
    b.set_next(columns0, columns);
    b.set_next(tri0, tri);
    for (&l0, &l) in lines0.iter().zip(&lines) {
        b.set_next(l0, l);
    }
    let columns = b.cast(columns, Ty::I32);
    let x_first = b.and(columns, low16);
    let x_last = b.shr(columns, sixteen);
    let line_x = |b: &mut KernelBuilder, s: Value, o: Value, fy: Value| {
        let sx = b.fmul(s, fy);
        let x = b.fadd(sx, o);
        let x = b.fmax(x, lo_clamp);
        let x = b.fmin(x, hi_clamp);
        b.ftoi_trunc(x)
    };
    for j in 0..SPANGEN_ROWS {
        let y = if j == 0 {
            row
        } else {
            let jj = b.i32(j as i32);
            b.iadd(row, jj)
        };
        let fy = {
            let f = b.itof(y);
            b.fadd(f, half)
        };
        let from = {
            let x = line_x(&mut b, lines[0], lines[1], fy);
            b.imax(x, x_first)
        };
        let to = {
            let x = line_x(&mut b, lines[2], lines[3], fy);
            b.imin(x, x_last)
        };
        let in_half = b.ile(y, last);
        let nonempty = b.ile(from, to);
        let ok = all(&mut b, &[in_half, nonempty]);
        let pos = {
            let y = b.shl(y, sixteen);
            b.or(y, from)
        };
        b.write_if(pos_out, ok, pos);
        b.write_if(end_out, ok, to);
        b.write_if(tri_out, ok, tri);
    }
    b.end_loop();
    // (One row more than the rows `spanrast` reads, which start in the last span's row.)
    let every = b.ieq(zero, zero);
    let nulls = [
        (pos_out, zero),
        (end_out, forever),
        (tri_out, b.i32(shape.batch as i32)),
    ];
    for _ in 0..=SENTINEL_ROWS {
        for &(stream, null) in &nulls {
            b.write_if(stream, every, null);
        }
    }
    Ok(finish(b))
}

/// `spanpack`: `spangen`'s conditional streams `pos` and `end`, read a row at a time, as
/// [`SPAN_WORDS`]-word records in the cluster-row layout `spanrast` takes them in
/// (`spans`); after the loop, `counts`: `spanrast`'s iterations (the same word in every
/// cluster), then each cluster's candidate pixels, whose sum bounds the fragments.
pub fn spanpack(desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    Needs::new("spanpack", desc).power_of_two_clusters(None)?;
    let clusters = desc.cluster.count;
    let mut b = KernelBuilder::new("spanpack");
    let pos = b.input("pos");
    let end = b.input("end");
    let spans = b.output("spans");
    let counts = b.output("counts");
    let (zero, one) = (b.i32(0), b.i32(1));
    let low16 = b.i32(0xFFFF);
    let forever = b.i32(SENTINEL_END as i32);
    b.begin_loop(LoopSpec::OverStream(pos));
    let work0 = b.carried(zero);
    let most0 = b.carried(zero);
    let candidates0 = b.carried(zero);
    let p = b.read_i32(pos);
    let e = b.read_i32(end);
    let real = b.ilt(e, forever);
    let pixels = {
        let x = b.and(p, low16);
        let d = b.isub(e, x);
        let n = b.iadd(d, one);
        b.select(real, n, zero)
    };
    let iterations = {
        let n = iterations_of(&mut b, pixels, SPANRAST_PIXELS);
        b.select(real, n, zero)
    };
    let cost = b.select(real, iterations, forever);
    for w in [p, e, cost] {
        b.write(spans, w);
    }
    let work = b.iadd(work0, iterations);
    b.set_next(work0, work);
    let most = b.imax(most0, iterations);
    b.set_next(most0, most);
    let candidates = b.iadd(candidates0, pixels);
    b.set_next(candidates0, candidates);
    b.end_loop();
    let bound = iteration_bound(&mut b, clusters, work0, most0);
    b.write(counts, bound);
    b.write(counts, candidates0);
    Ok(finish(b))
}

/// `spanrast`: walks spans, taken by load-balanced conditional input from `spans`
/// ([`SPAN_WORDS`]) and `edges` (the span's triangle's edge record, gathered), [`SPANRAST_PIXELS`]
/// pixels per iteration, and writes the covered ones as `xyrast` does: `addr`
/// (`y·W + x`), `tri`, `e0`, `e1`, `e2`, then a row of nulls. The loop runs over
/// `tickets`, as many iterations as `spanpack` counts.
pub fn spanrast(desc: &MachineDesc, shape: FrameShape) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("spanrast");
    let spans = b.input("spans");
    let edges = b.input("edges");
    let tickets = b.input("tickets");
    let addr_out = b.output("addr");
    let tri_out = b.output("tri");
    let e_out: [_; 3] = ["e0", "e1", "e2"].map(|n| b.output(n));
    let input = RecordInput::in_step(
        &mut b,
        desc,
        "spanrast",
        &[(spans, SPAN_WORDS), (edges, EDGE_WORDS)],
        Some(0),
    )?;
    let zero = b.i32(0);
    let (zero_f, half) = (b.f32(0.0), b.f32(0.5));
    let edge_test = EdgeTest::new(&mut b, desc, zero_f);
    let low16 = b.i32(0xFFFF);
    let sixteen = b.i32(16);
    let run = b.i32(SPANRAST_PIXELS as i32);
    let width = b.i32(shape.width as i32);
    let tri_mask = b.i32((1 << TRI_BITS) - 1);
    let minus_one = b.i32(-1);

    b.begin_loop(LoopSpec::OverStream(tickets));
    let _ticket = b.read(tickets);
    // The span being walked: its next pixel, row and last pixel, and its edge record; and
    // the span held ahead, taken when this one was started.
    let held = input.take_ahead(&mut b, |b, ahead| b.cast(ahead[2], Ty::I32));
    let (switch, ahead) = (held.switch, &held.ahead);
    let x0 = b.carried(zero);
    let y0 = b.carried(zero);
    let last0 = b.carried(minus_one);
    let rec0: Vec<Value> = (0..EDGE_WORDS).map(|_| b.carried(zero)).collect();
    let (ahead_x, ahead_y, ahead_last) = {
        let p = b.cast(ahead[0], Ty::I32);
        let x = b.and(p, low16);
        let y = b.shr(p, sixteen);
        (x, y, b.cast(ahead[1], Ty::I32))
    };
    let x = b.select(switch, ahead_x, x0);
    let y = b.select(switch, ahead_y, y0);
    let last = b.select(switch, ahead_last, last0);
    let rec: Vec<Value> = rec0
        .iter()
        .zip(&ahead[SPAN_WORDS..])
        .map(|(&r, &a)| b.select(switch, a, r))
        .collect();
    let x_next = b.iadd(x, run);
    b.set_next(x0, x_next);
    b.set_next(y0, y);
    b.set_next(last0, last);
    for (&r0, &r) in rec0.iter().zip(&rec) {
        b.set_next(r0, r);
    }
    let tag = b.cast(rec[9], Ty::I32);
    let rec: Vec<Value> = rec[..9].iter().map(|&w| b.cast(w, Ty::F32)).collect();
    let thresholds = edge_test.thresholds(&mut b, tag);
    let tri = b.and(tag, tri_mask);
    let fy = {
        let f = b.itof(y);
        b.fadd(f, half)
    };
    let fx0 = {
        let f = b.itof(x);
        b.fadd(f, half)
    };
    let addr0 = {
        let r = b.imul(y, width);
        b.iadd(r, x)
    };
    for j in 0..SPANRAST_PIXELS {
        let (fx, addr, px) = if j == 0 {
            (fx0, addr0, x)
        } else {
            let fj = b.f32(j as f32);
            let ij = b.i32(j as i32);
            (b.fadd(fx0, fj), b.iadd(addr0, ij), b.iadd(x, ij))
        };
        let mut tests = vec![b.ile(px, last)];
        let mut e_values = [zero_f; 3];
        for (i, e_value) in e_values.iter_mut().enumerate() {
            let e = EdgeTest::value(&mut b, std::array::from_fn(|k| rec[3 * i + k]), fx, fy);
            *e_value = e;
            tests.push(edge_test.passes(&mut b, thresholds[i], e));
        }
        let covered = all(&mut b, &tests);
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
