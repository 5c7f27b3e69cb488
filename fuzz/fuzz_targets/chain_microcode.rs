//! The microcode chain: kernel text → `assemble` and check on gold8 → a run on the clocked
//! gold8 machine for a few thousand core cycles, each input stream given 64 words. A
//! program the checker accepts may time out or stop on a contract error, but nothing may
//! panic.
#![no_main]

use imagine_fuzz::{
    MAX_CYCLES, every_op_program, gold8, input_streams, text, write_seeds_if_asked,
};
use imagine_units::microcode::assemble;
use imagine_units::runner::{RunOptions, run_kernel};
use libfuzzer_sys::fuzz_target;

fuzz_target!(init: write_seeds_if_asked(seeds), |data: &[u8]| {
    let Some(text) = text(data) else { return };
    let desc = gold8();
    let Ok(program) = assemble(text, desc) else {
        return;
    };
    let inputs = input_streams(&program, 64);
    let options = RunOptions {
        max_cycles: MAX_CYCLES,
        ..RunOptions::default()
    };
    let _ = run_kernel(desc, &program, &inputs, options);
});

/// [`every_op_program`], which must assemble for gold8 (the example programs are copied
/// from `units/tests/microcode/`).
fn seeds() -> Vec<(String, Vec<u8>)> {
    let text = every_op_program();
    if let Err(e) = assemble(&text, gold8()) {
        panic!("the every-op seed does not assemble: {e}\n{text}");
    }
    vec![("every_op.uc".into(), text.into_bytes())]
}
