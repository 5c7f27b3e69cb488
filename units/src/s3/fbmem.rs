//! The frame-buffer memory: the paper's "ideal multi-ported memory" (l.190–203), one port
//! per accelerator, each taking up to four accesses per clock (Z read, Z write,
//! destination read, destination write: the paper's 128 bits per clock per accelerator)
//! with a fixed latency each way (`s3.memory_latency`). Reads answer in request order;
//! writes take effect at the clock edge. No bank conflicts, no bandwidth limit across
//! ports: the memory never stalls an accelerator, as in the paper's simulator.
//!
//! The colour buffer holds RGBA8 words, the depth buffer 48-bit words (24-bit depth over
//! the 24-bit order tag, see [`super::raster`]).

use imagine_hdl::{
    ContractError, DomainId, Module, PipeRx, PipeTx, Scope, SignalId, SignalKind, Trace,
};

use super::raster::Frame;
use super::{MemReq, MemRsp};

/// Accesses one port takes per clock.
pub const PORT_ACCESSES: usize = 4;
/// Read data one port returns per clock (a Z read and a destination read).
pub const PORT_READS: usize = 2;

pub struct FbMem {
    domain: DomainId,
    ports: Vec<(PipeRx<MemReq>, PipeTx<MemRsp>)>,
    frame: Frame,
    /// Writes of this cycle, applied at commit.
    writes: Vec<MemReq>,
    reads_q: u32,
    writes_q: u32,
    reads_d: u32,
    ids: [SignalId; 2],
}

impl FbMem {
    pub fn new(
        s: &mut Scope<'_>,
        domain: DomainId,
        frame: Frame,
        ports: Vec<(PipeRx<MemReq>, PipeTx<MemRsp>)>,
    ) -> Self {
        let w = imagine_hdl::bits_for((PORT_ACCESSES * ports.len()) as u64);
        let ids = [
            s.signal("reads", w, SignalKind::Wire),
            s.signal("writes", w, SignalKind::Wire),
        ];
        FbMem {
            domain,
            ports,
            frame,
            writes: Vec::new(),
            reads_q: 0,
            writes_q: 0,
            reads_d: 0,
            ids,
        }
    }

    pub fn frame(&self) -> &Frame {
        &self.frame
    }
}

impl Module for FbMem {
    fn domain(&self) -> DomainId {
        self.domain
    }

    fn eval(&mut self) -> Result<(), ContractError> {
        self.writes.clear();
        self.reads_d = 0;
        for (rx, tx) in &mut self.ports {
            while let Some(r) = rx.read() {
                match r {
                    MemReq::ReadDepth(a) => {
                        tx.write(MemRsp::Depth(self.frame.depth[a as usize]))?;
                        self.reads_d += 1;
                    }
                    MemReq::ReadColour(a) => {
                        tx.write(MemRsp::Colour(self.frame.colour[a as usize]))?;
                        self.reads_d += 1;
                    }
                    w => self.writes.push(w),
                }
            }
        }
        Ok(())
    }

    fn commit(&mut self) {
        for w in &self.writes {
            match *w {
                MemReq::WriteDepth(a, v) => self.frame.depth[a as usize] = v,
                MemReq::WriteColour(a, v) => self.frame.colour[a as usize] = v,
                _ => {}
            }
        }
        self.reads_q = self.reads_d;
        self.writes_q = self.writes.len() as u32;
    }

    fn trace(&self, t: &mut Trace) {
        t.value(self.ids[0], self.reads_q as u64);
        t.value(self.ids[1], self.writes_q as u64);
    }
}
