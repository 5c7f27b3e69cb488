//! Helpers for lane-batched state: one word per cluster.

/// Copies one word per cluster. The common cluster counts get fixed-size copies the compiler
/// turns into a few vector moves; the general case is a plain slice copy.
#[inline(always)]
pub fn copy_lanes(dst: &mut [u32], src: &[u32]) {
    fn fixed<const N: usize>(dst: &mut [u32], src: &[u32]) -> bool {
        match (<&mut [u32; N]>::try_from(dst), <&[u32; N]>::try_from(src)) {
            (Ok(d), Ok(s)) => {
                *d = *s;
                true
            }
            _ => false,
        }
    }
    if !(fixed::<8>(dst, src) || fixed::<16>(dst, src) || fixed::<32>(dst, src)) {
        dst.copy_from_slice(src);
    }
}
