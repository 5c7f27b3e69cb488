//! Helpers for lane-batched state: one word per cluster.
//!
//! # Lane counts fixed at compile time
//!
//! The cluster array's per-cycle path is compiled once for each of the common cluster
//! counts ([`FIXED`]) and once for any other count, through a `const L: usize` parameter
//! that is the cluster count, or 0 for "whatever the machine has" ([`count`]). With `L`
//! fixed, every lane vector has a length known to the compiler: loops over the clusters are
//! unrolled and vectorised, copies are a few vector moves rather than calls to `memcpy`,
//! and the bounds checks of lane indices fold away. Storage stays as it is (one `Vec` per
//! block, `lanes` words per row); only the code is specialised, and it computes the same
//! thing for every `L`.

/// The cluster counts the per-cycle path is specialised for.
pub const FIXED: [usize; 3] = [8, 16, 32];

/// The lane count of code compiled for `L`: `L`, or `dynamic` where `L` is 0.
#[inline(always)]
pub fn count<const L: usize>(dynamic: usize) -> usize {
    if L == 0 {
        dynamic
    } else {
        debug_assert_eq!(L, dynamic, "code for {L} lanes on a machine of {dynamic}");
        L
    }
}

/// Copies one word per cluster (`L`: see the module doc).
#[inline(always)]
pub fn copy_lanes<const L: usize>(dst: &mut [u32], src: &[u32]) {
    let n = count::<L>(dst.len());
    dst[..n].copy_from_slice(&src[..n]);
}

/// Copies one flag per cluster (`L`: see the module doc).
#[inline(always)]
pub fn copy_mask<const L: usize>(dst: &mut [bool], src: &[bool]) {
    let n = count::<L>(dst.len());
    dst[..n].copy_from_slice(&src[..n]);
}

/// The clusters whose flag is set.
#[inline(always)]
pub fn count_set<const L: usize>(mask: &[bool]) -> usize {
    let n = count::<L>(mask.len());
    mask[..n].iter().filter(|&&b| b).count()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_specialisation_copies_every_lane() {
        fn check<const L: usize>(n: usize) {
            let src: Vec<u32> = (0..n as u32).map(|i| i * 7 + 1).collect();
            let mut dst = vec![0; n];
            copy_lanes::<L>(&mut dst, &src);
            assert_eq!(dst, src);
            let flags: Vec<bool> = (0..n).map(|i| i % 3 == 0).collect();
            let mut out = vec![false; n];
            copy_mask::<L>(&mut out, &flags);
            assert_eq!(out, flags);
            assert_eq!(count_set::<L>(&flags), n.div_ceil(3));
        }
        for n in [1, 2, 3, 8, 9, 16, 31, 32, 37] {
            match n {
                8 => check::<8>(n),
                16 => check::<16>(n),
                32 => check::<32>(n),
                _ => check::<0>(n),
            }
        }
    }
}
