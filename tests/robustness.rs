//! Hostile input at the command line (ARCHITECTURE §8): for every format the tool reads —
//! machine descriptions, scene files and their meshes, `.tri` files, microcode text and
//! images, TestFloat vectors, command-line options, output paths — the classes of bad
//! input (empty, binary garbage, truncated, wrong counts, NaN and infinities, huge, negative
//! and zero values, missing and unknown keys, `base` cycles, unreadable and unwritable
//! paths) each end with a non-zero exit, an `error:` line naming the file or option and the
//! problem, and no panic, within a time limit. DRAM traces have their own cases in
//! `tests/cli.rs`.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// No hostile input may keep the tool busy for longer (the cases here are refused in
/// milliseconds; the limit only catches a hang).
const TIME_LIMIT: Duration = Duration::from_secs(60);

struct Outcome {
    success: bool,
    stdout: String,
    stderr: String,
}

/// Runs the binary with `args` and `stdin`, killing it past [`TIME_LIMIT`].
fn run(args: &[&str], stdin: &[u8]) -> Outcome {
    let mut child = Command::new(env!("CARGO_BIN_EXE_imagine"))
        .args(args)
        .env("IMAGINE_CACHE_DIR", dir().join("cache"))
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary starts");
    let mut input = child.stdin.take().expect("piped stdin");
    let bytes = stdin.to_vec();
    let writer = std::thread::spawn(move || {
        let _ = input.write_all(&bytes);
    });
    let start = Instant::now();
    while child.try_wait().expect("wait").is_none() {
        if start.elapsed() > TIME_LIMIT {
            let _ = child.kill();
            panic!("`imagine {}` ran past {TIME_LIMIT:?}", args.join(" "));
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    writer.join().expect("stdin writer");
    let out = child.wait_with_output().expect("output");
    Outcome {
        success: out.status.success(),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// Asserts a clean refusal: a non-zero exit, an `error:` line holding every one of `want`,
/// and no panic.
#[track_caller]
fn refused(args: &[&str], stdin: &[u8], want: &[&str]) {
    let o = run(args, stdin);
    let shown = format!(
        "`imagine {}`\nstdout: {}\nstderr: {}",
        args.join(" "),
        o.stdout,
        o.stderr
    );
    assert!(!o.success, "exited 0: {shown}");
    assert!(
        !o.stderr.contains("panicked") && !o.stderr.contains("RUST_BACKTRACE"),
        "panicked: {shown}"
    );
    assert!(
        o.stderr.lines().any(|l| l.starts_with("error:")),
        "no `error:` line: {shown}"
    );
    // A message may run over several lines (a TOML error shows the key on its own line).
    for w in want {
        assert!(
            o.stderr.contains(w),
            "the error does not mention `{w}`: {shown}"
        );
    }
}

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("imagine-robustness-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

/// Writes `bytes` to a fresh file `name` in the test directory.
fn file(name: &str, bytes: impl AsRef<[u8]>) -> String {
    let path = dir().join(name);
    std::fs::write(&path, bytes).expect("write a test input");
    path.to_str().expect("UTF-8 temp path").to_string()
}

fn root(rel: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(rel)
        .to_str()
        .expect("UTF-8 path")
        .to_string()
}

/// CRC-32 (ISO 3309, as PNG chunks use).
fn crc32(bytes: &[u8]) -> u32 {
    !bytes.iter().fold(!0u32, |mut c, &b| {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 == 1 {
                (c >> 1) ^ 0xedb8_8320
            } else {
                c >> 1
            };
        }
        c
    })
}

const GARBAGE: &[u8] = &[0x00, 0xff, 0xfe, 0x89, b'P', b'N', b'G', 0x1a, 0x00, 0x9c];

fn gold8() -> String {
    std::fs::read_to_string(root("machines/gold8.toml")).expect("gold8.toml")
}

/// gold8 with one line replaced (the line starting with `key =`).
fn gold8_with(key: &str, line: &str) -> String {
    let text = gold8();
    let mut found = false;
    let out: Vec<String> = text
        .lines()
        .map(|l| {
            if l.split('=').next().is_some_and(|k| k.trim() == key) && !found {
                found = true;
                line.to_string()
            } else {
                l.to_string()
            }
        })
        .collect();
    assert!(found, "gold8.toml has no key `{key}`");
    out.join("\n")
}

#[test]
fn machine_descriptions() {
    let show = |name: &str, text: &[u8], want: &[&str]| {
        let f = file(name, text);
        let mut want = want.to_vec();
        want.push(name);
        refused(&["machine", "show", &f], b"", &want);
    };
    show("empty.toml", b"", &["empty.toml"]);
    show("garbage.toml", GARBAGE, &["UTF-8"]);
    let g = gold8();
    show("truncated.toml", &g.as_bytes()[..g.len() / 2], &[]);
    show(
        "zero-clusters.toml",
        gold8_with("count", "count = 0").as_bytes(),
        &["cluster.count", "is 0"],
    );
    show(
        "negative.toml",
        gold8_with("adders", "adders = -1").as_bytes(),
        &["adders"],
    );
    show(
        "huge.toml",
        gold8_with("words", "words = 1000000000000000").as_bytes(),
        &["scratchpad.words"],
    );
    show(
        "nan.toml",
        gold8_with("core_mhz", "core_mhz = nan").as_bytes(),
        &["core_mhz"],
    );
    show(
        "inf.toml",
        gold8_with("core_mhz", "core_mhz = inf").as_bytes(),
        &["core_mhz"],
    );
    show(
        "zero-srf.toml",
        gold8_with("words", "words = 0").as_bytes(),
        &["words"],
    );
    show(
        "unknown-key.toml",
        format!("{g}\n[cluster.extra]\nbogus = 1\n").as_bytes(),
        &[],
    );
    show(
        "missing.toml",
        b"name = \"m\"\n[clocks]\ncore_mhz = 500\n",
        &[],
    );
    show(
        "base-cycle.toml",
        b"base = \"base-cycle.toml\"\nname = \"x\"\n",
        &["base"],
    );
    show(
        "s3-zero-accelerators.toml",
        gold8_with("accelerators", "accelerators = 0").as_bytes(),
        &["s3.accelerators", "is 0"],
    );
    show(
        "s3-sram.toml",
        gold8_with("memory", "memory = \"sram\"").as_bytes(),
        &["s3.memory", "ideal"],
    );
    show(
        "min-kernel.toml",
        gold8_with("min_kernel_cycles", "min_kernel_cycles = 100000000000").as_bytes(),
        &["min_kernel_cycles"],
    );
    refused(
        &[
            "machine",
            "show",
            &dir().join("no-such.toml").to_string_lossy(),
        ],
        b"",
        &["no-such.toml"],
    );
    refused(&["machine", "show", &dir().to_string_lossy()], b"", &[]);
    refused(&["machine", "show", "/dev/zero"], b"", &["/dev/zero"]);
    // A named pipe nobody writes would block the open for ever.
    let fifo = dir().join("fifo.toml");
    let made = Command::new("mkfifo").arg(&fifo).status();
    if made.is_ok_and(|s| s.success()) {
        let fifo = fifo.to_str().unwrap();
        refused(&["machine", "show", fifo], b"", &["named pipe"]);
        refused(&["kernel", "asm", fifo], b"", &["named pipe"]);
        refused(&["render", "--machine", fifo], b"", &["named pipe"]);
        refused(&["dram", "--trace", fifo], b"", &["named pipe"]);
        refused(&["s3", "--trace", fifo], b"", &["named pipe"]);
    }
}

#[test]
fn machines_the_kernels_cannot_serve_are_refused_before_any_simulation() {
    for (name, key, line, want) in [
        ("c3.toml", "count", "count = 3", "clusters"),
        ("c256.toml", "count", "count = 256", "256"),
        (
            "cc1.toml",
            "condition_codes",
            "condition_codes = 1",
            "condition code",
        ),
        ("lrf2.toml", "entries", "entries = 2", "LRF"),
        ("sp16.toml", "words", "words = 16", "scratchpad"),
        (
            "us16.toml",
            "store_words",
            "store_words = 16",
            "microcode store",
        ),
    ] {
        let f = file(name, gold8_with(key, line));
        refused(
            &["render", "RATE-1", "--size", "32", "--machine", &f],
            b"",
            &[want],
        );
        refused(&["kernel", "check", "all", "--machine", &f], b"", &[want]);
    }
}

fn scene(body: &str) -> String {
    format!(
        "[window]\nwidth = 64\nheight = 64\n[camera]\neye = [0.0, 0.0, 3.0]\n\
         target = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 45.0\nnear = 1.0\nfar = 10.0\n\
         {body}"
    )
}

#[test]
fn scene_files() {
    let check = |name: &str, text: &[u8], want: &[&str]| {
        let f = file(name, text);
        let mut want = want.to_vec();
        want.push(name);
        refused(&["scene", "show", &f], b"", &want);
        refused(&["render", &f], b"", &want);
    };
    let sphere = "[[object]]\nprimitive = { kind = \"icosphere\", subdivisions = 1 }\n";
    check("empty.toml", b"", &[]);
    check("garbage.toml", GARBAGE, &["UTF-8"]);
    let full = std::fs::read_to_string(root("scenes/SPHERE.toml")).expect("SPHERE.toml");
    check("truncated.toml", &full.as_bytes()[..full.len() / 3], &[]);
    check(
        "nan-camera.toml",
        scene(sphere)
            .replace("fov_y = 45.0", "fov_y = nan")
            .as_bytes(),
        &["fov_y"],
    );
    check(
        "inf-translate.toml",
        scene(&format!("{sphere}translate = [inf, 0.0, 0.0]\n")).as_bytes(),
        &["translate"],
    );
    check(
        "huge-window.toml",
        scene(sphere)
            .replace("width = 64", "width = 100000000")
            .as_bytes(),
        &["width"],
    );
    check(
        "zero-window.toml",
        scene(sphere).replace("width = 64", "width = 0").as_bytes(),
        &["width"],
    );
    check(
        "negative-window.toml",
        scene(sphere)
            .replace("height = 64", "height = -64")
            .as_bytes(),
        &["height"],
    );
    check(
        "huge-subdivisions.toml",
        scene("[[object]]\nprimitive = { kind = \"icosphere\", subdivisions = 4000000000 }\n")
            .as_bytes(),
        &["subdivisions"],
    );
    check(
        "huge-sphere.toml",
        scene(
            "[[object]]\nprimitive = { kind = \"uv_sphere\", rings = 1000000, segments = 1000000 }\n",
        )
        .as_bytes(),
        &["rings"],
    );
    check(
        "no-geometry.toml",
        scene("[[object]]\nname = \"nothing\"\n").as_bytes(),
        &["object"],
    );
    check(
        "unknown-key.toml",
        scene(&format!("{sphere}bogus = 1\n")).as_bytes(),
        &["bogus"],
    );
    check("no-objects.toml", scene("").as_bytes(), &["object"]);
    check(
        "missing-mesh.toml",
        scene("[[object]]\nmesh = \"no-such.obj\"\n").as_bytes(),
        &["no-such.obj"],
    );
    file("garbage.obj", GARBAGE);
    check(
        "garbage-mesh.toml",
        scene("[[object]]\nmesh = \"garbage.obj\"\n").as_bytes(),
        &["garbage.obj"],
    );
    file("bad-index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    check(
        "bad-index.toml",
        scene("[[object]]\nmesh = \"bad-index.obj\"\n").as_bytes(),
        &["bad-index.obj"],
    );
    file("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n");
    check(
        "nan-mesh.toml",
        scene("[[object]]\nmesh = \"nan.obj\"\n").as_bytes(),
        &["nan.obj"],
    );
    file("short.bpt", "1\n3 3\n0 0 0\n");
    check(
        "short-patches.toml",
        scene("[[object]]\npatches = \"short.bpt\"\ntessellate = 4\n").as_bytes(),
        &["short.bpt"],
    );
    file("many.bpt", "1000000000\n3 3\n");
    check(
        "many-patches.toml",
        scene("[[object]]\npatches = \"many.bpt\"\ntessellate = 4\n").as_bytes(),
        &["many.bpt"],
    );
    // Textures: garbage, a truncated PNG, and a header declaring 100,000² texels (refused
    // from the header, before anything is allocated).
    let png = |w: u32, h: u32| {
        let mut ihdr = b"IHDR".to_vec();
        ihdr.extend_from_slice(&w.to_be_bytes());
        ihdr.extend_from_slice(&h.to_be_bytes());
        ihdr.extend_from_slice(&[8, 6, 0, 0, 0]);
        let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
        out.extend_from_slice(&13u32.to_be_bytes());
        out.extend_from_slice(&ihdr);
        out.extend_from_slice(&crc32(&ihdr).to_be_bytes());
        out
    };
    let textured = |image: &str| {
        scene(&format!(
            "[[texture]]\nname = \"t\"\nimage = \"{image}\"\n[[material]]\nname = \"m\"\n\
             shader = \"unlit\"\ntextures = [\"t\"]\n{sphere}material = \"m\"\n"
        ))
    };
    file("garbage.png", GARBAGE);
    file("truncated.png", png(4, 4));
    file("huge.png", png(100_000, 100_000));
    for (image, want) in [
        ("garbage.png", "not a PNG"),
        ("truncated.png", "not a PNG"),
        ("huge.png", "4096 texels"),
        ("no-such.png", "cannot read"),
    ] {
        let name = format!("texture-{image}.toml");
        check(
            &name,
            textured(image).as_bytes(),
            &["texture[0].image", want],
        );
    }
    refused(
        &["render", &dir().join("no-such.toml").to_string_lossy()],
        b"",
        &["no-such.toml"],
    );
}

#[test]
fn triangle_files() {
    let check = |name: &str, text: &[u8], want: &[&str]| {
        let f = file(name, text);
        let mut want = want.to_vec();
        want.push(name);
        refused(&["render", &f], b"", &want);
        refused(&["s3", "--trace", &f], b"", &want);
    };
    let tri = "0 0 0.5 1 0 0  8 0 0.5 0 1 0  0 8 0.5 0 0 1\n";
    check("empty.tri", b"", &[]);
    check("garbage.tri", GARBAGE, &[]);
    check(
        "truncated.tri",
        format!("16 16\n{}", &tri[..20]).as_bytes(),
        &[],
    );
    check(
        "nan.tri",
        format!("16 16\n{}", tri.replace("0.5", "nan")).as_bytes(),
        &[],
    );
    check(
        "huge.tri",
        format!("16 16\n{}", tri.replace(" 8 ", " 1e30 ")).as_bytes(),
        &[],
    );
    check("zero-window.tri", format!("0 16\n{tri}").as_bytes(), &[]);
    check(
        "huge-window.tri",
        format!("100000000 16\n{tri}").as_bytes(),
        &[],
    );
    check(
        "negative-window.tri",
        format!("-16 16\n{tri}").as_bytes(),
        &[],
    );
}

const MADD: &str = "units/tests/microcode/madd.uc";

#[test]
fn microcode_text_and_images() {
    refused(
        &["kernel", "asm", &file("empty.uc", "")],
        b"",
        &["empty.uc"],
    );
    refused(
        &["kernel", "asm", &file("garbage.uc", GARBAGE)],
        b"",
        &["garbage.uc"],
    );
    let text = std::fs::read_to_string(root(MADD)).expect("madd.uc");
    refused(
        &[
            "kernel",
            "asm",
            &file("truncated.uc", &text[..text.len() / 2]),
        ],
        b"",
        &["truncated.uc"],
    );
    refused(
        &[
            "kernel",
            "asm",
            &file(
                "huge-imm.uc",
                "kernel k\nin x\nout y\n    imm 1e39 -> add0.a[0]\ndone\n",
            ),
        ],
        b"",
        &["huge-imm.uc", "range of fp32"],
    );
    // An image: built, then damaged, then run on a machine it was not built for.
    let image = dir().join("madd.imuc");
    let o = run(
        &["kernel", "asm", &root(MADD), "-o", image.to_str().unwrap()],
        b"",
    );
    assert!(o.success, "{}", o.stderr);
    let bytes = std::fs::read(&image).expect("image");
    for cut in [5, bytes.len() / 2, bytes.len() - 1] {
        let f = file(&format!("cut{cut}.imuc"), &bytes[..cut]);
        refused(&["kernel", "disasm", &f], b"", &["truncated"]);
    }
    let mut flipped = bytes.clone();
    let last = flipped.len() - 3;
    flipped[last] ^= 0xff;
    let f = file("flipped.imuc", &flipped);
    let o = run(&["kernel", "disasm", &f], b"");
    assert!(!o.stderr.contains("panicked"), "{}", o.stderr);
    let mix = file(
        "mix.toml",
        "base = \"gold8\"\nname = \"mix\"\n[cluster]\nmultipliers = 1\ndivsqrt = 2\n",
    );
    refused(
        &[
            "kernel",
            "run",
            image.to_str().unwrap(),
            "--machine",
            &mix,
            "--input",
            "x=1",
            "--input",
            "y=1",
            "--input",
            "w=1",
        ],
        b"",
        &["`gold8`", "`mix`"],
    );
}

#[test]
fn kernel_run_inputs() {
    let madd = root(MADD);
    let run_with = |x: &str, want: &[&str]| {
        let x = format!("x={x}");
        refused(
            &[
                "kernel", "run", &madd, "--input", &x, "--input", "y=1", "--input", "w=1",
            ],
            b"",
            want,
        );
    };
    run_with("1e39", &["1e39", "range of fp32"]);
    run_with("-1e39", &["range of fp32"]);
    run_with("1e-50", &["rounds to zero"]);
    run_with("inf", &["hex"]);
    run_with("nan", &["hex"]);
    run_with("4294967296", &["32 bits"]);
    run_with("0x1ffffffff", &["32-bit hex"]);
    run_with("1,,zz", &["zz"]);
    run_with("@/no/such/file", &["/no/such/file"]);
    run_with("@/dev/zero", &["/dev/zero"]);
    refused(
        &["kernel", "run", &madd, "--input", "x=1", "--input", "y=1"],
        b"",
        &["`w`"],
    );
    refused(
        &[
            "kernel", "run", &madd, "--input", "x=1", "--input", "y=1", "--input", "w=1",
            "--input", "q=1",
        ],
        b"",
        &["`q`"],
    );
}

#[test]
fn testfloat_vectors() {
    refused(&["verify", "fpu", "f32_add"], b"", &["no f32_add vectors"]);
    refused(
        &["verify", "fpu", "f32_add"],
        b"\n\n",
        &["no f32_add vectors"],
    );
    for bad in [
        &b"3F800000 40000000 40400000\n"[..],
        b"3F800000 40000000 40400000 00 00 00\n",
        b"3F800000 zz 40400000 00\n",
        b"3F800000 140000000 40400000 00\n",
        GARBAGE,
    ] {
        refused(&["verify", "fpu", "f32_add"], bad, &[]);
    }
    refused(&["verify", "fpu", "f32_nonsense"], b"", &["f32_nonsense"]);
}

#[test]
fn options_out_of_range() {
    for (args, want) in [
        (&["render", "RATE-1", "--size", "0"][..], "--size"),
        (&["render", "RATE-1", "--size", "1000000"], "--size"),
        (
            &["render", "SPHERE", "--subdivisions", "100"],
            "subdivisions",
        ),
        (&["render", "RATE-1", "--size", "-5"], "-5"),
        (&["render", "RATE-1", "--max-cycles", "0"], "--max-cycles"),
        (&["render", "NO-SUCH-SCENE"], "NO-SUCH-SCENE"),
        (&["render", "RATE-1", "--machine", "gold9"], "gold9"),
        (&["kernel", "check", "hash", "--rows", "0"], "--rows"),
        (
            &["kernel", "check", "hash", "--rows", "1000000000000"],
            "--rows",
        ),
        (&["kernel", "check", "nosuch"], "nosuch"),
        (
            &["demo", "--crossing-capacity", "1000000000000"],
            "--crossing-capacity",
        ),
        (&["demo", "--crossing-capacity", "0"], "--crossing-capacity"),
        (&["demo", "--cycles", "18446744073709551615"], "--cycles"),
        (&["demo", "--core-mhz", "0"], "--core-mhz"),
        (
            &["machine", "bench", "--cycles", "18446744073709551615"],
            "--cycles",
        ),
        (&["machine", "bench", "--cycles", "0"], "--cycles"),
        (
            &["dram", "--bench", "unit", "--policy", "fastest"],
            "fastest",
        ),
    ] {
        let o = run(args, b"");
        let shown = format!("`imagine {}`: {}", args.join(" "), o.stderr);
        assert!(!o.success, "{shown}");
        assert!(!o.stderr.contains("panicked"), "{shown}");
        assert!(o.stderr.contains("error"), "{shown}");
        assert!(o.stderr.contains(want), "{shown}");
    }
}

#[test]
fn bad_output_paths_are_refused_before_the_work() {
    let missing = dir().join("no-such-dir/out.png");
    let missing = missing.to_str().unwrap();
    let d = dir();
    let d = d.to_str().unwrap();
    let a = dir().join("same.out");
    let a = a.to_str().unwrap();
    // SPHERE would simulate for seconds: a refusal in time proves it came first.
    for (args, want) in [
        (vec!["render", "SPHERE", "--png", missing], "--png"),
        (vec!["render", "SPHERE", "--stats", d], "--stats"),
        (
            vec!["render", "SPHERE", "--stats-csv", missing],
            "--stats-csv",
        ),
        (
            vec!["render", "SPHERE", "--reference-png", missing],
            "--reference-png",
        ),
        (
            vec!["render", "SPHERE", "--timeline", missing],
            "--timeline",
        ),
        (vec!["render", "SPHERE", "--vcd", missing], "--vcd"),
        (
            vec!["render", "SPHERE", "--png", a, "--stats", a],
            "--stats",
        ),
        (vec!["demo", "--vcd", "x.gtkw"], "GTKWave"),
        (
            vec!["dram", "--bench", "unit", "--dram-trace", missing],
            "--dram-trace",
        ),
        (
            vec!["kernel", "asm", &root(MADD), "-o", missing],
            "--output",
        ),
        (
            vec!["kernel", "asm", &root(MADD), "-o", &root(MADD)],
            "source file",
        ),
    ] {
        let start = Instant::now();
        refused(&args, b"", &[want]);
        assert!(
            start.elapsed() < Duration::from_secs(5),
            "`imagine {}` took {:?} before refusing",
            args.join(" "),
            start.elapsed()
        );
    }
    assert!(!Path::new("x.gtkw").exists());
}
