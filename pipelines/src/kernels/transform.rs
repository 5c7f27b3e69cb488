//! `transform`: a 4×4 fp32 matrix times homogeneous positions — the geometry transform of
//! the OpenGL pipeline (Owens et al., "Polygon Rendering on a Stream Architecture",
//! Graphics Hardware 2000).
//!
//! Input `positions`: records (x, y, z, w), four words per element. Parameters: the matrix
//! `m0..m15`, row-major. Output `transformed`: records (x', y', z', w') with
//! `out_i = ((m_i0·x + m_i1·y) + m_i2·z) + m_i3·w`, each product and sum rounded (the
//! machine has no fused multiply-add). 16 multiplies and 12 adds per element.

use imagine_units::arith::fp32::testgen::SplitMix64;
use imagine_units::desc::MachineDesc;

use super::{finish, records_to_stream, uniform_words};
use crate::kernel::{
    Kernel, KernelBuilder, KernelInputs, LoopSpec, MachineRequirementError, Value,
};

/// Declares the 16 matrix parameters `{prefix}0..{prefix}15` (row-major).
pub(crate) fn matrix_params(b: &mut KernelBuilder, prefix: &str) -> [Value; 16] {
    std::array::from_fn(|i| b.param_f32(&format!("{prefix}{i}")))
}

/// `m · (x, y, z, w)`, row by row, summing left to right. A `w` of `None` stands for 1
/// (the last column is added without a multiply).
pub(crate) fn transform_point(
    b: &mut KernelBuilder,
    m: &[Value; 16],
    [x, y, z]: [Value; 3],
    w: Option<Value>,
) -> [Value; 4] {
    std::array::from_fn(|row| {
        let r = &m[4 * row..4 * row + 4];
        let mx = b.fmul(r[0], x);
        let my = b.fmul(r[1], y);
        let sum = b.fadd(mx, my);
        let mz = b.fmul(r[2], z);
        let sum = b.fadd(sum, mz);
        let mw = match w {
            Some(w) => b.fmul(r[3], w),
            None => r[3],
        };
        b.fadd(sum, mw)
    })
}

/// Any machine serves it (any cluster count; the units every description has).
pub fn build(_desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("transform");
    let positions = b.input("positions");
    let transformed = b.output("transformed");
    let m = matrix_params(&mut b, "m");
    b.begin_loop(LoopSpec::OverStream(positions));
    let [x, y, z, w] = [
        b.read_f32(positions),
        b.read_f32(positions),
        b.read_f32(positions),
        b.read_f32(positions),
    ];
    for v in transform_point(&mut b, &m, [x, y, z], Some(w)) {
        b.write(transformed, v);
    }
    b.end_loop();
    Ok(finish(b))
}

/// `rows × C` positions with coordinates in [-10, 10) and w in [0.5, 2); matrix entries in
/// [-2, 2).
pub fn inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let mut rng = SplitMix64::new(seed);
    let n = rows * desc.cluster.count;
    let records: Vec<Vec<u32>> = (0..n)
        .map(|_| {
            let mut r = uniform_words(&mut rng, 3, -10.0, 10.0);
            r.extend(uniform_words(&mut rng, 1, 0.5, 2.0));
            r
        })
        .collect();
    KernelInputs {
        streams: vec![records_to_stream(&records, desc.cluster.count), Vec::new()],
        params: uniform_words(&mut rng, 16, -2.0, 2.0),
    }
}
