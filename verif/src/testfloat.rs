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
//!
//! [`Datapath`] chooses what is checked: the bit-level datapath one case at a time (the
//! default), or the machine's lane entry point with the host floating-point fast path
//! ([`imagine_units::ops::Op::eval_lanes_host`]), the cases going through it in vectors of
//! [`HOST_LANE_COUNTS`] lanes in turn.

use imagine_units::arith::fp32::testfloat::{Case, Op, format_case, format_result, parse_case};
use imagine_units::arith::fp32::{Flags, FpMode};
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

    /// The machine op that carries this op.
    pub fn machine_op(self) -> imagine_units::ops::Op {
        crate::blocks::fpu::unit_op(self.unit_op())
    }
}

/// Which evaluation of the fp32 ops a check runs: [`Datapath::BitLevel`] checks the
/// fp32 datapath one case at a time (the model of record), [`Datapath::Host`] the machine op
/// over lanes with the host floating-point fast path (`Op::eval_lanes_host`; the bit-level
/// lane datapath for ops without one).
pub use imagine_units::ops::Datapath;

/// The lane counts of the vectors [`Datapath::Host`] evaluates, in turn: a single cluster,
/// leftover lanes only, whole groups of the host path's vectors, and groups with leftovers.
pub const HOST_LANE_COUNTS: [usize; 6] = [1, 3, 8, 16, 32, 37];

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

/// Check a stream of TestFloat vectors for `op` under `mode` on the bit-level datapath; see
/// [`check_stream_on`].
pub fn check_stream_with_mode(
    op: FpuOp,
    mode: FpMode,
    input: impl BufRead,
    mismatches_out: &mut impl Write,
    max_reported: usize,
) -> Result<Summary, TestFloatError> {
    check_stream_on(
        op,
        mode,
        Datapath::BitLevel,
        input,
        mismatches_out,
        max_reported,
    )
}

/// Check a stream of TestFloat vectors for `op` under `mode` on `datapath`.
///
/// Every case is checked; the first `max_reported` mismatches are written to
/// `mismatches_out`, one line each, in line order:
///
/// ```text
/// line 12: f32_add 3F800000 40000000: expected 40400000 flags 00, got 40400001 flags 01
/// ```
///
/// Returns the pass/fail counts, or an error for an unreadable stream, a malformed line
/// (with its number; the cases before it are checked and reported first), or a failed write.
pub fn check_stream_on(
    op: FpuOp,
    mode: FpMode,
    datapath: Datapath,
    mut input: impl BufRead,
    mismatches_out: &mut impl Write,
    max_reported: usize,
) -> Result<Summary, TestFloatError> {
    let unit = op.unit_op();
    let mut checker = Checker {
        op,
        mode,
        datapath,
        summary: Summary::default(),
        reported: 0,
        max_reported,
        batch: Vec::new(),
    };
    // The bit-level datapath takes a case at a time, the host path vectors of lanes.
    let mut batch_sizes = HOST_LANE_COUNTS.into_iter().cycle();
    let mut batch_size = batch_sizes.next().expect("a lane count");
    let mut buf = Vec::with_capacity(64);
    let mut line_no = 0u64;
    loop {
        buf.clear();
        if input.read_until(b'\n', &mut buf)? == 0 {
            break;
        }
        line_no += 1;
        match parse_line(unit, &buf) {
            Ok(None) => {}
            Ok(Some(case)) => {
                checker.batch.push((line_no, case));
                if datapath == Datapath::BitLevel || checker.batch.len() == batch_size {
                    checker.check_batch(mismatches_out)?;
                    batch_size = batch_sizes.next().expect("a cycle");
                }
            }
            Err(message) => {
                checker.check_batch(mismatches_out)?;
                return Err(TestFloatError::Parse {
                    line: line_no,
                    message,
                });
            }
        }
    }
    checker.check_batch(mismatches_out)?;
    Ok(checker.summary)
}

/// One input line: a case, `None` for a blank or comment line, or what is wrong with it.
fn parse_line(op: Op, bytes: &[u8]) -> Result<Option<Case>, String> {
    let line = std::str::from_utf8(bytes).map_err(|_| "not valid UTF-8".to_string())?;
    let line = line.trim();
    if line.is_empty() || line.starts_with('#') {
        return Ok(None);
    }
    parse_case(op, line)
        .map(Some)
        .map_err(|e| format!("{e} (in `{line}`)"))
}

/// The state of one [`check_stream_on`]: the counts so far and the cases read but not yet
/// evaluated, with their line numbers.
struct Checker {
    op: FpuOp,
    mode: FpMode,
    datapath: Datapath,
    summary: Summary,
    reported: usize,
    max_reported: usize,
    batch: Vec<(u64, Case)>,
}

impl Checker {
    /// Evaluate the pending cases on the datapath, count and report them, and clear them.
    fn check_batch(&mut self, mismatches_out: &mut impl Write) -> Result<(), TestFloatError> {
        let unit = self.op.unit_op();
        let got: Vec<(u32, Flags)> = match self.datapath {
            Datapath::BitLevel => self
                .batch
                .iter()
                .map(|(_, case)| unit.eval(case.a, case.b, self.mode))
                .collect(),
            Datapath::Host => {
                let a: Vec<u32> = self.batch.iter().map(|(_, case)| case.a).collect();
                let b: Vec<u32> = self.batch.iter().map(|(_, case)| case.b).collect();
                let (mut out, mut flags) = (vec![0; a.len()], vec![Flags::NONE; a.len()]);
                self.op
                    .machine_op()
                    .eval_lanes_host(&a, &b, &a, self.mode, &mut out, &mut flags);
                out.into_iter().zip(flags).collect()
            }
        };
        for (&(line_no, case), (result, flags)) in self.batch.iter().zip(got) {
            if result == case.result && flags == case.flags {
                self.summary.passed += 1;
                continue;
            }
            self.summary.failed += 1;
            if self.reported < self.max_reported {
                self.reported += 1;
                let operands = format_case(unit, &Case { result: 0, ..case });
                // The formatted case ends with "<result> <flags>": keep only the operands.
                let operands: Vec<&str> = operands.split(' ').take(unit.arity()).collect();
                writeln!(
                    mismatches_out,
                    "line {line_no}: {} {}: expected {} flags {}, got {} flags {}",
                    self.op,
                    operands.join(" "),
                    format_result(unit, case.result),
                    case.flags,
                    format_result(unit, result),
                    flags,
                )?;
            }
        }
        self.batch.clear();
        Ok(())
    }
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

    #[test]
    fn datapaths_parse_and_name_themselves() {
        for d in Datapath::ALL {
            assert_eq!(d.name().parse::<Datapath>(), Ok(d));
            assert_eq!(d.to_string(), d.name());
        }
        assert_eq!(Datapath::default(), Datapath::BitLevel);
        assert!(
            "fast"
                .parse::<Datapath>()
                .unwrap_err()
                .contains("bit-level")
        );
    }

    #[test]
    fn machine_ops_carry_their_testfloat_ops() {
        for op in FpuOp::ALL {
            let (a, b) = (0x3F80_0000, 0x4000_0000);
            assert_eq!(
                op.machine_op().eval(a, b, a, FpMode::IEEE),
                op.unit_op().eval(a, b, FpMode::IEEE),
                "{op}"
            );
        }
    }

    /// The host datapath passes every committed vector file, IEEE and FTZ, in lanes.
    #[test]
    fn committed_softfloat_vectors_pass_on_the_host_datapath() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../units/tests/vectors");
        let ftz_ops = [FpuOp::F32Add, FpuOp::F32Sub, FpuOp::F32Mul];
        let files = FpuOp::ALL
            .map(|op| (op, FpMode::IEEE, format!("{op}.txt")))
            .into_iter()
            .chain(ftz_ops.map(|op| (op, FpMode::FTZ, format!("ftz_{op}.txt"))));
        for (op, mode, name) in files {
            let text = std::fs::read(dir.join(&name)).expect("a vector file");
            let mut report = Vec::new();
            let s = check_stream_on(op, mode, Datapath::Host, &text[..], &mut report, 5)
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(
                s.total() >= 500 && s.is_success(),
                "{name}: {s}\n{}",
                String::from_utf8_lossy(&report)
            );
        }
    }

    /// Both datapaths count and report the same mismatches, in line order, and report those
    /// before a malformed line before its error.
    #[test]
    fn datapaths_report_alike() {
        // Lines 2, 5 and 9 are wrong (vectors of 1, 3 and 8 lanes on the host: lines 1, 2-4,
        // 5-12); line 14 is malformed.
        let mut text = String::new();
        for line in 1..=13 {
            let wrong = [2, 5, 9].contains(&line);
            text += if wrong {
                "3F800000 40000000 40400001 00\n"
            } else {
                "3F800000 40000000 40400000 00\n"
            };
        }
        let check = |datapath, text: &str| {
            let mut report = Vec::new();
            let r = check_stream_on(
                FpuOp::F32Add,
                FpMode::IEEE,
                datapath,
                text.as_bytes(),
                &mut report,
                10,
            );
            (
                r.map_err(|e| e.to_string()),
                String::from_utf8(report).expect("utf-8"),
            )
        };
        let (summary, report) = check(Datapath::Host, &text);
        assert_eq!(
            summary,
            Ok(Summary {
                passed: 10,
                failed: 3
            })
        );
        let lines: Vec<&str> = report.lines().map(|l| &l[..7]).collect();
        assert_eq!(lines, ["line 2:", "line 5:", "line 9:"]);
        assert_eq!(check(Datapath::BitLevel, &text), (summary, report.clone()));
        text += "3F800000\n";
        let (error, host_report) = check(Datapath::Host, &text);
        assert!(error.unwrap_err().starts_with("line 14: "));
        assert_eq!(host_report, report);
    }
}
