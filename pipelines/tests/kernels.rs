//! The kernel library against plain-Rust references: every kernel is built for 1, 8 and 32
//! clusters, interpreted on random inputs, and every output word compared (bit for bit)
//! with an independent reference that does the same fp32 operations in the same order.

use std::f32::consts::{FRAC_PI_2, PI};

use imagine_pipelines::kernel::{
    KernelBuilder, KernelInputs, LoopSpec, Region, Ty, interp::scratchpad_words, interpret,
};
use imagine_pipelines::kernels::{self, find, library, unit_mix};
use imagine_units::desc::MachineDesc;

const MACHINES: [&str; 3] = ["gold1", "gold8", "gold32"];

fn machine(name: &str) -> MachineDesc {
    MachineDesc::resolve(name).expect("built-in machine")
}

/// Runs library kernel `name` on `machine` for `rows` iterations: its inputs and outputs.
fn run(name: &str, desc: &MachineDesc, rows: usize, seed: u64) -> (KernelInputs, Vec<Vec<u32>>) {
    let lib = find(name).expect("library kernel");
    let kernel = (lib.build)(desc).unwrap();
    let inputs = (lib.inputs)(desc, rows, seed);
    let out = interpret(&kernel, &inputs, desc).unwrap_or_else(|e| panic!("{e}"));
    (inputs, out)
}

/// Element `e`'s record of `k` words in a stream laid out for `c` clusters.
fn record(words: &[u32], e: usize, k: usize, c: usize) -> Vec<u32> {
    (0..k)
        .map(|j| words[(e / c) * k * c + j * c + e % c])
        .collect()
}

fn floats(words: &[u32]) -> Vec<f32> {
    words.iter().map(|&w| f32::from_bits(w)).collect()
}

/// Compares output words bit for bit, naming the first difference.
fn assert_words(what: &str, got: &[u32], want: &[u32]) {
    assert_eq!(got.len(), want.len(), "{what}: lengths differ");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert_eq!(
            g,
            w,
            "{what}: word {i} is {g:#010x} ({}), expected {w:#010x} ({})",
            f32::from_bits(*g),
            f32::from_bits(*w)
        );
    }
}

/// RISC-V `fmax.s`/`fmin.s` on non-NaN operands: −0 orders below +0.
fn fmax(a: f32, b: f32) -> f32 {
    if a == b {
        if a.is_sign_positive() { a } else { b }
    } else if a > b {
        a
    } else {
        b
    }
}

fn fmin(a: f32, b: f32) -> f32 {
    if a == b {
        if a.is_sign_negative() { a } else { b }
    } else if a < b {
        a
    } else {
        b
    }
}

fn dot(u: [f32; 3], v: [f32; 3]) -> f32 {
    (u[0] * v[0] + u[1] * v[1]) + u[2] * v[2]
}

// ---- transform ------------------------------------------------------------------------

fn transform_reference(m: &[f32], p: [f32; 4]) -> [f32; 4] {
    std::array::from_fn(|i| {
        let r = &m[4 * i..4 * i + 4];
        ((r[0] * p[0] + r[1] * p[1]) + r[2] * p[2]) + r[3] * p[3]
    })
}

#[test]
fn transform_matches_reference() {
    for name in MACHINES {
        let desc = machine(name);
        let c = desc.cluster.count;
        let (inputs, out) = run("transform", &desc, 3, 11);
        let m = floats(&inputs.params);
        let n = inputs.streams[0].len() / 4;
        let mut want = vec![0; 4 * n];
        for e in 0..n {
            let p = floats(&record(&inputs.streams[0], e, 4, c));
            let r = transform_reference(&m, [p[0], p[1], p[2], p[3]]);
            for (j, v) in r.iter().enumerate() {
                want[(e / c) * 4 * c + j * c + e % c] = v.to_bits();
            }
        }
        assert_words(&format!("transform on {name}"), &out[1], &want);
    }
}

// ---- vertex ---------------------------------------------------------------------------

fn normalize(v: [f32; 3]) -> [f32; 3] {
    let inverse = 1.0 / dot(v, v).sqrt();
    v.map(|c| c * inverse)
}

fn vertex_reference(params: &[f32], vertex: &[f32]) -> [f32; 7] {
    let m = &params[0..16];
    let eye = [params[16], params[17], params[18]];
    let p = [vertex[0], vertex[1], vertex[2]];
    let clip = transform_reference(m, [p[0], p[1], p[2], 1.0]);
    let n = normalize([vertex[3], vertex[4], vertex[5]]);
    let v = normalize(std::array::from_fn(|i| eye[i] - p[i]));
    let material = &params[16 + 3 + 18..];
    let (diffuse, specular, ambient) = (&material[0..3], &material[3..6], &material[6..9]);
    let mut colour = [ambient[0], ambient[1], ambient[2]];
    for light in params[19..37].chunks(6) {
        let l = normalize(std::array::from_fn(|i| light[i] - p[i]));
        let n_dot_l = fmax(dot(n, l), 0.0);
        let h = normalize(std::array::from_fn(|i| l[i] + v[i]));
        let mut spec = fmax(dot(n, h), 0.0);
        for _ in 0..4 {
            spec *= spec;
        }
        for ch in 0..3 {
            colour[ch] += (diffuse[ch] * n_dot_l + specular[ch] * spec) * light[3 + ch];
        }
    }
    let mut out = [0.0; 7];
    out[..4].copy_from_slice(&clip);
    for ch in 0..3 {
        out[4 + ch] = fmin(fmax(colour[ch], 0.0), 1.0);
    }
    out
}

#[test]
fn vertex_matches_reference() {
    for name in MACHINES {
        let desc = machine(name);
        let c = desc.cluster.count;
        let (inputs, out) = run("vertex", &desc, 3, 12);
        let params = floats(&inputs.params);
        assert_eq!(params.len(), kernels::vertex::PARAMS);
        let n = inputs.streams[0].len() / 6;
        let mut want = vec![0; 7 * n];
        for e in 0..n {
            let r = vertex_reference(&params, &floats(&record(&inputs.streams[0], e, 6, c)));
            for (j, v) in r.iter().enumerate() {
                want[(e / c) * 7 * c + j * c + e % c] = v.to_bits();
            }
        }
        assert_words(&format!("vertex on {name}"), &out[1], &want);
    }
}

// ---- turbulence -----------------------------------------------------------------------

/// Perlin's reference `grad`.
fn grad(hash: usize, x: f32, y: f32, z: f32) -> f32 {
    let h = hash & 15;
    let u = if h < 8 { x } else { y };
    let v = if h < 4 {
        y
    } else if h == 12 || h == 14 {
        x
    } else {
        z
    };
    (if h & 1 == 0 { u } else { -u }) + (if h & 2 == 0 { v } else { -v })
}

fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// Perlin's improved noise with his doubled table; the trilinear interpolation as the
/// kernel evaluates it (weights `w_z·(w_y·w_x)`, corners x fastest).
fn noise(p: &[usize; 512], x: f32, y: f32, z: f32) -> f32 {
    let cell = |t: f32| (t.floor() as i32 & 255) as usize;
    let (cx, cy, cz) = (cell(x), cell(y), cell(z));
    let (x, y, z) = (x - x.floor(), y - y.floor(), z - z.floor());
    let (u, v, w) = (fade(x), fade(y), fade(z));
    let a = p[cx] + cy;
    let (aa, ab) = (p[a] + cz, p[a + 1] + cz);
    let b = p[cx + 1] + cy;
    let (ba, bb) = (p[b] + cz, p[b + 1] + cz);
    let g = [
        grad(p[aa], x, y, z),
        grad(p[ba], x - 1.0, y, z),
        grad(p[ab], x, y - 1.0, z),
        grad(p[bb], x - 1.0, y - 1.0, z),
        grad(p[aa + 1], x, y, z - 1.0),
        grad(p[ba + 1], x - 1.0, y, z - 1.0),
        grad(p[ab + 1], x, y - 1.0, z - 1.0),
        grad(p[bb + 1], x - 1.0, y - 1.0, z - 1.0),
    ];
    let (wu, wv, ww) = ([1.0 - u, u], [1.0 - v, v], [1.0 - w, w]);
    let mut sum = 0.0;
    for (corner, gradient) in g.iter().enumerate() {
        let weight = ww[corner >> 2] * (wv[(corner >> 1) & 1] * wu[corner & 1]);
        let term = weight * gradient;
        sum = if corner == 0 { term } else { sum + term };
    }
    sum
}

/// Perlin's noise exactly as his reference code (nested lerps), in f64.
fn textbook_noise(p: &[usize; 512], x: f64, y: f64, z: f64) -> f64 {
    let fade = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let lerp = |t: f64, a: f64, b: f64| a + t * (b - a);
    let grad = |h: usize, x: f64, y: f64, z: f64| {
        let h = h & 15;
        let u = if h < 8 { x } else { y };
        let v = if h < 4 {
            y
        } else if h == 12 || h == 14 {
            x
        } else {
            z
        };
        (if h & 1 == 0 { u } else { -u }) + (if h & 2 == 0 { v } else { -v })
    };
    let cell = |t: f64| (t.floor() as i64 & 255) as usize;
    let (cx, cy, cz) = (cell(x), cell(y), cell(z));
    let (x, y, z) = (x - x.floor(), y - y.floor(), z - z.floor());
    let (u, v, w) = (fade(x), fade(y), fade(z));
    let a = p[cx] + cy;
    let (aa, ab) = (p[a] + cz, p[a + 1] + cz);
    let b = p[cx + 1] + cy;
    let (ba, bb) = (p[b] + cz, p[b + 1] + cz);
    lerp(
        w,
        lerp(
            v,
            lerp(u, grad(p[aa], x, y, z), grad(p[ba], x - 1.0, y, z)),
            lerp(
                u,
                grad(p[ab], x, y - 1.0, z),
                grad(p[bb], x - 1.0, y - 1.0, z),
            ),
        ),
        lerp(
            v,
            lerp(
                u,
                grad(p[aa + 1], x, y, z - 1.0),
                grad(p[ba + 1], x - 1.0, y, z - 1.0),
            ),
            lerp(
                u,
                grad(p[ab + 1], x, y - 1.0, z - 1.0),
                grad(p[bb + 1], x - 1.0, y - 1.0, z - 1.0),
            ),
        ),
    )
}

fn doubled_table(perm: &[u32]) -> [usize; 512] {
    std::array::from_fn(|i| perm[i & 255] as usize)
}

fn sine(a: f32) -> f32 {
    use kernels::turbulence::{INV_TWO_PI, SIN_COEFFICIENTS as S, TWO_PI_HI, TWO_PI_LO};
    let turns = (a * INV_TWO_PI).round_ties_even();
    let r = (a - turns * TWO_PI_HI) - turns * TWO_PI_LO;
    let r = if r > FRAC_PI_2 {
        PI - r
    } else if r < -FRAC_PI_2 {
        -PI - r
    } else {
        r
    };
    let r2 = r * r;
    ((((r2 * S[3] + S[2]) * r2 + S[1]) * r2 + S[0]) * r2 + 1.0) * r
}

fn rsqrt(x: f32) -> f32 {
    let mut y = f32::from_bits(0x5F37_59DF - (x.to_bits() >> 1));
    let half = x * 0.5;
    for _ in 0..3 {
        y *= 1.5 - half * (y * y);
    }
    y
}

const BINOMIAL_7: [f32; 8] = [1.0, 7.0, 21.0, 35.0, 35.0, 21.0, 7.0, 1.0];

/// The noise of a marble: Perlin's over his (doubled) table, or Ward's.
#[derive(Clone, Copy)]
enum Noise<'a> {
    Perlin(&'a [usize; 512]),
    Ward,
}

// ---- Ward's noise, as the kernel evaluates it (see `kernels::ward_noise`) -------------

/// `frand`'s integer `v` as fp32: `((s·(s·s·15731 + 789221) + 1376312589) & 0x7fffffff)`
/// with `s = (seed << 13) ^ seed`, 32-bit wrapping.
fn ward_v(seed: i32) -> f32 {
    let s = (seed << 13) ^ seed;
    let r = s
        .wrapping_mul(s.wrapping_mul(s).wrapping_mul(15731).wrapping_add(789_221))
        .wrapping_add(1_376_312_589);
    (r & 0x7fff_ffff) as f32
}

/// `[hpoly1, hpoly2, hpoly3, hpoly4]` and `hpoly3 + hpoly4`, in the kernel's order.
fn ward_hermite(t: f32) -> ([f32; 4], f32) {
    let t2 = t * t;
    let q = ((t + t) - 3.0) * t2;
    let tm1 = t - 1.0;
    let (h3, h4) = ((tm1 * tm1) * t, tm1 * t2);
    ([q + 1.0, -q, h3, h4], h3 + h4)
}

fn ward_weighted(h: &[f32; 4], a: f32, b: f32, tangents: Option<(f32, f32)>) -> f32 {
    let mut sum = h[0] * a + h[1] * b;
    if let Some((c, d)) = tangents {
        sum += h[2] * c;
        sum += h[3] * d;
    }
    sum
}

/// Ward's noise in fp32, the kernel's evaluation: the interpolation of the `v`s, then
/// `((1 + S_x) + S_y) + S_z − 2^−30·I`.
fn ward_noise32(p: [f32; 3]) -> f32 {
    let floor = p.map(|c| c.floor());
    let cell = floor.map(|c| c as i32);
    let ([hx, hy, hz], [sx, sy, sz]) = {
        let w = std::array::from_fn::<_, 3, _>(|i| ward_hermite(p[i] - floor[i]));
        (w.map(|(h, _)| h), w.map(|(_, s)| s))
    };
    const COEFFICIENTS: [[i32; 3]; 4] =
        [[67, 59, 71], [73, 79, 83], [89, 97, 101], [103, 107, 109]];
    // v[corner][random], corner bit 0 x, bit 1 y, bit 2 z.
    let v: Vec<[f32; 4]> = (0..8)
        .map(|corner: usize| {
            std::array::from_fn(|random| {
                let seed = (0..3).fold(0i32, |acc, axis| {
                    let c = cell[axis].wrapping_add((corner >> axis & 1) as i32);
                    acc.wrapping_add(COEFFICIENTS[random][axis].wrapping_mul(c))
                });
                ward_v(seed)
            })
        })
        .collect();
    let x: Vec<[f32; 3]> = [0, 2, 4, 6]
        .iter()
        .map(|&i| {
            let (a, b) = (v[i], v[i | 1]);
            [
                ward_weighted(&hx, a[3], b[3], Some((a[0], b[0]))),
                ward_weighted(&hx, a[1], b[1], None),
                ward_weighted(&hx, a[2], b[2], None),
            ]
        })
        .collect();
    let y: Vec<[f32; 2]> = [0, 2]
        .iter()
        .map(|&j| {
            let (a, b) = (x[j], x[j + 1]);
            [
                ward_weighted(&hy, a[0], b[0], Some((a[1], b[1]))),
                ward_weighted(&hy, a[2], b[2], None),
            ]
        })
        .collect();
    let interpolated = ward_weighted(&hz, y[0][0], y[1][0], Some((y[0][1], y[1][1])));
    (((1.0 + sx) + sy) + sz) + interpolated * -(1.0 / (1u32 << 30) as f32)
}

/// Ward's `noise3` as his code has it (recursive over the axes, each random in f64 from
/// its exact integer), the value.
fn textbook_ward_noise(p: [f64; 3]) -> f64 {
    fn frand(seed: i32) -> f64 {
        let s = (seed << 13) ^ seed;
        let r = s
            .wrapping_mul(s.wrapping_mul(s).wrapping_mul(15731).wrapping_add(789_221))
            .wrapping_add(1_376_312_589);
        1.0 - f64::from(r & 0x7fff_ffff) / 1_073_741_824.0
    }
    fn interpolate(f: &mut [f64; 4], i: usize, n: usize, lim: &[[i32; 2]; 3], arg: &[f64; 3]) {
        if n == 0 {
            let (x, y, z) = (lim[0][i & 1], lim[1][i >> 1 & 1], lim[2][i >> 2]);
            let r = |a: i32, b: i32, c: i32| {
                frand(
                    a.wrapping_mul(x)
                        .wrapping_add(b.wrapping_mul(y))
                        .wrapping_add(c.wrapping_mul(z)),
                )
            };
            *f = [
                r(67, 59, 71),
                r(73, 79, 83),
                r(89, 97, 101),
                r(103, 107, 109),
            ];
            return;
        }
        let n = n - 1;
        let (mut f0, mut f1) = ([0.0; 4], [0.0; 4]);
        interpolate(&mut f0, i, n, lim, arg);
        interpolate(&mut f1, i | 1 << n, n, lim, arg);
        let t = arg[n];
        let (hp1, hp2) = ((2.0 * t - 3.0) * t * t + 1.0, (-2.0 * t + 3.0) * t * t);
        let (hp3, hp4) = (((t - 2.0) * t + 1.0) * t, (t - 1.0) * t * t);
        for j in 0..3 {
            f[j] = f0[j] * hp1 + f1[j] * hp2;
        }
        f[3] = f0[3] * hp1 + f1[3] * hp2 + f0[n] * hp3 + f1[n] * hp4;
    }
    let lim = p.map(|c| [c.floor() as i32, c.floor() as i32 + 1]);
    let arg: [f64; 3] = std::array::from_fn(|i| p[i] - p[i].floor());
    let mut f = [0.0; 4];
    interpolate(&mut f, 0, 3, &lim, &arg);
    f[3]
}

/// The marble shader's colour for fragment `f`, as the kernel computes it.
fn marble_reference(noise_of: Noise, params: &[f32], f: &[f32]) -> [f32; 3] {
    let (frequency, scale) = (params[0], params[1]);
    let (light, half) = (
        [params[2], params[3], params[4]],
        [params[5], params[6], params[7]],
    );
    let (ambient, specular) = (params[8], params[9]);
    let mut turbulence = 0.0f32;
    // Ward's octaves start from `0·|noise|` of the one before (+0: the same point).
    let mut after = None;
    for octave in 0..4 {
        let s = (1 << octave) as f32;
        let q = [f[0] * s, f[1] * s, f[2] * s];
        let n = match noise_of {
            Noise::Perlin(p) => noise(p, q[0], q[1], q[2]),
            Noise::Ward => ward_noise32(q.map(|c| after.map_or(c, |zero| c + zero))),
        }
        .abs();
        after = Some(n * 0.0);
        turbulence = if octave == 0 { n } else { turbulence + n / s };
    }
    let u = sine(f[0] * frequency + turbulence * scale) * 0.5 + 0.5;
    let powers = |base: f32| -> Vec<f32> {
        (1..8)
            .scan(1.0f32, |acc, i| {
                *acc = if i == 1 { base } else { *acc * base };
                Some(*acc)
            })
            .collect()
    };
    let (up, down) = (powers(u), powers(1.0 - u));
    let basis: Vec<f32> = (0..8)
        .map(|i| match i {
            0 => down[6],
            7 => up[6],
            i => up[i - 1] * down[6 - i],
        })
        .collect();
    let normal = [f[3], f[4], f[5]];
    let y = rsqrt(dot(normal, normal));
    let n = normal.map(|c| c * y);
    let lit = ambient + fmax(dot(n, light), 0.0);
    let mut highlight = fmax(dot(n, half), 0.0);
    for _ in 0..4 {
        highlight *= highlight;
    }
    let highlight = highlight * specular;
    std::array::from_fn(|ch| {
        let ramp = |i: usize| kernels::turbulence::RAMP_COLOURS[i][ch] * BINOMIAL_7[i];
        let mut colour = basis[0] * ramp(0);
        for (i, b) in basis.iter().enumerate().skip(1) {
            colour += b * ramp(i);
        }
        fmin(fmax(colour * lit + highlight, 0.0), 1.0)
    })
}

#[test]
fn turbulence_matches_reference() {
    turbulence_matches_reference_over("turbulence", true);
}

/// Ward's noise: its kernel takes the compiler about 4 minutes a machine.
#[test]
#[ignore = "Ward's turbulence compiles for minutes: cargo test --release -- --ignored"]
fn turbulence_ward_matches_reference() {
    turbulence_matches_reference_over("turbulence_ward", false);
}

fn turbulence_matches_reference_over(kernel: &str, perlin: bool) {
    for name in MACHINES {
        let desc = machine(name);
        let c = desc.cluster.count;
        let rows = if c == 1 { 16 } else { 2 };
        let (inputs, out) = run(kernel, &desc, rows, 13);
        let table =
            perlin.then(|| doubled_table(&kernels::turbulence::table_of(&inputs.streams[1], c)));
        let noise = table.as_ref().map_or(Noise::Ward, Noise::Perlin);
        let params = floats(&inputs.params);
        let n = inputs.streams[0].len() / 6;
        let mut want = vec![0; 3 * n];
        for e in 0..n {
            let f = floats(&record(&inputs.streams[0], e, 6, c));
            for (j, v) in marble_reference(noise, &params, &f).iter().enumerate() {
                want[(e / c) * 3 * c + j * c + e % c] = v.to_bits();
            }
        }
        let colours = out.last().expect("the colours");
        assert_words(&format!("{kernel} on {name}"), colours, &want);
    }
}

/// The marble fragment program reads irast's varyings (r, g, b dropped, then the
/// turbulence kernel's record) and packs the shader's colour as RGBA8.
#[test]
fn marble_fragment_is_turbulence_packed() {
    marble_fragment_is_turbulence_packed_over("marble", true);
}

/// Over Ward's noise (minutes of compiling a machine).
#[test]
#[ignore = "Ward's marble compiles for minutes: cargo test --release -- --ignored"]
fn marble_ward_fragment_is_turbulence_packed() {
    marble_fragment_is_turbulence_packed_over("marble_ward", false);
}

fn marble_fragment_is_turbulence_packed_over(kernel: &str, perlin: bool) {
    for name in MACHINES {
        let desc = machine(name);
        let c = desc.cluster.count;
        let rows = if c == 1 { 16 } else { 2 };
        let (inputs, out) = run(kernel, &desc, rows, 17);
        let table =
            perlin.then(|| doubled_table(&kernels::turbulence::table_of(&inputs.streams[1], c)));
        let noise = table.as_ref().map_or(Noise::Ward, Noise::Perlin);
        let params = floats(&inputs.params);
        let k = kernels::turbulence::MARBLE_RECORD_WORDS;
        let n = inputs.streams[0].len() / k;
        let want: Vec<u32> = (0..n)
            .map(|e| {
                let f = floats(&record(&inputs.streams[0], e, k, c)[3..]);
                let rgb = marble_reference(noise, &params, &f);
                let byte = |ch: usize| ((rgb[ch] * 255.0 + 0.5) as u32) << (8 * ch);
                0xFF00_0000 | byte(0) | byte(1) | byte(2)
            })
            .collect();
        // One word per fragment: element order is the stream's.
        let colour = out.last().expect("the colour");
        assert_words(&format!("{kernel} on {name}"), colour, &want);
    }
}

/// The kernel's evaluation of Ward's noise (folded affine `frand`, fp32) against Ward's
/// recursion in f64, and at lattice points the corner's value exactly as `frand` gives it.
#[test]
fn turbulence_noise_is_wards() {
    let mut rng = imagine_units::arith::fp32::testgen::SplitMix64::new(21);
    let mut worst = 0.0f64;
    for _ in 0..5000 {
        let v: [f32; 3] =
            std::array::from_fn(|_| (rng.next_u32() as f32 / u32::MAX as f32) * 80.0 - 40.0);
        let ours = f64::from(ward_noise32(v));
        let ward = textbook_ward_noise(v.map(f64::from));
        worst = worst.max((ours - ward).abs());
        assert!(ward.abs() <= 2.0, "noise{v:?} = {ward} is out of range");
    }
    assert!(worst < 2e-5, "worst difference {worst}");
    let at = textbook_ward_noise([3.0, -7.0, 12.0]);
    assert!((f64::from(ward_noise32([3.0, -7.0, 12.0])) - at).abs() < 1e-6);
}

#[test]
fn perlins_permutation_is_a_permutation() {
    let mut seen = [false; 256];
    for &p in &kernels::turbulence::PERLIN_PERMUTATION {
        assert!(!seen[p as usize], "{p} twice");
        seen[p as usize] = true;
    }
}

#[test]
fn turbulence_noise_is_perlins() {
    // The reference's weighted-sum interpolation agrees with Perlin's nested lerps (to
    // rounding), and both vanish on lattice points.
    let desc = machine("gold8");
    let inputs = (find("turbulence").unwrap().inputs)(&desc, 1, 5);
    let table = doubled_table(&kernels::turbulence::table_of(
        &inputs.streams[1],
        desc.cluster.count,
    ));
    let mut rng = imagine_units::arith::fp32::testgen::SplitMix64::new(9);
    for _ in 0..2000 {
        let v: [f32; 3] =
            std::array::from_fn(|_| (rng.next_u32() as f32 / u32::MAX as f32) * 80.0 - 40.0);
        let ours = noise(&table, v[0], v[1], v[2]);
        let perlin = textbook_noise(&table, v[0] as f64, v[1] as f64, v[2] as f64);
        assert!(
            (ours as f64 - perlin).abs() < 1e-5,
            "noise{v:?}: {ours} vs {perlin}"
        );
        assert!(perlin.abs() <= 1.1, "noise{v:?} = {perlin} is out of range");
    }
    assert_eq!(noise(&table, 3.0, -7.0, 12.0), 0.0);
}

#[test]
fn turbulence_is_a_big_balanced_loop() {
    let kernel = kernels::turbulence::build(&machine("gold8")).unwrap();
    assert!(kernel.op_count(Region::Loop) > 1000);
    let mix = unit_mix(&kernel, Region::Loop);
    assert_eq!(mix.divsqrt, 0, "no divide or square root in the loop");
    // Neither the 3 adders nor the 2 multipliers carry more than 1.5 times the load of the
    // other (per unit).
    let (adder, multiplier) = (mix.adder as f64 / 3.0, mix.multiplier as f64 / 2.0);
    assert!(
        adder < 1.5 * multiplier && multiplier < 1.5 * adder,
        "{mix:?}"
    );
}

// ---- prefix_sum, compact --------------------------------------------------------------

#[test]
fn prefix_sum_matches_reference() {
    for name in MACHINES {
        let desc = machine(name);
        let (inputs, out) = run("prefix_sum", &desc, 5, 14);
        let want: Vec<u32> = inputs.streams[0]
            .iter()
            .scan(0u32, |sum, &v| {
                *sum = sum.wrapping_add(v);
                Some(*sum)
            })
            .collect();
        assert_words(&format!("prefix_sum on {name}"), &out[1], &want);
    }
}

#[test]
fn compact_matches_reference() {
    for name in MACHINES {
        let desc = machine(name);
        let (mut inputs, _) = run("compact", &desc, 6, 15);
        // A NaN, an infinity and the threshold itself are dropped.
        let threshold = inputs.params[0];
        inputs.streams[0][..3].copy_from_slice(&[0x7FC0_0000, 0x7F80_0000, threshold]);
        let kernel = kernels::compact::build(&desc).unwrap();
        let out = interpret(&kernel, &inputs, &desc).unwrap();
        let t = f32::from_bits(threshold);
        let want: Vec<u32> = inputs.streams[0]
            .iter()
            .copied()
            .filter(|&w| f32::from_bits(w) < t)
            .collect();
        assert!(!want.is_empty() && want.len() < inputs.streams[0].len());
        assert_words(&format!("compact on {name}"), &out[1], &want);
    }
}

// ---- hash -----------------------------------------------------------------------------

#[test]
fn hash_matches_reference() {
    for name in MACHINES {
        let desc = machine(name);
        let c = desc.cluster.count;
        let rows = if c == 1 { 96 } else { 12 };
        let (inputs, out) = run("hash_xy", &desc, rows, 16);
        let mut stamps = vec![[0u32; 32]; c];
        let (mut ok, mut conflict) = (Vec::new(), Vec::new());
        for row in 0..rows {
            let (mut ok_row, mut conflict_row) = (Vec::new(), Vec::new());
            for (cluster, stamp) in stamps.iter_mut().enumerate() {
                let f = record(&inputs.streams[0], row * c + cluster, 2, c);
                let (x, y) = (f[0], f[1]);
                let bit = 1u32 << (x % 32);
                if stamp[(y % 32) as usize] & bit != 0 {
                    conflict_row.push((x, y));
                } else {
                    stamp[(y % 32) as usize] |= bit;
                    ok_row.push((x, y));
                }
            }
            for (list, row) in [(&mut ok, ok_row), (&mut conflict, conflict_row)] {
                list.extend(row.iter().map(|f| f.0));
                list.extend(row.iter().map(|f| f.1));
            }
        }
        assert!(
            !conflict.is_empty() && !ok.is_empty(),
            "{name}: test both outcomes"
        );
        assert_words(&format!("hash ok on {name}"), &out[1], &ok);
        assert_words(&format!("hash conflict on {name}"), &out[2], &conflict);
    }
}

// ---- sort32, merge --------------------------------------------------------------------

/// Kernel `name` leaves every `chunk`-word chunk of its input sorted.
fn sorts_chunks(name: &str, chunk: usize, seed: u64) {
    for machine_name in MACHINES {
        let desc = machine(machine_name);
        let (inputs, out) = run(name, &desc, 5, seed);
        let mut want = inputs.streams[0].clone();
        for c in want.chunks_mut(chunk) {
            c.sort_unstable();
        }
        assert_words(&format!("{name} on {machine_name}"), &out[1], &want);
    }
}

#[test]
fn sort32_matches_reference() {
    sorts_chunks("sort32_keys", 32, 17);
}

#[test]
fn merge_matches_reference() {
    sorts_chunks("merge", 64, 18);
}

#[test]
fn sort32_sorts_every_pattern_of_a_sorting_network_test() {
    // 0/1 principle: a comparator network sorts everything if it sorts all 0/1 inputs; a
    // sample of them plus reversed and constant chunks.
    let desc = machine("gold8");
    let kernel = kernels::sort32::build(&desc).unwrap();
    let mut rng = imagine_units::arith::fp32::testgen::SplitMix64::new(3);
    let mut keys: Vec<u32> = (0..32).rev().collect();
    keys.extend([7u32; 32]);
    for _ in 0..64 {
        let bits = rng.next_u32();
        keys.extend((0..32).map(|i| (bits >> i) & 1));
    }
    let inputs = KernelInputs {
        streams: vec![keys.clone(), Vec::new()],
        params: Vec::new(),
    };
    let out = interpret(&kernel, &inputs, &desc).unwrap();
    for chunk in keys.chunks_mut(32) {
        chunk.sort_unstable();
    }
    assert_words("sort32 patterns", &out[1], &keys);
}

// ---- the library and its limits -------------------------------------------------------

#[test]
fn library_kernels_fit_the_machine() {
    for name in MACHINES {
        let desc = machine(name);
        for lib in library() {
            let kernel = (lib.build)(&desc).unwrap();
            assert_eq!(kernel.name, lib.name);
            let hidden = usize::from(!kernel.params.is_empty());
            assert!(
                kernel.streams.len() + hidden <= 8,
                "{}: too many streams",
                lib.name
            );
            assert!(scratchpad_words(&kernel, &desc) >= 32);
            // Inputs are deterministic and fit the kernel.
            let inputs = (lib.inputs)(&desc, 2, 7);
            assert_eq!(inputs, (lib.inputs)(&desc, 2, 7));
            assert_ne!(inputs, (lib.inputs)(&desc, 2, 8));
            assert_eq!(inputs.streams.len(), kernel.streams.len());
            assert_eq!(inputs.params.len(), kernel.params.len(), "{}", lib.name);
            interpret(&kernel, &inputs, &desc).unwrap_or_else(|e| panic!("{e}"));
        }
    }
    assert!(find("no_such_kernel").is_none());
    let mut names: Vec<&str> = library().iter().map(|k| k.name).collect();
    names.sort_unstable();
    names.dedup();
    assert_eq!(names.len(), library().len());
}

#[test]
fn library_rejects_bad_inputs() {
    let desc = machine("gold8");
    // A stream that ends inside a chunk.
    let kernel = kernels::sort32::build(&desc).unwrap();
    let inputs = KernelInputs {
        streams: vec![vec![0; 40], Vec::new()],
        params: Vec::new(),
    };
    let e = interpret(&kernel, &inputs, &desc).unwrap_err();
    assert!(e.message.contains("only"), "{e}");
    // Missing parameters.
    let kernel = kernels::transform::build(&desc).unwrap();
    let mut inputs = (find("transform").unwrap().inputs)(&desc, 1, 1);
    inputs.params.pop();
    let e = interpret(&kernel, &inputs, &desc).unwrap_err();
    assert!(e.message.contains("parameters"), "{e}");
}

#[test]
fn library_kernels_name_what_the_machine_lacks() {
    let shaped = |clusters: usize, scratchpad: usize, condition_codes: usize| {
        let mut desc = machine("gold8");
        desc.name = "shaped".into();
        desc.cluster.count = clusters;
        desc.scratchpad.words = scratchpad;
        desc.cluster.condition_codes = condition_codes;
        desc
    };
    let error = |name: &str, desc: &MachineDesc| {
        (find(name).unwrap().build)(desc)
            .map(|_| ())
            .unwrap_err()
            .to_string()
    };
    for clusters in [6, 12, 64] {
        let desc = shaped(clusters, 256, 16);
        for name in ["sort32_keys", "merge"] {
            assert_eq!(
                error(name, &desc),
                format!(
                    "kernel `{name}` needs a power-of-two cluster count up to 32 \
                     (machine `shaped` has {clusters} clusters)"
                )
            );
        }
    }
    for clusters in [3, 6, 12] {
        let e = error("turbulence", &shaped(clusters, 256, 16));
        assert!(
            e.contains("turbulence") && e.contains("dividing the 256"),
            "{e}"
        );
    }
    let e = error("turbulence", &shaped(8, 255, 16));
    assert!(e.contains("256 scratchpad words"), "{e}");
    let e = error("hash_xy", &shaped(8, 8, 16));
    assert!(
        e.contains("34 scratchpad words") && e.contains("has 8 words"),
        "{e}"
    );
    let e = error("sort32_keys", &shaped(8, 256, 2));
    assert!(
        e.contains("condition codes") && e.contains("has 2 condition codes"),
        "{e}"
    );
    // Kernels that serve any cluster count do.
    for name in [
        "transform",
        "vertex",
        "prefix_sum",
        "compact",
        "hash_xy",
        "turbulence_ward",
    ] {
        for clusters in [3, 6, 12, 64] {
            let desc = shaped(clusters, 256, 16);
            (find(name).unwrap().build)(&desc).unwrap_or_else(|e| panic!("{e}"));
        }
    }
}

#[test]
fn verifier_rejects_a_loop_value_used_after_the_loop() {
    let mut b = KernelBuilder::new("leak");
    let (input, output) = (b.input("in"), b.output("out"));
    b.begin_loop(LoopSpec::OverStream(input));
    let x = b.read_as(input, Ty::F32);
    b.end_loop();
    b.write(output, x);
    let e = b.finish().unwrap_err();
    assert!(e.message.contains("after the loop"), "{e}");
}

/// `turbulence` on a machine with two condition codes has no schedule at any interval (not
/// even one iteration at a time): the compiler gives up after a bounded number of tries,
/// naming the kernel and the resource, where it used to try every interval up to three
/// times the bound for minutes. About a minute of compiling: run with `--ignored`.
#[test]
#[ignore]
fn the_compiler_gives_up_after_bounded_effort() {
    let mut desc = machine("gold8");
    desc.name = "two-codes".into();
    desc.cluster.condition_codes = 2;
    let kernel = (find("turbulence").unwrap().build)(&desc).unwrap();
    let e = imagine_pipelines::compile::compile(&kernel, &desc)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("turbulence") && e.contains("condition codes") && e.contains("gave up"),
        "{e}"
    );
}
