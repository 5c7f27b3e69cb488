//! Microcode text on gold8: `assemble` (which checks the program against the machine).
//! An assembled program must survive the round trips the tests rely on: disassembled and
//! assembled again, encoded and decoded, written as an image and read back.
#![no_main]

use imagine_fuzz::{every_op_program, gold8, text, write_seeds_if_asked};
use imagine_units::microcode::image::{read_image, write_image};
use imagine_units::microcode::{InstructionLayout, assemble, disassemble};
use libfuzzer_sys::fuzz_target;

fuzz_target!(init: write_seeds_if_asked(seeds), |data: &[u8]| {
    let Some(text) = text(data) else { return };
    let desc = gold8();
    let Ok(program) = assemble(text, desc) else {
        return;
    };
    program.check(desc).expect("an assembled program checks");
    let listing = disassemble(&program, desc);
    let again = assemble(&listing, desc)
        .unwrap_or_else(|e| panic!("the disassembly does not assemble: {e}\n{listing}"));
    assert_eq!(again, program, "text round trip\n{listing}");
    let layout = InstructionLayout::new(desc);
    for ins in &program.code {
        assert_eq!(&layout.decode(&layout.encode(ins)).unwrap(), ins);
    }
    let image = write_image(&program, desc);
    assert_eq!(
        read_image(&image, desc).unwrap(),
        program,
        "image round trip"
    );
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
