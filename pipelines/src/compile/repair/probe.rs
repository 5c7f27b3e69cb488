//! What a move of the local search would cost, without making it.
//!
//! Each min-conflicts move weighs a shortlist of places for the op it takes out by the
//! search's whole cost. Attaching the op there and detaching it again updates every tally
//! twice (slot holders, destinations, reads, lifetimes) to learn one number. The cost is a
//! sum of terms that attaching an op can only add to — resources over capacity,
//! destinations beyond two, broken dependences and lifetimes, values over an LRF's entries,
//! waits — so what attaching adds is found by counting those additions alone, the cheap
//! ones first: a place whose cheap additions already reach the best so far cannot win, and
//! its lifetimes are not counted.

use super::{CROWD, HARD, Kind, Loc, SCALE, Src, State, circle};

/// Scratch of [`State::attach_cost`], kept between moves so that a probe allocates nothing.
#[derive(Default)]
pub(super) struct Probe {
    /// Usage cells (row × resource, and the resource) the op would take, in turn.
    cells: Vec<(usize, usize)>,
    /// Locations whose entries held for the whole loop would gain one.
    kept: Vec<usize>,
    /// Lifetimes that would start or grow: (location, from, to).
    lifetimes: Vec<(usize, i64, i64)>,
    /// (value, location) destinations the op's reads would add.
    new_dests: Vec<(usize, Loc)>,
}

impl State<'_> {
    /// What [`Self::attach`] of op `u` (out of the schedule) at `(t, slot, swap)` would add to
    /// [`Self::cost`], if less than `bound`; `None` if it would add `bound` or more. The state
    /// is left as it was.
    pub(super) fn attach_cost(
        &mut self,
        u: usize,
        t: i64,
        slot: usize,
        swap: bool,
        bound: i64,
    ) -> Option<i64> {
        let p = self.p;
        if p.reads_itself[u] {
            // (Its own reads would change its destinations: counted by doing it.)
            let aff = self.affected(u);
            let before = self.cost();
            self.attach(u, t, slot, swap, &aff);
            let added = self.cost() - before;
            self.detach(u, &aff);
            return (added < bound).then_some(added);
        }
        let mut probe = std::mem::take(&mut self.probe);
        let added = self.probe_cost(&mut probe, u, t, slot, swap, bound);
        self.probe = probe;
        added
    }

    fn probe_cost(
        &mut self,
        probe: &mut Probe,
        u: usize,
        t: i64,
        slot: usize,
        swap: bool,
        bound: i64,
    ) -> Option<i64> {
        let p = self.p;
        let op = &p.ops[u];
        let res = &p.res;
        let w = t + op.lat;
        let cell = |time: i64, r: usize| (p.row(time) * res.per_row + r, r);
        // Its own slots and ports, as `op` and `value` take them.
        probe.cells.clear();
        match op.kind {
            Kind::Fu(_) => {
                for c in 0..op.issue.min(p.ii) {
                    probe.cells.push(cell(t + c, res.issue(slot)));
                }
                probe.cells.push(cell(w, res.result(slot)));
            }
            Kind::SpRead { .. } | Kind::SpWrite { .. } => probe.cells.push(cell(t, res.sp(slot))),
            Kind::Comm(_) => probe.cells.push(cell(t, res.comm(slot))),
            Kind::StreamIn { .. } => probe.cells.push(cell(t, res.words())),
            Kind::StreamOut { .. } => {
                probe.cells.push(cell(t, res.words()));
                probe.cells.push(cell(t, res.sout()));
            }
            Kind::Imm(_) => probe.cells.push(cell(t, res.imm())),
        }
        for &(l, _) in &self.dests[u] {
            if let Loc::Lrf(x) = l {
                probe.cells.push(cell(w, res.port(x)));
            }
        }
        let mut dest_over = (self.dests[u].len() as i64 - 2).max(0);
        // The destinations its reads add to its operands' values, and their write ports.
        probe.new_dests.clear();
        for (i, &(src, _)) in op.args.iter().enumerate() {
            let Src::Loop { op: x, .. } = src else {
                continue;
            };
            let l = p.arg_loc(u, i, slot, swap);
            if !self.dests[x].iter().any(|e| e.0 == l) && !probe.new_dests.contains(&(x, l)) {
                probe.new_dests.push((x, l));
            }
        }
        for (j, &(x, l)) in probe.new_dests.iter().enumerate() {
            if !self.placed[x] {
                continue;
            }
            if let Loc::Lrf(lrf) = l {
                probe
                    .cells
                    .push(cell(self.t[x] + p.ops[x].lat, res.port(lrf)));
            }
            // (Counted once per value, at its first new destination.)
            if probe.new_dests[..j].iter().all(|e| e.0 != x) {
                let old = self.dests[x].len() as i64;
                let new = old + probe.new_dests.iter().filter(|e| e.0 == x).count() as i64;
                dest_over += (new - 2).max(0) - (old - 2).max(0);
            }
        }
        let mut over = 0;
        for (j, &(c, r)) in probe.cells.iter().enumerate() {
            let earlier = probe.cells[..j].iter().filter(|e| e.0 == c).count() as i32;
            over += i64::from(self.usage[c] + earlier >= res.cap[r]);
        }
        // Dependences and lifetimes it would break.
        let mut broken = self.dependences_broken(u, t);
        for &(r, i) in &p.readers[u] {
            if self.placed[r] && matches!(p.ops[r].args[i].0, Src::Loop { carried: false, .. }) {
                broken += Self::pen(self.t[r] - (w + p.reach));
            }
        }
        for &(src, _) in &op.args {
            if let Src::Loop {
                op: x,
                carried: false,
            } = src
                && self.placed[x]
            {
                broken += Self::pen(t - (self.t[x] + p.ops[x].lat + p.reach));
            }
        }
        let cheap = SCALE * (HARD * (over + dest_over) + broken);
        if cheap >= bound {
            return None;
        }
        // Entries held for the whole loop: a carried value's or an earlier value's new place.
        // (A value read twice from one place counts once, here and in its lifetime.)
        let first_read = |i: usize| {
            let (src, l) = (op.args[i].0, p.arg_loc(u, i, slot, swap));
            (0..i).all(|j| op.args[j].0 != src || p.arg_loc(u, j, slot, swap) != l)
        };
        probe.kept.clear();
        for (i, &(src, _)) in op.args.iter().enumerate() {
            let l = p.arg_loc(u, i, slot, swap);
            let gains = match src {
                Src::Loop { op: x, .. } => p.ops[x].permanent && probe.new_dests.contains(&(x, l)),
                Src::Earlier(x) => self.kept_pairs[x * p.nloc + p.loc_index(l)] == 0,
            };
            if gains && first_read(i) {
                probe.kept.push(p.loc_index(l));
            }
        }
        // Lifetimes: its value's, and its operands' grown to its reads.
        probe.lifetimes.clear();
        if !op.permanent {
            for &(l, _) in &self.dests[u] {
                probe
                    .lifetimes
                    .push((p.loc_index(l), w, self.live_end(u, l, w)));
            }
        }
        for (i, &(src, _)) in op.args.iter().enumerate() {
            let Src::Loop { op: x, .. } = src else {
                continue;
            };
            if !self.placed[x] || p.ops[x].permanent || !first_read(i) {
                continue;
            }
            let l = p.arg_loc(u, i, slot, swap);
            let wx = self.t[x] + p.ops[x].lat;
            let k = p.loc_index(l);
            if probe.new_dests.contains(&(x, l)) {
                probe.lifetimes.push((k, wx, t.max(wx + 1)));
            } else {
                let end = self.live_end(x, l, wx);
                if t > end {
                    probe.lifetimes.push((k, end, t));
                }
            }
        }
        // The waits are known from the lifetimes' lengths; the values over an LRF's entries
        // need its rows.
        let wait: i64 = probe.lifetimes.iter().map(|&(_, from, to)| to - from).sum();
        let known = cheap + self.wait_weight * wait;
        if known >= bound {
            return None;
        }
        let crowd = if self.lifetimes_apart(probe) {
            // Each lifetime alone in its LRF, none round the interval twice: its rows are
            // counted where they stand, lifetime by lifetime until the bound is reached.
            let mut crowd = 0;
            for &(k, from, to) in &probe.lifetimes {
                let cap = p.cap[k] - self.kept[k];
                let live = &self.live[k];
                for run in circle::cycles(from, to, p.ii) {
                    crowd += live[run].iter().filter(|&&x| x >= cap).count() as i64;
                }
                if known + SCALE * CROWD * crowd >= bound {
                    return None;
                }
            }
            crowd
        } else {
            self.crowd_added(probe)
        };
        let added = known + SCALE * CROWD * crowd;
        (added < bound).then_some(added)
    }

    /// Whether the lifetimes a probe adds are each in an LRF of their own, none longer than
    /// the interval, and no entry held for the whole loop is added: then each row gains at
    /// most one value, and what it adds to the crowding is counted without changing a row.
    fn lifetimes_apart(&self, probe: &Probe) -> bool {
        probe.kept.is_empty()
            && probe
                .lifetimes
                .iter()
                .enumerate()
                .all(|(j, &(k, from, to))| {
                    to - from <= self.p.ii && probe.lifetimes[..j].iter().all(|e| e.0 != k)
                })
    }

    /// What the probe's entries held for the whole loop and lifetimes add to the values over
    /// the LRFs' entries, counted as `add_kept` and `interval` count them, on tallies changed
    /// for the moment and then put back.
    fn crowd_added(&mut self, probe: &Probe) -> i64 {
        let p = self.p;
        let (crowd_before, wait_before) = (self.crowd, self.wait);
        let mut crowd = 0;
        for &k in &probe.kept {
            let cap = p.cap[k] - self.kept[k];
            crowd += self.live[k].iter().filter(|&&x| x >= cap).count() as i64;
            self.kept[k] += 1;
        }
        for &(k, from, to) in &probe.lifetimes {
            self.interval(k, from, to, 1);
        }
        crowd += self.crowd - crowd_before;
        for &(k, from, to) in &probe.lifetimes {
            self.interval(k, from, to, -1);
        }
        for &k in &probe.kept {
            self.kept[k] -= 1;
        }
        (self.crowd, self.wait) = (crowd_before, wait_before);
        crowd
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Problem, Rng, SCALE, State};
    use crate::compile::schedule::{Schedule, Slots, reach};
    use crate::compile::{bind, bounds, graph};
    use crate::kernel::Region;
    use imagine_units::desc::MachineDesc;

    /// A probe gives what attaching adds to the cost, for random places of random ops in a
    /// search's state (the loops of library kernels at their bound, a greedy start moved
    /// about), with waits weighed and not.
    #[test]
    fn probes_count_what_attaching_adds() {
        let desc = MachineDesc::gold8();
        let slots = Slots::new(&desc);
        for name in [
            "vertex",
            "merge",
            "sort32_keys",
            "prefix_sum",
            "transform",
            "texaddr",
        ] {
            let kernel = (crate::kernels::find(name).expect("a library kernel").build)(&desc)
                .expect("builds for gold8");
            let mut g = graph::lower(&kernel, slots.shape.lrf("add0", "a").0 as u16);
            g.expand = true;
            let b = bounds(&g, &desc, &slots);
            let ii = i64::from(b.res_mii.max(b.rec_mii).max(1));
            let mut sched = Schedule::new(g.ops.len());
            bind::bind(&mut g, &mut sched, Region::Loop, Some(ii), &slots);
            let ops = g.in_region(Region::Loop);
            let edges = g.edges(Region::Loop, &desc);
            let reach = reach(&g, ii, &desc);
            let problem = Problem::new(&g, &ops, &edges, ii, reach, &slots, &desc)
                .unwrap_or_else(|| panic!("{name}: the search takes its loop"));
            let mut st = State::new(&problem);
            let priority: Vec<i64> = (0..ops.len() as i64).rev().collect();
            st.start(&priority);
            let mut rng = Rng(7);
            let n = ops.len();
            for step in 0..4000 {
                st.wait_weight = if step % 2 == 0 { 0 } else { SCALE };
                let u = rng.below(n);
                let aff = st.affected(u);
                let home = (st.t[u], st.slot[u], st.swap[u]);
                st.detach(u, &aff);
                let mut places = Vec::new();
                for _ in 0..6 {
                    let t = home.0 - ii + rng.below(2 * ii as usize) as i64;
                    let (k, s) = problem.ops[u].options[rng.below(problem.ops[u].options.len())];
                    let detached = st.cost();
                    st.attach(u, t, k, s, &aff);
                    let added = st.cost() - detached;
                    st.detach(u, &aff);
                    assert_eq!(st.cost(), detached, "{name}: detaching undoes attaching");
                    assert_eq!(st.attach_cost(u, t, k, s, i64::MAX), Some(added), "{name}");
                    assert_eq!(st.attach_cost(u, t, k, s, added + 1), Some(added), "{name}");
                    assert_eq!(st.attach_cost(u, t, k, s, added), None, "{name}");
                    assert_eq!(st.cost(), detached, "{name}: a probe changes nothing");
                    places.push((t, k, s));
                }
                // Wander: to one of the places, or back home.
                let (t, k, s) = match rng.below(3) {
                    0 => home,
                    _ => places[rng.below(places.len())],
                };
                st.attach(u, t, k, s, &aff);
            }
        }
    }
}
