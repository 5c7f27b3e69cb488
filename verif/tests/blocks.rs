//! The block testbenches on the built-in machines, and the proof that each catches the
//! design mistake injected into its block (`imagine_hdl::inject`).

use imagine_hdl::inject::{Bug, inject};
use imagine_units::desc::MachineDesc;
use imagine_verif::blocks::{self, Config, Report};

/// Few transactions: `cargo test` runs every block on three machines in well under a second.
const TRANSACTIONS: u64 = 400;

fn run(block: &str, machine: &str, seed: u64) -> Report {
    let desc = MachineDesc::resolve(machine).unwrap();
    let block = blocks::find(block).unwrap();
    blocks::run_block(block, &desc, &Config::new(seed, TRANSACTIONS))
}

/// The testbench of `block` passes on gold1, gold8 and gold32 and reaches coverage.
fn passes_on_the_built_in_machines(block: &str) {
    for machine in ["gold1", "gold8", "gold32"] {
        let r = run(block, machine, 7);
        assert!(r.passed(), "{}", r.first_mismatch().unwrap_or_default());
        assert!(r.scoreboard.transactions >= TRANSACTIONS);
        assert!(
            r.coverage.reached() * 4 >= r.coverage.total() * 3,
            "{block} on {machine}: coverage {}/{} bins: {:?}",
            r.coverage.reached(),
            r.coverage.total(),
            r.coverage.bins()
        );
    }
}

/// With `bug` injected, the testbench of `block` reports a mismatch on gold8, and its
/// replay with a waveform is the same run and writes a VCD window around the mismatch
/// (with its GTKWave save file) in which the block's signals change.
fn catches(block: &str, bug: Bug) {
    let _bug = inject(bug);
    let r = run(block, "gold8", 7);
    assert!(!r.passed(), "{block}: {bug:?} was not caught");
    let m = r.first_mismatch().unwrap();
    assert!(m.contains("--seed 7"), "{m}");
    eprintln!("{bug:?} caught: {m}");

    let dir = std::env::temp_dir().join(format!("imagine-verif-{}-{block}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let vcd = dir.join("fail.vcd");
    let desc = MachineDesc::resolve("gold8").unwrap();
    let replay = blocks::run_block_with_waves(
        blocks::find(block).unwrap(),
        &desc,
        &Config::new(7, TRANSACTIONS),
        Some(&vcd),
    );
    assert_eq!(
        replay.scoreboard.first, r.scoreboard.first,
        "{block}: replay differs"
    );
    let summary = replay.waves.unwrap().expect("a waveform was written");
    let text = std::fs::read_to_string(&vcd).unwrap();
    assert!(
        text.contains("$dumpvars"),
        "{block}: the window was never reached"
    );
    let block_vars = text
        .lines()
        .filter(|l| l.starts_with("$var") && !l.contains(" clk_"))
        .count();
    assert!(
        block_vars > 0,
        "{block}: no signal of the block in the waveform"
    );
    assert!(
        summary.values_written > summary.signals as u64,
        "{block}: nothing changes after the window opens"
    );
    assert!(summary.gtkw.as_ref().is_some_and(|g| g.exists()));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn lrf_passes() {
    passes_on_the_built_in_machines("lrf");
}

#[test]
fn scratchpad_passes() {
    passes_on_the_built_in_machines("scratchpad");
}

#[test]
fn fu_passes() {
    passes_on_the_built_in_machines("fu");
}

#[test]
fn fpu_passes() {
    passes_on_the_built_in_machines("fpu");
}

#[test]
fn alu_passes() {
    passes_on_the_built_in_machines("alu");
}

#[test]
fn ccfile_passes() {
    passes_on_the_built_in_machines("ccfile");
}

#[test]
fn comm_passes() {
    passes_on_the_built_in_machines("comm");
}

#[test]
fn cdc_passes() {
    passes_on_the_built_in_machines("cdc");
}

#[test]
fn sdram_passes() {
    passes_on_the_built_in_machines("sdram");
}

#[test]
fn scheduler_passes() {
    passes_on_the_built_in_machines("scheduler");
}

#[test]
fn address_gen_passes() {
    passes_on_the_built_in_machines("address_gen");
}

#[test]
fn srf_passes() {
    passes_on_the_built_in_machines("srf");
}

#[test]
fn scoreboard_passes() {
    passes_on_the_built_in_machines("scoreboard");
}

#[test]
fn condstream_passes() {
    passes_on_the_built_in_machines("condstream");
}

/// Two conditional words per cluster per cycle: the conditional read and write of one
/// instruction share the network and scratchpad claim the program check allows them.
#[test]
fn condstream_passes_with_two_conditional_words_per_cycle() {
    let mut desc = MachineDesc::resolve("gold8").unwrap();
    desc.srf.conditional_words_per_cycle = 2;
    desc.name = "gold8 with 2 conditional words per cycle".into();
    let r = blocks::run_block(
        blocks::find("condstream").unwrap(),
        &desc,
        &Config::new(7, TRANSACTIONS),
    );
    assert!(r.passed(), "{}", r.first_mismatch().unwrap_or_default());
    let fused = r
        .coverage
        .bins()
        .iter()
        .find(|(n, _)| n == "two conditional accesses in one instruction");
    assert!(
        fused.is_some_and(|(_, hits)| *hits > 0),
        "{:?}",
        r.coverage.bins()
    );
}

#[test]
fn microcontroller_passes() {
    passes_on_the_built_in_machines("microcontroller");
}

#[test]
fn lrf_catches_a_write_dropped_on_a_same_entry_read() {
    catches("lrf", Bug::LrfDropsWriteOnSameEntryRead);
}

#[test]
fn scratchpad_catches_a_write_landing_a_cycle_late() {
    catches("scratchpad", Bug::ScratchpadWriteLandsLate);
}

#[test]
fn fu_catches_short_ops_one_cycle_late() {
    catches("fu", Bug::PipelineShortOpsOneCycleLate);
}

#[test]
fn fpu_catches_a_dropped_sticky_bit() {
    catches("fpu", Bug::FpAddDropsStickyBit);
}

#[test]
fn alu_catches_a_carry_across_packed_lanes() {
    catches("alu", Bug::PackedAddCarriesAcrossLanes);
}

#[test]
fn ccfile_catches_a_write_that_ignores_its_mask() {
    catches("ccfile", Bug::CcFileIgnoresWriteMask);
}

#[test]
fn comm_catches_a_backwards_rotation() {
    catches("comm", Bug::CommRotatesBackwards);
}

#[test]
fn cdc_catches_a_zero_stage_synchroniser() {
    catches("cdc", Bug::CdcZeroStageSynchroniser);
}

#[test]
fn sdram_catches_a_precharge_that_keeps_the_row_open() {
    catches("sdram", Bug::SdramPrechargeKeepsRowOpen);
}

#[test]
fn scheduler_catches_a_column_access_ignoring_the_same_burst_hazard() {
    catches("scheduler", Bug::SchedulerIgnoresSameBurstHazard);
}

#[test]
fn address_gen_catches_a_record_word_offset_dropped() {
    catches("address_gen", Bug::AgDropsRecordWordOffset);
}

#[test]
fn srf_catches_a_flush_that_keeps_the_partial_line() {
    catches("srf", Bug::SrfFlushKeepsPartialLine);
}

#[test]
fn scoreboard_catches_a_write_passing_an_older_read() {
    catches("scoreboard", Bug::ScoreboardIgnoresWriteAfterRead);
}

#[test]
fn condstream_catches_a_conditional_word_lost_in_a_full_row() {
    catches("condstream", Bug::CondOutputDropsLastWord);
}

#[test]
fn microcontroller_catches_a_stage_squashed_one_pass_late() {
    catches("microcontroller", Bug::MicrocontrollerSquashesOneStageLate);
}

#[test]
fn a_seed_replays_the_same_run() {
    let (a, b) = (run("scratchpad", "gold8", 3), run("scratchpad", "gold8", 3));
    assert_eq!(a.scoreboard.checks, b.scoreboard.checks);
    assert_eq!(a.coverage.bins(), b.coverage.bins());
}
