//! imagine-units: every hardware block of the stream processor and the composed machine
//! (ARCHITECTURE §4).
//!
//! * [`arith`] — the combinational datapaths: pure functions on raw bits shared by the
//!   interpreter and the clocked functional units.
//! * [`desc`] — machine descriptions (`machines/*.toml`): every count and latency.
//! * [`limits`] — every bound on an input that keeps a run finite and its memory bounded.
//! * [`ops`] — the arithmetic op set: semantics, unit class, latency, mnemonic and opcode of
//!   every op, shared by the interpreter and the clocked units.
//! * [`fu`] — the clocked, lane-batched functional units: pipelined adders and multipliers,
//!   and the iterative divide/sqrt unit.
//! * [`microcode`] — the clusters' VLIW instructions: the semantic model, the checks that a
//!   program fits the machine, the binary word layout, and the assembler/disassembler.
//! * the cluster's blocks: [`lrf`] (local register files), [`switch`] (intracluster
//!   switch), [`ccfile`] (condition codes), [`scratchpad`], [`comm`] (intercluster network),
//!   [`delay`] (result pipeline registers), and the [`microcontroller`];
//! * [`machine`] — the composed machine that runs microcode kernels cycle by cycle.
//! * [`dram`] — the SDRAM channels in the DRAM clock domain: memory access scheduler, SDRAM
//!   banks and data bus, timing checker, trace replay.
//! * [`memory`] — the address generators and their clock-crossing ports to the channels.
//! * [`stream_controller`] — the stream instruction queue and scoreboard; [`processor`] —
//!   the whole stream processor (stream controller, address generators, clusters, SRF and
//!   SDRAM channels) running stream programs.
//! * [`s3`] — the S3 superscalar out-of-order rasterizer (Wolfe & Noonburg): fetch, issue
//!   unit, K rasterizing accelerators and their frame-buffer memory, with a trace driver.
//! * [`hwrast`] — the thesis's hardware rasterizer (§6.6): an SRF client the stream
//!   controller runs as a hardware kernel.
//! * [`srf`] — the stream register file: block-interleaved storage, stream buffers and the
//!   arbiter that grants the SRF port to them.

pub mod arith;
pub mod ccfile;
pub mod comm;
pub mod delay;
pub mod desc;
pub mod dram;
pub mod fu;
pub mod hwrast;
pub mod lanes;
pub mod limits;
pub mod lrf;
pub mod machine;
pub mod memory;
pub mod microcode;
pub mod microcontroller;
pub mod ops;
pub mod processor;
mod ring_position;
pub mod runner;
pub mod s3;
pub mod scratchpad;
pub mod srf;
pub mod stream_controller;
pub mod switch;
pub mod workloads;
