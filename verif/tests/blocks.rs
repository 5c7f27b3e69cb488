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
    blocks::run_block(
        block,
        &desc,
        &Config {
            seed,
            transactions: TRANSACTIONS,
        },
    )
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

/// With `bug` injected, the testbench of `block` reports a mismatch on gold8.
fn catches(block: &str, bug: Bug) {
    let _bug = inject(bug);
    let r = run(block, "gold8", 7);
    assert!(!r.passed(), "{block}: {bug:?} was not caught");
    let m = r.first_mismatch().unwrap();
    assert!(m.contains("--seed 7"), "{m}");
    eprintln!("{bug:?} caught: {m}");
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
fn alu_passes() {
    passes_on_the_built_in_machines("alu");
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
fn alu_catches_a_carry_across_packed_lanes() {
    catches("alu", Bug::PackedAddCarriesAcrossLanes);
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
fn microcontroller_catches_a_stage_squashed_one_pass_late() {
    catches("microcontroller", Bug::MicrocontrollerSquashesOneStageLate);
}

#[test]
fn a_seed_replays_the_same_run() {
    let (a, b) = (run("scratchpad", "gold8", 3), run("scratchpad", "gold8", 3));
    assert_eq!(a.scoreboard.checks, b.scoreboard.checks);
    assert_eq!(a.coverage.bins(), b.coverage.bins());
}
