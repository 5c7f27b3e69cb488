//! imagine-units: every hardware block of the stream processor and the composed machine
//! (ARCHITECTURE §4).
//!
//! * [`arith`] — the combinational datapaths: pure functions on raw bits shared by the
//!   interpreter and the clocked functional units.
//! * [`desc`] — machine descriptions (`machines/*.toml`): every count and latency.
//! * [`ops`] — the arithmetic op set: semantics, unit class, latency, mnemonic and opcode of
//!   every op, shared by the interpreter and the clocked units.
//! * [`fu`] — the clocked, lane-batched functional units: pipelined adders and multipliers,
//!   and the iterative divide/sqrt unit.
//! * [`srf`] — the stream register file: block-interleaved storage, stream buffers and the
//!   arbiter that grants the SRF port to them.

pub mod arith;
pub mod desc;
pub mod fu;
pub mod ops;
pub mod srf;
