//! VCD files written by the tool read back with an independent parser, show the design's
//! hierarchy, and (with the `gtkwave` feature) are accepted by GTKWave's `vcd2fst`.

use std::collections::BTreeSet;
use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs `imagine ARGS... --vcd DIR/out.vcd` in a fresh directory and returns the VCD path.
fn run_with_vcd(name: &str, args: &[&str]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("imagine-vcd-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let vcd = dir.join("out.vcd");
    let o = Command::new(env!("CARGO_BIN_EXE_imagine"))
        .args(args)
        .arg("--vcd")
        .arg(&vcd)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    vcd
}

fn demo_vcd(name: &str, extra: &[&str]) -> PathBuf {
    let args: Vec<&str> = ["demo"].iter().chain(extra).copied().collect();
    run_with_vcd(name, &args)
}

/// Checks `vcd` with GTKWave's own converter.
#[cfg(feature = "gtkwave")]
fn assert_gtkwave_accepts(vcd: &Path) {
    let fst = vcd.with_extension("fst");
    let o = Command::new("vcd2fst")
        .arg(vcd)
        .arg(&fst)
        .output()
        .expect("vcd2fst is installed");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(std::fs::metadata(&fst).unwrap().len() > 0);
}

/// Every variable's full hierarchical path.
fn var_paths(path: &Path) -> BTreeSet<String> {
    let mut parser = vcd::Parser::new(BufReader::new(File::open(path).unwrap()));
    let header = parser.parse_header().unwrap();
    let mut out = BTreeSet::new();
    fn walk(items: &[vcd::ScopeItem], prefix: &str, out: &mut BTreeSet<String>) {
        for item in items {
            match item {
                vcd::ScopeItem::Scope(s) => {
                    walk(&s.items, &format!("{prefix}{}.", s.identifier), out)
                }
                vcd::ScopeItem::Var(v) => {
                    out.insert(format!("{prefix}{}", v.reference));
                }
                _ => {}
            }
        }
    }
    walk(&header.items, "", &mut out);
    out
}

#[test]
fn demo_vcd_shows_the_design_hierarchy() {
    let vcd = demo_vcd("hier", &["--cycles", "2000"]);
    let vars = var_paths(&vcd);
    for want in [
        "top.clk_core",
        "top.clk_dram",
        "top.source.lfsr",
        "top.mac.s1.valid",
        "top.mac.s2.pp_lo",
        "top.mac.s4.acc",
        "top.out.write_level",
        "top.sink.checksum",
        "top.monitor.count",
    ] {
        assert!(vars.contains(want), "{want} missing from {vars:?}");
    }
    assert!(vcd.with_extension("gtkw").exists());
}

#[test]
fn scope_filter_keeps_only_matching_modules_and_clocks() {
    let vcd = demo_vcd("scope", &["--cycles", "500", "--vcd-scope", "top.sink"]);
    let vars = var_paths(&vcd);
    assert!(
        vars.contains("top.sink.count") && vars.contains("top.clk_dram"),
        "{vars:?}"
    );
    assert!(!vars.iter().any(|v| v.starts_with("top.mac")), "{vars:?}");
}

#[cfg(feature = "gtkwave")]
#[test]
fn gtkwave_accepts_the_demo_vcd() {
    assert_gtkwave_accepts(&demo_vcd("fst", &["--cycles", "100000"]));
}

fn kernel_vcd(name: &str, program: &str, inputs: &[&str]) -> PathBuf {
    let file = format!(
        "{}/units/tests/microcode/{program}.uc",
        env!("CARGO_MANIFEST_DIR")
    );
    let mut args = vec!["kernel", "run", &file];
    for i in inputs {
        args.extend(["--input", i]);
    }
    run_with_vcd(name, &args)
}

#[test]
fn machine_vcd_shows_units_registers_streams_and_sequencer() {
    let x: Vec<String> = (0..64).map(|i| i.to_string()).collect();
    let vcd = kernel_vcd("machine", "prefix_sum", &[&format!("x={}", x.join(","))]);
    let vars = var_paths(&vcd);
    for want in [
        // per cluster and unit: opcode, operands, result
        "top.cluster3.add0.op",
        "top.cluster3.add0.a",
        "top.cluster3.add0.b",
        "top.cluster3.add0.result",
        "top.cluster7.mul1.result",
        "top.cluster0.dsq0.core.quotient",
        // LRF writes
        "top.cluster3.lrf.add0_a.we",
        "top.cluster3.lrf.add0_a.wdata",
        "top.lrf.add0_a.write_addr",
        // scratchpad and comm traffic
        "top.cluster3.sp0.addr",
        "top.cluster3.comm0.source",
        "top.cluster3.comm0.data",
        // stream buffers and the microcontroller
        "top.srf.sb0.level",
        "top.srf.arbiter.grant",
        "top.uc.pc",
        "top.uc.pass",
        "top.uc.loop_depth",
    ] {
        assert!(vars.contains(want), "{want} missing");
    }
}

#[cfg(feature = "gtkwave")]
#[test]
fn gtkwave_accepts_a_machine_vcd() {
    let x: Vec<String> = (0..64).map(|i| i.to_string()).collect();
    let vcd = kernel_vcd(
        "machine-fst",
        "prefix_sum",
        &[&format!("x={}", x.join(","))],
    );
    assert_gtkwave_accepts(&vcd);
}

/// The values (as text, a Verilog string right-justified in its bits) the variable
/// `name` of scope `scope` took.
/// The commands after the header, each parsed with its declared width.
fn value_changes(path: &Path) -> usize {
    let mut parser = vcd::Parser::new(BufReader::new(File::open(path).unwrap()));
    parser.parse_header().unwrap();
    parser
        .inspect(|command| assert!(command.is_ok(), "{command:?}"))
        .count()
}

fn text_values(path: &Path, scope: &str, name: &str) -> BTreeSet<String> {
    let mut parser = vcd::Parser::new(BufReader::new(File::open(path).unwrap()));
    let header = parser.parse_header().unwrap();
    let var = header
        .find_var(&[scope, name].concat().split('.').collect::<Vec<_>>())
        .unwrap_or_else(|| panic!("{scope}{name} missing"));
    let code = var.code;
    let mut out = BTreeSet::new();
    for cmd in parser {
        if let vcd::Command::ChangeVector(c, bits) = cmd.unwrap()
            && c == code
        {
            let bytes: Vec<u8> = bits
                .iter()
                .collect::<Vec<_>>()
                .chunks(8)
                .map(|b| {
                    b.iter()
                        .fold(0u8, |a, &v| (a << 1) | u8::from(v == vcd::Value::V1))
                })
                .filter(|&b| b != 0)
                .collect();
            out.insert(String::from_utf8(bytes).unwrap());
        }
    }
    out
}

#[test]
fn a_render_waveform_names_its_kernels_and_decodes_coded_fields() {
    let vcd = run_with_vcd(
        "render-names",
        &[
            "render",
            "RATE-1",
            "--size",
            "16",
            "--vcd-scope",
            "top.sc",
            "--vcd-scope",
            "top.uc",
            "--vcd-scope",
            "top.mem.ch0*",
        ],
    );
    // The running kernel and the issued stream instruction, as text.
    let kernels = text_values(&vcd, "top.sc.", "kernel");
    assert!(
        kernels.contains("xyrast") && kernels.contains("vertex_unlit"),
        "{kernels:?}"
    );
    let issued = text_values(&vcd, "top.sc.", "issue");
    assert!(
        issued.contains("kernel xyrast") && issued.contains("load"),
        "{issued:?}"
    );
    // The save file: the control path first, text as ASCII, DRAM commands by name.
    let gtkw = std::fs::read_to_string(vcd.with_extension("gtkw")).unwrap();
    let at = |s: &str| {
        gtkw.find(s)
            .unwrap_or_else(|| panic!("`{s}` missing:\n{gtkw}"))
    };
    assert!(at("-top.uc") < at("-top.mem.ch0") && at("-top.sc") < at("-top.mem.ch0"));
    assert!(gtkw.contains("@820\ntop.sc.kernel[191:0]"), "{gtkw}");
    let cmd = at("top.mem.ch0.cmd[2:0]");
    let filter_line = gtkw[..cmd].lines().last().unwrap();
    let file = filter_line.split_once(' ').unwrap().1;
    assert!(filter_line.starts_with('^'), "{filter_line}");
    let names = std::fs::read_to_string(file).unwrap();
    assert!(
        names.contains("1 ACT\n") && names.contains("4 PRE\n"),
        "{names}"
    );
}

#[test]
fn a_kernel_call_is_dumped_by_name_and_a_waveform_over_its_limit_stops_the_run() {
    // Call 2 of `xyrast`: the dump's running kernel is xyrast (or nothing, as it ends).
    let vcd = run_with_vcd(
        "render-kernel",
        &[
            "render",
            "RATE-1",
            "--size",
            "16",
            "--vcd-scope",
            "top.sc",
            "--vcd-kernel",
            "xyrast",
            "--vcd-call",
            "2",
        ],
    );
    let kernels = text_values(&vcd, "top.sc.", "kernel");
    assert!(kernels.contains("xyrast"), "{kernels:?}");
    assert!(
        kernels.iter().all(|k| k == "xyrast" || k.is_empty()),
        "{kernels:?}"
    );

    let dir = vcd.parent().unwrap();
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_imagine"))
            .args(["render", "RATE-1", "--size", "16", "--vcd"])
            .arg(dir.join("limit.vcd"))
            .args(args)
            .output()
            .unwrap()
    };
    let o = run(&["--vcd-max-bytes", "20K"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("--vcd-max-bytes is 20.0 kB"),
        "{err}"
    );
    assert!(std::fs::metadata(dir.join("limit.vcd")).unwrap().len() < 200_000);
    let o = run(&["--vcd-kernel", "nosuch"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("it calls") && err.contains("xyrast"),
        "{err}"
    );
}

#[test]
fn an_s3_waveform_through_the_dram_shows_the_memory_blocks_and_reads_back_whole() {
    let dir =
        std::env::temp_dir().join(format!("imagine-vcd-{}-s3-dram-trace", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let trace = dir.join("s3.tri");
    std::fs::write(
        &trace,
        "48 32\n0 0 0.5 1 0 0  47 0 0.5 0 1 0  24 31 0.5 0 0 1\n\
         4 4 0.25 0 1 1  30 4 0.25 1 1 0  12 28 0.25 1 0 1\n\
         20 2 0.75 0 0 1  46 8 0.75 1 1 1  30 30 0.75 0 1 0\n",
    )
    .unwrap();
    let vcd = run_with_vcd(
        "s3-dram",
        &[
            "s3",
            "--trace",
            trace.to_str().unwrap(),
            "--accelerators",
            "2",
            "--memory",
            "dram",
        ],
    );
    let paths = var_paths(&vcd);
    for want in [
        "top.s3.fbdram.reads",
        "top.s3.fbdram.outbox",
        "top.s3.fbdram.in_flight",
        "top.s3.accel1.mem_stall",
        "top.s3.accel1.unacked_writes",
        "top.s3.accel1.mem_ack.valid",
        "top.mem.ch0.cmd",
        "top.mem.ch3.cmd",
    ] {
        assert!(paths.contains(want), "`{want}` missing");
    }
    let changes = value_changes(&vcd);
    assert!(changes > 1_000, "{changes}");
}

#[test]
fn an_s3_waveform_shows_every_block_and_reads_back_whole() {
    let vcd = run_with_vcd(
        "s3",
        &[
            "s3",
            "--trace",
            "game-sky",
            "--accelerators",
            "4",
            "--vcd-window",
            "0:3000",
        ],
    );
    let paths = var_paths(&vcd);
    for want in [
        "top.s3.host.sent",
        "top.s3.fetch.order",
        "top.s3.command_queue.level",
        "top.s3.issue.rs_valid",
        "top.s3.issue.cause",
        "top.s3.issue.cand31.dep",
        "top.s3.issue.cand31.conflict",
        "top.s3.accel3.phase",
        "top.s3.accel3.pipe.s2_zcompare_blend",
        "top.s3.accel3.mem_req.valid",
        "top.s3.fbmem.writes",
    ] {
        assert!(paths.contains(want), "`{want}` missing");
    }
    // Every value change parses, with the declared widths.
    let changes = value_changes(&vcd);
    assert!(changes > 10_000, "{changes}");
    #[cfg(feature = "gtkwave")]
    assert_gtkwave_accepts(&vcd);
}
