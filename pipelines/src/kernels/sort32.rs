//! `sort32_keys`: sorts 32-word chunks of u32 keys in place with Batcher's bitonic sorting
//! network (Batcher, "Sorting Networks and their Applications", AFIPS 1968), as the sort
//! stage of the OpenGL pipeline does (Owens et al., "Polygon Rendering on a Stream
//! Architecture", Graphics Hardware 2000; the pipeline's own `sort32`,
//! [`crate::opengl::mergefrag::sort32`], sorts fragments by address).
//!
//! Input `keys`, output `sorted`: each 32-word chunk of the stream is sorted ascending
//! (unsigned compares). The kernel is built for the machine's cluster count `C` (a power of
//! two up to 32): an iteration reads `k = 32 / C` words per cluster, so chunk word
//! `i = j·C + c` is read `j` of cluster `c`. A compare-exchange of word `i` with its partner
//! `i xor d` is a comm `Xor(d)` and a select between `imin_u` and `imax_u` when `d < C`
//! (the partner is in another cluster), and a local `imin_u`/`imax_u` pair between reads
//! `j` and `j xor (d / C)` when `d ≥ C`.

use std::collections::HashMap;

use imagine_units::arith::fp32::testgen::SplitMix64;
use imagine_units::desc::MachineDesc;
use imagine_units::ops::Op;

use super::finish;
use crate::kernel::{
    Kernel, KernelBuilder, KernelInputs, LoopSpec, MachineRequirementError, Needs, Perm, Value,
};

/// Words of a chunk.
pub const CHUNK: usize = 32;

/// Which elements of a compare-exchange step end up holding the smaller key.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum Order {
    /// Every pair ascending.
    Ascending,
    /// Ascending where element bit `s` is clear, descending where it is set (the blocks of
    /// a bitonic sort's stage `s`).
    ByBit(usize),
}

/// One compare-exchange step of a bitonic network: every element `i` against `i xor d`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Step {
    pub distance: usize,
    pub order: Order,
}

/// The steps of a bitonic sort of `n` elements (a power of two).
pub(crate) fn sort_steps(n: usize) -> Vec<Step> {
    let mut steps = Vec::new();
    let mut size = 2;
    while size <= n {
        let mut distance = size / 2;
        while distance > 0 {
            let order = if size == n {
                Order::Ascending
            } else {
                Order::ByBit(size)
            };
            steps.push(Step { distance, order });
            distance /= 2;
        }
        size *= 2;
    }
    steps
}

/// Whether element `i` sorts its pair ascending.
fn ascending(order: Order, i: usize) -> bool {
    match order {
        Order::Ascending => true,
        Order::ByBit(s) => i & s == 0,
    }
}

/// A bitonic network over `words.len() · C` elements held as one value per cluster each:
/// element `i = j·C + c` is `words[j]` in cluster `c`.
pub(crate) struct Network {
    clusters: usize,
    /// Per-cluster conditions "this cluster's element keeps the smaller key" of the steps
    /// with `d < C`, computed before the loop.
    keeps_min: HashMap<(usize, Option<usize>, bool), Value>,
}

impl Network {
    /// Builds (before the loop) the conditions `steps` need.
    pub(crate) fn new(
        b: &mut KernelBuilder,
        clusters: usize,
        words: usize,
        steps: &[Step],
    ) -> Self {
        let mut net = Network {
            clusters,
            keeps_min: HashMap::new(),
        };
        let cluster = b.cluster_id();
        let zero = b.i32(0);
        let one = b.i32(1);
        for step in steps.iter().filter(|s| s.distance < clusters) {
            for j in 0..words {
                let key = net.key(*step, j);
                if net.keeps_min.contains_key(&key) {
                    continue;
                }
                let d = step.distance;
                let cond = match key {
                    // The bit of `i` that orders the pair is a cluster bit: the cluster
                    // keeps the minimum where its bits `d` and `s` agree.
                    (_, Some(s), _) => {
                        let d_bit = b.i32(d.trailing_zeros() as i32);
                        let s_bit = b.i32(s.trailing_zeros() as i32);
                        let by_d = b.shr(cluster, d_bit);
                        let by_s = b.shr(cluster, s_bit);
                        let differ = b.xor(by_d, by_s);
                        let differ = b.and(differ, one);
                        b.ieq(differ, zero)
                    }
                    // The lower element of an ascending pair keeps the minimum.
                    (_, None, ascending) => {
                        let distance = b.i32(d as i32);
                        let upper = b.and(cluster, distance);
                        if ascending {
                            b.ieq(upper, zero)
                        } else {
                            b.ine(upper, zero)
                        }
                    }
                };
                net.keeps_min.insert(key, cond);
            }
        }
        net
    }

    /// Checks that the machine has a condition code for each of the network's conditions:
    /// they are made before the loop and kept across it.
    pub(crate) fn check_condition_codes(
        &self,
        needs: Needs,
    ) -> Result<(), MachineRequirementError> {
        needs.condition_codes(
            self.keeps_min.len(),
            "the conditions of its steps between clusters, kept across the loop",
        )
    }

    /// What the condition of a cross-cluster step depends on: the distance, the ordering
    /// bit if it is a cluster bit, else whether word `j`'s pairs are ascending.
    fn key(&self, step: Step, j: usize) -> (usize, Option<usize>, bool) {
        match step.order {
            Order::ByBit(s) if s < self.clusters => (step.distance, Some(s), true),
            order => (step.distance, None, ascending(order, j * self.clusters)),
        }
    }

    /// Emits one compare-exchange step (in the loop).
    pub(crate) fn step(&self, b: &mut KernelBuilder, words: &mut [Value], step: Step) {
        let c = self.clusters;
        if step.distance >= c {
            let dj = step.distance / c;
            for j in (0..words.len()).filter(|j| j & dj == 0) {
                let (a, z) = (words[j], words[j | dj]);
                let min = b.op(Op::IMinU, &[a, z]);
                let max = b.op(Op::IMaxU, &[a, z]);
                let (low, high) = if ascending(step.order, j * c) {
                    (min, max)
                } else {
                    (max, min)
                };
                words[j] = low;
                words[j | dj] = high;
            }
        } else {
            for (j, word) in words.iter_mut().enumerate() {
                let partner = b.comm(*word, Perm::Xor(step.distance as u16));
                let min = b.op(Op::IMinU, &[*word, partner]);
                let max = b.op(Op::IMaxU, &[*word, partner]);
                *word = b.select(self.keeps_min[&self.key(step, j)], min, max);
            }
        }
    }
}

/// Words per cluster of a chunk, `32 / C`, if the machine has a power-of-two cluster count
/// up to 32 (a chunk spread evenly over the clusters, exchanges between clusters by
/// `Xor(d)`).
pub(crate) fn words_per_cluster(needs: Needs) -> Result<usize, MachineRequirementError> {
    needs.power_of_two_clusters(Some(CHUNK))?;
    Ok(CHUNK / needs.clusters())
}

/// Needs a power-of-two cluster count up to 32, and a condition code for each condition of
/// a step between clusters (they are kept across the loop).
pub fn build(desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    let clusters = desc.cluster.count;
    let needs = Needs::new("sort32_keys", desc);
    let k = words_per_cluster(needs)?;
    let mut b = KernelBuilder::new("sort32_keys");
    let keys = b.input("keys");
    let sorted = b.output("sorted");
    let steps = sort_steps(CHUNK);
    let network = Network::new(&mut b, clusters, k, &steps);
    network.check_condition_codes(needs)?;
    b.begin_loop(LoopSpec::OverStream(keys));
    let mut words: Vec<Value> = (0..k).map(|_| b.read(keys)).collect();
    for &step in &steps {
        network.step(&mut b, &mut words, step);
    }
    for w in words {
        b.write(sorted, w);
    }
    b.end_loop();
    Ok(finish(b))
}

/// `rows` chunks of random keys, with a few repeated keys and extremes mixed in.
pub fn inputs(_desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let mut rng = SplitMix64::new(seed);
    KernelInputs {
        streams: vec![random_keys(&mut rng, rows * CHUNK), Vec::new()],
        params: Vec::new(),
    }
}

/// Random u32 keys: mostly uniform, some small (so that keys repeat), some extreme.
pub(crate) fn random_keys(rng: &mut SplitMix64, n: usize) -> Vec<u32> {
    (0..n)
        .map(|_| match rng.below(8) {
            0 => rng.below(4),
            1 => u32::MAX - rng.below(4),
            _ => rng.next_u32(),
        })
        .collect()
}
