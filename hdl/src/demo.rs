//! A demonstration design made only of `hdl` parts, exercising both clock domains.
//!
//! ```text
//!  core domain (500 MHz)                                          DRAM domain (167 MHz)
//!  Source ──fifo ops(4)──▶ Mac: s1 operands ▶ s2 partial products ▶ s3 product ▶ s4 acc
//!                              └─────────────────────────── async_fifo out(8) ──▶ Sink
//!                              └── pipe results (latency 1) ──▶ Monitor
//! ```
//!
//! * `Source` steps a 32-bit Galois LFSR and offers its halves as 16-bit operands whenever
//!   the `ops` FIFO has room.
//! * `Mac` is a 4-stage multiply-accumulate pipeline: operand latch; two 16×8 partial
//!   products; their sum, the 32-bit product; the 40-bit running sum. It stalls as a whole
//!   when its result cannot enter the clock-crossing FIFO, which is the back-pressure that
//!   the 3:1 clock ratio makes routine.
//! * `Sink` (DRAM domain) drains one result per DRAM cycle into a checksum; `Monitor`
//!   (core domain) sees every result the Mac delivered through a latency-1 pipe and keeps
//!   the same checksum, so the two sides can be compared, and both against [`golden`].

use crate::{
    AsyncFifoRx, AsyncFifoTx, ClockDomain, ContractError, Design, DesignError, DomainId, FifoRx,
    FifoTx, Module, PipeRx, PipeTx, Reg, Scope, Sim, Trace,
    bits::{u24, u40},
};

const LFSR_SEED: u32 = 0xACE1_2468;
/// x^32 + x^22 + x^2 + x + 1, a maximal-length Galois LFSR.
const LFSR_TAPS: u32 = 0x8020_0003;
const ACC_MASK: u64 = (1 << 40) - 1;

fn lfsr_next(x: u32) -> u32 {
    (x >> 1) ^ (if x & 1 != 0 { LFSR_TAPS } else { 0 })
}

/// Folds a delivered result into a checksum.
pub fn checksum_step(sum: u64, value: u64) -> u64 {
    sum.rotate_left(7) ^ value
}

/// The first `n` results of the demo, computed directly (the behavioural model).
pub fn golden(n: usize) -> Vec<u64> {
    let mut lfsr = LFSR_SEED;
    let mut acc = 0u64;
    (0..n)
        .map(|_| {
            lfsr = lfsr_next(lfsr);
            let (a, b) = (lfsr & 0xFFFF, lfsr >> 16);
            acc = (acc + (a as u64) * (b as u64)) & ACC_MASK;
            acc
        })
        .collect()
}

#[derive(Clone, Copy, Debug)]
struct Operands {
    a: u16,
    b: u16,
}

struct Source {
    domain: DomainId,
    lfsr: Reg<u32>,
    issued: Reg<u32>,
    ops: FifoTx<Operands>,
}

impl Module for Source {
    fn domain(&self) -> DomainId {
        self.domain
    }
    fn eval(&mut self) -> Result<(), ContractError> {
        if self.ops.free() > 0 {
            let next = lfsr_next(self.lfsr.q());
            self.ops.push(Operands {
                a: next as u16,
                b: (next >> 16) as u16,
            })?;
            self.lfsr.set(next);
            self.issued.set(self.issued.q().wrapping_add(1));
        }
        Ok(())
    }
    fn commit(&mut self) {
        self.lfsr.commit();
        self.issued.commit();
    }
    fn trace(&self, t: &mut Trace) {
        self.lfsr.trace(t);
        self.issued.trace(t);
    }
}

/// One pipeline stage: a valid bit and its payload registers.
struct Stage<P> {
    valid: Reg<bool>,
    data: P,
}

struct Mac {
    domain: DomainId,
    ops: FifoRx<Operands>,
    out: AsyncFifoTx<u64>,
    results: PipeTx<u64>,
    s1: Stage<(Reg<u16>, Reg<u16>)>,
    s2: Stage<(Reg<u24>, Reg<u24>)>,
    s3: Stage<Reg<u32>>,
    s4: Stage<Reg<u40>>,
    stalled: Reg<bool>,
}

impl Mac {
    fn new(
        s: &mut Scope<'_>,
        domain: DomainId,
        ops: FifoRx<Operands>,
        out: AsyncFifoTx<u64>,
        results: PipeTx<u64>,
    ) -> Self {
        let mut st = |name: &str| s.child(name).reg("valid", false);
        let (v1, v2, v3, v4) = (st("s1"), st("s2"), st("s3"), st("s4"));
        Mac {
            domain,
            ops,
            out,
            results,
            s1: Stage {
                valid: v1,
                data: (s.child("s1").reg("a", 0u16), s.child("s1").reg("b", 0u16)),
            },
            s2: Stage {
                valid: v2,
                data: (
                    s.child("s2").reg("pp_lo", u24::new(0)),
                    s.child("s2").reg("pp_hi", u24::new(0)),
                ),
            },
            s3: Stage {
                valid: v3,
                data: s.child("s3").reg("product", 0u32),
            },
            s4: Stage {
                valid: v4,
                data: s.child("s4").reg("acc", u40::new(0)),
            },
            stalled: s.reg("stalled", false),
        }
    }
}

/// Every register of the Mac, borrowed as `&` or `&mut`: one list for commit and trace.
macro_rules! mac_regs {
    ($m:ident, $($borrow:tt)+) => {
        [
            $($borrow)+ $m.s1.valid, $($borrow)+ $m.s1.data.0, $($borrow)+ $m.s1.data.1,
            $($borrow)+ $m.s2.valid, $($borrow)+ $m.s2.data.0, $($borrow)+ $m.s2.data.1,
            $($borrow)+ $m.s3.valid, $($borrow)+ $m.s3.data, $($borrow)+ $m.s4.valid,
            $($borrow)+ $m.s4.data, $($borrow)+ $m.stalled,
        ]
    };
}

/// Lets a module commit and trace its registers of different types in one loop.
trait TraceReg {
    fn commit_reg(&mut self);
    fn trace_reg(&self, t: &mut Trace);
}
impl<T: crate::Bits> TraceReg for Reg<T> {
    fn commit_reg(&mut self) {
        self.commit();
    }
    fn trace_reg(&self, t: &mut Trace) {
        self.trace(t);
    }
}

impl Module for Mac {
    fn domain(&self) -> DomainId {
        self.domain
    }
    fn eval(&mut self) -> Result<(), ContractError> {
        // The whole pipeline holds while a finished result waits for room downstream.
        let advance = !self.s4.valid.q() || self.out.can_push();
        self.stalled.set(!advance);
        if !advance {
            return Ok(());
        }
        if self.s4.valid.q() {
            let acc = self.s4.data.q().value();
            self.out.push(acc)?;
            self.results.write(acc)?;
        }
        // s4: accumulate the product (40-bit, wrapping).
        if self.s3.valid.q() {
            let sum = self
                .s4
                .data
                .q()
                .wrapping_add(u40::new(self.s3.data.q() as u64));
            self.s4.data.set(sum);
        }
        self.s4.valid.set(self.s3.valid.q());
        // s3: sum the partial products into the 32-bit product.
        let (lo, hi) = (self.s2.data.0.q().value(), self.s2.data.1.q().value());
        self.s3.data.set(lo + (hi << 8));
        self.s3.valid.set(self.s2.valid.q());
        // s2: two 16×8 partial products.
        let (a, b) = (self.s1.data.0.q() as u32, self.s1.data.1.q() as u32);
        self.s2.data.0.set(u24::new(a * (b & 0xFF)));
        self.s2.data.1.set(u24::new(a * (b >> 8)));
        self.s2.valid.set(self.s1.valid.q());
        // s1: latch the next operands.
        let fetch = self.ops.available() > 0;
        if fetch {
            let o = self.ops.pop()?;
            self.s1.data.0.set(o.a);
            self.s1.data.1.set(o.b);
        }
        self.s1.valid.set(fetch);
        Ok(())
    }
    fn commit(&mut self) {
        let regs: [&mut dyn TraceReg; 11] = mac_regs!(self, &mut);
        for r in regs {
            r.commit_reg();
        }
    }
    fn trace(&self, t: &mut Trace) {
        let regs: [&dyn TraceReg; 11] = mac_regs!(self, &);
        for r in regs {
            r.trace_reg(t);
        }
    }
}

/// Consumer of results on one side of the design: a count and a checksum.
pub struct Checker {
    domain: DomainId,
    input: CheckerInput,
    count: Reg<u40>,
    checksum: Reg<u64>,
    last: Reg<u40>,
}

enum CheckerInput {
    Crossing(AsyncFifoRx<u64>),
    Pipe(PipeRx<u64>),
}

impl Checker {
    fn new(s: &mut Scope<'_>, domain: DomainId, input: CheckerInput) -> Self {
        Checker {
            domain,
            input,
            count: s.reg("count", u40::new(0)),
            checksum: s.reg("checksum", 0u64),
            last: s.reg("last", u40::new(0)),
        }
    }
    /// Results received so far.
    pub fn count(&self) -> u64 {
        self.count.q().value()
    }
    /// Checksum of the results received so far (see [`checksum_step`]).
    pub fn checksum(&self) -> u64 {
        self.checksum.q()
    }
    /// Whether this is the DRAM-side sink (as opposed to the core-side monitor).
    pub fn is_sink(&self) -> bool {
        matches!(self.input, CheckerInput::Crossing(_))
    }
}

impl Module for Checker {
    fn domain(&self) -> DomainId {
        self.domain
    }
    fn eval(&mut self) -> Result<(), ContractError> {
        let v = match &mut self.input {
            CheckerInput::Crossing(rx) if rx.can_pop() => Some(rx.pop()?),
            CheckerInput::Crossing(_) => None,
            CheckerInput::Pipe(rx) => rx.read(),
        };
        if let Some(v) = v {
            self.count.set(self.count.q().wrapping_add(u40::new(1)));
            self.checksum.set(checksum_step(self.checksum.q(), v));
            self.last.set(u40::new(v));
        }
        Ok(())
    }
    fn commit(&mut self) {
        self.count.commit();
        self.checksum.commit();
        self.last.commit();
    }
    fn trace(&self, t: &mut Trace) {
        self.count.trace(t);
        self.checksum.trace(t);
        self.last.trace(t);
    }
}

/// Sizes of the demo's buffers.
#[derive(Clone, Copy, Debug)]
pub struct DemoConfig {
    pub ops_capacity: usize,
    pub crossing_capacity: usize,
    pub sync_stages: usize,
}

impl Default for DemoConfig {
    fn default() -> Self {
        DemoConfig {
            ops_capacity: 4,
            crossing_capacity: 8,
            sync_stages: 2,
        }
    }
}

/// Builds the demo over the given clock domains (`core` and `dram` must exist).
pub fn build(domains: Vec<ClockDomain>, cfg: DemoConfig) -> Result<Sim, DesignError> {
    let mut design = Design::new("top", domains)?;
    let core = design.domain("core")?;
    let dram = design.domain("dram")?;
    let mut top = design.scope();
    let (ops_tx, ops_rx) = top.fifo("ops", core, cfg.ops_capacity, 1)?;
    let (out_tx, out_rx) =
        top.async_fifo("out", (core, dram), cfg.crossing_capacity, cfg.sync_stages)?;
    let (res_tx, res_rx) = top.pipe("results", core, 1, 1)?;
    let source = {
        let mut s = top.child("source");
        Source {
            domain: core,
            lfsr: s.reg("lfsr", LFSR_SEED),
            issued: s.reg("issued", 0u32),
            ops: ops_tx,
        }
    };
    let mac = Mac::new(&mut top.child("mac"), core, ops_rx, out_tx, res_tx);
    let sink = Checker::new(&mut top.child("sink"), dram, CheckerInput::Crossing(out_rx));
    let monitor = Checker::new(&mut top.child("monitor"), core, CheckerInput::Pipe(res_rx));
    design.add(source);
    design.add(mac);
    design.add(sink);
    design.add(monitor);
    Ok(Sim::new(design))
}

/// Outcome of a demo run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DemoReport {
    pub core_cycles: u64,
    pub dram_cycles: u64,
    /// Results that crossed into the DRAM domain, and their checksum.
    pub delivered: u64,
    pub sink_checksum: u64,
    /// Results the Mac produced, as the core-side monitor saw them.
    pub produced: u64,
    pub monitor_checksum: u64,
}

impl DemoReport {
    pub fn of(sim: &Sim) -> Self {
        let dram = sim.clocks().find("dram").unwrap_or(DomainId(1));
        let mut r = DemoReport {
            core_cycles: sim.core_cycles(),
            dram_cycles: sim.clocks().cycles(dram),
            delivered: 0,
            sink_checksum: 0,
            produced: 0,
            monitor_checksum: 0,
        };
        for m in [true, false] {
            let c = sim_checker(sim, m);
            if m {
                (r.delivered, r.sink_checksum) = (c.count(), c.checksum());
            } else {
                (r.produced, r.monitor_checksum) = (c.count(), c.checksum());
            }
        }
        r
    }

    /// Whether both checkers agree with the behavioural model.
    pub fn matches_golden(&self) -> bool {
        let g = golden(self.produced.max(self.delivered) as usize);
        let sum = |n: u64| g[..n as usize].iter().fold(0, |s, &v| checksum_step(s, v));
        sum(self.delivered) == self.sink_checksum && sum(self.produced) == self.monitor_checksum
    }
}

fn sim_checker(sim: &Sim, sink: bool) -> &Checker {
    sim.modules_of::<Checker>()
        .find(|c| c.is_sink() == sink)
        .expect("the demo has a sink and a monitor")
}
