//! The command line: help, clear errors with non-zero exits, and the demo's report.

use std::process::{Command, Output};

/// Runs the CLI with its compile cache under the target directory (never the user's).
fn imagine(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_imagine"))
        .env(
            "IMAGINE_CACHE_DIR",
            concat!(env!("CARGO_TARGET_TMPDIR"), "/compile-cache"),
        )
        .args(args)
        .output()
        .expect("run imagine")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A run that fails with an `error:` message, not a panic.
fn assert_clear_error(args: &[&str]) {
    let o = imagine(args);
    let err = stderr(&o);
    assert!(!o.status.success(), "{args:?} succeeded");
    assert!(err.contains("error"), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn help_lists_every_subcommand() {
    let o = imagine(&["--help"]);
    assert!(o.status.success());
    let out = stdout(&o);
    for sub in [
        "render", "verify", "kernel", "machine", "scene", "dram", "demo", "s3",
    ] {
        assert!(out.contains(sub), "`{sub}` missing from help:\n{out}");
    }
    let o = imagine(&["demo", "--help"]);
    assert!(stdout(&o).contains("--vcd-window"), "{}", stdout(&o));
}

#[test]
fn bad_arguments_are_errors_not_panics() {
    for args in [
        &["demo", "--cycles", "lots"][..],
        &["no-such-command"],
        &["demo", "--vcd-window", "5:3", "--vcd", "x.vcd"],
        &["demo", "--vcd-window", "a:b", "--vcd", "x.vcd"],
        &["demo", "--core-mhz", "0"],
        &["demo", "--core-mhz", "99999999999999"],
        &["demo", "--crossing-capacity", "0"],
        &["machine", "show", "gold9"],
        &["machine", "show", "/nonexistent/m.toml"],
    ] {
        assert_clear_error(args);
    }
}

#[test]
fn unwritable_vcd_is_a_clear_error() {
    let o = imagine(&[
        "demo",
        "--cycles",
        "10",
        "--vcd",
        "/nonexistent-dir/out.vcd",
    ]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.starts_with("error:") && err.contains("/nonexistent-dir/out.vcd"),
        "{err}"
    );
}

#[test]
fn vcd_options_need_a_vcd_file() {
    let o = imagine(&["demo", "--cycles", "10", "--vcd-scope", "top.mac"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--vcd"), "{}", stderr(&o));
}

#[test]
fn demo_reports_a_result_matching_its_model() {
    let o = imagine(&["demo", "--cycles", "30000"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("core cycles        30000"), "{out}");
    // 30000 core cycles at 500 MHz are 10020 DRAM cycles at 167 MHz (edges 0..=10019).
    assert!(out.contains("dram cycles        10020"), "{out}");
    assert!(out.contains("results match the behavioural model"), "{out}");
}

fn imagine_with_stdin(args: &[&str], input: &str) -> Output {
    use std::io::Write;
    let mut child = Command::new(env!("CARGO_BIN_EXE_imagine"))
        .args(args)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run imagine");
    child
        .stdin
        .take()
        .unwrap()
        .write_all(input.as_bytes())
        .unwrap();
    child.wait_with_output().unwrap()
}

#[test]
fn verify_fpu_passes_committed_softfloat_vectors() {
    let vectors = include_str!("../units/tests/vectors/f32_div.txt");
    let o = imagine_with_stdin(&["verify", "fpu", "f32_div"], vectors);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let lines = vectors.lines().count();
    assert!(
        stdout(&o)
            .trim_end()
            .ends_with(&format!("{lines} passed, 0 failed")),
        "{}",
        stdout(&o)
    );
}

#[test]
fn verify_fpu_reports_mismatches_and_fails() {
    // 1 + 2 = 3 exactly: the second line's expected result and flags are wrong.
    let o = imagine_with_stdin(
        &["verify", "fpu", "f32_add"],
        "3F800000 40000000 40400000 00\n3F800000 40000000 40400001 01\n",
    );
    assert!(!o.status.success());
    let out = stdout(&o);
    assert!(out.contains("line 2") && out.contains("40400001"), "{out}");
    assert!(out.trim_end().ends_with("1 passed, 1 failed"), "{out}");
}

#[test]
fn verify_fpu_rejects_malformed_input_and_unknown_ops() {
    let o = imagine_with_stdin(
        &["verify", "fpu", "f32_sqrt"],
        "3F800000 3F800000 00\n12345 3F800000\n",
    );
    assert!(!o.status.success());
    assert!(stderr(&o).contains("line 2"), "{}", stderr(&o));
    let o = imagine_with_stdin(&["verify", "fpu", "f64_add"], "");
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("f64_add") && stderr(&o).contains("f32_add"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn machine_list_and_show_describe_every_builtin() {
    let o = imagine(&["machine", "list"]);
    assert!(o.status.success());
    let list = stdout(&o);
    for name in [
        "gold8",
        "gold1",
        "gold2",
        "gold4",
        "gold16",
        "gold32",
        "gold8+F",
        "gold8+C",
        "gold8+F+C",
        "gold8+srf4x",
        "gold32combo",
        "gold32combo+tc1",
        "gold32combo+tc4",
        "gold32combo+tc32",
        "gold8+hwrast",
        "reyes",
        "reyes400",
    ] {
        assert!(
            list.lines()
                .any(|l| l.split_whitespace().next() == Some(name)),
            "{name} missing:\n{list}"
        );
        let o = imagine(&["machine", "show", name]);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        let first = stdout(&o).lines().next().unwrap_or("").to_string();
        assert!(
            first.split_whitespace().take(2).eq(["machine", name]),
            "{}",
            stdout(&o)
        );
    }
    let show = stdout(&imagine(&["machine", "show", "gold8+F"]));
    assert!(show.contains("6 adders, 4 multipliers"), "{show}");
    let show = stdout(&imagine(&["machine", "show", "gold32combo+tc4"]));
    assert!(
        show.contains("texture cache") && show.contains("hit_words_per_cycle 4"),
        "{show}"
    );
    let show = stdout(&imagine(&["machine", "show", "gold8+hwrast"]));
    assert!(
        show.contains("rasterizer") && show.contains("latency 100 core cycles"),
        "{show}"
    );
}

/// `machine show` prints every section of the description, and every key of the sections
/// whose values are not plain counts (latency, dram, memory, stream controller) as the
/// file names it, beside its value.
#[test]
fn machine_show_prints_every_section_of_the_description() {
    let gold8 = concat!(env!("CARGO_MANIFEST_DIR"), "/machines/gold8.toml");
    for (machine, file, wants) in [
        (
            "gold8",
            gold8,
            &[
                "core 500 MHz",
                "DRAM 167 MHz",
                "8 × (3 adders, 2 multipliers, 1 divide/sqrt unit, 1 scratchpad",
                "16 condition codes",
                "fp32 subnormals kept",
                "17 per cluster, 304 entries",
                "add0.a       32 entries",
                "256 words (1024 bytes) per scratchpad",
                "32768 words (128 KB), 8 banks, 32-word blocks, 16 words/cycle, 22 stream buffers",
                "4 stream words/cycle unconditional, 1 conditional",
                "2048 instructions of microcode store, loops nested 4 deep",
                "4 channels × 4 banks × 4096 rows × 256 columns",
                "peak 2.67 GB/s",
                "min_kernel_cycles 300 core cycles",
            ][..],
        ),
        (
            "unfamiliar",
            UNFAMILIAR_MACHINE,
            &[
                "core 400 MHz",
                "6 × (2 adders, 3 multipliers",
                "8 condition codes",
                "flushed to zero",
                "24 entries each, 48 in the large ones (add0.a, mul2.b)",
                "512 words",
                "16384 words (64 KB), 4 banks, 16-word blocks",
            ][..],
        ),
    ] {
        let o = imagine(&["machine", "show", file]);
        assert!(o.status.success(), "{machine}: {}", stderr(&o));
        let out = stdout(&o);
        for section in [
            "machine",
            "clocks",
            "cluster",
            "arithmetic",
            "latency",
            "lrf",
            "scratchpad",
            "srf",
            "microcontroller",
            "dram",
            "memory",
            "stream controller",
            "s3",
        ] {
            assert!(
                out.lines().any(|l| l.starts_with(&format!("{section}  "))),
                "{machine}: section `{section}` missing:\n{out}"
            );
        }
        for want in wants {
            assert!(out.contains(want), "{machine}: `{want}` missing:\n{out}");
        }
        // Every key of these sections, by its name in the file, with its value (the DRAM's
        // geometry is printed as `4 channels × 4 banks × …`).
        let text = std::fs::read_to_string(file).unwrap();
        let mut section = String::new();
        let mut keys = 0;
        for line in text.lines() {
            let line = line.split('#').next().unwrap().trim();
            if let Some(name) = line.strip_prefix('[') {
                section = name.trim_end_matches(']').to_string();
            } else if let Some((key, value)) = line.split_once('=')
                && ["latency", "dram", "memory", "stream_controller", "s3"]
                    .contains(&section.as_str())
                && !["channels", "banks", "rows", "columns"].contains(&key.trim())
            {
                let want = format!("{} {}", key.trim(), value.trim().trim_matches('"'));
                assert!(out.contains(&want), "{machine}: `{want}` missing:\n{out}");
                keys += 1;
            }
        }
        assert!(keys >= 25, "{machine}: {keys} keys checked");
    }
}

fn temp(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("imagine-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

const MADD: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/units/tests/microcode/madd.uc");

#[test]
fn kernel_asm_disasm_round_trip() {
    let image = temp("madd.imuc");
    let o = imagine(&["kernel", "asm", MADD, "-o", image.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("kernel `madd`"), "{}", stdout(&o));
    let from_image = imagine(&["kernel", "disasm", image.to_str().unwrap()]);
    let from_text = imagine(&["kernel", "disasm", MADD]);
    assert!(from_image.status.success(), "{}", stderr(&from_image));
    assert_eq!(stdout(&from_image), stdout(&from_text));
    assert!(
        stdout(&from_image).contains("fmul a[0], b[0]"),
        "{}",
        stdout(&from_image)
    );
    // An image is tied to its machine's instruction layout.
    let o = imagine(&[
        "kernel",
        "disasm",
        image.to_str().unwrap(),
        "--machine",
        "gold8+F",
    ]);
    assert!(
        !o.status.success() && stderr(&o).contains("gold8+F"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn kernel_run_prints_output_streams_and_cycles() {
    let o = imagine(&[
        "kernel",
        "run",
        MADD,
        "--format",
        "f32",
        "--input",
        "x=1.0,2.0,3.0,4.0,5.0,6.0,7.0,8.0",
        "--input",
        "y=2.0,2.0,2.0,2.0,2.0,2.0,2.0,2.0",
        "--input",
        "w=0.5,0.5,0.5,0.5,0.5,0.5,0.5,0.5",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("z (8 words):"), "{out}");
    assert!(out.contains("2.5 4.5 6.5 8.5 10.5 12.5 14.5 16.5"), "{out}");
    assert!(out.contains("cycles "), "{out}");
}

/// With `--format f32` a decimal integer input is the float it names: madd's
/// `x·y + w` of 10, 1 and 0.5 is 10.5 (it read 10 as the bit pattern 10, a subnormal, and
/// printed 0.5). Hex stays a bit pattern; the range errors stay.
#[test]
fn kernel_run_reads_integers_as_floats_in_f32_format() {
    let run = |format: &str, x: &str| {
        imagine(&[
            "kernel",
            "run",
            MADD,
            "--format",
            format,
            "--input",
            &format!("x={x},2,3,4,5,6,7,8"),
            "--input",
            "y=1,1,1,1,1,1,1,1",
            "--input",
            "w=0.5,0.5,0.5,0.5,0.5,0.5,0.5,0.5",
        ])
    };
    let o = run("f32", "10");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("10.5 2.5 3.5 4.5 5.5 6.5 7.5 8.5"),
        "{}",
        stdout(&o)
    );
    let o = run("f32", "0x41200000");
    assert!(stdout(&o).contains("  10.5 2.5"), "{}", stdout(&o));
    let o = run("f32", "-10");
    assert!(stdout(&o).contains("  -9.5 2.5"), "{}", stdout(&o));
    // The other formats read integers as integers, as before.
    let o = run("hex", "10");
    assert!(stdout(&o).contains("  3f000000 "), "{}", stdout(&o));
    for (x, want) in [
        (
            "99999999999999999999999999999999999999999",
            "beyond the range of fp32",
        ),
        ("1e-50", "rounds to zero"),
    ] {
        let o = run("f32", x);
        assert!(
            !o.status.success() && stderr(&o).contains(want),
            "{}",
            stderr(&o)
        );
    }
}

#[test]
fn kernel_errors_name_the_problem() {
    let bad = temp("bad.uc");
    std::fs::write(
        &bad,
        "kernel k\nin x\nout y\n    add0 fmul a[0], b[0]\ndone\n",
    )
    .unwrap();
    let o = imagine(&["kernel", "asm", bad.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("4:") && stderr(&o).contains("fmul"),
        "{}",
        stderr(&o)
    );
    let o = imagine(&["kernel", "run", MADD, "--input", "x=1,2"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("`y`"), "{}", stderr(&o));
    let o = imagine(&[
        "kernel",
        "run",
        MADD,
        "--input",
        "x=1,2,3,4,5,6,7",
        "--input",
        "y=1",
        "--input",
        "w=1",
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("multiple of the 8 clusters"),
        "{}",
        stderr(&o)
    );
    let o = imagine(&["kernel", "run", MADD, "--input", "x=1,zz"]);
    assert!(
        !o.status.success() && stderr(&o).contains("`zz`"),
        "{}",
        stderr(&o)
    );
}

fn temp_file(name: &str, contents: impl AsRef<[u8]>) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("imagine-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, contents).unwrap();
    p
}

#[test]
fn dram_replays_a_trace_and_reports_its_statistics() {
    let trace = temp_file(
        "ok.trace",
        "0x0 READ 0\n0x4 READ 0\n0x1000 WRITE 3\n0x8 READ 5\n",
    );
    let o = imagine(&["dram", "--trace", trace.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    for key in [
        "bandwidth",
        "finish cycle",
        "data bus",
        "row hits",
        "ACT",
        "PRE",
        "READ 3",
        "WRITE 1",
        "read latency",
        "no violations",
    ] {
        assert!(out.contains(key), "`{key}` missing:\n{out}");
    }
}

#[test]
fn dram_bench_json_reaches_peak_on_unit_stride_reads() {
    let o = imagine(&[
        "dram",
        "--bench",
        "unit-load",
        "--requests",
        "4096",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let frac: f64 = out
        .lines()
        .find(|l| l.contains("\"fraction_of_peak\""))
        .and_then(|l| l.split(':').nth(1))
        .map(|v| v.trim().trim_end_matches(',').parse().unwrap())
        .expect("fraction_of_peak in the JSON");
    assert!(frac >= 0.95, "{out}");
    assert!(out.contains("\"timing_violations\": 0"), "{out}");
    let o = imagine(&[
        "dram",
        "--bench",
        "random",
        "--requests",
        "512",
        "--policy",
        "all",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    for p in ["in-order", "first-ready", "row-closed", "load-over-store"] {
        assert!(stdout(&o).contains(p), "{}", stdout(&o));
    }
}

#[test]
fn dram_writes_a_trace_that_replays() {
    let dir = std::env::temp_dir().join(format!("imagine-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let rec = dir.join("rec.trace");
    let o = imagine(&[
        "dram",
        "--bench",
        "unit",
        "--requests",
        "256",
        "--dram-trace",
        rec.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&rec).unwrap();
    assert_eq!(text.lines().count(), 256);
    let o = imagine(&["dram", "--trace", rec.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("(256 requests)"), "{}", stdout(&o));
}

#[test]
fn dram_bad_input_names_the_line() {
    for (text, want) in [
        ("0x0 READ 4\n0x4 READ 2\n", "line 2"),
        ("0x0 READ 0\nnonsense\n", "line 2"),
        ("0x0 FETCH 0\n", "line 1"),
        ("0xfffffffff READ 0\n", "out of range"),
    ] {
        let t = temp_file("bad.trace", text);
        let o = imagine(&["dram", "--trace", t.to_str().unwrap()]);
        let err = stderr(&o);
        assert!(!o.status.success(), "{text:?} succeeded");
        assert!(
            err.starts_with("error:") && err.contains(want),
            "{text:?}: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    }
    let t = temp_file("one.trace", "0x0 READ 0\n");
    for args in [
        &[
            "dram",
            "--trace",
            t.to_str().unwrap(),
            "--policy",
            "fastest",
        ][..],
        &["dram", "--bench", "sequential"],
        &["dram", "--trace", "/nonexistent/x.trace"],
        &["dram"],
        &["dram", "--bench", "unit", "--machine", "gold9"],
    ] {
        assert_clear_error(args);
    }
}

#[test]
fn dram_serves_and_counts_every_request() {
    let one = temp_file("readme.trace", "0x1f40 READ 12\n");
    let spread = temp_file("spread.trace", "0x0 READ 5\n0x40 WRITE 50\n0x80 READ 100\n");
    for (args, want) in [
        // Presented at 12, ACTIVATE at 15, READ at 18, its word at 21.
        (
            &["dram", "--trace", one.to_str().unwrap()][..],
            &["(1 requests)", "finish cycle   21", "READ 1  WRITE 0"][..],
        ),
        (
            &["dram", "--trace", spread.to_str().unwrap()],
            &["(3 requests)", "READ 2  WRITE 1"],
        ),
        (
            &["dram", "--bench", "unit-load", "--requests", "7"],
            &["(7 requests)", "READ 7  WRITE 0"],
        ),
    ] {
        let o = imagine(args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        for w in want {
            assert!(
                stdout(&o).contains(w),
                "{args:?}: `{w}` missing:\n{}",
                stdout(&o)
            );
        }
    }
}

#[test]
fn dram_jumps_over_a_trillion_idle_cycles() {
    let t = temp_file("gap.trace", "0x0 READ 5\n0x40 READ 1000000000000\n");
    let o = imagine(&["dram", "--trace", t.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    // The second read as after any idle time (9 cycles from presentation to its word);
    // 4 channels × ⌊(10^12 + 9) / 2604⌋ refreshes, all on time.
    for w in [
        "(2 requests)",
        "finish cycle   1000000000009",
        "READ 2",
        "REF 1536098308",
        "no violations",
    ] {
        assert!(out.contains(w), "`{w}` missing:\n{out}");
    }
}

#[test]
fn dram_hostile_traces_are_clear_errors_naming_file_and_line() {
    let past = imagine_units::dram::trace::MAX_TRACE_CYCLE + 1;
    let cases: [(&str, Vec<u8>, &[&str]); 14] = [
        (
            "cap",
            b"0x0 READ 1\n0x4000000 READ 2\n".to_vec(),
            &["line 2", "out of range", "67108864 bytes"],
        ),
        (
            "addr",
            b"0xfffffffffffffffffff READ 1\n".to_vec(),
            &["line 1", "out of range"],
        ),
        (
            "word",
            b"0x0 READ soon\n".to_vec(),
            &["line 1", "`soon` is not a cycle number"],
        ),
        (
            "neg",
            b"0x0 READ -4\n".to_vec(),
            &["line 1", "not negative"],
        ),
        (
            "late",
            format!("0x0 READ {past}\n").into_bytes(),
            &["line 1", "past the latest"],
        ),
        (
            "huge",
            b"0x0 READ 123456789012345678901234567890\n".to_vec(),
            &["line 1", "past the latest"],
        ),
        (
            "dec",
            b"0x0 READ 9\n0x4 READ 8\n".to_vec(),
            &["line 2", "must not decrease"],
        ),
        (
            "op",
            b"0x0 PREFETCH 1\n".to_vec(),
            &["line 1", "`PREFETCH` is not a request type"],
        ),
        (
            "fields",
            b"0x0 READ 1 0x4\n".to_vec(),
            &["line 1", "3 fields", "found 4"],
        ),
        ("empty", Vec::new(), &["no requests"]),
        ("comments", b"# nothing yet\n\n".to_vec(), &["no requests"]),
        (
            "binary",
            vec![0x7f, 0x45, 0x4c, 0x46, 0x02, 0x01, 0xff, 0xfe, 0x00, b'\n'],
            &["line 1", "not UTF-8"],
        ),
        (
            "nul",
            b"0x0 READ 1\n\0\0\0\0\n".to_vec(),
            &["line 2", "3 fields"],
        ),
        (
            "long",
            vec![b'7'; 100_000],
            &["line 1", "longer than 4096 bytes"],
        ),
    ];
    for (name, contents, want) in cases {
        let t = temp_file(&format!("hostile-{name}.trace"), contents);
        let o = imagine(&["dram", "--trace", t.to_str().unwrap()]);
        let err = stderr(&o);
        assert!(!o.status.success(), "{name}: succeeded");
        assert!(err.starts_with("error:"), "{name}: {err}");
        assert!(
            err.contains(&format!("hostile-{name}.trace")),
            "{name}: {err}"
        );
        for w in want {
            assert!(err.contains(w), "{name}: `{w}` missing: {err}");
        }
        assert!(!err.contains("panicked"), "{name}: {err}");
    }
    let limit = imagine_units::dram::trace::MAX_TRACE_REQUESTS.to_string();
    let over = (imagine_units::dram::trace::MAX_TRACE_REQUESTS + 1).to_string();
    for (n, want) in [
        ("0", &["--requests 0", limit.as_str()][..]),
        (over.as_str(), &["--requests", limit.as_str()]),
        ("18446744073709551615", &["--requests", limit.as_str()]),
        ("many", &["--requests", "invalid value"]),
        ("99999999999999999999999", &["--requests", "too large"]),
    ] {
        let o = imagine(&["dram", "--bench", "unit", "--requests", n]);
        let err = stderr(&o);
        assert!(!o.status.success(), "--requests {n}: succeeded");
        assert!(err.starts_with("error:"), "--requests {n}: {err}");
        for w in want {
            assert!(err.contains(w), "--requests {n}: `{w}` missing: {err}");
        }
        assert!(!err.contains("panicked"), "{err}");
    }
    // The help states the limits the parser applies.
    let help = stdout(&imagine(&["dram", "--help"]));
    assert!(help.contains(&limit), "{help}");
    assert!(
        help.contains(&imagine_units::dram::trace::MAX_TRACE_CYCLE.to_string()),
        "{help}"
    );
}

#[test]
fn dram_vcd_is_deterministic_and_has_the_memory_signals() {
    let dir = std::env::temp_dir().join(format!("imagine-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let run = |name: &str| {
        let vcd = dir.join(name);
        // The header's `$date` is the wall clock unless SOURCE_DATE_EPOCH fixes it.
        let o = Command::new(env!("CARGO_BIN_EXE_imagine"))
            .env("SOURCE_DATE_EPOCH", "1798675200")
            .args([
                "dram",
                "--bench",
                "constrained-random",
                "--requests",
                "300",
                "--policy",
                "row-closed",
                "--vcd",
                vcd.to_str().unwrap(),
            ])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::read_to_string(vcd).unwrap()
    };
    let (a, b) = (run("a.vcd"), run("b.vcd"));
    assert_eq!(a, b, "same inputs, same waveform");
    assert!(
        a.contains("2026-12-31 00:00:00 UTC"),
        "the $date SOURCE_DATE_EPOCH gives"
    );
    for sig in ["queue_depth", "decision", "cmd_row", "state", "row", "dq"] {
        assert!(a.contains(&format!(" {sig} ")), "`{sig}` missing");
    }
}

#[test]
fn kernel_library_list_show_check() {
    let o = imagine(&["kernel", "list"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    for name in [
        "transform",
        "vertex",
        "turbulence",
        "marble",
        "prefix_sum",
        "compact",
        "hash_xy",
        "sort32_keys",
        "merge",
    ] {
        assert!(
            out.lines()
                .any(|l| l.split_whitespace().next() == Some(name)),
            "{out}"
        );
    }
    let o = imagine(&["kernel", "show", "transform", "--machine", "gold8"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(
        out.contains("II 8 (bound 8: ResMII 8 set by multipliers"),
        "{out}"
    );
    assert!(
        out.contains("schedule (op/stage)") && out.contains("fmul/"),
        "{out}"
    );
    // `check` names the interval, its bound and the rate as `show` does, word for word.
    let interval = out.lines().find(|l| l.starts_with("II ")).unwrap();
    let interval = &interval[..interval.find(" ops/cycle").unwrap() + " ops/cycle".len()];
    let o = imagine(&["kernel", "check", "transform", "--machine", "gold8"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains(interval),
        "`{interval}`: {}",
        stdout(&o)
    );
    let o = imagine(&[
        "kernel",
        "show",
        "prefix_sum",
        "--machine",
        "gold1",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(json["kernel"], "prefix_sum");
    assert_eq!(json["machine"], "gold1");
    assert!(json["ii"].as_u64().unwrap() >= json["rec_mii"].as_u64().unwrap());
    let o = imagine(&["kernel", "check", "compact", "--machine", "gold8", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(json[0]["pass"], true);
    assert!(json[0]["words"].as_u64().unwrap() > 0);
    // The same keys as `show --json` for the same quantities.
    let o = imagine(&["kernel", "show", "compact", "--machine", "gold8", "--json"]);
    let shown: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    for key in ["ii", "res_mii", "res_limit", "rec_mii", "ops_per_cycle"] {
        assert_eq!(json[0][key], shown[key], "{key}");
    }
    let o = imagine(&["kernel", "check", "sort32_keys", "--machine", "gold32"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("sort32_keys: pass on gold32"),
        "{}",
        stdout(&o)
    );
    for command in ["show", "check"] {
        let o = imagine(&["kernel", command, "nope"]);
        assert_clear_error(&["kernel", command, "nope"]);
        let err = stderr(&o);
        // The error lists the valid names: the library's and the pipeline's.
        assert!(
            err.contains("no kernel `nope`")
                && err.contains("transform")
                && err.contains("xyrast")
                && err.contains("compact_recycle:z,colour"),
            "{err}"
        );
    }
}

/// The names of SPHERE's kernel breakdown (`render SPHERE`, `kernels built`): the kernels
/// `kernel list` lists as its pipeline's by default.
const SPHERE_KERNELS: [&str; 16] = [
    "perbegin:vertex_lit3_s16",
    "perlight:vertex_lit3_s16",
    "vertex_lit3_s16",
    "assemble_clip",
    "viewport_cull",
    "baryprep",
    "xyprep",
    "xyrast",
    "irast",
    "hash",
    "zcompare",
    "compact_recycle:z,colour",
    "compact_recycle:addr,prim",
    "clear",
    "sort32",
    "mergefrag",
];

/// `kernel list|show|check` take the pipeline's kernels by the render's names. Compiling
/// every one takes too long for a debug test (the vertex program, `assemble_clip`, `sort32`
/// and `mergefrag` take seconds each): those are shown and checked by hand in a release
/// build (`for k in $(imagine kernel list --json | ...)`); the rest are checked here.
#[test]
fn kernel_list_show_check_take_the_pipelines_kernels() {
    let o = imagine(&["kernel", "list", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let list: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let pipeline: Vec<&str> = list
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["in_pipeline"] == true)
        .map(|e| e["name"].as_str().unwrap())
        .collect();
    assert_eq!(
        pipeline, SPHERE_KERNELS,
        "SPHERE's kernels, in the render's order"
    );
    let text = stdout(&imagine(&["kernel", "list"]));
    for name in SPHERE_KERNELS {
        assert!(
            text.lines()
                .any(|l| l.split_whitespace().next() == Some(name)),
            "{name} missing:\n{text}"
        );
    }

    let o = imagine(&["kernel", "show", "xyrast"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(
        out.starts_with("kernel xyrast on gold8 (8 clusters)"),
        "{out}"
    );
    assert!(out.contains("render SPHERE"), "{out}");
    let ii = out.lines().find(|l| l.starts_with("II ")).unwrap();
    assert!(ii.contains("(bound ") && ii.contains("ops/cycle"), "{out}");
    assert!(out.contains("schedule (op/stage)"), "{out}");
    // Its II is the one `check` names.
    let ii = &ii[..ii.find(" ops/cycle").unwrap()];
    let o = imagine(&["kernel", "check", "xyrast"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(
        out.starts_with("xyrast: pass on gold8") && out.contains(ii),
        "{out}"
    );

    let slow = [
        "vertex_lit3_s16",
        "assemble_clip",
        "hash",
        "sort32",
        "mergefrag",
    ];
    for name in SPHERE_KERNELS
        .iter()
        .filter(|n| !slow.contains(n) && **n != "xyrast")
    {
        let o = imagine(&["kernel", "check", name, "--rows", "2"]);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        assert!(
            stdout(&o).starts_with(&format!("{name}: pass on gold8")),
            "{}",
            stdout(&o)
        );
    }
    // A kernel's own name (the one its microcode carries) selects each of its kind.
    let o = imagine(&["kernel", "check", "compact_recycle", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let checked: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let names: Vec<&str> = checked
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["kernel"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        ["compact_recycle:z,colour", "compact_recycle:addr,prim"]
    );
    let o = imagine(&["kernel", "show", "perbegin", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let shown: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(shown["kernel"], "perbegin:vertex_lit3_s16");
    assert_eq!(shown["source"], "pipeline");

    // Another scene's pipeline: its own kernels, built for it.
    let o = imagine(&["kernel", "list", "--scene", "MARBLE", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("\"fragment:marble\""), "{}", stdout(&o));
    let o = imagine(&["kernel", "show", "fragment:marble"]);
    assert!(!o.status.success(), "SPHERE has no marble");
    assert!(
        stderr(&o).contains("no kernel `fragment:marble`"),
        "{}",
        stderr(&o)
    );
    assert_clear_error(&["kernel", "list", "--scene", "TEAPOT-9"]);
    assert_clear_error(&["kernel", "show", "xyrast", "--size", "0"]);
}

#[test]
fn render_rejects_bad_scenes_with_a_clear_error() {
    let dir = std::env::temp_dir().join(format!("imagine-render-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.tri");
    std::fs::write(&bad, "8 8\n0 0 0.5 1 1 1  8 0 nan 1 1 1  0 8 0.5 1 1 1\n").unwrap();
    for (args, want) in [
        (vec!["render", bad.to_str().unwrap()], "line 2"),
        (vec!["render", "TEAPOT-9"], "unknown scene"),
        (
            vec!["render", "RATE-3"],
            "unknown scene: the built-in scenes are SPHERE, RATE-1",
        ),
        (vec!["render", "SPHERE", "--size", "0"], "--size"),
        (vec!["render", "SPHERE", "--batch", "0"], "--batch"),
        (vec!["scene", "show", "PIN", "--batch", "70000"], "--batch"),
    ] {
        assert_clear_error(&args);
        let err = stderr(&imagine(&args));
        assert!(err.contains(want), "{args:?}: {err}");
    }
}

/// `render --dram-trace` writes the frame's DRAM requests, which `dram --untimed` replays
/// with no computation: the trace moves the frame's DRAM bytes, and faster than the frame
/// did with its computation in between (Table 5.6's trace bandwidth).
#[test]
fn a_frames_dram_trace_replays_faster_untimed() {
    let dir = std::env::temp_dir().join(format!("imagine-dram-trace-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (trace, stats) = (dir.join("f.trace"), dir.join("f.json"));
    let (trace_s, stats_s) = (trace.to_str().unwrap(), stats.to_str().unwrap());
    let o = imagine(&[
        "render",
        "RATE-8",
        "--size",
        "32",
        "--dram-trace",
        trace_s,
        "--stats",
        stats_s,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let frame: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    let frame_gbs = frame["frame"]["dram_gbs"].as_f64().unwrap();
    let replay = |extra: &[&str]| {
        let mut args = vec!["dram", "--trace", trace_s, "--json"];
        args.extend(extra);
        let o = imagine(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
        json["runs"][0].clone()
    };
    let untimed = replay(&["--untimed"]);
    let requests = std::fs::read_to_string(&trace).unwrap().lines().count() as u64;
    assert!(requests > 0);
    assert_eq!(untimed["requests"].as_u64(), Some(requests));
    assert_eq!(
        untimed["bytes"].as_u64(),
        frame["frame"]["dram_bytes"].as_u64(),
        "the trace holds the frame's DRAM words, one request each"
    );
    let untimed_gbs = untimed["bandwidth_gbs"].as_f64().unwrap();
    assert!(untimed_gbs > frame_gbs, "{untimed_gbs} against {frame_gbs}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn render_writes_png_and_stats() {
    let dir = std::env::temp_dir().join(format!("imagine-render-ok-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("f.png");
    let stats = dir.join("f.json");
    let (png_s, stats_s) = (png.to_str().unwrap(), stats.to_str().unwrap());
    // A compile cache of its own, empty: the first render compiles every kernel and the
    // second reads them all back.
    let cache = dir.join("cache");
    let _ = std::fs::remove_dir_all(&cache);
    let render = || {
        let out = Command::new(env!("CARGO_BIN_EXE_imagine"))
            .env("IMAGINE_CACHE_DIR", &cache)
            .args([
                "render", "RATE-8", "--size", "32", "--png", png_s, "--stats", stats_s,
            ])
            .output()
            .expect("run imagine");
        assert!(out.status.success(), "{}", stderr(&out));
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
        (out, json, std::fs::read(&png).unwrap())
    };
    let (cold, cold_json, cold_png) = render();
    let programs = cold_json["frame"]["kernel_programs"].as_u64().unwrap();
    assert!(programs > 0);
    assert_eq!(cold_json["frame"]["kernels_from_cache"], 0);
    assert!(
        stdout(&cold).contains(&format!("0 of {programs} kernels from the cache")),
        "{}",
        stdout(&cold)
    );
    let (warm, warm_json, warm_png) = render();
    assert_eq!(warm_json["frame"]["kernels_from_cache"], programs);
    assert!(
        stdout(&warm).contains(&format!("{programs} of {programs} kernels from the cache")),
        "{}",
        stdout(&warm)
    );
    assert_eq!(
        cold_png, warm_png,
        "the cached microcode draws the same frame"
    );
    assert_eq!(cold_json["frame"]["cycles"], warm_json["frame"]["cycles"]);
    assert!(std::fs::metadata(&png).unwrap().len() > 0);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert_eq!(json["frame"]["fragments"], 32 * 32);
    assert_eq!(json["reference_error"]["coverage_mismatch_share"], 0.0);
    // gold8 has 17 LRFs of one read and one write port in each of 8 clusters.
    for field in ["lrf_reads_per_cycle", "lrf_writes_per_cycle"] {
        let words = json["frame"][field].as_f64().unwrap();
        assert!(words > 0.0 && words <= 17.0 * 8.0, "{field} = {words}");
    }
}

#[test]
fn scene_list_names_every_builtin() {
    let o = imagine(&["scene", "list"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let list = stdout(&o);
    for name in [
        "SPHERE",
        "RATE-1",
        "RATE-2",
        "RATE-4",
        "RATE-8",
        "RATE-16",
        "RATE-32",
        "RATE-64",
        "RATE-128",
        "SPHERE-FULL",
        "ADVS-1",
        "ADVS-8",
        "PIN",
        "PIN-8",
        "MARBLE",
        "VERONA",
    ] {
        let line = list
            .lines()
            .find(|l| l.split_whitespace().next() == Some(name))
            .unwrap_or_else(|| panic!("{name} missing:\n{list}"));
        assert!(
            line.len() > name.len() + 10,
            "{name} has no description: {line}"
        );
    }
}

#[test]
fn scene_show_describes_sphere() {
    let o = imagine(&["scene", "show", "SPHERE"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    for want in [
        "scene        SPHERE",
        "SPHERE.toml",
        "720 × 720",
        "cull back",
        "lights       3",
        "blue-grey: lit",
        "shininess 16",
        "245,760 vertices, 81,920 triangles (separate)",
        "world space",
        "1 objects, 245,760 vertices, 81,920 triangles, 0 textures",
    ] {
        assert!(out.contains(want), "`{want}` missing:\n{out}");
    }
    let o = imagine(&["scene", "show", "rate-8", "--size", "64", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["window"]["width"], 64);
    assert_eq!(v["totals"]["triangles"], 512);
    assert_eq!(v["objects"][0]["space"], "window");
}

#[test]
fn scene_show_errors_name_the_file() {
    let o = imagine(&["scene", "show", "nope.toml"]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(err.contains("error") && err.contains("nope.toml"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    let bad = temp_file(
        "bad-scene.toml",
        "[window]\nwidth = 64\nheight = \"tall\"\n",
    );
    let o = imagine(&["scene", "show", bad.to_str().unwrap()]);
    let err = stderr(&o);
    assert!(!o.status.success());
    assert!(
        err.contains("bad-scene.toml") && err.contains("window.height") && err.contains("line 3"),
        "{err}"
    );
    assert_clear_error(&["scene", "show", "TEAPOT-9"]);
}

/// A machine file derived from gold8 with `table` (TOML) laid over it.
fn machine_file(name: &str, table: &str) -> std::path::PathBuf {
    temp_file(
        &format!("{name}.toml"),
        format!("name = \"{name}\"\nbase = \"gold8\"\n{table}"),
    )
}

/// Machines the kernels cannot serve are refused before anything is compiled: a clear
/// error naming the kernel and what it needs, never a panic.
#[test]
fn machine_shapes_the_kernels_cannot_serve_are_named() {
    for (name, table, render_wants, check_wants) in [
        (
            "c6",
            "[cluster]\ncount = 6",
            "kernel `assemble_clip` needs a power-of-two cluster count (machine `c6` has 6 clusters)",
            "kernel `turbulence` needs a cluster count dividing the 256 entries",
        ),
        (
            "c12",
            "[cluster]\ncount = 12",
            "kernel `assemble_clip` needs a power-of-two cluster count (machine `c12` has 12 clusters)",
            "kernel `turbulence` needs a cluster count dividing the 256 entries",
        ),
        (
            "c64",
            "[cluster]\ncount = 64",
            "kernel `sort32` needs a power-of-two cluster count up to 32 (machine `c64` has 64 clusters)",
            "kernel `sort32_keys` needs a power-of-two cluster count up to 32 (machine `c64` has 64 clusters)",
        ),
        (
            "cc1",
            "[cluster]\ncondition_codes = 1",
            "kernel `sort32` needs at least 9 condition codes",
            "condition codes per cluster",
        ),
        (
            "sp16",
            "[scratchpad]\nwords = 16",
            "kernel `xyrast` needs 27 scratchpad words",
            "kernel `turbulence` needs 256 scratchpad words",
        ),
    ] {
        let file = machine_file(name, table);
        let file = file.to_str().unwrap();
        for (args, want) in [
            (
                vec!["render", "RATE-8", "--size", "64", "--machine", file],
                render_wants,
            ),
            (
                vec!["kernel", "check", "all", "--machine", file],
                check_wants,
            ),
        ] {
            let start = std::time::Instant::now();
            let o = imagine(&args);
            let err = stderr(&o);
            assert!(!o.status.success(), "{args:?} succeeded");
            assert!(
                err.starts_with("error:") && err.contains(want) && err.contains("kernel `"),
                "{args:?}: {err}"
            );
            assert!(!err.contains("panicked"), "{args:?}: {err}");
            assert!(o.stdout.is_empty(), "{args:?}: {}", stdout(&o));
            assert!(
                start.elapsed().as_secs() < 20,
                "{args:?} took {:?}",
                start.elapsed()
            );
        }
    }
}

/// The description itself refuses what the model cannot hold, naming the file and the key.
#[test]
fn machine_shapes_the_model_cannot_hold_name_the_file_and_key() {
    for (name, table, key) in [
        ("c0", "[cluster]\ncount = 0", "cluster.count"),
        ("c257", "[cluster]\ncount = 257", "cluster.count"),
        ("nocomm", "[cluster]\ncomm_units = 0", "cluster.comm_units"),
        ("noadd", "[cluster]\nadders = 0", "cluster.adders"),
        (
            "cc0",
            "[cluster]\ncondition_codes = 0",
            "cluster.condition_codes",
        ),
        (
            "ks65",
            "[srf]\nkernel_streams = 65\nstream_buffers = 80",
            "srf.kernel_streams",
        ),
    ] {
        let file = machine_file(name, table);
        let file = file.to_str().unwrap();
        for args in [
            vec!["machine", "show", file],
            vec!["render", "RATE-8", "--size", "64", "--machine", file],
        ] {
            assert_clear_error(&args);
            let err = stderr(&imagine(&args));
            assert!(err.contains(file) && err.contains(key), "{args:?}: {err}");
        }
    }
}

#[test]
fn render_reports_its_pipeline_and_one_csv_row_per_batch() {
    let dir = std::env::temp_dir().join(format!("imagine-render-csv-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (csv, stats, timeline) = (dir.join("b.csv"), dir.join("s.json"), dir.join("t.json"));
    let o = imagine(&[
        "render",
        "RATE-4",
        "--size",
        "32",
        "--stats-csv",
        csv.to_str().unwrap(),
        "--stats",
        stats.to_str().unwrap(),
        "--timeline",
        timeline.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    let frame = &json["frame"];
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert!(
        lines
            .next()
            .unwrap()
            .starts_with("batch,object,triangles,vertices,cycles")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len() as u64, frame["batches"].as_u64().unwrap());
    let sum = |col: usize| {
        rows.iter()
            .map(|r| r[col].parse::<u64>().unwrap())
            .sum::<u64>()
    };
    assert_eq!(
        sum(2),
        frame["triangles"].as_u64().unwrap(),
        "triangles per batch add up"
    );
    assert_eq!(
        sum(6),
        frame["fragments"].as_u64().unwrap(),
        "fragments per batch add up"
    );
    assert!(
        sum(5) > 0 && sum(9) > 0,
        "kernel cycles and DRAM words are counted"
    );
    // The attribution: every frame cycle in one category, in the JSON and per batch.
    let attribution = frame["attribution"].as_object().unwrap();
    let attributed: u64 = attribution.values().map(|v| v.as_u64().unwrap()).sum();
    assert_eq!(attributed, frame["cycles"].as_u64().unwrap());
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("where cycles went") && out.contains("kernels running"),
        "{out}"
    );
    let timeline: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&timeline).unwrap()).unwrap();
    assert!(timeline["traceEvents"].as_array().unwrap().len() > 10);
    // `compare`: a copy whose frame took twice the cycles shows that difference first.
    let mut doubled = json.clone();
    doubled["frame"]["cycles"] = (2 * frame["cycles"].as_u64().unwrap()).into();
    let other = dir.join("s2.json");
    std::fs::write(&other, doubled.to_string()).unwrap();
    let (a, b) = (stats.to_str().unwrap(), other.to_str().unwrap());
    let compared = imagine(&["compare", a, b, "--json"]);
    assert!(compared.status.success(), "{}", stderr(&compared));
    let cmp: serde_json::Value = serde_json::from_slice(&compared.stdout).unwrap();
    let first = &cmp["rows"][0];
    assert_eq!(
        (first["name"].as_str(), first["ratio"].as_f64()),
        (Some("cycles"), Some(2.0))
    );
    assert_eq!(cmp["rows"][1]["ratio"].as_f64(), Some(1.0));
    assert_clear_error(&["compare", a, csv.to_str().unwrap()]);
    // An unlit scene: no lighting kernel built, the merge stage never reached.
    let sp = &frame["specialisation"];
    let built: Vec<&str> = sp["kernels_built"]
        .as_array()
        .unwrap()
        .iter()
        .map(|k| k.as_str().unwrap())
        .collect();
    assert!(
        built
            .iter()
            .all(|k| !k.contains("lit") || k.contains("unlit")),
        "{built:?}"
    );
    assert!(
        built
            .iter()
            .all(|k| !["noise", "turbulence", "texture", "filter"]
                .iter()
                .any(|w| k.contains(w))),
        "{built:?}"
    );
    assert!(
        sp["left_out"]
            .as_array()
            .unwrap()
            .iter()
            .any(|f| f == "lighting")
    );
    assert!(stdout(&o).contains("left out"), "{}", stdout(&o));
    let phases = &frame["phases"];
    assert_eq!(
        phases["frame_plus_clear_cycles"].as_u64().unwrap(),
        frame["cycles"].as_u64().unwrap() + phases["clear_cycles"].as_u64().unwrap()
    );
}

#[test]
fn scene_show_plans_the_pipeline_the_scene_gets() {
    let o = imagine(&["scene", "show", "SPHERE"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    for want in [
        "vertex_lit3_s16",
        "perlight",
        "SRF plan",
        "(elastic)",
        "64 triangles per batch",
    ] {
        assert!(out.contains(want), "`{want}` missing:\n{out}");
    }
    let o = imagine(&["scene", "show", "RATE-8", "--size", "64", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let kernels = v["plan"]["kernels"].as_array().unwrap();
    assert!(kernels.iter().any(|k| k == "vertex_unlit"));
    assert!(
        v["plan"]["left_out"]
            .as_array()
            .unwrap()
            .iter()
            .any(|k| k == "lighting")
    );
    let o = imagine(&["scene", "show", "SPHERE", "--machine", "gold1"]);
    assert!(stdout(&o).contains("on gold1"), "{}", stdout(&o));
}

/// A reader that stops early (`| head -1`) ends the output quietly: no panic, nothing on
/// stderr.
#[cfg(unix)]
#[test]
fn output_into_a_closed_pipe_ends_quietly() {
    use std::io::Read;
    use std::process::Stdio;
    for args in [
        &["scene", "show", "SPHERE", "--json"][..],
        &["kernel", "show", "vertex", "--microcode"][..],
    ] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_imagine"))
            .env(
                "IMAGINE_CACHE_DIR",
                concat!(env!("CARGO_TARGET_TMPDIR"), "/compile-cache"),
            )
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("run imagine");
        let mut first = [0u8; 1];
        child.stdout.take().unwrap().read_exact(&mut first).unwrap();
        // The read end is closed here (dropped); the rest of the output hits a closed pipe.
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(err.is_empty(), "{args:?}: {err}");
    }
}

/// A machine description written to differ from every built-in one in sizes, latencies,
/// clocks and DRAM timings.
const UNFAMILIAR_MACHINE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/verif/tests/machines/unfamiliar.toml"
);

#[test]
fn verify_lists_and_runs_every_block() {
    let out = stdout(&imagine(&["verify", "list"]));
    let listed = out.lines().count();
    for block in [
        "lrf",
        "scratchpad",
        "fu",
        "fpu",
        "alu",
        "ccfile",
        "comm",
        "cdc",
        "sdram",
        "scheduler",
        "address_gen",
        "srf",
        "scoreboard",
    ] {
        assert!(out.contains(block), "{out}");
    }
    for machine in ["gold1", UNFAMILIAR_MACHINE] {
        let o = imagine(&[
            "verify",
            "all",
            "--machine",
            machine,
            "--transactions",
            "200",
        ]);
        let out = stdout(&o);
        assert!(o.status.success(), "{out}");
        let summary = format!("{listed} passed, 0 failed");
        assert!(out.trim_end().ends_with(&summary), "{out}");
    }
    let o = imagine(&["verify", "comm", "--machine", "gold8", "--seed", "3"]);
    assert!(
        o.status.success() && stdout(&o).contains("PASS"),
        "{}",
        stdout(&o)
    );
    // The fpu block testbench is `verify fpu` without an op.
    let o = imagine(&[
        "verify",
        "fpu",
        "--machine",
        "gold32",
        "--transactions",
        "300",
    ]);
    assert!(
        o.status.success() && stdout(&o).contains("op f32_sqrt"),
        "{}",
        stdout(&o)
    );
    let o = imagine(&["verify", "all", "--transactions", "100", "--json"]);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(json["failed"], 0);
    assert_eq!(json["blocks"].as_array().unwrap().len(), listed);
}

#[test]
fn verify_writes_no_waveform_when_nothing_fails() {
    let dir = std::env::temp_dir().join(format!("imagine-cli-vcd-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let vcd = dir.join("fail.vcd");
    let o = imagine(&[
        "verify",
        "all",
        "--transactions",
        "100",
        "--vcd-on-fail",
        vcd.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stdout(&o));
    let written: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert!(written.is_empty(), "{written:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn verify_refuses_bad_blocks_machines_and_counts() {
    assert_clear_error(&["verify", "nosuch"]);
    assert_clear_error(&["verify", "lrf", "--transactions", "0"]);
    assert_clear_error(&["verify", "all", "--machine", "nosuch"]);
    assert_clear_error(&["verify", "cdc", "--seed", "x"]);
    assert_clear_error(&["verify", "lrf", "--vcd-on-fail", "fail.txt"]);
    assert_clear_error(&["verify", "all", "--vcd-on-fail", "/no/such/dir/fail.vcd"]);
    assert_clear_error(&["verify", "fpu", "--ftz"]);
}

/// Every argument and option of the `kernel` and `machine` subcommands says what it does.
#[test]
fn kernel_and_machine_options_all_have_help() {
    for [command, sub] in [
        ["kernel", "asm"],
        ["kernel", "disasm"],
        ["kernel", "run"],
        ["kernel", "list"],
        ["kernel", "show"],
        ["kernel", "check"],
        ["machine", "list"],
        ["machine", "show"],
        ["machine", "bench"],
    ] {
        let o = imagine(&[command, sub, "--help"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let out = stdout(&o);
        // An argument's line (`  -o, --output <OUTPUT>`) says what it does beside it, or,
        // when the help is long, on the more indented lines under it.
        let lines: Vec<&str> = out.lines().collect();
        let indent = |l: &str| l.len() - l.trim_start().len();
        let mut arguments = 0;
        for (i, l) in lines.iter().enumerate() {
            let t = l.trim_start();
            if indent(l) <= 6 && (t.starts_with('-') || t.starts_with('<')) {
                arguments += 1;
                let beside = t
                    .split_once("  ")
                    .is_some_and(|(_, h)| !h.trim().is_empty());
                let under = lines
                    .get(i + 1)
                    .is_some_and(|n| !n.trim().is_empty() && indent(n) > indent(l));
                let described = beside || under;
                assert!(described, "{command} {sub}: `{t}` has no help:\n{out}");
            }
        }
        assert!(
            arguments >= 1,
            "{command} {sub}: no arguments found:\n{out}"
        );
    }
}

/// A small `.tri` trace: a big triangle under a fan of small ones, with equal depths.
fn s3_trace() -> std::path::PathBuf {
    let mut text = String::from("# S3 test trace\n96 80\n");
    text += "0 0 0.5 1 0 0  95 0 0.5 0 1 0  48 79 0.5 0 0 1\n";
    for i in 0..24 {
        let x = 4.0 + 3.5 * i as f32;
        let z = if i % 3 == 0 { 0.5 } else { 0.25 };
        text += &format!(
            "{x} 10 {z} 0 1 1  {} 10 {z} 1 1 0  {} 30 {z} 1 0 1\n",
            x + 9.0,
            x + 4.0
        );
    }
    temp_file("s3.tri", text)
}

#[test]
fn s3_runs_a_trace_with_json_csv_png_and_speedup() {
    let trace = s3_trace();
    let (json, csv, png) = (temp("s3.json"), temp("s3.csv"), temp("s3.png"));
    let o = imagine(&[
        "s3",
        "--trace",
        trace.to_str().unwrap(),
        "--accelerators",
        "4",
        "--speedup",
        "--json",
        json.to_str().unwrap(),
        "--csv",
        csv.to_str().unwrap(),
        "--png",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("identical to in-order drawing"), "{out}");
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let tlp = j["mean_parallelism"].as_f64().unwrap();
    assert!(tlp > 1.0 && tlp <= 4.0, "{j}");
    assert!(j["speedup_over_k1"].as_f64().unwrap() > 1.0, "{j}");
    assert_eq!(j["triangles"], 25);
    assert_eq!(j["accelerators"], 4);
    for key in ["cycles", "issue_cycles", "busy_histogram", "k1_cycles"] {
        assert!(!j[key].is_null(), "{key} missing: {j}");
    }
    let csv = std::fs::read_to_string(&csv).unwrap();
    assert!(csv.starts_with("cycle,mean_busy_accelerators\n0,"), "{csv}");
    assert!(std::fs::metadata(&png).unwrap().len() > 100);
}

#[test]
fn s3_sweeps_k_and_dumps_every_block_to_vcd() {
    let trace = s3_trace();
    let t = trace.to_str().unwrap();
    let o = imagine(&["s3", "--trace", t, "--sweep", "1,2,4", "--no-split"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert_eq!(
        out.lines()
            .filter(|l| l.trim_start().starts_with(['1', '2', '4']))
            .count(),
        3,
        "{out}"
    );
    let vcd = temp("s3.vcd");
    let o = imagine(&[
        "s3",
        "--trace",
        t,
        "--accelerators",
        "2",
        "--vcd",
        vcd.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&vcd).unwrap();
    for scope in [
        "host", "fetch", "issue", "accel0", "accel1", "fbmem", "cand0", "pipe",
    ] {
        assert!(
            text.contains(&format!("$scope module {scope} $end")),
            "{scope} missing"
        );
    }
}

#[test]
fn s3_through_the_dram_draws_the_same_frame_slower_and_reports_the_dram() {
    let trace = s3_trace();
    let t = trace.to_str().unwrap();
    let mut runs = Vec::new();
    for memory in ["ideal", "dram"] {
        let json = temp(&format!("s3-{memory}.json"));
        let png = temp(&format!("s3-{memory}.png"));
        let o = imagine(&[
            "s3",
            "--trace",
            t,
            "--accelerators",
            "4",
            "--memory",
            memory,
            "--json",
            json.to_str().unwrap(),
            "--png",
            png.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(
            stdout(&o).contains(&format!("{memory} memory")),
            "{}",
            stdout(&o)
        );
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        assert_eq!(j["memory"], memory, "{j}");
        runs.push((j, std::fs::read(&png).unwrap()));
    }
    let ((ideal, ideal_png), (dram, dram_png)) = (&runs[0], &runs[1]);
    assert_eq!(
        ideal_png, dram_png,
        "the two memories drew different frames"
    );
    assert!(
        ideal["dram"].is_null() && ideal["memory_stall_cycles"] == 0,
        "{ideal}"
    );
    assert!(
        dram["cycles"].as_u64().unwrap() > ideal["cycles"].as_u64().unwrap(),
        "{dram}"
    );
    assert!(dram["memory_stall_cycles"].as_u64().unwrap() > 0, "{dram}");
    let d = &dram["dram"];
    assert_eq!(d["channels"], 4, "{d}");
    for key in ["reads", "writes", "activates", "row_hits", "dram_cycles"] {
        assert!(d[key].as_u64().unwrap() > 0, "{key}: {d}");
    }
    // A Z access is two DRAM words.
    assert!(
        d["reads"].as_u64().unwrap() >= 2 * ideal["pixels"].as_u64().unwrap(),
        "{d}"
    );
}

#[test]
fn s3_bad_input_is_a_clear_error() {
    let trace = s3_trace();
    let t = trace.to_str().unwrap();
    let bad = temp_file("s3-bad.tri", "10 10\n1 2 3\n");
    for args in [
        &["s3", "--trace", "no-such-trace"][..],
        &["s3", "--trace", "/nonexistent/x.tri"],
        &["s3", "--trace", bad.to_str().unwrap()],
        &["s3", "--trace", t, "--accelerators", "0"],
        &["s3", "--trace", t, "--accelerators", "65"],
        &["s3", "--trace", t, "--window", "0"],
        &["s3", "--trace", t, "--sweep", "1,0"],
        &["s3", "--trace", t, "--csv-window", "0"],
        &["s3", "--trace", t, "--machine", "gold9"],
        &["s3", "--trace", t, "--memory", "sram"],
    ] {
        assert_clear_error(args);
    }
}

/// `imagine kernel` takes the Reyes pipeline's kernels by their breakdown's names: `shade`
/// checks against its interpretation, the list names every kernel, a textured scene's
/// fragment program checks too, and gold8 (whose scratchpad is too small for `subdiv`)
/// checks `shade` but refuses `subdiv`, saying why.
#[test]
fn kernel_takes_the_reyes_pipelines_kernels() {
    let reyes = [
        "--scene",
        "TEAPOT-20",
        "--pipeline",
        "reyes",
        "--machine",
        "reyes",
    ];
    let o = imagine(&[&["kernel", "list"], &reyes[..]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    for name in [
        "project",
        "subdiv_split",
        "subdiv",
        "perlight",
        "shade",
        "sample",
    ] {
        assert!(
            stdout(&o).lines().any(|l| l.trim_start().starts_with(name)),
            "{name}: {}",
            stdout(&o)
        );
    }
    let o = imagine(&[&["kernel", "check", "shade"], &reyes[..]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("shade: pass on reyes"),
        "{}",
        stdout(&o)
    );
    for kernel in ["texaddr", "fragment"] {
        let o = imagine(&[
            "kernel",
            "check",
            kernel,
            "--scene",
            "PIN-PATCHES",
            "--pipeline",
            "reyes",
            "--machine",
            "reyes",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(stdout(&o).contains(&format!("{kernel}: pass on reyes")));
    }
    let gold8 = ["--scene", "TEAPOT-20", "--pipeline", "reyes"];
    let o = imagine(&[&["kernel", "check", "shade"], &gold8[..]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("shade: pass on gold8"));
    let o = imagine(&[&["kernel", "check", "subdiv"], &gold8[..]].concat());
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("kernel `subdiv` needs 504 scratchpad words"),
        "{}",
        stderr(&o)
    );
    let o = imagine(&[&["kernel", "list"], &gold8[..]].concat());
    assert!(
        stdout(&o)
            .lines()
            .any(|l| l.contains("subdiv") && l.contains("refused on gold8")),
        "{}",
        stdout(&o)
    );
    let o = imagine(&["kernel", "list", "--stop-length", "2"]);
    assert!(stderr(&o).contains("--stop-length is for the Reyes pipeline"));
}

/// `imagine bench` on a tiny scene: a cold compile that takes longer than the cache read,
/// the same cycles in every warm run (it checks that itself), rates worked out from the
/// times it reports, and the build it ran on named in the table and in every JSON row.
#[test]
fn bench_reports_a_frame_and_names_its_build() {
    let dir = std::env::temp_dir().join(format!("imagine-bench-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("tiny.toml");
    std::fs::write(
        &scene,
        "name = \"TINY\"\n[window]\nwidth = 16\nheight = 16\n[pipeline]\n\
         depth_test = \"less\"\ncull = \"none\"\n[[object]]\n\
         primitive = { kind = \"rate\", size = 8 }\ntriangles = \"separate\"\n",
    )
    .unwrap();
    let json = dir.join("bench.json");
    let o = imagine(&[
        "bench",
        scene.to_str().unwrap(),
        "--runs",
        "2",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let build = if cfg!(debug_assertions) {
        "debug"
    } else {
        "release"
    };
    assert!(
        stdout(&o).contains(&format!("build: {build}")),
        "{}",
        stdout(&o)
    );
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), 1);
    let row = &rows[0];
    assert_eq!(row["scene"], "TINY");
    assert_eq!(row["machine"], "gold8");
    assert_eq!(row["build"], build);
    let f = |k: &str| row[k].as_f64().unwrap_or_else(|| panic!("{k}: {row}"));
    assert!(f("simulated_cycles") > 0.0);
    assert!(f("compile_cold") > f("compile_warm"), "{row}");
    let rate = f("simulated_cycles") / f("simulate");
    assert!(
        (f("simulated_cycles_per_second") - rate).abs() <= 1e-9 * rate,
        "{row}"
    );
    assert!(f("host_per_frame") >= f("simulate"), "{row}");
}
