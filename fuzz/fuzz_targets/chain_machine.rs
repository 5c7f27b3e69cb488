//! The machine chain: a description's text → `MachineDesc::parse` (and `validate`) →
//! one of the hand-written microcode programs of `units/tests/microcode/` assembled and
//! checked for it → the machine built from the description runs it for a few thousand core
//! cycles. Programs that do not fit the machine (too few units, LRF entries or streams) are
//! refused by the assembler; the run may time out or stop on a contract error, but nothing
//! may panic.
#![no_main]

use imagine_fuzz::{EXAMPLE_PROGRAMS, MAX_CYCLES, input_streams, text};
use imagine_units::desc::MachineDesc;
use imagine_units::microcode::assemble;
use imagine_units::runner::{RunOptions, run_kernel};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some(text) = text(data) else { return };
    let Ok(desc) = MachineDesc::parse(text, "fuzz.toml") else {
        return;
    };
    let (_, source) = EXAMPLE_PROGRAMS[data.len() % EXAMPLE_PROGRAMS.len()];
    let Ok(program) = assemble(source, &desc) else {
        return;
    };
    let inputs = input_streams(&program, 16 * desc.cluster.count);
    let options = RunOptions {
        max_cycles: MAX_CYCLES,
        ..RunOptions::default()
    };
    let _ = run_kernel(&desc, &program, &inputs, options);
});
