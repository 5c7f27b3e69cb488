//! The SRF port arbiter's priority rule: round robin over stream-buffer indices.
//!
//! The arbiter grants the SRF port to one requesting stream buffer per cycle. Priority
//! rotates: the buffer after the last one granted has the highest priority, then the next,
//! wrapping at the number of buffers. A buffer that keeps requesting is therefore served
//! within `stream_buffers` cycles whatever the others do (no starvation), and `k` buffers
//! that all request every cycle are served in turn, one grant each per `k` cycles.
//!
//! The pointer is a register: it moves when the cycle's grant is committed
//! ([`RoundRobin::granted`]), never during evaluation.

/// Rotating priority over `n` requesters.
#[derive(Clone, Debug)]
pub(crate) struct RoundRobin {
    n: usize,
    /// The requester with the highest priority this cycle.
    next: usize,
}

impl RoundRobin {
    pub fn new(n: usize) -> Self {
        assert!(n > 0, "a round-robin arbiter needs at least one requester");
        RoundRobin { n, next: 0 }
    }

    /// Priority rank of requester `i` this cycle: 0 is the highest; ranks are distinct.
    #[inline(always)]
    pub fn rank(&self, i: usize) -> usize {
        debug_assert!(i < self.n);
        if i >= self.next {
            i - self.next
        } else {
            i + self.n - self.next
        }
    }

    /// Commits a grant to `i`: the requester after it has the highest priority next cycle.
    #[inline(always)]
    pub fn granted(&mut self, i: usize) {
        self.next = if i + 1 == self.n { 0 } else { i + 1 };
    }

    /// The requester with the highest priority this cycle.
    #[cfg(test)]
    pub fn next(&self) -> usize {
        self.next
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The winner among `requests` under `rr`.
    fn pick(rr: &RoundRobin, requests: &[usize]) -> Option<usize> {
        requests.iter().copied().min_by_key(|&i| rr.rank(i))
    }

    #[test]
    fn ranks_rotate_from_the_pointer() {
        let mut rr = RoundRobin::new(5);
        assert_eq!(
            (0..5).map(|i| rr.rank(i)).collect::<Vec<_>>(),
            [0, 1, 2, 3, 4]
        );
        rr.granted(2);
        assert_eq!(rr.next(), 3);
        assert_eq!(
            (0..5).map(|i| rr.rank(i)).collect::<Vec<_>>(),
            [2, 3, 4, 0, 1]
        );
        rr.granted(4);
        assert_eq!(rr.next(), 0);
    }

    #[test]
    fn persistent_requesters_are_served_in_turn() {
        let mut rr = RoundRobin::new(22);
        let requests = [3, 7, 19];
        let mut order = Vec::new();
        for _ in 0..7 {
            let w = pick(&rr, &requests).unwrap();
            order.push(w);
            rr.granted(w);
        }
        assert_eq!(order, [3, 7, 19, 3, 7, 19, 3]);
        assert_eq!(pick(&rr, &[]), None);
    }

    #[test]
    fn a_lone_requester_wins_every_cycle() {
        let mut rr = RoundRobin::new(4);
        for _ in 0..6 {
            assert_eq!(pick(&rr, &[2]), Some(2));
            rr.granted(2);
        }
    }
}
