//! LRF and condition-code entry allocation, after scheduling.
//!
//! Values live across regions (computed before the loop and read in or after it, and the
//! loop's carried values) keep their entries for the whole kernel. The other values are
//! packed first-fit: a value written at cycle `w` and last read at `r` holds its entry over
//! `[w, r)` — in the loop modulo the length of the loop body. A body of one interval holds
//! each value in one entry, which the next iteration rewrites; a value that outlives the
//! interval makes the body a few passes long, and then each pass's copy of the value gets
//! an entry of its own (modulo variable expansion).

use std::collections::HashMap;

use super::graph::{Graph, Loc, Source};
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
    match pack(g, s, slots, ii, desc, false) {
        // Packing the loop's values round the interval in order of issue can leave gaps
        // that a later value does not fit. Then every pass's copy of every loop value
        // gets an entry of its own (full renaming under modulo variable expansion, Rau et
        // al., "Register allocation for software pipelined loops", PLDI 1992), so each
        // copy is a single arc round the unrolled body, and the arcs are coloured by a
        // search ([`colour`]), which needs barely more entries than values live at once.
        Err(o) if o.region == Some(Region::Loop) => {
            pack(g, s, slots, ii, desc, true).map_err(|_| o)
        }
        other => other,
    }
}

/// Packs the entries, the loop's values first-fit in order of issue or, with `renamed`,
/// each pass's copy of each by [`colour`].
fn pack(
    g: &Graph,
    s: &Schedule,
    slots: &Slots,
    ii: Option<i64>,
    desc: &imagine_units::desc::MachineDesc,
    renamed: bool,
) -> Result<Entries, Overflow> {
    let n = g.ops.len();
    let perm = permanent(g);
    let last_read = last_reads(g, s, slots, None);
    let nlrf = slots.lrfs();
    let capacity = |loc: Loc| match loc {
        Loc::Lrf(l) => slots.shape.lrf_sizes[l as usize],
        Loc::Cc => slots.shape.condition_codes,
    };
    let index = |loc: Loc| index(slots, loc);
    let mut out = Entries {
        peak: vec![0; nlrf],
        unroll: ii.map_or(1, |ii| unroll(g, s, &perm, &last_read, ii, desc)),
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
    let mut kept_from: HashMap<(usize, u16), i64> = HashMap::new();
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
    let mut packed: HashMap<(usize, Loc), Vec<u16>> = HashMap::new();
    if let (true, Some(m), Some(ii)) = (renamed, modulus, ii) {
        // Per location: each value and the rows each pass's copy of it is live.
        type Copies = Vec<(usize, Vec<Vec<i64>>)>;
        let mut by_loc: Vec<(Loc, Copies)> = Vec::new();
        for &(u, loc) in &pairs {
            if g.ops[u].region != Region::Loop {
                continue;
            }
            let w = s.place[u].expect("placed").time + g.latency(u, desc);
            let r = live_end(&last_read, u, loc, w);
            let passes =
                (0..out.unroll as i64).map(|j| (w + j * ii..r + j * ii).map(|c| c.rem_euclid(m)));
            let held: Vec<Vec<i64>> = passes.map(Iterator::collect).collect();
            match by_loc.iter_mut().find(|(l, _)| *l == loc) {
                Some((_, v)) => v.push((u, held)),
                None => by_loc.push((loc, vec![(u, held)])),
            }
        }
        for (loc, values) in by_loc {
            let k = index(loc);
            let first = next_perm[k];
            let items: Vec<Vec<i64>> = values.iter().flat_map(|(_, h)| h.iter().cloned()).collect();
            let Some(colours) = colour(&items, first, capacity(loc), m as usize) else {
                return Err(Overflow {
                    loc,
                    needed: capacity(loc) + 1,
                    entries: capacity(loc),
                    region: Some(Region::Loop),
                });
            };
            let mut it = colours.into_iter();
            for (u, held) in values {
                let es: Vec<u16> = held
                    .iter()
                    .map(|_| it.next().expect("coloured") as u16)
                    .collect();
                let o = &mut occ[k];
                for (cycles, &e) in held.iter().zip(&es) {
                    let bits = &mut o.modulo[e as usize];
                    if bits.is_empty() {
                        bits.resize(m as usize, false);
                    }
                    for &c in cycles {
                        bits[c as usize] = true;
                    }
                }
                packed.insert((u, loc), es);
            }
        }
    }
    for (u, loc) in pairs {
        let pl = s.place[u].expect("placed");
        let region = g.ops[u].region;
        let w = pl.time + g.latency(u, desc);
        if let Some(es) = packed.remove(&(u, loc)) {
            if let [e] = es[..] {
                out.entry.insert((u, loc), e);
            } else {
                out.instances.insert((u, loc), es);
            }
            continue;
        }
        {
            let r = live_end(&last_read, u, loc, w);
            let k = index(loc);
            let first = next_perm[k];
            let cap = capacity(loc);
            let o = &mut occ[k];
            // The cycles each entry to choose is held: one entry for every pass of the
            // unrolled loop body unless the value outlives the interval, when each pass
            // gets an entry of its own.
            let held: Vec<Vec<i64>> = match (region, ii, modulus) {
                (Region::Loop, Some(ii), Some(m)) => {
                    let passes = (0..out.unroll as i64)
                        .map(|j| (w + j * ii..r + j * ii).map(|c| c.rem_euclid(m)));
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
                            cycles.iter().all(|&c| !bits[c as usize])
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
                        for &c in cycles {
                            o.modulo[e][c as usize] = true;
                        }
                    }
                    _ => o.line[e].push((region, w, r)),
                }
                chosen.push(e as u16);
            }
            if let [e] = chosen[..] {
                out.entry.insert((u, loc), e);
            } else {
                out.instances.insert((u, loc), chosen);
            }
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

/// Entries in `first..entries` for arcs (each the rows, in order, of an arc round a circle
/// of `m` rows), no two sharing a row in one entry, or `None` within a bounded search.
///
/// The arcs crossing the row where fewest are live go first, then the rest in order of
/// their first row from there (the left-edge order, which colours intervals with as many
/// entries as are live at once); each takes the entry whose last arc ends nearest before
/// it starts, and a dead end backs up to the arc before.
fn colour(items: &[Vec<i64>], first: usize, entries: usize, m: usize) -> Option<Vec<usize>> {
    const STEPS: usize = 20_000;
    let mut live = vec![0usize; m];
    for item in items {
        for &c in item {
            live[c as usize] += 1;
        }
    }
    let cut = (0..m).min_by_key(|&c| (live[c], c)).unwrap_or(0) as i64;
    let mut order: Vec<usize> = (0..items.len()).collect();
    order.sort_by_key(|&i| {
        let item = &items[i];
        let start = item.first().copied().unwrap_or(0);
        (!item.contains(&cut), (start - cut).rem_euclid(m as i64))
    });
    let items: Vec<&Vec<i64>> = order.iter().map(|&i| &items[i]).collect();
    let words = m.div_ceil(64);
    let bits: Vec<Vec<u64>> = items
        .iter()
        .map(|cycles| {
            let mut b = vec![0u64; words];
            for &c in cycles.iter() {
                b[c as usize / 64] |= 1 << (c as usize % 64);
            }
            b
        })
        .collect();
    let mut used = vec![vec![0u64; words]; entries];
    let free = |used: &[u64], b: &[u64]| used.iter().zip(b).all(|(x, y)| x & y == 0);
    let gap = |used: &[u64], start: i64| -> usize {
        (1..=m as i64)
            .find(|&d| {
                let c = (start - d).rem_euclid(m as i64) as usize;
                used[c / 64] >> (c % 64) & 1 == 1
            })
            .unwrap_or(m as i64) as usize
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
            let start = items[i].first().copied().unwrap_or(0);
            let mut options: Vec<(usize, usize)> = (first..entries)
                .filter(|&e| free(&used[e], &bits[i]))
                .map(|e| (gap(&used[e], start), e))
                .collect();
            options.sort_unstable_by(|a, b| b.cmp(a));
            choice.push(options.into_iter().map(|(_, e)| e).collect());
        }
        steps += 1;
        if steps > STEPS {
            return None;
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

/// Passes the loop body at interval `ii` is unrolled into: its longest-lived value's
/// lifetime (landing to last read), in intervals.
fn unroll(
    g: &Graph,
    s: &Schedule,
    perm: &[bool],
    last_read: &HashMap<(usize, Loc), i64>,
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
            let r = live_end(last_read, u, loc, w);
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
        let nlrf = slots.lrfs();
        let perm = permanent(g);
        let mut kept = vec![0usize; nlrf + 1];
        let mut rows = vec![vec![0usize; ii as usize]; nlrf + 1];
        let last_read = last_reads(g, s, slots, Some(Region::Loop));
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
                let r = live_end(&last_read, u, loc, w);
                for c in w..r {
                    rows[index(slots, loc)][c.rem_euclid(ii) as usize] += 1;
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

/// The last cycle each value is read from each location, in the reader's region time;
/// with `region`, only the readers in that region count.
pub fn last_reads(
    g: &Graph,
    s: &Schedule,
    slots: &Slots,
    region: Option<Region>,
) -> HashMap<(usize, Loc), i64> {
    let mut last_read: HashMap<(usize, Loc), i64> = HashMap::new();
    for (u, op) in g.ops.iter().enumerate() {
        let Some(pl) = s.place[u] else { continue };
        if region.is_some_and(|r| r != op.region) {
            continue;
        }
        for a in &op.args {
            if let Source::Local(p) = a.src {
                let loc = slots.operand_loc(op.kind, pl.slot, pl.swap, a);
                let e = last_read.entry((p, loc)).or_insert(pl.time);
                *e = (*e).max(pl.time);
            }
        }
    }
    last_read
}

/// Until when value `u`, landing in `loc` at cycle `w`, holds its entry: its last read
/// there, and at least the cycle after it lands.
fn live_end(last_read: &HashMap<(usize, Loc), i64>, u: usize, loc: Loc, w: i64) -> i64 {
    last_read.get(&(u, loc)).map_or(w + 1, |&r| r.max(w + 1))
}

#[cfg(test)]
mod tests {
    use super::colour;

    /// Arcs round a circle of `m` rows from a small deterministic generator.
    fn arcs(count: usize, m: i64, longest: i64, seed: u64) -> Vec<Vec<i64>> {
        let mut x = seed;
        let mut next = |n: i64| {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((x >> 33) % n as u64) as i64
        };
        (0..count)
            .map(|_| {
                let (start, len) = (next(m), 1 + next(longest));
                (start..start + len).map(|c| c.rem_euclid(m)).collect()
            })
            .collect()
    }

    fn max_live(items: &[Vec<i64>], m: usize) -> usize {
        let mut live = vec![0; m];
        for item in items {
            for &c in item {
                live[c as usize] += 1;
            }
        }
        live.into_iter().max().unwrap_or(0)
    }

    #[test]
    fn colouring_gives_no_entry_two_arcs_at_once() {
        for seed in 0..20 {
            let m = 120;
            let items = arcs(60, m, 40, seed);
            let need = max_live(&items, m as usize);
            // Two entries below `first` are someone else's.
            let Some(entries) = colour(&items, 2, need + 4, m as usize) else {
                panic!(
                    "seed {seed}: {need} live at most, not coloured in {}",
                    need + 2
                )
            };
            let mut held = vec![vec![false; m as usize]; need + 4];
            for (item, &e) in items.iter().zip(&entries) {
                assert!((2..need + 4).contains(&e));
                for &c in item {
                    assert!(!held[e][c as usize], "seed {seed}: entry {e} twice at {c}");
                    held[e][c as usize] = true;
                }
            }
        }
    }

    #[test]
    fn colouring_fails_when_more_arcs_are_live_than_entries() {
        let items = arcs(60, 120, 40, 7);
        let need = max_live(&items, 120);
        assert_eq!(colour(&items, 0, need - 1, 120), None);
    }
}
