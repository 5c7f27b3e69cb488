//! 32-bit integer datapath of the cluster adders and multipliers (ARCHITECTURE §4), as pure
//! functions on raw bits.
//!
//! Conventions shared by every function here:
//!
//! * Operands and results are raw 32-bit words (`u32`). Whether a word is read as signed
//!   (two's complement) or unsigned is decided by the op, never by the type: `_s` ops read
//!   their operands as two's-complement `i32`, `_u` ops as unsigned, and ops without a suffix
//!   (add, sub, logic, `mul_lo`) give the same bits either way.
//! * No flags: arithmetic wraps modulo 2^32 (there is no saturating 32-bit op).
//! * Shifts take their amount from the **low 5 bits** of the second operand (`b & 31`), as a
//!   32-bit barrel shifter with a 5-bit control does; the upper 27 bits of `b` are ignored, so
//!   a shift by 32 is a shift by 0 and a shift by 33 is a shift by 1.
//! * Compares produce a 1-bit condition (`bool`), which the cluster writes into a condition
//!   code register or feeds to [`select`]. Greater-than forms are the same comparators with the
//!   operands swapped (`a > b` is `lt_s(b, a)`), so they are not listed separately.
//! * The multiplier computes the full 64-bit product; `mul_lo` returns its low half (identical
//!   for signed and unsigned operands), `mul_hi_*` its high half for the operand signedness
//!   named in the suffix.

/// `a + b` modulo 2^32.
#[inline]
pub const fn add(a: u32, b: u32) -> u32 {
    a.wrapping_add(b)
}

/// `a - b` modulo 2^32.
#[inline]
pub const fn sub(a: u32, b: u32) -> u32 {
    a.wrapping_sub(b)
}

/// `0 - a` modulo 2^32 (two's-complement negation; `neg(0x8000_0000) == 0x8000_0000`).
#[inline]
pub const fn neg(a: u32) -> u32 {
    a.wrapping_neg()
}

/// Bitwise AND.
#[inline]
pub const fn and(a: u32, b: u32) -> u32 {
    a & b
}

/// Bitwise OR.
#[inline]
pub const fn or(a: u32, b: u32) -> u32 {
    a | b
}

/// Bitwise XOR.
#[inline]
pub const fn xor(a: u32, b: u32) -> u32 {
    a ^ b
}

/// Bitwise NOT (one's complement).
#[inline]
pub const fn not(a: u32) -> u32 {
    !a
}

/// Logical shift left of `a` by `b & 31`; zeros enter at the bottom.
#[inline]
pub const fn shift_left(a: u32, b: u32) -> u32 {
    a << (b & 31)
}

/// Logical shift right of `a` by `b & 31`; zeros enter at the top.
#[inline]
pub const fn shift_right_logical(a: u32, b: u32) -> u32 {
    a >> (b & 31)
}

/// Arithmetic shift right of `a` by `b & 31`; copies of bit 31 enter at the top.
#[inline]
pub const fn shift_right_arith(a: u32, b: u32) -> u32 {
    ((a as i32) >> (b & 31)) as u32
}

/// `a == b`.
#[inline]
pub const fn eq(a: u32, b: u32) -> bool {
    a == b
}

/// `a != b`.
#[inline]
pub const fn ne(a: u32, b: u32) -> bool {
    a != b
}

/// `a < b`, both read as two's-complement signed.
#[inline]
pub const fn lt_s(a: u32, b: u32) -> bool {
    (a as i32) < (b as i32)
}

/// `a <= b`, both read as two's-complement signed.
#[inline]
pub const fn le_s(a: u32, b: u32) -> bool {
    (a as i32) <= (b as i32)
}

/// `a < b`, both read as unsigned.
#[inline]
pub const fn lt_u(a: u32, b: u32) -> bool {
    a < b
}

/// `a <= b`, both read as unsigned.
#[inline]
pub const fn le_u(a: u32, b: u32) -> bool {
    a <= b
}

/// `cond ? a : b` (the select unit's 2:1 multiplexer).
#[inline]
pub const fn select(cond: bool, a: u32, b: u32) -> u32 {
    if cond { a } else { b }
}

/// Signed minimum.
#[inline]
pub const fn min_s(a: u32, b: u32) -> u32 {
    select(lt_s(a, b), a, b)
}

/// Signed maximum.
#[inline]
pub const fn max_s(a: u32, b: u32) -> u32 {
    select(lt_s(a, b), b, a)
}

/// Unsigned minimum.
#[inline]
pub const fn min_u(a: u32, b: u32) -> u32 {
    select(lt_u(a, b), a, b)
}

/// Unsigned maximum.
#[inline]
pub const fn max_u(a: u32, b: u32) -> u32 {
    select(lt_u(a, b), b, a)
}

/// Absolute value of `a` read as signed, wrapping: `abs_s(0x8000_0000) == 0x8000_0000`
/// (there is no saturation; read the result as unsigned to get the true magnitude 2^31).
#[inline]
pub const fn abs_s(a: u32) -> u32 {
    (a as i32).wrapping_abs() as u32
}

/// Low 32 bits of the 64-bit product `a * b` (the same bits for signed and unsigned operands).
#[inline]
pub const fn mul_lo(a: u32, b: u32) -> u32 {
    a.wrapping_mul(b)
}

/// High 32 bits of the 64-bit product of `a` and `b`, both read as signed.
#[inline]
pub const fn mul_hi_s(a: u32, b: u32) -> u32 {
    (((a as i32 as i64) * (b as i32 as i64)) >> 32) as u32
}

/// High 32 bits of the 64-bit product of `a` and `b`, both read as unsigned.
#[inline]
pub const fn mul_hi_u(a: u32, b: u32) -> u32 {
    (((a as u64) * (b as u64)) >> 32) as u32
}

/// High 32 bits of the 64-bit product of `a` read as signed and `b` read as unsigned.
#[inline]
pub const fn mul_hi_su(a: u32, b: u32) -> u32 {
    (((a as i32 as i64) * (b as i64)) >> 32) as u32
}
