//! `merge`: merges pairs of sorted 32-word chunks of u32 keys into sorted 64-word chunks
//! with Batcher's bitonic merging network (Batcher, "Sorting Networks and their
//! Applications", AFIPS 1968) — the merge stage after [`sort32`](super::sort32) in the
//! OpenGL pipeline (Owens et al., "Polygon Rendering on a Stream Architecture", Graphics
//! Hardware 2000).
//!
//! Input `chunks`: pairs of ascending 32-word chunks; output `merged`: each pair's 64 keys
//! ascending (unsigned). Built for the machine's cluster count `C` (a power of two up to
//! 32): an iteration reads `2k` words per cluster (`k = 32 / C`), element `i = j·C + c` of
//! the pair in read `j` of cluster `c`. The second chunk is reversed — its word `i` moves
//! to `31 − i`: read `k − 1 − j` through a comm `Xor(C − 1)` — which makes the pair one
//! bitonic sequence; six half-cleaner steps (distances 32, 16, …, 1, all ascending) sort it.

use imagine_units::arith::fp32::testgen::SplitMix64;
use imagine_units::desc::MachineDesc;

use super::finish;
use super::sort32::{CHUNK, Network, Order, Step, random_keys, words_per_cluster};
use crate::kernel::{
    Kernel, KernelBuilder, KernelInputs, LoopSpec, MachineRequirementError, Needs, Perm, Value,
};

/// Needs a power-of-two cluster count up to 32, and a condition code for each condition of
/// a step between clusters (they are kept across the loop).
pub fn build(desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    let clusters = desc.cluster.count;
    let needs = Needs::new("merge", desc);
    let k = words_per_cluster(needs)?;
    let mut b = KernelBuilder::new("merge");
    let chunks = b.input("chunks");
    let merged = b.output("merged");
    let steps: Vec<Step> = (0..=CHUNK.trailing_zeros())
        .rev()
        .map(|s| Step {
            distance: 1 << s,
            order: Order::Ascending,
        })
        .collect();
    let network = Network::new(&mut b, clusters, 2 * k, &steps);
    network.check_condition_codes(needs)?;
    b.begin_loop(LoopSpec::OverStream(chunks));
    let first: Vec<Value> = (0..k).map(|_| b.read(chunks)).collect();
    let second: Vec<Value> = (0..k).map(|_| b.read(chunks)).collect();
    let mut words = first;
    for &w in second.iter().rev() {
        words.push(if clusters > 1 {
            b.comm(w, Perm::Xor(clusters as u16 - 1))
        } else {
            w
        });
    }
    for &step in &steps {
        network.step(&mut b, &mut words, step);
    }
    for w in words {
        b.write(merged, w);
    }
    b.end_loop();
    Ok(finish(b))
}

/// `rows` pairs of sorted chunks of random keys (with repeats and extremes).
pub fn inputs(_desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let mut rng = SplitMix64::new(seed);
    let mut keys = random_keys(&mut rng, rows * 2 * CHUNK);
    for chunk in keys.chunks_mut(CHUNK) {
        chunk.sort_unstable();
    }
    KernelInputs {
        streams: vec![keys, Vec::new()],
        params: Vec::new(),
    }
}
