//! The Reyes pipeline on the stream machine (Owens et al., "Comparing Reyes and OpenGL on
//! a Stream Architecture", Graphics Hardware 2002; Owens's thesis ch. 8): Bezier patches
//! projected to window space, subdivided depth-first in each cluster's scratchpad into
//! quads whose sides are shorter than the stop length, with crack-free edge freezing, then
//! sampled by a bounding-box rasterizer against each quad's four edge equations.
//!
//! * [`kernels`]: `project`, `subdiv`, `sample` — built with the kernel builder, compiled
//!   to microcode, checked against their interpretation.
//! * [`frame`]: a frame as a stream program on the whole machine (stream controller, SRF
//!   streams by name, DRAM), composited by the OpenGL pipeline's composite.

pub mod frame;
pub mod kernels;
