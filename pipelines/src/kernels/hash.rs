//! `hash_xy`: the composite stamp test of the OpenGL pipeline (Owens et al., "Polygon
//! Rendering on a Stream Architecture", Graphics Hardware 2000; Kapasi et al.,
//! "Efficient Conditional Operations for Data-parallel Architectures", MICRO 2000), on
//! (x, y) records; the pipeline's own `hash` ([`crate::opengl::kernels::hash`]) tests pixel
//! addresses.
//! Fragments that fall on a pixel an earlier fragment of the batch already covered must
//! wait for it (OpenGL's ordering); the others may be composited at once.
//!
//! Input `fragments`: records (x, y) of int32 pixel coordinates. Each cluster keeps a 32×32
//! bit stamp in its own scratchpad (words 0..32, word `y & 31`, bit `x & 31`), cleared
//! before the loop. A fragment whose bit is already set goes to output `conflict`; any other
//! sets its bit and goes to output `ok`. The stamp is per cluster: a fragment is tested only
//! against the earlier fragments of its own cluster (elements `e ≡ c mod C`).
//!
//! Each output record is written by two conditional writes (x, then y), so an iteration
//! appends the x words of its selected fragments in cluster order, then their y words.

use imagine_units::arith::fp32::testgen::SplitMix64;
use imagine_units::desc::MachineDesc;

use super::{finish, records_to_stream};
use crate::kernel::{
    Kernel, KernelBuilder, KernelInputs, LoopSpec, MachineRequirementError, Needs,
};

/// Rows of the stamp: scratchpad words 0..32.
pub const STAMP_ROWS: u16 = 32;

/// Needs a scratchpad that holds the stamp besides the words of its conditional outputs.
pub fn build(desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    Needs::new("hash_xy", desc).scratchpad_words(usize::from(STAMP_ROWS), "the stamp", true)?;
    let mut b = KernelBuilder::new("hash_xy");
    let fragments = b.input("fragments");
    let ok = b.output("ok");
    let conflict = b.output("conflict");
    let zero = b.i32(0);
    let one = b.i32(1);
    let row_mask = b.i32(i32::from(STAMP_ROWS) - 1);
    for row in 0..STAMP_ROWS {
        b.sp_write(row, None, zero);
    }

    b.begin_loop(LoopSpec::OverStream(fragments));
    let x = b.read_i32(fragments);
    let y = b.read_i32(fragments);
    let row = b.and(y, row_mask);
    let stamp_row = b.sp_read(0, Some(row));
    // `shl` shifts by its operand's low five bits: bit `x & 31`.
    let bit = b.shl(one, x);
    let covered = b.and(stamp_row, bit);
    let is_conflict = b.ine(covered, zero);
    let is_ok = b.ieq(covered, zero);
    let stamped = b.or(stamp_row, bit);
    b.sp_write(0, Some(row), stamped);
    b.write_if(ok, is_ok, x);
    b.write_if(ok, is_ok, y);
    b.write_if(conflict, is_conflict, x);
    b.write_if(conflict, is_conflict, y);
    b.end_loop();
    Ok(finish(b))
}

/// `rows × C` fragments with x in 0..40 and y in 0..6, so that stamp bits alias (x and
/// x + 32) and conflicts are common.
pub fn inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let mut rng = SplitMix64::new(seed);
    let records: Vec<Vec<u32>> = (0..rows * desc.cluster.count)
        .map(|_| vec![rng.below(40), rng.below(6)])
        .collect();
    KernelInputs {
        streams: vec![
            records_to_stream(&records, desc.cluster.count),
            Vec::new(),
            Vec::new(),
        ],
        params: Vec::new(),
    }
}
