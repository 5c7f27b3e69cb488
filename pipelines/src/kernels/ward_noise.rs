//! Greg Ward's noise on the clusters: "A Recursive Implementation of the Perlin Noise
//! Function", Graphics Gems II ch. VIII.10 (1991), pp. 396–401, the noise the MARBLE scene
//! of Owens et al. used (thesis §4.4.4). Ward's code survives as `noise3.c` in Radiance
//! (LBL, "@(#)noise3.c 2.1 11/12/91"); this module was written from that file's algorithm.
//!
//! Ward's noise is Perlin's original (1985) gradient-and-value noise without a table: each
//! lattice corner `(x, y, z)` (integers) draws four pseudorandom numbers,
//!
//! * `frand(s)`: `s ← (s << 13) ^ s`, then
//!   `1 − ((s·(s·s·15731 + 789221) + 1376312589) & 0x7fffffff) / 2^30`, in `[−1, 1)`,
//!   all integer arithmetic 32-bit and wrapping (the original's `long` was 32 bits);
//! * `rand3a = frand(67x + 59y + 71z)`, the gradient's x component; `rand3b = frand(73x +
//!   79y + 83z)`, its y; `rand3c = frand(89x + 97y + 101z)`, its z; `rand3d = frand(103x +
//!   107y + 109z)`, the value ([`HASH_COEFFICIENTS`], in that order);
//!
//! and `noise3(p)` interpolates them over the cell of `p` with Hermite cubics, one axis at
//! a time (z outermost, x innermost): with `t` the offset along the axis, the value is
//! `hpoly1(t)·value₀ + hpoly2(t)·value₁ + hpoly3(t)·g₀ + hpoly4(t)·g₁`, `g` the corners'
//! gradient components along that axis (already interpolated along the inner axes), and
//! each remaining gradient component `hpoly1(t)·g₀ + hpoly2(t)·g₁`;
//! `hpoly1 = (2t − 3)t² + 1`, `hpoly2 = (3 − 2t)t²`, `hpoly3 = ((t − 2)t + 1)t`,
//! `hpoly4 = (t − 1)t²`. Radiance's `noise3` returns Ward's four interpolated numbers; the
//! noise is the value, unscaled (the gradients are its partial derivatives). Ward
//! interpolates every component at every level; a component no outer level reads is left
//! out here (the value is the same).
//!
//! How the cluster (3 adders, 2 multipliers) evaluates it, per call:
//!
//! 1. `floor` and the offsets `t` as the improved noise's (`super::floor_and_offset`).
//! 2. The seeds: per random, `a·X + b·Y + c·Z` of the cell's lower corner once (three
//!    `imul_lo`, two `iadd`), then the corners in a Gray code ([`GRAY_ORDER`]), each seed
//!    the one before plus a constant step (one `iadd`, wrapping like the original's sum):
//!    12 multiplies and 36 adds for the 32 seeds.
//! 3. `frand` keeps only its integer part: `v = (s·(s·s·15731 + 789221) + 1376312589) &
//!    0x7fffffff` as fp32 (`i32tof` rounds to 24 bits). `s << 13` is a `shl` on an adder
//!    for the gradient's randoms and an `imul_lo` by 2^13 on a multiplier for the value's
//!    (the same word), which balances the two kinds of unit: 1,252 adder and 823
//!    multiplier ops a fragment, 417 and 412 cycles of them.
//! 4. Since `frand = 1 − 2^−30·v` is affine and the interpolation linear, the noise is
//!    `(1 + Σ_axes (hpoly3 + hpoly4)) − 2^−30·I`, `I` the interpolation of the `v`s (the
//!    interpolation of ones is 1 for the value-weights, `hpoly1 + hpoly2 = 1`, plus each
//!    axis's tangent weights): one multiply instead of 32 multiply-adds.
//!    `hpoly3 + hpoly4 = t(t − 1)(2t − 1)`.
//! 5. Per axis: `t² = t·t`, `q = (2t − 3)·t²` (`2t` as `t + t`), `hpoly1 = q + 1`,
//!    `hpoly2 = −q`, `hpoly3 = ((t − 1)·(t − 1))·t`, `hpoly4 = (t − 1)·t²`, and
//!    `hpoly3 + hpoly4` summed.
//! 6. The interpolation: each weighted sum `h₁·a + h₂·b + h₃·c + h₄·d` as
//!    `((h₁·a + h₂·b) + h₃·c) + h₄·d` (two-term ones stop after the first add); x first
//!    (corner pairs `(i, i | 1)`, `i` = 0, 2, 4, 6: value, y and z gradients), then y
//!    (value and z gradient), then z (value). Each pair is interpolated as soon as its
//!    corners' randoms are made, and each y pair as soon as its x results are, so that
//!    few values wait in the LRFs.
//! 7. `noise = constant − 2^−30·I` with `constant = ((1 + S_x) + S_y) + S_z`.
//!
//! Per call: 32 × 9 = 288 ops of `frand`, 48 of seeds, 18 of floors, 33 for the Hermite
//! weights, 79 of interpolation, 5 to finish: 471 (the marble fragment program, four
//! calls and the rest of the shader, is 2,075).

use crate::kernel::{KernelBuilder, Ty, Value};

/// The seeds' coefficients `(a, b, c)` of `a·x + b·y + c·z`: Ward's `rand3a` (gradient
/// x), `rand3b` (gradient y), `rand3c` (gradient z), `rand3d` (value).
pub const HASH_COEFFICIENTS: [[i32; 3]; 4] =
    [[67, 59, 71], [73, 79, 83], [89, 97, 101], [103, 107, 109]];

/// `frand`'s shift, multipliers and offset: `s ← (s << 13) ^ s`,
/// `(s·(s·s·15731 + 789221) + 1376312589) & 0x7fffffff`.
pub const FRAND_SHIFT: u32 = 13;
pub const FRAND_CUBIC: i32 = 15_731;
pub const FRAND_LINEAR: i32 = 789_221;
pub const FRAND_OFFSET: i32 = 1_376_312_589;
pub const FRAND_MASK: u32 = 0x7fff_ffff;

/// `frand(s) = 1 − v·FRAND_SCALE`.
pub const FRAND_SCALE: f32 = 1.0 / (1u32 << 30) as f32;

/// Which of [`HASH_COEFFICIENTS`]' randoms shift with `shl` (the others multiply by 2^13).
pub const SHIFT_ON_ADDER: [bool; 4] = [true, true, true, false];

/// The order the corners' seeds are computed in (bit 0 x, bit 1 y, bit 2 z): a Gray code,
/// so each seed is the one before plus a constant (one coordinate changes by ±1), and the
/// x pairs `(i, i | 1)` come one after the other.
pub const GRAY_ORDER: [usize; 8] = [0, 1, 3, 2, 6, 7, 5, 4];

/// The constants of Ward's noise, created before the loop.
pub struct Constants {
    one: Value,
    three: Value,
    minus_scale: Value,
    shift: Value,
    shift_multiplier: Value,
    cubic: Value,
    linear: Value,
    offset: Value,
    mask: Value,
    coefficients: [[Value; 3]; 4],
    /// Per random, the seed's step to each corner of [`GRAY_ORDER`] from the one before
    /// (index 0 unused).
    gray_steps: [[Value; 8]; 4],
}

impl Constants {
    pub fn new(b: &mut KernelBuilder) -> Self {
        let coefficients = HASH_COEFFICIENTS.map(|c| c.map(|x| b.i32(x)));
        let seed_step = |c: [i32; 3], corner: usize| -> i32 {
            (0..3)
                .filter(|axis| corner >> axis & 1 == 1)
                .map(|axis| c[axis])
                .sum()
        };
        let gray_steps = HASH_COEFFICIENTS.map(|c| {
            std::array::from_fn(|n| match n {
                0 => b.i32(0),
                n => b.i32(seed_step(c, GRAY_ORDER[n]) - seed_step(c, GRAY_ORDER[n - 1])),
            })
        });
        Constants {
            one: b.f32(1.0),
            three: b.f32(3.0),
            minus_scale: b.f32(-FRAND_SCALE),
            shift: b.i32(FRAND_SHIFT as i32),
            shift_multiplier: b.i32(1 << FRAND_SHIFT),
            cubic: b.i32(FRAND_CUBIC),
            linear: b.i32(FRAND_LINEAR),
            offset: b.i32(FRAND_OFFSET),
            mask: b.constant(FRAND_MASK, Ty::I32),
            coefficients,
            gray_steps,
        }
    }
}

/// `frand`'s `v` of `seed`, as fp32 (step 3 of the module notes).
fn frand_integer(b: &mut KernelBuilder, k: &Constants, seed: Value, on_adder: bool) -> Value {
    let shifted = if on_adder {
        b.shl(seed, k.shift)
    } else {
        b.imul(seed, k.shift_multiplier)
    };
    let s = b.xor(shifted, seed);
    let square = b.imul(s, s);
    let cubic = b.imul(square, k.cubic);
    let inner = b.iadd(cubic, k.linear);
    let r = b.imul(s, inner);
    let r = b.iadd(r, k.offset);
    let v = b.and(r, k.mask);
    b.itof(v)
}

/// Ward's Hermite weights at offset `t`: `[hpoly1, hpoly2, hpoly3, hpoly4]` and
/// `hpoly3 + hpoly4` (step 5 of the module notes).
fn hermite(b: &mut KernelBuilder, k: &Constants, t: Value) -> ([Value; 4], Value) {
    let t2 = b.fmul(t, t);
    let two_t = b.fadd(t, t);
    let a = b.fsub(two_t, k.three);
    let q = b.fmul(a, t2);
    let h1 = b.fadd(q, k.one);
    let h2 = b.fneg(q);
    let t_minus_1 = b.fsub(t, k.one);
    let square = b.fmul(t_minus_1, t_minus_1);
    let h3 = b.fmul(square, t);
    let h4 = b.fmul(t_minus_1, t2);
    let tangents = b.fadd(h3, h4);
    ([h1, h2, h3, h4], tangents)
}

/// `((h₁·a + h₂·b) + h₃·c) + h₄·d`, or `h₁·a + h₂·b` without a tangent pair.
fn weighted(
    b: &mut KernelBuilder,
    h: &[Value; 4],
    ends: [Value; 2],
    tangents: Option<[Value; 2]>,
) -> Value {
    let p = b.fmul(h[0], ends[0]);
    let q = b.fmul(h[1], ends[1]);
    let mut sum = b.fadd(p, q);
    if let Some([c, d]) = tangents {
        let r = b.fmul(h[2], c);
        sum = b.fadd(sum, r);
        let s = b.fmul(h[3], d);
        sum = b.fadd(sum, s);
    }
    sum
}

/// Ward's `noise3(p)`, the value (see the module notes).
pub fn noise(b: &mut KernelBuilder, k: &Constants, p: [Value; 3]) -> Value {
    let [(x, tx), (y, ty), (z, tz)] = p.map(|c| super::floor_and_offset(b, c));
    let [(hx, sx), (hy, sy), (hz, sz)] = [tx, ty, tz].map(|t| hermite(b, k, t));
    // Per random, the seed of the cell's lower corner.
    let base: [Value; 4] = std::array::from_fn(|random| {
        let [ca, cb, cc] = k.coefficients[random];
        let sx = b.imul(x, ca);
        let sy = b.imul(y, cb);
        let sz = b.imul(z, cc);
        let base = b.iadd(sx, sy);
        b.iadd(base, sz)
    });
    // The corners in Gray order, each seed the one before plus a step; each x pair
    // `(i, i | 1)` is interpolated as soon as both its corners' randoms are there, and each
    // z slice's y pair as soon as its two x results are, so that few values are live.
    let mut seeds = base;
    let mut corner_values = |b: &mut KernelBuilder, n: usize| -> [Value; 4] {
        std::array::from_fn(|random| {
            if n > 0 {
                seeds[random] = b.iadd(seeds[random], k.gray_steps[random][n]);
            }
            frand_integer(b, k, seeds[random], SHIFT_ON_ADDER[random])
        })
    };
    let mut along_x = [None; 4];
    let mut along_y = Vec::new();
    for pair in 0..4 {
        // `v` of the randoms (gradient x, y, z, value) at corners `i` and `i | 1`.
        let first = corner_values(b, 2 * pair);
        let second = corner_values(b, 2 * pair + 1);
        let ([gx0, gy0, gz0, v0], [gx1, gy1, gz1, v1]) = if GRAY_ORDER[2 * pair] & 1 == 0 {
            (first, second)
        } else {
            (second, first)
        };
        // Along x: the value, and the y and z gradients.
        along_x[GRAY_ORDER[2 * pair] >> 1] = Some([
            weighted(b, &hx, [v0, v1], Some([gx0, gx1])),
            weighted(b, &hx, [gy0, gy1], None),
            weighted(b, &hx, [gz0, gz1], None),
        ]);
        // Along y, once a z slice (x results 0 and 1, or 2 and 3) is complete: the value
        // and the z gradient.
        if pair % 2 == 1 {
            let slice = 2 * (GRAY_ORDER[2 * pair] >> 2);
            let [v0, gy0, gz0] = along_x[slice].expect("both x pairs of the slice");
            let [v1, gy1, gz1] = along_x[slice + 1].expect("both x pairs of the slice");
            along_y.push((
                slice,
                [
                    weighted(b, &hy, [v0, v1], Some([gy0, gy1])),
                    weighted(b, &hy, [gz0, gz1], None),
                ],
            ));
        }
    }
    along_y.sort_by_key(|(slice, _)| *slice);
    let [(_, [v0, gz0]), (_, [v1, gz1])] = [along_y[0], along_y[1]];
    let interpolated = weighted(b, &hz, [v0, v1], Some([gz0, gz1]));
    let constant = b.fadd(k.one, sx);
    let constant = b.fadd(constant, sy);
    let constant = b.fadd(constant, sz);
    let scaled = b.fmul(interpolated, k.minus_scale);
    b.fadd(constant, scaled)
}
