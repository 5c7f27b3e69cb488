//! `prefix_sum`: the inclusive prefix sum of an int32 stream, wrapping on overflow.
//!
//! Input `values`, output `sums`: `sums[i] = values[0] + … + values[i]` (mod 2^32). Each
//! iteration takes one row of `C` words (cluster `c` holds word `c` of the row) and scans
//! it across the clusters in `log2 C` steps (Hillis & Steele, "Data Parallel Algorithms",
//! CACM 1986): at step `d = 1, 2, 4, …` every cluster receives the partial sum of the
//! cluster `d` below it (comm `Rotate(C − d)`) and adds it if it has such a cluster
//! (`d ≤ c`, a select on the cluster index). A loop-carried running total — the last
//! cluster's sum of the previous row, broadcast to all (comm `Broadcast(C − 1)`) — is then
//! added.

use imagine_units::arith::fp32::testgen::SplitMix64;
use imagine_units::desc::MachineDesc;

use super::finish;
use crate::kernel::{
    Kernel, KernelBuilder, KernelInputs, LoopSpec, MachineRequirementError, Needs, Perm, Value,
};

/// Serves any cluster count; needs a condition code for each of the scan's `⌈log2 C⌉`
/// steps (whether a cluster adds, kept across the loop).
pub fn build(desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    let clusters = desc.cluster.count;
    let mut b = KernelBuilder::new("prefix_sum");
    let values = b.input("values");
    let sums = b.output("sums");
    let cluster = b.cluster_id();
    let zero = b.i32(0);
    let steps = scan_steps(&mut b, clusters, cluster);
    Needs::new("prefix_sum", desc).condition_codes(
        steps.len(),
        "whether a cluster adds at each step of the scan, kept across the loop",
    )?;

    b.begin_loop(LoopSpec::OverStream(values));
    let total = b.carried(zero);
    b.name(total, "running_total");
    let value = b.read_i32(values);
    let partial = inclusive_scan(&mut b, clusters, &steps, value);
    let sum = b.iadd(partial, total);
    b.write(sums, sum);
    let next_total = b.comm(sum, Perm::Broadcast((clusters - 1) as u16));
    b.set_next(total, next_total);
    b.end_loop();
    Ok(finish(b))
}

/// The steps of a scan across `clusters` clusters: each distance `d = 1, 2, 4, …` below
/// `clusters` and whether this cluster (`cluster`, its index) adds at it (`d ≤ c`).
pub(crate) fn scan_steps(
    b: &mut KernelBuilder,
    clusters: usize,
    cluster: Value,
) -> Vec<(usize, Value)> {
    (0..)
        .map(|s| 1usize << s)
        .take_while(|&d| d < clusters)
        .map(|d| {
            let distance = b.i32(d as i32);
            (d, b.ile(distance, cluster))
        })
        .collect()
}

/// The inclusive scan (int32 sum) of `x` across the clusters, by the steps of
/// [`scan_steps`]: cluster `c` gets the sum of `x` over clusters `0 ..= c`.
pub(crate) fn inclusive_scan(
    b: &mut KernelBuilder,
    clusters: usize,
    steps: &[(usize, Value)],
    x: Value,
) -> Value {
    let mut partial = x;
    for &(d, adds) in steps {
        let below = b.comm(partial, Perm::Rotate((clusters - d) as u16));
        let added = b.iadd(partial, below);
        partial = b.select(adds, added, partial);
    }
    partial
}

/// `rows × C` random words.
pub fn inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let mut rng = SplitMix64::new(seed);
    let values = (0..rows * desc.cluster.count)
        .map(|_| rng.next_u32())
        .collect();
    KernelInputs {
        streams: vec![values, Vec::new()],
        params: Vec::new(),
    }
}
