//! Checks every committed SoftFloat-generated vector under `tests/vectors/` (no feature
//! needed). `<op>.txt` are IEEE-mode vectors in TestFloat format, `ftz_<op>.txt`
//! flush-to-zero vectors from the SoftFloat-based FTZ reference. Regenerate with
//! `sh units/tests/vectors/regenerate.sh` (feature `softfloat`).

use imagine_units::arith::fp32::FpMode;
use imagine_units::arith::fp32::testfloat::{Op, format_case, parse_case};
use std::path::{Path, PathBuf};

fn vector_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/vectors")
}

/// Check one file; returns the number of cases.
fn check_file(path: &Path, op: Op, mode: FpMode) -> usize {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let mut failures = Vec::new();
    let mut cases = 0;
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let case =
            parse_case(op, line).unwrap_or_else(|e| panic!("{}:{}: {e}", path.display(), i + 1));
        cases += 1;
        let (result, flags) = op.eval(case.a, case.b, mode);
        if (result, flags) != (case.result, case.flags) {
            let mut got = case;
            got.result = result;
            got.flags = flags;
            failures.push(format!(
                "line {}: expected `{line}`, got `{}`",
                i + 1,
                format_case(op, &got)
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{}: {} of {cases} vectors fail:\n{}",
        path.display(),
        failures.len(),
        failures
            .iter()
            .take(20)
            .cloned()
            .collect::<Vec<_>>()
            .join("\n")
    );
    cases
}

#[test]
fn every_op_has_ieee_vectors_and_they_pass() {
    for op in Op::ALL {
        let path = vector_dir().join(format!("{}.txt", op.name()));
        let n = check_file(&path, op, FpMode::IEEE);
        assert!(n >= 1000, "{}: only {n} vectors", path.display());
    }
}

#[test]
fn ftz_vectors_pass() {
    for op in [Op::Add, Op::Sub, Op::Mul, Op::Div, Op::Sqrt] {
        let path = vector_dir().join(format!("ftz_{}.txt", op.name()));
        let n = check_file(&path, op, FpMode::FTZ);
        assert!(n >= 500, "{}: only {n} vectors", path.display());
    }
}

#[test]
fn no_stray_vector_files() {
    for entry in std::fs::read_dir(vector_dir()).expect("vector dir") {
        let name = entry
            .expect("dir entry")
            .file_name()
            .into_string()
            .expect("utf-8");
        let Some(stem) = name.strip_suffix(".txt") else {
            continue;
        };
        let stem = stem.strip_prefix("ftz_").unwrap_or(stem);
        assert!(Op::from_name(stem).is_some(), "unknown vector file {name}");
    }
}
