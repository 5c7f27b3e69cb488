//! TestFloat vectors: the first line names the op (`f32_add`, …, optionally preceded by
//! `ftz ` for flush-to-zero), the rest goes to `check_stream_with_mode` as bytes.
#![no_main]

use imagine_fuzz::{repo_root, write_seeds_if_asked};
use imagine_units::arith::fp32::FpMode;
use imagine_verif::testfloat::{FpuOp, check_stream_with_mode};
use libfuzzer_sys::fuzz_target;

fuzz_target!(init: write_seeds_if_asked(seeds), |data: &[u8]| {
    let split = data.iter().position(|&b| b == b'\n').unwrap_or(data.len());
    let (head, rest) = data.split_at(split);
    let head = String::from_utf8_lossy(head);
    let (mode, name) = match head.trim().strip_prefix("ftz ") {
        Some(name) => (
            FpMode {
                flush_to_zero: true,
            },
            name,
        ),
        None => (FpMode::IEEE, head.trim()),
    };
    let op: FpuOp = name.parse().unwrap_or(FpuOp::F32Add);
    let mut mismatches = Vec::new();
    let _ = check_stream_with_mode(op, mode, rest, &mut mismatches, 4);
});

/// The first 32 lines of each committed vector file of `units/tests/vectors/`, under the
/// line naming its op (`ftz_f32_add.txt` → `ftz f32_add`).
fn seeds() -> Vec<(String, Vec<u8>)> {
    let dir = repo_root().join("units/tests/vectors");
    let mut seeds = Vec::new();
    for entry in std::fs::read_dir(&dir).expect("units/tests/vectors") {
        let path = entry.expect("a directory entry").path();
        let Some(stem) = path.file_stem().and_then(|s| s.to_str()) else {
            continue;
        };
        if path.extension().is_none_or(|e| e != "txt") {
            continue;
        }
        let op = match stem.strip_prefix("ftz_") {
            Some(op) => format!("ftz {op}"),
            None => stem.to_string(),
        };
        let text = std::fs::read_to_string(&path).expect("a vector file");
        let head: Vec<&str> = text.lines().take(32).collect();
        seeds.push((
            format!("{stem}.txt"),
            format!("{op}\n{}\n", head.join("\n")).into_bytes(),
        ));
    }
    seeds
}
