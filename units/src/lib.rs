//! imagine-units: every hardware block of the stream processor and the composed machine
//! (ARCHITECTURE §4).
//!
//! * [`arith`] — the combinational datapaths: pure functions on raw bits shared by the
//!   interpreter and the clocked functional units.

pub mod arith;
