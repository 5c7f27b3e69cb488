//! Batching, written once for every pipeline: strip-mining a stream into batches sized to
//! the SRF, two batches in flight, and spilling — splitting a piece of work that would
//! overflow its streams until each piece fits.

use super::srf::{PlanError, SrfPlan};

/// The largest batch in `candidates` (tried in order, largest first) whose plan fits the
/// SRF, with that plan; the error of the smallest if none fits.
pub fn strip_mine<T>(
    candidates: impl IntoIterator<Item = usize>,
    mut plan: impl FnMut(usize) -> Result<(SrfPlan, T), PlanError>,
) -> Result<(usize, SrfPlan, T), PlanError> {
    let mut last = PlanError("no batch size to try".into());
    for b in candidates {
        match plan(b) {
            Ok((p, t)) => return Ok((b, p, t)),
            Err(e) => last = e,
        }
    }
    Err(last)
}

/// Runs `batches` batches with two in flight: `prefetch(b)` queues what batch `b` needs
/// before its body (its input loads, and work deferred to the body's first wait), and is
/// called for batch `b + 1` before `body(b)` runs, so that the next batch's inputs move
/// while this one computes. `done(b)` follows each body.
pub fn pipelined<H, E>(
    host: &mut H,
    batches: usize,
    mut prefetch: impl FnMut(&mut H, usize) -> Result<(), E>,
    mut body: impl FnMut(&mut H, usize) -> Result<(), E>,
    mut done: impl FnMut(&mut H, usize),
) -> Result<(), E> {
    if batches == 0 {
        return Ok(());
    }
    prefetch(host, 0)?;
    for b in 0..batches {
        if b + 1 < batches {
            prefetch(host, b + 1)?;
        }
        body(host, b)?;
        done(host, b);
    }
    Ok(())
}

/// Whether a piece of work fits its streams.
pub enum Fit {
    /// It ran.
    Done,
    /// It would overflow: split it (the count is what it needed, for the error).
    Overflow(String),
}

/// Runs `work` on `domain`, splitting a domain that overflows in two with `split` and
/// running the halves in order, recursively (depth first). Returns the number of splits;
/// errors with the overflow's message when a domain that overflows cannot be split.
pub fn split_to_fit<D, E>(
    domain: D,
    mut work: impl FnMut(&D) -> Result<Fit, E>,
    split: impl Fn(&D) -> Option<(D, D)>,
    cannot: impl Fn(String) -> E,
) -> Result<u64, E> {
    let mut todo = vec![domain];
    let mut splits = 0;
    while let Some(d) = todo.pop() {
        match work(&d)? {
            Fit::Done => {}
            Fit::Overflow(why) => {
                let Some((first, second)) = split(&d) else {
                    return Err(cannot(why));
                };
                splits += 1;
                todo.push(second);
                todo.push(first);
            }
        }
    }
    Ok(splits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_to_fit_halves_until_each_piece_fits_in_order() {
        let mut ran = Vec::new();
        let splits = split_to_fit(
            (0u32, 16u32),
            |&(a, b)| {
                Ok::<_, String>(if b - a > 4 {
                    Fit::Overflow(format!("{} > 4", b - a))
                } else {
                    ran.push((a, b));
                    Fit::Done
                })
            },
            |&(a, b)| (b - a > 1).then(|| ((a, (a + b) / 2), ((a + b) / 2, b))),
            |why| why,
        )
        .unwrap();
        assert_eq!(ran, vec![(0, 4), (4, 8), (8, 12), (12, 16)]);
        assert_eq!(splits, 3);
        let e = split_to_fit(
            (0u32, 1u32),
            |_| Ok::<_, String>(Fit::Overflow("x".into())),
            |_| None,
            |w| w,
        );
        assert_eq!(e.unwrap_err(), "x");
    }

    #[test]
    fn pipelined_prefetches_one_batch_ahead() {
        let mut log = Vec::new();
        pipelined::<_, ()>(
            &mut log,
            3,
            |l, b| {
                l.push(format!("p{b}"));
                Ok(())
            },
            |l, b| {
                l.push(format!("b{b}"));
                Ok(())
            },
            |_, _| {},
        )
        .unwrap();
        assert_eq!(log, ["p0", "p1", "b0", "p2", "b1", "b2"]);
    }
}
