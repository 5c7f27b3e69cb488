//! What a channel's cycles were spent on, over time: cumulative counters of data transfer,
//! row switching, column accesses and activates, sampled every [`SAMPLE_CYCLES`] DRAM
//! cycles (only when they changed), so that after a run the counts over any stretch of time
//! can be read back — the attribution of waiting cycles to DRAM bandwidth or bank conflicts,
//! and the timeline's row-hit counter. Sampling costs a comparison per cycle and a few
//! bytes per busy sample period; inside a sample period counts are interpolated linearly.

/// DRAM cycles between samples (a power of two).
pub const SAMPLE_CYCLES: u64 = 64;

/// A channel's cumulative counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Activity {
    /// Cycles the data bus carried a word (read data, or a write's burst).
    pub transfer_cycles: u64,
    /// Cycles without a word on the data bus while references waited and a bank was being
    /// precharged, activated or refreshed: row misses, bank conflicts and refresh.
    pub row_switch_cycles: u64,
    /// Read and write commands.
    pub columns: u64,
    /// Activate commands.
    pub activates: u64,
}

impl Activity {
    fn minus(self, o: Activity) -> [f64; 4] {
        [
            (self.transfer_cycles - o.transfer_cycles) as f64,
            (self.row_switch_cycles - o.row_switch_cycles) as f64,
            (self.columns - o.columns) as f64,
            (self.activates - o.activates) as f64,
        ]
    }
}

/// Counts over a stretch of time (fractional where a sample period is cut).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ActivitySpan {
    pub transfer_cycles: f64,
    pub row_switch_cycles: f64,
    pub columns: f64,
    pub activates: f64,
}

/// A channel's counters at every multiple of [`SAMPLE_CYCLES`] at which they had changed.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ActivityLog {
    /// (DRAM cycle, counters after every cycle before it), in cycle order.
    samples: Vec<(u64, Activity)>,
}

impl ActivityLog {
    /// Records the counters `now` (cycles before `cycle` counted) if `cycle` is a sample
    /// point and they changed since the last sample.
    #[inline]
    pub fn sample(&mut self, cycle: u64, now: Activity) {
        if cycle.is_multiple_of(SAMPLE_CYCLES) && self.last() != now {
            self.samples.push((cycle, now));
        }
    }

    /// Records, before a jump from `cycle` over `n` cycles in which the counters stay at
    /// `now`, the first sample point the jump passes over (later ones would be the same).
    pub fn sample_over(&mut self, cycle: u64, n: u64, now: Activity) {
        let next = (cycle / SAMPLE_CYCLES + 1) * SAMPLE_CYCLES;
        if next <= cycle + n {
            self.sample(next, now);
        }
    }

    fn last(&self) -> Activity {
        self.samples.last().map(|s| s.1).unwrap_or_default()
    }

    /// The counters at sample point `m` (a multiple of [`SAMPLE_CYCLES`]).
    fn at_point(&self, m: u64) -> Activity {
        let i = self.samples.partition_point(|s| s.0 <= m);
        if i == 0 {
            Activity::default()
        } else {
            self.samples[i - 1].1
        }
    }

    /// The counters at (fractional) DRAM cycle `x`, interpolated inside its sample period.
    fn at(&self, x: f64) -> [f64; 4] {
        let x = x.max(0.0);
        let m = (x as u64 / SAMPLE_CYCLES) * SAMPLE_CYCLES;
        let (lo, hi) = (self.at_point(m), self.at_point(m + SAMPLE_CYCLES));
        let f = (x - m as f64) / SAMPLE_CYCLES as f64;
        let base = lo.minus(Activity::default());
        let step = hi.minus(lo);
        std::array::from_fn(|i| base[i] + f * step[i])
    }

    /// The counts between (fractional) DRAM cycles `from` and `to`.
    pub fn between(&self, from: f64, to: f64) -> ActivitySpan {
        let (a, b) = (self.at(from), self.at(to.max(from)));
        ActivitySpan {
            transfer_cycles: b[0] - a[0],
            row_switch_cycles: b[1] - a[1],
            columns: b[2] - a[2],
            activates: b[3] - a[3],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn counters(transfer: u64) -> Activity {
        Activity {
            transfer_cycles: transfer,
            ..Activity::default()
        }
    }

    #[test]
    fn counts_between_sample_points_are_exact_and_inside_them_interpolated() {
        let mut log = ActivityLog::default();
        // 64 transfer cycles in the second sample period, none after.
        log.sample(64, counters(0));
        log.sample(128, counters(64));
        log.sample(192, counters(64));
        log.sample(4096, counters(64));
        assert_eq!(log.samples.len(), 1, "only changes are kept");
        assert_eq!(log.between(0.0, 4096.0).transfer_cycles, 64.0);
        assert_eq!(log.between(64.0, 128.0).transfer_cycles, 64.0);
        assert_eq!(log.between(128.0, 4096.0).transfer_cycles, 0.0);
        assert_eq!(log.between(96.0, 112.0).transfer_cycles, 16.0);
        assert_eq!(log.between(112.0, 96.0).transfer_cycles, 0.0);
    }

    #[test]
    fn a_jump_over_sample_points_keeps_the_counts_before_it() {
        let mut log = ActivityLog::default();
        // Counters change at cycle 70, then the channel jumps from 100 to 1000.
        log.sample_over(100, 900, counters(30));
        assert_eq!(log.between(0.0, 128.0).transfer_cycles, 30.0);
        assert_eq!(log.between(128.0, 1000.0).transfer_cycles, 0.0);
        // A jump that passes no sample point records nothing.
        let mut short = ActivityLog::default();
        short.sample_over(100, 20, counters(30));
        assert!(short.samples.is_empty());
    }
}
