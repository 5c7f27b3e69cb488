//! imagine-hdl: the RTL vocabulary of the model (ARCHITECTURE §3).
//!
//! * [`bits`] — bit-accurate field types (`arbitrary-int`) and wide words (`bitvec`);
//! * [`Reg`] — registers with `q`/`d` and a probe;
//! * [`PipeTx`]/[`PipeRx`], [`FifoTx`]/[`FifoRx`] — fixed-latency pipes and FIFOs with a
//!   contract (latency ≥ 1, bandwidth per cycle, one writer and one reader);
//! * [`Clocks`] — clock domains with exact rational ratios, time in picoseconds, and
//!   [`AsyncFifoTx`]/[`AsyncFifoRx`] for crossings;
//! * [`ProbeRegistry`], [`Trace`], [`Tracer`] — named, sized signals and change reporting;
//!   [`Recorder`] keeps every change for testbenches;
//! * [`Module`], [`Design`], [`Sim`] — two-phase evaluation (`eval` then `commit`).
//! * [`demo`] — a small design made only of these parts.

pub mod async_fifo;
pub mod bits;
pub mod clock;
pub mod demo;
mod edge_counts;
pub mod error;
pub mod fifo;
#[cfg(feature = "inject-bugs")]
pub mod inject;
pub mod pipe;
pub mod probe;
pub mod recorder;
pub mod reg;
pub mod sim;

pub use async_fifo::{AsyncFifoRx, AsyncFifoTx};
pub use bits::{Bits, WideWord, bits_for, wide_word};
pub use clock::{ClockDomain, ClockError, Clocks, DomainId, DomainSet, Edge, default_domains};
pub use error::{Contract, ContractError, Violation};
pub use fifo::{FifoRx, FifoTx};
pub use pipe::{PipeRx, PipeTx};
pub use probe::{Display, ProbeRegistry, SignalDecl, SignalId, SignalKind, Trace, Tracer};
pub use recorder::{Recorder, Recording};
pub use reg::Reg;
pub use sim::{Channel, Design, DesignError, Module, Scope, Sim, Traced};
