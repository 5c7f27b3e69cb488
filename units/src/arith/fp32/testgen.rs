//! Deterministic test-operand generators biased to the hard cases of binary32 arithmetic.
//!
//! Dependency-free (a SplitMix64 generator), so the same distributions drive the committed
//! vector generator, the live SoftFloat cross-check and the benches; the proptest strategies
//! in `strategies` (feature `proptest`) cover the same classes with shrinking.
//!
//! Classes emphasised: signed zeros, subnormals (including the largest and smallest), the
//! subnormal/normal boundary, near-overflow exponents (0xFD, 0xFE), values near one, all-ones
//! and sparse significands (rounding carries and exact/halfway products), quiet and
//! signalling NaNs, infinities, integers and half-integers (conversions, ±2^31), operand
//! pairs that cancel (`a, −a·(1 ± k ulp)`), pairs whose exponents differ by about the
//! significand width (halfway and sticky cases of the adder), and pairs whose product or
//! quotient lands near the overflow or underflow threshold.

/// SplitMix64 (Steele, Lea & Flood, "Fast splittable pseudorandom number generators",
/// OOPSLA 2014): a tiny, good-quality, seedable generator.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A generator seeded with `seed`.
    pub fn new(seed: u64) -> SplitMix64 {
        SplitMix64(seed)
    }

    /// Next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Next 32 random bits.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        (self.next_u64() >> 32) as u32
    }

    /// Uniform in `0..n` (`n > 0`; slight modulo bias is irrelevant here).
    #[inline]
    pub fn below(&mut self, n: u32) -> u32 {
        ((self.next_u32() as u64 * n as u64) >> 32) as u32
    }
}

/// Hand-picked special and boundary binary32 values (both signs where it matters).
pub const SPECIALS: &[u32] = &[
    0x0000_0000, // +0
    0x8000_0000, // -0
    0x0000_0001, // smallest subnormal
    0x8000_0001,
    0x0000_0002,
    0x0040_0000, // 2^-127
    0x007F_FFFF, // largest subnormal
    0x807F_FFFF,
    0x0080_0000, // smallest normal
    0x8080_0000,
    0x0080_0001,
    0x00FF_FFFF,
    0x0100_0000,
    0x3380_0000, // 2^-24
    0x3400_0000, // 2^-23
    0x3EFF_FFFF, // just below 0.5
    0x3F00_0000, // 0.5
    0x3F00_0001,
    0x3F7F_FFFF, // 1 - ulp
    0x3F80_0000, // 1
    0xBF80_0000, // -1
    0x3F80_0001, // 1 + ulp
    0x3FC0_0000, // 1.5
    0x4000_0000, // 2
    0x4020_0000, // 2.5
    0x4040_0000, // 3
    0xC060_0000, // -3.5
    0x4B00_0000, // 2^23
    0x4B7F_FFFF, // 2^24 - 1
    0x4B80_0000, // 2^24
    0x4EFF_FFFF, // largest float below 2^31
    0x4F00_0000, // 2^31
    0xCF00_0000, // -2^31
    0xCF00_0001,
    0x5F00_0000, // 2^63
    0x7F00_0000, // 2^127
    0x7F7F_FFFF, // largest finite
    0xFF7F_FFFF,
    0x7F7F_FFFE,
    0x7F80_0000, // +inf
    0xFF80_0000, // -inf
    0x7FC0_0000, // canonical qNaN
    0xFFC0_0000,
    0x7FFF_FFFF, // qNaN, all-ones payload
    0x7F80_0001, // sNaN, smallest payload
    0xFFBF_FFFF, // sNaN, largest payload
    0x7FA0_0000, // sNaN
];

/// A smaller set of specials whose cross product seeds the committed vectors of binary ops.
pub const CORE_SPECIALS: &[u32] = &[
    0x0000_0000,
    0x8000_0000,
    0x0000_0001,
    0x8000_0001,
    0x0040_0000,
    0x007F_FFFF,
    0x0080_0000,
    0x3380_0000,
    0x3F7F_FFFF,
    0x3F80_0000,
    0xBF80_0000,
    0x3F80_0001,
    0x3FC0_0000,
    0x4B80_0000,
    0x4F00_0000,
    0xCF00_0000,
    0x7F7F_FFFF,
    0xFF7F_FFFF,
    0x7F80_0000,
    0xFF80_0000,
    0x7FC0_0000,
    0x7F80_0001,
];

/// Edge-case i32 values for conversions (two's-complement bits).
pub const INT_SPECIALS: &[u32] = &[
    0,
    1,
    0xFFFF_FFFF, // -1
    0x7FFF_FFFF,
    0x8000_0000,
    0x8000_0001,
    0x00FF_FFFF,
    0x0100_0000,
    0x0100_0001,
    0x0100_0003,
    0xFEFF_FFFF,
    0x7FFF_FFC0,
    0x7FFF_FF80,
    0x4000_0040,
    0x4000_00C0,
];

/// One binary32 bit pattern biased to the hard cases (see the module doc).
pub fn biased_f32(rng: &mut SplitMix64) -> u32 {
    let r = rng.next_u32();
    let sign = rng.next_u32() & 0x8000_0000;
    let frac = rng.next_u32() & 0x007F_FFFF;
    match rng.below(16) {
        0 | 1 => SPECIALS[rng.below(SPECIALS.len() as u32) as usize],
        2 | 3 => r,                                               // uniform bit pattern
        4 => sign | (frac | (rng.below(2))).max(1),               // subnormal
        5 => sign | (1 << rng.below(23)) >> rng.below(4),         // sparse subnormal
        6 => sign | ((rng.below(3)) << 23) | frac, // subnormal/normal boundary (exp 0..=2)
        7 => sign | ((0xFC + rng.below(3)) << 23) | frac, // near overflow (exp 0xFC..=0xFE)
        8 => sign | ((0x7D + rng.below(4)) << 23) | frac, // near one
        9 => sign | (r & 0x7F80_0000) | significand_pattern(rng), // all-ones / runs
        10 => sign | (r & 0x7F80_0000) | (frac & !((1 << rng.below(24)) - 1)), // sparse low bits
        11 => {
            // Integers and half-integers up to ±2^32 (conversion rounding, ±2^31 boundary).
            let e = 0x7E + rng.below(34); // 0.5 .. 2^32
            sign | (e << 23) | (frac & !((1 << rng.below(24)) - 1))
        }
        12 => {
            // NaNs with random payloads, both kinds.
            let payload = frac.max(1);
            sign | 0x7F80_0000 | payload
        }
        13 => sign | 0x7F80_0000 | (rng.below(2) << 22), // infinity or payload-less qNaN
        _ => sign | (rng.below(255) << 23) | frac,       // random finite
    }
}

/// A non-negative-biased operand for square root: 7/8 of the draws have the sign cleared.
pub fn biased_sqrt_operand(rng: &mut SplitMix64) -> u32 {
    let a = biased_f32(rng);
    if rng.below(8) == 0 {
        a
    } else {
        a & 0x7FFF_FFFF
    }
}

/// An operand for f32 → i32 conversion: mostly in-range values with few fraction bits
/// (exact, halfway and near-halfway cases), values around ±2^31, and the general classes.
pub fn biased_to_int_operand(rng: &mut SplitMix64) -> u32 {
    let sign = rng.next_u32() & 0x8000_0000;
    let frac = rng.next_u32() & 0x007F_FFFF;
    match rng.below(8) {
        0..=2 => {
            // |x| in [0.5, 2^31): keep only a few bits below the binary point.
            let e = 0x7E + rng.below(0x9E - 0x7E);
            let int_bits = (e as i32 - 0x7F).max(0) as u32; // fraction bits above the point
            let keep = (int_bits + 1 + rng.below(3)).min(23);
            sign | (e << 23) | (frac & !((1u32 << (23 - keep)) - 1))
        }
        3 => sign | ((0x9D + rng.below(3)) << 23) | significand_pattern(rng), // near ±2^31
        4 => sign | ((0x70 + rng.below(15)) << 23) | frac,                    // |x| < 1
        _ => biased_f32(rng),
    }
}

/// Significand fields of the forms that exercise carries: all ones, runs of ones or zeros,
/// a single bit, and all ones but one.
fn significand_pattern(rng: &mut SplitMix64) -> u32 {
    let lo = rng.below(24);
    let hi = rng.below(24);
    let (lo, hi) = (lo.min(hi), lo.max(hi));
    let run = ((1u32 << hi) - 1) & !((1u32 << lo) - 1);
    match rng.below(5) {
        0 => 0x007F_FFFF,
        1 => run,
        2 => !run & 0x007F_FFFF,
        3 => 1 << rng.below(23),
        _ => 0x007F_FFFF & !(1 << rng.below(23)),
    }
}

/// A binary32 operand pair biased to the hard cases of add/sub/mul/div and compares.
pub fn biased_pair(rng: &mut SplitMix64) -> (u32, u32) {
    let a = biased_f32(rng);
    match rng.below(12) {
        0..=3 => (a, biased_f32(rng)),
        4 => {
            // Cancellation: b = −a·(1 ± k ulp) (adjacent bit patterns, opposite sign).
            let k = rng.below(5);
            let b = if rng.below(2) == 0 {
                a.wrapping_add(k)
            } else {
                a.wrapping_sub(k)
            };
            (a, b ^ 0x8000_0000)
        }
        5 => {
            // Same magnitude, near copies of each other (compares, ties).
            let b = a ^ (rng.below(2) << 31) ^ (rng.below(2) * (1 << rng.below(23)));
            (a, b)
        }
        6 => {
            // Exponent difference around the significand width (add halfway/sticky cases).
            let ea = (a >> 23) & 0xFF;
            let d = 20 + rng.below(8);
            let eb = ea.saturating_sub(d);
            let b = (rng.next_u32() & 0x8000_0000) | (eb << 23) | significand_pattern(rng);
            if rng.below(2) == 0 { (a, b) } else { (b, a) }
        }
        7 => {
            // Close exponents with random significands (normalisation after subtraction).
            let ea = (a >> 23) & 0xFF;
            let eb = (ea + rng.below(3)).saturating_sub(1).min(0xFE);
            let b = (rng.next_u32() & 0x807F_FFFF) | (eb << 23);
            (a, b)
        }
        8 | 9 => {
            // Product or quotient whose exponent lands near the underflow threshold (result
            // exponent in [−26, 2]) or the overflow threshold ([252, 256]).
            let (ea, target) = if rng.below(2) == 0 {
                (1 + rng.below(127) as i32, 2 - rng.below(29) as i32)
            } else {
                (128 + rng.below(127) as i32, 252 + rng.below(5) as i32)
            };
            let eb = if rng.below(2) == 0 {
                target + 127 - ea // mul: E = ea + eb − 127
            } else {
                ea + 127 - target // div: E = ea − eb + 127
            };
            let eb = eb.clamp(1, 0xFE) as u32;
            (
                (rng.next_u32() & 0x807F_FFFF) | ((ea as u32) << 23),
                (rng.next_u32() & 0x807F_FFFF) | (eb << 23),
            )
        }
        10 => {
            // Short significands: many exact and exactly-halfway products and quotients.
            let keep = 12 + rng.below(6);
            let mask = !((1u32 << (23 - keep)) - 1);
            let b = biased_f32(rng) & (0xFF80_0000 | mask);
            (a & (0xFF80_0000 | mask), b)
        }
        _ => (a, SPECIALS[rng.below(SPECIALS.len() as u32) as usize]),
    }
}

/// An i32 bit pattern biased to the conversion edge cases: small values, values around 2^24
/// (the first non-representable magnitudes), halfway patterns, powers of two ± small, the
/// extremes, and uniform bits.
pub fn biased_i32(rng: &mut SplitMix64) -> u32 {
    let r = rng.next_u32();
    let neg = rng.below(2) == 1;
    let v = match rng.below(8) {
        0 => r,
        1 => r & 0xFF,
        2 => (1u32 << (24 + rng.below(7))).wrapping_add(r & 0xFF),
        3 => {
            // halfway between representable neighbours: 2^k·(odd) + 2^(k−25)
            let k = 24 + rng.below(7);
            let base = (r | 1 << 31) >> (31 - k);
            (base & !((1 << (k - 23)) - 1)) | (1 << (k - 24))
        }
        4 => (1u32 << rng.below(32)).wrapping_sub(rng.below(3)),
        5 => [0, 1, 0x7FFF_FFFF, 0x8000_0000, 0x00FF_FFFF, 0x0100_0001][rng.below(6) as usize],
        6 => r >> rng.below(32),
        _ => r & 0x03FF_FFFF,
    };
    if neg { v.wrapping_neg() } else { v }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generators_cover_classes() {
        let mut rng = SplitMix64::new(1);
        let (mut sub, mut nan, mut inf, mut zero, mut big) = (0, 0, 0, 0, 0);
        for _ in 0..20_000 {
            let x = biased_f32(&mut rng);
            sub += super::super::is_subnormal(x) as u32;
            nan += super::super::is_nan(x) as u32;
            inf += super::super::is_inf(x) as u32;
            zero += super::super::is_zero(x) as u32;
            big += ((x >> 23) & 0xFF == 0xFE) as u32;
            let _ = biased_pair(&mut rng);
            let _ = biased_i32(&mut rng);
        }
        for count in [sub, nan, inf, zero, big] {
            assert!(count > 100, "class under-represented: {count}");
        }
    }

    #[test]
    fn splitmix_is_deterministic() {
        let mut a = SplitMix64::new(42);
        let mut b = SplitMix64::new(42);
        for _ in 0..10 {
            assert_eq!(a.next_u64(), b.next_u64());
        }
        assert!(SplitMix64::new(7).below(10) < 10);
    }
}
