//! Modules, designs and the two-phase simulator.
//!
//! A [`Design`] is built once: modules are constructed inside [`Scope`]s, which give them
//! hierarchical names and register their probes, registers and channels. The [`Sim`] then
//! advances the [`Clocks`]; at each instant where clocks rise it calls `eval` on every
//! module of the rising domains (each computes its next state from the committed state of
//! itself and its inputs), then `commit` on all of them, then commits every channel (the
//! synchronising FIFOs excepted: their registers are a function of the edges each clock has
//! committed, which the simulator counts; see [`crate::async_fifo`]). No event queue and no
//! iteration to a fixed point: evaluation order cannot change results, and
//! [`Sim::reverse_eval_order`] exists so tests can prove it.

use std::any::Any;
use std::cell::{Cell, RefCell};
use std::fmt;
use std::io;
use std::rc::Rc;

use crate::async_fifo::{AsyncFifoRx, AsyncFifoTx, new_async_fifo};
use crate::edge_counts::EdgeCounts;
use crate::fifo::{FifoRx, FifoTx, new_fifo};
use crate::pipe::{PipeRx, PipeTx, new_pipe};
use crate::{
    Bits, ClockDomain, ClockError, Clocks, ContractError, DomainId, DomainSet, Edge, ProbeRegistry,
    Reg, SignalId, SignalKind, Trace, Tracer, bits_for,
};

/// A clocked hardware block.
pub trait Module: Any {
    /// The clock domain whose rising edges drive this module.
    fn domain(&self) -> DomainId;
    /// Computes the next state from the committed state of this module and its inputs.
    fn eval(&mut self) -> Result<(), ContractError>;
    /// Makes the next state current (registers take their `d`).
    fn commit(&mut self);
    /// Reports the current value of every probe.
    fn trace(&self, _t: &mut Trace) {}
    /// Whether a tracer is attached. A block keeps the latches that only its probes read
    /// (operands of the last issue, the last write's data, ...) while one is, and may also
    /// choose a faster path that gives the same results when none is (e.g. a divider that
    /// computes its result at issue rather than stepping its recurrence core, whose
    /// registers only a waveform shows). Blocks start with tracing on; [`Sim::new`] turns
    /// it off and [`Sim::attach`] on again.
    fn set_tracing(&mut self, _on: bool) {}
}

/// Shared state between modules whose probes the simulator reports after each edge: the
/// channels and the synchronising FIFOs (which are never committed, see
/// [`crate::async_fifo`]).
pub trait Traced {
    fn trace(&self, t: &mut Trace);
}

/// Shared state between two modules that commits on clock edges (pipes, FIFOs).
pub trait Channel: Traced {
    /// Ends the cycle of the domains in `rising`. Returns whether the channel is now
    /// static: edges of any clock change nothing here until an endpoint next acts (and
    /// raises the channel's wake flag), so the simulator stops committing it. (One call
    /// rather than a second query: a busy channel is committed on every edge.)
    fn commit(&mut self, rising: DomainSet) -> Result<bool, ContractError>;
    /// The domain whose cycle count locates this channel's errors.
    fn domain(&self) -> DomainId;
}

/// A mistake in how a design is put together.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DesignError {
    Clock(ClockError),
    /// A pipe or FIFO parameter that cannot be built, e.g. latency 0.
    Parameter {
        path: String,
        problem: String,
    },
    UnknownDomain(String),
}

impl fmt::Display for DesignError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DesignError::Clock(e) => e.fmt(f),
            DesignError::Parameter { path, problem } => write!(f, "`{path}`: {problem}"),
            DesignError::UnknownDomain(d) => write!(f, "no clock domain named `{d}`"),
        }
    }
}

impl std::error::Error for DesignError {}

impl From<ClockError> for DesignError {
    fn from(e: ClockError) -> Self {
        DesignError::Clock(e)
    }
}

/// A channel as the simulator commits it.
struct WiredChannel {
    channel: Rc<RefCell<dyn Channel>>,
    /// Raised by the channel's endpoints when they act (see [`Channel::commit`]).
    wake: Rc<Cell<bool>>,
    /// The channel was static at its last commit: it is not committed again until `wake`
    /// rises.
    asleep: bool,
}

/// A design under construction: clocks, probes, channels and modules.
pub struct Design {
    clocks: Clocks,
    /// The edges each domain has committed, as the synchronising FIFOs read them.
    edges: Rc<EdgeCounts>,
    probes: ProbeRegistry,
    clock_ids: Vec<SignalId>,
    channels: Vec<WiredChannel>,
    /// Every channel, in construction order, for tracing: those above and the
    /// synchronising FIFOs, which are never committed (their state is a function of the
    /// committed edges).
    traced: Vec<Rc<RefCell<dyn Traced>>>,
    modules: Vec<Box<dyn Module>>,
    top: String,
}

impl Design {
    /// A design whose root scope is `top`, with the given clock domains (the first is the
    /// core clock whose cycles the simulator counts).
    pub fn new(top: &str, domains: Vec<ClockDomain>) -> Result<Self, DesignError> {
        let clocks = Clocks::new(domains)?;
        let mut probes = ProbeRegistry::new();
        let clock_ids = clocks
            .domains()
            .iter()
            .map(|d| probes.register(format!("{top}.clk_{}", d.name), 1, SignalKind::Clock))
            .collect();
        Ok(Design {
            edges: Rc::new(EdgeCounts::new(clocks.domains().len())),
            clocks,
            probes,
            clock_ids,
            channels: Vec::new(),
            traced: Vec::new(),
            modules: Vec::new(),
            top: top.into(),
        })
    }

    /// The root scope.
    pub fn scope(&mut self) -> Scope<'_> {
        let path = self.top.clone();
        Scope { design: self, path }
    }

    pub fn domain(&self, name: &str) -> Result<DomainId, DesignError> {
        self.clocks
            .find(name)
            .ok_or_else(|| DesignError::UnknownDomain(name.into()))
    }

    pub fn add<M: Module>(&mut self, m: M) {
        self.modules.push(Box::new(m));
    }

    pub fn probes(&self) -> &ProbeRegistry {
        &self.probes
    }

    fn add_channel<C: Channel + 'static>(&mut self, channel: Rc<RefCell<C>>, wake: Rc<Cell<bool>>) {
        self.traced.push(channel.clone());
        self.channels.push(WiredChannel {
            channel,
            wake,
            asleep: false,
        });
    }
}

/// A place in the design hierarchy where modules register signals and channels.
pub struct Scope<'a> {
    design: &'a mut Design,
    path: String,
}

impl Scope<'_> {
    pub fn path(&self) -> &str {
        &self.path
    }

    /// A nested scope `self.name`.
    pub fn child(&mut self, name: &str) -> Scope<'_> {
        let path = format!("{}.{name}", self.path);
        Scope {
            design: self.design,
            path,
        }
    }

    pub fn domain(&self, name: &str) -> Result<DomainId, DesignError> {
        self.design.domain(name)
    }

    fn full(&self, name: &str) -> String {
        format!("{}.{name}", self.path)
    }

    /// Registers a probe `self.name`.
    pub fn signal(&mut self, name: &str, width: u32, kind: SignalKind) -> SignalId {
        let path = self.full(name);
        self.design.probes.register(path, width, kind)
    }

    /// Registers a probe `self.name` that a viewer shows as `display`.
    pub fn signal_shown(
        &mut self,
        name: &str,
        width: u32,
        kind: SignalKind,
        display: crate::Display,
    ) -> SignalId {
        let id = self.signal(name, width, kind);
        self.design.probes.set_display(id, display);
        id
    }

    /// Marks signal `id` as one to show at a glance (see [`crate::SignalDecl::glance`]).
    pub fn glance(&mut self, id: SignalId) {
        self.design.probes.set_glance(id);
    }

    /// A register probed as `self.name`.
    pub fn reg<T: Bits>(&mut self, name: &str, init: T) -> Reg<T> {
        Reg::new(self, name, init)
    }

    /// A pipe `self.name` of `latency` ≥ 1 cycles carrying up to `bandwidth` ≥ 1 values per
    /// cycle; its probe `self.name.valid` counts the values arriving each cycle.
    pub fn pipe<T: 'static>(
        &mut self,
        name: &str,
        domain: DomainId,
        latency: usize,
        bandwidth: usize,
    ) -> Result<(PipeTx<T>, PipeRx<T>), DesignError> {
        let path = self.full(name);
        positive(&path, "latency", latency)?;
        positive(&path, "bandwidth", bandwidth)?;
        let valid = self
            .child(name)
            .signal("valid", bits_for(bandwidth as u64), SignalKind::Wire);
        let (tx, rx, ch) = new_pipe(path, domain, latency, bandwidth, valid);
        self.design.add_channel(ch, Rc::default());
        Ok((tx, rx))
    }

    /// A FIFO `self.name` with `capacity` ≥ 1 entries and up to `bandwidth` pushes and pops
    /// per cycle; its probe `self.name.level` is the committed occupancy.
    pub fn fifo<T: Clone + 'static>(
        &mut self,
        name: &str,
        domain: DomainId,
        capacity: usize,
        bandwidth: usize,
    ) -> Result<(FifoTx<T>, FifoRx<T>), DesignError> {
        let path = self.full(name);
        positive(&path, "capacity", capacity)?;
        positive(&path, "bandwidth", bandwidth)?;
        let level = self
            .child(name)
            .signal("level", bits_for(capacity as u64), SignalKind::Wire);
        let (tx, rx, ch) = new_fifo(path, domain, capacity, bandwidth, level);
        self.design.add_channel(ch, Rc::default());
        Ok((tx, rx))
    }

    /// A synchronising FIFO `self.name` from `write` to `read` domain, with `sync_stages`
    /// ≥ 1 flip-flops in each pointer synchroniser; probes `self.name.write_level` and
    /// `self.name.read_level` are the occupancy each side sees.
    pub fn async_fifo<T: 'static>(
        &mut self,
        name: &str,
        (write, read): (DomainId, DomainId),
        capacity: usize,
        sync_stages: usize,
    ) -> Result<(AsyncFifoTx<T>, AsyncFifoRx<T>), DesignError> {
        let path = self.full(name);
        positive(&path, "capacity", capacity)?;
        positive(&path, "sync_stages", sync_stages)?;
        let width = bits_for(capacity as u64);
        let mut s = self.child(name);
        let ids = [
            s.signal("write_level", width, SignalKind::Wire),
            s.signal("read_level", width, SignalKind::Wire),
        ];
        let edges = self.design.edges.clone();
        let (tx, rx, ch) = new_async_fifo(path, (write, read), capacity, sync_stages, ids, edges);
        self.design.traced.push(ch);
        Ok((tx, rx))
    }
}

fn positive(path: &str, what: &str, v: usize) -> Result<(), DesignError> {
    if v == 0 {
        return Err(DesignError::Parameter {
            path: path.into(),
            problem: format!("{what} must be at least 1"),
        });
    }
    Ok(())
}

/// Per domain (of `domains`), the positions of the modules in `module_domains` it drives
/// (a module of no domain of the design is driven by none, as no edge of it comes).
fn driven_by(module_domains: &[DomainId], domains: usize) -> Vec<Vec<usize>> {
    let mut driven = vec![Vec::new(); domains];
    for (i, d) in module_domains.iter().enumerate() {
        if let Some(modules) = driven.get_mut(usize::from(d.0)) {
            modules.push(i);
        }
    }
    driven
}

/// Runs a design.
pub struct Sim {
    design: Design,
    /// Per module (in their order), the domain whose edges drive it: fixed once built, so
    /// not asked of each module at each edge.
    module_domains: Vec<DomainId>,
    /// Per domain, the positions of the modules its edges drive, in module order: an edge
    /// of one domain (most edges) visits only those.
    driven: Vec<Vec<usize>>,
    /// Domains other than the core's that hold no module.
    quiet: u64,
    #[cfg(feature = "probes")]
    trace: Option<Trace>,
    core: DomainId,
}

impl Sim {
    pub fn new(mut design: Design) -> Self {
        let core = DomainId(0);
        let mut busy = 1u64 << core.0;
        for m in &design.modules {
            busy |= 1 << m.domain().0;
        }
        let module_domains: Vec<DomainId> = design.modules.iter().map(|m| m.domain()).collect();
        let driven = driven_by(&module_domains, design.clocks.domains().len());
        for m in &mut design.modules {
            m.set_tracing(false);
        }
        Sim {
            design,
            module_domains,
            driven,
            quiet: !busy,
            #[cfg(feature = "probes")]
            trace: None,
            core,
        }
    }

    /// Attaches a tracer; from now on every change of every probe reaches it. Without the
    /// `probes` feature this does nothing.
    pub fn attach(&mut self, mut tracer: Box<dyn Tracer>) -> io::Result<()> {
        tracer.start(&self.design.probes, self.design.clocks.domains())?;
        #[cfg(feature = "probes")]
        {
            self.trace = Some(Trace::new(&self.design.probes, tracer));
            for m in &mut self.design.modules {
                m.set_tracing(true);
            }
        }
        Ok(())
    }

    /// Ends tracing: flushes the tracer and reports any write error it met.
    pub fn finish(&mut self) -> io::Result<()> {
        #[cfg(feature = "probes")]
        if let Some(mut t) = self.trace.take() {
            return t.tracer().finish();
        }
        Ok(())
    }

    pub fn clocks(&self) -> &Clocks {
        &self.design.clocks
    }

    pub fn probes(&self) -> &ProbeRegistry {
        &self.design.probes
    }

    /// Core-domain cycles so far.
    pub fn core_cycles(&self) -> u64 {
        self.design.clocks.cycles(self.core)
    }

    /// Evaluates modules and commits channels in the reverse of their construction order,
    /// for tests that show evaluation order does not matter.
    pub fn reverse_eval_order(&mut self) {
        self.design.modules.reverse();
        self.design.channels.reverse();
        self.design.traced.reverse();
        self.module_domains.reverse();
        self.driven = driven_by(&self.module_domains, self.driven.len());
    }

    /// The modules of type `M`, for inspecting their state.
    pub fn modules_of<M: Module>(&self) -> impl Iterator<Item = &M> {
        self.design
            .modules
            .iter()
            .filter_map(|m| (&**m as &dyn Any).downcast_ref::<M>())
    }

    /// The position of the first module of type `M`, for a caller that inspects it every
    /// cycle: [`module`](Self::module) then asks one module its type instead of each.
    pub fn module_index<M: Module>(&self) -> Option<usize> {
        (self.design.modules.iter()).position(|m| (&**m as &dyn Any).is::<M>())
    }

    /// The module at `index` (see [`module_index`](Self::module_index)), if it is an `M`.
    pub fn module<M: Module>(&self, index: usize) -> Option<&M> {
        (self.design.modules.get(index)).and_then(|m| (&**m as &dyn Any).downcast_ref::<M>())
    }

    /// The modules of type `M`, for a host that hands them more work between cycles (a
    /// stream program's host adding instructions).
    pub fn modules_of_mut<M: Module>(&mut self) -> impl Iterator<Item = &mut M> {
        self.design
            .modules
            .iter_mut()
            .filter_map(|m| (&mut **m as &mut dyn Any).downcast_mut::<M>())
    }

    /// Whether a tracer wants this instant's changes (falling edges matter only then).
    #[inline]
    fn tracing(&self) -> bool {
        #[cfg(feature = "probes")]
        if let Some(t) = &self.trace {
            return t.wants_changes();
        }
        false
    }

    /// Whether idle time may be jumped over ([`skip_to`](Self::skip_to)): no tracer is
    /// attached (a waveform would have to show the skipped edges).
    pub fn can_skip(&self) -> bool {
        #[cfg(feature = "probes")]
        if self.trace.is_some() {
            return false;
        }
        true
    }

    /// Whether [`skip_cycles`](Self::skip_cycles) may be used: the design has one clock
    /// domain and [`can_skip`](Self::can_skip).
    pub fn can_skip_cycles(&self) -> bool {
        self.can_skip() && self.design.clocks.domains().len() == 1
    }

    /// Advances time by `n` cycles without evaluating or committing anything: for a caller
    /// that has itself brought every module to the state those `n` cycles would leave
    /// (idle time in a trace replay) and whose channels are empty, so committing them
    /// would change nothing. Returns `false`, changing nothing, unless
    /// [`can_skip_cycles`](Self::can_skip_cycles).
    pub fn skip_cycles(&mut self, n: u64) -> bool {
        let skipped = self.can_skip_cycles() && self.design.clocks.skip_rising_edges(n);
        self.design.edges.sync(&self.design.clocks);
        skipped
    }

    /// The rising edges each domain will have had once the core clock has had
    /// `core_cycles` ([`Clocks::cycles_at`]), for a caller about to
    /// [`skip_to`](Self::skip_to) there that must bring the other domains' modules along.
    pub fn cycles_at(&self, core_cycles: u64) -> Option<Vec<u64>> {
        self.design.clocks.cycles_at(self.core, core_cycles)
    }

    /// Advances every clock until the core clock has had `core_cycles` rising edges,
    /// exactly as stepping would leave them ([`Clocks::skip_to`]), without evaluating or
    /// committing anything: for a caller that has itself brought every module of every
    /// domain to the state those edges would leave, and whose channels are settled, so
    /// committing them would change nothing. Returns `false`, changing nothing, unless
    /// [`can_skip`](Self::can_skip) and `core_cycles` is ahead.
    pub fn skip_to(&mut self, core_cycles: u64) -> bool {
        let skipped = self.can_skip() && self.design.clocks.skip_to(self.core, core_cycles);
        self.design.edges.sync(&self.design.clocks);
        skipped
    }

    /// Advances to the next clock edge of any domain (without a tracer, the next rising
    /// edge: falling edges change nothing then).
    pub fn step(&mut self) -> Result<Edge, ContractError> {
        let tracing = self.tracing();
        // Without a tracer, falling edges and the edges of domains that hold no module
        // change nothing: skip them.
        let edge = if tracing {
            self.design.clocks.next_edge()
        } else {
            self.design.clocks.next_rising_edge(DomainSet(!self.quiet))
        };
        if !edge.rising.is_empty() {
            self.design.edges.begin(edge.rising);
            let committed = self.clock_edge(edge.rising);
            self.design.edges.end();
            committed?;
        }
        #[cfg(feature = "probes")]
        if let Some(t) = &mut self.trace
            && t.wants_changes()
        {
            let clocks = &self.design.clocks;
            t.tracer()
                .time(edge.time_ps, clocks.cycles(self.core).saturating_sub(1));
            for (i, id) in self.design.clock_ids.iter().enumerate() {
                let d = DomainId(i as u8);
                if edge.rising.contains(d) {
                    t.value(*id, 1);
                } else if edge.falling.contains(d) {
                    t.value(*id, 0);
                }
            }
            if !edge.rising.is_empty() {
                for m in &self.design.modules {
                    m.trace(t);
                }
                for c in &self.design.traced {
                    c.borrow().trace(t);
                }
            }
            if let Some(why) = t.tracer().abort() {
                let path = format!("{}.waveform", self.design.top);
                return Err(ContractError::at(&path, crate::Violation::Other(why)));
            }
        }
        Ok(edge)
    }

    fn clock_edge(&mut self, rising: DomainSet) -> Result<(), ContractError> {
        let clocks = &self.design.clocks;
        let stamp = |e: ContractError, d: DomainId| {
            let cycle = clocks.cycles(d).saturating_sub(1);
            e.in_cycle(&clocks.domains()[d.0 as usize].name, cycle)
        };
        let modules = &mut self.design.modules;
        if rising.0.is_power_of_two() {
            let d = DomainId(rising.0.trailing_zeros() as u8);
            let driven = &self.driven[d.0 as usize];
            for &i in driven {
                modules[i].eval().map_err(|e| stamp(e, d))?;
            }
            for &i in driven {
                modules[i].commit();
            }
        } else {
            for (m, &d) in modules.iter_mut().zip(&self.module_domains) {
                if rising.contains(d) {
                    m.eval().map_err(|e| stamp(e, d))?;
                }
            }
            for (m, &d) in modules.iter_mut().zip(&self.module_domains) {
                if rising.contains(d) {
                    m.commit();
                }
            }
        }
        for WiredChannel {
            channel: c,
            wake,
            asleep,
        } in &mut self.design.channels
        {
            // A static channel's commit would change nothing: skip it, without touching
            // it, until one of its endpoints acts.
            if *asleep && !wake.get() {
                continue;
            }
            wake.set(false);
            let mut c = c.borrow_mut();
            *asleep = c.commit(rising).map_err(|e| stamp(e, c.domain()))?;
        }
        Ok(())
    }

    /// Runs until `done` holds (checked after every core-clock edge) or `max` more core
    /// cycles have elapsed; returns whether `done` held.
    pub fn run_until(
        &mut self,
        max: u64,
        mut done: impl FnMut(&Sim) -> bool,
    ) -> Result<bool, ContractError> {
        let end = self.core_cycles() + max;
        while self.core_cycles() < end {
            if self.step()?.rising.contains(self.core) && done(self) {
                return Ok(true);
            }
        }
        Ok(false)
    }

    /// Runs until `n` more core-clock cycles have elapsed, calling `progress` every
    /// 65,536 core cycles with the cycles done.
    pub fn run_core_cycles(
        &mut self,
        n: u64,
        mut progress: impl FnMut(u64),
    ) -> Result<(), ContractError> {
        let end = self.core_cycles() + n;
        let start = self.core_cycles();
        while self.core_cycles() < end {
            let edge = self.step()?;
            let done = self.core_cycles() - start;
            if edge.rising.contains(self.core) && done.is_multiple_of(65_536) {
                progress(done);
            }
        }
        Ok(())
    }
}
