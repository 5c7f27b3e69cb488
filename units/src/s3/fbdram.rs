//! The frame-buffer memory through the DRAM model (`s3.memory = "dram"`): the issue's
//! second memory mode, beside the paper's ideal one ([`super::fbmem`]).
//!
//! The accelerators keep their ports (`mem_req k` in, `mem_rsp k` out, both
//! `s3.memory_latency` cycles); this block adds a third pipe per port, `mem_ack k`, which
//! carries how many of the port's writes completed this cycle. Behind the ports are the
//! main machine's own memory blocks, built by [`crate::memory::build_memory`] from the
//! machine's `[dram]` and `[memory]` tables: one [`crate::dram::DramChannel`] per channel
//! (access scheduler under `memory.policy`, SDRAM, timing checker) in the DRAM clock
//! domain (`clocks.dram_mhz`), reached through the same synchronising FIFOs
//! (`memory.crossing_entries`, `memory.sync_stages`). The S3 engine then runs at the
//! machine's core clock (`clocks.core_mhz`), and its cycles are core cycles.
//!
//! **Address map** (32-bit words, word address × 4 = byte address, then the DRAM's own
//! channel/bank/row/column interleave): the colour buffer row-major from word 0 (pixel
//! `a = y · width + x` at word `a`), then the depth buffer row-major from word
//! `width · height`, two words per pixel: the 48-bit depth word (24-bit depth over the
//! 24-bit order tag) as its low 32 bits at `width · height + 2a` and its high 16 bits at
//! the next word. A Z read or write is thus two DRAM references, a colour access one. The
//! buffers start cleared ([`Frame::cleared`], preloaded as the host would), and the final
//! frame is read back from the SDRAM arrays. One-word bursts only (`dram.burst_words = 1`):
//! a longer burst would make a one-word write a read-modify-write, which is not modelled.
//!
//! **Each core cycle** (`eval`, from committed state only):
//!
//! 1. every request arriving on a port is taken (a pipe's contract) into the port's slot
//!    list (one slot per request, in request order) and its DRAM references into the
//!    port's outbox;
//! 2. at most one reply per channel comes back through its crossing
//!    ([`MemPorts::pop_replies`]); its tag (port, slot, half) fills its slot;
//! 3. finished slots leave each port's slot list from the front, in request order: read
//!    data goes back on `mem_rsp` (up to [`PORT_READS`] per cycle, a Z read's two words
//!    joined into one 48-bit word), finished writes are counted on `mem_ack`;
//! 4. arbitration: the ports offer the heads of their outboxes, in turn from a
//!    round-robin pointer that advances by one port each cycle; a port keeps offering its
//!    next reference while the channel it maps to can take one (each channel's crossing
//!    takes one reference per core cycle). A port's references enter the DRAM in its
//!    request order (its head blocks it).
//!
//! **Ordering.** Two primitives in flight never touch the same pixel (the issue unit's
//! dependence checks), and a pixel's write leaves an accelerator only after its read data
//! came back, so the DRAM scheduler may reorder references freely. Across primitives, an
//! accelerator retires only when this block has acknowledged all its writes (a DRAM
//! `WRITE` put the data into the array), so a dependent primitive, issued after the
//! broadcast, reads what the earlier one wrote.
//!
//! **Bounded storage.** A port holds at most `4L + MAX_UNACKED_WRITES` slots (L the port
//! latency): at most 2L pixels wait for read data between the walker and the compare stage
//! (two reads each), and the accelerator stops sending writes at
//! [`MAX_UNACKED_WRITES`] unacknowledged (see [`super::accel`]). More is a contract error.

use std::collections::VecDeque;

use imagine_hdl::{
    ContractError, DomainId, Module, PipeRx, PipeTx, Scope, SignalId, SignalKind, Trace, Violation,
    bits_for,
};

use super::accel::MAX_UNACKED_WRITES;
use super::fbmem::PORT_READS;
use super::raster::Frame;
use super::{MemReq, MemRsp};
use crate::dram::{DramChannel, DramParams, Reply, Request, Tag};
use crate::memory::MemPorts;

/// Where the two buffers live in DRAM (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    pub pixels: u64,
}

impl Layout {
    pub fn of(width: u32, height: u32) -> Layout {
        Layout {
            pixels: width as u64 * height as u64,
        }
    }

    /// Words the two buffers take.
    pub fn words(&self) -> u64 {
        3 * self.pixels
    }

    pub fn colour_word(&self, a: u32) -> u64 {
        a as u64
    }

    /// The depth word's low half; its high half is the next word.
    pub fn depth_word(&self, a: u32) -> u64 {
        self.pixels + 2 * a as u64
    }

    /// The cleared frame as initial DRAM contents: (first word, words).
    pub fn init(&self, f: &Frame) -> Vec<(u64, Vec<u32>)> {
        let depth = f
            .depth
            .iter()
            .flat_map(|&d| [d as u32, (d >> 32) as u32])
            .collect();
        vec![(0, f.colour.clone()), (self.pixels, depth)]
    }
}

/// The port's side of a request: read data being gathered, or a write being done.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Depth,
    Colour,
    Write,
}

#[derive(Clone, Copy, Debug)]
struct Slot {
    kind: Kind,
    /// DRAM references not yet replied to.
    left: u8,
    data: [u32; 2],
}

#[derive(Clone, Debug, Default)]
struct PortState {
    /// Requests in order, from the oldest unfinished one.
    slots: VecDeque<Slot>,
    /// Sequence number of `slots[0]` (wrapping).
    first: u32,
    /// DRAM references not yet given to a channel.
    outbox: VecDeque<Request>,
}

#[derive(Clone, Debug, Default)]
struct State {
    ports: Vec<PortState>,
    rr: usize,
    reads: u64,
    writes: u64,
    /// This cycle's accepted reads and writes, for the probes.
    cycle_reads: u32,
    cycle_writes: u32,
}

/// One accelerator's port as this block sees it.
pub type DramPort = (PipeRx<MemReq>, PipeTx<MemRsp>, PipeTx<u8>);

pub struct FbDram {
    domain: DomainId,
    path: String,
    ports: Vec<DramPort>,
    mem: MemPorts,
    layout: Layout,
    bound: usize,
    q: State,
    d: State,
    replies: Vec<Reply>,
    ids: [SignalId; 5],
}

impl FbDram {
    /// `mem`: the core-side ends of the machine's channels; `latency`: the ports' L.
    pub fn new(
        s: &mut Scope<'_>,
        domain: DomainId,
        layout: Layout,
        latency: u32,
        ports: Vec<DramPort>,
        mem: MemPorts,
    ) -> Self {
        let bound = 4 * latency as usize + MAX_UNACKED_WRITES as usize;
        let n = ports.len();
        let per_cycle = bits_for((4 * n) as u64);
        let ids = [
            s.signal("reads", per_cycle, SignalKind::Wire),
            s.signal("writes", per_cycle, SignalKind::Wire),
            s.signal("in_flight", bits_for((bound * n) as u64), SignalKind::Reg),
            s.signal("outbox", bits_for((2 * bound * n) as u64), SignalKind::Reg),
            s.signal("rr", bits_for(n as u64 - 1), SignalKind::Reg),
        ];
        let q = State {
            ports: vec![PortState::default(); n],
            ..State::default()
        };
        FbDram {
            domain,
            path: s.path().to_string(),
            ports,
            mem,
            layout,
            bound,
            d: q.clone(),
            q,
            replies: Vec::new(),
            ids,
        }
    }

    /// Frame-buffer reads and writes the accelerators made.
    pub fn accesses(&self) -> (u64, u64) {
        (self.q.reads, self.q.writes)
    }

    pub fn params(&self) -> &DramParams {
        self.mem.params()
    }

    /// The frame as the SDRAM arrays hold it (between cycles).
    pub fn frame<'a>(
        &self,
        width: u32,
        height: u32,
        channels: impl Iterator<Item = &'a DramChannel>,
    ) -> Frame {
        let mut ch: Vec<&DramChannel> = channels.collect();
        ch.sort_by_key(|c| c.index());
        let p = self.mem.params();
        let word = |w: u64| {
            let byte = 4 * w;
            let c = p
                .map(byte)
                .expect("the frame fits (checked at build)")
                .channel;
            ch[c].peek(byte).expect("mapped")
        };
        let mut f = Frame::cleared(width, height);
        for a in 0..self.layout.pixels as u32 {
            f.colour[a as usize] = word(self.layout.colour_word(a));
            let d = self.layout.depth_word(a);
            f.depth[a as usize] = word(d) as u64 | (word(d + 1) as u64) << 32;
        }
        f
    }

    fn reference(port: usize, seq: u32, half: u32, write: bool, word: u64, v: u32) -> Request {
        let mut data = [0; 8];
        data[0] = v;
        Request {
            write,
            byte_addr: 4 * word,
            data,
            tag: Tag {
                source: port as u8,
                seq: seq.wrapping_mul(2) | half,
            },
        }
    }
}

fn fail(path: &str, why: String) -> ContractError {
    ContractError::at(path, Violation::Other(why))
}

impl Module for FbDram {
    fn domain(&self) -> DomainId {
        self.domain
    }

    fn eval(&mut self) -> Result<(), ContractError> {
        let mut st = self.q.clone();
        st.cycle_reads = 0;
        st.cycle_writes = 0;
        let l = self.layout;
        // 1. Take every arriving request.
        for (k, ((rx, _, _), ps)) in self.ports.iter_mut().zip(&mut st.ports).enumerate() {
            while let Some(r) = rx.read() {
                let seq = ps.first.wrapping_add(ps.slots.len() as u32);
                let (kind, refs): (Kind, Vec<(bool, u64, u32)>) = match r {
                    MemReq::ReadDepth(a) => {
                        let w = l.depth_word(a);
                        (Kind::Depth, vec![(false, w, 0), (false, w + 1, 0)])
                    }
                    MemReq::ReadColour(a) => (Kind::Colour, vec![(false, l.colour_word(a), 0)]),
                    MemReq::WriteDepth(a, v) => {
                        let w = l.depth_word(a);
                        (
                            Kind::Write,
                            vec![(true, w, v as u32), (true, w + 1, (v >> 32) as u32)],
                        )
                    }
                    MemReq::WriteColour(a, v) => (Kind::Write, vec![(true, l.colour_word(a), v)]),
                };
                if kind == Kind::Write {
                    st.cycle_writes += 1;
                } else {
                    st.cycle_reads += 1;
                }
                for (half, &(write, word, v)) in refs.iter().enumerate() {
                    ps.outbox
                        .push_back(Self::reference(k, seq, half as u32, write, word, v));
                }
                ps.slots.push_back(Slot {
                    kind,
                    left: refs.len() as u8,
                    data: [0; 2],
                });
            }
            if ps.slots.len() > self.bound {
                let n = ps.slots.len();
                return Err(fail(
                    &self.path,
                    format!(
                        "port {k} holds {n} requests; the accelerator's flow control bounds it at {}",
                        self.bound
                    ),
                ));
            }
        }
        st.reads += st.cycle_reads as u64;
        st.writes += st.cycle_writes as u64;
        // 2. Replies find their slots by tag.
        self.replies.clear();
        self.mem.pop_replies(&mut self.replies)?;
        for r in &self.replies {
            let ps = &mut st.ports[r.tag.source as usize];
            let i = (r.tag.seq >> 1).wrapping_sub(ps.first) as usize;
            let Some(slot) = ps.slots.get_mut(i).filter(|s| s.left > 0) else {
                return Err(fail(
                    &self.path,
                    format!("a reply with no request: {:?}", r.tag),
                ));
            };
            slot.data[(r.tag.seq & 1) as usize] = r.data[0];
            slot.left -= 1;
        }
        // 3. Finished requests leave in order.
        for ((_, tx, ack), ps) in self.ports.iter_mut().zip(&mut st.ports) {
            let (mut sent, mut acked) = (0, 0u8);
            while let Some(s) = ps.slots.front().filter(|s| s.left == 0) {
                let rsp = match s.kind {
                    Kind::Write => None,
                    Kind::Depth => Some(MemRsp::Depth(s.data[0] as u64 | (s.data[1] as u64) << 32)),
                    Kind::Colour => Some(MemRsp::Colour(s.data[0])),
                };
                match rsp {
                    Some(_) if sent == PORT_READS => break,
                    Some(v) => {
                        tx.write(v)?;
                        sent += 1;
                    }
                    None => acked += 1,
                }
                ps.slots.pop_front();
                ps.first = ps.first.wrapping_add(1);
            }
            if acked > 0 {
                ack.write(acked)?;
            }
        }
        // 4. Round-robin arbitration onto the channels.
        let n = st.ports.len();
        for i in 0..n {
            let ps = &mut st.ports[(st.rr + i) % n];
            while let Some(r) = ps.outbox.front() {
                let Some(loc) = self.mem.params().map(r.byte_addr) else {
                    return Err(fail(
                        &self.path,
                        format!("byte address {:#x} past memory", r.byte_addr),
                    ));
                };
                if !self.mem.can_push(loc.channel) {
                    break;
                }
                self.mem.push(loc.channel, *r)?;
                ps.outbox.pop_front();
            }
        }
        st.rr = (st.rr + 1) % n;
        self.d = st;
        Ok(())
    }

    fn commit(&mut self) {
        std::mem::swap(&mut self.q, &mut self.d);
        self.mem.commit();
    }

    fn trace(&self, t: &mut Trace) {
        let q = &self.q;
        t.value(self.ids[0], q.cycle_reads as u64);
        t.value(self.ids[1], q.cycle_writes as u64);
        let slots: usize = q.ports.iter().map(|p| p.slots.len()).sum();
        let outbox: usize = q.ports.iter().map(|p| p.outbox.len()).sum();
        t.value(self.ids[2], slots as u64);
        t.value(self.ids[3], outbox as u64);
        t.value(self.ids[4], q.rr as u64);
    }
}
