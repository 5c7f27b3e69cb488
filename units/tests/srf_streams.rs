//! The SRF moving streams: input streams arrive in order, output streams land in the SRF
//! after a flush, and the port's bandwidth is what the machine description says — a lone
//! stream is read at a row per cycle once primed, and streams that want more than
//! `words_per_cycle` together share it.

use imagine_hdl::{Design, default_domains};
use imagine_units::desc::MachineDesc;
use imagine_units::srf::{Grant, SbMode, Srf};

fn srf_of(desc: &MachineDesc) -> Srf {
    let mut design = Design::new("top", default_domains()).unwrap();
    let mut top = design.scope();
    Srf::new(&mut top.child("srf"), desc)
}

fn gold8() -> (MachineDesc, Srf) {
    let desc = MachineDesc::gold8();
    let srf = srf_of(&desc);
    (desc, srf)
}

/// A recognisable word for element `i` of stream `s`.
fn word(s: u32, i: usize) -> u32 {
    (s << 24) ^ (i as u32).wrapping_mul(0x9E37_79B9) >> 8
}

fn stream(s: u32, len: usize) -> Vec<u32> {
    (0..len).map(|i| word(s, i)).collect()
}

/// An input stream being read: its SB, how many words the clusters take per cycle at
/// most, and what they got.
struct Reader {
    sb: usize,
    words_per_cycle: usize,
    got: Vec<u32>,
    /// The cycle after which its stream was exhausted.
    done_at: Option<u64>,
}

impl Reader {
    fn new(sb: usize, words_per_cycle: usize) -> Self {
        Reader {
            sb,
            words_per_cycle,
            got: vec![],
            done_at: None,
        }
    }
}

/// Clocks `srf` until every reader's stream is exhausted, each reader taking the largest
/// multiple of `lanes` up to its rate that is available each cycle. Returns the cycles.
fn read_all(srf: &mut Srf, readers: &mut [Reader], limit: u64) -> u64 {
    let lanes = srf.lanes();
    let mut cycles = 0;
    while !readers.iter().all(|r| srf.exhausted(r.sb)) {
        for r in readers.iter_mut() {
            let n = srf.available(r.sb).min(r.words_per_cycle) / lanes * lanes;
            if n > 0 {
                r.got.extend_from_slice(srf.read(r.sb, n).unwrap());
            }
        }
        srf.eval();
        srf.commit();
        cycles += 1;
        for r in readers.iter_mut() {
            if r.done_at.is_none() && srf.exhausted(r.sb) {
                r.done_at = Some(cycles);
            }
        }
        assert!(cycles < limit, "streams not done after {limit} cycles");
    }
    cycles
}

#[test]
fn an_input_stream_arrives_in_order_row_by_row() {
    let (_, mut srf) = gold8();
    let data = stream(1, 1000);
    srf.load(64, &data).unwrap();
    srf.bind_input(3, 64, data.len()).unwrap();
    assert_eq!(srf.mode(3), SbMode::Input);
    assert_eq!(
        srf.available(3),
        0,
        "nothing is visible before the first transfer"
    );
    // Cycle 0: the SB asks for the first line and gets it, visible from cycle 1.
    srf.eval();
    assert_eq!(srf.grant(), Some(Grant { sb: 3, words: 16 }));
    assert_eq!(srf.available(3), 0);
    srf.commit();
    assert_eq!(srf.available(3), 16);
    let row = srf.read(3, 8).unwrap().to_vec();
    assert_eq!(row, data[..8], "element c of the row goes to cluster c");
    assert_eq!(srf.available(3), 8);
    assert_eq!(srf.remaining(3), 992);
    srf.eval();
    srf.commit();
    let mut r = [Reader::new(3, 8)];
    r[0].got = row;
    read_all(&mut srf, &mut r, 10_000);
    assert_eq!(r[0].got, data);
    assert!(srf.exhausted(3));
    assert_eq!(srf.available(3), 0);
    let st = &srf.stats().sb[3];
    assert_eq!((st.srf_words, st.cluster_words), (1000, 1000));
    // 1000 words = 62 full lines and one of 8.
    assert_eq!(st.grants, 63);
    assert_eq!(srf.stats().words_histogram[8], 1);
    srf.unbind(3).unwrap();
    assert_eq!(srf.mode(3), SbMode::Idle);
}

#[test]
fn a_read_of_several_rows_deals_words_to_clusters_round_robin() {
    let (_, mut srf) = gold8();
    let data = stream(2, 64);
    srf.load(0, &data).unwrap();
    srf.bind_input(0, 0, 64).unwrap();
    for _ in 0..3 {
        srf.eval();
        srf.commit();
    }
    assert!(srf.available(0) >= 32);
    // Four rows in one access: the clusters' full unconditional bandwidth.
    let w = srf.read(0, 32).unwrap();
    for c in 0..8 {
        let cluster: Vec<u32> = (0..4).map(|k| w[k * 8 + c]).collect();
        assert_eq!(
            cluster,
            (0..4).map(|k| data[k * 8 + c]).collect::<Vec<_>>(),
            "cluster {c}"
        );
    }
}

#[test]
fn an_output_stream_lands_in_the_srf_after_a_flush() {
    let (_, mut srf) = gold8();
    let sentinel = vec![0xDEAD_BEEF; 1024];
    srf.load(2048, &sentinel).unwrap();
    // 1000 words: the last line is partial (1000 = 62 × 16 + 8) and only leaves on flush.
    let data = stream(3, 1000);
    srf.bind_output(5, 2048, 1000).unwrap();
    let mut written = 0;
    let mut cycles = 0;
    while written < data.len() {
        if srf.space(5) >= 8 {
            srf.write(5, &data[written..written + 8]).unwrap();
            written += 8;
        }
        srf.eval();
        srf.commit();
        cycles += 1;
        assert!(cycles < 10_000);
    }
    assert_eq!(srf.output_len(5), 1000);
    assert!(!srf.flushed(5) && !srf.idle(), "not flushed yet");
    // Without the flush the partial line never leaves.
    for _ in 0..20 {
        srf.eval();
        srf.commit();
    }
    assert!(!srf.flushed(5));
    assert_eq!(srf.read_back(2048 + 992, 8).unwrap(), sentinel[..8]);
    srf.flush(5).unwrap();
    srf.eval();
    assert_eq!(srf.grant(), None, "the flush takes effect at the edge");
    srf.commit();
    assert_eq!(srf.mode(5), SbMode::Flushing);
    let mut drain = 0;
    while !srf.flushed(5) {
        srf.eval();
        srf.commit();
        drain += 1;
        assert!(drain < 100);
    }
    assert_eq!(drain, 1, "one partial line was left");
    assert!(srf.idle());
    assert_eq!(srf.read_back(2048, 1000).unwrap(), data);
    let tail = srf.read_back(3040, 32).unwrap();
    assert_eq!(tail[..8], data[992..]);
    assert_eq!(tail[8..], sentinel[8..32], "beyond the stream");
    srf.unbind(5).unwrap();
}

#[test]
fn a_write_in_the_cycle_of_the_flush_is_part_of_the_stream() {
    let (_, mut srf) = gold8();
    srf.bind_output(1, 0, 64).unwrap();
    // flush first, then write, in the same cycle: order does not matter.
    srf.flush(1).unwrap();
    srf.write(1, &[7; 8]).unwrap();
    srf.eval();
    srf.commit();
    while !srf.flushed(1) {
        srf.eval();
        srf.commit();
    }
    assert_eq!(srf.output_len(1), 8);
    assert_eq!(srf.read_back(0, 8).unwrap(), [7; 8]);
}

#[test]
fn a_lone_stream_is_read_at_a_row_per_cycle_once_primed() {
    let (desc, mut srf) = gold8();
    let lanes = desc.cluster.count;
    let len = 4096;
    let data = stream(4, len);
    srf.load(0, &data).unwrap();
    srf.bind_input(0, 0, len).unwrap();
    let mut r = [Reader::new(0, lanes)];
    let cycles = read_all(&mut srf, &mut r, 100_000);
    assert_eq!(r[0].got, data);
    // One cycle to bring the first line in, then one row every cycle.
    let ideal = (len / lanes) as u64;
    println!("lone stream, 1 row/cycle: {len} words in {cycles} cycles (ideal {ideal} + 1)");
    assert!(cycles <= ideal + 2, "{cycles} cycles for {ideal} rows");
    assert_eq!(
        srf.stats().sb[0].starved_cycles,
        1,
        "only the first cycle lacks a row"
    );
}

#[test]
fn a_lone_stream_can_use_the_whole_port() {
    let (desc, mut srf) = gold8();
    let wpc = desc.srf.words_per_cycle;
    let len = 4096;
    let data = stream(5, len);
    srf.load(0, &data).unwrap();
    srf.bind_input(0, 0, len).unwrap();
    let mut r = [Reader::new(0, wpc)];
    let cycles = read_all(&mut srf, &mut r, 100_000);
    assert_eq!(r[0].got, data);
    let ideal = (len / wpc) as u64;
    println!(
        "lone stream, {wpc} words/cycle: {cycles} cycles (ideal {ideal}), port {:.2} words/cycle",
        srf.stats().words_per_cycle()
    );
    assert!(cycles <= ideal + 2, "{cycles} cycles, ideal {ideal}");
    assert!(srf.stats().words_per_cycle() > 0.99 * wpc as f64);
}

/// Reads `k` streams of `len` words concurrently, each at up to `rate` words per cycle;
/// returns the cycles and the port's mean words per cycle. The round-robin arbiter serves
/// them fairly: they finish within a few cycles of each other.
fn concurrent(k: usize, len: usize, rate: usize) -> (u64, f64) {
    let (_, mut srf) = gold8();
    let mut readers = Vec::new();
    let mut data = Vec::new();
    for s in 0..k {
        let d = stream(s as u32 + 10, len);
        let start = s * len.next_multiple_of(32);
        srf.load(start, &d).unwrap();
        // Spread the SBs over the index space: round robin must not care.
        let sb = s * 5;
        srf.bind_input(sb, start, len).unwrap();
        readers.push(Reader::new(sb, rate));
        data.push(d);
    }
    let cycles = read_all(&mut srf, &mut readers, 1_000_000);
    for (r, d) in readers.iter().zip(&data) {
        assert_eq!(&r.got, d, "sb{}", r.sb);
    }
    let done: Vec<u64> = readers.iter().map(|r| r.done_at.unwrap()).collect();
    let spread = done.iter().max().unwrap() - done.iter().min().unwrap();
    assert!(
        spread <= 4,
        "unfair arbitration: streams finished at {done:?}"
    );
    (cycles, srf.stats().words_per_cycle())
}

#[test]
fn streams_that_want_more_than_the_port_share_it() {
    let desc = MachineDesc::gold8();
    let (lanes, wpc) = (desc.cluster.count, desc.srf.words_per_cycle);
    let len = 2048;
    // At the port's full rate, two streams need twice the cycles of one.
    let (one, _) = concurrent(1, len, wpc);
    let (two, port) = concurrent(2, len, wpc);
    let bound = (2 * len / wpc) as u64;
    println!(
        "2 streams × {wpc} words/cycle: {two} cycles (one alone {one}), port {port:.2} words/cycle"
    );
    assert!(two >= bound, "{two} cycles beat the port's {bound}");
    assert!(two <= bound + 4, "{two} cycles, port bound {bound}");
    let ratio = two as f64 / one as f64;
    assert!((1.9..=2.1).contains(&ratio), "ratio {ratio}");
    // Four streams at a row per cycle each (32 words/cycle: all the clusters' bandwidth)
    // want twice what the port gives: they take twice as long as one such stream.
    let (one_row, _) = concurrent(1, len, lanes);
    let (four, port) = concurrent(4, len, lanes);
    let bound = (4 * len / wpc) as u64;
    println!(
        "4 streams × {lanes} words/cycle: {four} cycles (one alone {one_row}), port {port:.2} words/cycle"
    );
    assert!(four >= bound && four <= bound + 8, "{four} vs {bound}");
    let ratio = four as f64 / one_row as f64;
    assert!((1.9..=2.1).contains(&ratio), "ratio {ratio}");
    assert!(port > 0.99 * wpc as f64, "port {port}");
}

#[test]
fn two_streams_at_a_row_per_cycle_fit_in_the_port() {
    let desc = MachineDesc::gold8();
    let lanes = desc.cluster.count;
    let len = 2048;
    // 2 × 8 = 16 words/cycle: exactly the port. Neither slows down much.
    let (one, _) = concurrent(1, len, lanes);
    let (two, port) = concurrent(2, len, lanes);
    println!("2 streams × {lanes} words/cycle: {two} cycles (one alone {one}), port {port:.2}");
    assert!(two <= one + 4, "{two} vs {one}");
}

#[test]
fn a_copy_kernel_reads_and_writes_a_row_per_cycle() {
    let (desc, mut srf) = gold8();
    let lanes = desc.cluster.count;
    let len = 2048;
    let data = stream(6, len);
    srf.load(0, &data).unwrap();
    srf.bind_input(2, 0, len).unwrap();
    srf.bind_output(9, 4096, len).unwrap();
    let mut cycles = 0u64;
    let mut row = vec![0u32; lanes];
    // The kernel: a row in, the same row out (no pipeline latency modelled here).
    let mut held = false;
    while !srf.exhausted(2) || held {
        if held && srf.space(9) >= lanes {
            srf.write(9, &row).unwrap();
            held = false;
        }
        if !held && srf.available(2) >= lanes {
            row.copy_from_slice(srf.read(2, lanes).unwrap());
            held = true;
        }
        srf.eval();
        srf.commit();
        cycles += 1;
        assert!(cycles < 100_000);
    }
    srf.flush(9).unwrap();
    while !srf.idle() {
        srf.eval();
        srf.commit();
        cycles += 1;
    }
    let ideal = (len / lanes) as u64;
    println!("copy kernel: {len} words in and out in {cycles} cycles (ideal {ideal})");
    assert!(cycles <= ideal + 6, "{cycles} vs {ideal}");
    assert_eq!(srf.read_back(4096, len).unwrap(), data);
}

#[test]
fn conditional_accesses_take_any_word_count() {
    let (desc, mut srf) = gold8();
    let lanes = desc.cluster.count;
    // A short stream (one partial line) and a long one whose odd-sized writes wrap around
    // the output buffer's ring at every possible offset.
    for (k, len) in [37, 1000].into_iter().enumerate() {
        let (sb_in, sb_out) = (2 * k, 2 * k + 1);
        let out = 8192 + 2048 * k;
        let data = stream(7 + k as u32, len);
        srf.load(2048 * k, &data).unwrap();
        srf.bind_input(sb_in, 2048 * k, len).unwrap();
        srf.bind_output(sb_out, out, len).unwrap();
        let mut got = vec![];
        let mut cycles = 0;
        while !srf.exhausted(sb_in) {
            // A varying number of clusters want a word each cycle; what they read goes
            // straight back out, and reads and writes share the conditional bandwidth.
            let want = (cycles % (lanes / 2) + 1).min(srf.available(sb_in));
            let w = srf.read_conditional(sb_in, want).unwrap().to_vec();
            srf.write_conditional(sb_out, &w).unwrap();
            got.extend(w);
            srf.eval();
            srf.commit();
            cycles += 1;
            assert!(cycles < 10_000);
        }
        srf.flush(sb_out).unwrap();
        while !srf.idle() {
            srf.eval();
            srf.commit();
        }
        assert_eq!(got, data, "{len} words in");
        assert_eq!(srf.output_len(sb_out), len);
        assert_eq!(srf.read_back(out, len).unwrap(), data, "{len} words out");
    }
}

#[test]
fn a_stream_starting_mid_line_wraps_the_input_ring() {
    // gold32's port line is 64 words, its blocks 32: a stream at block 1 starts with a
    // half line, so every later transfer straddles the end of the 256-word ring once.
    let desc = MachineDesc::resolve("gold32").unwrap();
    let mut srf = srf_of(&desc);
    let len = 2000;
    let data = stream(11, len);
    srf.load(32, &data).unwrap();
    srf.bind_input(0, 32, len).unwrap();
    let mut got = vec![];
    let mut cycles = 0;
    while !srf.exhausted(0) {
        // Odd-sized conditional reads, so reads straddle the ring's end too.
        let n = (7 + cycles % 19).min(srf.available(0));
        got.extend_from_slice(srf.read_conditional(0, n).unwrap());
        srf.eval();
        srf.commit();
        cycles += 1;
        assert!(cycles < 10_000);
    }
    assert_eq!(got, data);
    let first = srf.stats().words_histogram[32];
    assert!(first >= 1, "the first transfer was a half line");
}

#[test]
fn evaluation_order_does_not_matter() {
    // Reading before or after the arbiter's eval gives the same cycle-by-cycle history.
    let history = |reads_first: bool| {
        let (_, mut srf) = gold8();
        let data = stream(8, 512);
        srf.load(0, &data).unwrap();
        srf.bind_input(0, 0, 512).unwrap();
        srf.bind_input(1, 0, 512).unwrap();
        let mut h = vec![];
        for t in 0..200 {
            if !reads_first {
                srf.eval();
            }
            for sb in [0, 1] {
                let n = srf.available(sb).min(8 * (1 + (t + sb) % 2)) / 8 * 8;
                if n > 0 {
                    srf.read(sb, n).unwrap();
                }
            }
            if reads_first {
                srf.eval();
            }
            h.push((srf.grant(), srf.available(0), srf.available(1)));
            srf.commit();
        }
        h
    };
    assert_eq!(history(true), history(false));
}

#[test]
fn wide_machines_move_a_whole_port_width_per_cycle() {
    // gold32: 64 words/cycle over 32-word blocks: a transfer spans two blocks (two banks).
    for name in ["gold32", "gold16", "gold1"] {
        let desc = MachineDesc::resolve(name).unwrap();
        let mut srf = srf_of(&desc);
        let (lanes, wpc) = (desc.cluster.count, desc.srf.words_per_cycle);
        let len = 64 * wpc;
        let data = stream(9, len);
        srf.load(0, &data).unwrap();
        srf.bind_input(0, 0, len).unwrap();
        let rate = wpc.min(lanes * desc.srf.cluster_words_per_cycle);
        let mut r = [Reader::new(0, rate)];
        let cycles = read_all(&mut srf, &mut r, 100_000);
        assert_eq!(r[0].got, data, "{name}");
        let ideal = (len / rate) as u64;
        println!("{name}: {len} words at {rate}/cycle in {cycles} cycles (ideal {ideal})");
        assert!(cycles <= ideal + 2, "{name}: {cycles} vs {ideal}");
        assert_eq!(srf.stats().grants as usize, len / wpc, "{name}: full lines");
    }
}

#[test]
fn blocks_are_interleaved_across_banks() {
    let (desc, srf) = gold8();
    let (bw, banks) = (desc.srf.block_words, desc.srf.banks);
    assert_eq!(srf.bank_of(0), 0);
    assert_eq!(srf.bank_of(bw - 1), 0);
    assert_eq!(srf.bank_of(bw), 1);
    assert_eq!(srf.bank_of(bw * banks), 0);
    assert_eq!(srf.bank_of(bw * (banks + 3) + 5), 3);
    assert_eq!(srf.sb_capacity(), 64);
    assert_eq!(srf.words(), 32768);
}
