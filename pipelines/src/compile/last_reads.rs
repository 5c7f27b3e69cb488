//! When each value is last read from each place: what a value's lifetime in an LRF ends at.
//! The allocator and the LRF repairs ask it of every schedule they see, several times
//! over, so it is a table indexed by value and location rather than a map.

use super::alloc::index;
use super::graph::{Graph, Loc, Source};
use super::schedule::{Schedule, Slots};
use crate::kernel::Region;

/// The last cycle each value is read from each location, in the reader's region time.
pub struct LastReads {
    /// Locations per value: the LRFs, then the condition codes.
    locs: usize,
    /// `[value * locs + location]`: the last read, or [`UNREAD`].
    last: Vec<i64>,
}

/// No reader reads the value from the location.
const UNREAD: i64 = i64::MIN;

impl LastReads {
    /// The last reads of the placed readers of `s`; with `region`, only of the readers in
    /// that region.
    pub fn new(g: &Graph, s: &Schedule, slots: &Slots, region: Option<Region>) -> LastReads {
        let locs = slots.lrfs() + 1;
        let mut last = vec![UNREAD; g.ops.len() * locs];
        for (u, op) in g.ops.iter().enumerate() {
            let Some(pl) = s.place[u] else { continue };
            if region.is_some_and(|r| r != op.region) {
                continue;
            }
            for a in &op.args {
                if let Source::Local(p) = a.src {
                    let loc = slots.operand_loc(op.kind, pl.slot, pl.swap, a);
                    let e = &mut last[p * locs + index(slots, loc)];
                    *e = (*e).max(pl.time);
                }
            }
        }
        LastReads { locs, last }
    }

    /// The last cycle `value` is read from the location of [`index`] `k`, if it is.
    fn at(&self, value: usize, k: usize) -> Option<i64> {
        let r = self.last[value * self.locs + k];
        (r != UNREAD).then_some(r)
    }

    /// The last cycle `value` is read from `loc`, if it is.
    pub fn get(&self, slots: &Slots, value: usize, loc: Loc) -> Option<i64> {
        self.at(value, index(slots, loc))
    }

    /// Until when `value`, landing in `loc` at cycle `w`, holds its entry: its last read
    /// there, and at least the cycle after it lands.
    pub fn live_end(&self, slots: &Slots, value: usize, loc: Loc, w: i64) -> i64 {
        self.get(slots, value, loc).map_or(w + 1, |r| r.max(w + 1))
    }
}
