//! Machine descriptions: `MachineDesc::parse` (which validates), then what the tools derive
//! from a description without building a machine (LRF names, instruction layout, DRAM map).
#![no_main]

use imagine_fuzz::text;
use imagine_units::desc::MachineDesc;
use imagine_units::dram::DramParams;
use imagine_units::microcode::InstructionLayout;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some(text) = text(data) else { return };
    let Ok(desc) = MachineDesc::parse(text, "fuzz.toml") else {
        return;
    };
    desc.validate().expect("a parsed description is valid");
    for name in desc.lrf_names() {
        assert!(desc.lrf_entries(&name) > 0);
    }
    let _ = InstructionLayout::new(&desc).describe();
    let p = DramParams::of(&desc);
    let _ = (p.capacity_bytes(), p.peak_bytes_per_s());
});
