//! Berkeley TestFloat-format checker for the fp32 datapath (`imagine verify fpu OP`).
//!
//! [`check_stream`] reads TestFloat text vectors — one case per line: operands, expected
//! result, expected flags as two hex digits (inexact 1, underflow 2, overflow 4, infinite 8,
//! invalid 16), e.g. `3F800000 40000000 40400000 00` for `f32_add` — runs each case through
//! the `imagine-units` datapath (`arith::fp32`, IEEE mode unless a [`FpMode`] is given), and
//! compares result bits and all five flags exactly. Vectors come from SoftFloat (the
//! `testfloat_gen` example of `imagine-units`, feature `softfloat`) or from Berkeley
//! TestFloat's `testfloat_gen` (use `-exact` for conversions to integer: our conversions
//! raise inexact, like RISC-V `fcvt`).
//!
//! Blank lines and lines starting with `#` are skipped. A malformed line stops the check with
//! [`TestFloatError::Parse`] naming the line; nothing panics on bad input.

use imagine_units::arith::fp32::FpMode;
use imagine_units::arith::fp32::testfloat::{Case, Op, format_case, format_result, parse_case};
use std::fmt;
use std::io::{BufRead, Write};
use std::str::FromStr;

/// An fp32 operation checkable against TestFloat vectors.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FpuOp {
    /// `f32_add`
    F32Add,
    /// `f32_sub`
    F32Sub,
    /// `f32_mul`
    F32Mul,
    /// `f32_div`
    F32Div,
    /// `f32_sqrt`
    F32Sqrt,
    /// `f32_to_i32`: round to nearest even, inexact raised (`-exact`)
    F32ToI32,
    /// `i32_to_f32`
    I32ToF32,
    /// `f32_lt` (signalling)
    F32Lt,
    /// `f32_le` (signalling)
    F32Le,
    /// `f32_eq` (quiet)
    F32Eq,
    /// `f32_to_i32_r_minMag`: round toward zero, inexact raised (`-exact`)
    F32ToI32RMinMag,
    /// `f32_min`: RISC-V `fmin.s` (not a TestFloat function; same line format)
    F32Min,
    /// `f32_max`: RISC-V `fmax.s` (not a TestFloat function; same line format)
    F32Max,
}

impl FpuOp {
    /// Every op.
    pub const ALL: [FpuOp; 13] = [
        FpuOp::F32Add,
        FpuOp::F32Sub,
        FpuOp::F32Mul,
        FpuOp::F32Div,
        FpuOp::F32Sqrt,
        FpuOp::F32ToI32,
        FpuOp::I32ToF32,
        FpuOp::F32Lt,
        FpuOp::F32Le,
        FpuOp::F32Eq,
        FpuOp::F32ToI32RMinMag,
        FpuOp::F32Min,
        FpuOp::F32Max,
    ];

    /// The datapath op this checks.
    pub const fn unit_op(self) -> Op {
        match self {
            FpuOp::F32Add => Op::Add,
            FpuOp::F32Sub => Op::Sub,
            FpuOp::F32Mul => Op::Mul,
            FpuOp::F32Div => Op::Div,
            FpuOp::F32Sqrt => Op::Sqrt,
            FpuOp::F32ToI32 => Op::ToI32,
            FpuOp::I32ToF32 => Op::FromI32,
            FpuOp::F32Lt => Op::Lt,
            FpuOp::F32Le => Op::Le,
            FpuOp::F32Eq => Op::Eq,
            FpuOp::F32ToI32RMinMag => Op::ToI32Rtz,
            FpuOp::F32Min => Op::Min,
            FpuOp::F32Max => Op::Max,
        }
    }

    /// The TestFloat name (`f32_add`, …), as accepted by [`FromStr`].
    pub const fn name(self) -> &'static str {
        self.unit_op().name()
    }

    /// Number of operands per line.
    pub const fn arity(self) -> usize {
        self.unit_op().arity()
    }
}

impl fmt::Display for FpuOp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for FpuOp {
    type Err = TestFloatError;

    /// Parse a TestFloat function name (`f32_add`, `f32_sub`, `f32_mul`, `f32_div`,
    /// `f32_sqrt`, `f32_to_i32`, `i32_to_f32`, `f32_lt`, `f32_le`, `f32_eq`,
    /// `f32_to_i32_r_minMag`, `f32_min`, `f32_max`).
    fn from_str(s: &str) -> Result<FpuOp, TestFloatError> {
        FpuOp::ALL
            .into_iter()
            .find(|op| op.name() == s)
            .ok_or_else(|| TestFloatError::UnknownOp(s.to_string()))
    }
}

/// Outcome counts of a check.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Summary {
    /// Cases whose result and flags matched.
    pub passed: u64,
    /// Cases that differed.
    pub failed: u64,
}

impl Summary {
    /// Cases checked.
    pub fn total(&self) -> u64 {
        self.passed + self.failed
    }

    /// True if no case failed.
    pub fn is_success(&self) -> bool {
        self.failed == 0
    }
}

impl fmt::Display for Summary {
    /// `N passed, M failed`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} passed, {} failed", self.passed, self.failed)
    }
}

/// Why a check could not be completed.
#[derive(Debug)]
pub enum TestFloatError {
    /// Not a known op name.
    UnknownOp(String),
    /// A malformed input line (1-based line number).
    Parse {
        /// 1-based line number.
        line: u64,
        /// What is wrong with it.
        message: String,
    },
    /// Reading the input or writing the report failed.
    Io(std::io::Error),
}

impl fmt::Display for TestFloatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TestFloatError::UnknownOp(name) => {
                let names: Vec<&str> = FpuOp::ALL.iter().map(|op| op.name()).collect();
                write!(
                    f,
                    "unknown fpu op `{name}` (expected one of: {})",
                    names.join(", ")
                )
            }
            TestFloatError::Parse { line, message } => write!(f, "line {line}: {message}"),
            TestFloatError::Io(e) => write!(f, "i/o error: {e}"),
        }
    }
}

impl std::error::Error for TestFloatError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            TestFloatError::Io(e) => Some(e),
            _ => None,
        }
    }
}

impl From<std::io::Error> for TestFloatError {
    fn from(e: std::io::Error) -> TestFloatError {
        TestFloatError::Io(e)
    }
}

/// Check a stream of TestFloat vectors for `op` in IEEE mode; see [`check_stream_with_mode`].
pub fn check_stream(
    op: FpuOp,
    input: impl BufRead,
    mismatches_out: &mut impl Write,
    max_reported: usize,
) -> Result<Summary, TestFloatError> {
    check_stream_with_mode(op, FpMode::IEEE, input, mismatches_out, max_reported)
}

/// Check a stream of TestFloat vectors for `op` under `mode`.
///
/// Every case is checked; the first `max_reported` mismatches are written to
/// `mismatches_out`, one line each:
///
/// ```text
/// line 12: f32_add 3F800000 40000000: expected 40400000 flags 00, got 40400001 flags 01
/// ```
///
/// Returns the pass/fail counts, or an error for an unreadable stream, a malformed line
/// (with its number), or a failed write.
pub fn check_stream_with_mode(
    op: FpuOp,
    mode: FpMode,
    mut input: impl BufRead,
    mismatches_out: &mut impl Write,
    max_reported: usize,
) -> Result<Summary, TestFloatError> {
    let unit = op.unit_op();
    let mut summary = Summary::default();
    let mut reported = 0usize;
    let mut buf = Vec::with_capacity(64);
    let mut line_no = 0u64;
    loop {
        buf.clear();
        if input.read_until(b'\n', &mut buf)? == 0 {
            break;
        }
        line_no += 1;
        let line = std::str::from_utf8(&buf).map_err(|_| TestFloatError::Parse {
            line: line_no,
            message: "not valid UTF-8".into(),
        })?;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let case = parse_case(unit, line).map_err(|e| TestFloatError::Parse {
            line: line_no,
            message: format!("{e} (in `{line}`)"),
        })?;
        let (result, flags) = unit.eval(case.a, case.b, mode);
        if result == case.result && flags == case.flags {
            summary.passed += 1;
            continue;
        }
        summary.failed += 1;
        if reported < max_reported {
            reported += 1;
            let operands = format_case(unit, &Case { result: 0, ..case });
            // The formatted case ends with "<result> <flags>": keep only the operands.
            let operands: Vec<&str> = operands.split(' ').take(unit.arity()).collect();
            writeln!(
                mismatches_out,
                "line {line_no}: {op} {}: expected {} flags {}, got {} flags {}",
                operands.join(" "),
                format_result(unit, case.result),
                case.flags,
                format_result(unit, result),
                flags,
            )?;
        }
    }
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    fn run(op: FpuOp, text: &str, max: usize) -> (Result<Summary, TestFloatError>, String) {
        let mut out = Vec::new();
        let r = check_stream(op, Cursor::new(text.as_bytes()), &mut out, max);
        (r, String::from_utf8(out).expect("utf-8 report"))
    }

    #[test]
    fn names_parse() {
        for op in FpuOp::ALL {
            assert_eq!(op.name().parse::<FpuOp>().ok(), Some(op));
            assert_eq!(op.to_string(), op.name());
        }
        for (name, op) in [
            ("f32_add", FpuOp::F32Add),
            ("f32_sub", FpuOp::F32Sub),
            ("f32_mul", FpuOp::F32Mul),
            ("f32_div", FpuOp::F32Div),
            ("f32_sqrt", FpuOp::F32Sqrt),
            ("f32_to_i32", FpuOp::F32ToI32),
            ("i32_to_f32", FpuOp::I32ToF32),
            ("f32_lt", FpuOp::F32Lt),
            ("f32_le", FpuOp::F32Le),
            ("f32_eq", FpuOp::F32Eq),
        ] {
            assert_eq!(name.parse::<FpuOp>().ok(), Some(op));
        }
        let err = "f64_add".parse::<FpuOp>().unwrap_err();
        assert!(matches!(err, TestFloatError::UnknownOp(ref n) if n == "f64_add"));
        assert!(err.to_string().contains("f32_sqrt"));
    }

    #[test]
    fn passing_vectors() {
        let text = "3F800000 40000000 40400000 00\n\
                    # a comment\n\
                    \n\
                    7F800000 FF800000 7FC00000 10\r\n\
                    3F800000 33800000 3F800000 01";
        let (r, report) = run(FpuOp::F32Add, text, 10);
        let s = r.expect("well-formed");
        assert_eq!(
            s,
            Summary {
                passed: 3,
                failed: 0
            }
        );
        assert!(s.is_success());
        assert_eq!(s.to_string(), "3 passed, 0 failed");
        assert!(report.is_empty());
    }

    #[test]
    fn mismatches_are_counted_and_reported() {
        // Wrong result on line 2, wrong flags on line 3, both wrong on line 4.
        let text = "3F800000 40000000 40400000 00\n\
                    3F800000 40000000 40400001 00\n\
                    3F800000 40000000 40400000 01\n\
                    00000000 00000000 00000001 04\n";
        let (r, report) = run(FpuOp::F32Add, text, 2);
        assert_eq!(
            r.expect("well-formed"),
            Summary {
                passed: 1,
                failed: 3
            }
        );
        let lines: Vec<&str> = report.lines().collect();
        assert_eq!(lines.len(), 2, "max_reported caps the report: {report}");
        assert_eq!(
            lines[0],
            "line 2: f32_add 3F800000 40000000: expected 40400001 flags 00, got 40400000 flags 00"
        );
        assert_eq!(
            lines[1],
            "line 3: f32_add 3F800000 40000000: expected 40400000 flags 01, got 40400000 flags 00"
        );
    }

    #[test]
    fn unary_bool_and_int_ops() {
        let (r, _) = run(
            FpuOp::F32Sqrt,
            "40800000 40000000 00\nBF800000 7FC00000 10\n",
            5,
        );
        assert_eq!(
            r.expect("ok"),
            Summary {
                passed: 2,
                failed: 0
            }
        );
        let (r, _) = run(
            FpuOp::F32Lt,
            "7FC00000 3F800000 0 10\n3F800000 40000000 1 00\n",
            5,
        );
        assert_eq!(
            r.expect("ok"),
            Summary {
                passed: 2,
                failed: 0
            }
        );
        let (r, report) = run(FpuOp::F32Eq, "3F800000 3F800000 0 00\n", 5);
        assert_eq!(
            r.expect("ok"),
            Summary {
                passed: 0,
                failed: 1
            }
        );
        assert!(
            report.contains("expected 0 flags 00, got 1 flags 00"),
            "{report}"
        );
        let (r, _) = run(
            FpuOp::F32ToI32,
            "3FC00000 00000002 01\nCF000000 80000000 00\n",
            5,
        );
        assert_eq!(
            r.expect("ok"),
            Summary {
                passed: 2,
                failed: 0
            }
        );
        let (r, _) = run(FpuOp::I32ToF32, "FFFFFFFF BF800000 00\n", 5);
        assert_eq!(
            r.expect("ok"),
            Summary {
                passed: 1,
                failed: 0
            }
        );
        let (r, _) = run(FpuOp::F32ToI32RMinMag, "C0600000 FFFFFFFD 01\n", 5);
        assert_eq!(
            r.expect("ok"),
            Summary {
                passed: 1,
                failed: 0
            }
        );
    }

    #[test]
    fn malformed_lines_name_the_line() {
        let cases = [
            (
                "3F800000 40000000 40400000 00\n3F800000 40400000 00\n",
                2,
                "expected 4 fields",
            ),
            ("3F80000Z 40000000 40400000 00\n", 1, "operand 1"),
            (
                "3F800000 40000000 40400000 00\n\n1 2 3 4 5\n",
                3,
                "expected 4 fields",
            ),
            ("3F800000 40000000 40400000 1F0\n", 1, "flags"),
            ("3F800000 40000000 40400000 20\n", 1, "flags"),
            ("3F800000 40000000 1234567890 00\n", 1, "result"),
        ];
        for (text, line, what) in cases {
            let (r, _) = run(FpuOp::F32Add, text, 10);
            match r {
                Err(TestFloatError::Parse {
                    line: l,
                    ref message,
                }) => {
                    assert_eq!(l, line, "{text:?}");
                    assert!(message.contains(what), "{message}");
                    let shown = r.unwrap_err().to_string();
                    assert!(shown.starts_with(&format!("line {line}: ")), "{shown}");
                }
                other => panic!("{text:?}: expected a parse error, got {other:?}"),
            }
        }
        let (r, _) = run(FpuOp::F32Lt, "3F800000 40000000 2 00\n", 10);
        assert!(matches!(r, Err(TestFloatError::Parse { line: 1, .. })));
        let mut out = Vec::new();
        let r = check_stream(
            FpuOp::F32Sqrt,
            Cursor::new(&b"4080\xFF0000 40000000 00\n"[..]),
            &mut out,
            1,
        );
        assert!(
            matches!(r, Err(TestFloatError::Parse { line: 1, ref message }) if message.contains("UTF-8"))
        );
    }

    #[test]
    fn write_errors_surface() {
        struct Broken;
        impl Write for Broken {
            fn write(&mut self, _: &[u8]) -> std::io::Result<usize> {
                Err(std::io::Error::other("closed"))
            }
            fn flush(&mut self) -> std::io::Result<()> {
                Ok(())
            }
        }
        let r = check_stream(
            FpuOp::F32Add,
            Cursor::new("3F800000 40000000 40400001 00\n"),
            &mut Broken,
            1,
        );
        assert!(matches!(r, Err(TestFloatError::Io(_))));
    }

    #[test]
    fn committed_softfloat_vectors_pass() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../units/tests/vectors");
        for op in FpuOp::ALL {
            let path = dir.join(format!("{}.txt", op.name()));
            let file =
                std::fs::File::open(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let mut report = Vec::new();
            let s = check_stream(op, std::io::BufReader::new(file), &mut report, 5)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert!(
                s.total() >= 1000 && s.is_success(),
                "{op}: {s}\n{}",
                String::from_utf8_lossy(&report)
            );
        }
        // FTZ vectors pass under the FTZ mode and not all of them under IEEE.
        let path = dir.join("ftz_f32_mul.txt");
        let text = std::fs::read(&path).expect("ftz vectors");
        let ftz = check_stream_with_mode(
            FpuOp::F32Mul,
            FpMode::FTZ,
            Cursor::new(&text),
            &mut Vec::new(),
            0,
        )
        .expect("well-formed");
        assert!(ftz.is_success(), "{ftz}");
        let ieee = check_stream(FpuOp::F32Mul, Cursor::new(&text), &mut Vec::new(), 0)
            .expect("well-formed");
        assert!(
            ieee.failed > 0,
            "FTZ vectors should exercise flushing: {ieee}"
        );
    }
}
