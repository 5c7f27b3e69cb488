//! The intercluster communication unit (ARCHITECTURE §4): every cycle it may carry one
//! word from every cluster to another cluster through a permutation network. The pattern
//! comes from the microcontroller (rotate, butterfly, broadcast: Imagine's `commucperm`) or
//! is computed per cluster from a register (`commclperm`). The word arrives `comm` cycles
//! later at the receiving cluster.

use imagine_hdl::{ContractError, Scope, SignalId, SignalKind, Trace, Violation, bits_for};

use crate::delay::{DelayLine, InFlight};
use crate::microcode::Permutation;

pub struct CommUnit {
    path: String,
    lanes: usize,
    latency: u32,
    line: DelayLine,
    sent: bool,
    sources: Vec<u32>,
    lane_src: Vec<SignalId>,
    lane_data: Vec<SignalId>,
    valid: SignalId,
    last_sent: bool,
    /// A tracer is attached: the last words sent and their sources are latched.
    tracing: bool,
    last_data: Vec<u32>,
    last_sources: Vec<u32>,
}

/// The network's state: the words on their way (not the probes' latches, which only a
/// tracer reads).
impl std::fmt::Debug for CommUnit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CommUnit")
            .field("path", &self.path)
            .field("line", &self.line)
            .field("sent", &self.sent)
            .field("last_sent", &self.last_sent)
            .finish()
    }
}

impl CommUnit {
    /// Communication unit `name` (e.g. `comm0`) spanning all clusters.
    pub fn new(scope: &mut Scope<'_>, name: &str, lanes: usize, latency: u32) -> Self {
        let path = format!("{}.{name}", scope.path());
        let valid = scope.child(name).signal("send", 1, SignalKind::Wire);
        let (mut lane_src, mut lane_data) = (Vec::new(), Vec::new());
        for c in 0..lanes {
            let mut s = scope.child(&format!("cluster{c}"));
            let mut s = s.child(name);
            let source = s.signal("source", bits_for(lanes as u64 - 1), SignalKind::Wire);
            s.glance(source);
            lane_src.push(source);
            lane_data.push(s.signal("data", 32, SignalKind::Wire));
        }
        CommUnit {
            line: DelayLine::new(format!("{path}.result"), lanes, latency),
            path,
            lanes,
            latency,
            sent: false,
            sources: vec![0; lanes],
            lane_src,
            lane_data,
            valid,
            last_sent: false,
            tracing: true,
            last_data: vec![0; lanes],
            last_sources: vec![0; lanes],
        }
    }

    /// Sends `data` (one word per cluster); cluster `c` receives the word of the cluster the
    /// permutation names, `comm` cycles later, with `tag`. `perm_regs` holds each cluster's
    /// source for [`Permutation::PerCluster`] (taken modulo the cluster count).
    pub fn send(
        &mut self,
        data: &[u32],
        perm: Permutation,
        perm_regs: Option<&[u32]>,
        tag: u16,
    ) -> Result<(), ContractError> {
        if std::mem::replace(&mut self.sent, true) {
            return Err(ContractError::over_bandwidth(&self.path, 1));
        }
        let n = self.lanes as u32;
        for c in 0..self.lanes {
            let c32 = c as u32;
            self.sources[c] = match perm {
                #[cfg(feature = "inject-bugs")]
                Permutation::Rotate(k)
                    if imagine_hdl::inject::active(
                        imagine_hdl::inject::Bug::CommRotatesBackwards,
                    ) =>
                {
                    (c32 + n - k as u32 % n) % n
                }
                Permutation::Rotate(k) => (c32 + k as u32) % n,
                Permutation::Xor(k) => (c32 ^ k as u32) % n,
                Permutation::Broadcast(k) => k as u32 % n,
                Permutation::PerCluster(_) => perm_regs.map_or(c32, |r| r[c] % n),
            };
        }
        let sources = &self.sources;
        self.line.insert(self.latency, tag, None, |v| {
            for (c, out) in v.iter_mut().enumerate() {
                *out = data[sources[c] as usize];
            }
        })?;
        if self.tracing {
            self.last_data.copy_from_slice(data);
            self.last_sources.copy_from_slice(&self.sources);
        }
        Ok(())
    }

    /// Claims the network for a conditional stream access this cycle (its words are routed
    /// between clusters in cluster order); nothing else may be sent in the same cycle.
    pub fn reserve(&mut self) -> Result<(), ContractError> {
        if std::mem::replace(&mut self.sent, true) {
            return Err(ContractError::at(
                &self.path,
                Violation::Busy {
                    detail: "a conditional stream access needs the network this cycle".into(),
                },
            ));
        }
        Ok(())
    }

    /// The words arriving this cycle.
    #[inline]
    pub fn completed(&self) -> Option<&InFlight> {
        self.line.current()
    }

    pub fn in_flight(&self) -> usize {
        self.line.in_flight()
    }

    /// Brings a unit with nothing in flight and nothing sent this cycle over `n ≥ 1`
    /// cycles, as `n` commits would.
    pub fn skip_idle(&mut self, n: u64) {
        debug_assert!(self.in_flight() == 0 && !self.sent && n > 0);
        self.line.skip_idle(n);
        self.last_sent = false;
    }

    pub fn commit(&mut self) {
        self.line.commit();
        self.last_sent = std::mem::take(&mut self.sent);
    }

    /// Whether a tracer is attached (see [`imagine_hdl::Module::set_tracing`]): without one
    /// the words sent and their sources are not latched for the probes.
    pub fn set_tracing(&mut self, on: bool) {
        self.tracing = on;
    }

    pub fn trace(&self, t: &mut Trace) {
        t.value(self.valid, self.last_sent as u64);
        for c in 0..self.lanes {
            t.value(self.lane_src[c], self.last_sources[c] as u64);
            t.value(self.lane_data[c], self.last_data[c] as u64);
        }
    }
}
