//! The rasterizer as a block on an SRF: its latency, its output rate, back-pressure from
//! its stream buffers, and how its streams end (a row of nulls, or an overflow).

use imagine_hdl::{Design, default_domains};

use super::*;
use crate::desc::MachineDesc;

/// A right triangle with legs of `n` pixels at `(x, y)`, counter-clockwise, w = 1: its
/// window record (the kernels' layout) and the pixels it covers, `n(n-1)/2` (centres with
/// `dx + dy ≤ n − 2`).
fn triangle(x: f32, y: f32, n: f32, kept: bool) -> ([u32; WINDOW_WORDS], usize) {
    let v = [[x, y, 1.0], [x + n, y, 1.0], [x, y + n, 1.0]];
    let cross = |p: [f32; 3], q: [f32; 3]| {
        [
            p[1] * q[2] - p[2] * q[1],
            p[2] * q[0] - p[0] * q[2],
            p[0] * q[1] - p[1] * q[0],
        ]
    };
    let edges = [cross(v[1], v[2]), cross(v[2], v[0]), cross(v[0], v[1])];
    let mut w = [0u32; WINDOW_WORDS];
    for (e, edge) in edges.iter().enumerate() {
        for k in 0..3 {
            w[3 * e + k] = edge[k].to_bits();
        }
    }
    let bounds = [x as i32, y as i32, (x + n) as i32 - 1, (y + n) as i32 - 1];
    for (slot, b) in bounds.iter().enumerate() {
        w[9 + slot] = *b as u32;
    }
    let mut flags = u32::from(kept);
    for (i, e) in edges.iter().enumerate() {
        if e[0] > 0.0 || (e[0] == 0.0 && e[1] < 0.0) {
            flags |= 1 << (29 + i);
        }
    }
    w[13] = flags;
    let n = n as usize;
    (w, if kept { n * (n - 1) / 2 } else { 0 })
}

fn state() -> RasterState {
    RasterState {
        reference_depth: false,
        newton_steps: 0,
        width: 64,
        trash: 64 * 64,
        tile: [0, 0, 63, 63],
        prim_base: 0,
        extras: 0,
        derivatives: false,
        fragment_program: false,
    }
}

/// Triangles' streams in the cluster-row layout (record `t` in lane `t mod C`).
fn rows_of(records: &[Vec<u32>], lanes: usize) -> Vec<u32> {
    let w = records[0].len();
    let mut out = Vec::new();
    for row in records.chunks(lanes) {
        for k in 0..w {
            out.extend(row.iter().map(|r| r[k]));
        }
    }
    out
}

struct Run {
    result: RasterResult,
    /// Output words per stream, as the SRF holds them.
    streams: Vec<Vec<u32>>,
    /// Words written in each cycle.
    per_cycle: Vec<u64>,
    /// The cycle the first triangle was set up.
    first_setup: Option<usize>,
    stats: RasterStats,
}

/// Rasterizes `tris` (each `(window record, covered pixels)`) on `desc` with output regions
/// of `capacity` fragments.
fn run(desc: &MachineDesc, tris: &[([u32; WINDOW_WORDS], usize)], capacity: usize) -> Run {
    let mut design = Design::new("top", default_domains()).unwrap();
    let mut top = design.scope();
    let mut srf = Srf::new(&mut top.child("srf"), desc);
    let mut unit = Rasterizer::new(&mut top.child("rasterizer"), desc).expect("a rasterizer");
    let c = desc.cluster.count;
    let st = state();
    let window = rows_of(&tris.iter().map(|t| t.0.to_vec()).collect::<Vec<_>>(), c);
    let det: Vec<u32> = tris.iter().map(|_| 1.0f32.to_bits()).collect();
    let attribs: Vec<Vec<u32>> = (0..tris.len())
        .map(|t| {
            (0..st.attrib_words())
                .map(|k| (0.25 + 0.05 * k as f32 + 0.01 * t as f32).to_bits())
                .collect()
        })
        .collect();
    let attribs = rows_of(&attribs, c);
    let block = desc.srf.block_words;
    let mut at = 0;
    let mut place = |words: usize| {
        let start = at;
        at += words.div_ceil(block) * block;
        StreamBinding { start, words }
    };
    let inputs = [place(window.len()), place(det.len()), place(attribs.len())];
    let outputs =
        std::array::from_fn(|k| place(capacity * if k == 3 { st.value_words() } else { 1 }));
    for (b, words) in inputs.iter().zip([&window, &det, &attribs]) {
        srf.load(b.start, words).unwrap();
    }
    unit.start(
        RasterJob {
            inputs,
            outputs,
            state: st,
        },
        &mut srf,
    )
    .unwrap();
    let mut per_cycle = Vec::new();
    let mut first_setup = None;
    let result = loop {
        let before = unit.stats().words_written;
        srf.eval();
        unit.eval(&mut srf).unwrap();
        srf.commit();
        unit.commit(&mut srf).unwrap();
        per_cycle.push(unit.stats().words_written - before);
        if first_setup.is_none() && unit.stats().triangles > 0 {
            first_setup = Some(per_cycle.len() - 1);
        }
        if let Some(r) = unit.take_finished() {
            break r;
        }
        assert!(per_cycle.len() < 100_000, "the rasterizer never finished");
    };
    let streams = outputs
        .iter()
        .zip(&result.outputs)
        .map(|(b, &n)| srf.read_back(b.start, n).unwrap())
        .collect();
    Run {
        result,
        streams,
        per_cycle,
        first_setup,
        stats: unit.stats().clone(),
    }
}

fn hwrast() -> MachineDesc {
    MachineDesc::resolve("gold8+hwrast").unwrap()
}

/// Eight 6-pixel triangles side by side, the first `kept` of them kept.
fn row_of_triangles(kept: usize) -> Vec<([u32; WINDOW_WORDS], usize)> {
    (0..8)
        .map(|t| triangle(8.0 * t as f32, 4.0, 6.0, t < kept))
        .collect()
}

#[test]
fn the_first_fragment_comes_the_latency_after_its_triangle() {
    let desc = hwrast();
    let latency = desc.rasterizer.as_ref().unwrap().latency as usize;
    let r = run(&desc, &row_of_triangles(1), 64);
    let setup = r.first_setup.expect("a triangle was set up");
    let first = r.per_cycle.iter().position(|&n| n > 0).expect("a word");
    // Ready `latency` cycles after setup; moved into the row, then written.
    assert!(
        (setup + latency..=setup + latency + 2).contains(&first),
        "set up at {setup}, first word at {first}, latency {latency}"
    );
}

#[test]
fn it_writes_one_word_per_cycle_without_gaps() {
    let desc = hwrast();
    let tris: Vec<_> = (0..16)
        .map(|t| triangle(8.0 * (t % 8) as f32, 8.0 * (t / 8) as f32, 8.0, true))
        .collect();
    let expected: usize = tris.iter().map(|t| t.1).sum();
    let r = run(&desc, &tris, 512);
    assert_eq!(r.result.fragments, expected);
    assert!(!r.result.overflowed);
    assert!(
        r.per_cycle.iter().all(|&n| n <= 1),
        "more than 1 word a cycle"
    );
    let first = r.per_cycle.iter().position(|&n| n > 0).unwrap();
    let last = r.per_cycle.iter().rposition(|&n| n > 0).unwrap();
    let words: u64 = r.per_cycle.iter().sum();
    assert_eq!(words as usize, last - first + 1, "the output paused");
    assert_eq!(words, r.stats.words_written);
}

#[test]
fn a_full_stream_buffer_stalls_the_output_and_loses_nothing() {
    let slow = hwrast();
    let mut fast = hwrast();
    // Faster than the SRF port drains a stream buffer: the buffers fill and push back.
    fast.rasterizer.as_mut().unwrap().output_words_per_cycle = 64;
    let tris: Vec<_> = (0..16)
        .map(|t| triangle(8.0 * (t % 8) as f32, 8.0 * (t / 8) as f32, 8.0, true))
        .collect();
    let a = run(&slow, &tris, 512);
    let b = run(&fast, &tris, 512);
    assert!(b.stats.output_stall_cycles > 0, "{:?}", b.stats);
    assert_eq!(a.stats.output_stall_cycles, 0, "{:?}", a.stats);
    assert_eq!(a.streams, b.streams);
    assert!(b.per_cycle.len() < a.per_cycle.len());
}

#[test]
fn the_stream_ends_with_a_row_of_nulls_or_an_overflow() {
    let desc = hwrast();
    let c = desc.cluster.count;
    let st = state();
    // Three kept triangles of 15 fragments: 45, a row and 5 short.
    let r = run(&desc, &row_of_triangles(3), 64);
    assert_eq!(r.result.fragments, 3 * 15);
    let rows = (3 * 15usize).div_ceil(c);
    assert_eq!(
        r.result.outputs,
        vec![rows * c, rows * c, rows * c, rows * c]
    );
    let (addr, z, prim) = (&r.streams[0], &r.streams[1], &r.streams[2]);
    for f in 0..rows * c {
        let null = f >= 45;
        assert_eq!(addr[f] == st.trash, null, "fragment {f}");
        assert_eq!(z[f] == fragments::NULL_DEPTH, null, "fragment {f}");
        assert_eq!(prim[f] == 0, null, "fragment {f}");
    }
    // Primitive order: triangle t's fragments carry primitive t + 1, in order.
    let prims: Vec<u32> = prim[..45].to_vec();
    assert!(prims.windows(2).all(|w| w[0] <= w[1]), "{prims:?}");
    // Room for 4 rows of 8 only: the unit stops at the row that would not fit.
    let r = run(&desc, &row_of_triangles(3), 4 * c);
    assert!(r.result.overflowed);
    assert_eq!(r.result.fragments, 4 * c);
    assert!(r.result.outputs.iter().all(|&n| n <= 4 * c));
    // No triangle kept: nothing written, and the call ends.
    let r = run(&desc, &row_of_triangles(0), 64);
    assert_eq!((r.result.fragments, r.result.outputs[0]), (0, 0));
}
