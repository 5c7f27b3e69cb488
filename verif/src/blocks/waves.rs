//! The waveform of a failing testbench (`imagine verify --vcd-on-fail F`): the run is
//! replayed from its seed with a VCD window around the first mismatch, which GTKWave opens
//! with the `.gtkw` save file written next to it.
//!
//! A testbench that clocks its block itself makes a [`Waves`] after building the block and
//! reports the block's probes once per cycle, after the commit; one driven by the
//! [`Sim`] attaches it to the simulator instead, which then reports every probe and clock.

use std::cell::RefCell;
use std::io;
use std::path::{Path, PathBuf};
use std::rc::Rc;

use imagine_hdl::{ClockDomain, ProbeRegistry, SignalId, Sim, Trace, Tracer};
use imagine_units::desc::MachineDesc;
use imagine_waves::{CycleWindow, VcdOptions, VcdSummary, VcdWriter};

use super::Config;

/// Cycles of the block's clock shown before the first mismatch: enough to see the
/// transaction that caused it begin in most testbenches.
pub const CYCLES_BEFORE: u64 = 64;
/// Cycles shown after it.
pub const CYCLES_AFTER: u64 = 8;

/// Where to write the waveform and which cycles of the block's clock it covers.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WaveRequest {
    pub path: PathBuf,
    pub window: CycleWindow,
}

impl WaveRequest {
    /// The window of [`CYCLES_BEFORE`] cycles up to `cycle` and [`CYCLES_AFTER`] after it.
    pub fn around(path: &Path, cycle: u64) -> Self {
        WaveRequest {
            path: path.to_path_buf(),
            window: CycleWindow {
                from: cycle.saturating_sub(CYCLES_BEFORE),
                to: Some(cycle + CYCLES_AFTER + 1),
            },
        }
    }
}

/// The clock a testbench advances its block by, one cycle per step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BlockClock {
    Core,
    Dram,
}

/// A testbench's waveform: nothing unless the run was asked for one.
pub struct Waves {
    dump: Option<Dump>,
    /// What the writer wrote, filled in when it finishes.
    summary: Option<Rc<RefCell<VcdSummary>>>,
    /// A failure to create or write the file, reported by [`Waves::finish`].
    error: Option<String>,
}

/// A waveform being written by a testbench that clocks its block itself.
struct Dump {
    trace: Trace,
    window: CycleWindow,
    clock: SignalId,
    period_ps: u64,
}

impl Waves {
    /// No waveform.
    pub fn none() -> Self {
        Waves {
            dump: None,
            summary: None,
            error: None,
        }
    }

    fn failed(error: impl ToString) -> Self {
        Waves {
            error: Some(error.to_string()),
            ..Self::none()
        }
    }

    /// For a testbench that clocks its block by `clock` itself: `probes` are the design's,
    /// every signal of the block registered.
    pub fn new(
        probes: &ProbeRegistry,
        desc: &MachineDesc,
        clock: BlockClock,
        config: &Config,
    ) -> Self {
        let Some(request) = &config.waves else {
            return Self::none();
        };
        let (ours, other) = match clock {
            BlockClock::Core => (
                ClockDomain::mhz("core", desc.clocks.core_mhz),
                ClockDomain::mhz("dram", desc.clocks.dram_mhz),
            ),
            BlockClock::Dram => (
                ClockDomain::mhz("dram", desc.clocks.dram_mhz),
                ClockDomain::mhz("core", desc.clocks.core_mhz),
            ),
        };
        let clock_path = |d: &ClockDomain| {
            probes
                .signals()
                .iter()
                .position(|s| s.path.ends_with(&format!(".clk_{}", d.name)))
                .map(|i| SignalId(i as u32))
        };
        let (Some(clock), other_clock) = (clock_path(&ours), clock_path(&other)) else {
            return Self::failed(format!("the design has no `clk_{}` signal", ours.name));
        };
        let period_ps = 1_000_000_000_000 / ours.freq_hz;
        let options = VcdOptions {
            window: request.window,
            scopes: Vec::new(),
            max_bytes: None,
        };
        let started = VcdWriter::create(&request.path, &options).and_then(|mut w| {
            w.start(probes, &[ours, other])?;
            Ok(w)
        });
        match started {
            Ok(mut writer) => {
                let summary = writer.summary_handle();
                let mut trace = Trace::new(probes, Box::new(writer));
                // The other clock does not run in this testbench: held low, not unknown.
                if let Some(other) = other_clock {
                    trace.value(other, 0);
                }
                Waves {
                    dump: Some(Dump {
                        trace,
                        window: request.window,
                        clock,
                        period_ps,
                    }),
                    summary: Some(summary),
                    error: None,
                }
            }
            Err(e) => Self::failed(e),
        }
    }

    /// For a testbench driven by the simulator: attaches the writer to `sim`.
    pub fn attach(sim: &mut Sim, config: &Config) -> Self {
        let Some(request) = &config.waves else {
            return Self::none();
        };
        let options = VcdOptions {
            window: request.window,
            scopes: Vec::new(),
            max_bytes: None,
        };
        let attached = VcdWriter::create(&request.path, &options).and_then(|mut writer| {
            let summary = writer.summary_handle();
            sim.attach(Box::new(writer))?;
            Ok(summary)
        });
        match attached {
            Ok(summary) => Waves {
                summary: Some(summary),
                ..Self::none()
            },
            Err(e) => Self::failed(e),
        }
    }

    /// The state committed at the end of `cycle` (the block's clock), shown from the rising
    /// edge that starts the next cycle; `report` sends every probe of the block to the trace.
    /// Cycles outside the window cost nothing.
    pub fn cycle(&mut self, cycle: u64, report: impl FnOnce(&mut Trace)) {
        let Some(d) = &mut self.dump else { return };
        let edge = cycle + 1;
        if !d.window.contains(edge) {
            if d.window.to.is_some_and(|to| edge == to) {
                // Closes the window at its end.
                d.trace.tracer().time(edge * d.period_ps, edge);
            }
            return;
        }
        let t = edge * d.period_ps;
        d.trace.tracer().time(t, edge);
        d.trace.value(d.clock, 1);
        report(&mut d.trace);
        d.trace.tracer().time(t + d.period_ps / 2, edge);
        d.trace.value(d.clock, 0);
    }

    /// Closes the waveform (for a simulator-driven testbench, pass its simulator): what was
    /// written, or why it could not be.
    pub fn finish(self, sim: Option<&mut Sim>) -> Result<Option<VcdSummary>, String> {
        if let Some(e) = self.error {
            return Err(e);
        }
        let finished: io::Result<()> = match (self.dump, sim) {
            (Some(mut d), _) => d.trace.tracer().finish(),
            (None, Some(sim)) => sim.finish(),
            (None, None) => return Ok(None),
        };
        finished.map_err(|e| e.to_string())?;
        Ok(self.summary.map(|s| s.borrow().clone()))
    }
}
