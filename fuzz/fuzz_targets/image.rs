//! Microcode images (`.imuc`) on gold8: `read_image` (which checks the program), then the
//! disassembly and a second image, which must read back the same.
#![no_main]

use imagine_fuzz::{EXAMPLE_PROGRAMS, every_op_program, gold8, write_seeds_if_asked};
use imagine_units::microcode::image::{read_image, write_image};
use imagine_units::microcode::{assemble, disassemble};
use libfuzzer_sys::fuzz_target;

fuzz_target!(init: write_seeds_if_asked(seeds), |data: &[u8]| {
    let desc = gold8();
    let Ok(program) = read_image(data, desc) else {
        return;
    };
    program.check(desc).expect("a read image checks");
    let _ = disassemble(&program, desc);
    let image = write_image(&program, desc);
    assert_eq!(read_image(&image, desc).unwrap(), program, "image round trip");
});

/// Images of the example programs and of [`every_op_program`], assembled for gold8.
fn seeds() -> Vec<(String, Vec<u8>)> {
    let every_op = every_op_program();
    EXAMPLE_PROGRAMS
        .iter()
        .map(|&(name, text)| (name, text))
        .chain([("every_op", every_op.as_str())])
        .map(|(name, text)| {
            let program = assemble(text, gold8()).expect("the seed programs assemble");
            (format!("{name}.imuc"), write_image(&program, gold8()))
        })
        .collect()
}
