//! The op catalogue by Berkeley TestFloat name, and the TestFloat text format.
//!
//! [`Op`] names every fp32 datapath op the way TestFloat's `testfloat_gen` does
//! (`f32_add`, `f32_to_i32`, …), knows its arity and operand/result kinds, evaluates it on
//! our datapath ([`Op::eval`]) and draws operands for it ([`Op::biased_operands`]). The
//! committed vectors, the SoftFloat cross-check, the vector generator example and
//! `imagine-verif`'s `testfloat` checker all go through this table.
//!
//! # TestFloat text format
//!
//! One case per line, fields separated by white space, all hexadecimal: the operands (one
//! for unary ops, two for binary ops), the expected result, and the expected exception flags
//! as two hex digits (inexact 1, underflow 2, overflow 4, infinite 8, invalid 16). Floats and
//! 32-bit integers are written as 8 digits, a boolean compare result as `0` or `1`:
//!
//! ```text
//! 3F800000 40000000 40400000 00
//! ```
//!
//! Conversions to integer follow SoftFloat's `exact = true` (the RISC-V `fcvt` behaviour:
//! inexact is raised); vectors from the real `testfloat_gen` must be made with `-exact`.
//! `f32_min`/`f32_max` are not TestFloat functions; their vectors use the same format with
//! RISC-V `fmin.s`/`fmax.s` semantics.

use super::testgen::{
    CORE_SPECIALS, INT_SPECIALS, SPECIALS, SplitMix64, biased_i32, biased_pair,
    biased_sqrt_operand, biased_to_int_operand,
};
use super::{Flags, FpMode};
use core::fmt;

/// What a field of a case holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kind {
    /// A binary32 bit pattern (8 hex digits).
    F32,
    /// A 32-bit two's-complement integer (8 hex digits).
    I32,
    /// A boolean (`0` or `1`).
    Bool,
}

/// An fp32 op of the datapath, named as in TestFloat.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Op {
    /// `f32_add`
    Add,
    /// `f32_sub`
    Sub,
    /// `f32_mul`
    Mul,
    /// `f32_div`
    Div,
    /// `f32_sqrt`
    Sqrt,
    /// `f32_lt` (signalling)
    Lt,
    /// `f32_le` (signalling)
    Le,
    /// `f32_eq` (quiet)
    Eq,
    /// `f32_min` (RISC-V `fmin.s`; not a TestFloat function)
    Min,
    /// `f32_max` (RISC-V `fmax.s`; not a TestFloat function)
    Max,
    /// `f32_to_i32`, round to nearest even, exact = true
    ToI32,
    /// `f32_to_i32_r_minMag`, round toward zero, exact = true
    ToI32Rtz,
    /// `i32_to_f32`
    FromI32,
}

impl Op {
    /// Every op, in catalogue order.
    pub const ALL: [Op; 13] = [
        Op::Add,
        Op::Sub,
        Op::Mul,
        Op::Div,
        Op::Sqrt,
        Op::Lt,
        Op::Le,
        Op::Eq,
        Op::Min,
        Op::Max,
        Op::ToI32,
        Op::ToI32Rtz,
        Op::FromI32,
    ];

    /// The TestFloat function name.
    pub const fn name(self) -> &'static str {
        match self {
            Op::Add => "f32_add",
            Op::Sub => "f32_sub",
            Op::Mul => "f32_mul",
            Op::Div => "f32_div",
            Op::Sqrt => "f32_sqrt",
            Op::Lt => "f32_lt",
            Op::Le => "f32_le",
            Op::Eq => "f32_eq",
            Op::Min => "f32_min",
            Op::Max => "f32_max",
            Op::ToI32 => "f32_to_i32",
            Op::ToI32Rtz => "f32_to_i32_r_minMag",
            Op::FromI32 => "i32_to_f32",
        }
    }

    /// Look an op up by its TestFloat name.
    pub fn from_name(name: &str) -> Option<Op> {
        Op::ALL.into_iter().find(|op| op.name() == name)
    }

    /// Number of operands (1 or 2).
    pub const fn arity(self) -> usize {
        match self {
            Op::Sqrt | Op::ToI32 | Op::ToI32Rtz | Op::FromI32 => 1,
            _ => 2,
        }
    }

    /// Kind of the operands.
    pub const fn operand_kind(self) -> Kind {
        match self {
            Op::FromI32 => Kind::I32,
            _ => Kind::F32,
        }
    }

    /// Kind of the result.
    pub const fn result_kind(self) -> Kind {
        match self {
            Op::Lt | Op::Le | Op::Eq => Kind::Bool,
            Op::ToI32 | Op::ToI32Rtz => Kind::I32,
            _ => Kind::F32,
        }
    }

    /// Evaluate on the datapath. `b` is ignored by unary ops; a boolean result is 0 or 1.
    #[inline]
    pub fn eval(self, a: u32, b: u32, mode: FpMode) -> (u32, Flags) {
        use super as f;
        let flag = |(r, fl): (bool, Flags)| (r as u32, fl);
        match self {
            Op::Add => f::add(a, b, mode),
            Op::Sub => f::sub(a, b, mode),
            Op::Mul => f::mul(a, b, mode),
            Op::Div => f::div(a, b, mode),
            Op::Sqrt => f::sqrt(a, mode),
            Op::Lt => flag(f::lt(a, b, mode)),
            Op::Le => flag(f::le(a, b, mode)),
            Op::Eq => flag(f::eq(a, b, mode)),
            Op::Min => f::min(a, b, mode),
            Op::Max => f::max(a, b, mode),
            Op::ToI32 => f::to_i32(a, mode),
            Op::ToI32Rtz => f::to_i32_rtz(a, mode),
            Op::FromI32 => f::from_i32(a),
        }
    }

    /// Operands biased to this op's hard cases (`b` is 0 for unary ops).
    pub fn biased_operands(self, rng: &mut SplitMix64) -> (u32, u32) {
        match self {
            Op::FromI32 => (biased_i32(rng), 0),
            Op::Sqrt => (biased_sqrt_operand(rng), 0),
            Op::ToI32 | Op::ToI32Rtz => (biased_to_int_operand(rng), 0),
            _ => biased_pair(rng),
        }
    }

    /// Deterministic edge-case operands: every special for unary ops, the cross product of
    /// the core specials for binary ops.
    pub fn edge_operands(self) -> Vec<(u32, u32)> {
        match self {
            Op::FromI32 => INT_SPECIALS.iter().map(|&a| (a, 0)).collect(),
            Op::Sqrt | Op::ToI32 | Op::ToI32Rtz => SPECIALS.iter().map(|&a| (a, 0)).collect(),
            _ => CORE_SPECIALS
                .iter()
                .flat_map(|&a| CORE_SPECIALS.iter().map(move |&b| (a, b)))
                .collect(),
        }
    }

    /// Uniformly random operand bit patterns (`b` is 0 for unary ops).
    pub fn uniform_operands(self, rng: &mut SplitMix64) -> (u32, u32) {
        let a = rng.next_u32();
        let b = if self.arity() == 2 { rng.next_u32() } else { 0 };
        (a, b)
    }
}

impl fmt::Display for Op {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One test case: operands, expected (or computed) result and flags.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Case {
    /// First operand.
    pub a: u32,
    /// Second operand (0 for unary ops).
    pub b: u32,
    /// Result bits (0/1 for a boolean).
    pub result: u32,
    /// Exception flags.
    pub flags: Flags,
}

/// Why a line is not a valid TestFloat case for an op.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CaseError {
    /// Wrong number of white-space separated fields.
    FieldCount {
        /// Fields the op needs.
        expected: usize,
        /// Fields present.
        found: usize,
    },
    /// A field is not hexadecimal or does not fit its kind.
    BadField {
        /// Which field (`operand 1`, `result`, `flags`, …).
        field: &'static str,
        /// The offending text.
        text: String,
        /// What was expected.
        expected: &'static str,
    },
}

impl fmt::Display for CaseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CaseError::FieldCount { expected, found } => {
                write!(f, "expected {expected} fields, found {found}")
            }
            CaseError::BadField {
                field,
                text,
                expected,
            } => write!(f, "{field} `{text}` is not {expected}"),
        }
    }
}

impl std::error::Error for CaseError {}

fn parse_hex(field: &'static str, text: &str, kind: Kind) -> Result<u32, CaseError> {
    let bad = |expected| CaseError::BadField {
        field,
        text: text.to_string(),
        expected,
    };
    match kind {
        Kind::F32 | Kind::I32 => {
            if text.is_empty() || text.len() > 8 || !text.bytes().all(|c| c.is_ascii_hexdigit()) {
                return Err(bad("1 to 8 hex digits"));
            }
            u32::from_str_radix(text, 16).map_err(|_| bad("1 to 8 hex digits"))
        }
        Kind::Bool => match text {
            "0" => Ok(0),
            "1" => Ok(1),
            _ => Err(bad("0 or 1")),
        },
    }
}

/// Parse one TestFloat line for `op`. Blank lines are the caller's business.
pub fn parse_case(op: Op, line: &str) -> Result<Case, CaseError> {
    let fields: Vec<&str> = line.split_ascii_whitespace().collect();
    let expected = op.arity() + 2;
    if fields.len() != expected {
        return Err(CaseError::FieldCount {
            expected,
            found: fields.len(),
        });
    }
    let a = parse_hex("operand 1", fields[0], op.operand_kind())?;
    let b = if op.arity() == 2 {
        parse_hex("operand 2", fields[1], op.operand_kind())?
    } else {
        0
    };
    let result = parse_hex("result", fields[op.arity()], op.result_kind())?;
    let flag_text = fields[op.arity() + 1];
    let flags = match u8::from_str_radix(flag_text, 16) {
        Ok(v)
            if v < 32
                && flag_text.len() <= 2
                && flag_text.bytes().all(|c| c.is_ascii_hexdigit()) =>
        {
            Flags::from_bits(v)
        }
        _ => {
            return Err(CaseError::BadField {
                field: "flags",
                text: flag_text.to_string(),
                expected: "2 hex digits below 20",
            });
        }
    };
    Ok(Case {
        a,
        b,
        result,
        flags,
    })
}

/// Format a result of `op` as TestFloat prints it (8 hex digits, or `0`/`1`).
pub fn format_result(op: Op, result: u32) -> String {
    match op.result_kind() {
        Kind::Bool => format!("{}", result & 1),
        _ => format!("{result:08X}"),
    }
}

/// Format one case as a TestFloat line (no newline).
pub fn format_case(op: Op, case: &Case) -> String {
    let result = format_result(op, case.result);
    if op.arity() == 2 {
        format!("{:08X} {:08X} {result} {}", case.a, case.b, case.flags)
    } else {
        format!("{:08X} {result} {}", case.a, case.flags)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for op in Op::ALL {
            assert_eq!(Op::from_name(op.name()), Some(op));
        }
        assert_eq!(Op::from_name("f32_foo"), None);
    }

    #[test]
    fn format_and_parse() {
        let c = Case {
            a: 0x3F80_0000,
            b: 0x4000_0000,
            result: 0x4040_0000,
            flags: Flags::NONE,
        };
        let line = format_case(Op::Add, &c);
        assert_eq!(line, "3F800000 40000000 40400000 00");
        assert_eq!(parse_case(Op::Add, &line), Ok(c));
        let lt = Case {
            a: 1,
            b: 2,
            result: 1,
            flags: Flags::INVALID,
        };
        assert_eq!(format_case(Op::Lt, &lt), "00000001 00000002 1 10");
        assert_eq!(parse_case(Op::Lt, "00000001 00000002 1 10"), Ok(lt));
        let s = Case {
            a: 0x4080_0000,
            b: 0,
            result: 0x4000_0000,
            flags: Flags::NONE,
        };
        assert_eq!(format_case(Op::Sqrt, &s), "40800000 40000000 00");
        assert_eq!(parse_case(Op::Sqrt, " 40800000\t40000000 00 "), Ok(s));
    }

    #[test]
    fn parse_errors() {
        assert_eq!(
            parse_case(Op::Add, "3F800000 40000000 00"),
            Err(CaseError::FieldCount {
                expected: 4,
                found: 3
            })
        );
        assert!(matches!(
            parse_case(Op::Add, "3F80000G 40000000 40400000 00"),
            Err(CaseError::BadField {
                field: "operand 1",
                ..
            })
        ));
        assert!(matches!(
            parse_case(Op::Add, "3F800000 140000000 40400000 00"),
            Err(CaseError::BadField {
                field: "operand 2",
                ..
            })
        ));
        assert!(matches!(
            parse_case(Op::Eq, "3F800000 40000000 2 00"),
            Err(CaseError::BadField {
                field: "result",
                ..
            })
        ));
        assert!(matches!(
            parse_case(Op::Add, "3F800000 40000000 40400000 20"),
            Err(CaseError::BadField { field: "flags", .. })
        ));
        assert!(matches!(
            parse_case(Op::Add, "3F800000 40000000 40400000 +1"),
            Err(CaseError::BadField { field: "flags", .. })
        ));
        let msg = parse_case(Op::Sqrt, "zz 0 00").unwrap_err().to_string();
        assert!(msg.contains("operand 1") && msg.contains("zz"), "{msg}");
    }

    #[test]
    fn eval_dispatches() {
        assert_eq!(
            Op::Lt.eval(0x3F80_0000, 0x4000_0000, FpMode::IEEE),
            (1, Flags::NONE)
        );
        assert_eq!(
            Op::FromI32.eval(3, 0, FpMode::IEEE),
            (0x4040_0000, Flags::NONE)
        );
        assert_eq!(
            Op::Sqrt.eval(0x4080_0000, 0xFFFF_FFFF, FpMode::IEEE).0,
            0x4000_0000
        );
    }
}
