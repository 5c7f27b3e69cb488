//! imagine-waves: waveforms of `imagine-hdl` designs (ARCHITECTURE §7).
//!
//! * [`VcdWriter`] — a [`imagine_hdl::Tracer`] that streams probe changes to a Value Change
//!   Dump (timescale 1 ps, one `$scope module` per level of the dotted signal paths), in
//!   bounded memory, fast enough for millions of cycles;
//! * [`CycleWindow`] / [`parse_window`] — `--vcd-window FROM:TO`: core cycles `FROM`
//!   (inclusive) to `TO` (exclusive), `FROM:` to the end;
//! * [`ScopeFilter`] — `--vcd-scope GLOB`: a signal is dumped when a glob matches its path
//!   or one of its enclosing scopes; clocks always are;
//! * [`write_gtkw`] — the GTKWave save file next to a dump (`out.vcd` → `out.gtkw`): the
//!   clocks, then a group per module.
//!
//! ```no_run
//! use imagine_waves::{VcdOptions, VcdWriter, parse_window};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let mut sim = imagine_hdl::demo::build(imagine_hdl::default_domains(), Default::default())?;
//! let options = VcdOptions {
//!     window: parse_window("1000:1100")?,
//!     scopes: vec!["top.mac".into()],
//!     max_bytes: None,
//! };
//! for p in options.unmatched_scopes(sim.probes())? {
//!     eprintln!("warning: --vcd-scope {p} matches no signal");
//! }
//! sim.attach(Box::new(VcdWriter::create("out.vcd", &options)?))?;
//! sim.run_core_cycles(2000, |_| {})?;
//! sim.finish()?; // writes out.gtkw too
//! # Ok(()) }
//! ```

mod filter;
mod gtkw;
mod window;
mod writer;

pub use filter::ScopeFilter;
pub use gtkw::{GtkwView, gtkw_path, gtkw_signal_name, render_gtkw, write_gtkw};
pub use window::{CycleWindow, parse_window};
pub use writer::{VcdOptions, VcdSummary, VcdWriter};
