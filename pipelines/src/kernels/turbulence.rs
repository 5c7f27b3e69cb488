//! `turbulence`: the MARBLE fragment shader — Perlin's marble (Perlin, "An Image
//! Synthesizer", SIGGRAPH 1985) lit per fragment, as in the MARBLE scene of Owens et al.,
//! "Polygon Rendering on a Stream Architecture", Graphics Hardware 2000, over one of two
//! noises ([`Noise`]): Greg Ward's implementation of Perlin's noise (Graphics Gems II
//! ch. VIII.10), the publication's, built by [`super::ward_noise`] (the library's
//! `turbulence_ward` and `marble_ward`); or, the default, Perlin's improved gradient noise
//! (Perlin, "Improving Noise", SIGGRAPH 2002), step 1 below (the library's `turbulence`
//! and `marble`). Ward's is not the default because the compiler schedules it poorly and
//! slowly: II 626 against a bound of 418 on gold8, after about 4 minutes.
//!
//! Inputs: `fragments`, records (x, y, z, nx, ny, nz) of shading positions and (not
//! necessarily unit) normals; with Perlin's noise `perm`, Perlin's permutation table (256
//! words, a permutation of 0..256). Parameters, in order: `frequency` and `turbulence_scale` of the marble;
//! `light_x, _y, _z`, the unit direction towards a directional light; `half_x, _y, _z`, the
//! unit half vector of that light and a viewer at infinity; `ambient` and `specular`
//! intensities; the eight control colours `ramp{i}_r, _g, _b` of the colour ramp. Output
//! `colours`: records (r, g, b).
//!
//! Per element:
//!
//! 1. `noise(p)` is Perlin's 2002 improved noise: lattice cell `floor(p) & 255` and offset
//!    `f = p − floor(p)`; the fade curve `6t⁵ − 15t⁴ + 10t³` evaluated as
//!    `t·t·t·(t·(t·6 − 15) + 10)`; the hash `perm[perm[perm[X] + Y] + Z]` of the eight
//!    cell corners; one of the 12 gradient directions per corner chosen by the hash's low
//!    four bits (Perlin's `grad`). Perlin's table holds the permutation twice (512 entries)
//!    so that indices up to 511 need no wrap; here every index is reduced with `and 255`
//!    instead, which reads the same entries. The trilinear interpolation of the corner
//!    gradients is the weighted sum `Σ_corners (w_z·(w_y·w_x))·grad`, each weight `t` or
//!    `1 − t` of the faded offsets, summed in corner order (x fastest, then y, then z) —
//!    the polynomial of Perlin's nested `lerp`s with more multiplies and fewer adds, to
//!    suit a cluster's 3 adders and 2 multipliers.
//! 2. `turbulence = Σ_{i=0..4} |noise(p·2^i)| / 2^i` (four octaves; the scalings by powers
//!    of two are exact multiplies; with Ward's noise each octave's point also adds
//!    `0·|noise|` of the octave before: see the function `turbulence`).
//! 3. `s = sin(x·frequency + turbulence·turbulence_scale)` by a polynomial: the argument is
//!    reduced to `[−π, π]` by `k = round(a / 2π)` (Cody–Waite, with 2π split in two
//!    parts), folded to `[−π/2, π/2]` (`sin(π − r) = sin r`), and the degree-9 odd Taylor
//!    polynomial is evaluated by Horner's rule in `r²` (error below 4·10⁻⁶).
//! 4. `u = s·0.5 + 0.5` indexes a colour ramp: the degree-7 Bézier curve of the eight
//!    control colours, `Σ_i C(7, i)·u^i·(1 − u)^(7−i)·ramp_i` (the binomial weights are
//!    folded into the colours before the loop), summed in order of `i`.
//! 5. Lighting: the normal is normalized by a reciprocal square root from the bit-level
//!    initial guess `0x5F3759DF − (bits(n²) >> 1)` (Lomont, "Fast Inverse Square Root",
//!    2003) and three Newton steps `y·(1.5 − (n²/2)·y·y)`; then
//!    `colour = clamp(ramp(u)·(ambient + max(N·light, 0)) + specular·max(N·half, 0)^16,
//!    0, 1)` per channel (exponent 16: four squarings).
//!
//! Perlin's permutation table lives in each cluster's scratchpad (words 0..256), loaded
//! before the loop: the `perm` stream holds each table word `C` times, so each of 256 reads gives
//! every cluster the same word, which it writes to its scratchpad (one read and one write
//! per cycle; no word waits in an LRF).
//!
//! [`build_fragment`] is the same shader as the OpenGL pipeline's fragment program for
//! `shader = "marble"` (library name `marble`): it reads `irast`'s varyings records
//! (r, g, b, dropped; the object-space position and normal; any further words of the
//! frame, dropped) and writes the packed RGBA8 colour. With Perlin's noise the pipeline
//! feeds it Perlin's own permutation ([`PERLIN_PERMUTATION`]) from DRAM; its parameters
//! are as [`crate::opengl::fragment_program`] describes. Its loop is, with Ward's noise,
//! 2,075 arithmetic ops (1,252 on the adders, 823 on the multipliers) per fragment; with
//! Perlin's, 1031 (663 and 368) and 120 scratchpad reads.
//!
//! `floor` is `ftoi32_trunc`, back to fp32 and one less where that rounded up (negative
//! non-integers); it holds for |x| < 2^31. The loop body has no divide or square root.

use imagine_units::arith::fp32::testgen::SplitMix64;
use imagine_units::desc::MachineDesc;

use imagine_units::ops::Op;

use super::{finish, records_to_stream, uniform, uniform_words, ward_noise};
use crate::kernel::{
    Kernel, KernelBuilder, KernelInputs, LoopSpec, MachineRequirementError, Needs, StreamId, Ty,
    Value,
};
pub use crate::scene::model::Noise;

/// Entries of the permutation table (scratchpad words `0..TABLE`).
pub const TABLE: usize = 256;

/// Octaves of the turbulence sum.
pub const OCTAVES: u32 = 4;

/// Control colours of the marble ramp (a Bézier curve of degree `RAMP − 1`).
pub const RAMP: usize = 8;

/// The marble's control colours (linear RGB): white stone with grey and dark veins. They
/// are the material, compiled into the kernel as constants.
pub const RAMP_COLOURS: [[f32; 3]; RAMP] = [
    [0.92, 0.91, 0.88],
    [0.85, 0.84, 0.80],
    [0.62, 0.60, 0.58],
    [0.30, 0.28, 0.30],
    [0.12, 0.11, 0.13],
    [0.45, 0.43, 0.44],
    [0.78, 0.77, 0.74],
    [0.95, 0.94, 0.92],
];

/// 2π split for the argument reduction: `TWO_PI_HI` has 8 significant bits, so `k·TWO_PI_HI`
/// is exact for |k| < 2^16; `TWO_PI_LO` is the rest.
pub const TWO_PI_HI: f32 = 6.281_25;
pub const TWO_PI_LO: f32 = 0.001_935_307_2;
pub const INV_TWO_PI: f32 = 0.159_154_94;

/// The odd Taylor coefficients of sine: `x³`, `x⁵`, `x⁷`, `x⁹`.
pub const SIN_COEFFICIENTS: [f32; 4] = [-1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362_880.0];

/// Constants the shader shares, created before the loop.
struct Constants {
    one_f: Value,
    noise: NoiseConstants,
}

enum NoiseConstants {
    Perlin(PerlinConstants),
    Ward(ward_noise::Constants),
}

impl Constants {
    fn new(b: &mut KernelBuilder, noise: Noise) -> Self {
        let one_f = b.f32(1.0);
        let noise = match noise {
            Noise::Perlin => NoiseConstants::Perlin(PerlinConstants::new(b, one_f)),
            Noise::Ward => NoiseConstants::Ward(ward_noise::Constants::new(b)),
        };
        Constants { one_f, noise }
    }
}

/// Constants of Perlin's improved noise.
struct PerlinConstants {
    one_f: Value,
    six: Value,
    fifteen: Value,
    ten: Value,
    one: Value,
    index_mask: Value,
    nibble_to_top: Value,
    bit0_to_sign: Value,
    top_8: Value,
    top_4: Value,
    mask_12_14: Value,
    top_12: Value,
}

impl PerlinConstants {
    /// `one_f` is the shader's (created first, as it always was).
    fn new(b: &mut KernelBuilder, one_f: Value) -> Self {
        let int = |b: &mut KernelBuilder, bits: u32| b.constant(bits, Ty::I32);
        PerlinConstants {
            one_f,
            six: b.f32(6.0),
            fifteen: b.f32(15.0),
            ten: b.f32(10.0),
            one: int(b, 1),
            index_mask: int(b, TABLE as u32 - 1),
            nibble_to_top: int(b, 1 << 28),
            bit0_to_sign: int(b, 1 << 31),
            top_8: int(b, 8 << 28),
            top_4: int(b, 4 << 28),
            mask_12_14: int(b, 0xD000_0000),
            top_12: int(b, 12 << 28),
        }
    }
}

/// `floor(x) & 255` (int32) and `x − floor(x)` (fp32).
fn cell_and_offset(b: &mut KernelBuilder, k: &PerlinConstants, x: Value) -> (Value, Value) {
    let (floor, offset) = super::floor_and_offset(b, x);
    (b.and(floor, k.index_mask), offset)
}

/// Perlin's fade curve `t·t·t·(t·(t·6 − 15) + 10)`.
fn fade(b: &mut KernelBuilder, k: &PerlinConstants, t: Value) -> Value {
    let a = b.fmul(t, k.six);
    let a = b.fsub(a, k.fifteen);
    let a = b.fmul(t, a);
    let a = b.fadd(a, k.ten);
    let t2 = b.fmul(t, t);
    let t3 = b.fmul(t2, t);
    b.fmul(t3, a)
}

/// Perlin's `grad(hash, x, y, z)`: with `h = hash & 15`, `u = h < 8 ? x : y`,
/// `v = h < 4 ? y : (h == 12 || h == 14 ? x : z)`, the sum of `u` and `v` negated by bits
/// 0 and 1 of `h`. The low nibble is moved to the top four bits by a multiply, so the tests
/// are unsigned compares; the negations flip the sign bit, moved there by multiplies
/// (`imul_hi_u` by 2^31 is a right shift by one).
fn grad(
    b: &mut KernelBuilder,
    k: &PerlinConstants,
    hash: Value,
    x: Value,
    y: Value,
    z: Value,
) -> Value {
    let nibble = b.imul(hash, k.nibble_to_top);
    let below_8 = b.iltu(nibble, k.top_8);
    let u = b.select(below_8, x, y);
    let below_4 = b.iltu(nibble, k.top_4);
    let masked = b.and(nibble, k.mask_12_14);
    let is_12_or_14 = b.ieq(masked, k.top_12);
    let x_or_z = b.select(is_12_or_14, x, z);
    let v = b.select(below_4, y, x_or_z);
    let u_sign = b.imul(hash, k.bit0_to_sign);
    let u = b.xor(u, u_sign);
    let u = b.cast(u, Ty::F32);
    let bit1_to_bit0 = b.op(Op::IMulHiU, &[hash, k.bit0_to_sign]);
    let v_sign = b.imul(bit1_to_bit0, k.bit0_to_sign);
    let v = b.xor(v, v_sign);
    let v = b.cast(v, Ty::F32);
    b.fadd(u, v)
}

/// Perlin's improved noise at `(x, y, z)`, the table in scratchpad words 0..256.
fn perlin_noise(b: &mut KernelBuilder, k: &PerlinConstants, [x, y, z]: [Value; 3]) -> Value {
    let (cx, x) = cell_and_offset(b, k, x);
    let (cy, y) = cell_and_offset(b, k, y);
    let (cz, z) = cell_and_offset(b, k, z);
    let [x1, y1, z1] = [x, y, z].map(|t| b.fsub(t, k.one_f));
    let [u, v, w] = [x, y, z].map(|t| fade(b, k, t));

    let next = |b: &mut KernelBuilder, i: Value| {
        let n = b.iadd(i, k.one);
        b.and(n, k.index_mask)
    };
    let lookup = |b: &mut KernelBuilder, i: Value| b.sp_read(0, Some(i));
    let hash = |b: &mut KernelBuilder, i: Value, add: Value| {
        let p = b.sp_read(0, Some(i));
        let s = b.iadd(p, add);
        b.and(s, k.index_mask)
    };
    let cx1 = next(b, cx);
    let a = hash(b, cx, cy);
    let bb = hash(b, cx1, cy);
    let (a1, b1) = (next(b, a), next(b, bb));
    let aa = hash(b, a, cz);
    let ab = hash(b, a1, cz);
    let ba = hash(b, bb, cz);
    let bbb = hash(b, b1, cz);
    let corners = [aa, ba, ab, bbb].map(|h| lookup(b, h));
    let far: Vec<Value> = [aa, ba, ab, bbb].iter().map(|&h| next(b, h)).collect();
    let far_corners: Vec<Value> = far.iter().map(|&h| lookup(b, h)).collect();

    let gradients = [
        grad(b, k, corners[0], x, y, z),
        grad(b, k, corners[1], x1, y, z),
        grad(b, k, corners[2], x, y1, z),
        grad(b, k, corners[3], x1, y1, z),
        grad(b, k, far_corners[0], x, y, z1),
        grad(b, k, far_corners[1], x1, y, z1),
        grad(b, k, far_corners[2], x, y1, z1),
        grad(b, k, far_corners[3], x1, y1, z1),
    ];
    // Trilinear weights of the corners, in the order of `gradients` (x fastest).
    let [wu, wv, ww] = [u, v, w].map(|t| [b.fsub(k.one_f, t), t]);
    let wuv: Vec<Value> = (0..4).map(|c| b.fmul(wv[c >> 1], wu[c & 1])).collect();
    let mut sum = None;
    for (corner, &g) in gradients.iter().enumerate() {
        let weight = b.fmul(ww[corner >> 2], wuv[corner & 3]);
        let term = b.fmul(weight, g);
        sum = Some(match sum {
            None => term,
            Some(s) => b.fadd(s, term),
        });
    }
    sum.expect("eight corners")
}

/// `Σ_{i<4} |noise(p·2^i)| / 2^i`.
///
/// With Ward's noise each octave after the first starts from the one before: its point
/// is `p·2^i + 0·|noise|` of the octave before (`+0`, so the same point). The compiler's
/// list scheduler orders ops by height, and Ward's 32 hash chains per octave all have more
/// height than any octave's interpolation: without the dependency it would start all 128
/// at once and leave their results waiting longer than the LRFs hold them (no schedule at
/// any interval); with it, octaves follow each other within an iteration (the software
/// pipeline overlaps iterations instead). One multiply and three adds per octave.
fn turbulence(b: &mut KernelBuilder, k: &Constants, p: [Value; 3]) -> Value {
    let mut sum = None;
    let mut after: Option<Value> = None;
    for octave in 0..OCTAVES {
        let scale = (1u32 << octave) as f32;
        let q = if octave == 0 {
            p
        } else {
            let s = b.f32(scale);
            p.map(|c| b.fmul(c, s))
        };
        let q = match after {
            Some(zero) => q.map(|c| b.fadd(c, zero)),
            None => q,
        };
        let n = match &k.noise {
            NoiseConstants::Perlin(k) => perlin_noise(b, k, q),
            NoiseConstants::Ward(k) => ward_noise::noise(b, k, q),
        };
        let magnitude = b.fabs(n);
        if let NoiseConstants::Ward(_) = k.noise {
            let zero = b.f32(0.0);
            after = Some(b.fmul(magnitude, zero));
        }
        sum = Some(match sum {
            None => magnitude,
            Some(sum) => {
                let weight = b.f32(1.0 / scale);
                let weighted = b.fmul(magnitude, weight);
                b.fadd(sum, weighted)
            }
        });
    }
    sum.expect("at least one octave")
}

/// `sin(a)` by argument reduction and a degree-9 odd polynomial (see the module notes).
fn sine(b: &mut KernelBuilder, k: &Constants, a: Value) -> Value {
    use std::f32::consts::{FRAC_PI_2, PI};
    let inv_two_pi = b.f32(INV_TWO_PI);
    let turns = b.fmul(a, inv_two_pi);
    let turns = b.ftoi(turns);
    let turns = b.itof(turns);
    let two_pi_hi = b.f32(TWO_PI_HI);
    let two_pi_lo = b.f32(TWO_PI_LO);
    let whole = b.fmul(turns, two_pi_hi);
    let r = b.fsub(a, whole);
    let rest = b.fmul(turns, two_pi_lo);
    let r = b.fsub(r, rest);
    let (half_pi, minus_half_pi) = (b.f32(FRAC_PI_2), b.f32(-FRAC_PI_2));
    let (pi, minus_pi) = (b.f32(PI), b.f32(-PI));
    let above = b.flt(half_pi, r);
    let below = b.flt(r, minus_half_pi);
    let mirrored_above = b.fsub(pi, r);
    let mirrored_below = b.fsub(minus_pi, r);
    let r = b.select(below, mirrored_below, r);
    let r = b.select(above, mirrored_above, r);
    let r2 = b.fmul(r, r);
    let [c3, c5, c7, c9] = SIN_COEFFICIENTS.map(|c| b.f32(c));
    let p = b.fmul(r2, c9);
    let p = b.fadd(p, c7);
    let p = b.fmul(p, r2);
    let p = b.fadd(p, c5);
    let p = b.fmul(p, r2);
    let p = b.fadd(p, c3);
    let p = b.fmul(p, r2);
    let p = b.fadd(p, k.one_f);
    b.fmul(p, r)
}

/// `C(n, i)`.
pub fn binomial(n: usize, i: usize) -> f32 {
    (0..i).fold(1.0, |acc, j| acc * (n - j) as f32 / (j + 1) as f32)
}

/// `0x5F3759DF`, the initial guess of the reciprocal square root.
pub const RSQRT_MAGIC: u32 = 0x5F37_59DF;

/// Newton steps of the reciprocal square root.
pub const RSQRT_STEPS: usize = 3;

/// Parameters of the kernel (the ramp colours are constants).
pub const SCALAR_PARAMS: usize = 10;

use super::{Vec3, dot};

/// `v / |v|` without a divide or square root (see the module notes).
fn normalize(b: &mut KernelBuilder, v: Vec3) -> Vec3 {
    let length_squared = dot(b, v, v);
    let y = reciprocal_sqrt(b, length_squared);
    v.map(|c| b.fmul(c, y))
}

/// `1 / sqrt(x)` without a divide or square root: the bit-level initial guess and
/// [`RSQRT_STEPS`] Newton steps (see the module notes).
pub(crate) fn reciprocal_sqrt(b: &mut KernelBuilder, length_squared: Value) -> Value {
    let bits = b.cast(length_squared, Ty::I32);
    let shift_right = b.constant(1 << 31, Ty::I32);
    let halved_bits = b.op(Op::IMulHiU, &[bits, shift_right]);
    let magic = b.constant(RSQRT_MAGIC, Ty::I32);
    let guess = b.isub(magic, halved_bits);
    let mut y = b.cast(guess, Ty::F32);
    let half = b.f32(0.5);
    let three_halves = b.f32(1.5);
    let half_length_squared = b.fmul(length_squared, half);
    for _ in 0..RSQRT_STEPS {
        let yy = b.fmul(y, y);
        let t = b.fmul(half_length_squared, yy);
        let t = b.fsub(three_halves, t);
        y = b.fmul(y, t);
    }
    y
}

/// With Perlin's noise, needs a cluster count that divides the table's 256 entries (it
/// loads the table in rows) and a scratchpad that holds the table; Ward's needs neither.
fn check_machine(
    desc: &MachineDesc,
    name: &str,
    noise: Noise,
) -> Result<(), MachineRequirementError> {
    if !noise.uses_table() {
        return Ok(());
    }
    let clusters = desc.cluster.count;
    let needs = Needs::new(name, desc);
    if !TABLE.is_multiple_of(clusters) {
        return Err(needs.error(
            format!(
                "a cluster count dividing the {TABLE} entries of its permutation table, which \
                 it loads in rows"
            ),
            format!("{clusters} clusters"),
        ));
    }
    needs.scratchpad_words(TABLE, "the permutation table", false)?;
    Ok(())
}

/// The shader's parameters, declared in stream order (see the module notes).
struct Params {
    frequency: Value,
    turbulence_scale: Value,
    light: Vec3,
    half_vector: Vec3,
    ambient: Value,
    specular: Value,
}

/// Parameters, ramp colours and constants: what comes before the loop (with the table's
/// load, [`load_table`], for Perlin's noise).
fn prologue(b: &mut KernelBuilder, noise: Noise) -> (Params, Vec<[Value; 3]>, Constants) {
    let params = Params {
        frequency: b.param_f32("frequency"),
        turbulence_scale: b.param_f32("turbulence_scale"),
        light: ["x", "y", "z"].map(|c| b.param_f32(&format!("light_{c}"))),
        half_vector: ["x", "y", "z"].map(|c| b.param_f32(&format!("half_{c}"))),
        ambient: b.param_f32("ambient"),
        specular: b.param_f32("specular"),
    };
    // Control colours times their binomial weights (one fp32 multiply, as the machine's).
    let ramp: Vec<[Value; 3]> = (0..RAMP)
        .map(|i| {
            let weight = binomial(RAMP - 1, i);
            RAMP_COLOURS[i].map(|c| b.f32(c * weight))
        })
        .collect();
    let k = Constants::new(b, noise);
    (params, ramp, k)
}

fn load_table(b: &mut KernelBuilder, perm: StreamId) {
    for entry in 0..TABLE {
        let word = b.read_i32(perm);
        b.sp_write(entry as u16, None, word);
    }
}

/// The lit marble colour (r, g, b in [0, 1]) of shading position `p` with normal `normal`.
fn shade(
    b: &mut KernelBuilder,
    k: &Constants,
    params: &Params,
    ramp: &[[Value; 3]],
    zero: Value,
    p: Vec3,
    normal: Vec3,
) -> [Value; 3] {
    let turbulence = turbulence(b, k, p);
    let along = b.fmul(p[0], params.frequency);
    let perturbation = b.fmul(turbulence, params.turbulence_scale);
    let angle = b.fadd(along, perturbation);
    let s = sine(b, k, angle);
    let half = b.f32(0.5);
    let u = b.fmadd(s, half, half);
    let one_minus_u = b.fsub(k.one_f, u);
    // u^i and (1 − u)^i for i in 1..RAMP.
    let powers = |b: &mut KernelBuilder, base: Value| {
        let mut v = vec![base];
        for _ in 2..RAMP {
            let last = *v.last().expect("nonempty");
            v.push(b.fmul(last, base));
        }
        v
    };
    let up = powers(b, u);
    let down = powers(b, one_minus_u);
    let degree = RAMP - 1;
    let basis: Vec<Value> = (0..RAMP)
        .map(|i| match i {
            0 => down[degree - 1],
            i if i == degree => up[degree - 1],
            i => b.fmul(up[i - 1], down[degree - i - 1]),
        })
        .collect();

    let n = normalize(b, normal);
    let n_dot_l = dot(b, n, params.light);
    let diffuse = b.fmax(n_dot_l, zero);
    let lit = b.fadd(params.ambient, diffuse);
    let n_dot_h = dot(b, n, params.half_vector);
    let mut highlight = b.fmax(n_dot_h, zero);
    for _ in 0..4 {
        highlight = b.fmul(highlight, highlight);
    }
    let highlight = b.fmul(highlight, params.specular);

    std::array::from_fn(|ch| {
        let mut colour = None;
        for (&weight, control) in basis.iter().zip(ramp) {
            let term = b.fmul(weight, control[ch]);
            colour = Some(match colour {
                None => term,
                Some(sum) => b.fadd(sum, term),
            });
        }
        let colour = colour.expect("ramp colours");
        let colour = b.fmul(colour, lit);
        let colour = b.fadd(colour, highlight);
        let colour = b.fmax(colour, zero);
        b.fmin(colour, k.one_f)
    })
}

/// The library's `turbulence_ward` (Ward's noise): `fragments` (x, y, z, nx, ny, nz) in,
/// `colours` (r, g, b) out.
pub fn build(desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    build_shader(desc, Noise::Ward)
}

/// The library's `turbulence`: [`build`] over Perlin's improved noise, its table on a
/// second input, `perm`.
pub fn build_perlin(desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    build_shader(desc, Noise::Perlin)
}

/// The shader on (x, y, z, nx, ny, nz) records (see [`check_machine`] for what it needs).
fn build_shader(desc: &MachineDesc, noise: Noise) -> Result<Kernel, MachineRequirementError> {
    let name = match noise {
        Noise::Ward => "turbulence_ward",
        Noise::Perlin => "turbulence",
    };
    check_machine(desc, name, noise)?;
    let mut b = KernelBuilder::new(name);
    let fragments = b.input("fragments");
    let perm = noise.uses_table().then(|| b.input("perm"));
    let colours = b.output("colours");
    let (params, ramp, k) = prologue(&mut b, noise);
    let zero = b.f32(0.0);
    if let Some(perm) = perm {
        load_table(&mut b, perm);
    }

    b.begin_loop(LoopSpec::OverStream(fragments));
    let p: Vec3 = std::array::from_fn(|_| b.read_f32(fragments));
    let normal: Vec3 = std::array::from_fn(|_| b.read_f32(fragments));
    for c in shade(&mut b, &k, &params, &ramp, zero, p, normal) {
        b.write(colours, c);
    }
    b.end_loop();
    Ok(finish(b))
}

/// Words of the `varyings` record of a frame whose only fragment programs are marble: r,
/// g, b, then x, y, z, nx, ny, nz.
pub const MARBLE_RECORD_WORDS: usize = 9;

/// The name of the fragment program of a `noise` marble (`marble`, `marble_ward`).
pub fn fragment_name(noise: Noise) -> &'static str {
    match noise {
        Noise::Ward => "marble_ward",
        Noise::Perlin => "marble",
    }
}

/// `marble`: the shader as the OpenGL pipeline's fragment program (depth 0, no lookups).
/// Per fragment it reads the `varyings` record `irast` writes (`record_words` words: r, g,
/// b, which it drops, then the object-space shading position and normal, then any further
/// words of the frame, dropped) and writes the packed RGBA8 `colour` (each channel
/// `⌊255·c + ½⌋`, alpha 255) the composite expects. With Perlin's noise the table comes in
/// on `perm` as for [`build_perlin`]; the parameters are [`build`]'s.
pub fn build_fragment(
    desc: &MachineDesc,
    record_words: usize,
    noise: Noise,
) -> Result<Kernel, MachineRequirementError> {
    assert!(
        record_words >= MARBLE_RECORD_WORDS,
        "r, g, b, position and normal"
    );
    let name = fragment_name(noise);
    check_machine(desc, name, noise)?;
    let mut b = KernelBuilder::new(name);
    let varyings = b.input("varyings");
    let perm = noise.uses_table().then(|| b.input("perm"));
    let colour_out = b.output("colour");
    let (params, ramp, k) = prologue(&mut b, noise);
    let zero = b.f32(0.0);
    let (half, scale) = (b.f32(0.5), b.f32(255.0));
    let alpha = b.word(0xFF00_0000);
    if let Some(perm) = perm {
        load_table(&mut b, perm);
    }

    b.begin_loop(LoopSpec::OverStream(varyings));
    let record: Vec<Value> = (0..record_words).map(|_| b.read_f32(varyings)).collect();
    let p: Vec3 = std::array::from_fn(|i| record[3 + i]);
    let normal: Vec3 = std::array::from_fn(|i| record[6 + i]);
    let colour = shade(&mut b, &k, &params, &ramp, zero, p, normal);
    let mut packed = alpha;
    for (ch, c) in colour.into_iter().enumerate() {
        packed = super::or_channel(&mut b, packed, c, ch, (half, scale));
    }
    b.write(colour_out, packed);
    b.end_loop();
    Ok(finish(b))
}

/// [`build_fragment`] for the record of a marble-only frame over Ward's noise (the
/// library's `marble_ward`).
pub fn build_marble(desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    build_fragment(desc, MARBLE_RECORD_WORDS, Noise::Ward)
}

/// The library's `marble`: [`build_marble`] over Perlin's improved noise.
pub fn build_marble_perlin(desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    build_fragment(desc, MARBLE_RECORD_WORDS, Noise::Perlin)
}

/// Perlin's permutation (the table of his reference implementation of improved noise),
/// the one the OpenGL pipeline's `marble` fragment program uses.
pub const PERLIN_PERMUTATION: [u8; TABLE] = [
    151, 160, 137, 91, 90, 15, 131, 13, 201, 95, 96, 53, 194, 233, 7, 225, 140, 36, 103, 30, 69,
    142, 8, 99, 37, 240, 21, 10, 23, 190, 6, 148, 247, 120, 234, 75, 0, 26, 197, 62, 94, 252, 219,
    203, 117, 35, 11, 32, 57, 177, 33, 88, 237, 149, 56, 87, 174, 20, 125, 136, 171, 168, 68, 175,
    74, 165, 71, 134, 139, 48, 27, 166, 77, 146, 158, 231, 83, 111, 229, 122, 60, 211, 133, 230,
    220, 105, 92, 41, 55, 46, 245, 40, 244, 102, 143, 54, 65, 25, 63, 161, 1, 216, 80, 73, 209, 76,
    132, 187, 208, 89, 18, 169, 200, 196, 135, 130, 116, 188, 159, 86, 164, 100, 109, 198, 173,
    186, 3, 64, 52, 217, 226, 250, 124, 123, 5, 202, 38, 147, 118, 126, 255, 82, 85, 212, 207, 206,
    59, 227, 47, 16, 58, 17, 182, 189, 28, 42, 223, 183, 170, 213, 119, 248, 152, 2, 44, 154, 163,
    70, 221, 153, 101, 155, 167, 43, 172, 9, 129, 22, 39, 253, 19, 98, 108, 110, 79, 113, 224, 232,
    178, 185, 112, 104, 218, 246, 97, 228, 251, 34, 242, 193, 238, 210, 144, 12, 191, 179, 162,
    241, 81, 51, 145, 235, 249, 14, 239, 107, 49, 192, 214, 31, 181, 199, 106, 157, 184, 84, 204,
    176, 115, 121, 50, 45, 127, 4, 150, 254, 138, 236, 205, 93, 222, 114, 67, 29, 24, 72, 243, 141,
    128, 195, 78, 66, 215, 61, 156, 180,
];

/// A `perm` stream of `table` for `clusters` clusters: each word once per cluster.
pub fn perm_stream(table: impl IntoIterator<Item = u32>, clusters: usize) -> Vec<u32> {
    table
        .into_iter()
        .flat_map(|w| std::iter::repeat_n(w, clusters))
        .collect()
}

/// The `perm` stream of Perlin's permutation ([`PERLIN_PERMUTATION`]) for `clusters`
/// clusters, as the pipelines' marble programs read it.
pub fn perlin_perm_stream(clusters: usize) -> Vec<u32> {
    perm_stream(PERLIN_PERMUTATION.map(u32::from), clusters)
}

/// The table a `perm` stream holds (each word is there once per cluster).
pub fn table_of(perm: &[u32], clusters: usize) -> Vec<u32> {
    perm.iter().step_by(clusters.max(1)).copied().collect()
}

/// A random permutation of `0..256` (Fisher–Yates).
pub fn random_permutation(rng: &mut SplitMix64) -> Vec<u32> {
    let mut table: Vec<u32> = (0..TABLE as u32).collect();
    for i in (1..TABLE).rev() {
        let j = rng.below(i as u32 + 1) as usize;
        table.swap(i, j);
    }
    table
}

/// A random unit vector (as fp32 words).
fn unit_vector(rng: &mut SplitMix64) -> [f32; 3] {
    loop {
        let v: [f32; 3] = std::array::from_fn(|_| uniform(rng, -1.0, 1.0));
        let length = v.iter().map(|c| c * c).sum::<f32>().sqrt();
        if length > 0.25 {
            return v.map(|c| c / length);
        }
    }
}

/// Inputs of [`build`]: [`perlin_inputs`] without the table.
pub fn inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let mut inputs = perlin_inputs(desc, rows, seed);
    inputs.streams.remove(1);
    inputs
}

/// Inputs of [`build_perlin`]: `rows × C` fragments in [-20, 20)³ (negative coordinates
/// exercise `floor`) with normals of length 0.5 to 2, a random permutation table, a
/// frequency in [0.5, 4), a turbulence scale in [1, 8), unit light and half vectors,
/// ambient in [0, 0.3), specular in [0, 1) (the ramp colours are the kernel's constants).
pub fn perlin_inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let mut rng = SplitMix64::new(seed);
    let records: Vec<Vec<u32>> = (0..rows * desc.cluster.count)
        .map(|_| {
            let mut r = uniform_words(&mut rng, 3, -20.0, 20.0);
            let scale = uniform(&mut rng, 0.5, 2.0);
            r.extend(unit_vector(&mut rng).map(|c| (c * scale).to_bits()));
            r
        })
        .collect();
    let table = perm_stream(random_permutation(&mut rng), desc.cluster.count);
    let mut params = vec![
        uniform(&mut rng, 0.5, 4.0).to_bits(),
        uniform(&mut rng, 1.0, 8.0).to_bits(),
    ];
    params.extend(unit_vector(&mut rng).map(f32::to_bits));
    params.extend(unit_vector(&mut rng).map(f32::to_bits));
    params.push(uniform(&mut rng, 0.0, 0.3).to_bits());
    params.push(uniform(&mut rng, 0.0, 1.0).to_bits());
    KernelInputs {
        streams: vec![
            records_to_stream(&records, desc.cluster.count),
            table,
            Vec::new(),
        ],
        params,
    }
}

/// Inputs of [`build_marble`]: [`marble_perlin_inputs`] without the table.
pub fn marble_inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let mut inputs = marble_perlin_inputs(desc, rows, seed);
    inputs.streams.remove(1);
    inputs
}

/// Inputs of [`build_marble_perlin`]: [`perlin_inputs`]' fragments as `varyings` records
/// (a random colour in [0, 1) first, which the kernel drops), the same table and
/// parameters.
pub fn marble_perlin_inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let c = desc.cluster.count;
    let mut inputs = perlin_inputs(desc, rows, seed);
    let mut rng = SplitMix64::new(seed ^ 0x6D61_7262_6C65);
    let records: Vec<Vec<u32>> = super::stream_to_records(&inputs.streams[0], 6, c)
        .into_iter()
        .map(|r| {
            let mut record = uniform_words(&mut rng, 3, 0.0, 1.0);
            record.extend(r);
            record
        })
        .collect();
    inputs.streams[0] = records_to_stream(&records, c);
    inputs
}
