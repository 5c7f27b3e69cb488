//! The op table (`imagine_units::ops`) against the datapath functions it maps to: every op's
//! `eval` equals a direct call of its `arith` function on random operands, mnemonics
//! round-trip, and units / latencies / arities match ARCHITECTURE §4.

use imagine_units::arith::flags::Flags;
use imagine_units::arith::fp32::testgen::{SplitMix64, biased_f32, biased_i32};
use imagine_units::arith::fp32::{self, FpMode};
use imagine_units::arith::{int, packed};
use imagine_units::desc::MachineDesc;
use imagine_units::ops::{LatencyClass, Op, UnitClass};

type Reference = fn(u32, u32, u32, FpMode) -> (u32, Flags);

/// Written independently of the op table: what each op must compute.
fn reference(op: Op) -> Reference {
    fn nf(x: u32) -> (u32, Flags) {
        (x, Flags::NONE)
    }
    fn b(x: bool) -> (u32, Flags) {
        (u32::from(x), Flags::NONE)
    }
    fn fb((x, f): (bool, Flags)) -> (u32, Flags) {
        (u32::from(x), f)
    }
    match op {
        Op::FAdd => |a, b, _, m| fp32::add(a, b, m),
        Op::FSub => |a, b, _, m| fp32::sub(a, b, m),
        Op::FLt => |a, b, _, m| fb(fp32::lt(a, b, m)),
        Op::FLe => |a, b, _, m| fb(fp32::le(a, b, m)),
        Op::FEq => |a, b, _, m| fb(fp32::eq(a, b, m)),
        Op::FMin => |a, b, _, m| fp32::min(a, b, m),
        Op::FMax => |a, b, _, m| fp32::max(a, b, m),
        Op::FAbs => |a, _, _, _| nf(fp32::abs(a)),
        Op::FNeg => |a, _, _, _| nf(fp32::neg(a)),
        Op::FToI32 => |a, _, _, m| fp32::to_i32(a, m),
        Op::FToI32Trunc => |a, _, _, m| fp32::to_i32_rtz(a, m),
        Op::I32ToF => |a, _, _, _| fp32::from_i32(a),
        Op::FMul => |a, b, _, m| fp32::mul(a, b, m),
        Op::FDiv => |a, b, _, m| fp32::div(a, b, m),
        Op::FSqrt => |a, _, _, m| fp32::sqrt(a, m),
        Op::IAdd => |a, b_, _, _| nf(int::add(a, b_)),
        Op::ISub => |a, b_, _, _| nf(int::sub(a, b_)),
        Op::INeg => |a, _, _, _| nf(int::neg(a)),
        Op::IAbs => |a, _, _, _| nf(int::abs_s(a)),
        Op::And => |a, b_, _, _| nf(int::and(a, b_)),
        Op::Or => |a, b_, _, _| nf(int::or(a, b_)),
        Op::Xor => |a, b_, _, _| nf(int::xor(a, b_)),
        Op::Not => |a, _, _, _| nf(int::not(a)),
        Op::Shl => |a, b_, _, _| nf(int::shift_left(a, b_)),
        Op::Shr => |a, b_, _, _| nf(int::shift_right_logical(a, b_)),
        Op::Sra => |a, b_, _, _| nf(int::shift_right_arith(a, b_)),
        Op::IEq => |a, b_, _, _| b(int::eq(a, b_)),
        Op::INe => |a, b_, _, _| b(int::ne(a, b_)),
        Op::ILtS => |a, b_, _, _| b(int::lt_s(a, b_)),
        Op::ILeS => |a, b_, _, _| b(int::le_s(a, b_)),
        Op::ILtU => |a, b_, _, _| b(int::lt_u(a, b_)),
        Op::ILeU => |a, b_, _, _| b(int::le_u(a, b_)),
        Op::IMinS => |a, b_, _, _| nf(int::min_s(a, b_)),
        Op::IMaxS => |a, b_, _, _| nf(int::max_s(a, b_)),
        Op::IMinU => |a, b_, _, _| nf(int::min_u(a, b_)),
        Op::IMaxU => |a, b_, _, _| nf(int::max_u(a, b_)),
        Op::Select => |s, x, y, _| nf(int::select(s & 1 == 1, x, y)),
        Op::IMulLo => |a, b_, _, _| nf(int::mul_lo(a, b_)),
        Op::IMulHiS => |a, b_, _, _| nf(int::mul_hi_s(a, b_)),
        Op::IMulHiU => |a, b_, _, _| nf(int::mul_hi_u(a, b_)),
        Op::IMulHiSU => |a, b_, _, _| nf(int::mul_hi_su(a, b_)),
        Op::Add16x2 => |a, b_, _, _| nf(packed::add_16x2(a, b_)),
        Op::Sub16x2 => |a, b_, _, _| nf(packed::sub_16x2(a, b_)),
        Op::AddSat16x2S => |a, b_, _, _| nf(packed::add_sat_s_16x2(a, b_)),
        Op::AddSat16x2U => |a, b_, _, _| nf(packed::add_sat_u_16x2(a, b_)),
        Op::SubSat16x2S => |a, b_, _, _| nf(packed::sub_sat_s_16x2(a, b_)),
        Op::SubSat16x2U => |a, b_, _, _| nf(packed::sub_sat_u_16x2(a, b_)),
        Op::Eq16x2 => |a, b_, _, _| nf(packed::eq_16x2(a, b_)),
        Op::Lt16x2S => |a, b_, _, _| nf(packed::lt_s_16x2(a, b_)),
        Op::Le16x2S => |a, b_, _, _| nf(packed::le_s_16x2(a, b_)),
        Op::Lt16x2U => |a, b_, _, _| nf(packed::lt_u_16x2(a, b_)),
        Op::Le16x2U => |a, b_, _, _| nf(packed::le_u_16x2(a, b_)),
        Op::Min16x2S => |a, b_, _, _| nf(packed::min_s_16x2(a, b_)),
        Op::Max16x2S => |a, b_, _, _| nf(packed::max_s_16x2(a, b_)),
        Op::Min16x2U => |a, b_, _, _| nf(packed::min_u_16x2(a, b_)),
        Op::Max16x2U => |a, b_, _, _| nf(packed::max_u_16x2(a, b_)),
        Op::Add8x4 => |a, b_, _, _| nf(packed::add_8x4(a, b_)),
        Op::Sub8x4 => |a, b_, _, _| nf(packed::sub_8x4(a, b_)),
        Op::AddSat8x4S => |a, b_, _, _| nf(packed::add_sat_s_8x4(a, b_)),
        Op::AddSat8x4U => |a, b_, _, _| nf(packed::add_sat_u_8x4(a, b_)),
        Op::SubSat8x4S => |a, b_, _, _| nf(packed::sub_sat_s_8x4(a, b_)),
        Op::SubSat8x4U => |a, b_, _, _| nf(packed::sub_sat_u_8x4(a, b_)),
        Op::Eq8x4 => |a, b_, _, _| nf(packed::eq_8x4(a, b_)),
        Op::Lt8x4S => |a, b_, _, _| nf(packed::lt_s_8x4(a, b_)),
        Op::Le8x4S => |a, b_, _, _| nf(packed::le_s_8x4(a, b_)),
        Op::Lt8x4U => |a, b_, _, _| nf(packed::lt_u_8x4(a, b_)),
        Op::Le8x4U => |a, b_, _, _| nf(packed::le_u_8x4(a, b_)),
        Op::Min8x4S => |a, b_, _, _| nf(packed::min_s_8x4(a, b_)),
        Op::Max8x4S => |a, b_, _, _| nf(packed::max_s_8x4(a, b_)),
        Op::Min8x4U => |a, b_, _, _| nf(packed::min_u_8x4(a, b_)),
        Op::Max8x4U => |a, b_, _, _| nf(packed::max_u_8x4(a, b_)),
        Op::Mul16x2Lo => |a, b_, _, _| nf(packed::mul_lo_16x2(a, b_)),
        Op::Mul16x2HiS => |a, b_, _, _| nf(packed::mul_hi_s_16x2(a, b_)),
        Op::Mul16x2HiU => |a, b_, _, _| nf(packed::mul_hi_u_16x2(a, b_)),
        Op::Mov => |a, _, _, _| nf(a),
    }
}

fn is_fp_operand(op: Op) -> bool {
    op.name().starts_with('f')
}

/// Operands for `op`: fp-biased for fp ops, edge-biased integers otherwise; sometimes equal
/// (so `lt` and `le`, `min` and `max` differ) and sometimes sharing lanes.
fn operands(op: Op, rng: &mut SplitMix64) -> (u32, u32, u32) {
    let word = |rng: &mut SplitMix64| {
        if is_fp_operand(op) {
            biased_f32(rng)
        } else {
            biased_i32(rng)
        }
    };
    let a = word(rng);
    let b = match rng.below(8) {
        0 => a,
        1 => (a & 0xFFFF_0000) | (word(rng) & 0xFFFF),
        2 => (a & 0x00FF_00FF) | (word(rng) & 0xFF00_FF00),
        _ => word(rng),
    };
    let c = word(rng);
    (a, b, c)
}

#[test]
fn every_op_evaluates_its_datapath_function() {
    let mut rng = SplitMix64::new(0x0F5_0B5);
    for &op in Op::ALL {
        let f = reference(op);
        for mode in [FpMode::IEEE, FpMode::FTZ] {
            for _ in 0..3000 {
                let (a, b, c) = operands(op, &mut rng);
                assert_eq!(
                    op.eval(a, b, c, mode),
                    f(a, b, c, mode),
                    "{op} {a:#010x} {b:#010x} {c:#010x} {mode:?}"
                );
            }
        }
    }
}

#[test]
fn lane_evaluation_equals_scalar_evaluation() {
    let mut rng = SplitMix64::new(7);
    let n = 13;
    for &op in Op::ALL {
        let ops: Vec<_> = (0..n).map(|_| operands(op, &mut rng)).collect();
        let a: Vec<u32> = ops.iter().map(|o| o.0).collect();
        let b: Vec<u32> = ops.iter().map(|o| o.1).collect();
        let c: Vec<u32> = ops.iter().map(|o| o.2).collect();
        let mut out = vec![0; n];
        let mut flags = vec![Flags::NONE; n];
        op.eval_lanes(&a, &b, &c, FpMode::IEEE, &mut out, &mut flags);
        for i in 0..n {
            assert_eq!(
                (out[i], flags[i]),
                op.eval(a[i], b[i], c[i], FpMode::IEEE),
                "{op} lane {i}"
            );
        }
    }
}

#[test]
fn operands_beyond_the_arity_are_ignored() {
    let mut rng = SplitMix64::new(11);
    for &op in Op::ALL {
        for _ in 0..200 {
            let (a, b, c) = operands(op, &mut rng);
            let (x, y) = (rng.next_u32(), rng.next_u32());
            let got = op.eval(a, b, c, FpMode::IEEE);
            match op.arity() {
                1 => assert_eq!(got, op.eval(a, x, y, FpMode::IEEE), "{op}"),
                2 => assert_eq!(got, op.eval(a, b, y, FpMode::IEEE), "{op}"),
                3 => {}
                n => panic!("{op}: arity {n}"),
            }
        }
    }
}

#[test]
fn selected_examples() {
    let m = FpMode::IEEE;
    assert_eq!(
        Op::FAdd.eval(0x3F80_0000, 0x4000_0000, 0, m),
        (0x4040_0000, Flags::NONE)
    );
    assert_eq!(
        Op::FLt.eval(0x3F80_0000, 0x4000_0000, 0, m),
        (1, Flags::NONE)
    );
    assert_eq!(
        Op::FLt.eval(0x7FC0_0000, 0, 0, m),
        (0, Flags::INVALID),
        "signalling compare on a quiet NaN"
    );
    assert_eq!(Op::ILtS.eval(0xFFFF_FFFF, 0, 0, m), (1, Flags::NONE));
    assert_eq!(Op::ILtU.eval(0xFFFF_FFFF, 0, 0, m), (0, Flags::NONE));
    assert_eq!(Op::Select.eval(1, 10, 20, m).0, 10);
    assert_eq!(Op::Select.eval(0, 10, 20, m).0, 20);
    assert_eq!(
        Op::Select.eval(0xFFFF_FFFF, 10, 20, m).0,
        10,
        "mask selects a"
    );
    assert_eq!(
        Op::Select.eval(2, 10, 20, m).0,
        20,
        "only bit 0 is the condition"
    );
    assert_eq!(
        Op::Eq16x2.eval(0x1234_5678, 0x1234_0000, 0, m).0,
        0xFFFF_0000
    );
    assert_eq!(
        Op::FDiv.eval(0x3F80_0000, 0, 0, m),
        (0x7F80_0000, Flags::INFINITE)
    );
}

#[test]
fn mnemonics_round_trip_and_are_unique() {
    let mut seen = std::collections::HashSet::new();
    for &op in Op::ALL {
        let name = op.name();
        assert!(seen.insert(name), "duplicate mnemonic {name}");
        assert_eq!(name, name.to_lowercase());
        assert!(!name.contains(' '));
        assert_eq!(name.parse::<Op>(), Ok(op));
        assert_eq!(op.to_string(), name);
    }
    for (name, op) in [
        ("fadd", Op::FAdd),
        ("imul_hi_s", Op::IMulHiS),
        ("add_sat_16x2_s", Op::AddSat16x2S),
        ("sub_sat_8x4_u", Op::SubSat8x4U),
        ("ftoi32_trunc", Op::FToI32Trunc),
        ("i32tof", Op::I32ToF),
        ("select", Op::Select),
    ] {
        assert_eq!(name.parse::<Op>(), Ok(op));
    }
    let e = "fadd.s".parse::<Op>().unwrap_err();
    assert!(e.to_string().contains("fadd.s"), "{e}");
    assert!("FADD".parse::<Op>().is_err());
}

#[test]
fn opcodes_index_the_op_list() {
    assert!(Op::ALL.len() <= 1 << Op::OPCODE_BITS);
    assert!(
        Op::ALL.len() > 1 << (Op::OPCODE_BITS - 1),
        "OPCODE_BITS is minimal"
    );
    for (i, &op) in Op::ALL.iter().enumerate() {
        assert_eq!(usize::from(op.opcode()), i);
        assert_eq!(Op::from_opcode(op.opcode()), Some(op));
    }
    assert_eq!(Op::from_opcode(u8::MAX), None);
}

/// ARCHITECTURE §4: adders do fp32/int32 add, sub, compare, convert, logic, shift, select
/// and packed 16/8-bit add/sub/compare/min/max; multipliers every multiply; DivSqrt div and
/// sqrt.
#[test]
fn units_latencies_and_arities_follow_the_architecture() {
    const MULTIPLIES: [Op; 8] = [
        Op::FMul,
        Op::IMulLo,
        Op::IMulHiS,
        Op::IMulHiU,
        Op::IMulHiSU,
        Op::Mul16x2Lo,
        Op::Mul16x2HiS,
        Op::Mul16x2HiU,
    ];
    const FP_ADDER: [Op; 12] = [
        Op::FAdd,
        Op::FSub,
        Op::FLt,
        Op::FLe,
        Op::FEq,
        Op::FMin,
        Op::FMax,
        Op::FAbs,
        Op::FNeg,
        Op::FToI32,
        Op::FToI32Trunc,
        Op::I32ToF,
    ];
    const UNARY: [Op; 10] = [
        Op::FSqrt,
        Op::FAbs,
        Op::FNeg,
        Op::FToI32,
        Op::FToI32Trunc,
        Op::I32ToF,
        Op::INeg,
        Op::IAbs,
        Op::Not,
        Op::Mov,
    ];
    // Distinct values so a wrong latency class cannot pass by coincidence.
    let mut desc = MachineDesc::gold8();
    desc.latency.int = 3;
    desc.latency.fp_add = 5;
    desc.latency.mul = 7;
    desc.latency.div = 17;
    desc.latency.sqrt = 19;
    let l = &desc.latency;
    for &op in Op::ALL {
        let (unit, lat) = match op {
            Op::FDiv => (UnitClass::DivSqrt, 17),
            Op::FSqrt => (UnitClass::DivSqrt, 19),
            _ if MULTIPLIES.contains(&op) => (UnitClass::Multiplier, 7),
            _ if FP_ADDER.contains(&op) => (UnitClass::Adder, 5),
            _ => (UnitClass::Adder, 3),
        };
        assert_eq!(op.unit(), unit, "{op}");
        assert_eq!(op.latency(l), lat, "{op}");
        let arity = match op {
            Op::Select => 3,
            _ if UNARY.contains(&op) => 1,
            _ => 2,
        };
        assert_eq!(op.arity(), arity, "{op}");
    }
    // gold8 itself: int 2, fp add 4, mul 4, div 16, sqrt 16.
    let g = MachineDesc::gold8().latency;
    assert_eq!(Op::IAdd.latency(&g), 2);
    assert_eq!(Op::Add8x4.latency(&g), 2);
    assert_eq!(Op::FAdd.latency(&g), 4);
    assert_eq!(Op::I32ToF.latency(&g), 4);
    assert_eq!(Op::IMulLo.latency(&g), 4);
    assert_eq!(Op::FDiv.latency(&g), 16);
    assert_eq!(Op::FSqrt.latency(&g), 16);
    assert_eq!(Op::FSqrt.latency_class(), LatencyClass::Sqrt);
    // Every unit class has ops, and the op list covers each arith module.
    for class in [UnitClass::Adder, UnitClass::Multiplier, UnitClass::DivSqrt] {
        assert!(Op::ALL.iter().any(|o| o.unit() == class));
    }
    assert_eq!(
        Op::ALL.len(),
        15 + 26 + 33 + 1,
        "fp32, int32, packed, and `mov`"
    );
}
