//! Test-only bug injection (feature `inject-bugs`, off by default): each [`Bug`] is one
//! realistic design mistake that a block checks for at one place when the feature is on.
//! The block testbenches of `imagine-verif` turn one on for the current thread and show
//! that their scoreboard catches it. Without the feature this module does not exist and
//! the blocks carry no check; with it, no bug is active unless a thread injects one.

use std::cell::Cell;

/// A design mistake a block can be built with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bug {
    /// The LRF drops a write when its read port reads the same entry in the same cycle.
    LrfDropsWriteOnSameEntryRead,
    /// The scratchpad lands a write one cycle after its write latency.
    ScratchpadWriteLandsLate,
    /// The fp32 adder's alignment shifter drops the sticky bit (the bits shifted out).
    FpAddDropsStickyBit,
    /// A pipelined unit delivers its shorter-latency ops one cycle late.
    PipelineShortOpsOneCycleLate,
    /// The adder's carry chain is not cut between the lanes of `add_16x2`.
    PackedAddCarriesAcrossLanes,
    /// The condition-code file writes every cluster, ignoring the write mask.
    CcFileIgnoresWriteMask,
    /// The intercluster network rotates the wrong way (`c - k` for `c + k`).
    CommRotatesBackwards,
    /// The crossing's write pointer reaches the reader with no synchroniser stage.
    CdcZeroStageSynchroniser,
    /// An SDRAM bank's PRECHARGE leaves its row open.
    SdramPrechargeKeepsRowOpen,
    /// The DRAM scheduler's column arbiter ignores an older pending reference to the same
    /// burst.
    SchedulerIgnoresSameBurstHazard,
    /// An address generator addresses every word of a record at the record's first word.
    AgDropsRecordWordOffset,
    /// A flushing SRF output stream buffer never drains its last partial line.
    SrfFlushKeepsPartialLine,
    /// The stream controller's scoreboard lets a write pass an older read of the same SRF
    /// words.
    ScoreboardIgnoresWriteAfterRead,
    /// The packing of a conditional output loses the last selected cluster's word when
    /// every cluster is selected (its word count saturates one short of a full row).
    CondOutputDropsLastWord,
    /// The microcontroller squashes a software-pipeline stage one pass late in the
    /// epilogue: stage `s` of a loop of `N` iterations is still live in pass `N + s`.
    MicrocontrollerSquashesOneStageLate,
}

thread_local! {
    static ACTIVE: Cell<Option<Bug>> = const { Cell::new(None) };
}

/// Whether `bug` is injected on this thread.
#[inline]
pub fn active(bug: Bug) -> bool {
    ACTIVE.with(|a| a.get() == Some(bug))
}

/// Injects `bug` on this thread until the guard is dropped.
pub fn inject(bug: Bug) -> Injected {
    ACTIVE.with(|a| a.set(Some(bug)));
    Injected(())
}

/// Keeps a bug injected; dropping it restores the correct design.
pub struct Injected(());

impl Drop for Injected {
    fn drop(&mut self) {
        ACTIVE.with(|a| a.set(None));
    }
}
