//! Combinational arithmetic: op semantics on raw bits, no host floating point (but for the
//! proven-exact alternative evaluation `fp32::host`).
//!
//! * [`flags`] — IEEE 754 exception flags in the TestFloat/SoftFloat bit encoding.
//! * [`fp32`] — the IEEE 754 binary32 datapath (add, mul, div/sqrt, compare, convert),
//!   bit-identical to Berkeley SoftFloat 3 with the RISC-V specialisation.

pub mod flags;
pub mod fp32;
pub mod int;
pub mod packed;
