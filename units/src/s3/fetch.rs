//! The fetch unit (Fig. 8): reads the command queue, decodes each triangle into the
//! accelerators' fixed-point formats, computes its operand regions (the bounding box of
//! its pixel centres is its destination; a blended triangle reads its destination, its one
//! source region) and hands primitives to the issue unit, one per cycle.
//!
//! With splitting on (§4.5, l.251–258) a triangle whose box is taller than the split
//! height leaves as slices of `split_height` rows, one per cycle, each a primitive with its
//! own box (the triangle cut to the slice's rows). Only the paper's one direction, cutting
//! into horizontal bands ("split vertically"), is modelled. A triangle with no pixel centre
//! in the window is dropped here (it would write nothing).

use imagine_hdl::{
    ContractError, DomainId, FifoRx, FifoTx, Module, Scope, SignalId, SignalKind, Trace,
};

use super::raster::{FixedTriangle, Mode, Region, TraceTriangle, region};
use super::{Prim, S3Config};

/// A command: a triangle and its order tag.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Command {
    pub order: u32,
    pub tri: TraceTriangle,
}

/// The triangle being cut into slices.
#[derive(Clone, Copy, Debug)]
struct Current {
    order: u32,
    tri: FixedTriangle,
    whole: Region,
    /// First row of the next slice.
    next_row: u16,
    slice: u16,
}

#[derive(Clone, Copy, Debug, Default)]
struct State {
    cur: Option<Current>,
    /// Primitives handed to the issue unit, triangles dropped.
    emitted: u64,
    culled: u64,
}

pub struct Fetch {
    domain: DomainId,
    commands: FifoRx<Command>,
    out: FifoTx<Prim>,
    split: Option<u16>,
    source_slots: usize,
    width: u32,
    height: u32,
    q: State,
    d: State,
    ids: [SignalId; 5],
}

impl Fetch {
    pub fn new(
        s: &mut Scope<'_>,
        domain: DomainId,
        cfg: &S3Config,
        (width, height): (u32, u32),
        commands: FifoRx<Command>,
        out: FifoTx<Prim>,
    ) -> Self {
        let ids = [
            s.signal("busy", 1, SignalKind::Reg),
            s.signal("order", 24, SignalKind::Reg),
            s.signal("next_row", 12, SignalKind::Reg),
            s.signal("emitted", 32, SignalKind::Reg),
            s.signal("culled", 32, SignalKind::Reg),
        ];
        Fetch {
            domain,
            commands,
            out,
            split: cfg.split.then_some(cfg.split_height),
            source_slots: cfg.source_slots,
            width,
            height,
            q: State::default(),
            d: State::default(),
            ids,
        }
    }

    /// Nothing held and nothing queued.
    pub fn is_idle(&self) -> bool {
        self.q.cur.is_none() && self.commands.available() == 0
    }

    pub fn emitted(&self) -> u64 {
        self.q.emitted
    }

    pub fn culled(&self) -> u64 {
        self.q.culled
    }

    /// The next slice of `c` (its rows and box), and whether it is the last.
    fn slice(&self, c: &Current) -> (Option<Region>, bool) {
        let w = &c.whole;
        match self.split {
            Some(h) if w.y1 - w.y0 + 1 > h => {
                let last_row = (c.next_row as u32 + h as u32 - 1).min(w.y1 as u32) as u16;
                let r = region(
                    &c.tri,
                    Some((c.next_row, last_row)),
                    self.width,
                    self.height,
                );
                (r, last_row == w.y1)
            }
            _ => (Some(*w), true),
        }
    }
}

impl Module for Fetch {
    fn domain(&self) -> DomainId {
        self.domain
    }

    fn eval(&mut self) -> Result<(), ContractError> {
        let mut st = self.q;
        if let Some(mut c) = st.cur
            && self.out.free() > 0
        {
            let (r, last) = self.slice(&c);
            if let Some(dest) = r {
                // A blended triangle reads the pixels it writes: its source region.
                let reads = c.tri.mode == Mode::Blended && self.source_slots > 0;
                self.out.push(Prim {
                    order: c.order,
                    slice: c.slice,
                    tri: c.tri,
                    dest,
                    sources: [reads.then_some(dest), None],
                })?;
                st.emitted += 1;
            }
            if last {
                st.cur = None;
            } else {
                c.next_row += self.split.expect("only split triangles have slices");
                c.slice += 1;
                st.cur = Some(c);
            }
        }
        if st.cur.is_none() && self.commands.available() > 0 {
            let cmd = self.commands.pop()?;
            let tri = FixedTriangle::from_trace(&cmd.tri);
            match region(&tri, None, self.width, self.height) {
                Some(whole) => {
                    st.cur = Some(Current {
                        order: cmd.order,
                        tri,
                        whole,
                        next_row: whole.y0,
                        slice: 0,
                    })
                }
                None => st.culled += 1,
            }
        }
        self.d = st;
        Ok(())
    }

    fn commit(&mut self) {
        self.q = self.d;
    }

    fn trace(&self, t: &mut Trace) {
        let c = self.q.cur;
        t.value(self.ids[0], c.is_some() as u64);
        t.value(self.ids[1], c.map_or(0, |c| c.order as u64));
        t.value(self.ids[2], c.map_or(0, |c| c.next_row as u64));
        t.value(self.ids[3], self.q.emitted & 0xFFFF_FFFF);
        t.value(self.ids[4], self.q.culled & 0xFFFF_FFFF);
    }
}
