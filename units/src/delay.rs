//! A result delay line: the pipeline registers between a unit that produces one word per
//! cluster and the intracluster switch, for units whose value is known at issue
//! (scratchpad reads, the intercluster network, stream reads, immediates). A value inserted
//! with latency `L` in cycle `t` leaves in cycle `t + L`; two values due in the same cycle
//! would share one result port, which is a [`ContractError`].

use crate::lanes::{copy_mask, count};
use crate::ring_position;
use imagine_hdl::{ContractError, Violation};

/// A value in flight: a word and a write-enable per cluster, and the owner's tag.
#[derive(Clone, Debug)]
pub struct InFlight {
    pub valid: bool,
    pub tag: u16,
    pub values: Vec<u32>,
    /// Clusters that write the value (conditional stream reads leave some out).
    pub mask: Vec<bool>,
    pub masked: bool,
}

#[derive(Debug)]
pub struct DelayLine {
    path: String,
    ring: Vec<InFlight>,
    head: usize,
    in_flight: usize,
}

impl DelayLine {
    /// A delay line for latencies 1..=`max_latency`; `path` names its result port in errors.
    pub fn new(path: String, lanes: usize, max_latency: u32) -> Self {
        let slot = InFlight {
            valid: false,
            tag: 0,
            values: vec![0; lanes],
            mask: vec![true; lanes],
            masked: false,
        };
        DelayLine {
            path,
            ring: vec![slot; max_latency as usize + 1],
            head: 0,
            in_flight: 0,
        }
    }

    /// Starts a value that leaves `latency` cycles from now; `fill` writes its words.
    #[inline]
    pub fn insert(
        &mut self,
        latency: u32,
        tag: u16,
        mask: Option<&[bool]>,
        fill: impl FnOnce(&mut [u32]),
    ) -> Result<(), ContractError> {
        self.insert_for::<0>(latency, tag, mask, fill)
    }

    /// [`insert`](Self::insert) compiled for `L` lanes ([`crate::lanes`]); `fill` gets a
    /// slice of exactly the lane count.
    #[inline(always)]
    pub fn insert_for<const L: usize>(
        &mut self,
        latency: u32,
        tag: u16,
        mask: Option<&[bool]>,
        fill: impl FnOnce(&mut [u32]),
    ) -> Result<(), ContractError> {
        let len = self.ring.len();
        debug_assert!(
            (1..len).contains(&(latency as usize)),
            "latency {latency} outside 1..{len}"
        );
        let at = self.after(latency as usize);
        let slot = &mut self.ring[at];
        if slot.valid {
            return Err(ContractError::at(
                &self.path,
                Violation::Busy {
                    detail: format!(
                        "result port conflict: a value issued now would leave in the same cycle as one issued earlier (tag {})",
                        slot.tag
                    ),
                },
            ));
        }
        slot.valid = true;
        slot.tag = tag;
        let n = count::<L>(slot.values.len());
        fill(&mut slot.values[..n]);
        slot.masked = mask.is_some();
        match mask {
            Some(m) => copy_mask::<L>(&mut slot.mask, m),
            None => slot.mask[..n].fill(true),
        }
        self.in_flight += 1;
        Ok(())
    }

    /// The value leaving this cycle, if any.
    #[inline]
    pub fn current(&self) -> Option<&InFlight> {
        let s = &self.ring[self.head];
        s.valid.then_some(s)
    }

    /// The value that leaves next cycle, if any (for state that must be updated at the edge
    /// before it: a write with latency 1 is visible to the next cycle's reads).
    #[inline]
    pub fn due_next(&self) -> Option<&InFlight> {
        let s = &self.ring[self.after(1)];
        s.valid.then_some(s)
    }

    /// The ring position `k < len` cycles after the head.
    #[inline(always)]
    fn after(&self, k: usize) -> usize {
        ring_position::after(self.head, k, self.ring.len())
    }

    /// Values still in flight (including the one leaving this cycle).
    pub fn in_flight(&self) -> usize {
        self.in_flight
    }

    /// Brings an empty line over `n` cycles: only the ring position turns.
    pub fn skip_idle(&mut self, n: u64) {
        debug_assert_eq!(self.in_flight, 0);
        self.head = ring_position::after_many(self.head, n, self.ring.len());
    }

    #[inline]
    pub fn commit(&mut self) {
        if self.in_flight > 0 {
            let s = &mut self.ring[self.head];
            if s.valid {
                s.valid = false;
                self.in_flight -= 1;
            }
        }
        self.head = ring_position::next(self.head, self.ring.len());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_leave_after_their_latency_and_conflicts_are_caught() {
        let mut d = DelayLine::new("top.x.result".into(), 2, 4);
        d.insert(3, 7, None, |v| v.copy_from_slice(&[1, 2]))
            .unwrap();
        d.commit();
        // due at the same cycle as the first value
        let e = d.insert(2, 8, None, |_| {}).unwrap_err();
        assert!(
            e.to_string().contains("top.x") && e.to_string().contains("tag 7"),
            "{e}"
        );
        d.insert(1, 9, Some(&[false, true]), |v| v.copy_from_slice(&[5, 6]))
            .unwrap();
        assert!(d.current().is_none());
        d.commit();
        let v = d.current().unwrap();
        assert_eq!(
            (v.tag, v.values.as_slice(), v.mask.as_slice(), v.masked),
            (9, &[5, 6][..], &[false, true][..], true)
        );
        d.commit();
        assert_eq!(d.current().unwrap().tag, 7);
        assert_eq!(d.in_flight(), 1);
        d.commit();
        assert_eq!(d.in_flight(), 0);
    }
}
