//! One rasterizing accelerator (Fig. 3, l.76–93): an independent MIMD rasterizer that
//! takes a primitive from the issue unit, sets it up, generates its spans, and runs its
//! pixels down a pipeline at one pixel per clock, then broadcasts its tag.
//!
//! * **Setup** — `setup_cycles` cycles (the machine's `[s3]`; the paper calls setup
//!   negligible and gives no figure): orientation, edge functions, tie biases.
//! * **Span generator** — one span (the covered pixels of one row inside the primitive's
//!   box) per clock into a one-entry span register; a row without pixels costs its clock.
//! * **Pixel walker** — one pixel per clock from the current span; it moves to the next
//!   span without a bubble, so a primitive runs at the paper's peak of one pixel per
//!   clock once its first span is ready.
//! * **Pixel pipeline**, `2L + 2` stages for a memory latency of L each way. Stage 0 (the
//!   walker's output)
//!   interpolates depth and colour and sends the Z read (and, blending, the destination
//!   read); stage 2L, when the read data returns, is the Z compare (and the blend); stage
//!   2L + 1 sends the Z write and the destination write. Untaken stages of the paper's
//!   list are skipped per mode (opaque: no alpha test, destination read or blend; the
//!   trace has no textures, so no texel read, filter or texture blend). With ideal memory
//!   the pipeline never stalls.
//! * **Memory stalls** (DRAM memory, [`super::fbdram`]): read data that arrives early waits
//!   in a read-data buffer; when the pixel at the compare stage has no data yet, or the
//!   write stage would exceed [`MAX_UNACKED_WRITES`] writes the memory has not yet
//!   acknowledged, the whole pixel pipeline, walker and span generator hold (an in-order
//!   stall: nothing moves, nothing is re-sent). A primitive retires only once its writes
//!   are acknowledged, so a dependent primitive issued after the broadcast reads what it
//!   wrote whatever the DRAM scheduler reorders. With the ideal memory (no acknowledge
//!   port) a missing read word is a contract error, as before.
//!
//! The accelerator is busy, for the parallelism statistic, from the cycle the primitive
//! arrives to the cycle it broadcasts its tag ("busy if any of its stages is busy", l.215).

use std::collections::VecDeque;

use imagine_hdl::{
    ContractError, Display, DomainId, Module, PipeRx, PipeTx, Scope, SignalId, SignalKind, Trace,
    Violation,
};

use super::raster::{Setup, apply_fragment};
use super::{Job, MemReq, MemRsp, Retire, S3Config};
use crate::s3::raster::Mode;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    Idle = 0,
    Setup = 1,
    Raster = 2,
}

pub const PHASE_NAMES: &[&str] = &["idle", "setup", "raster"];

/// Writes an accelerator may have sent and not yet seen acknowledged (DRAM memory): bounds
/// the memory's per-port queue. (A) Four pixels' depth and colour writes.
pub const MAX_UNACKED_WRITES: u32 = 8;

/// An accelerator's memory port: requests out, read data back in request order, and (for
/// a memory that can be slow) the count of its writes completed each cycle.
pub type Port = (PipeTx<MemReq>, PipeRx<MemRsp>, Option<PipeRx<u8>>);

/// A pixel in the pipeline.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Pixel {
    addr: u32,
    z: u32,
    colour: u32,
    /// After the compare: what to write.
    write_depth: Option<u64>,
    write_colour: Option<u32>,
}

#[derive(Clone, Debug)]
struct State {
    phase: Phase,
    /// Setup cycles left.
    count: u32,
    job: Option<Job>,
    setup: Option<Setup>,
    /// Next row for the span generator.
    row: u32,
    /// The span register: (row, first x, last x).
    span: Option<(u16, u16, u16)>,
    /// The walker: (row, next x, last x).
    walk: Option<(u16, u16, u16)>,
    pipe: Vec<Option<Pixel>>,
    /// Read data that arrived before its pixel reached the compare stage.
    read_data: VecDeque<MemRsp>,
    /// Writes sent and not acknowledged (DRAM memory only).
    unacked: u32,
    /// Cycles the accelerator was busy but held by the memory.
    mem_stalls: u64,
    /// This cycle was one of them.
    stalled: bool,
    pixels: u64,
    fragments_passed: u64,
    busy_cycles: u64,
}

pub struct Accel {
    domain: DomainId,
    index: u8,
    setup_cycles: u32,
    width: u32,
    dispatch: PipeRx<Job>,
    retire: PipeTx<Retire>,
    req: PipeTx<MemReq>,
    rsp: PipeRx<MemRsp>,
    acks: Option<PipeRx<u8>>,
    path: String,
    q: State,
    d: State,
    ids: AccelIds,
}

struct AccelIds {
    phase: SignalId,
    tag: SignalId,
    order: SignalId,
    row: SignalId,
    x: SignalId,
    stages: Vec<SignalId>,
    pixels: SignalId,
    read_data: SignalId,
    unacked: SignalId,
    stall: SignalId,
}

impl Accel {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        s: &mut Scope<'_>,
        domain: DomainId,
        index: usize,
        cfg: &S3Config,
        width: u32,
        dispatch: PipeRx<Job>,
        retire: PipeTx<Retire>,
        (req, rsp, acks): Port,
    ) -> Self {
        let l = cfg.memory_latency as usize;
        // Stage 0 (interpolate, send the reads) is the walker's output; the registers
        // behind it hold a pixel 1..=2L cycles later: the read data meets it at 2L.
        let n_stages = 2 * l + 1;
        let tag_w = imagine_hdl::bits_for(cfg.dest_rs() as u64 - 1);
        let phase = s.signal_shown("phase", 2, SignalKind::Reg, Display::Names(PHASE_NAMES));
        s.glance(phase);
        let stage_name = |i: usize| match i + 1 {
            j if j == 2 * l => format!("s{j}_zcompare_blend"),
            j if j == 2 * l + 1 => format!("s{j}_zwrite_dwrite"),
            j => format!("s{j}_memory"),
        };
        let ids = AccelIds {
            phase,
            tag: s.signal("tag", tag_w, SignalKind::Reg),
            order: s.signal("order", 24, SignalKind::Reg),
            row: s.signal("span_row", 13, SignalKind::Reg),
            x: s.signal("walk_x", 12, SignalKind::Reg),
            stages: (0..n_stages)
                .map(|i| s.child("pipe").signal(&stage_name(i), 1, SignalKind::Reg))
                .collect(),
            pixels: s.signal("pixels", 32, SignalKind::Reg),
            // At most two reads per pixel in the 2L stages before the compare.
            read_data: s.signal(
                "read_data",
                imagine_hdl::bits_for(4 * l as u64),
                SignalKind::Reg,
            ),
            unacked: s.signal(
                "unacked_writes",
                imagine_hdl::bits_for(MAX_UNACKED_WRITES as u64),
                SignalKind::Reg,
            ),
            stall: s.signal("mem_stall", 1, SignalKind::Reg),
        };
        let q = State {
            phase: Phase::Idle,
            count: 0,
            job: None,
            setup: None,
            row: 0,
            span: None,
            walk: None,
            pipe: vec![None; n_stages],
            read_data: VecDeque::new(),
            unacked: 0,
            mem_stalls: 0,
            stalled: false,
            pixels: 0,
            fragments_passed: 0,
            busy_cycles: 0,
        };
        Accel {
            domain,
            index: index as u8,
            setup_cycles: cfg.setup_cycles,
            width,
            dispatch,
            retire,
            req,
            rsp,
            acks,
            path: s.path().to_string(),
            d: q.clone(),
            q,
            ids,
        }
    }

    pub fn is_busy(&self) -> bool {
        self.q.phase != Phase::Idle
    }

    /// Pixels that entered the pipeline, fragments that passed the depth test.
    pub fn pixels(&self) -> (u64, u64) {
        (self.q.pixels, self.q.fragments_passed)
    }

    pub fn busy_cycles(&self) -> u64 {
        self.q.busy_cycles
    }

    /// Busy cycles the memory held this accelerator (read data late, too many writes
    /// unacknowledged, or its last writes not yet done).
    pub fn mem_stall_cycles(&self) -> u64 {
        self.q.mem_stalls
    }

    fn fail(&self, why: String) -> ContractError {
        ContractError::at(&self.path, Violation::Other(why))
    }

    fn raster(&mut self, st: &mut State) -> Result<(), ContractError> {
        let q = &self.q;
        let job = q.job.expect("rastering a job");
        let n = q.pipe.len();
        let (cmp, last) = (n - 2, n - 1);
        let mode = job.prim.tri.mode;
        // Hold everything while the memory is behind (see the module doc).
        let reads = 1 + (mode == Mode::Blended) as usize;
        let data_late = q.pipe[cmp].is_some() && st.read_data.len() < reads;
        let writes = q.pipe[last].map_or(0, |p| {
            p.write_depth.is_some() as u32 + p.write_colour.is_some() as u32
        });
        let acked = self.acks.is_some();
        let too_many_writes = acked && st.unacked + writes > MAX_UNACKED_WRITES;
        if data_late && !acked {
            return Err(self.fail("no depth read data at the compare stage".into()));
        }
        if data_late || too_many_writes {
            st.mem_stalls += 1;
            st.stalled = true;
            return Ok(());
        }
        // The write stage.
        if let Some(p) = q.pipe[last] {
            if let Some(w) = p.write_depth {
                self.req.write(MemReq::WriteDepth(p.addr, w))?;
            }
            if let Some(c) = p.write_colour {
                self.req.write(MemReq::WriteColour(p.addr, c))?;
            }
            if acked {
                st.unacked += writes;
            }
        }
        // The compare stage: the read data of this pixel is here.
        let mut decided = None;
        if let Some(mut p) = q.pipe[cmp] {
            let Some(MemRsp::Depth(old_z)) = st.read_data.pop_front() else {
                return Err(self.fail("no depth read data at the compare stage".into()));
            };
            let old_c = match mode {
                Mode::Blended => match st.read_data.pop_front() {
                    Some(MemRsp::Colour(c)) => c,
                    _ => return Err(self.fail("no destination read data to blend".into())),
                },
                Mode::Opaque => 0,
            };
            if let Some((dw, cw)) = apply_fragment(
                job.prim.tri.mode,
                p.z,
                p.colour,
                job.prim.order,
                old_z,
                old_c,
            ) {
                p.write_depth = dw;
                p.write_colour = Some(cw);
                st.fragments_passed += 1;
            }
            decided = Some(p);
        }
        for i in (1..n).rev() {
            st.pipe[i] = q.pipe[i - 1];
        }
        if n > cmp + 1 {
            st.pipe[cmp + 1] = decided;
        }
        // The walker emits a pixel; the span generator refills the span register.
        let setup = q.setup;
        let mut span = q.span;
        st.pipe[0] = None;
        st.walk = match q.walk {
            Some((y, x, xr)) => {
                let prim = &job.prim;
                if !prim.dest.contains(x, y) {
                    return Err(self.fail(format!(
                        "pixel ({x}, {y}) of triangle {} lies outside its region {:?}",
                        prim.order, prim.dest
                    )));
                }
                let s = setup.expect("a span implies a setup");
                let (z, colour) = s.shade(x, y);
                let addr = y as u32 * self.width + x as u32;
                self.req.write(MemReq::ReadDepth(addr))?;
                if prim.tri.mode == Mode::Blended {
                    self.req.write(MemReq::ReadColour(addr))?;
                }
                st.pipe[0] = Some(Pixel {
                    addr,
                    z,
                    colour,
                    write_depth: None,
                    write_colour: None,
                });
                st.pixels += 1;
                if x < xr {
                    Some((y, x + 1, xr))
                } else {
                    span.take()
                }
            }
            None => span.take(),
        };
        let r = job.prim.dest;
        if span.is_none() && q.row <= r.y1 as u32 {
            span = setup.and_then(|s| {
                s.span(q.row as u16, r.x0, r.x1)
                    .map(|(a, b)| (q.row as u16, a, b))
            });
            st.row = q.row + 1;
        }
        st.span = span;
        let drained = q.row > r.y1 as u32
            && q.span.is_none()
            && q.walk.is_none()
            && q.pipe.iter().all(Option::is_none);
        if drained && st.unacked > 0 {
            // Its last writes are still on their way into the DRAM.
            st.mem_stalls += 1;
            st.stalled = true;
        } else if drained {
            self.retire.write(Retire {
                accel: self.index,
                tag: job.tag,
            })?;
            st.phase = Phase::Idle;
            st.job = None;
            st.setup = None;
        }
        Ok(())
    }
}

impl Module for Accel {
    fn domain(&self) -> DomainId {
        self.domain
    }

    fn eval(&mut self) -> Result<(), ContractError> {
        let mut st = self.q.clone();
        st.stalled = false;
        // Every word that arrives is taken this cycle (a pipe's contract).
        while let Some(r) = self.rsp.read() {
            st.read_data.push_back(r);
        }
        if let Some(acks) = &mut self.acks {
            while let Some(n) = acks.read() {
                st.unacked = st.unacked.checked_sub(n as u32).ok_or_else(|| {
                    ContractError::at(
                        &self.path,
                        Violation::Other("more writes acknowledged than sent".into()),
                    )
                })?;
            }
        }
        if let Some(job) = self.dispatch.read() {
            if self.q.phase != Phase::Idle {
                return Err(self.fail(format!("given tag {} while busy", job.tag)));
            }
            st.job = Some(job);
            st.setup = Setup::new(&job.prim.tri);
            // A triangle of zero area has no spans.
            st.row = if st.setup.is_some() {
                job.prim.dest.y0 as u32
            } else {
                job.prim.dest.y1 as u32 + 1
            };
            st.span = None;
            st.walk = None;
            st.count = self.setup_cycles - 1;
            st.phase = if st.count == 0 {
                Phase::Raster
            } else {
                Phase::Setup
            };
        } else {
            match self.q.phase {
                Phase::Idle => {}
                Phase::Setup => {
                    st.count -= 1;
                    if st.count == 0 {
                        st.phase = Phase::Raster;
                    }
                }
                Phase::Raster => self.raster(&mut st)?,
            }
        }
        if self.acks.is_none() && !st.read_data.is_empty() {
            return Err(self.fail("read data arrived with no pixel to take it".into()));
        }
        st.busy_cycles = self.q.busy_cycles + (self.q.phase != Phase::Idle) as u64;
        self.d = st;
        Ok(())
    }

    fn commit(&mut self) {
        std::mem::swap(&mut self.q, &mut self.d);
    }

    fn trace(&self, t: &mut Trace) {
        let i = &self.ids;
        let q = &self.q;
        t.value(i.phase, q.phase as u64);
        t.value(i.tag, q.job.map_or(0, |j| j.tag as u64));
        t.value(i.order, q.job.map_or(0, |j| j.prim.order as u64));
        t.value(i.row, q.row.min(8191) as u64);
        t.value(i.x, q.walk.map_or(0, |w| w.1 as u64));
        for (id, s) in i.stages.iter().zip(&q.pipe) {
            t.value(*id, s.is_some() as u64);
        }
        t.value(i.pixels, q.pixels & 0xFFFF_FFFF);
        t.value(i.read_data, q.read_data.len() as u64);
        t.value(i.unacked, q.unacked as u64);
        t.value(i.stall, q.stalled as u64);
    }
}
