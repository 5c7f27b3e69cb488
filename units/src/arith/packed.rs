//! Packed-subword datapath of the cluster adders and multipliers (ARCHITECTURE §4): a 32-bit
//! word holds two 16-bit lanes (`_16x2` ops) or four 8-bit lanes (`_8x4` ops), and every op
//! acts on each lane independently, as pure functions on raw bits.
//!
//! Lane layout: lane 0 is the least significant bits. For `_16x2`, lane 0 is bits 15:0 and
//! lane 1 is bits 31:16; for `_8x4`, lane *i* is bits `8i+7 : 8i`.
//!
//! Conventions:
//!
//! * Plain `add`/`sub` wrap modulo 2^16 (or 2^8) per lane; no carry or borrow crosses a lane
//!   boundary.
//! * `_sat_s` ops read lanes as two's-complement signed and clamp to `[-2^(w-1), 2^(w-1)-1]`;
//!   `_sat_u` ops read lanes as unsigned and clamp to `[0, 2^w-1]`.
//! * Compares (`eq`, `lt_*`, `le_*`) return a lane mask: all ones in a lane where the
//!   condition holds, all zeros where it does not (so the result can feed a bitwise select).
//! * `mul_lo_16x2` returns the low 16 bits of each 16×16 lane product (the same bits for
//!   signed and unsigned lanes); `mul_hi_s_16x2` / `mul_hi_u_16x2` the high 16 bits of the
//!   32-bit lane product for signed / unsigned lanes.
//!
//! The adder-side ops are written SWAR-style, as the hardware builds them: one 32-bit adder
//! whose carry chain is cut at each lane boundary. Masking off each lane's top bit before the
//! add means no carry can leave a lane; the lane's top sum bit is then restored with an XOR
//! (sum bit = a ^ b ^ carry-in). Lane carry-outs and signed overflows come from the usual
//! top-bit formulas and are smeared across their lane to drive saturation and compare masks.

/// Lane geometry for lanes of `W` bits in a 32-bit word.
struct Lanes<const W: u32>;

impl<const W: u32> Lanes<W> {
    /// The most significant bit of every lane (`0x8000_8000` or `0x8080_8080`).
    const TOP: u32 = {
        let mut m = 0u32;
        let mut i = 0;
        while i < 32 / W {
            m |= 1 << (i * W + W - 1);
            i += 1;
        }
        m
    };
    /// Every bit except each lane's most significant bit.
    const LOW: u32 = !Self::TOP;
}

/// Spread a mask holding only lane top bits over the whole lane: each lane becomes all ones if
/// its top bit was set, else all zeros.
#[inline(always)]
const fn smear<const W: u32>(top_bits: u32) -> u32 {
    // `top_bits - (top_bits >> (W-1))` sets bits W-2:0 of each flagged lane and never borrows
    // across lanes; OR-ing the top bits back completes the lane.
    top_bits | (top_bits - (top_bits >> (W - 1)))
}

/// Lane-wise wrapping add. The low bits of a lane sum to at most 2^W - 2, so their carry stops
/// in the lane's top bit; XOR with a ^ b turns that carry-in into the true top sum bit.
#[inline(always)]
const fn add_lanes<const W: u32>(a: u32, b: u32) -> u32 {
    ((a & Lanes::<W>::LOW) + (b & Lanes::<W>::LOW)) ^ ((a ^ b) & Lanes::<W>::TOP)
}

#[inline(always)]
const fn sub_lanes<const W: u32>(a: u32, b: u32) -> u32 {
    // Setting each lane's top bit of `a` and clearing it in `b` means no lane borrows from its
    // neighbour. The computed top bit is then !borrow-in; XOR with a ^ !b turns it into the
    // true difference bit a ^ b ^ borrow-in.
    ((a | Lanes::<W>::TOP) - (b & Lanes::<W>::LOW)) ^ ((a ^ !b) & Lanes::<W>::TOP)
}

/// Top bit of each lane set where the unsigned lane add `a + b` carries out.
#[inline(always)]
const fn carry_out<const W: u32>(a: u32, b: u32, sum: u32) -> u32 {
    ((a & b) | ((a | b) & !sum)) & Lanes::<W>::TOP
}

/// Top bit of each lane set where the unsigned lane subtract `a - b` borrows (i.e. `a < b`).
#[inline(always)]
const fn borrow_out<const W: u32>(a: u32, b: u32, diff: u32) -> u32 {
    ((!a & b) | (!(a ^ b) & diff)) & Lanes::<W>::TOP
}

/// Per-lane saturation value chosen by the sign of `a`: `0111…` for non-negative lanes,
/// `1000…` for negative ones (`0111…` + 1, which never carries out of the lane).
#[inline(always)]
const fn signed_limit<const W: u32>(a: u32) -> u32 {
    Lanes::<W>::LOW + ((a & Lanes::<W>::TOP) >> (W - 1))
}

#[inline(always)]
const fn add_sat_u_lanes<const W: u32>(a: u32, b: u32) -> u32 {
    let sum = add_lanes::<W>(a, b);
    sum | smear::<W>(carry_out::<W>(a, b, sum))
}

#[inline(always)]
const fn sub_sat_u_lanes<const W: u32>(a: u32, b: u32) -> u32 {
    let diff = sub_lanes::<W>(a, b);
    diff & !smear::<W>(borrow_out::<W>(a, b, diff))
}

#[inline(always)]
const fn add_sat_s_lanes<const W: u32>(a: u32, b: u32) -> u32 {
    let sum = add_lanes::<W>(a, b);
    // Overflow: operands have the same sign and the sum's sign differs.
    let ovf = smear::<W>(!(a ^ b) & (a ^ sum) & Lanes::<W>::TOP);
    (sum & !ovf) | (signed_limit::<W>(a) & ovf)
}

#[inline(always)]
const fn sub_sat_s_lanes<const W: u32>(a: u32, b: u32) -> u32 {
    let diff = sub_lanes::<W>(a, b);
    // Overflow: operands have different signs and the difference's sign differs from a's.
    let ovf = smear::<W>((a ^ b) & (a ^ diff) & Lanes::<W>::TOP);
    (diff & !ovf) | (signed_limit::<W>(a) & ovf)
}

#[inline(always)]
const fn eq_lanes<const W: u32>(a: u32, b: u32) -> u32 {
    let x = a ^ b;
    // Top bit of each lane set iff the lane of x is nonzero (low bits carried into the top bit,
    // or the top bit itself set); no carry crosses lanes because the top bits are masked off.
    let nonzero = (((x & Lanes::<W>::LOW) + Lanes::<W>::LOW) | x) & Lanes::<W>::TOP;
    smear::<W>(nonzero ^ Lanes::<W>::TOP)
}

#[inline(always)]
const fn lt_u_lanes<const W: u32>(a: u32, b: u32) -> u32 {
    smear::<W>(borrow_out::<W>(a, b, sub_lanes::<W>(a, b)))
}

#[inline(always)]
const fn lt_s_lanes<const W: u32>(a: u32, b: u32) -> u32 {
    // Flipping the sign bits maps two's-complement order onto unsigned order.
    lt_u_lanes::<W>(a ^ Lanes::<W>::TOP, b ^ Lanes::<W>::TOP)
}

#[inline(always)]
const fn pick(mask: u32, a: u32, b: u32) -> u32 {
    (a & mask) | (b & !mask)
}

macro_rules! lane_ops {
    ($w:literal, $lanes:literal,
     $add:ident, $sub:ident, $add_sat_s:ident, $add_sat_u:ident, $sub_sat_s:ident,
     $sub_sat_u:ident, $eq:ident, $lt_s:ident, $le_s:ident, $lt_u:ident, $le_u:ident,
     $min_s:ident, $max_s:ident, $min_u:ident, $max_u:ident) => {
        #[doc = concat!("Lane-wise ", $lanes, "×", $w, "-bit `a + b`, wrapping in each lane.")]
        #[inline]
        pub const fn $add(a: u32, b: u32) -> u32 {
            add_lanes::<$w>(a, b)
        }

        #[doc = concat!("Lane-wise ", $lanes, "×", $w, "-bit `a - b`, wrapping in each lane.")]
        #[inline]
        pub const fn $sub(a: u32, b: u32) -> u32 {
            sub_lanes::<$w>(a, b)
        }

        #[doc = concat!("Lane-wise ", $lanes, "×", $w, "-bit signed `a + b`,")]
        /// saturating to the signed lane range.
        #[inline]
        pub const fn $add_sat_s(a: u32, b: u32) -> u32 {
            add_sat_s_lanes::<$w>(a, b)
        }

        #[doc = concat!("Lane-wise ", $lanes, "×", $w, "-bit unsigned `a + b`,")]
        /// saturating to the lane maximum.
        #[inline]
        pub const fn $add_sat_u(a: u32, b: u32) -> u32 {
            add_sat_u_lanes::<$w>(a, b)
        }

        #[doc = concat!("Lane-wise ", $lanes, "×", $w, "-bit signed `a - b`,")]
        /// saturating to the signed lane range.
        #[inline]
        pub const fn $sub_sat_s(a: u32, b: u32) -> u32 {
            sub_sat_s_lanes::<$w>(a, b)
        }

        #[doc = concat!("Lane-wise ", $lanes, "×", $w, "-bit unsigned `a - b`,")]
        /// saturating to zero.
        #[inline]
        pub const fn $sub_sat_u(a: u32, b: u32) -> u32 {
            sub_sat_u_lanes::<$w>(a, b)
        }

        #[doc = concat!("Lane-wise ", $lanes, "×", $w, "-bit `a == b`")]
        /// as a lane mask (all ones where true).
        #[inline]
        pub const fn $eq(a: u32, b: u32) -> u32 {
            eq_lanes::<$w>(a, b)
        }

        #[doc = concat!("Lane-wise ", $lanes, "×", $w, "-bit signed `a < b`")]
        /// as a lane mask (all ones where true).
        #[inline]
        pub const fn $lt_s(a: u32, b: u32) -> u32 {
            lt_s_lanes::<$w>(a, b)
        }

        #[doc = concat!("Lane-wise ", $lanes, "×", $w, "-bit signed `a <= b`")]
        /// as a lane mask (all ones where true).
        #[inline]
        pub const fn $le_s(a: u32, b: u32) -> u32 {
            !lt_s_lanes::<$w>(b, a)
        }

        #[doc = concat!("Lane-wise ", $lanes, "×", $w, "-bit unsigned `a < b`")]
        /// as a lane mask (all ones where true).
        #[inline]
        pub const fn $lt_u(a: u32, b: u32) -> u32 {
            lt_u_lanes::<$w>(a, b)
        }

        #[doc = concat!("Lane-wise ", $lanes, "×", $w, "-bit unsigned `a <= b`")]
        /// as a lane mask (all ones where true).
        #[inline]
        pub const fn $le_u(a: u32, b: u32) -> u32 {
            !lt_u_lanes::<$w>(b, a)
        }

        #[doc = concat!("Lane-wise ", $lanes, "×", $w, "-bit signed minimum.")]
        #[inline]
        pub const fn $min_s(a: u32, b: u32) -> u32 {
            pick(lt_s_lanes::<$w>(a, b), a, b)
        }

        #[doc = concat!("Lane-wise ", $lanes, "×", $w, "-bit signed maximum.")]
        #[inline]
        pub const fn $max_s(a: u32, b: u32) -> u32 {
            pick(lt_s_lanes::<$w>(a, b), b, a)
        }

        #[doc = concat!("Lane-wise ", $lanes, "×", $w, "-bit unsigned minimum.")]
        #[inline]
        pub const fn $min_u(a: u32, b: u32) -> u32 {
            pick(lt_u_lanes::<$w>(a, b), a, b)
        }

        #[doc = concat!("Lane-wise ", $lanes, "×", $w, "-bit unsigned maximum.")]
        #[inline]
        pub const fn $max_u(a: u32, b: u32) -> u32 {
            pick(lt_u_lanes::<$w>(a, b), b, a)
        }
    };
}

lane_ops! {
    16, 2, add_16x2, sub_16x2, add_sat_s_16x2, add_sat_u_16x2, sub_sat_s_16x2, sub_sat_u_16x2,
    eq_16x2, lt_s_16x2, le_s_16x2, lt_u_16x2, le_u_16x2, min_s_16x2, max_s_16x2, min_u_16x2,
    max_u_16x2
}

lane_ops! {
    8, 4, add_8x4, sub_8x4, add_sat_s_8x4, add_sat_u_8x4, sub_sat_s_8x4, sub_sat_u_8x4, eq_8x4,
    lt_s_8x4, le_s_8x4, lt_u_8x4, le_u_8x4, min_s_8x4, max_s_8x4, min_u_8x4, max_u_8x4
}

/// Lane-wise 2×16-bit multiply, low 16 bits of each 32-bit lane product (wrapping; the same
/// bits for signed and unsigned lanes).
#[inline]
pub const fn mul_lo_16x2(a: u32, b: u32) -> u32 {
    // Two lane multipliers. Lane 0: low 16 bits of a * b_lo equal those of a_lo * b_lo.
    // Lane 1: (a_hi << 16) * b_hi keeps exactly the low 16 bits of a_hi * b_hi, in bits 31:16.
    (a.wrapping_mul(b & 0xFFFF) & 0xFFFF) | (a & 0xFFFF_0000).wrapping_mul(b >> 16)
}

/// Lane-wise 2×16-bit multiply of signed lanes, high 16 bits of each 32-bit lane product.
#[inline]
pub const fn mul_hi_s_16x2(a: u32, b: u32) -> u32 {
    let lo = (a as i16 as i32) * (b as i16 as i32);
    let hi = ((a >> 16) as i16 as i32) * ((b >> 16) as i16 as i32);
    ((lo as u32) >> 16) | ((hi as u32) & 0xFFFF_0000)
}

/// Lane-wise 2×16-bit multiply of unsigned lanes, high 16 bits of each 32-bit lane product.
#[inline]
pub const fn mul_hi_u_16x2(a: u32, b: u32) -> u32 {
    let lo = (a & 0xFFFF) * (b & 0xFFFF);
    let hi = (a >> 16) * (b >> 16);
    (lo >> 16) | (hi & 0xFFFF_0000)
}
