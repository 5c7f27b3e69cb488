//! Built-in microcode workloads for measuring the simulator itself.

use std::fmt::Write;

use crate::desc::MachineDesc;
use crate::microcode::Program;
use crate::microcode::asm::{AsmError, assemble};

/// A loop of `iterations` passes that keeps every arithmetic unit of every cluster busy:
/// each adder issues an `fadd` and each multiplier an `fmul` every cycle, and each
/// divide/sqrt unit an `fdiv` as often as its issue interval allows. The loop body is
/// `max(8, divsqrt_issue_interval)` instructions long; results go to LRF entries no op reads,
/// so nothing waits on anything.
pub fn compute_dense(desc: &MachineDesc, iterations: u32) -> Result<Program, AsmError> {
    let c = &desc.cluster;
    let interval = desc.latency.divsqrt_issue_interval as usize;
    let body = interval.max(8);
    let units: Vec<(String, &str)> = (0..c.adders)
        .map(|i| (format!("add{i}"), "fadd"))
        .chain((0..c.multipliers).map(|i| (format!("mul{i}"), "fmul")))
        .chain((0..c.divsqrt).map(|i| (format!("dsq{i}"), "fdiv")))
        .collect();
    let mut s = String::from("kernel compute_dense\n");
    // Operands: a = 1.5 + cluster-dependent bits would need more ops; constants suffice.
    for (unit, _) in &units {
        let _ = writeln!(s, "    imm 1.5 -> {unit}.a[0], {unit}.b[0]");
    }
    let _ = writeln!(s, "loop count {iterations}:");
    for i in 0..body {
        let slots: Vec<String> = units
            .iter()
            .filter(|(unit, _)| !unit.starts_with("dsq") || i % interval == 0)
            .map(|(unit, op)| format!("{unit} {op} a[0], b[0] -> {unit}.a[1]"))
            .collect();
        let _ = writeln!(s, "    {}", slots.join(" | "));
    }
    s.push_str("end\ndone\n");
    assemble(&s, desc)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runner::{RunOptions, run_kernel};

    #[test]
    fn compute_dense_keeps_every_unit_busy() {
        for name in ["gold8", "gold8+F", "gold1"] {
            let desc = MachineDesc::resolve(name).unwrap();
            let program = compute_dense(&desc, 50).unwrap();
            let run = run_kernel(&desc, &program, &[], RunOptions::default()).unwrap();
            let s = &run.stats;
            let body = desc.latency.divsqrt_issue_interval.max(8) as u64;
            let c = &desc.cluster;
            for (slot, &ops) in s.fu_ops.iter().enumerate() {
                let expected = if slot < c.adders + c.multipliers {
                    50 * body
                } else {
                    50 * body / desc.latency.divsqrt_issue_interval as u64
                };
                assert_eq!(ops, expected, "{name} slot {slot}");
            }
            // The loop runs back to back; only the set-up and the drain add cycles.
            assert!(s.cycles < 50 * body + 64, "{name}: {s:?}");
            // One stage: a pass per iteration.
            assert_eq!(s.loop_passes, 50, "{name}");
        }
    }
}
