//! Unit binding, before scheduling: every op gets its slot (which adder, multiplier, comm
//! unit) and commutative ops their operand order. The binding decides which LRFs each value
//! is written to — one per distinct (slot, input) its readers read it through — so the
//! scheduler knows, when it places a producer, every write port its result needs.
//!
//! Ops are bound in program order to the least-loaded unit of their class, preferring
//! units whose input LRFs already receive their operands. A value read from more than two
//! LRFs (a result has two switch destinations) gets `mov` copies: it keeps its most-read
//! LRF and a copy serves the rest (recursively). This is the copy insertion of
//! communication scheduling on distributed register files (Mattson et al., MICRO 2000), in
//! its simplest greedy form. In the loop such a copy, and a lifetime copy, goes to the
//! adder or multiplier with most room: on a multiplier it is `imul_lo(x, 1)`, which copies
//! `x` exactly, so a loop that fills its adders can still copy values through an idle
//! multiplier.

use rustc_hash::FxHashMap as HashMap;

use imagine_units::ops::{Op, UnitClass};

use super::graph::{Arg, CopyKind, Graph, Kind, Loc, MOp, Source, commutative};
use super::schedule::{Schedule, Slots};
use crate::kernel::Region;

/// Binds the ops of `region` and sets their destinations (and the locations earlier
/// regions' values are required in).
pub fn bind(g: &mut Graph, sched: &mut Schedule, region: Region, ii: Option<i64>, slots: &Slots) {
    undo_fanout_copies(g, region);
    let mut ops = g.in_region(region);
    ops.sort_by_key(|&o| (g.ops[o].ir.map_or(u32::MAX, |v| v.0), o));
    let nfu = slots.shape.fu_count();
    let mut load = vec![0usize; nfu + slots.shape.comm_units];
    let mut groups: HashMap<usize, Vec<Loc>> = HashMap::default();
    // Values of earlier regions kept in each LRF (for the whole loop), and where.
    let mut kept = vec![0usize; slots.lrfs()];
    let mut kept_at: rustc_hash::FxHashSet<(usize, Loc)> = rustc_hash::FxHashSet::default();
    for (p, r) in sched.required.iter().enumerate() {
        for &(l, by) in r {
            if by != region
                && kept_at.insert((p, l))
                && let Loc::Lrf(x) = l
            {
                kept[x as usize] += 1;
            }
        }
    }
    for &o in &ops {
        groups.insert(o, g.ops[o].seeded.clone());
    }
    // A copy in the loop may go through a multiplier (`imul_lo(x, 1)`) when the adders are
    // busier: it reads the constant 1, kept before the loop.
    let one = (ii.is_some() && slots.shape.multipliers > 0).then(|| g.copy_multiplicand());
    let mut one_used = false;
    let mul_extra = slots.mul_copy_extra;
    let mut options: Vec<(usize, bool)> = Vec::new();
    // Each op's local operands and where it reads them (one buffer for every op).
    let mut reads: Vec<(usize, Loc)> = Vec::new();
    for &u in &ops {
        let through_mul = one.filter(|_| g.ops[u].copy_kind == Some(CopyKind::Lifetime));
        if let Some(one) = through_mul {
            // Bound as a `mov` first; a multiplier slot below makes it an `imul_lo`.
            let op = &mut g.ops[u];
            if op.kind == Kind::Fu(Op::IMulLo) {
                op.kind = Kind::Fu(Op::Mov);
                op.args.retain(|a| a.src != Source::Earlier(one));
                op.deadline = op.deadline.map(|d| d + mul_extra);
            }
        }
        let op = &g.ops[u];
        match op.kind {
            Kind::Fu(_) if through_mul.is_some() => {
                options.clear();
                options.extend(
                    slots
                        .fu_slots(UnitClass::Adder)
                        .chain(slots.fu_slots(UnitClass::Multiplier))
                        .map(|k| (k, false)),
                );
            }
            Kind::Fu(o) => fu_options_into(op, o, slots, &mut options),
            Kind::Comm(_) => {
                options.clear();
                options.extend((0..slots.shape.comm_units).map(|k| (k, false)));
            }
            // One scratchpad holds the kernel's data; stream and immediate slots are
            // assigned when the instruction is written.
            _ => {
                options.clear();
                options.push((0, false));
            }
        }
        let weight = match op.kind {
            Kind::Fu(o) if o.unit() == UnitClass::DivSqrt => slots.dsq_interval,
            _ => 1,
        };
        let load_index = |k: usize| match op.kind {
            Kind::Fu(_) => Some(k),
            Kind::Comm(_) => Some(nfu + k),
            _ => None,
        };
        let is_mul =
            |k: usize| through_mul.is_some() && slots.fu_slots(UnitClass::Multiplier).contains(&k);
        let cost = |&(k, swap): &(usize, bool)| -> usize {
            let mut c = load_index(k).map_or(0, |i| load[i] * 2);
            if let (true, Some(one)) = (is_mul(k), through_mul) {
                // The constant's entry, and the longer latency.
                let l = slots.fu_inputs[k][1];
                if !kept_at.contains(&(one, Loc::Lrf(l))) {
                    let room = slots.shape.lrf_sizes[l as usize];
                    c += 8 + 96 * kept[l as usize] / room.max(1);
                }
                c += 4;
            }
            for a in &op.args {
                if let Source::Earlier(p) = a.src
                    && let Loc::Lrf(l) = slots.operand_loc(op.kind, k, swap, a)
                    && !kept_at.contains(&(p, Loc::Lrf(l)))
                {
                    // A new entry for the whole loop: cheap in an LRF with room.
                    let room = slots.shape.lrf_sizes[l as usize];
                    c += 8 + 96 * kept[l as usize] / room.max(1);
                }
                let Some(q) = local_source(a) else { continue };
                let loc = slots.operand_loc(op.kind, k, swap, a);
                let have = groups.get(&q).map_or(&[][..], |v| &v[..]);
                if loc != Loc::Cc && !have.contains(&loc) {
                    c += if have.len() >= 2 { 40 } else { 6 };
                }
            }
            c
        };
        // A unit may not take more than an interval's worth of ops.
        let fits = |&&(k, _): &&(usize, bool)| {
            ii.is_none_or(|ii| load_index(k).is_none_or(|i| (load[i] + weight) as i64 <= ii))
        };
        let &(slot, swap) = options
            .iter()
            .filter(fits)
            .min_by_key(|o| cost(o))
            .or_else(|| options.iter().min_by_key(|o| cost(o)))
            .expect("every op has a slot");
        if let Some(i) = load_index(slot) {
            load[i] += weight;
        }
        if let (true, Some(one)) = (is_mul(slot), through_mul) {
            let op = &mut g.ops[u];
            op.copy_through_multiplier(one);
            op.deadline = op.deadline.map(|d| d - mul_extra);
            one_used = true;
        }
        let op = &g.ops[u];
        reads.clear();
        reads.extend(op.args.iter().filter_map(|a| {
            local_source(a).map(|q| (q, slots.operand_loc(op.kind, slot, swap, a)))
        }));
        for a in &op.args {
            if let Source::Earlier(p) = a.src {
                let loc = slots.operand_loc(op.kind, slot, swap, a);
                if kept_at.insert((p, loc))
                    && let Loc::Lrf(x) = loc
                {
                    kept[x as usize] += 1;
                }
            }
        }
        let op = &mut g.ops[u];
        op.slot = slot;
        op.swap = swap;
        for &(q, loc) in &reads {
            let v = groups.entry(q).or_default();
            if !v.contains(&loc) {
                v.push(loc);
            }
        }
    }
    // Values read from more than two places get copies. (Each value's readers, found once
    // and kept as the copies take them over, in the order a scan of the ops finds them.)
    let mut readers: Vec<Vec<(usize, usize)>> = vec![Vec::new(); g.ops.len()];
    for o in g.in_region(region) {
        for (i, a) in g.ops[o].args.iter().enumerate() {
            if let Some(q) = local_source(a) {
                readers[q].push((o, i));
            }
        }
    }
    loop {
        let mut over: Vec<usize> = groups
            .iter()
            .filter(|(_, v)| v.len() > 2)
            .map(|(&q, _)| q)
            .collect();
        over.sort_unstable();
        let Some(&q) = over.first() else { break };
        let through_mul = split(
            g,
            &mut groups,
            &mut readers,
            &mut load,
            q,
            region,
            ii,
            one,
            slots,
        );
        one_used |= through_mul;
    }
    if let (Some(one), false) = (one, one_used) {
        g.ops[one].dead = true;
    }
    for r in &mut sched.required {
        r.retain(|&(_, by)| by != region);
    }
    sched.grow(g.ops.len());
    for u in 0..g.ops.len() {
        if g.ops[u].region == region && g.ops[u].dead {
            sched.dests[u].clear();
        }
    }
    for u in g.in_region(region) {
        sched.dests[u] = groups.get(&u).cloned().unwrap_or_default();
        let op = &g.ops[u];
        for a in &op.args {
            if let Source::Earlier(p) = a.src {
                let loc = slots.operand_loc(op.kind, op.slot, op.swap, a);
                if !sched.required[p].contains(&(loc, region)) {
                    sched.required[p].push((loc, region));
                }
            }
        }
    }
    // Carried values' movs are in the loop; their readers there are bound above.
    for (&q, v) in &groups {
        if g.ops[q].region == region {
            sched.dests[q] = v.clone();
        }
    }
}

/// The (slot, operands swapped) places FU op `op` (doing `o`) may be bound to: its fixed
/// slot or any unit of its class, a commutative op's operands either way round.
pub fn fu_options(op: &MOp, o: Op, slots: &Slots) -> Vec<(usize, bool)> {
    let mut options = Vec::new();
    fu_options_into(op, o, slots, &mut options);
    options
}

/// [`fu_options`] into `options` (cleared first), so that binding every op of a region
/// allocates them once.
fn fu_options_into(op: &MOp, o: Op, slots: &Slots, options: &mut Vec<(usize, bool)>) {
    let units = match op.fixed_slot {
        Some(s) => s..s + 1,
        None => slots.fu_slots(o.unit()),
    };
    let swaps: &[bool] = if commutative(o) && op.args.len() == 2 {
        &[false, true]
    } else {
        &[false]
    };
    options.clear();
    options.extend(units.flat_map(|k| swaps.iter().map(move |&s| (k, s))));
}

/// Sets the destinations of the values of `region` from where their readers, already
/// bound, read them (and the locations earlier regions' values are required in).
pub fn destinations(g: &Graph, sched: &mut Schedule, region: Region, slots: &Slots) {
    for r in &mut sched.required {
        r.retain(|&(_, by)| by != region);
    }
    let ops = g.in_region(region);
    for &u in &ops {
        sched.dests[u] = g.ops[u].seeded.clone();
    }
    for &u in &ops {
        let op = &g.ops[u];
        for a in &op.args {
            let loc = slots.operand_loc(op.kind, op.slot, op.swap, a);
            match a.src {
                Source::Local(q) | Source::Carried(q) => {
                    if !sched.dests[q].contains(&loc) {
                        sched.dests[q].push(loc);
                    }
                }
                Source::Earlier(p) => {
                    if !sched.required[p].contains(&(loc, region)) {
                        sched.required[p].push((loc, region));
                    }
                }
            }
        }
    }
}

/// The op whose result an operand reads in this region (carried values included).
fn local_source(a: &Arg) -> Option<usize> {
    match a.src {
        Source::Local(q) | Source::Carried(q) => Some(q),
        Source::Earlier(_) => None,
    }
}

/// Gives value `q` a copy: `q` keeps its seeded and most-read location, the copy (reading
/// `q` from its unit's `a` LRF) serves the other readers. In a loop the copy may go on a
/// multiplier, as `imul_lo(q, 1)` (`one` holds the 1), so that a loop whose adders are full
/// still runs at its bound. `value_readers` holds each value's (reader, argument) pairs in
/// the region, in op order; the copy's are added and `q`'s brought up to date. Returns
/// whether it went on a multiplier.
#[allow(clippy::too_many_arguments)]
fn split(
    g: &mut Graph,
    groups: &mut HashMap<usize, Vec<Loc>>,
    value_readers: &mut Vec<Vec<(usize, usize)>>,
    load: &mut [usize],
    q: usize,
    region: Region,
    ii: Option<i64>,
    one: Option<usize>,
    slots: &Slots,
) -> bool {
    let readers: Vec<(usize, usize, Loc)> = value_readers[q]
        .iter()
        .map(|&(o, i)| {
            let op = &g.ops[o];
            (
                o,
                i,
                slots.operand_loc(op.kind, op.slot, op.swap, &op.args[i]),
            )
        })
        .collect();
    let have = &groups[&q];
    let adders = slots.fu_slots(UnitClass::Adder);
    let multipliers = slots
        .fu_slots(UnitClass::Multiplier)
        .filter(|_| one.is_some());
    // Lower ranks first. In a loop: a unit with room in the interval, the least loaded
    // (an adder, or one whose LRF `q` is written to already, counting as a little less
    // loaded); elsewhere an adder `q` is written to already, else the least-loaded.
    let rank = |k: usize, mul: bool| {
        let new_lrf = usize::from(!have.contains(&Loc::Lrf(slots.fu_inputs[k][0])));
        match ii {
            Some(ii) => (
                load[k] as i64 >= ii,
                load[k] + 2 * new_lrf + usize::from(mul),
                0,
                k,
            ),
            None => (false, new_lrf, load[k], k),
        }
    };
    let (copy_slot, through_mul) = adders
        .map(|k| (k, false))
        .chain(multipliers.map(|k| (k, true)))
        .min_by_key(|&(k, mul)| rank(k, mul))
        .expect("machines have adders");
    let copy_loc = Loc::Lrf(slots.fu_inputs[copy_slot][0]);
    let mut keep: Vec<Loc> = g.ops[q].seeded.clone();
    if !keep.contains(&copy_loc) {
        keep.push(copy_loc);
    }
    if keep.len() < 2 {
        // The most-read other location stays too.
        let best = have.iter().filter(|l| !keep.contains(l)).max_by_key(|&&l| {
            (
                readers.iter().filter(|r| r.2 == l).count(),
                std::cmp::Reverse(l),
            )
        });
        if let Some(&l) = best {
            keep.push(l);
        }
    }
    load[copy_slot] += 1;
    let src = match g.ops[readers[0].0].args[readers[0].1].src {
        Source::Carried(m) => Source::Carried(m),
        _ => Source::Local(q),
    };
    let c = g.ops.len();
    let mut mov = MOp::copy_of(src, region, g.ops[q].ir, CopyKind::Fanout);
    mov.slot = copy_slot;
    if let (true, Some(one)) = (through_mul, one) {
        mov.copy_through_multiplier(one);
    }
    g.ops.push(mov);
    let mut moved: Vec<Loc> = Vec::new();
    let (mut stay, mut go) = (Vec::new(), Vec::new());
    for (o, i, loc) in readers {
        if keep.contains(&loc) {
            stay.push((o, i));
            continue;
        }
        g.ops[o].args[i].src = Source::Local(c);
        go.push((o, i));
        if !moved.contains(&loc) {
            moved.push(loc);
        }
    }
    // (The copy, the last op, reads `q` through its first argument.)
    stay.push((c, 0));
    value_readers[q] = stay;
    debug_assert_eq!(value_readers.len(), c, "an entry per op");
    value_readers.push(go);
    groups.insert(q, keep);
    groups.insert(c, moved);
    through_mul
}

/// Removes the fan-out copies a previous binding of `region` made: their readers read the
/// copied value again.
fn undo_fanout_copies(g: &mut Graph, region: Region) {
    let copies: Vec<usize> = g
        .in_region(region)
        .into_iter()
        .filter(|&c| g.ops[c].copy_kind == Some(CopyKind::Fanout))
        .collect();
    if copies.is_empty() {
        return;
    }
    let mut copied: Vec<Option<Source>> = vec![None; g.ops.len()];
    for &c in &copies {
        copied[c] = Some(g.ops[c].args[0].src);
    }
    // (A copy may copy another copy: its readers read the value first copied.)
    let original = |mut src: Source| {
        while let Source::Local(c) = src
            && let Some(copied) = copied[c]
        {
            src = copied;
        }
        src
    };
    for op in &mut g.ops {
        for a in &mut op.args {
            a.src = original(a.src);
        }
    }
    for c in copies {
        g.ops[c].dead = true;
    }
}
