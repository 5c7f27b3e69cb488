//! The DRAM side of the memory system (ARCHITECTURE §4, memory row), modelled at command
//! level in the DRAM clock domain.
//!
//! Each channel (see [`channel`]) is one hdl module made of four blocks, one file each:
//!
//! * [`scheduler`] — the memory access scheduler of Rixner, Dally, Kapasi, Mattson and
//!   Owens, "Memory Access Scheduling", ISCA 2000: a pending-reference buffer
//!   ([`pending`]), per-bank precharge managers and row arbiters, a column arbiter, and the
//!   address arbiter that drives one command per cycle onto the channel's command bus
//!   under a [`Policy`];
//! * [`sdram`] — the SDRAM part: its banks ([`bank`]), the data it stores, and the data
//!   bus (read data CL cycles after READ, write data with WRITE);
//! * [`timing_check`] — an independent monitor of the command bus that knows only the
//!   datasheet rules and flags every violated constraint;
//! * the channel's input (a request FIFO) and output (a reply FIFO).
//!
//! Timings (`[dram]` in the machine description) default to a Micron MT48LC4M32B2
//! 128 Mb ×32 SDR SDRAM at the -6 speed grade, 167 MHz (6 ns clock): CL 3, tRCD 3, tRP 3,
//! tRAS 7, tRC 10, tRRD 2, tWR 2, tRFC 10 cycles, tREFI 2604 cycles (4096 refreshes per
//! 64 ms), 4 banks × 4096 rows × 256 columns of 32 bits. The burst length is one word (A):
//! streams on Imagine are word-granular, and a one-word burst makes every reference one
//! column access, as in Rixner et al.
//!
//! # Address mapping
//!
//! A reference names a byte address; the unit of access is one burst of `burst_words`
//! 32-bit words. With `u = address / (4 · burst_words)`:
//! `channel = u mod C`, then `column = (u / C) mod (columns / burst_words)` (in bursts),
//! `bank = …` the next bits and `row` the rest (the *row:bank:column:channel* order), so
//! consecutive words go to consecutive channels and a unit-stride stream walks a row of
//! each channel before it moves to the next bank.
//!
//! # Command-bus time
//!
//! The scheduler decides in its cycle `t` the command that the command-bus register drives
//! in cycle `t + 1`; the SDRAM and the timing checker act on it in that cycle. Every
//! constraint is between command-bus cycles, so the one-cycle register delays all commands
//! alike.

pub mod activity;
pub mod bank;
pub mod channel;
pub mod pending;
pub mod replay;
pub mod scheduler;
pub mod sdram;
pub mod timing_check;
pub mod trace;

use std::fmt;

use imagine_hdl::bits::{u4, u12};

use crate::desc::MachineDesc;

pub use channel::{ChannelConfig, ChannelInput, ChannelOutput, ChannelStats, DramChannel};
pub use replay::{ReplayOptions, ReplayReport, replay};
pub use timing_check::{TimingChecker, TimingViolation};
pub use trace::{TraceError, TraceKind, TraceRequest};

/// A memory access scheduling policy (Rixner et al. ISCA 2000, §4 and Table 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Policy {
    /// Only the oldest pending reference may have DRAM operations performed for it.
    InOrder,
    /// The oldest pending reference whose next operation is ready is served; a bank is
    /// precharged only when no pending reference hits its open row (open-row precharging).
    FirstReady,
    /// Column accesses before row operations (precharge, activate); banks stay open until a
    /// reference to another row needs them.
    ColOpen,
    /// Column accesses first; a bank is precharged as soon as no pending reference hits
    /// its open row.
    ColClosed,
    /// Row operations before column accesses; open-row precharging.
    RowOpen,
    /// Row operations first; closed-row precharging.
    RowClosed,
    /// Column-first, open-row, with loads served before stores in every arbiter.
    LoadOverStore,
}

impl Policy {
    pub const ALL: [Policy; 7] = [
        Policy::InOrder,
        Policy::FirstReady,
        Policy::ColOpen,
        Policy::ColClosed,
        Policy::RowOpen,
        Policy::RowClosed,
        Policy::LoadOverStore,
    ];
    pub const NAMES: [&'static str; 7] = [
        "in-order",
        "first-ready",
        "col-open",
        "col-closed",
        "row-open",
        "row-closed",
        "load-over-store",
    ];

    pub fn parse(s: &str) -> Option<Policy> {
        Self::NAMES
            .iter()
            .position(|n| *n == s)
            .map(|i| Self::ALL[i])
    }

    pub fn name(self) -> &'static str {
        Self::NAMES[Self::ALL.iter().position(|p| *p == self).expect("listed")]
    }

    /// Whether a bank is precharged as soon as no pending reference hits its open row.
    pub fn closed_row(self) -> bool {
        matches!(self, Policy::ColClosed | Policy::RowClosed)
    }
}

impl fmt::Display for Policy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An SDRAM command on a channel's command bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Command {
    Activate { bank: u4, row: u16 },
    Read { bank: u4, column: u12 },
    Write { bank: u4, column: u12 },
    Precharge { bank: u4 },
    Refresh,
}

impl Command {
    /// The 3-bit code of the `cmd` probe: 0 no command, 1 ACT, 2 READ, 3 WRITE, 4 PRE,
    /// 5 REF.
    pub fn code(self) -> u64 {
        match self {
            Command::Activate { .. } => 1,
            Command::Read { .. } => 2,
            Command::Write { .. } => 3,
            Command::Precharge { .. } => 4,
            Command::Refresh => 5,
        }
    }

    pub fn bank(self) -> Option<usize> {
        match self {
            Command::Activate { bank, .. }
            | Command::Read { bank, .. }
            | Command::Write { bank, .. }
            | Command::Precharge { bank } => Some(bank.value() as usize),
            Command::Refresh => None,
        }
    }

    pub fn mnemonic(self) -> &'static str {
        match self {
            Command::Activate { .. } => "ACT",
            Command::Read { .. } => "READ",
            Command::Write { .. } => "WRITE",
            Command::Precharge { .. } => "PRE",
            Command::Refresh => "REF",
        }
    }
}

/// Geometry and timing of the SDRAM of a machine, in DRAM cycles.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DramParams {
    pub channels: usize,
    pub banks: usize,
    pub rows: usize,
    pub columns: usize,
    pub burst: usize,
    pub cl: u64,
    pub t_rcd: u64,
    pub t_rp: u64,
    pub t_ras: u64,
    pub t_rc: u64,
    pub t_rrd: u64,
    pub t_wr: u64,
    pub turnaround: u64,
    pub t_refi: u64,
    pub t_rfc: u64,
    pub freq_hz: u64,
}

impl DramParams {
    pub fn of(desc: &MachineDesc) -> Self {
        let d = &desc.dram;
        DramParams {
            channels: d.channels,
            banks: d.banks,
            rows: d.rows,
            columns: d.columns,
            burst: d.burst_words,
            cl: d.cas_latency.into(),
            t_rcd: d.t_rcd.into(),
            t_rp: d.t_rp.into(),
            t_ras: d.t_ras.into(),
            t_rc: d.t_rc.into(),
            t_rrd: d.t_rrd.into(),
            t_wr: d.t_wr.into(),
            turnaround: d.turnaround.into(),
            t_refi: d.refresh_interval.into(),
            t_rfc: d.t_rfc.into(),
            freq_hz: desc.clocks.dram_mhz * 1_000_000,
        }
    }

    /// Bytes one column access moves.
    pub fn burst_bytes(&self) -> u64 {
        4 * self.burst as u64
    }

    /// Bytes of the whole memory.
    pub fn capacity_bytes(&self) -> u64 {
        (self.channels * self.banks * self.rows * self.columns) as u64 * 4
    }

    /// Peak bandwidth in bytes per second: every channel's data bus busy every cycle.
    pub fn peak_bytes_per_s(&self) -> f64 {
        self.channels as f64 * 4.0 * self.freq_hz as f64
    }

    /// Splits a byte address into its channel and location (see the module doc), or
    /// `None` past the end of memory.
    #[inline(always)]
    pub fn map(&self, byte_addr: u64) -> Option<Location> {
        if byte_addr >= self.capacity_bytes() {
            return None;
        }
        let (u, _) = div_rem(byte_addr, self.burst_bytes());
        let (u, channel) = div_rem(u, self.channels as u64);
        let (u, burst) = div_rem(u, self.bursts_per_row());
        let column = burst * self.burst as u64;
        let (row, bank) = div_rem(u, self.banks as u64);
        let channel = channel as usize;
        Some(Location {
            channel,
            bank: u4::new(bank as u8),
            row: row as u16,
            column: u12::new(column as u16),
        })
    }

    /// Bursts in a row (a shift, not a division, in every built-in part's geometry).
    fn bursts_per_row(&self) -> u64 {
        div_rem(self.columns as u64, self.burst as u64).0
    }

    /// The byte address of a location (the inverse of [`map`](Self::map), burst-aligned).
    pub fn unmap(&self, l: &Location) -> u64 {
        let bursts = self.bursts_per_row();
        let u = ((l.row as u64 * self.banks as u64 + l.bank.value() as u64) * bursts
            + l.column.value() as u64 / self.burst as u64)
            * self.channels as u64
            + l.channel as u64;
        u * self.burst_bytes()
    }
}

/// `(n / d, n % d)`, by a shift and a mask when `d` is a power of two (every built-in
/// part's geometry): an address is mapped for every word the memory system moves.
fn div_rem(n: u64, d: u64) -> (u64, u64) {
    if d.is_power_of_two() {
        (n >> d.trailing_zeros(), n & (d - 1))
    } else {
        (n / d, n % d)
    }
}

/// Where a burst lives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Location {
    pub channel: usize,
    pub bank: u4,
    pub row: u16,
    /// First column (word) of the burst.
    pub column: u12,
}

/// Who asked for a reference, so its reply finds its way back: an address generator and
/// the reference's sequence number within its stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Tag {
    pub source: u8,
    pub seq: u32,
}

/// A memory reference entering a channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Request {
    pub write: bool,
    pub byte_addr: u64,
    /// Write data (the first `burst_words` words are used).
    pub data: [u32; 8],
    pub tag: Tag,
}

/// A finished reference leaving a channel: read data, or the acknowledgement of a write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reply {
    pub write: bool,
    pub data: [u32; 8],
    pub tag: Tag,
}
