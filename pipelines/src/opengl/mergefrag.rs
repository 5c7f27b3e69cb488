//! `sort32` and `mergefrag`: the composite's merge of conflicting fragments, after Owens
//! et al., "Polygon Rendering on a Stream Architecture", Graphics Hardware 2000 (which
//! sorts the fragments `hash` holds back by pixel address and merges those of the same
//! pixel before they go round again). The code is ours.
//!
//! Without this stage a pixel with `k` fragments in a chunk takes `k` composite rounds:
//! `hash` lets one of them through per round. With it, the fragments held back are cut
//! into groups of 32 (32 consecutive fragments of the round's stream; those `hash` let
//! through, and the nulls, count as empty slots; [`group`]: `4·C` on fewer than 8
//! clusters), each group is sorted by pixel address,
//! and of the fragments of one address only the one `zcompare` would keep survives: the
//! smaller (depth, primitive) as a pair of unsigned words. Survivors are unique per
//! address within their group, so a stack of fragments on one pixel shrinks by up to 32×
//! per round.
//!
//! **Exactness.** `zcompare` replaces a pixel by a fragment exactly when the fragment's
//! (depth, primitive) is below the pixel's as unsigned words, so after any sequence of
//! rounds a pixel holds the minimum over itself and all its fragments: dropping a fragment
//! that is not the minimum of its address's fragments changes nothing, bit for bit, and
//! ties of depth still go to the earlier primitive (OpenGL's order). Depths outside [0, 1]
//! (negative, above 1, NaN: [`NULL_DEPTH`](super::kernels::NULL_DEPTH)) are words above
//! 1.0's, so such a fragment wins only against others like it and then fails `zcompare`
//! as it would have. Empty slots carry the trash address, one past the window: they form
//! a run of their own that no real fragment joins, and no slot with the trash address
//! survives.
//!
//! **`sort32`** (streams `conflict`, `addr`, `z`, `prim` → `key`, `z_sorted`,
//! `prim_sorted`). The sort key of a slot is `addr·32 + p`, `p` its position in the group
//! and `addr` the trash address for a slot `hash` did not hold back: unique keys, ordered
//! by address and then stream order. Only the keys go through the bitonic network (the
//! library's [`Network`] of [`sort32`](crate::kernels::sort32): `C` clusters hold a group
//! as `32 / C` words each, slot `j·C + c` in word `j` of cluster `c`). Carrying the depth
//! and primitive through the network's compare-exchanges would take three comms per word
//! and cross-cluster step instead of one (12 such steps on 8 clusters); instead each
//! sorted slot fetches its depth and primitive once, from the slot `p` its key names: a
//! `Perm::PerCluster` comm of each of the source cluster's `32 / C` words and a select of
//! the right one (with one cluster, only the select).
//!
//! Of the two ways to move the payloads this one compiles to fewer cycles on gold8:
//! `sort32`'s loop has 48 comms for the network and 32 for the fetch per group (II 86),
//! where carrying both payloads would take 144 for the network alone. (`sort32` cannot
//! fetch the colour too: with it, 9 streams, one over `srf.kernel_streams`.)
//!
//! **`mergefrag`** (streams `key`, `z_sorted`, `prim_sorted` and `colour` in the original
//! order → `z`, `colour`, `addr`, `prim`, conditional, then a row of nulls). A segmented
//! suffix minimum over the sorted group: in steps `d` = 1, 2, 4, 8, 16 each slot looks at
//! slot `i + d` (a `Rotate` comm and a select when `d < C`, another word of the same
//! cluster otherwise) and takes its (key, depth, primitive) when that slot has the same
//! address and a smaller (depth, primitive). After the step with `d`, slot `i` holds the
//! best of `i .. i + 2d` within its run of equal addresses, so the first slot of a run
//! holds the run's winner; its key names the winner's position, from which it fetches the
//! colour (as `sort32` fetches depths). The first slot of each run of a real address is
//! written with conditional writes: the survivors, compacted, for the next round.
//!
//! **Stream lengths.** Both kernels work on whole groups of 32, but a round's stream is
//! whole rows of `C` fragments. `hash` therefore follows its `conflict` flags with
//! `32 / C − 1` rows of zeros: read up to the next multiple of 32, the extra slots are
//! empty whatever the other streams hold there.
//!
//! **When it runs** is the host's choice ([`render`](super::render)): the stage costs two
//! kernel calls, as the two `compact_recycle` calls it replaces do, but each runs longer
//! (on gold8, II 86 and 107 per group of 32, against a few cycles per row for
//! `compact_recycle`), and the host must wait for `mergefrag`'s output length before it
//! queues the next round. It pays where a chunk holds several fragments of a pixel.

use imagine_units::desc::MachineDesc;
use imagine_units::ops::Op;

use super::kernels::{FrameShape, NULL_DEPTH, finish, null_row};
use crate::kernel::{
    Kernel, KernelBuilder, LoopSpec, MachineRequirementError, Needs, Perm, Ty, Value,
};
use crate::kernels::sort32::{CHUNK, Network, sort_steps};

/// The most fragments of a group, and the unit the host rounds the kernels' streams up to.
pub const GROUP: usize = CHUNK;
/// Bits of a slot's position in its group, below the address in a sort key.
pub const POS_BITS: u32 = GROUP.trailing_zeros();

/// Fragments of a group on `clusters` clusters: 32, but `4·C` on fewer than eight
/// clusters, where a group of 32 would need more words per cluster than the LRFs hold
/// while the keys are sorted (a divisor of 32 either way). Meaningful for the cluster
/// counts the two kernels accept, powers of two up to 32 (see [`group_for`]).
pub fn group(clusters: usize) -> usize {
    (4 * clusters).min(GROUP)
}

/// The group of `needs`'s machine, if the kernel can spread a group over its clusters: a
/// power-of-two cluster count up to 32 (words `j·C + c`, exchanges between clusters by
/// `Xor(d)`).
fn group_for(needs: Needs) -> Result<usize, MachineRequirementError> {
    needs.power_of_two_clusters(Some(GROUP))?;
    Ok(group(needs.clusters()))
}

/// The largest trash address (window pixels) whose sort keys fit a word with room for the
/// sentinel of `mergefrag`.
pub const MAX_TRASH: u32 = (1 << (32 - POS_BITS)) - 2;
// Every window a valid scene may have fits.
const _: () = assert!(crate::scene::MAX_WINDOW * crate::scene::MAX_WINDOW < MAX_TRASH);

/// The words of the slots `keys` name (position `key mod 32`: cluster `pos mod C`, word
/// `pos / C`), for each of `payloads`: each cluster takes every word of the source cluster
/// by `Perm::PerCluster` comms (none with one cluster) and selects the one it needs.
fn fetch(
    b: &mut KernelBuilder,
    clusters: usize,
    keys: &[Value],
    payloads: &[&[Value]],
) -> Vec<Vec<Value>> {
    let k = keys.len();
    let cluster_mask = b.i32(clusters as i32 - 1);
    let word_mask = b.i32(k as i32 - 1);
    let cluster_bits = b.i32(clusters.trailing_zeros() as i32);
    let word_is: Vec<Value> = (0..k).map(|w| b.i32(w as i32)).collect();
    let mut out = vec![Vec::with_capacity(k); payloads.len()];
    for &key in keys {
        let source = b.and(key, cluster_mask);
        // Whether the source word is word w (for w ≥ 1).
        let which: Vec<Value> = if k > 1 {
            let w = if clusters > 1 {
                b.shr(key, cluster_bits)
            } else {
                key
            };
            let w = b.and(w, word_mask);
            (1..k).map(|i| b.ieq(w, word_is[i])).collect()
        } else {
            Vec::new()
        };
        for (p, words) in payloads.iter().enumerate() {
            let from = |b: &mut KernelBuilder, w: Value| {
                if clusters > 1 {
                    b.comm(w, Perm::PerCluster(source))
                } else {
                    w
                }
            };
            let mut v = from(b, words[0]);
            for (i, &w) in words.iter().enumerate().skip(1) {
                let other = from(b, w);
                v = b.select(which[i - 1], other, v);
            }
            out[p].push(v);
        }
    }
    out
}

/// `sort32`: sorts each group of 32 slots by (address, position) — the slots `hash` held
/// back at their address, the others at the trash address — and gathers each sorted
/// slot's depth and primitive. Outputs, unconditional: `key` (`addr·32 + position`),
/// `z_sorted`, `prim_sorted`.
///
/// Needs a power-of-two cluster count up to 32 and a condition code for each condition of
/// its network's steps between clusters (they are kept across the loop).
///
/// # Panics
/// If the window has more than [`MAX_TRASH`] pixels (a valid scene has fewer).
pub fn sort32(desc: &MachineDesc, shape: FrameShape) -> Result<Kernel, MachineRequirementError> {
    let c = desc.cluster.count;
    let needs = Needs::new("sort32", desc);
    let n = group_for(needs)?;
    let k = n / c;
    assert!(
        shape.trash() <= MAX_TRASH,
        "sort32: a {}×{} window has too many pixels for its sort keys",
        shape.width,
        shape.height
    );
    let mut b = KernelBuilder::new("sort32");
    let conflict_in = b.input("conflict");
    let addr_in = b.input("addr");
    let z_in = b.input("z");
    let prim_in = b.input("prim");
    let key_out = b.output("key");
    let z_out = b.output("z_sorted");
    let prim_out = b.output("prim_sorted");
    let steps = sort_steps(n);
    let network = Network::new(&mut b, c, k, &steps);
    network.check_condition_codes(needs)?;
    let zero = b.i32(0);
    let trash = b.i32(shape.trash() as i32);
    let scale = b.i32(1 << POS_BITS);
    let lane = b.cluster_id();
    let positions: Vec<Value> = (0..k)
        .map(|j| {
            let base = b.i32((j * c) as i32);
            b.iadd(lane, base)
        })
        .collect();
    b.begin_loop(LoopSpec::OverStream(conflict_in));
    let mut keys = Vec::with_capacity(k);
    let (mut zs, mut prims) = (Vec::with_capacity(k), Vec::with_capacity(k));
    for &pos in &positions {
        let conflict = b.read_i32(conflict_in);
        let addr = b.read_i32(addr_in);
        zs.push(b.read(z_in));
        prims.push(b.read(prim_in));
        let held = b.ine(conflict, zero);
        let addr = b.select(held, addr, trash);
        // addr·32 on a multiplier: the adders are the busier.
        let shifted = b.imul(addr, scale);
        keys.push(b.or(shifted, pos));
    }
    for &step in &steps {
        network.step(&mut b, &mut keys, step);
    }
    let fetched = fetch(&mut b, c, &keys, &[&zs, &prims]);
    for j in 0..k {
        b.write(key_out, keys[j]);
        b.write(z_out, fetched[0][j]);
        b.write(prim_out, fetched[1][j]);
    }
    b.end_loop();
    Ok(finish(b))
}

/// `mergefrag`: of each run of equal addresses in a sorted group, keeps the fragment with
/// the smallest (depth, primitive) as unsigned words, with its colour (gathered from the
/// group's `colour` words in stream order); drops the trash address. Outputs, conditional:
/// `z`, `colour`, `addr`, `prim` of the survivors, then a row of nulls.
///
/// Needs a power-of-two cluster count up to 32.
pub fn mergefrag(desc: &MachineDesc, shape: FrameShape) -> Result<Kernel, MachineRequirementError> {
    let c = desc.cluster.count;
    let n = group_for(Needs::new("mergefrag", desc))?;
    let k = n / c;
    let mut b = KernelBuilder::new("mergefrag");
    let key_in = b.input("key");
    let z_in = b.input("z_sorted");
    let prim_in = b.input("prim_sorted");
    let colour_in = b.input("colour");
    let z_out = b.output("z");
    let colour_out = b.output("colour_kept");
    let addr_out = b.output("addr");
    let prim_out = b.output("prim_kept");
    let zero = b.word(0);
    let same_bound = b.i32(1 << POS_BITS);
    let last_pos = b.i32((1 << POS_BITS) - 1);
    // A key no slot has, whose address differs from every slot's.
    let sentinel = b.word(u32::MAX);
    let trash_key = b.word(shape.trash() << POS_BITS);
    // addr = key >> 5 as `imul_hi_u(key, 2^27)`, on a multiplier.
    let to_addr = b.word(1 << (32 - POS_BITS));
    let lane = b.cluster_id();
    // Slot c + d is in the same word when c < C − d.
    let in_word: Vec<(usize, Value)> = (0..)
        .map(|s| 1usize << s)
        .take_while(|&d| d < c)
        .map(|d| {
            let bound = b.i32((c - d) as i32);
            (d, b.ilt(lane, bound))
        })
        .collect();
    let first_lane = {
        let z = b.i32(0);
        b.ieq(lane, z)
    };
    b.begin_loop(LoopSpec::OverStream(key_in));
    let key0: Vec<Value> = (0..k).map(|_| b.read(key_in)).collect();
    let mut zs: Vec<Value> = (0..k).map(|_| b.read(z_in)).collect();
    let mut prims: Vec<Value> = (0..k).map(|_| b.read(prim_in)).collect();
    let colours: Vec<Value> = (0..k).map(|_| b.read(colour_in)).collect();
    let mut keys = key0.clone();
    let mut d = 1;
    while d < n {
        // (key, z, prim) of slot i + d for each word, None past the group.
        let next: Vec<Option<[Value; 3]>> = if d < c {
            let low = in_word.iter().find(|&&(dd, _)| dd == d).expect("d < C").1;
            let rotated: Vec<[Value; 3]> = (0..k)
                .map(|j| [keys[j], zs[j], prims[j]].map(|v| b.comm(v, Perm::Rotate(d as u16))))
                .collect();
            (0..k)
                .map(|j| {
                    let here = rotated[j];
                    let on = rotated.get(j + 1).copied();
                    let key = b.select(low, here[0], on.map_or(sentinel, |o| o[0]));
                    let rest = [1, 2].map(|v| match on {
                        Some(o) => b.select(low, here[v], o[v]),
                        // Past the group: the key differs, the rest does not matter.
                        None => here[v],
                    });
                    Some([key, rest[0], rest[1]])
                })
                .collect()
        } else {
            let dj = d / c;
            (0..k)
                .map(|j| (j + dj < k).then(|| [keys[j + dj], zs[j + dj], prims[j + dj]]))
                .collect()
        };
        for (j, n) in next.into_iter().enumerate() {
            let Some([nkey, nz, nprim]) = n else {
                continue;
            };
            // Same address: the keys differ only in their position bits.
            let diff = b.xor(nkey, keys[j]);
            let same = b.iltu(diff, same_bound);
            // (nz, nprim) < (z, prim) as unsigned pairs, and never across runs.
            let z_equal = b.ieq(nz, zs[j]);
            let lhs = b.select(z_equal, nprim, nz);
            let rhs = b.select(z_equal, prims[j], zs[j]);
            let rhs = b.select(same, rhs, zero);
            let take = b.iltu(lhs, rhs);
            keys[j] = b.select(take, nkey, keys[j]);
            zs[j] = b.select(take, nz, zs[j]);
            prims[j] = b.select(take, nprim, prims[j]);
        }
        d *= 2;
    }
    // The first slot of a run: its predecessor's address differs (slot 0 has none).
    let previous: Vec<Value> = if c > 1 {
        let rotated: Vec<Value> = key0
            .iter()
            .map(|&v| b.comm(v, Perm::Rotate(c as u16 - 1)))
            .collect();
        (0..k)
            .map(|j| {
                let before = if j == 0 { sentinel } else { rotated[j - 1] };
                b.select(first_lane, before, rotated[j])
            })
            .collect()
    } else {
        (0..k)
            .map(|j| if j == 0 { sentinel } else { key0[j - 1] })
            .collect()
    };
    let colour = fetch(&mut b, c, &keys, &[&colours]).remove(0);
    for j in 0..k {
        let diff = b.xor(previous[j], key0[j]);
        let head = b.iltu(last_pos, diff);
        // A run's first slot of a real address (below the trash address's keys).
        let masked = b.select(head, keys[j], trash_key);
        let keep = b.iltu(masked, trash_key);
        let addr = b.op(Op::IMulHiU, &[keys[j], to_addr]);
        let addr = b.cast(addr, Ty::I32);
        b.write_if(z_out, keep, zs[j]);
        b.write_if(colour_out, keep, colour[j]);
        b.write_if(addr_out, keep, addr);
        b.write_if(prim_out, keep, prims[j]);
    }
    b.end_loop();
    null_row(
        &mut b,
        &[
            (z_out, NULL_DEPTH),
            (colour_out, 0),
            (addr_out, shape.trash()),
            (prim_out, 0),
        ],
    );
    Ok(finish(b))
}
