//! Every misuse of the SRF is a contract error that names where it happened and what the
//! limit was, and leaves the SRF as it was.

use imagine_hdl::{ContractError, Design, default_domains};
use imagine_units::desc::MachineDesc;
use imagine_units::srf::{SbMode, Srf};

fn gold8() -> Srf {
    let mut design = Design::new("top", default_domains()).unwrap();
    let mut top = design.scope();
    Srf::new(&mut top.child("srf"), &MachineDesc::gold8())
}

fn clock(srf: &mut Srf, n: usize) {
    for _ in 0..n {
        srf.eval();
        srf.commit();
    }
}

/// Asserts that `e` is located at `path` and its message holds every one of `parts`.
#[track_caller]
fn expect(e: ContractError, path: &str, parts: &[&str]) {
    let msg = e.to_string();
    assert_eq!(format!("{}.{}", e.module, e.signal), path, "{msg}");
    for p in parts {
        assert!(msg.contains(p), "`{p}` missing from: {msg}");
    }
}

#[test]
fn host_accesses_must_be_aligned_and_inside_the_array() {
    let mut srf = gold8();
    let e = srf.load(33, &[1, 2, 3]).unwrap_err();
    expect(e, "top.srf.load", &["start 33", "32-word block", "3 words"]);
    let e = srf.load(32768 - 32, &[0; 40]).unwrap_err();
    expect(e, "top.srf.load", &["32736", "40", "capacity 32768"]);
    let e = srf.read_back(16, 4).unwrap_err();
    expect(e, "top.srf.read_back", &["start 16", "32-word block"]);
    let e = srf.read_back(32768, 1).unwrap_err();
    expect(e, "top.srf.read_back", &["32768", "capacity 32768"]);
    let e = srf.read_back(0, usize::MAX).unwrap_err();
    expect(e, "top.srf.read_back", &["capacity 32768"]);
    // Nothing was written by the refused load; the edges are fine.
    assert_eq!(srf.read_back(32768 - 32, 32).unwrap(), vec![0; 32]);
    srf.load(32768 - 32, &[5; 32]).unwrap();
    assert_eq!(srf.read_back(32768 - 32, 32).unwrap(), vec![5; 32]);
    assert!(srf.read_back(0, 0).unwrap().is_empty());
}

#[test]
fn binding_checks_the_buffer_and_the_region() {
    let mut srf = gold8();
    let e = srf.bind_input(22, 0, 64).unwrap_err();
    expect(
        e,
        "top.srf.bind",
        &["stream buffer 22", "gold8", "22", "sb21"],
    );
    let e = srf.bind_output(30, 0, 64).unwrap_err();
    expect(e, "top.srf.bind", &["stream buffer 30"]);
    let e = srf.bind_input(4, 40, 64).unwrap_err();
    expect(
        e,
        "top.srf.sb4.bind",
        &["input stream", "start 40", "32-word block"],
    );
    let e = srf.bind_output(4, 32768 - 64, 65).unwrap_err();
    expect(
        e,
        "top.srf.sb4.bind",
        &["output region", "65 words", "capacity 32768"],
    );
    assert_eq!(srf.mode(4), SbMode::Idle, "refused binds leave the SB free");
    srf.bind_input(4, 0, 64).unwrap();
    let e = srf.bind_output(4, 128, 64).unwrap_err();
    expect(e, "top.srf.sb4.bind", &["sb4 is already bound", "Input"]);
    srf.bind_output(6, 256, 64).unwrap();
    let e = srf.bind_output(7, 288, 64).unwrap_err();
    expect(
        e,
        "top.srf.sb7.bind",
        &["[288, 352)", "overlaps sb6", "[256, 320)"],
    );
    // An input may overlap an output (an in-place kernel), and outputs may abut.
    srf.bind_input(7, 256, 64).unwrap();
    srf.bind_output(8, 320, 64).unwrap();
    let e = srf.unbind(9).unwrap_err();
    expect(e, "top.srf.sb9.unbind", &["sb9 is not bound"]);
    let e = srf.unbind(99).unwrap_err();
    expect(e, "top.srf.unbind", &["stream buffer 99"]);
}

#[test]
fn reads_past_the_end_or_beyond_what_is_available_are_refused() {
    let mut srf = gold8();
    srf.load(0, &(0..24).collect::<Vec<u32>>()).unwrap();
    srf.bind_input(2, 0, 24).unwrap();
    let e = srf.read(2, 8).unwrap_err();
    expect(
        e,
        "top.srf.sb2.read",
        &["8 words from sb2", "only 0 available"],
    );
    clock(&mut srf, 3);
    assert_eq!(srf.available(2), 24);
    let e = srf.read(2, 32).unwrap_err();
    expect(
        e,
        "top.srf.sb2.read",
        &["32 words", "past the end", "0 of 24 words"],
    );
    assert_eq!(srf.read(2, 16).unwrap(), (0..16).collect::<Vec<u32>>());
    let e = srf.read(2, 16).unwrap_err();
    expect(e, "top.srf.sb2.read", &["past the end", "16 of 24 words"]);
    assert_eq!(srf.available(2), 8, "the refused read took nothing");
    assert_eq!(srf.read(2, 8).unwrap(), (16..24).collect::<Vec<u32>>());
    srf.eval();
    srf.commit();
    assert!(srf.exhausted(2));
    let e = srf.read(2, 8).unwrap_err();
    expect(e, "top.srf.sb2.read", &["past the end", "24 of 24 words"]);
    // A zero-word read is no access at all.
    assert!(srf.read(2, 0).unwrap().is_empty());
}

#[test]
fn accesses_to_the_wrong_kind_of_buffer_are_refused() {
    let mut srf = gold8();
    let e = srf.read(0, 8).unwrap_err();
    expect(e, "top.srf.sb0.read", &["sb0", "not bound", "not an input"]);
    let e = srf.read(40, 8).unwrap_err();
    expect(e, "top.srf.read", &["stream buffer 40"]);
    srf.bind_output(0, 0, 64).unwrap();
    let e = srf.read(0, 8).unwrap_err();
    expect(e, "top.srf.sb0.read", &["output stream", "not an input"]);
    srf.bind_input(1, 64, 64).unwrap();
    let e = srf.write(1, &[0; 8]).unwrap_err();
    expect(e, "top.srf.sb1.write", &["input stream", "not an output"]);
    let e = srf.write(40, &[0; 8]).unwrap_err();
    expect(e, "top.srf.write", &["stream buffer 40"]);
    let e = srf.flush(1).unwrap_err();
    expect(e, "top.srf.sb1.flush", &["not an output"]);
    assert_eq!((srf.available(0), srf.space(1)), (0, 0));
}

#[test]
fn unconditional_accesses_move_a_word_per_cluster() {
    let mut srf = gold8();
    srf.load(0, &[1; 64]).unwrap();
    srf.bind_input(0, 0, 64).unwrap();
    srf.bind_output(1, 64, 64).unwrap();
    clock(&mut srf, 2);
    let e = srf.read(0, 12).unwrap_err();
    expect(
        e,
        "top.srf.sb0.read",
        &[
            "unconditional read of 12 words",
            "multiple of the 8 clusters",
        ],
    );
    let e = srf.write(1, &[0; 5]).unwrap_err();
    expect(
        e,
        "top.srf.sb1.write",
        &["unconditional write of 5 words", "8 clusters"],
    );
    // As conditional accesses the same counts are fine.
    srf.read_conditional(0, 3).unwrap();
    srf.write_conditional(1, &[0; 5]).unwrap();
}

#[test]
fn the_clusters_stream_bandwidth_is_shared_by_every_buffer() {
    let mut srf = gold8();
    srf.load(0, &[3; 1024]).unwrap();
    for sb in 0..5 {
        srf.bind_input(sb, sb * 128, 128).unwrap();
    }
    srf.bind_output(5, 2048, 1024).unwrap();
    clock(&mut srf, 12);
    for sb in 0..5 {
        assert!(srf.available(sb) >= 16, "sb{sb} primed");
    }
    // 4 words per cluster per cycle: four rows, from any mix of buffers.
    srf.read(0, 8).unwrap();
    srf.read(1, 16).unwrap();
    srf.write(5, &[0; 8]).unwrap();
    assert_eq!(srf.cluster_words_left().0, 0);
    let before = srf.available(4);
    let e = srf.read(4, 8).unwrap_err();
    expect(
        e,
        "top.srf.sb4.read",
        &[
            "unconditional read of 8 words on sb4 after 32",
            "4 words per cluster per cycle × 8 clusters = 32",
        ],
    );
    let e = srf.write(5, &[0; 8]).unwrap_err();
    expect(
        e,
        "top.srf.sb5.write",
        &["after 32", "= 32 words per cycle"],
    );
    assert_eq!(srf.available(4), before, "nothing was taken");
    // The conditional bandwidth is separate: 1 word per cluster, reads and writes together.
    srf.read_conditional(4, 5).unwrap();
    srf.write_conditional(5, &[0; 3]).unwrap();
    let e = srf.read_conditional(3, 1).unwrap_err();
    expect(
        e,
        "top.srf.sb3.read",
        &[
            "conditional read of 1 words on sb3 after 8",
            "1 words per cluster per cycle × 8 clusters = 8",
        ],
    );
    // The budget is per cycle.
    srf.eval();
    srf.commit();
    assert_eq!(srf.cluster_words_left(), (32, 8));
    assert_eq!(srf.available(3), 32);
    srf.read(3, 32).unwrap();
    let e = srf.read_conditional(0, 9).unwrap_err();
    expect(e, "top.srf.sb0.read", &["conditional read of 9 words"]);
}

#[test]
fn an_output_stream_cannot_overflow_its_region_or_its_buffer() {
    let mut srf = gold8();
    srf.bind_output(3, 0, 24).unwrap();
    srf.write(3, &[1; 16]).unwrap();
    let e = srf.write(3, &[1; 16]).unwrap_err();
    expect(
        e,
        "top.srf.sb3.write",
        &[
            "16 words overflows the output region bound to sb3",
            "16 words written",
            "capacity 24 words",
        ],
    );
    srf.write(3, &[1; 8]).unwrap();
    srf.eval();
    srf.commit();
    assert_eq!(srf.output_len(3), 24);
    let e = srf.write_conditional(3, &[1]).unwrap_err();
    expect(e, "top.srf.sb3.write", &["overflows", "capacity 24"]);

    // The buffer itself: 64 words; the clusters must wait on `space`.
    let mut srf = gold8();
    srf.bind_output(4, 1024, 4096).unwrap();
    for _ in 0..2 {
        srf.write(4, &[2; 32]).unwrap();
        srf.commit(); // no eval: the port is busy elsewhere, nothing drains
    }
    assert_eq!(srf.space(4), 0);
    let e = srf.write(4, &[2; 8]).unwrap_err();
    expect(
        e,
        "top.srf.sb4.write",
        &["8 words to sb4", "only 0 words of space"],
    );
    clock(&mut srf, 1);
    assert_eq!(srf.space(4), 16, "one line drained");
}

#[test]
fn a_flushed_stream_takes_no_more_words_and_unbinds_only_when_empty() {
    let mut srf = gold8();
    srf.bind_output(2, 0, 64).unwrap();
    srf.write(2, &[9; 8]).unwrap();
    clock(&mut srf, 1);
    let e = srf.unbind(2).unwrap_err();
    expect(
        e,
        "top.srf.sb2.unbind",
        &["not flushed", "8 words still buffered"],
    );
    srf.flush(2).unwrap();
    srf.commit(); // the flush takes effect at the edge; no transfer yet
    let e = srf.write(2, &[9; 8]).unwrap_err();
    expect(e, "top.srf.sb2.write", &["after its stream was flushed"]);
    let e = srf.unbind(2).unwrap_err();
    expect(
        e,
        "top.srf.sb2.unbind",
        &["flush still in progress", "8 words"],
    );
    srf.flush(2).unwrap(); // flushing twice is harmless
    clock(&mut srf, 1);
    assert!(srf.flushed(2));
    srf.unbind(2).unwrap();
    assert_eq!(srf.read_back(0, 8).unwrap(), [9; 8]);
}
