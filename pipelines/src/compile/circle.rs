//! Rows round a circle. A modulo schedule's table has one row per cycle of the interval
//! (or of the unrolled body), and a value live over cycles `[w, r)` holds the rows `w, w+1,
//! …` taken round it. The schedulers and the allocator count over such spans millions of
//! times; walking one as runs that do not wrap keeps the division out of the inner loop and
//! lets the compiler vectorise the work on each run.

use std::ops::Range;

/// The rows `start, start + 1, …` (`len` of them) round a circle of `m` rows, as runs of
/// consecutive rows that do not wrap; a span longer than the circle goes round again.
pub fn runs(start: usize, len: usize, m: usize) -> impl Iterator<Item = Range<usize>> {
    debug_assert!(start < m || len == 0, "row {start} outside a circle of {m}");
    let (mut row, mut left) = (start, len);
    std::iter::from_fn(move || {
        (left > 0).then(|| {
            let end = m.min(row + left);
            left -= end - row;
            let run = row..end;
            row = 0;
            run
        })
    })
}

/// The row of cycle `t` in a table of `ii` rows.
pub fn row(t: i64, ii: i64) -> usize {
    // (Most cycles asked of are in the table's first pass; a compare costs less than the
    // division.)
    if (0..ii).contains(&t) {
        t as usize
    } else {
        t.rem_euclid(ii) as usize
    }
}

/// A table of `ii` rows whose row of a cycle is found without a division: by a multiply
/// with the interval's reciprocal (Lemire, Kaser and Kurz, "Faster remainder by direct
/// computation", 2019), for the cycles within a billion of 0.
#[derive(Clone, Copy, Debug)]
pub struct Circle {
    ii: i64,
    /// `⌈2⁶⁴ / ii⌉`.
    reciprocal: u64,
    /// A multiple of `ii` that takes every cycle of `(-NEAR, NEAR)` to `[0, 2³²)`.
    offset: i64,
}

/// The cycles, either side of 0, that [`Circle::row`] finds without a division.
const NEAR: i64 = 1 << 30;

impl Circle {
    pub fn new(ii: i64) -> Circle {
        assert!(ii > 0, "a table of {ii} rows");
        // (One row needs no reciprocal, whose ⌈2⁶⁴ / 1⌉ would not fit.)
        let fast = (2..NEAR).contains(&ii);
        Circle {
            ii,
            reciprocal: if fast { u64::MAX / ii as u64 + 1 } else { 0 },
            offset: if fast { (NEAR / ii + 1) * ii } else { 0 },
        }
    }

    /// The rows round the circle.
    pub fn ii(&self) -> i64 {
        self.ii
    }

    /// The row of cycle `t`: [`row`]`(t, ii)`.
    #[inline]
    pub fn row(&self, t: i64) -> usize {
        if (0..self.ii).contains(&t) {
            return t as usize;
        }
        if self.reciprocal == 0 || !(-NEAR..NEAR).contains(&t) {
            return t.rem_euclid(self.ii) as usize;
        }
        // (`t + offset` is below 2³² and `ii` below 2³⁰: the fraction of the product is
        // exact enough that its top bits times `ii` are the remainder.)
        let fraction = self.reciprocal.wrapping_mul((t + self.offset) as u64);
        ((u128::from(fraction) * self.ii as u128) >> 64) as usize
    }
}

/// The runs of cycles `[w, r)` round a table of `ii` rows (none if `r <= w`).
pub fn cycles(w: i64, r: i64, ii: i64) -> impl Iterator<Item = Range<usize>> {
    let len = usize::try_from(r - w).unwrap_or(0);
    runs(row(w, ii), len, ii as usize)
}

#[cfg(test)]
mod tests {
    use super::{Circle, NEAR, cycles, row, runs};

    #[test]
    fn a_circle_finds_the_rows_the_remainder_gives() {
        let mut rng = 0x1234_5678_9abc_def0u64;
        let mut next = || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            rng
        };
        let iis = (1..300).chain([1021, 4096, 65_535, NEAR - 1, NEAR, NEAR + 7, i64::MAX / 3]);
        for ii in iis {
            let circle = Circle::new(ii);
            let edges = [
                0,
                1,
                ii - 1,
                ii,
                ii + 1,
                -1,
                -ii,
                -ii - 1,
                NEAR - 1,
                -NEAR,
                NEAR,
            ];
            let random = (0..2000).map(|_| (next() as i64) >> (next() % 64));
            for t in edges.into_iter().chain(random) {
                assert_eq!(
                    circle.row(t),
                    t.rem_euclid(ii) as usize,
                    "cycle {t}, {ii} rows"
                );
            }
        }
    }

    /// The rows of `runs`, one by one.
    fn rows(start: usize, len: usize, m: usize) -> Vec<usize> {
        runs(start, len, m).flatten().collect()
    }

    #[test]
    fn runs_cover_the_rows_round_the_circle_in_order() {
        for m in 1..9 {
            for start in 0..m {
                for len in 0..3 * m {
                    let expected: Vec<usize> = (start..start + len).map(|c| c % m).collect();
                    assert_eq!(
                        rows(start, len, m),
                        expected,
                        "start {start}, len {len}, m {m}"
                    );
                    assert!(runs(start, len, m).all(|r| !r.is_empty() && r.end <= m));
                }
            }
        }
    }

    #[test]
    fn cycles_take_negative_and_late_times_round_the_table() {
        let rows = |w, r| cycles(w, r, 5).flatten().collect::<Vec<_>>();
        assert_eq!(rows(-2, 3), vec![3, 4, 0, 1, 2]);
        assert_eq!(rows(12, 14), vec![2, 3]);
        assert_eq!(rows(4, 4), Vec::<usize>::new());
        assert_eq!(rows(4, 1), Vec::<usize>::new());
        for t in -12..12 {
            assert_eq!(row(t, 5), t.rem_euclid(5) as usize);
        }
    }
}
