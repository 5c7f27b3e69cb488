//! Contract violations: the errors a design reports instead of silently dropping values.

use std::fmt;

/// What rule of a port, pipe or FIFO was broken.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Violation {
    /// More values written in one cycle than the declared bandwidth.
    OverBandwidth { written: usize, bandwidth: usize },
    /// A value reached the end of a pipe and its reader did not take it.
    Unread { lost: usize },
    /// More values read in one cycle than the declared bandwidth allows.
    OverRead { bandwidth: usize },
    /// Push into a FIFO that has no room.
    Overflow { capacity: usize },
    /// Pop from a FIFO with nothing visible to the reader.
    Underflow,
    /// A unit was issued an operation while it could not accept one.
    Busy { detail: String },
    /// Anything else a block checks about its use.
    Other(String),
}

impl fmt::Display for Violation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Violation::OverBandwidth { written, bandwidth } => write!(
                f,
                "{written} values written in one cycle, bandwidth is {bandwidth} per cycle"
            ),
            Violation::Unread { lost } => {
                write!(f, "{lost} value(s) lost: they arrived and nobody read them")
            }
            Violation::OverRead { bandwidth } => {
                write!(f, "read more than the bandwidth of {bandwidth} per cycle")
            }
            Violation::Overflow { capacity } => {
                write!(f, "push into a full FIFO (capacity {capacity})")
            }
            Violation::Underflow => write!(f, "pop from an empty FIFO"),
            Violation::Busy { detail } => write!(f, "issue to a busy unit: {detail}"),
            Violation::Other(s) => f.write_str(s),
        }
    }
}

/// A broken contract, located by the signal's hierarchical path and the cycle. Boxed:
/// every block's `eval` returns `Result<_, ContractError>` each cycle, and a pointer-sized
/// error keeps those results in registers (the fields read through `Deref`).
#[derive(Clone, PartialEq, Eq)]
pub struct ContractError(Box<Contract>);

/// What a [`ContractError`] says.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Contract {
    /// Hierarchical path of the module that owns the signal, e.g. `top.mac`.
    pub module: String,
    /// Name of the signal, port or FIFO within that module.
    pub signal: String,
    /// The cycle of the signal's clock domain; filled in by the simulator.
    pub cycle: Option<u64>,
    /// The clock domain's name; filled in by the simulator.
    pub domain: Option<String>,
    pub violation: Violation,
}

impl ContractError {
    /// An error on the signal at hierarchical `path` (`module.signal`).
    pub fn at(path: &str, violation: Violation) -> Self {
        let (module, signal) = path.rsplit_once('.').unwrap_or(("", path));
        ContractError(Box::new(Contract {
            module: module.to_string(),
            signal: signal.to_string(),
            cycle: None,
            domain: None,
            violation,
        }))
    }

    /// One access more than the `bandwidth` of the port at `path` in one cycle.
    #[cold]
    pub fn over_bandwidth(path: &str, bandwidth: usize) -> Self {
        Self::at(
            path,
            Violation::OverBandwidth {
                written: bandwidth + 1,
                bandwidth,
            },
        )
    }

    /// Stamps the error with the cycle it happened in, unless already stamped.
    pub fn in_cycle(mut self, domain: &str, cycle: u64) -> Self {
        if self.cycle.is_none() {
            self.cycle = Some(cycle);
            self.domain = Some(domain.to_string());
        }
        self
    }
}

impl std::ops::Deref for ContractError {
    type Target = Contract;
    fn deref(&self) -> &Contract {
        &self.0
    }
}

impl std::ops::DerefMut for ContractError {
    fn deref_mut(&mut self) -> &mut Contract {
        &mut self.0
    }
}

impl fmt::Debug for ContractError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let c = &*self.0;
        f.debug_struct("ContractError")
            .field("module", &c.module)
            .field("signal", &c.signal)
            .field("cycle", &c.cycle)
            .field("domain", &c.domain)
            .field("violation", &c.violation)
            .finish()
    }
}

impl fmt::Display for ContractError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "contract violation in `{}`, signal `{}`",
            self.module, self.signal
        )?;
        if let Some(c) = self.cycle {
            write!(f, " at {} cycle {c}", self.domain.as_deref().unwrap_or("?"))?;
        }
        write!(f, ": {}", self.violation)
    }
}

impl std::error::Error for ContractError {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn message_names_module_signal_and_cycle() {
        let e =
            ContractError::at("top.mac.out", Violation::Unread { lost: 1 }).in_cycle("core", 17);
        let msg = e.to_string();
        assert!(msg.contains("`top.mac`"), "{msg}");
        assert!(msg.contains("`out`"), "{msg}");
        assert!(msg.contains("core cycle 17"), "{msg}");
        // the first stamp wins
        let e = e.in_cycle("dram", 3);
        assert_eq!(e.cycle, Some(17));
    }
}
