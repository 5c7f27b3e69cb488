//! The S3 superscalar rasterizer: exactness against in-order drawing, the dependence
//! invariant, no deadlock, evaluation order, and the parallelism the features buy.

use imagine_units::desc::{MachineDesc, S3};
use imagine_units::s3::game::{GameParams, generate};
use imagine_units::s3::raster::{Mode, TraceTriangle, reference_frame};
use imagine_units::s3::run::{RunOptions, S3Report, cycle_bound, run};
use imagine_units::s3::{S3Config, S3Memory, Select};
use proptest::prelude::*;

fn config(k: usize) -> S3Config {
    let mut c = S3Config::of(&MachineDesc::gold8());
    c.accelerators = k;
    c
}

/// A small game-like frame with few depth levels (many equal depths) and particles.
fn small_game(seed: u64) -> (u32, u32, Vec<TraceTriangle>) {
    let p = GameParams {
        width: 160,
        height: 120,
        seed,
        background_rows: 40,
        strips: 10,
        strip_triangles: 12,
        strip_width: 14.0,
        strip_step: 9.0,
        particles: 20,
        depth_levels: 3,
    };
    (p.width, p.height, generate(&p))
}

fn run_ok(cfg: &S3Config, w: u32, h: u32, tris: &[TraceTriangle]) -> S3Report {
    let r = run(cfg, w, h, tris, RunOptions::default()).expect("the run finishes");
    assert_eq!(
        r.in_flight_hazards, 0,
        "two primitives in hazard were in flight"
    );
    r
}

#[test]
fn one_accelerator_draws_the_in_order_frame() {
    let (w, h, tris) = small_game(7);
    let r = run_ok(&config(1), w, h, &tris);
    let golden = reference_frame(&tris, w, h);
    assert_eq!(r.frame, golden);
    // Something was drawn, blended particles included, and depth ties occurred.
    assert!(r.fragments_passed > 10_000, "{}", r.fragments_passed);
    assert!(tris.iter().any(|t| t.mode == Mode::Blended));
    assert_eq!(r.busy_histogram.len(), 2);
    assert!(r.mean_parallelism() <= 1.0);
}

#[test]
fn every_configuration_draws_the_frame_of_one_accelerator_bit_for_bit() {
    let (w, h, tris) = small_game(11);
    let k1 = run_ok(&config(1), w, h, &tris);
    for k in [2, 4, 8] {
        for (split, chain_break) in [(false, false), (true, false), (false, true), (true, true)] {
            for select in [Select::Random, Select::Oldest] {
                let mut c = config(k);
                (c.split, c.chain_break, c.select) = (split, chain_break, select);
                let r = run_ok(&c, w, h, &tris);
                assert!(
                    r.frame == k1.frame,
                    "K={k} split={split} chain_break={chain_break} {select:?}: frames differ"
                );
                assert_eq!(
                    r.pixels, k1.pixels,
                    "every covered pixel is rasterized once"
                );
                assert!(r.cycles < k1.cycles, "K={k} is no faster than K=1");
            }
        }
    }
}

#[test]
fn splitting_lifts_the_parallelism_of_a_frame_dominated_by_one_huge_triangle() {
    // The turok3 case in small: a sky over most of the window, then small strips.
    let p = GameParams {
        width: 160,
        height: 120,
        seed: 3,
        background_rows: 100,
        strips: 12,
        strip_triangles: 16,
        strip_width: 10.0,
        strip_step: 6.0,
        particles: 0,
        depth_levels: 1 << 16,
    };
    let tris = generate(&p);
    let mut c = config(8);
    c.chain_break = false;
    c.split = false;
    let whole = run_ok(&c, p.width, p.height, &tris);
    c.split = true;
    c.split_height = 8;
    let split = run_ok(&c, p.width, p.height, &tris);
    assert_eq!(whole.frame, split.frame);
    assert!(split.primitives > whole.primitives);
    assert!(
        split.mean_parallelism() > 1.3 * whole.mean_parallelism(),
        "{} vs {}",
        split.mean_parallelism(),
        whole.mean_parallelism()
    );
}

#[test]
fn chain_breaking_lets_a_strip_run_on_several_accelerators() {
    // One long strip: without chain breaking each triangle waits for its neighbour.
    let p = GameParams {
        width: 256,
        height: 64,
        seed: 5,
        background_rows: 0,
        strips: 1,
        strip_triangles: 60,
        strip_width: 20.0,
        strip_step: 4.0,
        particles: 0,
        depth_levels: 1 << 16,
    };
    let mut tris = generate(&p);
    // Lay the strip along the window.
    for (i, t) in tris.iter_mut().enumerate() {
        for (v, pos) in t.positions.iter_mut().enumerate() {
            let k = i + v;
            *pos = [
                4.0 + 4.0 * k as f32,
                if k % 2 == 0 { 12.0 } else { 40.0 },
                0.5,
            ];
        }
    }
    let mut c = config(8);
    c.split = false;
    c.chain_break = false;
    let chained = run_ok(&c, p.width, p.height, &tris);
    c.chain_break = true;
    let broken = run_ok(&c, p.width, p.height, &tris);
    assert_eq!(chained.frame, broken.frame);
    assert!(
        chained.mean_parallelism() < 1.2,
        "{}",
        chained.mean_parallelism()
    );
    assert!(
        broken.mean_parallelism() > 1.5 * chained.mean_parallelism(),
        "{} vs {}",
        broken.mean_parallelism(),
        chained.mean_parallelism()
    );
    assert!(chained.causes[3] > 0, "dependence stalls are counted");
}

#[test]
fn the_statistics_add_up() {
    let (w, h, tris) = small_game(13);
    let r = run_ok(&config(4), w, h, &tris);
    assert_eq!(r.busy_histogram.iter().sum::<u64>(), r.cycles);
    assert_eq!(r.causes.iter().sum::<u64>(), r.cycles);
    assert_eq!(r.windows.len() as u64, r.cycles.div_ceil(100));
    let mean: f64 = r.windows.iter().sum::<f64>() / r.windows.len() as f64;
    assert!(mean > 0.0 && r.mean_parallelism() > 1.0 && r.mean_parallelism() <= 4.0);
    assert_eq!(r.causes[1], r.primitives, "every primitive issued once");
}

#[test]
fn the_machine_description_carries_the_papers_defaults_and_names_bad_keys() {
    let m = MachineDesc::gold8();
    assert_eq!(m.s3, S3::default());
    let c = S3Config::of(&m);
    assert_eq!(
        (c.accelerators, c.candidates(), c.dest_rs()),
        (16, 128, 144)
    );
    assert_eq!(c.split_height, 32);
    let text = include_str!("../../machines/gold8.toml");
    for (from, to, key) in [
        ("accelerators = 16", "accelerators = 0", "s3.accelerators"),
        ("source_slots = 1", "source_slots = 3", "s3.source_slots"),
        ("select = \"random\"", "select = \"best\"", "s3.select"),
        ("memory = \"ideal\"", "memory = \"sram\"", "s3.memory"),
        ("split_height = 32", "split_height = 0", "s3.split_height"),
        ("select_seed = 1", "select_seed = 0", "s3.select_seed"),
    ] {
        let e = MachineDesc::parse(&text.replace(from, to), "t").unwrap_err();
        assert!(e.to_string().contains(key), "{from}: {e}");
    }
    let e = MachineDesc::parse(&text.replace("split = true", "splitt = true"), "t").unwrap_err();
    assert!(e.to_string().contains("splitt"), "{e}");
}

#[test]
fn a_trace_outside_the_window_or_empty_finishes_at_once() {
    let off = TraceTriangle {
        positions: [
            [-50.0, -50.0, 0.5],
            [-40.0, -50.0, 0.5],
            [-45.0, -40.0, 0.5],
        ],
        colours: [[1.0; 3]; 3],
        mode: Mode::Opaque,
    };
    let r = run_ok(&config(2), 32, 32, &[off, off]);
    assert_eq!((r.culled, r.primitives, r.pixels), (2, 0, 0));
    assert!(r.cycles < 20, "{}", r.cycles);
    let r = run_ok(&config(2), 32, 32, &[]);
    assert!(r.cycles < 10);
}

/// Random triangles in a small window: sizes from slivers to the whole window, few depth
/// levels (ties), both modes.
fn triangles() -> impl Strategy<Value = Vec<TraceTriangle>> {
    let vertex = (-8.0f32..72.0, -8.0f32..72.0);
    let tri = (
        [vertex.clone(), vertex.clone(), vertex],
        0u32..4,
        0u32..8,
        any::<bool>(),
    )
        .prop_map(|(v, level, shade, blended)| TraceTriangle {
            positions: v.map(|(x, y)| [x, y, 0.2 + 0.2 * level as f32]),
            colours: [[shade as f32 / 7.0, 0.5, 1.0 - shade as f32 / 7.0]; 3],
            mode: if blended { Mode::Blended } else { Mode::Opaque },
        });
    prop::collection::vec(tri, 1..24)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Any machine, with either memory, draws the in-order frame, never has two primitives
    /// in hazard in flight, retires everything within the sequential bound, and does not
    /// care in which order its blocks are evaluated (the DRAM memory's two clock domains,
    /// crossings and channels included).
    #[test]
    fn any_machine_is_exact_safe_live_and_order_independent(
        tris in triangles(),
        k in 1usize..6,
        window in 1usize..4,
        split in any::<bool>(),
        split_height in 2u16..20,
        chain_break in any::<bool>(),
        oldest in any::<bool>(),
        slots in 0usize..3,
        dram in any::<bool>(),
        latency in 1u32..4,
    ) {
        let mut c = if dram { dram_config(k) } else { config(k) };
        c.memory_latency = latency;
        c.window_per_accelerator = window;
        (c.split, c.split_height, c.chain_break) = (split, split_height, chain_break);
        c.select = if oldest { Select::Oldest } else { Select::Random };
        c.source_slots = slots;
        let r = run(&c, 64, 64, &tris, RunOptions::default()).expect("finishes");
        prop_assert_eq!(r.in_flight_hazards, 0);
        prop_assert!(r.cycles <= cycle_bound(&c, &tris, 64, 64));
        prop_assert!(r.frame == reference_frame(&tris, 64, 64), "frame differs");
        let reversed = run(&c, 64, 64, &tris, RunOptions { reverse_order: true, ..RunOptions::default() })
            .expect("finishes");
        prop_assert_eq!(reversed, r);
    }
}

/// The built-in game frames at K = 16 with every combination of the two features, and
/// through the DRAM, draw the in-order frame (`imagine s3` checks this on every run too).
#[test]
#[ignore]
fn the_builtin_game_frames_are_exact_at_sixteen_accelerators() {
    for name in ["game-strips", "game-sky"] {
        let p = GameParams::builtin(name).unwrap();
        let tris = generate(&p);
        let golden = reference_frame(&tris, p.width, p.height);
        for (split, chain_break) in [(false, false), (true, false), (false, true), (true, true)] {
            let mut c = config(16);
            (c.split, c.chain_break) = (split, chain_break);
            let r = run_ok(&c, p.width, p.height, &tris);
            assert!(
                r.frame == golden,
                "{name} split={split} chain_break={chain_break}"
            );
        }
        // Through the DRAM (about a minute each).
        let r = run_ok(&dram_config(16), p.width, p.height, &tris);
        assert!(r.frame == golden, "{name} through the DRAM");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    /// Vertices far outside a small window (clamped boxes, huge edge values) change
    /// nothing: exact, safe and live.
    #[test]
    fn far_vertices_are_clamped_and_exact(
        v in prop::collection::vec(
            ([(-1.0e6f32..1.0e6, -1.0e6f32..1.0e6), (-1.0e6f32..1.0e6, -1.0e6f32..1.0e6),
              (0.0f32..32.0, 0.0f32..32.0)], 0u32..3),
            1..8),
        k in 1usize..5,
        split in any::<bool>(),
    ) {
        let tris: Vec<TraceTriangle> = v
            .iter()
            .map(|(p, level)| TraceTriangle {
                positions: p.map(|(x, y)| [x, y, 0.3 * *level as f32]),
                colours: [[0.1 * *level as f32, 0.4, 0.9]; 3],
                mode: Mode::Opaque,
            })
            .collect();
        let mut c = config(k);
        (c.split, c.split_height) = (split, 4);
        let r = run(&c, 32, 32, &tris, RunOptions::default()).expect("finishes");
        prop_assert_eq!(r.in_flight_hazards, 0);
        prop_assert!(r.frame == reference_frame(&tris, 32, 32), "frame differs");
    }
}

/// `config(k)` with `s3.memory = "dram"`: the gold8 DRAM behind the accelerators.
fn dram_config(k: usize) -> S3Config {
    let mut c = config(k);
    c.memory = S3Memory::Dram(Box::new(MachineDesc::gold8()));
    c
}

#[test]
fn the_dram_memory_draws_the_ideal_memorys_frame_in_more_cycles() {
    let (w, h, tris) = small_game(11);
    let golden = reference_frame(&tris, w, h);
    for k in [1, 16] {
        let ideal = run_ok(&config(k), w, h, &tris);
        let dram = run_ok(&dram_config(k), w, h, &tris);
        assert_eq!(
            dram.frame, golden,
            "K={k}: the DRAM frame is not in-order drawing's"
        );
        assert_eq!(dram.frame, ideal.frame, "K={k}");
        assert_eq!(
            (dram.pixels, dram.primitives),
            (ideal.pixels, ideal.primitives)
        );
        assert!(
            dram.cycles > ideal.cycles,
            "K={k}: {} vs {}",
            dram.cycles,
            ideal.cycles
        );
        assert!(dram.mem_stall_cycles > 0 && ideal.mem_stall_cycles == 0);
        assert_eq!((ideal.memory, dram.memory), ("ideal", "dram"));
        let s = dram.dram.clone().expect("DRAM counters");
        assert!(ideal.dram.is_none());
        // Every Z access is two DRAM words, a colour access one; every read is a Z read
        // or a blend's destination read, and every passed fragment writes.
        assert!(s.fb_reads >= dram.pixels && s.fb_writes >= dram.fragments_passed);
        assert!(s.reads > s.fb_reads && s.writes > s.fb_writes);
        assert!(s.row_hits > 0 && s.activates > 0);
        eprintln!(
            "K={k}: ideal {} cycles TLP {:.2}, dram {} cycles TLP {:.2} stalls {} {:?}",
            ideal.cycles,
            ideal.mean_parallelism(),
            dram.cycles,
            dram.mean_parallelism(),
            dram.mem_stall_cycles,
            s
        );
    }
}

#[test]
fn the_dram_memory_refuses_bursts_it_would_have_to_read_modify_write() {
    let (w, h, tris) = small_game(11);
    let mut m = MachineDesc::gold8();
    m.dram.burst_words = 4;
    let mut c = config(2);
    c.memory = S3Memory::Dram(Box::new(m));
    let e = run(&c, w, h, &tris, RunOptions::default()).unwrap_err();
    assert!(e.to_string().contains("burst_words = 1"), "{e}");
}
