//! Positions in a ring of slots indexed from a head that turns once a cycle: the FU
//! pipelines' result rings and the delay lines. Within a cycle's reach the wrap is a
//! compare, not a division: every unit does this every cycle.

/// The position `k` steps after `head`, for `head < len` and `k ≤ len`.
#[inline(always)]
pub(crate) fn after(head: usize, k: usize, len: usize) -> usize {
    let i = head + k;
    if i >= len { i - len } else { i }
}

/// The position after `head < len`: the head's turn at the end of a cycle.
#[inline(always)]
pub(crate) fn next(head: usize, len: usize) -> usize {
    let i = head + 1;
    if i == len { 0 } else { i }
}

/// The position `n` steps after `head < len`, for any `n` (a jump over idle cycles).
pub(crate) fn after_many(head: usize, n: u64, len: usize) -> usize {
    (head + (n % len as u64) as usize) % len
}
