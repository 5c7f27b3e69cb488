//! The OpenGL-like pipeline (ARCHITECTURE §5, §7): kernels compiled to microcode and a
//! host that drives the stream processor batch by batch.

pub mod fragment_program;
pub mod kernels;
pub mod mergefrag;
pub mod render;
pub mod scanline;
pub mod srf_model;
pub mod stats;
pub mod vertex_program;
