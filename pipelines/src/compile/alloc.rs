//! LRF and condition-code entry allocation, after scheduling.
//!
//! Values live across regions (computed before the loop and read in or after it, and the
//! loop's carried values) keep their entries for the whole kernel. The other values are
//! packed first-fit: a value written at cycle `w` and last read at `r` holds its entry over
//! `[w, r)` — in the loop modulo the length of the loop body. A body of one interval holds
//! each value in one entry, which the next iteration rewrites; a value that outlives the
//! interval makes the body a few passes long, and then each pass's copy of the value gets
//! an entry of its own (modulo variable expansion).

use std::ops::Range;

use rustc_hash::FxHashMap as HashMap;

use super::circle;
use super::graph::{Graph, Loc};
use super::last_reads::LastReads;
use super::schedule::{Schedule, Slots};
use crate::kernel::Region;

/// Entries of every (value, location) pair.
#[derive(Clone, Debug, Default)]
pub struct Entries {
    pub entry: HashMap<(usize, Loc), u16>,
    /// Loop values that outlive the initiation interval: the entry of each copy, copy `c`
    /// holding the value of the iterations `i` with `i mod unroll == c`.
    pub instances: HashMap<(usize, Loc), Vec<u16>>,
    /// Passes the loop body is unrolled into: the longest-lived loop value's lifetime in
    /// intervals (modulo variable expansion, see [`super::schedule::reach`]).
    pub unroll: usize,
    /// Entries in use per LRF (highest + 1), then the condition codes.
    pub peak: Vec<usize>,
    pub cc_peak: usize,
}

/// A location full: which, how many entries were needed, how many it has.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Overflow {
    pub loc: Loc,
    pub needed: usize,
    pub entries: usize,
    pub region: Option<Region>,
}

/// The ops whose results stay in their entries for the whole kernel.
pub fn permanent(g: &Graph) -> Vec<bool> {
    let mut p = vec![false; g.ops.len()];
    for (i, op) in g.ops.iter().enumerate() {
        if op.region == Region::Pre && !op.seeded.is_empty() {
            p[i] = true;
        }
        if let Some(m) = op.tie {
            p[m] = true;
            p[i] = true;
        }
    }
    p
}

struct Occupancy {
    /// Loop entries: cycles (mod II) each is held.
    modulo: Vec<Vec<bool>>,
    /// Straight-line entries: held intervals per region.
    line: Vec<Vec<(Region, i64, i64)>>,
}

pub fn allocate(
    g: &Graph,
    s: &Schedule,
    slots: &Slots,
    ii: Option<i64>,
    desc: &imagine_units::desc::MachineDesc,
) -> Result<Entries, Overflow> {
    // (What every packing below reads of the schedule, found once.)
    let perm = permanent(g);
    let last_read = LastReads::new(g, s, slots, None);
    let passes = ii.map_or(1, |ii| unroll(g, s, &perm, &last_read, slots, ii, desc));
    let lives = Lives {
        perm,
        last_read,
        passes,
    };
    match pack(g, s, slots, ii, desc, &lives, None) {
        // Packing the loop's values round the interval in order of issue can leave gaps
        // that a later value does not fit. Then every pass's copy of every loop value
        // gets an entry of its own (full renaming under modulo variable expansion, Rau et
        // al., "Register allocation for software pipelined loops", PLDI 1992), so each
        // copy is a single arc round the unrolled body, and the arcs are coloured by a
        // search ([`colour`]). Two copies share an entry only if their arcs fit round the
        // body together, so long-lived values may need a pass or two more than their
        // lifetimes to fit in about as many entries as values live at once (Eisenbeis et
        // al., "The meeting graph", 1995).
        Err(o) if o.region == Some(Region::Loop) => {
            let Some(ii) = ii else { return Err(o) };
            let least = lives.passes;
            let most = (desc.microcontroller.store_words / 2 / ii as usize).max(least);
            (least..=most.min(least + EXTRA_PASSES))
                .find_map(|passes| pack(g, s, slots, Some(ii), desc, &lives, Some(passes)).ok())
                .ok_or(o)
        }
        other => other,
    }
}

/// Which values are kept for the whole loop ([`permanent`]), where each value is last
/// read, and the passes of the loop body its longest lifetime needs ([`unroll`]; 1 without
/// a loop): what packing reads of a schedule besides its places.
struct Lives {
    perm: Vec<bool>,
    last_read: LastReads,
    passes: usize,
}

/// Passes beyond the longest lifetime that the renamed allocation may unroll the loop body
/// into (see [`allocate`]).
const EXTRA_PASSES: usize = 2;

/// Packs the entries, the loop's values first-fit in order of issue or, with `renamed`
/// passes, each pass's copy of each by [`colour`].
fn pack(
    g: &Graph,
    s: &Schedule,
    slots: &Slots,
    ii: Option<i64>,
    desc: &imagine_units::desc::MachineDesc,
    lives: &Lives,
    renamed: Option<usize>,
) -> Result<Entries, Overflow> {
    let n = g.ops.len();
    let Lives {
        perm, last_read, ..
    } = lives;
    let nlrf = slots.lrfs();
    let capacity = |loc: Loc| match loc {
        Loc::Lrf(l) => slots.shape.lrf_sizes[l as usize],
        Loc::Cc => slots.shape.condition_codes,
    };
    let index = |loc: Loc| index(slots, loc);
    let mut out = Entries {
        peak: vec![0; nlrf],
        unroll: renamed.unwrap_or(lives.passes),
        ..Entries::default()
    };
    let modulus = ii.map(|ii| ii * out.unroll as i64);
    let mut next_perm = vec![0usize; nlrf + 1];
    // Permanent values first: carried movs, then what their initialising movs share.
    let mut order: Vec<usize> = (0..n)
        .filter(|&i| perm[i] && g.ops[i].tie.is_none())
        .collect();
    order.extend((0..n).filter(|&i| perm[i] && g.ops[i].tie.is_some()));
    for u in order {
        for &loc in &s.dests[u] {
            let e = match g.ops[u].tie {
                Some(m) => *out
                    .entry
                    .get(&(m, loc))
                    .expect("carried entries come first"),
                None => {
                    let k = index(loc);
                    let e = next_perm[k];
                    next_perm[k] += 1;
                    if e >= capacity(loc) {
                        return Err(Overflow {
                            loc,
                            needed: e + 1,
                            entries: capacity(loc),
                            region: None,
                        });
                    }
                    e as u16
                }
            };
            out.entry.insert((u, loc), e);
        }
    }
    // Before the loop, a kept value's entry is free until the value is written.
    let mut kept_from: HashMap<(usize, u16), i64> = HashMap::default();
    for (u, op) in g.ops.iter().enumerate() {
        let (true, Region::Pre, Some(pl)) = (perm[u], op.region, s.place[u]) else {
            continue;
        };
        let w = pl.time + g.latency(u, desc);
        for &loc in &s.dests[u] {
            if let Some(&e) = out.entry.get(&(u, loc)) {
                let at = kept_from.entry((index(loc), e)).or_insert(w);
                *at = (*at).min(w);
            }
        }
    }
    let mut occ: Vec<Occupancy> = (0..=nlrf)
        .map(|k| {
            let cap = if k == nlrf {
                slots.shape.condition_codes
            } else {
                slots.shape.lrf_sizes[k]
            };
            Occupancy {
                modulo: vec![Vec::new(); cap],
                line: vec![Vec::new(); cap],
            }
        })
        .collect();
    let mut values: Vec<usize> = (0..n)
        .filter(|&i| !perm[i] && s.place[i].is_some() && !s.dests[i].is_empty())
        .collect();
    values.sort_by_key(|&i| (g.ops[i].region, s.place[i].map(|p| p.time)));
    let pairs: Vec<(usize, Loc)> = values
        .iter()
        .flat_map(|&u| s.dests[u].iter().map(move |&loc| (u, loc)))
        .collect();
    // With `renamed`, each location's loop values are coloured first.
    let mut packed: HashMap<(usize, Loc), Vec<u16>> = HashMap::default();
    if let (Some(_), Some(m), Some(ii)) = (renamed, modulus, ii) {
        // Per location: each value and the arc each pass's copy of it is live.
        type Copies = Vec<(usize, Vec<Arc>)>;
        let mut by_loc: Vec<(Loc, Copies)> = Vec::new();
        for &(u, loc) in &pairs {
            if g.ops[u].region != Region::Loop {
                continue;
            }
            let w = s.place[u].expect("placed").time + g.latency(u, desc);
            let r = last_read.live_end(slots, u, loc, w);
            let held: Vec<Arc> = (0..out.unroll as i64)
                .map(|j| ((w + j * ii).rem_euclid(m) as usize, (r - w) as usize))
                .collect();
            match by_loc.iter_mut().find(|(l, _)| *l == loc) {
                Some((_, v)) => v.push((u, held)),
                None => by_loc.push((loc, vec![(u, held)])),
            }
        }
        for (loc, values) in by_loc {
            let k = index(loc);
            let first = next_perm[k];
            let arcs: Vec<Arc> = values.iter().flat_map(|(_, h)| h.iter().copied()).collect();
            let Some(colours) = colour(&arcs, first, capacity(loc), m as usize) else {
                return Err(Overflow {
                    loc,
                    needed: capacity(loc) + 1,
                    entries: capacity(loc),
                    region: Some(Region::Loop),
                });
            };
            // (Every loop value is coloured, so first fit below, which packs the rest,
            // need not know which rows these entries hold.)
            let mut it = colours.into_iter();
            for (u, held) in values {
                let es = it.by_ref().take(held.len()).map(|e| e as u16).collect();
                packed.insert((u, loc), es);
            }
        }
    }
    for (u, loc) in pairs {
        let chosen = match packed.remove(&(u, loc)) {
            Some(coloured) => coloured,
            None => {
                let region = g.ops[u].region;
                let w = s.place[u].expect("placed").time + g.latency(u, desc);
                let r = last_read.live_end(slots, u, loc, w);
                let k = index(loc);
                let first = next_perm[k];
                let cap = capacity(loc);
                let o = &mut occ[k];
                // The cycles each entry to choose is held: one entry for every pass of the
                // unrolled loop body unless the value outlives the interval, when each pass
                // gets an entry of its own.
                // (As runs of rows round the unrolled body.)
                let held: Vec<Vec<Range<usize>>> = match (region, ii, modulus) {
                    (Region::Loop, Some(ii), Some(m)) => {
                        let passes = (0..out.unroll as i64)
                            .map(|j| circle::cycles(w + j * ii, r + j * ii, m));
                        if r - w <= ii {
                            vec![passes.flatten().collect()]
                        } else {
                            passes.map(Iterator::collect).collect()
                        }
                    }
                    _ => vec![Vec::new()],
                };
                let mut chosen = Vec::with_capacity(held.len());
                for cycles in &held {
                    let mut found = None;
                    for e in 0..cap {
                        if e < first {
                            // A kept value's entry, usable before the loop until it is written.
                            let until = kept_from.get(&(k, e as u16)).copied();
                            if region != Region::Pre || until.is_none_or(|w0| r > w0) {
                                continue;
                            }
                        }
                        let free = match modulus {
                            Some(m) if region == Region::Loop => {
                                let bits = &mut o.modulo[e];
                                if bits.is_empty() {
                                    bits.resize(m as usize, false);
                                }
                                cycles.iter().all(|run| !bits[run.clone()].contains(&true))
                            }
                            _ => o.line[e]
                                .iter()
                                .all(|&(rg, a, b)| rg != region || r <= a || b <= w),
                        };
                        if free {
                            found = Some(e);
                            break;
                        }
                    }
                    let Some(e) = found else {
                        return Err(Overflow {
                            loc,
                            needed: cap + 1,
                            entries: cap,
                            region: Some(region),
                        });
                    };
                    match modulus {
                        Some(_) if region == Region::Loop => {
                            for run in cycles {
                                o.modulo[e][run.clone()].fill(true);
                            }
                        }
                        _ => o.line[e].push((region, w, r)),
                    }
                    chosen.push(e as u16);
                }
                chosen
            }
        };
        if let [e] = chosen[..] {
            out.entry.insert((u, loc), e);
        } else {
            out.instances.insert((u, loc), chosen);
        }
    }
    let instances = out
        .instances
        .iter()
        .flat_map(|(&(_, loc), es)| es.iter().map(move |&e| (loc, e)));
    for (loc, e) in out
        .entry
        .iter()
        .map(|(&(_, loc), &e)| (loc, e))
        .chain(instances)
    {
        match loc {
            Loc::Lrf(l) => out.peak[l as usize] = out.peak[l as usize].max(e as usize + 1),
            Loc::Cc => out.cc_peak = out.cc_peak.max(e as usize + 1),
        }
    }
    Ok(out)
}

/// An arc round a circle of rows (the unrolled loop body): its first row and its length,
/// at most the circle's.
type Arc = (usize, usize);

/// The rows of `arc` round a circle of `m`.
fn rows((start, len): Arc, m: usize) -> impl Iterator<Item = usize> {
    circle::runs(start, len, m).flatten()
}

/// The rows of `arc` as a bit set.
fn row_bits(arc: Arc, m: usize) -> Vec<u64> {
    let mut bits = vec![0u64; m.div_ceil(64)];
    for c in rows(arc, m) {
        bits[c / 64] |= 1 << (c % 64);
    }
    bits
}

/// The highest row below `limit` set in `bits`.
fn last_below(bits: &[u64], limit: usize) -> Option<usize> {
    let (word, bit) = (limit / 64, limit % 64);
    let partial = (bit > 0).then(|| (word, bits[word] & ((1u64 << bit) - 1)));
    partial
        .into_iter()
        .chain((0..word).rev().map(|w| (w, bits[w])))
        .find(|&(_, b)| b != 0)
        .map(|(w, b)| w * 64 + 63 - b.leading_zeros() as usize)
}

/// Entries in `first..entries` for arcs round a circle of `m` rows, no two sharing a row
/// in one entry, or `None` within a bounded search.
///
/// The arcs crossing the row where fewest are live go first, then the rest in order of
/// their first row from there (the left-edge order, which colours intervals with as many
/// entries as are live at once); each takes the entry whose last arc ends nearest before
/// it starts, and a dead end backs up to the arc before.
fn colour(arcs: &[Arc], first: usize, entries: usize, m: usize) -> Option<Vec<usize>> {
    const STEPS: usize = 20_000;
    // Arcs live per row, from the rows where each starts and ends.
    let mut change = vec![0i64; m + 1];
    for &(start, len) in arcs {
        let end = start + len;
        change[start] += 1;
        change[end.min(m)] -= 1;
        if end > m {
            change[0] += 1;
            change[end - m] -= 1;
        }
    }
    let live: Vec<usize> = change[..m]
        .iter()
        .scan(0i64, |n, &d| {
            *n += d;
            Some(*n as usize)
        })
        .collect();
    // Two arcs share an entry only if they fit round the circle together: the longest
    // arcs, down to where the two shortest of them no longer fit, need an entry each.
    let mut lengths: Vec<usize> = arcs.iter().map(|a| a.1).collect();
    lengths.sort_unstable_by(|a, b| b.cmp(a));
    let apart = (1..lengths.len())
        .find(|&t| lengths[t - 1] + lengths[t] <= m)
        .unwrap_or(lengths.len());
    if first + live.iter().copied().max().unwrap_or(0).max(apart) > entries {
        return None;
    }
    let cut = (0..m).min_by_key(|&c| (live[c], c)).unwrap_or(0);
    let mut order: Vec<usize> = (0..arcs.len()).collect();
    order.sort_by_key(|&i| {
        let (start, len) = arcs[i];
        let from_cut = (start + m - cut) % m;
        (from_cut != 0 && from_cut + len <= m, from_cut)
    });
    let items: Vec<Arc> = order.iter().map(|&i| arcs[i]).collect();
    let bits: Vec<Vec<u64>> = items.iter().map(|&arc| row_bits(arc, m)).collect();
    let mut used = vec![vec![0u64; m.div_ceil(64)]; entries];
    let free = |used: &[u64], b: &[u64]| used.iter().zip(b).all(|(x, y)| x & y == 0);
    // How far back round the circle from `start` the entry's nearest held row is.
    let gap = |used: &[u64], start: usize| -> usize {
        match (last_below(used, start), last_below(used, m)) {
            (Some(c), _) => start - c,
            (None, Some(c)) => start + m - c,
            (None, None) => m,
        }
    };
    // Per arc: the entries still to try, snuggest first.
    let mut choice: Vec<Vec<usize>> = Vec::with_capacity(items.len());
    let mut assigned: Vec<usize> = Vec::with_capacity(items.len());
    let mut steps = 0;
    loop {
        let i = assigned.len();
        if i == items.len() {
            let mut out = vec![0; items.len()];
            for (&k, e) in order.iter().zip(assigned) {
                out[k] = e;
            }
            return Some(out);
        }
        if choice.len() == i {
            let start = items[i].0;
            let mut options: Vec<(usize, usize)> = (first..entries)
                .filter(|&e| free(&used[e], &bits[i]))
                .map(|e| (gap(&used[e], start), e))
                .collect();
            options.sort_unstable_by(|a, b| b.cmp(a));
            choice.push(options.into_iter().map(|(_, e)| e).collect());
        }
        steps += 1;
        if steps > STEPS {
            // (Out of steps, not of choices: the arcs may still fit.)
            let colours = tabu_colour(&bits, entries - first)?;
            let mut out = vec![0; items.len()];
            for (&k, c) in order.iter().zip(colours) {
                out[k] = first + c;
            }
            return Some(out);
        }
        match choice[i].pop() {
            Some(e) => {
                for (x, y) in used[e].iter_mut().zip(&bits[i]) {
                    *x |= y;
                }
                assigned.push(e);
            }
            None => {
                // Back up: the arc before tries its next entry.
                choice.pop();
                let j = i.checked_sub(1)?;
                let e = assigned.pop().expect("an arc before");
                for (x, y) in used[e].iter_mut().zip(&bits[j]) {
                    *x &= !y;
                }
            }
        }
    }
}

/// Colours `0..colours` for the arcs (as bit sets of rows), no two overlapping arcs in one
/// colour, by tabu search (Hertz and de Werra, "Using tabu search techniques for graph
/// coloring", Computing 39, 1987): from a greedy start with conflicts, each move recolours
/// an arc in conflict to the colour that removes the most conflicts, and the colour it
/// left is tabu for that arc for a while (unless taking it would beat the best so far).
/// `None` if conflicts remain after a bounded number of moves. Deterministic.
fn tabu_colour(bits: &[Vec<u64>], colours: usize) -> Option<Vec<usize>> {
    const MOVES: usize = 50_000;
    let n = bits.len();
    if colours == 0 {
        return (n == 0).then(Vec::new);
    }
    let k = colours;
    let overlap = |a: &[u64], b: &[u64]| a.iter().zip(b).any(|(x, y)| x & y != 0);
    let adjacent: Vec<Vec<usize>> = (0..n)
        .map(|i| {
            (0..n)
                .filter(|&j| j != i && overlap(&bits[i], &bits[j]))
                .collect()
        })
        .collect();
    // `sharing[i * k + c]`: arcs overlapping arc `i` that have colour `c`.
    let mut sharing = vec![0i64; n * k];
    let mut colour = vec![0usize; n];
    for i in 0..n {
        let c = (0..k).min_by_key(|&c| sharing[i * k + c]).expect("colours");
        colour[i] = c;
        for &j in &adjacent[i] {
            sharing[j * k + c] += 1;
        }
    }
    let mut conflicts: i64 = (0..n).map(|i| sharing[i * k + colour[i]]).sum::<i64>() / 2;
    let mut best = conflicts;
    let mut tabu_until = vec![0usize; n * k];
    let mut rng = super::repair::Rng(0x7AB0 ^ ((n as u64) << 16) ^ k as u64);
    for step in 0..MOVES {
        if conflicts == 0 {
            return Some(colour);
        }
        // The best allowed move, ties broken at random; and how many arcs are in conflict.
        let mut pick: Option<(i64, usize, usize)> = None;
        let (mut ties, mut troubled) = (0usize, 0usize);
        for i in 0..n {
            let own = sharing[i * k + colour[i]];
            if own == 0 {
                continue;
            }
            troubled += 1;
            for c in (0..k).filter(|&c| c != colour[i]) {
                let delta = sharing[i * k + c] - own;
                // (Worse than the pick so far: skipped before its tabu entry is read.)
                if pick.is_some_and(|(d, ..)| delta > d)
                    || tabu_until[i * k + c] > step && conflicts + delta >= best
                {
                    continue;
                }
                match pick {
                    Some((d, ..)) if delta == d => {
                        ties += 1;
                        if rng.below(ties) != 0 {
                            continue;
                        }
                    }
                    _ => ties = 1,
                }
                pick = Some((delta, i, c));
            }
        }
        let Some((delta, i, c)) = pick else {
            continue;
        };
        let old = colour[i];
        tabu_until[i * k + old] = step + 1 + rng.below(10) + troubled * 3 / 5;
        for &j in &adjacent[i] {
            sharing[j * k + old] -= 1;
            sharing[j * k + c] += 1;
        }
        colour[i] = c;
        conflicts += delta;
        best = best.min(conflicts);
    }
    (conflicts == 0).then_some(colour)
}

/// Passes the loop body at interval `ii` is unrolled into: its longest-lived value's
/// lifetime (landing to last read), in intervals.
fn unroll(
    g: &Graph,
    s: &Schedule,
    perm: &[bool],
    last_read: &LastReads,
    slots: &Slots,
    ii: i64,
    desc: &imagine_units::desc::MachineDesc,
) -> usize {
    let mut passes = 1;
    for (u, op) in g.ops.iter().enumerate() {
        let (Region::Loop, false, Some(pl)) = (op.region, perm[u], s.place[u]) else {
            continue;
        };
        let w = pl.time + g.latency(u, desc);
        for &loc in &s.dests[u] {
            let r = last_read.live_end(slots, u, loc, w);
            passes = passes.max((r - w + ii - 1) / ii);
        }
    }
    passes as usize
}

/// Values live in each location (LRFs, then the condition codes) in the loop at interval
/// `ii`: per row of the interval, the loop's values written there (from landing to last
/// read), and the values kept there for the whole loop.
pub struct Liveness {
    pub rows: Vec<Vec<usize>>,
    pub kept: Vec<usize>,
}

impl Liveness {
    pub fn new(
        g: &Graph,
        s: &Schedule,
        slots: &Slots,
        ii: i64,
        desc: &imagine_units::desc::MachineDesc,
    ) -> Liveness {
        let last_read = LastReads::new(g, s, slots, Some(Region::Loop));
        Liveness::with_last_reads(g, s, slots, ii, desc, &last_read)
    }

    /// [`Liveness::new`] with the loop's readers' last reads found already.
    pub fn with_last_reads(
        g: &Graph,
        s: &Schedule,
        slots: &Slots,
        ii: i64,
        desc: &imagine_units::desc::MachineDesc,
        last_read: &LastReads,
    ) -> Liveness {
        let nlrf = slots.lrfs();
        let perm = permanent(g);
        let mut kept = vec![0usize; nlrf + 1];
        let mut rows = vec![vec![0usize; ii as usize]; nlrf + 1];
        for (u, op) in g.ops.iter().enumerate() {
            if perm[u] && op.tie.is_none() {
                for &loc in &s.dests[u] {
                    kept[index(slots, loc)] += 1;
                }
                continue;
            }
            if perm[u] || op.region != Region::Loop {
                continue;
            }
            let Some(pl) = s.place[u] else { continue };
            let w = pl.time + g.latency(u, desc);
            for &loc in &s.dests[u] {
                let r = last_read.live_end(slots, u, loc, w);
                let rows = &mut rows[index(slots, loc)];
                for run in circle::cycles(w, r, ii) {
                    rows[run].iter_mut().for_each(|x| *x += 1);
                }
            }
        }
        Liveness { rows, kept }
    }

    /// The most values live at once in location `k` (an index as [`index`] gives).
    pub fn peak(&self, k: usize) -> usize {
        self.kept[k] + self.rows[k].iter().copied().max().unwrap_or(0)
    }
}

/// The index of a location in [`Liveness`]: LRFs, then the condition codes.
pub fn index(slots: &Slots, loc: Loc) -> usize {
    match loc {
        Loc::Lrf(l) => l as usize,
        Loc::Cc => slots.lrfs(),
    }
}

#[cfg(test)]
mod tests {
    use super::{Arc, colour, last_below, row_bits, rows, tabu_colour};

    /// Arcs round a circle of `m` rows from a small deterministic generator.
    fn arcs(count: usize, m: usize, longest: usize, seed: u64) -> Vec<Arc> {
        let mut x = seed;
        let mut next = |n: usize| {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((x >> 33) % n as u64) as usize
        };
        (0..count).map(|_| (next(m), 1 + next(longest))).collect()
    }

    fn max_live(arcs: &[Arc], m: usize) -> usize {
        let mut live = vec![0; m];
        for &arc in arcs {
            for c in rows(arc, m) {
                live[c] += 1;
            }
        }
        live.into_iter().max().unwrap_or(0)
    }

    /// No entry of `entries` is held by two arcs at one row.
    fn assert_valid(arcs: &[Arc], entries: &[usize], m: usize) {
        let mut held = rustc_hash::FxHashSet::default();
        for (&arc, &e) in arcs.iter().zip(entries) {
            for c in rows(arc, m) {
                assert!(held.insert((e, c)), "entry {e} twice at row {c} of {m}");
            }
        }
    }

    #[test]
    fn colouring_gives_no_entry_two_arcs_at_once() {
        for seed in 0..20 {
            let m = 120;
            let arcs = arcs(60, m, 40, seed);
            let need = max_live(&arcs, m);
            // Two entries below `first` are someone else's.
            let Some(entries) = colour(&arcs, 2, need + 4, m) else {
                panic!(
                    "seed {seed}: {need} live at most, not coloured in {}",
                    need + 2
                )
            };
            assert!(entries.iter().all(|e| (2..need + 4).contains(e)));
            assert_valid(&arcs, &entries, m);
        }
    }

    /// The loop values of vertex's mul0.a on gold8+F at interval 30, renamed over six
    /// passes (start row and lifetime of the first pass's copy): at most 12 live at once,
    /// 15 entries free. Backtracking runs out of steps on it; tabu search colours it.
    #[test]
    fn colouring_packs_long_lived_values_renamed_over_many_passes() {
        let (ii, passes, m) = (30, 6, 180);
        let values = [
            (115, 100),
            (129, 96),
            (152, 82),
            (29, 8),
            (35, 1),
            (36, 4),
            (37, 1),
            (38, 1),
            (41, 1),
            (45, 2),
            (46, 2),
            (47, 2),
            (49, 1),
            (50, 1),
            (52, 1),
        ];
        let arcs: Vec<Arc> = values
            .iter()
            .flat_map(|&(start, len)| (0..passes).map(move |p| ((start + p * ii) % m, len)))
            .collect();
        assert!(max_live(&arcs, m) <= 12);
        let entries = colour(&arcs, 1, 16, m).expect("coloured in 15 entries");
        assert!(entries.iter().all(|e| (1..16).contains(e)));
        assert_valid(&arcs, &entries, m);
    }

    /// Arcs longer than half the circle never share an entry, however few are live at once.
    #[test]
    fn colouring_refuses_long_arcs_that_cannot_share() {
        let arcs = [(0, 70), (40, 70), (80, 70)];
        assert_eq!(max_live(&arcs, 120), 2);
        assert_eq!(colour(&arcs, 0, 2, 120), None);
        let entries = colour(&arcs, 0, 3, 120).expect("one entry each");
        assert_valid(&arcs, &entries, 120);
    }

    #[test]
    fn tabu_colouring_is_valid_or_refuses() {
        for seed in 0..10 {
            let m = 96;
            let arcs = arcs(50, m, 48, seed);
            let need = max_live(&arcs, m);
            let bits: Vec<Vec<u64>> = arcs.iter().map(|&arc| row_bits(arc, m)).collect();
            let colours = tabu_colour(&bits, need + 2).unwrap_or_else(|| {
                panic!("seed {seed}: {need} live, not coloured in {}", need + 2)
            });
            assert!(colours.iter().all(|&c| c < need + 2));
            assert_valid(&arcs, &colours, m);
            // Fewer colours than arcs live at once: never a colouring.
            assert_eq!(tabu_colour(&bits, need - 1), None, "seed {seed}");
        }
    }

    #[test]
    fn last_below_finds_the_highest_held_row_below_a_limit() {
        let m: usize = 150;
        for seed in 0..20 {
            let mut bits = vec![0u64; m.div_ceil(64)];
            for arc in arcs(3, m, 20, seed) {
                for (b, a) in bits.iter_mut().zip(row_bits(arc, m)) {
                    *b |= a;
                }
            }
            for limit in 0..=m {
                let naive = (0..limit)
                    .rev()
                    .find(|&c| bits[c / 64] >> (c % 64) & 1 == 1);
                assert_eq!(last_below(&bits, limit), naive, "seed {seed} limit {limit}");
            }
        }
    }

    #[test]
    fn colouring_fails_when_more_arcs_are_live_than_entries() {
        let arcs = arcs(60, 120, 40, 7);
        let need = max_live(&arcs, 120);
        assert_eq!(colour(&arcs, 0, need - 1, 120), None);
    }
}
