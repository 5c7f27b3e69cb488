//! GTKWave's own tools accept the dump (`cargo test -p imagine-waves --features gtkwave`;
//! needs `vcd2fst` and `fst2vcd` from the gtkwave package on the PATH).

#![cfg(feature = "gtkwave")]

mod common;

use std::process::Command;

use common::{read, temp_dir};
use imagine_hdl::default_domains;
use imagine_hdl::demo::{self, DemoConfig};
use imagine_waves::{VcdOptions, VcdWriter};

#[test]
fn vcd2fst_converts_a_demo_dump_and_fst2vcd_gives_it_back() {
    let dir = temp_dir("gtkwave");
    let vcd = dir.join("demo.vcd");
    let fst = dir.join("demo.fst");
    let mut sim = demo::build(default_domains(), DemoConfig::default()).unwrap();
    sim.attach(Box::new(
        VcdWriter::create(&vcd, &VcdOptions::default()).unwrap(),
    ))
    .unwrap();
    sim.run_core_cycles(5000, |_| {}).unwrap();
    sim.finish().unwrap();

    let out = Command::new("vcd2fst")
        .arg(&vcd)
        .arg(&fst)
        .output()
        .expect("vcd2fst runs (apt-get install gtkwave)");
    assert!(
        out.status.success(),
        "vcd2fst: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(std::fs::metadata(&fst).unwrap().len() > 0);

    // Back to VCD through GTKWave's FST reader: the same signals and value changes.
    let back = Command::new("fst2vcd")
        .arg(&fst)
        .output()
        .expect("fst2vcd runs");
    assert!(
        back.status.success(),
        "fst2vcd: {}",
        String::from_utf8_lossy(&back.stderr)
    );
    let ours = read(&std::fs::read(&vcd).unwrap());
    let theirs = vcd::Parser::new(&back.stdout[..]).parse_header().unwrap();
    for path in ours.vars.keys() {
        let parts: Vec<&str> = path.split('.').collect();
        let v = theirs
            .find_var(&parts)
            .unwrap_or_else(|| panic!("{path} in fst2vcd output"));
        assert_eq!(v.size, ours.vars[path].width, "{path}");
    }
}
