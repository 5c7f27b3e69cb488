//! Machine descriptions: every count, size and latency of the modelled machine comes from a
//! TOML file in `machines/` (ARCHITECTURE §4). Parsing rejects unknown keys, so a typo is
//! an error rather than a silently ignored setting, and [`MachineDesc::validate`] rejects
//! descriptions that cannot be built, naming the offending key.

use std::fmt;
use std::path::Path;

use serde::Deserialize;

use crate::arith::fp32::FpMode;

#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct MachineDesc {
    pub name: String,
    #[serde(default)]
    pub description: String,
    pub clocks: Clocks,
    pub cluster: Cluster,
    #[serde(default)]
    pub arithmetic: Arithmetic,
    pub latency: Latency,
}

#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Clocks {
    pub core_mhz: u64,
    pub dram_mhz: u64,
}

#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Cluster {
    /// Clusters, all driven by one microcontroller (SIMD).
    pub count: usize,
    pub adders: usize,
    pub multipliers: usize,
    pub divsqrt: usize,
}

#[derive(Clone, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Arithmetic {
    /// Flush subnormal fp32 inputs and results to zero.
    #[serde(default)]
    pub flush_to_zero: bool,
}

/// Latencies in core cycles.
#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Latency {
    /// Integer, logic, shift, select and packed add/sub in an adder.
    pub int: u32,
    /// fp32 add, subtract, compare, convert, min/max in an adder.
    pub fp_add: u32,
    /// Every multiply.
    pub mul: u32,
    pub div: u32,
    pub sqrt: u32,
    /// Cycles between issues to one divide/sqrt unit (1 = fully pipelined).
    pub divsqrt_issue_interval: u32,
}

/// A machine description that cannot be read or built.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DescError {
    Io { path: String, message: String },
    Parse { source: String, message: String },
    Invalid { machine: String, key: &'static str, problem: String },
}

impl fmt::Display for DescError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DescError::Io { path, message } => write!(f, "cannot read machine description {path}: {message}"),
            DescError::Parse { source, message } => write!(f, "machine description {source}: {}", message.trim_end()),
            DescError::Invalid { machine, key, problem } => write!(f, "machine `{machine}`: `{key}` {problem}"),
        }
    }
}

impl std::error::Error for DescError {}

/// Upper bounds that keep the model's state and the probe hierarchy sane.
const MAX_CLUSTERS: usize = 256;
const MAX_UNITS: usize = 32;
const MAX_LATENCY: u32 = 256;
const MAX_MHZ: u64 = 100_000;

impl MachineDesc {
    /// Parses a description; `source` names it in errors (a path or a built-in name).
    pub fn parse(text: &str, source: &str) -> Result<Self, DescError> {
        let desc: MachineDesc = toml::from_str(text)
            .map_err(|e| DescError::Parse { source: source.into(), message: e.to_string() })?;
        desc.validate()?;
        Ok(desc)
    }

    pub fn load(path: &Path) -> Result<Self, DescError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| DescError::Io { path: path.display().to_string(), message: e.to_string() })?;
        Self::parse(&text, &path.display().to_string())
    }

    /// The built-in default machine, `machines/gold8.toml`.
    pub fn gold8() -> Self {
        Self::parse(include_str!("../../machines/gold8.toml"), "gold8").expect("gold8 is valid")
    }

    pub fn fp_mode(&self) -> FpMode {
        FpMode { flush_to_zero: self.arithmetic.flush_to_zero }
    }

    /// Rejects descriptions that cannot be built.
    pub fn validate(&self) -> Result<(), DescError> {
        let bad = |key, problem: String| Err(DescError::Invalid { machine: self.name.clone(), key, problem });
        let c = &self.cluster;
        if !(1..=MAX_CLUSTERS).contains(&c.count) {
            return bad("cluster.count", format!("is {}, must be 1..={MAX_CLUSTERS}", c.count));
        }
        for (key, n) in [("cluster.adders", c.adders), ("cluster.multipliers", c.multipliers), ("cluster.divsqrt", c.divsqrt)] {
            if !(1..=MAX_UNITS).contains(&n) {
                return bad(key, format!("is {n}, must be 1..={MAX_UNITS}"));
            }
        }
        for (key, mhz) in [("clocks.core_mhz", self.clocks.core_mhz), ("clocks.dram_mhz", self.clocks.dram_mhz)] {
            if !(1..=MAX_MHZ).contains(&mhz) {
                return bad(key, format!("is {mhz}, must be 1..={MAX_MHZ}"));
            }
        }
        let l = &self.latency;
        for (key, v) in [
            ("latency.int", l.int),
            ("latency.fp_add", l.fp_add),
            ("latency.mul", l.mul),
            ("latency.div", l.div),
            ("latency.sqrt", l.sqrt),
            ("latency.divsqrt_issue_interval", l.divsqrt_issue_interval),
        ] {
            if !(1..=MAX_LATENCY).contains(&v) {
                return bad(key, format!("is {v}, must be 1..={MAX_LATENCY} cycles"));
            }
        }
        let shortest = l.div.min(l.sqrt);
        if l.divsqrt_issue_interval > shortest {
            return bad(
                "latency.divsqrt_issue_interval",
                format!("is {}, longer than the divide/sqrt latency {shortest}", l.divsqrt_issue_interval),
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOLD8: &str = include_str!("../../machines/gold8.toml");

    #[test]
    fn gold8_has_the_architecture_defaults() {
        let m = MachineDesc::gold8();
        assert_eq!((m.cluster.count, m.cluster.adders, m.cluster.multipliers, m.cluster.divsqrt), (8, 3, 2, 1));
        assert_eq!((m.latency.int, m.latency.fp_add, m.latency.mul, m.latency.div), (2, 4, 4, 16));
        assert_eq!(m.latency.divsqrt_issue_interval, 8);
        assert_eq!((m.clocks.core_mhz, m.clocks.dram_mhz), (500, 167));
        assert!(!m.fp_mode().flush_to_zero);
    }

    #[test]
    fn typos_and_impossible_values_are_named() {
        let e = MachineDesc::parse(&GOLD8.replace("adders = 3", "addres = 3"), "t").unwrap_err();
        assert!(e.to_string().contains("addres"), "{e}");
        let e = MachineDesc::parse(&GOLD8.replace("count = 8", "count = 0"), "t").unwrap_err();
        assert!(e.to_string().contains("cluster.count"), "{e}");
        let e = MachineDesc::parse(&GOLD8.replace("divsqrt_issue_interval = 8", "divsqrt_issue_interval = 17"), "t")
            .unwrap_err();
        assert!(e.to_string().contains("divsqrt_issue_interval"), "{e}");
        let e = MachineDesc::parse(&GOLD8.replace("mul = 4", "mul = 0"), "t").unwrap_err();
        assert!(e.to_string().contains("latency.mul"), "{e}");
        let e = MachineDesc::parse(&GOLD8.replace("core_mhz = 500", "core_mhz = -5"), "t").unwrap_err();
        assert!(e.to_string().contains("core_mhz"), "{e}");
        let e = MachineDesc::load(Path::new("/nonexistent/m.toml")).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/m.toml"), "{e}");
    }
}
