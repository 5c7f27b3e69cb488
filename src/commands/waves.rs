//! The waveform options shared by every subcommand that runs a design.

use std::collections::BTreeSet;
use std::path::PathBuf;

use super::outputs::Outputs;
use anyhow::{Context, Result, bail};
use clap::Args;
use imagine_hdl::Sim;
use imagine_waves::{CycleWindow, VcdOptions, VcdWriter, gtkw_path, parse_window};

#[derive(Args, Clone)]
pub struct WaveArgs {
    /// Write a VCD waveform to FILE (and a GTKWave save file next to it, FILE.gtkw)
    #[arg(long, value_name = "FILE")]
    vcd: Option<PathBuf>,
    /// Dump only core cycles FROM (inclusive) to TO (exclusive); `FROM:` dumps to the end
    #[arg(long, value_name = "FROM:TO", requires = "vcd", value_parser = parse_window)]
    vcd_window: Option<CycleWindow>,
    /// Dump only signals under scopes matching GLOB, e.g. 'top.mac' or '*.s2.*'
    /// (repeatable; clocks are always dumped)
    #[arg(long, value_name = "GLOB", requires = "vcd")]
    vcd_scope: Vec<String>,
    /// Stop the run at once when the waveform passes this size, or is projected to pass it
    /// over a bounded window after its first 1,000 cycles (bytes; K, M and G suffixes)
    #[arg(long, value_name = "BYTES", default_value = "4G", value_parser = parse_bytes)]
    vcd_max_bytes: u64,
}

/// A byte count: digits with an optional K, M or G (powers of 1024).
fn parse_bytes(s: &str) -> Result<u64, String> {
    let (digits, scale) = match s.trim().char_indices().last() {
        Some((i, 'K' | 'k')) => (&s[..i], 1u64 << 10),
        Some((i, 'M' | 'm')) => (&s[..i], 1 << 20),
        Some((i, 'G' | 'g')) => (&s[..i], 1 << 30),
        _ => (s, 1),
    };
    let n: u64 = digits
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a byte count (digits, then K, M or G)"))?;
    n.checked_mul(scale)
        .filter(|&b| b > 0)
        .ok_or_else(|| format!("`{s}` is not a byte count between 1 and 2^64 - 1"))
}

/// The files a traced run writes.
pub struct WavePaths {
    pub vcd: PathBuf,
    pub gtkw: PathBuf,
}

impl WaveArgs {
    /// Whether `--vcd` was given.
    pub fn wants_vcd(&self) -> bool {
        self.vcd.is_some()
    }

    /// The same options dumping `window` instead.
    pub fn with_window(&self, window: CycleWindow) -> WaveArgs {
        WaveArgs {
            vcd_window: Some(window),
            ..self.clone()
        }
    }

    /// Adds the waveform and its GTKWave save file to a command's outputs.
    pub fn check_outputs(&self, outputs: &mut Outputs) -> Result<()> {
        let Some(path) = &self.vcd else {
            return Ok(());
        };
        let gtkw = gtkw_path(path);
        if gtkw == *path {
            bail!(
                "--vcd `{}`: its GTKWave save file would be the same file; name the waveform \
                 `.vcd`",
                path.display()
            );
        }
        outputs.add("--vcd", path)?;
        outputs.add("the GTKWave save file of --vcd", &gtkw)
    }

    /// Attaches a VCD writer to `sim` if `--vcd` was given.
    pub fn attach(&self, sim: &mut Sim) -> Result<Option<WavePaths>> {
        let Some(path) = &self.vcd else {
            return Ok(None);
        };
        let options = VcdOptions {
            window: self.vcd_window.unwrap_or_default(),
            scopes: self.vcd_scope.clone(),
            max_bytes: Some(self.vcd_max_bytes),
        };
        let unmatched = options
            .unmatched_scopes(sim.probes())
            .map_err(anyhow::Error::msg)?;
        if !unmatched.is_empty() {
            let modules: BTreeSet<&str> =
                sim.probes().signals().iter().map(|s| s.scope()).collect();
            bail!(
                "--vcd-scope {} matches no signal; the design's scopes are: {}",
                unmatched.join(", "),
                modules.into_iter().collect::<Vec<_>>().join(", ")
            );
        }
        let writer = VcdWriter::create(path, &options)?;
        sim.attach(Box::new(writer))
            .with_context(|| format!("cannot write `{}`", path.display()))?;
        Ok(Some(WavePaths {
            vcd: path.clone(),
            gtkw: gtkw_path(path),
        }))
    }
}
