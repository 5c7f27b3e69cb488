//! The S3 design and its trace driver: a host block writes the trace's triangles into the
//! command queue, one per clock; the design runs until every primitive has retired; the
//! driver watches the committed state after each clock for the statistics.
//!
//! Statistics (spec §1.2 "Metric"): triangle-level parallelism (TLP) is the number of busy
//! accelerators per cycle — its mean over the frame, its histogram, and its mean over
//! each window of `window` cycles (Fig. 14 plots 100-cycle windows); the issue stage's
//! outcome per cycle (issued, or the cause it did not: no free accelerator, dependence,
//! conflict, nothing to issue); and the cycles fetch waited on a full window. With the
//! DRAM memory ([`super::fbdram`]) the design has a second clock domain; the driver
//! samples after every core-clock edge, and adds the DRAM's counters and the cycles the
//! accelerators waited on memory.

use imagine_hdl::{
    ClockDomain, ContractError, Design, DomainId, FifoTx, Module, Scope, SignalId, SignalKind, Sim,
    Trace,
};

use super::accel::{Accel, Port};
use super::fbdram::{FbDram, Layout};
use super::fbmem::{FbMem, PORT_ACCESSES, PORT_READS};
use super::fetch::{Command, Fetch};
use super::issue::Issue;
use super::raster::{Frame, TraceTriangle};
use super::{S3Config, S3Memory};
use crate::dram::DramChannel;
use crate::limits::{MAX_S3_PRIMITIVES, MAX_WINDOW};
use crate::memory::{MemoryConfig, build_memory};

/// The host: the trace in its memory, written into the command queue one triangle per
/// clock while the queue has room.
pub struct Host {
    domain: DomainId,
    tris: Vec<TraceTriangle>,
    next: usize,
    next_d: usize,
    out: FifoTx<Command>,
    id: SignalId,
}

impl Host {
    fn new(
        s: &mut Scope<'_>,
        domain: DomainId,
        tris: Vec<TraceTriangle>,
        out: FifoTx<Command>,
    ) -> Self {
        let id = s.signal(
            "sent",
            imagine_hdl::bits_for(tris.len() as u64),
            SignalKind::Reg,
        );
        Host {
            domain,
            tris,
            next: 0,
            next_d: 0,
            out,
            id,
        }
    }

    pub fn is_done(&self) -> bool {
        self.next == self.tris.len()
    }
}

impl Module for Host {
    fn domain(&self) -> DomainId {
        self.domain
    }
    fn eval(&mut self) -> Result<(), ContractError> {
        self.next_d = self.next;
        if self.next < self.tris.len() && self.out.free() > 0 {
            self.out.push(Command {
                order: self.next as u32 + 1,
                tri: self.tris[self.next],
            })?;
            self.next_d += 1;
        }
        Ok(())
    }
    fn commit(&mut self) {
        self.next = self.next_d;
    }
    fn trace(&self, t: &mut Trace) {
        t.value(self.id, self.next as u64);
    }
}

/// A hook run on the built simulator before the first clock (to attach a waveform).
pub type OnStart = Box<dyn FnOnce(&mut Sim) -> Result<(), String>>;

/// How to run a trace.
pub struct RunOptions {
    /// Cycles per parallelism window (the CSV's rows).
    pub window: u64,
    /// Evaluate the blocks in the reverse of their construction order.
    pub reverse_order: bool,
    pub on_start: Option<OnStart>,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            window: 100,
            reverse_order: false,
            on_start: None,
        }
    }
}

/// What a run measured.
#[derive(Clone, Debug, PartialEq)]
pub struct S3Report {
    pub accelerators: usize,
    pub cycles: u64,
    pub frame: Frame,
    /// Triangles in the trace; primitives issued (slices count one each); triangles fetch
    /// dropped (no pixel centre in the window).
    pub triangles: usize,
    pub primitives: u64,
    pub culled: u64,
    /// Pixels rasterized (entered a pixel pipeline), fragments that passed the depth test.
    pub pixels: u64,
    pub fragments_passed: u64,
    /// `busy_histogram[n]`: cycles with exactly n accelerators busy.
    pub busy_histogram: Vec<u64>,
    /// Mean busy accelerators over each window of `window` cycles (the last may be short).
    pub window: u64,
    pub windows: Vec<f64>,
    /// Cycles by issue-stage outcome, indexed by [`Cause`].
    pub causes: [u64; 5],
    /// Cycles fetch held a primitive the issue window had no room for.
    pub window_full: u64,
    /// Cycles in which two in-flight primitives were in hazard (must be 0).
    pub in_flight_hazards: u64,
    /// `ideal` or `dram` (`s3.memory`).
    pub memory: &'static str,
    /// Busy accelerator-cycles held by the memory (0 with the ideal memory).
    pub mem_stall_cycles: u64,
    /// The DRAM's counters (DRAM memory only).
    pub dram: Option<S3DramStats>,
}

/// What the frame buffer's traffic did in DRAM, summed over the channels.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct S3DramStats {
    pub channels: usize,
    /// Frame-buffer requests from the accelerators (a Z access is two DRAM words).
    pub fb_reads: u64,
    pub fb_writes: u64,
    /// DRAM column reads and writes (one word each), activates, refreshes.
    pub reads: u64,
    pub writes: u64,
    pub activates: u64,
    pub refreshes: u64,
    /// Column accesses that found their row open: columns − activates.
    pub row_hits: u64,
    /// DRAM-clock cycles of the run.
    pub dram_cycles: u64,
}

impl S3Report {
    /// Mean busy accelerators per cycle: the paper's triangle-level parallelism.
    pub fn mean_parallelism(&self) -> f64 {
        let busy: u64 = self
            .busy_histogram
            .iter()
            .enumerate()
            .map(|(n, c)| n as u64 * c)
            .sum();
        busy as f64 / self.cycles.max(1) as f64
    }
}

/// Why a run failed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum S3Error {
    /// The trace or window cannot be run (names the problem).
    Input(String),
    /// A block broke a contract (an error in the model).
    Contract(String),
    /// Not every primitive retired within the bound: a deadlock.
    Timeout { cycles: u64, retired_all: bool },
}

impl std::fmt::Display for S3Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            S3Error::Input(m) => write!(f, "{m}"),
            S3Error::Contract(m) => write!(f, "the S3 design broke a contract: {m}"),
            S3Error::Timeout { cycles, .. } => write!(
                f,
                "the S3 design did not finish within {cycles} cycles (a deadlock in the issue unit?)"
            ),
        }
    }
}

impl std::error::Error for S3Error {}

impl From<ContractError> for S3Error {
    fn from(e: ContractError) -> Self {
        S3Error::Contract(e.to_string())
    }
}

/// A bound on the cycles of any correct run: every primitive run alone, one after
/// another (setup, one clock per row and per pixel of its box, the pipeline), plus the
/// host's and fetch's clocks. Running past it means a primitive never retired. With the
/// DRAM memory each of a pixel's clocks may become its six DRAM references one after
/// another, each a full row cycle, a CAS latency and the crossings both ways, in core
/// clocks, with refreshes in between: a loose bound, only to catch a deadlock.
pub fn cycle_bound(cfg: &S3Config, tris: &[TraceTriangle], width: u32, height: u32) -> u64 {
    let ideal = ideal_cycle_bound(cfg, tris, width, height);
    match &cfg.memory {
        S3Memory::Ideal => ideal,
        S3Memory::Dram(m) => {
            let d = &m.dram;
            let ratio = m.clocks.core_mhz.div_ceil(m.clocks.dram_mhz.max(1));
            let sync = 2 * (m.memory.sync_stages as u64 + 2);
            let per_ref = (d.t_rc + d.t_rp + d.t_rcd + d.cas_latency + d.t_rfc) as u64 + sync;
            ideal.saturating_mul(6 * per_ref * ratio)
        }
    }
}

fn ideal_cycle_bound(cfg: &S3Config, tris: &[TraceTriangle], width: u32, height: u32) -> u64 {
    let pipe = 2 * cfg.memory_latency as u64 + 8;
    let mut total = 64 + 4 * tris.len() as u64;
    for t in tris {
        let f = super::raster::FixedTriangle::from_trace(t);
        if let Some(r) = super::raster::region(&f, None, width, height) {
            let rows = (r.y1 - r.y0 + 1) as u64;
            let slices = rows.div_ceil(cfg.split_height as u64);
            total += slices * (cfg.setup_cycles as u64 + pipe + 4) + rows + r.pixels();
        }
    }
    total
}

/// Builds the design for a `width × height` window and runs `tris` to completion.
pub fn run(
    cfg: &S3Config,
    width: u32,
    height: u32,
    tris: &[TraceTriangle],
    mut opts: RunOptions,
) -> Result<S3Report, S3Error> {
    if !(1..=MAX_WINDOW).contains(&width) || !(1..=MAX_WINDOW).contains(&height) {
        return Err(S3Error::Input(format!(
            "window {width}×{height}: each side must be 1..={MAX_WINDOW}"
        )));
    }
    if tris.len() > MAX_S3_PRIMITIVES {
        return Err(S3Error::Input(format!(
            "{} triangles: the 24-bit order tag numbers at most {MAX_S3_PRIMITIVES}",
            tris.len()
        )));
    }
    if opts.window == 0 {
        return Err(S3Error::Input(
            "the parallelism window must be at least 1 cycle".into(),
        ));
    }
    let bound = cycle_bound(cfg, tris, width, height);
    let (mut sim, core) = build(cfg, width, height, tris)?;
    if opts.reverse_order {
        sim.reverse_eval_order();
    }
    if let Some(f) = opts.on_start.take() {
        f(&mut sim).map_err(S3Error::Input)?;
    }
    let k = cfg.accelerators;
    let mut hist = vec![0u64; k + 1];
    let mut causes = [0u64; 5];
    let (mut window_full, mut hazards) = (0u64, 0u64);
    let mut windows = Vec::new();
    let (mut win_busy, mut win_cycles) = (0u64, 0u64);
    // Once the last accelerator retires, its last writes are still in the ideal memory's
    // request pipe for L − 1 more cycles; the frame is done when they land. (The DRAM
    // memory acknowledges writes before an accelerator retires.)
    let mut tail = match cfg.memory {
        S3Memory::Ideal => cfg.memory_latency as u64 - 1,
        S3Memory::Dram(_) => 0,
    };
    loop {
        if sim.core_cycles() >= bound {
            sim.finish().map_err(|e| S3Error::Input(e.to_string()))?;
            return Err(S3Error::Timeout {
                cycles: bound,
                retired_all: false,
            });
        }
        while !sim.step()?.rising.contains(core) {}
        let busy = sim.modules_of::<Accel>().filter(|a| a.is_busy()).count();
        hist[busy] += 1;
        win_busy += busy as u64;
        win_cycles += 1;
        if win_cycles == opts.window {
            windows.push(win_busy as f64 / win_cycles as f64);
            (win_busy, win_cycles) = (0, 0);
        }
        let issue = sim.modules_of::<Issue>().next().expect("one issue unit");
        if let Some(c) = issue.cause() {
            causes[c as usize] += 1;
        }
        window_full += issue.window_full() as u64;
        hazards += (issue.in_flight_hazards() > 0) as u64;
        let done = sim.modules_of::<Host>().all(Host::is_done)
            && sim.modules_of::<Fetch>().all(Fetch::is_idle)
            && issue.is_idle()
            && busy == 0;
        if done {
            if tail == 0 {
                break;
            }
            tail -= 1;
        }
    }
    if win_cycles > 0 {
        windows.push(win_busy as f64 / win_cycles as f64);
    }
    sim.finish()
        .map_err(|e| S3Error::Input(format!("cannot finish the waveform: {e}")))?;
    let fetch = sim.modules_of::<Fetch>().next().expect("one fetch unit");
    let (pixels, passed) = sim
        .modules_of::<Accel>()
        .map(Accel::pixels)
        .fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    let mem_stall_cycles = sim.modules_of::<Accel>().map(Accel::mem_stall_cycles).sum();
    let (frame, dram) = match sim.modules_of::<FbDram>().next() {
        None => (
            sim.modules_of::<FbMem>()
                .next()
                .expect("one memory")
                .frame()
                .clone(),
            None,
        ),
        Some(m) => {
            let frame = m.frame(width, height, sim.modules_of::<DramChannel>());
            let (fb_reads, fb_writes) = m.accesses();
            let mut s = S3DramStats {
                channels: m.params().channels,
                fb_reads,
                fb_writes,
                reads: 0,
                writes: 0,
                activates: 0,
                refreshes: 0,
                row_hits: 0,
                dram_cycles: 0,
            };
            for c in sim.modules_of::<DramChannel>() {
                let cs = c.stats();
                if !c.violations().is_empty() {
                    return Err(S3Error::Contract(format!(
                        "DRAM channel {} broke a timing constraint: {:?}",
                        c.index(),
                        c.violations()[0]
                    )));
                }
                s.reads += cs.reads;
                s.writes += cs.writes;
                s.activates += cs.activates;
                s.refreshes += cs.refreshes;
                s.dram_cycles = s.dram_cycles.max(cs.cycles);
            }
            s.row_hits = (s.reads + s.writes).saturating_sub(s.activates);
            (frame, Some(s))
        }
    };
    Ok(S3Report {
        accelerators: k,
        cycles: sim.core_cycles(),
        frame,
        triangles: tris.len(),
        primitives: fetch.emitted(),
        culled: fetch.culled(),
        pixels,
        fragments_passed: passed,
        busy_histogram: hist,
        window: opts.window,
        windows,
        causes,
        window_full,
        in_flight_hazards: hazards,
        memory: cfg.memory.name(),
        mem_stall_cycles,
        dram,
    })
}

/// The design: host → command queue → fetch → issue → K accelerators ↔ memory; returns
/// it with its core domain.
fn build(
    cfg: &S3Config,
    width: u32,
    height: u32,
    tris: &[TraceTriangle],
) -> Result<(Sim, DomainId), S3Error> {
    let e = |e: imagine_hdl::DesignError| S3Error::Input(e.to_string());
    let dram = match &cfg.memory {
        S3Memory::Ideal => None,
        S3Memory::Dram(m) => Some(m),
    };
    let layout = Layout::of(width, height);
    if let Some(m) = dram {
        let p = crate::dram::DramParams::of(m);
        if p.burst != 1 {
            return Err(S3Error::Input(format!(
                "s3.memory = \"dram\" needs dram.burst_words = 1 (a one-word frame-buffer \
                 write would otherwise be a read-modify-write), not {}",
                p.burst
            )));
        }
        if 4 * layout.words() > p.capacity_bytes() {
            return Err(S3Error::Input(format!(
                "a {width}×{height} frame buffer ({} bytes) does not fit in the DRAM ({} bytes)",
                4 * layout.words(),
                p.capacity_bytes()
            )));
        }
    }
    // The S3 engine runs on one core clock; with the ideal memory its frequency only names
    // time in the waveform. With the DRAM it is the machine's core clock, beside its DRAM
    // clock.
    let clocks = match dram {
        None => vec![ClockDomain::mhz("core", 100)],
        Some(m) => vec![
            ClockDomain::mhz("core", m.clocks.core_mhz),
            ClockDomain::mhz("dram", m.clocks.dram_mhz),
        ],
    };
    let mut design = Design::new("top", clocks).map_err(e)?;
    let core = design.domain("core").map_err(e)?;
    let mem_ports = match dram {
        None => None,
        Some(m) => Some(
            build_memory(
                &mut design,
                m,
                MemoryConfig {
                    policy: crate::dram::Policy::parse(&m.memory.policy)
                        .expect("a validated policy"),
                    record: false,
                    init: layout.init(&Frame::cleared(width, height)),
                },
            )
            .map_err(e)?,
        ),
    };
    let mut top = design.scope();
    let mut s3 = top.child("s3");
    let (cmd_tx, cmd_rx) = s3
        .fifo("command_queue", core, cfg.queue_entries, 1)
        .map_err(e)?;
    let (prim_tx, prim_rx) = s3.fifo("fetch_out", core, 2, 1).map_err(e)?;
    let host = Host::new(&mut s3.child("host"), core, tris.to_vec(), cmd_tx);
    let fetch = Fetch::new(
        &mut s3.child("fetch"),
        core,
        cfg,
        (width, height),
        cmd_rx,
        prim_tx,
    );
    let lat = cfg.memory_latency as usize;
    let (mut dispatch, mut retire, mut ports, mut accels) = (vec![], vec![], vec![], vec![]);
    let (mut dram_ports, mut accel_parts) = (vec![], vec![]);
    for k in 0..cfg.accelerators {
        let mut a = s3.child(&format!("accel{k}"));
        let (dtx, drx) = a.pipe("dispatch", core, 1, 1).map_err(e)?;
        let (rtx, rrx) = a.pipe("retire", core, 1, 1).map_err(e)?;
        let (qtx, qrx) = a.pipe("mem_req", core, lat, PORT_ACCESSES).map_err(e)?;
        let (ptx, prx) = a.pipe("mem_rsp", core, lat, PORT_READS).map_err(e)?;
        dispatch.push(dtx);
        retire.push(rrx);
        let port: Port = if dram.is_some() {
            let (atx, arx) = a.pipe("mem_ack", core, lat, 1).map_err(e)?;
            dram_ports.push((qrx, ptx, atx));
            (qtx, prx, Some(arx))
        } else {
            ports.push((qrx, ptx));
            (qtx, prx, None)
        };
        accel_parts.push((k, drx, rtx, port));
    }
    for (k, drx, rtx, port) in accel_parts {
        let mut a = s3.child(&format!("accel{k}"));
        accels.push(Accel::new(&mut a, core, k, cfg, width, drx, rtx, port));
    }
    let issue = Issue::new(&mut s3.child("issue"), core, cfg, prim_rx, dispatch, retire);
    let memory: Box<dyn FnOnce(&mut Design)> = match mem_ports {
        None => {
            let m = FbMem::new(
                &mut s3.child("fbmem"),
                core,
                Frame::cleared(width, height),
                ports,
            );
            Box::new(move |d: &mut Design| d.add(m))
        }
        Some(mp) => {
            let m = FbDram::new(
                &mut s3.child("fbdram"),
                core,
                layout,
                cfg.memory_latency,
                dram_ports,
                mp,
            );
            Box::new(move |d: &mut Design| d.add(m))
        }
    };
    design.add(host);
    design.add(fetch);
    design.add(issue);
    for a in accels {
        design.add(a);
    }
    memory(&mut design);
    Ok((Sim::new(design), core))
}
