//! The stream controller runs a load–kernel–store chain over several batches on the whole
//! processor (address generators, SDRAM channels, clusters, SRF). With two SRF buffers the
//! scoreboard lets the next batch's loads run while the current batch's kernel computes;
//! with one buffer it cannot, and the cycle counts show the difference.

use imagine_units::arith::fp32::{self, FpMode};
use imagine_units::desc::MachineDesc;
use imagine_units::machine::StreamBinding;
use imagine_units::memory::{MemOp, MemOpKind, Pattern};
use imagine_units::microcode::asm::assemble;
use imagine_units::processor::{self, ProcessorOptions, StreamProgram, StreamReport};
use imagine_units::stream_controller::StreamInstr;

const N: usize = 512;
const BATCHES: usize = 4;
/// DRAM word addresses of the x, y, w inputs and the z output (batch b at + b·N).
const X: u64 = 0;
const Y: u64 = 0x1_0000;
const W: u64 = 0x2_0000;
const Z: u64 = 0x3_0000;

struct Rng(u64);
impl Rng {
    fn float(&mut self) -> u32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let x = (self.0 >> 32) as u32;
        (0x3C00_0000 + (x & 0x7FF_FFFF) % 0x0480_0000) | (x & 0x8000_0000)
    }
}

fn strided(kind: MemOpKind, base: u64, srf_start: usize) -> StreamInstr {
    StreamInstr::Memory(MemOp {
        kind,
        base,
        pattern: Pattern::Strided { stride: 1 },
        record_words: 1,
        records: N,
        srf_start,
        row_records: 1,
        cacheable: false,
    })
}

/// The stream program: load the microcode, then per batch three loads, madd, one store.
/// Batch `b` uses SRF buffer `b % buffers` (each buffer: x, y, w, z of N words).
/// z = x·y + w word by word, as the madd kernel computes it.
fn madd_expected(x: &[u32], y: &[u32], w: &[u32]) -> Vec<u32> {
    x.iter()
        .zip(y)
        .zip(w)
        .map(|((&x, &y), &w)| fp32::add(fp32::mul(x, y, FpMode::IEEE).0, w, FpMode::IEEE).0)
        .collect()
}

/// The madd kernel (program 0) over x, y, w and z streams of `N` words starting at these
/// SRF words.
fn madd_kernel(starts: [usize; 4]) -> StreamInstr {
    StreamInstr::Kernel {
        program: 0,
        bindings: starts
            .map(|start| StreamBinding { start, words: N })
            .to_vec(),
    }
}

fn chain(buffers: usize, desc: &MachineDesc) -> StreamProgram {
    let text = include_str!("microcode/madd.uc");
    let madd = assemble(text, desc).expect("madd assembles");
    let mut instrs = vec![StreamInstr::LoadMicrocode { program: 0 }];
    for b in 0..BATCHES {
        let s = (b % buffers) * 4 * N;
        let off = (b * N) as u64;
        let (sx, sy, sw, sz) = (s, s + N, s + 2 * N, s + 3 * N);
        instrs.push(strided(MemOpKind::Load, X + off, sx));
        instrs.push(strided(MemOpKind::Load, Y + off, sy));
        instrs.push(strided(MemOpKind::Load, W + off, sw));
        instrs.push(madd_kernel([sx, sy, sw, sz]));
        instrs.push(strided(MemOpKind::Store, Z + off, sz));
    }
    StreamProgram {
        kernels: vec![madd],
        instrs,
    }
}

fn run(buffers: usize) -> (StreamReport, Vec<u32>, Vec<u32>) {
    let desc = MachineDesc::gold8();
    let mut rng = Rng(7);
    let total = N * BATCHES;
    let [x, y, w]: [Vec<u32>; 3] =
        std::array::from_fn(|_| (0..total).map(|_| rng.float()).collect());
    let expected = madd_expected(&x, &y, &w);
    let opts = ProcessorOptions {
        dram_init: vec![(X, x), (Y, y), (W, w)],
        record_dram: true,
        ..ProcessorOptions::default()
    };
    let mut sim = processor::build(&desc, chain(buffers, &desc), opts).expect("builds");
    let report = processor::run(&mut sim, &desc, 2_000_000).expect("runs");
    let z = processor::read_dram(&sim, &desc, Z, total);
    (report, z, expected)
}

fn span(r: &StreamReport, i: usize) -> (u64, u64) {
    let rec = &r.records[i];
    (rec.issued.unwrap(), rec.completed.unwrap())
}

fn show(r: &StreamReport) {
    for (i, rec) in r.records.iter().enumerate() {
        eprintln!(
            "{i:3} {:<16} entered {:>6?} issued {:>6?} completed {:>6?} on {:?}",
            r.names[i], rec.entered, rec.issued, rec.completed, rec.unit
        );
    }
    eprintln!("core cycles {}", r.core_cycles);
}

#[test]
fn double_buffering_overlaps_the_next_load_with_the_kernel() {
    let (double, z, expected) = run(2);
    show(&double);
    assert_eq!(z, expected, "the results in DRAM");
    assert!(
        double.dram.violations.is_empty(),
        "{:?}",
        double.dram.violations
    );
    // Instruction layout: 0 microcode, then per batch b at 1 + 5b: 3 loads, kernel, store.
    let kernel = |b: usize| 1 + 5 * b + 3;
    for b in 0..BATCHES - 1 {
        let (k_start, k_end) = span(&double, kernel(b));
        let (next_load, _) = span(&double, kernel(b + 1) - 3);
        assert!(
            next_load < k_end,
            "batch {}'s first load issued at {next_load}, after kernel {b} ended at {k_end}",
            b + 1
        );
        assert!(k_end - k_start >= 300, "the minimum kernel duration");
    }
    let (single, z1, _) = run(1);
    show(&single);
    assert_eq!(z1, expected);
    // One buffer: the next batch's loads wait for the kernel that reads the buffer.
    for b in 0..BATCHES - 1 {
        let (_, k_end) = span(&single, kernel(b));
        let (next_load, _) = span(&single, kernel(b + 1) - 3);
        assert!(
            next_load > k_end,
            "single buffer: batch {} load at {next_load}",
            b + 1
        );
    }
    eprintln!(
        "double-buffered {} core cycles, single-buffered {} core cycles",
        double.core_cycles, single.core_cycles
    );
    assert!(
        (double.core_cycles as f64) < 0.85 * single.core_cycles as f64,
        "overlap saves at least 15%: {} vs {}",
        double.core_cycles,
        single.core_cycles
    );
}

/// Everything a run of the madd chain on `desc` reports and leaves in DRAM, its core
/// cycles, and the core cycles it jumped over as idle time.
fn chain_results(desc: &MachineDesc, buffers: usize, step_idle: bool) -> (String, u64, u64) {
    let mut rng = Rng(7);
    let total = N * BATCHES;
    let [x, y, w]: [Vec<u32>; 3] =
        std::array::from_fn(|_| (0..total).map(|_| rng.float()).collect());
    let expected = madd_expected(&x, &y, &w);
    let opts = ProcessorOptions {
        dram_init: vec![(X, x), (Y, y), (W, w)],
        step_idle,
        ..ProcessorOptions::default()
    };
    let mut sim = processor::build(desc, chain(buffers, desc), opts).expect("builds");
    let r = processor::run(&mut sim, desc, 1 << 40).expect("runs");
    assert_eq!(processor::read_dram(&sim, desc, Z, total), expected);
    let p = processor::processor(&sim);
    let ags: Vec<_> = p.address_generators().iter().map(|a| a.stats()).collect();
    let channels: Vec<_> = sim
        .modules_of::<imagine_units::dram::DramChannel>()
        .map(|c| (c.stats().clone(), c.violations().to_vec()))
        .collect();
    let results = format!(
        "cycles {} {}\nrecords {:?}\nnames {:?}\ndram {:?}\nsc {:?}\nsrf {:?}\nags {:?}\n\
         lrf {:?}\nchannels {channels:?}",
        r.core_cycles,
        r.dram_cycles,
        r.records,
        r.names,
        r.dram,
        p.controller().stats(),
        p.machine().srf().stats(),
        ags,
        p.machine().lrf_words_moved(),
    );
    (results, r.core_cycles, p.skipped_cycles())
}

/// Kernels that hold the clusters far longer than they run (the host's dispatch overhead):
/// jumping over the idle cycles gives every result, count and statistic stepping gives.
#[test]
fn jumping_over_idle_time_gives_what_stepping_gives() {
    let gold8 = MachineDesc::gold8();
    let refi = gold8.dram.refresh_interval as u64 * gold8.clocks.core_mhz / gold8.clocks.dram_mhz;
    for (min, buffers) in [(100_000, 2), (100_000, 1), (refi + 3, 2), (300, 2)] {
        let mut desc = gold8.clone();
        desc.stream_controller.min_kernel_cycles = min;
        let (jumped, _, skipped) = chain_results(&desc, buffers, false);
        let (stepped, _, none) = chain_results(&desc, buffers, true);
        assert!(jumped == stepped, "min {min}:\n{jumped}\n{stepped}");
        assert_eq!(none, 0);
        // A channel leaves its last row open until the next refresh closes it; from
        // then on the idle time is jumped over.
        if min > refi {
            assert!(skipped > 0, "min {min}");
        }
        if min > 10 * refi {
            assert!(
                skipped > (BATCHES as u64 - 1) * min / 2,
                "min {min}: {skipped}"
            );
        }
    }
}

/// The longest minimum kernel time a machine may ask for finishes at once: the idle time
/// is jumped over.
#[test]
fn kernels_held_for_the_longest_minimum_time_finish() {
    let mut desc = MachineDesc::gold8();
    desc.stream_controller.min_kernel_cycles = 1 << 24;
    desc.validate().unwrap();
    let (_, cycles, skipped) = chain_results(&desc, 2, false);
    assert!(cycles >= (BATCHES as u64) << 24, "{cycles}");
    assert!(skipped > (BATCHES as u64 - 1) << 24);
}

#[test]
fn gather_record_and_scatter_streams_move_the_right_words() {
    gather_record_and_scatter(1);
}

/// The same streams with each row of 8 records stored word by word in the SRF (the layout
/// kernels read): memory sees the same records, the SRF holds them transposed per row.
#[test]
fn cluster_row_layout_transposes_records_in_the_srf_only() {
    gather_record_and_scatter(8);
}

fn gather_record_and_scatter(row_records: usize) {
    let desc = MachineDesc::gold8();
    const T: u64 = 0x4_0000; // table
    const D: u64 = 0x5_0000; // strided record store
    const S: u64 = 0x6_0000; // scatter target
    let k = 64usize;
    let table: Vec<u32> = (0..2 * k as u32 + 8).map(|i| 0xA000_0000 | i).collect();
    // A permutation of 0..k as the index stream.
    let index: Vec<u32> = (0..k as u32).map(|i| (i * 37 + 5) % k as u32).collect();
    let mem = |kind, base, pattern, srf_start| {
        StreamInstr::Memory(MemOp {
            kind,
            base,
            pattern,
            record_words: 2,
            records: k,
            srf_start,
            row_records,
            cacheable: false,
        })
    };
    let indexed = Pattern::Indexed {
        index_start: 0,
        scale: 2,
        bound: None,
    };
    let program = StreamProgram {
        kernels: vec![],
        instrs: vec![
            mem(MemOpKind::Load, T, indexed, 1024),
            mem(MemOpKind::Store, D, Pattern::Strided { stride: 3 }, 1024),
            mem(MemOpKind::Store, S, indexed, 1024),
        ],
    };
    let opts = ProcessorOptions {
        dram_init: vec![(T, table.clone())],
        srf_init: vec![(0, index.clone())],
        ..ProcessorOptions::default()
    };
    let mut sim = processor::build(&desc, program, opts).expect("builds");
    let r = processor::run(&mut sim, &desc, 1_000_000).expect("runs");
    assert!(r.dram.violations.is_empty());
    let gathered: Vec<u32> = index
        .iter()
        .flat_map(|&i| [table[2 * i as usize], table[2 * i as usize + 1]])
        .collect();
    let srf = processor::processor(&sim)
        .machine()
        .srf()
        .read_back(1024, 2 * k)
        .unwrap();
    let r_ = row_records;
    let laid_out: Vec<u32> = (0..2 * k)
        .map(|n| {
            let (row, within) = (n / (2 * r_), n % (2 * r_));
            gathered[2 * (row * r_ + within % r_) + within / r_]
        })
        .collect();
    assert_eq!(srf, laid_out, "gather");
    let d = processor::read_dram(&sim, &desc, D, 3 * k);
    for (n, rec) in gathered.chunks(2).enumerate() {
        assert_eq!(&d[3 * n..3 * n + 2], rec, "record {n} of the strided store");
        assert_eq!(d[3 * n + 2], 0, "the gap between records is untouched");
    }
    // Scattering the gathered records back through the same indices rebuilds the table.
    let s = processor::read_dram(&sim, &desc, S, 2 * k);
    assert_eq!(s, table[..2 * k], "scatter");
    // The three operations depend on each other (SRF, then DRAM via the indexed range).
    let (a, b, c) = (&r.records[0], &r.records[1], &r.records[2]);
    assert!(b.issued > a.completed && c.issued > b.completed);
}

/// A bounds register tells the scoreboard where an indexed stream may go: a gather from a
/// table with a bound overlaps a store elsewhere in memory, one without a bound waits for
/// it, and an index past the bound stops the gather with an error.
#[test]
fn a_bounded_gather_overlaps_a_store_elsewhere() {
    let desc = MachineDesc::gold8();
    const T: u64 = 0x4_0000; // table
    const D: u64 = 0x5_0000; // store target
    let k = 64usize;
    let index: Vec<u32> = (0..k as u32).map(|i| (i * 37 + 5) % k as u32).collect();
    let run = |bound: Option<u64>| {
        let op = |kind, base, pattern, records, srf_start| {
            StreamInstr::Memory(MemOp {
                kind,
                base,
                pattern,
                record_words: 1,
                records,
                srf_start,
                row_records: 1,
                cacheable: false,
            })
        };
        let gather = Pattern::Indexed {
            index_start: 0,
            scale: 1,
            bound,
        };
        let program = StreamProgram {
            kernels: vec![],
            instrs: vec![
                op(
                    MemOpKind::Store,
                    D,
                    Pattern::Strided { stride: 1 },
                    4096,
                    8192,
                ),
                op(MemOpKind::Load, T, gather, k, 1024),
            ],
        };
        let opts = ProcessorOptions {
            srf_init: vec![(0, index.clone())],
            ..ProcessorOptions::default()
        };
        let mut sim = processor::build(&desc, program, opts).expect("builds");
        processor::run(&mut sim, &desc, 1_000_000).map(|r| {
            (
                r.records[0].completed.unwrap(),
                r.records[1].issued.unwrap(),
            )
        })
    };
    let (store_done, gather_issued) = run(None).expect("runs");
    assert!(
        gather_issued > store_done,
        "without a bound the gather waits"
    );
    let (store_done, gather_issued) = run(Some(k as u64)).expect("runs");
    assert!(
        gather_issued < store_done,
        "with a bound the gather overlaps"
    );
    // The permutation holds index k − 1.
    let err = run(Some(k as u64 - 1)).expect_err("an index past the bound");
    assert!(err.to_string().contains("past its bound"), "{err}");
}

#[test]
fn host_writes_land_before_their_reader_and_after_the_previous_one() {
    let desc = MachineDesc::gold8();
    let per_cycle = desc.stream_controller.host_words_per_cycle;
    let mut rng = Rng(11);
    let [x, y, w, x2]: [Vec<u32>; 4] =
        std::array::from_fn(|_| (0..N).map(|_| rng.float()).collect());
    let (sx, sy, sw, sz, sz2) = (0, N, 2 * N, 3 * N, 4 * N);
    let madd = |x: usize, z: usize| madd_kernel([x, sy, sw, z]);
    let instrs = vec![
        StreamInstr::LoadMicrocode { program: 0 },
        StreamInstr::WriteSrf {
            start: sx,
            words: x.clone(),
        },
        StreamInstr::WriteSrf {
            start: sy,
            words: y.clone(),
        },
        strided(MemOpKind::Load, W, sw),
        madd(sx, sz),
        strided(MemOpKind::Store, Z, sz),
        // Overwrites the first kernel's input: it must wait for that kernel.
        StreamInstr::WriteSrf {
            start: sx,
            words: x2.clone(),
        },
        madd(sx, sz2),
        strided(MemOpKind::Store, Z + N as u64, sz2),
    ];
    let program = StreamProgram {
        kernels: vec![assemble(include_str!("microcode/madd.uc"), &desc).unwrap()],
        instrs,
    };
    let opts = ProcessorOptions {
        dram_init: vec![(W, w.clone())],
        ..ProcessorOptions::default()
    };
    let mut sim = processor::build(&desc, program, opts).expect("builds");
    let r = processor::run(&mut sim, &desc, 2_000_000).expect("runs");
    show(&r);
    let z = processor::read_dram(&sim, &desc, Z, 2 * N);
    let madd_of = |x: &[u32]| madd_expected(x, &y, &w);
    assert_eq!(z[..N], madd_of(&x), "the first kernel read the first write");
    assert_eq!(
        z[N..],
        madd_of(&x2),
        "the second kernel read the second write"
    );
    for write in [1, 2, 6] {
        let (issued, completed) = span(&r, write);
        assert_eq!(
            completed - issued,
            N.div_ceil(per_cycle) as u64,
            "host write {write} moves {per_cycle} words per cycle"
        );
    }
    // One host interface: the second write waits for the first.
    assert!(span(&r, 2).0 >= span(&r, 1).1);
    assert!(
        span(&r, 4).0 >= span(&r, 2).1,
        "the kernel waits for its inputs"
    );
    assert!(
        span(&r, 6).0 >= span(&r, 4).1,
        "the rewrite waits for the reader"
    );
}

#[test]
fn host_reads_take_a_kernels_output_after_it_and_before_its_next_writer() {
    let desc = MachineDesc::gold8();
    let per_cycle = desc.stream_controller.host_words_per_cycle;
    let mut rng = Rng(13);
    let [x, y, w, rewrite]: [Vec<u32>; 4] =
        std::array::from_fn(|_| (0..N).map(|_| rng.float()).collect());
    let (sx, sy, sw, sz) = (0, N, 2 * N, 3 * N);
    let instrs = vec![
        StreamInstr::LoadMicrocode { program: 0 },
        StreamInstr::WriteSrf {
            start: sx,
            words: x.clone(),
        },
        StreamInstr::WriteSrf {
            start: sy,
            words: y.clone(),
        },
        StreamInstr::WriteSrf {
            start: sw,
            words: w.clone(),
        },
        madd_kernel([sx, sy, sw, sz]),
        // Reads the kernel's output: it must wait for the kernel.
        StreamInstr::ReadSrf { start: sz, len: N },
        // Overwrites what the read takes: it must wait for the read.
        StreamInstr::WriteSrf {
            start: sz,
            words: rewrite.clone(),
        },
        StreamInstr::ReadSrf { start: sz, len: 32 },
    ];
    let program = StreamProgram {
        kernels: vec![assemble(include_str!("microcode/madd.uc"), &desc).unwrap()],
        instrs,
    };
    let mut sim = processor::build(&desc, program, ProcessorOptions::default()).expect("builds");
    let r = processor::run(&mut sim, &desc, 2_000_000).expect("runs");
    show(&r);
    let z = madd_expected(&x, &y, &w);
    assert_eq!(
        r.records[5].read, z,
        "the read brings back the kernel's output"
    );
    assert_eq!(
        r.records[7].read,
        rewrite[..32],
        "and the next read the rewrite"
    );
    assert!(
        r.records[4].read.is_empty(),
        "only host reads bring words back"
    );
    assert!(
        span(&r, 5).0 >= span(&r, 4).1,
        "the read waits for the kernel that writes its words"
    );
    assert_eq!(
        span(&r, 5).1 - span(&r, 5).0,
        N.div_ceil(per_cycle) as u64,
        "a host read moves {per_cycle} words per cycle"
    );
    assert!(
        span(&r, 6).0 >= span(&r, 5).1,
        "the rewrite waits for the read"
    );
}

#[test]
fn a_host_read_past_the_srf_is_refused_before_the_run() {
    let desc = MachineDesc::gold8();
    let program = StreamProgram {
        kernels: Vec::new(),
        instrs: vec![StreamInstr::ReadSrf {
            start: desc.srf.words - 32,
            len: 64,
        }],
    };
    let err = processor::build(&desc, program, ProcessorOptions::default())
        .err()
        .expect("refused");
    assert!(err.to_string().contains("stream instruction 0"), "{err}");
}
