//! What a kernel needs of the machine. A kernel builder checks its needs before it builds
//! anything, so a machine description the kernel cannot serve (a cluster count its
//! permutations do not work for, a scratchpad too small for its tables) is refused with a
//! message that names the kernel and the requirement, never a panic.
//!
//! The machine description itself ([`MachineDesc::validate`]) already refuses what the
//! simulator cannot model (no adders, no comm unit, zero clusters); this is what a
//! particular kernel needs on top of that.

use std::fmt;

use imagine_units::desc::MachineDesc;

/// A machine a kernel cannot be built for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MachineRequirementError {
    pub kernel: String,
    pub machine: String,
    /// What the kernel needs, as a noun phrase: "a power-of-two cluster count up to 32".
    pub requirement: String,
    /// What the machine has instead: "6 clusters".
    pub machine_has: String,
}

impl fmt::Display for MachineRequirementError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "kernel `{}` needs {} (machine `{}` has {})",
            self.kernel, self.requirement, self.machine, self.machine_has
        )
    }
}

impl std::error::Error for MachineRequirementError {}

/// The checks of one kernel's builder on one machine.
#[derive(Clone, Copy)]
pub struct Needs<'a> {
    kernel: &'a str,
    desc: &'a MachineDesc,
}

impl<'a> Needs<'a> {
    pub fn new(kernel: &'a str, desc: &'a MachineDesc) -> Self {
        Needs { kernel, desc }
    }

    /// An error for this kernel: it needs `requirement`; the machine has `machine_has`.
    pub fn error(
        &self,
        requirement: impl Into<String>,
        machine_has: impl Into<String>,
    ) -> MachineRequirementError {
        MachineRequirementError {
            kernel: self.kernel.into(),
            machine: self.desc.name.clone(),
            requirement: requirement.into(),
            machine_has: machine_has.into(),
        }
    }

    /// The machine's cluster count.
    pub fn clusters(&self) -> usize {
        self.desc.cluster.count
    }

    fn clusters_has(&self) -> String {
        let c = self.desc.cluster.count;
        format!("{c} cluster{}", if c == 1 { "" } else { "s" })
    }

    /// A cluster count that is a power of two (butterfly exchanges `Xor(d)`, divisions by
    /// `C` as shifts), and at most `max` if given.
    pub fn power_of_two_clusters(&self, max: Option<usize>) -> Result<(), MachineRequirementError> {
        let c = self.desc.cluster.count;
        if c.is_power_of_two() && max.is_none_or(|m| c <= m) {
            return Ok(());
        }
        let requirement = match max {
            Some(m) => format!("a power-of-two cluster count up to {m}"),
            None => "a power-of-two cluster count".into(),
        };
        Err(self.error(requirement, self.clusters_has()))
    }

    /// Usable scratchpad words per cluster: `words` for what the kernel keeps there, plus
    /// the words the machine reserves for conditional streams if the kernel has any.
    pub fn scratchpad_words(
        &self,
        words: usize,
        what: &str,
        conditional_streams: bool,
    ) -> Result<(), MachineRequirementError> {
        let reserved = if conditional_streams {
            2 * self.desc.srf.conditional_words_per_cycle
        } else {
            0
        };
        let have = self.desc.scratchpad.words;
        if have >= words + reserved {
            return Ok(());
        }
        let requirement = if reserved > 0 {
            format!(
                "{} scratchpad words per cluster ({words} for {what}, {reserved} kept for \
                 conditional streams)",
                words + reserved
            )
        } else {
            format!("{words} scratchpad words per cluster (for {what})")
        };
        Err(self.error(requirement, format!("{have} words")))
    }

    /// At least `n` condition-code registers per cluster.
    pub fn condition_codes(&self, n: usize, why: &str) -> Result<(), MachineRequirementError> {
        let have = self.desc.cluster.condition_codes;
        if have >= n {
            return Ok(());
        }
        Err(self.error(
            format!("at least {n} condition codes per cluster ({why})"),
            format!("{have} condition code{}", if have == 1 { "" } else { "s" }),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_kernel_requirement_and_machine() {
        let mut desc = MachineDesc::gold8();
        desc.cluster.count = 6;
        let e = Needs::new("assemble_clip", &desc)
            .power_of_two_clusters(None)
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "kernel `assemble_clip` needs a power-of-two cluster count (machine `gold8` has 6 clusters)"
        );
        desc.cluster.count = 64;
        let needs = Needs::new("sort32", &desc);
        assert!(needs.power_of_two_clusters(None).is_ok());
        let e = needs.power_of_two_clusters(Some(32)).unwrap_err();
        assert!(e.to_string().contains("up to 32"), "{e}");
        desc.scratchpad.words = 8;
        let e = Needs::new("hash", &desc)
            .scratchpad_words(32, "its stamp", true)
            .unwrap_err();
        assert!(
            e.to_string().contains("34 scratchpad words")
                && e.to_string().ends_with("has 8 words)"),
            "{e}"
        );
    }
}
