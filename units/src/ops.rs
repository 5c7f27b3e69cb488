//! The machine's arithmetic op set: the one place where what an op computes, which unit
//! executes it and how long it takes is defined, shared by the kernel interpreter and the
//! clocked functional units ([`crate::fu`]).
//!
//! Every op is a function of up to three 32-bit words and the machine's [`FpMode`], returning
//! a 32-bit word and the IEEE exception [`Flags`] it raised. The semantics are those of the
//! datapath functions in [`crate::arith`] (`fp32`, `int`, `packed`); [`Op::eval`] only maps
//! an opcode to its function and its operands:
//!
//! * compares ([`Op::FLt`], [`Op::IEq`], …) return `1` or `0` in the word (a condition);
//!   packed compares ([`Op::Eq16x2`], …) return lane masks, as [`crate::arith::packed`]
//!   documents;
//! * [`Op::Select`] takes `(cond, a, b)` and returns `a` where bit 0 of `cond` is set, else
//!   `b` — bit 0 is the 1-bit condition wire, so both a compare's `1` and a packed mask
//!   select `a`;
//! * integer and packed ops never raise flags; fp32 ops raise what Berkeley SoftFloat raises.
//!
//! Units and latencies follow ARCHITECTURE §4: the adders do fp32 add/sub/compare/min/max/
//! abs/neg/convert (latency `fp_add`) and every integer/logic/shift/select/packed op except
//! multiplies (latency `int`); the multipliers do every multiply (latency `mul`); the
//! divide/sqrt unit does [`Op::FDiv`] (latency `div`) and [`Op::FSqrt`] (latency `sqrt`).
//!
//! Mnemonics ([`Op::name`], [`FromStr`]) are lower-case snake forms of the variant names
//! (`fadd`, `imul_hi_s`, `add_sat_16x2_s`) and are the microcode assembler's mnemonics.
//! Opcodes ([`Op::opcode`]) are indices into [`Op::ALL`], stable as long as ops are only
//! appended to the table.

use std::fmt;
use std::str::FromStr;

use crate::arith::flags::Flags;
use crate::arith::fp32::{self, FpMode};
use crate::arith::{int, packed};
use crate::desc::Latency;

/// The kinds of functional unit in a cluster that execute arithmetic ops.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum UnitClass {
    /// fp32/int32 add, sub, compare, convert, logic, shift, select, packed add/sub/compare.
    Adder,
    /// fp32, int32 and packed multiply.
    Multiplier,
    /// fp32 divide and square root (iterative core, see `divsqrt_issue_interval`).
    DivSqrt,
}

impl UnitClass {
    pub const fn name(self) -> &'static str {
        match self {
            UnitClass::Adder => "adder",
            UnitClass::Multiplier => "multiplier",
            UnitClass::DivSqrt => "divide/sqrt unit",
        }
    }
}

impl fmt::Display for UnitClass {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Which latency of the machine description an op takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LatencyClass {
    /// `latency.int`.
    Int,
    /// `latency.fp_add`.
    FpAdd,
    /// `latency.mul`.
    Mul,
    /// `latency.div`.
    Div,
    /// `latency.sqrt`.
    Sqrt,
}

impl LatencyClass {
    /// The latency of this class in `l`, in core cycles.
    #[inline]
    pub const fn of(self, l: &Latency) -> u32 {
        match self {
            LatencyClass::Int => l.int,
            LatencyClass::FpAdd => l.fp_add,
            LatencyClass::Mul => l.mul,
            LatencyClass::Div => l.div,
            LatencyClass::Sqrt => l.sqrt,
        }
    }
}

/// A plain word result, no flags.
#[inline(always)]
const fn w(x: u32) -> (u32, Flags) {
    (x, Flags::NONE)
}

/// An integer condition as a word: 1 or 0, no flags.
#[inline(always)]
const fn cc(x: bool) -> (u32, Flags) {
    (x as u32, Flags::NONE)
}

/// An fp32 compare as a word: 1 or 0, with the compare's flags.
#[inline(always)]
const fn fcc((x, f): (bool, Flags)) -> (u32, Flags) {
    (x as u32, f)
}

/// Generates [`Op`] and every per-op table from one list, so a mnemonic, unit, latency,
/// arity and function can never disagree by being written in two places.
macro_rules! op_table {
    ($(
        $(#[$doc:meta])*
        $v:ident = $name:literal, $unit:ident, $lat:ident, $arity:literal,
            |$a:pat_param, $b:pat_param, $c:pat_param, $m:pat_param| $e:expr;
    )*) => {
        /// An arithmetic op of the machine (see the module documentation).
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        #[repr(u8)]
        pub enum Op {
            $($(#[$doc])* $v,)*
        }

        impl Op {
            /// Every op, in opcode order.
            pub const ALL: &'static [Op] = &[$(Op::$v),*];

            /// The op's mnemonic.
            pub const fn name(self) -> &'static str {
                match self {
                    $(Op::$v => $name,)*
                }
            }

            /// The unit that executes the op.
            #[inline]
            pub const fn unit(self) -> UnitClass {
                match self {
                    $(Op::$v => UnitClass::$unit,)*
                }
            }

            /// Which latency of the machine description the op takes.
            #[inline]
            pub const fn latency_class(self) -> LatencyClass {
                match self {
                    $(Op::$v => LatencyClass::$lat,)*
                }
            }

            /// Number of operands: 1, 2, or 3 ([`Op::Select`]: cond, a, b).
            #[inline]
            pub const fn arity(self) -> usize {
                match self {
                    $(Op::$v => $arity,)*
                }
            }

            /// The op on one set of operands. Operands beyond the arity are ignored.
            #[inline]
            pub fn eval(self, a: u32, b: u32, c: u32, mode: FpMode) -> (u32, Flags) {
                match self {
                    $(Op::$v => {
                        let ($a, $b, $c, $m) = (a, b, c, mode);
                        $e
                    })*
                }
            }

            /// The op on every lane: `out[i], flags[i] = eval(a[i], b[i], c[i])`. The op is
            /// decoded once, outside the lane loop. Operand slices beyond the arity are not
            /// read but must be as long as `out` (pass `a` again for them).
            ///
            /// # Panics
            /// If a slice is shorter than `out` or `flags` is not as long as `out`.
            #[inline]
            pub fn eval_lanes(
                self,
                a: &[u32],
                b: &[u32],
                c: &[u32],
                mode: FpMode,
                out: &mut [u32],
                flags: &mut [Flags],
            ) {
                self.eval_lanes_fixed::<0>(Datapath::BitLevel, [a, b, c], mode, out, flags)
            }

            /// [`eval_lanes`](Self::eval_lanes) on `datapath`, compiled for `L` lanes
            /// (`out.len()` must be `L`), or for any count where `L` is 0: see
            /// [`crate::lanes`].
            #[inline]
            pub fn eval_lanes_fixed<const L: usize>(
                self,
                datapath: Datapath,
                [a, b, c]: [&[u32]; 3],
                mode: FpMode,
                out: &mut [u32],
                flags: &mut [Flags],
            ) {
                let n = crate::lanes::count::<L>(out.len());
                let (a, b, c) = (&a[..n], &b[..n], &c[..n]);
                let (out, flags) = (&mut out[..n], &mut flags[..n]);
                // The fp32 adder and multiplier ops have lane datapaths of their own: a
                // branch-free fast path over all lanes (evaluated several lanes at a time),
                // then the complete datapath for the lanes it could not finish; or the host
                // fast path.
                match (self, datapath) {
                    (Op::FAdd, Datapath::BitLevel) => {
                        return fp32::add::add_lanes(a, b, mode, out, flags);
                    }
                    (Op::FSub, Datapath::BitLevel) => {
                        return fp32::add::sub_lanes(a, b, mode, out, flags);
                    }
                    (Op::FMul, Datapath::BitLevel) => {
                        return fp32::mul::mul_lanes(a, b, mode, out, flags);
                    }
                    (Op::FAdd, Datapath::Host) => {
                        return fp32::host::add_lanes(a, b, mode, out, flags);
                    }
                    (Op::FSub, Datapath::Host) => {
                        return fp32::host::sub_lanes(a, b, mode, out, flags);
                    }
                    (Op::FMul, Datapath::Host) => {
                        return fp32::host::mul_lanes(a, b, mode, out, flags);
                    }
                    (Op::FDiv, Datapath::Host) => {
                        return fp32::host::div_lanes(a, b, mode, out, flags);
                    }
                    (Op::FSqrt, Datapath::Host) => {
                        return fp32::host::sqrt_lanes(a, mode, out, flags);
                    }
                    _ => {}
                }
                match self {
                    $(Op::$v => {
                        for i in 0..n {
                            let ($a, $b, $c, $m) = (a[i], b[i], c[i], mode);
                            let (r, f) = $e;
                            out[i] = r;
                            flags[i] = f;
                        }
                    })*
                }
            }

            fn from_name(s: &str) -> Option<Op> {
                match s {
                    $($name => Some(Op::$v),)*
                    _ => None,
                }
            }
        }
    };
}

op_table! {
    // ---- fp32, adder -------------------------------------------------------------------
    /// fp32 `a + b`.
    FAdd = "fadd", Adder, FpAdd, 2, |a, b, _, m| fp32::add(a, b, m);
    /// fp32 `a - b`.
    FSub = "fsub", Adder, FpAdd, 2, |a, b, _, m| fp32::sub(a, b, m);
    /// fp32 `a < b` (signalling compare) as 1/0.
    FLt = "flt", Adder, FpAdd, 2, |a, b, _, m| fcc(fp32::lt(a, b, m));
    /// fp32 `a <= b` (signalling compare) as 1/0.
    FLe = "fle", Adder, FpAdd, 2, |a, b, _, m| fcc(fp32::le(a, b, m));
    /// fp32 `a == b` (quiet compare) as 1/0.
    FEq = "feq", Adder, FpAdd, 2, |a, b, _, m| fcc(fp32::eq(a, b, m));
    /// fp32 minimum (RISC-V `fmin.s`).
    FMin = "fmin", Adder, FpAdd, 2, |a, b, _, m| fp32::min(a, b, m);
    /// fp32 maximum (RISC-V `fmax.s`).
    FMax = "fmax", Adder, FpAdd, 2, |a, b, _, m| fp32::max(a, b, m);
    /// fp32 absolute value (sign-bit op, never flushes).
    FAbs = "fabs", Adder, FpAdd, 1, |a, _, _, _| w(fp32::abs(a));
    /// fp32 negation (sign-bit op, never flushes).
    FNeg = "fneg", Adder, FpAdd, 1, |a, _, _, _| w(fp32::neg(a));
    /// fp32 to i32, rounding to nearest even.
    FToI32 = "ftoi32", Adder, FpAdd, 1, |a, _, _, m| fp32::to_i32(a, m);
    /// fp32 to i32, rounding toward zero.
    FToI32Trunc = "ftoi32_trunc", Adder, FpAdd, 1, |a, _, _, m| fp32::to_i32_rtz(a, m);
    /// i32 to fp32, rounding to nearest even.
    I32ToF = "i32tof", Adder, FpAdd, 1, |a, _, _, _| fp32::from_i32(a);
    // ---- fp32, multiplier and divide/sqrt ----------------------------------------------
    /// fp32 `a * b`.
    FMul = "fmul", Multiplier, Mul, 2, |a, b, _, m| fp32::mul(a, b, m);
    /// fp32 `a / b`.
    FDiv = "fdiv", DivSqrt, Div, 2, |a, b, _, m| fp32::div(a, b, m);
    /// fp32 square root.
    FSqrt = "fsqrt", DivSqrt, Sqrt, 1, |a, _, _, m| fp32::sqrt(a, m);
    // ---- int32, adder ------------------------------------------------------------------
    /// `a + b` wrapping.
    IAdd = "iadd", Adder, Int, 2, |a, b, _, _| w(int::add(a, b));
    /// `a - b` wrapping.
    ISub = "isub", Adder, Int, 2, |a, b, _, _| w(int::sub(a, b));
    /// `-a` wrapping.
    INeg = "ineg", Adder, Int, 1, |a, _, _, _| w(int::neg(a));
    /// Signed absolute value, wrapping.
    IAbs = "iabs", Adder, Int, 1, |a, _, _, _| w(int::abs_s(a));
    /// Bitwise AND.
    And = "and", Adder, Int, 2, |a, b, _, _| w(int::and(a, b));
    /// Bitwise OR.
    Or = "or", Adder, Int, 2, |a, b, _, _| w(int::or(a, b));
    /// Bitwise XOR.
    Xor = "xor", Adder, Int, 2, |a, b, _, _| w(int::xor(a, b));
    /// Bitwise NOT.
    Not = "not", Adder, Int, 1, |a, _, _, _| w(int::not(a));
    /// Shift left by `b & 31`.
    Shl = "shl", Adder, Int, 2, |a, b, _, _| w(int::shift_left(a, b));
    /// Logical shift right by `b & 31`.
    Shr = "shr", Adder, Int, 2, |a, b, _, _| w(int::shift_right_logical(a, b));
    /// Arithmetic shift right by `b & 31`.
    Sra = "sra", Adder, Int, 2, |a, b, _, _| w(int::shift_right_arith(a, b));
    /// `a == b` as 1/0.
    IEq = "ieq", Adder, Int, 2, |a, b, _, _| cc(int::eq(a, b));
    /// `a != b` as 1/0.
    INe = "ine", Adder, Int, 2, |a, b, _, _| cc(int::ne(a, b));
    /// Signed `a < b` as 1/0.
    ILtS = "ilt_s", Adder, Int, 2, |a, b, _, _| cc(int::lt_s(a, b));
    /// Signed `a <= b` as 1/0.
    ILeS = "ile_s", Adder, Int, 2, |a, b, _, _| cc(int::le_s(a, b));
    /// Unsigned `a < b` as 1/0.
    ILtU = "ilt_u", Adder, Int, 2, |a, b, _, _| cc(int::lt_u(a, b));
    /// Unsigned `a <= b` as 1/0.
    ILeU = "ile_u", Adder, Int, 2, |a, b, _, _| cc(int::le_u(a, b));
    /// Signed minimum.
    IMinS = "imin_s", Adder, Int, 2, |a, b, _, _| w(int::min_s(a, b));
    /// Signed maximum.
    IMaxS = "imax_s", Adder, Int, 2, |a, b, _, _| w(int::max_s(a, b));
    /// Unsigned minimum.
    IMinU = "imin_u", Adder, Int, 2, |a, b, _, _| w(int::min_u(a, b));
    /// Unsigned maximum.
    IMaxU = "imax_u", Adder, Int, 2, |a, b, _, _| w(int::max_u(a, b));
    /// `cond & 1 ? a : b` with operands `(cond, a, b)`.
    Select = "select", Adder, Int, 3, |s, a, b, _| w(int::select(s & 1 != 0, a, b));
    // ---- int32, multiplier -------------------------------------------------------------
    /// Low 32 bits of `a * b`.
    IMulLo = "imul_lo", Multiplier, Mul, 2, |a, b, _, _| w(int::mul_lo(a, b));
    /// High 32 bits of the signed product.
    IMulHiS = "imul_hi_s", Multiplier, Mul, 2, |a, b, _, _| w(int::mul_hi_s(a, b));
    /// High 32 bits of the unsigned product.
    IMulHiU = "imul_hi_u", Multiplier, Mul, 2, |a, b, _, _| w(int::mul_hi_u(a, b));
    /// High 32 bits of signed `a` times unsigned `b`.
    IMulHiSU = "imul_hi_su", Multiplier, Mul, 2, |a, b, _, _| w(int::mul_hi_su(a, b));
    // ---- packed 2×16, adder ------------------------------------------------------------
    /// Lane-wise wrapping add.
    Add16x2 = "add_16x2", Adder, Int, 2, |a, b, _, _| w(packed::add_16x2(a, b));
    /// Lane-wise wrapping subtract.
    Sub16x2 = "sub_16x2", Adder, Int, 2, |a, b, _, _| w(packed::sub_16x2(a, b));
    /// Lane-wise signed saturating add.
    AddSat16x2S = "add_sat_16x2_s", Adder, Int, 2, |a, b, _, _| w(packed::add_sat_s_16x2(a, b));
    /// Lane-wise unsigned saturating add.
    AddSat16x2U = "add_sat_16x2_u", Adder, Int, 2, |a, b, _, _| w(packed::add_sat_u_16x2(a, b));
    /// Lane-wise signed saturating subtract.
    SubSat16x2S = "sub_sat_16x2_s", Adder, Int, 2, |a, b, _, _| w(packed::sub_sat_s_16x2(a, b));
    /// Lane-wise unsigned saturating subtract.
    SubSat16x2U = "sub_sat_16x2_u", Adder, Int, 2, |a, b, _, _| w(packed::sub_sat_u_16x2(a, b));
    /// Lane-wise `a == b` mask.
    Eq16x2 = "eq_16x2", Adder, Int, 2, |a, b, _, _| w(packed::eq_16x2(a, b));
    /// Lane-wise signed `a < b` mask.
    Lt16x2S = "lt_16x2_s", Adder, Int, 2, |a, b, _, _| w(packed::lt_s_16x2(a, b));
    /// Lane-wise signed `a <= b` mask.
    Le16x2S = "le_16x2_s", Adder, Int, 2, |a, b, _, _| w(packed::le_s_16x2(a, b));
    /// Lane-wise unsigned `a < b` mask.
    Lt16x2U = "lt_16x2_u", Adder, Int, 2, |a, b, _, _| w(packed::lt_u_16x2(a, b));
    /// Lane-wise unsigned `a <= b` mask.
    Le16x2U = "le_16x2_u", Adder, Int, 2, |a, b, _, _| w(packed::le_u_16x2(a, b));
    /// Lane-wise signed minimum.
    Min16x2S = "min_16x2_s", Adder, Int, 2, |a, b, _, _| w(packed::min_s_16x2(a, b));
    /// Lane-wise signed maximum.
    Max16x2S = "max_16x2_s", Adder, Int, 2, |a, b, _, _| w(packed::max_s_16x2(a, b));
    /// Lane-wise unsigned minimum.
    Min16x2U = "min_16x2_u", Adder, Int, 2, |a, b, _, _| w(packed::min_u_16x2(a, b));
    /// Lane-wise unsigned maximum.
    Max16x2U = "max_16x2_u", Adder, Int, 2, |a, b, _, _| w(packed::max_u_16x2(a, b));
    // ---- packed 4×8, adder -------------------------------------------------------------
    /// Lane-wise wrapping add.
    Add8x4 = "add_8x4", Adder, Int, 2, |a, b, _, _| w(packed::add_8x4(a, b));
    /// Lane-wise wrapping subtract.
    Sub8x4 = "sub_8x4", Adder, Int, 2, |a, b, _, _| w(packed::sub_8x4(a, b));
    /// Lane-wise signed saturating add.
    AddSat8x4S = "add_sat_8x4_s", Adder, Int, 2, |a, b, _, _| w(packed::add_sat_s_8x4(a, b));
    /// Lane-wise unsigned saturating add.
    AddSat8x4U = "add_sat_8x4_u", Adder, Int, 2, |a, b, _, _| w(packed::add_sat_u_8x4(a, b));
    /// Lane-wise signed saturating subtract.
    SubSat8x4S = "sub_sat_8x4_s", Adder, Int, 2, |a, b, _, _| w(packed::sub_sat_s_8x4(a, b));
    /// Lane-wise unsigned saturating subtract.
    SubSat8x4U = "sub_sat_8x4_u", Adder, Int, 2, |a, b, _, _| w(packed::sub_sat_u_8x4(a, b));
    /// Lane-wise `a == b` mask.
    Eq8x4 = "eq_8x4", Adder, Int, 2, |a, b, _, _| w(packed::eq_8x4(a, b));
    /// Lane-wise signed `a < b` mask.
    Lt8x4S = "lt_8x4_s", Adder, Int, 2, |a, b, _, _| w(packed::lt_s_8x4(a, b));
    /// Lane-wise signed `a <= b` mask.
    Le8x4S = "le_8x4_s", Adder, Int, 2, |a, b, _, _| w(packed::le_s_8x4(a, b));
    /// Lane-wise unsigned `a < b` mask.
    Lt8x4U = "lt_8x4_u", Adder, Int, 2, |a, b, _, _| w(packed::lt_u_8x4(a, b));
    /// Lane-wise unsigned `a <= b` mask.
    Le8x4U = "le_8x4_u", Adder, Int, 2, |a, b, _, _| w(packed::le_u_8x4(a, b));
    /// Lane-wise signed minimum.
    Min8x4S = "min_8x4_s", Adder, Int, 2, |a, b, _, _| w(packed::min_s_8x4(a, b));
    /// Lane-wise signed maximum.
    Max8x4S = "max_8x4_s", Adder, Int, 2, |a, b, _, _| w(packed::max_s_8x4(a, b));
    /// Lane-wise unsigned minimum.
    Min8x4U = "min_8x4_u", Adder, Int, 2, |a, b, _, _| w(packed::min_u_8x4(a, b));
    /// Lane-wise unsigned maximum.
    Max8x4U = "max_8x4_u", Adder, Int, 2, |a, b, _, _| w(packed::max_u_8x4(a, b));
    // ---- packed 2×16, multiplier -------------------------------------------------------
    /// Lane-wise low 16 bits of each lane product.
    Mul16x2Lo = "mul_16x2_lo", Multiplier, Mul, 2, |a, b, _, _| w(packed::mul_lo_16x2(a, b));
    /// Lane-wise high 16 bits of each signed lane product.
    Mul16x2HiS = "mul_16x2_hi_s", Multiplier, Mul, 2, |a, b, _, _| w(packed::mul_hi_s_16x2(a, b));
    /// Lane-wise high 16 bits of each unsigned lane product.
    Mul16x2HiU = "mul_16x2_hi_u", Multiplier, Mul, 2, |a, b, _, _| w(packed::mul_hi_u_16x2(a, b));
    // ---- appended ops (opcodes are indices, so new ops go last) ------------------------
    /// Copies a word: the compiler's register move, from one LRF to others.
    Mov = "mov", Adder, Int, 1, |a, _, _, _| w(a);
}

/// What evaluates `fadd`, `fsub`, `fmul`, `fdiv` and `fsqrt` over lanes: the bit-level datapath
/// ([`crate::arith::fp32`], the model of record) or the host floating-point fast path
/// ([`fp32::host`]: the same words and flags, proven and cross-checked against SoftFloat,
/// computed with the host's IEEE arithmetic where that is exact). Every other op has one
/// datapath.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Datapath {
    #[default]
    BitLevel,
    Host,
}

impl Datapath {
    /// Every datapath.
    pub const ALL: [Datapath; 2] = [Datapath::BitLevel, Datapath::Host];

    /// The name `--datapath` takes.
    pub const fn name(self) -> &'static str {
        match self {
            Datapath::BitLevel => "bit-level",
            Datapath::Host => "host",
        }
    }
}

impl fmt::Display for Datapath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Datapath {
    type Err = String;

    /// `bit-level` or `host`.
    fn from_str(s: &str) -> Result<Datapath, String> {
        Datapath::ALL
            .into_iter()
            .find(|d| d.name() == s)
            .ok_or_else(|| format!("unknown datapath `{s}` (expected bit-level or host)"))
    }
}

impl Op {
    /// Width of an opcode field (and of the `op` probes of the units).
    pub const OPCODE_BITS: u32 = imagine_hdl::bits_for((Op::ALL.len() - 1) as u64);

    /// [`Op::eval_lanes`] with the host floating-point fast path ([`fp32::host`]) for
    /// [`Op::FAdd`], [`Op::FSub`], [`Op::FMul`], [`Op::FDiv`] and [`Op::FSqrt`]: the same
    /// result words and flags on every lane (proven, and cross-checked against SoftFloat),
    /// computed with the host's IEEE arithmetic where that is exact and by the bit-level
    /// datapath elsewhere. Every other op is [`Op::eval_lanes`]. The bit-level
    /// [`Op::eval_lanes`] stays the model of record.
    ///
    /// # Panics
    /// As [`Op::eval_lanes`]: if a slice is shorter than `out` or `flags` is not as long as
    /// `out`.
    #[inline]
    pub fn eval_lanes_host(
        self,
        a: &[u32],
        b: &[u32],
        c: &[u32],
        mode: FpMode,
        out: &mut [u32],
        flags: &mut [Flags],
    ) {
        self.eval_lanes_fixed::<0>(Datapath::Host, [a, b, c], mode, out, flags)
    }

    /// The op's latency in core cycles under `l`.
    #[inline]
    pub const fn latency(self, l: &Latency) -> u32 {
        self.latency_class().of(l)
    }

    /// How a waveform shows an opcode probe: by mnemonic.
    pub fn display() -> imagine_hdl::Display {
        static NAMES: std::sync::LazyLock<Vec<&'static str>> =
            std::sync::LazyLock::new(|| Op::ALL.iter().map(|o| o.name()).collect());
        imagine_hdl::Display::Names(&NAMES)
    }

    /// The opcode: the op's index in [`Op::ALL`] (fits [`Op::OPCODE_BITS`] bits).
    #[inline]
    pub const fn opcode(self) -> u8 {
        self as u8
    }

    /// The op of an opcode, if there is one.
    #[inline]
    pub fn from_opcode(code: u8) -> Option<Op> {
        Op::ALL.get(code as usize).copied()
    }

    /// True for compares that return a 1/0 condition word (not the packed mask compares).
    pub const fn is_condition(self) -> bool {
        matches!(
            self,
            Op::FLt
                | Op::FLe
                | Op::FEq
                | Op::IEq
                | Op::INe
                | Op::ILtS
                | Op::ILeS
                | Op::ILtU
                | Op::ILeU
        )
    }
}

impl fmt::Display for Op {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A mnemonic that names no op.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnknownOp(pub String);

impl fmt::Display for UnknownOp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "unknown op mnemonic `{}`", self.0)
    }
}

impl std::error::Error for UnknownOp {}

impl FromStr for Op {
    type Err = UnknownOp;

    /// Parses a mnemonic (exactly as [`Op::name`] spells it).
    fn from_str(s: &str) -> Result<Op, UnknownOp> {
        Op::from_name(s).ok_or_else(|| UnknownOp(s.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn opcodes_are_indices_and_fit() {
        for (i, op) in Op::ALL.iter().enumerate() {
            assert_eq!(op.opcode() as usize, i);
            assert_eq!(Op::from_opcode(i as u8), Some(*op));
            assert!(u32::from(op.opcode()) < 1 << Op::OPCODE_BITS);
        }
        assert_eq!(Op::from_opcode(Op::ALL.len() as u8), None);
        assert!(Op::ALL.len() > 1 << (Op::OPCODE_BITS - 1));
    }
}
