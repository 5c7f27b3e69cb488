//! The intracluster switch (ARCHITECTURE §4): a full crossbar from every result port (the
//! functional units, scratchpad reads, the intercluster network, stream reads, immediates)
//! to every LRF write port, the condition codes and the output streams. Each LRF still has
//! one write port: two results routed to one LRF in the same cycle are a port conflict,
//! reported by the [`Lrf`].

use imagine_hdl::ContractError;

use crate::ccfile::CcFile;
use crate::lrf::Lrf;
use crate::microcode::{Dest, Dests};

/// Where results routed to output streams go.
pub trait StreamSink {
    /// Appends the words of the clusters `mask` selects (all if `None`), in cluster order.
    fn append(
        &mut self,
        stream: u16,
        values: &[u32],
        mask: Option<&[bool]>,
    ) -> Result<(), ContractError>;
}

/// Routes one result (a word per cluster, written where `mask` allows) to its destinations;
/// compiled for `L` lanes ([`crate::lanes`]).
#[inline(always)]
pub fn route<const L: usize>(
    dests: &Dests,
    values: &[u32],
    mask: Option<&[bool]>,
    all_lanes: &[bool],
    lrfs: &mut [Lrf],
    cc: &mut CcFile,
    streams: &mut impl StreamSink,
) -> Result<(), ContractError> {
    for dest in dests.iter().flatten() {
        match *dest {
            Dest::Lrf { lrf, entry } => lrfs[lrf as usize].write_for::<L>(entry, values, mask)?,
            Dest::Cc { index } => cc.write(index, values, mask.unwrap_or(all_lanes))?,
            Dest::Stream { stream } => streams.append(stream, values, mask)?,
        }
    }
    Ok(())
}
