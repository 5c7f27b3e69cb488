//! Stream programs (ARCHITECTURE §5): the layer pipelines are written in, the StreamC of
//! this machine.
//!
//! * [`kernels`]: kernels registered by name with typed handles, compiled only when a
//!   program can reach them.
//! * [`srf`]: streams by name with record layouts, placed in the SRF by lifetime, with a
//!   printable plan.
//! * [`dram`]: DRAM buffers by name.
//! * [`host`]: the operations — kernel calls with streams bound by name, loads, stores,
//!   gathers, scatters, host-interface writes and read-backs — queued on the stream
//!   controller and ordered by its scoreboard; uploads and downloads through the host
//!   interface.
//! * [`attribution`]: every cycle of a run in one category (a kernel, waiting on a stream
//!   operation, dispatch, issue, host), from the stream controller's records.
//! * [`timeline`]: a run in the Trace Event format trace viewers open.
//! * [`batch`]: strip-mining, two batches in flight, and spilling by splitting work.

pub mod attribution;
pub mod batch;
pub mod dram;
pub mod host;
pub mod kernels;
pub mod srf;
pub mod timeline;

pub use batch::{Fit, pipelined, split_to_fit, strip_mine};
pub use dram::{Buffer, DramMap};
pub use host::{Call, HostError, RasterCall, StreamHost};
pub use kernels::{KernelId, KernelLibrary, PARAMS};
pub use srf::{Layout, Lifetime, PlanError, SrfPlan, SrfPlanner, StreamId, live};
