//! The core side of the memory system (ARCHITECTURE §4): the address generators and the
//! ports through which they reach the SDRAM channels.
//!
//! ```text
//!  core domain                                        DRAM domain
//!  AG0 ─┐                ┌─ async_fifo requests(8) ─▶ ch0: scheduler ▶ SDRAM
//!  AG1 ─┴─ MemPorts ─────┼─ …                          …
//!        (round robin)   └◀ async_fifo replies(8) ─── ch0
//! ```
//!
//! [`MemPorts`] owns the core-side ends of two synchronising FIFOs per channel
//! (`memory.crossing_entries` entries, `memory.sync_stages` flip-flops per pointer
//! synchroniser). Each core cycle a channel's request FIFO takes at most one reference;
//! the address generators take turns at being first to offer one (round robin). Each core
//! cycle every channel's reply FIFO hands at most one reply to the address generator its
//! tag names.

pub mod address_gen;
pub mod texture_cache;

pub use address_gen::{AddressGenerator, MemOp, MemOpKind, Pattern};
pub use texture_cache::{TextureCache, TextureCacheStats};

use imagine_hdl::{AsyncFifoRx, AsyncFifoTx, ContractError, Design, DesignError};

use crate::desc::MachineDesc;
use crate::dram::{
    ChannelConfig, ChannelInput, ChannelOutput, DramChannel, DramParams, Policy, Reply, Request,
};

/// The core-side ends of the clock-crossing FIFOs to and from every channel.
pub struct MemPorts {
    pub(crate) requests: Vec<AsyncFifoTx<Request>>,
    pub(crate) replies: Vec<AsyncFifoRx<Reply>>,
    /// Channels a request was pushed to this cycle (bit per channel).
    pub(crate) pushed: u64,
    pub(crate) params: DramParams,
}

impl MemPorts {
    /// Whether a request to `channel` can be pushed this cycle.
    pub fn can_push(&self, channel: usize) -> bool {
        self.pushed & (1 << channel) == 0 && self.requests[channel].can_push()
    }

    pub fn push(&mut self, channel: usize, r: Request) -> Result<(), ContractError> {
        self.pushed |= 1 << channel;
        self.requests[channel].push(r)
    }

    /// Pops at most one reply per channel this cycle.
    pub fn pop_replies(&mut self, out: &mut Vec<Reply>) -> Result<(), ContractError> {
        for rx in &mut self.replies {
            if let Some(r) = rx.try_pop()? {
                out.push(r);
            }
        }
        Ok(())
    }

    pub fn params(&self) -> &DramParams {
        &self.params
    }

    /// Whether every crossing FIFO is empty with its synchronisers settled and nothing was
    /// pushed this cycle: clock edges change nothing in them.
    pub fn is_settled(&self) -> bool {
        self.pushed == 0
            && self.requests.iter().all(AsyncFifoTx::is_settled)
            && self.replies.iter().all(AsyncFifoRx::is_settled)
    }

    /// Ends the cycle.
    pub fn commit(&mut self) {
        self.pushed = 0;
    }
}

/// How to build the memory system's DRAM side.
pub struct MemoryConfig {
    pub policy: Policy,
    /// Keep the requests each channel receives (for `--dram-trace`).
    pub record: bool,
    /// Words to place in DRAM before the run: (word address, words).
    pub init: Vec<(u64, Vec<u32>)>,
}

/// Builds the channels (DRAM domain, under `top.mem`) and the crossing FIFOs; adds the
/// channels to `design` and returns the core-side ports.
pub fn build_memory(
    design: &mut Design,
    desc: &MachineDesc,
    cfg: MemoryConfig,
) -> Result<MemPorts, DesignError> {
    let p = DramParams::of(desc);
    let core = design.domain("core")?;
    let dram = design.domain("dram")?;
    let m = &desc.memory;
    let mut requests = Vec::new();
    let mut replies = Vec::new();
    let mut channels = Vec::new();
    {
        let mut top = design.scope();
        let mut mem = top.child("mem");
        for c in 0..p.channels {
            let mut s = mem.child(&format!("ch{c}"));
            let (req_tx, req_rx) =
                s.async_fifo("requests", (core, dram), m.crossing_entries, m.sync_stages)?;
            let (rep_tx, rep_rx) =
                s.async_fifo("replies", (dram, core), m.crossing_entries, m.sync_stages)?;
            requests.push(req_tx);
            replies.push(rep_rx);
            channels.push(DramChannel::new(
                &mut s,
                dram,
                ChannelConfig {
                    index: c,
                    params: p.clone(),
                    scheduler_params: None,
                    policy: cfg.policy,
                    pending_references: m.pending_references,
                    record: cfg.record,
                },
                ChannelInput::Crossing(req_rx),
                ChannelOutput::Crossing(rep_tx),
            ));
        }
    }
    for (word, data) in &cfg.init {
        for (k, &v) in data.iter().enumerate() {
            let byte = (word + k as u64) * 4;
            let Some(l) = p.map(byte) else {
                return Err(DesignError::Parameter {
                    path: "top.mem".into(),
                    problem: format!(
                        "initial data at word {word} runs past the end of memory ({} bytes)",
                        p.capacity_bytes()
                    ),
                });
            };
            channels[l.channel].poke(byte, v);
        }
    }
    for ch in channels {
        design.add(ch);
    }
    Ok(MemPorts {
        requests,
        replies,
        pushed: 0,
        params: p,
    })
}
