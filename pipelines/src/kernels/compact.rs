//! `compact`: conditional compaction — keeps the fp32 words below a threshold, in stream
//! order, with a conditional output stream (Kapasi et al., "Efficient Conditional
//! Operations for Data-parallel Architectures", MICRO 2000).
//!
//! Input `values`; parameter `threshold`; output `kept`: the words `v` with `v < threshold`
//! (an IEEE compare: NaNs are dropped). One compare per element.

use imagine_units::arith::fp32::testgen::SplitMix64;
use imagine_units::desc::MachineDesc;

use super::{finish, uniform, uniform_words};
use crate::kernel::{Kernel, KernelBuilder, KernelInputs, LoopSpec, MachineRequirementError};

/// Any machine serves it (any cluster count; the units every description has).
pub fn build(_desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("compact");
    let values = b.input("values");
    let kept = b.output("kept");
    let threshold = b.param_f32("threshold");
    b.begin_loop(LoopSpec::OverStream(values));
    let v = b.read_f32(values);
    let below = b.flt(v, threshold);
    b.write_if(kept, below, v);
    b.end_loop();
    Ok(finish(b))
}

/// `rows × C` values in [-100, 100); a threshold in [-50, 50).
pub fn inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let mut rng = SplitMix64::new(seed);
    let values = uniform_words(&mut rng, rows * desc.cluster.count, -100.0, 100.0);
    KernelInputs {
        streams: vec![values, Vec::new()],
        params: vec![uniform(&mut rng, -50.0, 50.0).to_bits()],
    }
}
