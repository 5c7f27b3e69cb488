//! Texture sampling as kernels: a textured material's fragment program, split at its
//! texture lookups as the thesis splits RTSL fragment programs (Owens 2002, §4.2 and
//! §4.4.4). Kernels never address memory, so the work feeding the lookups (dependence
//! depth 1) is one kernel, `texaddr`, which emits the texel addresses; the memory system
//! gathers the texels (indexed loads, each texel written over its address in the SRF); the
//! depth-0 kernel, `fragment`, consumes them and computes the colour. A material whose
//! textures are all point-sampled or bilinear is 2 kernels and 1 gather; mipmapped textures
//! add [`filter8`] between the gather and `fragment` (8 texels and 5 weights in, 1 filtered
//! texel out per access, as §6.5.1's traffic implies).
//!
//! **Sampling** follows OpenGL 1.2 (`../shared/SCENE_FORMAT.md`): level 0 is `W × H`
//! (powers of two), `u = s·W`, `v = t·H`; `nearest` fetches texel `(⌊u⌋, ⌊v⌋)`; `linear`
//! fetches the 2 × 2 texels around `(u − ½, v − ½)` and weighs them by its fractions;
//! `trilinear` (`GL_LINEAR_MIPMAP_LINEAR`) finds the level of detail
//! `λ = log2 ρ`, `ρ = max(√(u_x² + v_x²), √(u_y² + v_y²))` from the screen-space
//! derivatives of the texture coordinates (which `irast` computes from the barycentric
//! interpolation), and blends the bilinear samples of levels `⌊d⌋` and `min(⌊d⌋ + 1, q)`,
//! `d = clamp(λ, 0, q)`, by `d − ⌊d⌋` (`λ ≤ 0` is magnification: level 0 alone). `log2`
//! is the exponent plus a quartic in the mantissa (error below 1.5·10⁻⁴, far below a level
//! fraction an 8-bit texel can show). Wrap `repeat` masks the texel index by the level's
//! side, `clamp` (to edge) clamps it.
//!
//! **Texture memory**: level `d` of a texture whose level 0 has `A_0` texels starts
//! `2·(A_0 − A_d)` words after level 0: each level at most halves, so the levels do not
//! overlap, the texture takes at most `2·A_0` words, and the kernel finds a level's start
//! from its size alone (shifts and a multiply, no table).
//!
//! **Environment**: the colour starts as the interpolated vertex colour with alpha 1; each
//! texture in order multiplies it (`modulate`, alpha too) or replaces it (`replace`). The
//! result is packed to RGBA8 with rounding, as `irast` packs an untextured colour.
//!
//! **Fragment records** (`varyings`, as `irast` writes them): r, g, b, s, t, then, when a
//! texture is mipmapped, ∂s/∂X, ∂s/∂Y, ∂t/∂X, ∂t/∂Y.

use imagine_units::arith::fp32::testgen::SplitMix64;
use imagine_units::desc::MachineDesc;

use super::{finish, records_to_stream, uniform, uniform_words};
use crate::kernel::{
    Kernel, KernelBuilder, KernelInputs, LoopSpec, MachineRequirementError, Ty, Value,
};
use crate::scene::mipmap;
use crate::scene::model::{Filter, Noise, TextureMode, Wrap};

/// Words `filter8` reads per mipmapped access: 8 texels, then the weights
/// `α_1, β_1, α_2, β_2, f` (the two levels' bilinear fractions and the level fraction).
pub const FILTER8_TEXELS: usize = 8;
pub const FILTER8_WEIGHTS: usize = 5;

/// `log2(1 + x)` on [0, 1) as `x·(a + x·(b + x·(c + x·d)))`, least squares with
/// `p(1) = 1` (maximum error 1.46·10⁻⁴).
const LOG2_POLY: [f32; 4] = [1.438_073_2, -0.674_766_7, 0.317_000_7, -0.080_307_3];

/// One texture unit as a fragment program samples it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Unit {
    pub filter: Filter,
    pub wrap: Wrap,
    pub width: u32,
    pub height: u32,
    /// Level 0's first word in the texture buffer.
    pub base: u32,
}

impl Unit {
    fn levels(&self) -> u32 {
        mipmap::level_count(self.width, self.height) as u32
    }
}

/// A textured material's fragment program, or (`marble`, with its noise) the marble
/// shader (built by [`super::turbulence::build_fragment`]), or (`bump_env`) VERONA's
/// shader over its maps (built by [`super::bump_env`]: a dependent read, 3 kernels and 2
/// gathers).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct FragmentProgram {
    pub units: Vec<Unit>,
    pub mode: TextureMode,
    pub marble: Option<Noise>,
    pub bump_env: Option<super::bump_env::Maps>,
}

impl FragmentProgram {
    /// The marble shader's program over `noise`.
    pub fn marble(noise: Noise) -> FragmentProgram {
        FragmentProgram {
            units: Vec::new(),
            mode: TextureMode::Modulate,
            marble: Some(noise),
            bump_env: None,
        }
    }

    /// The `bump_env` shader's program over `maps`.
    pub fn bump_env(maps: super::bump_env::Maps) -> FragmentProgram {
        FragmentProgram {
            units: Vec::new(),
            mode: TextureMode::Modulate,
            marble: None,
            bump_env: Some(maps),
        }
    }

    /// Texel words `texaddr` asks for per fragment outside mipmapped units (1 per
    /// point-sampled unit, 4 per bilinear one; `bump_env`'s depth-2 kernel: the 3 normal
    /// words).
    pub fn direct_fetches(&self) -> usize {
        let bump = self
            .bump_env
            .map_or(0, |_| super::bump_env::FRAGMENT_BUMP_WORDS);
        bump + self
            .units
            .iter()
            .map(|u| match u.filter {
                Filter::Nearest => 1,
                Filter::Linear => 4,
                Filter::Trilinear => 0,
            })
            .sum::<usize>()
    }

    /// Bilinear weights per fragment (2 per bilinear unit).
    pub fn direct_weights(&self) -> usize {
        2 * self
            .units
            .iter()
            .filter(|u| u.filter == Filter::Linear)
            .count()
    }

    /// Mipmapped units (each one `filter8` access per fragment).
    pub fn mipmapped(&self) -> usize {
        self.units
            .iter()
            .filter(|u| u.filter == Filter::Trilinear)
            .count()
    }

    /// Texel words fetched per fragment by an address computed from fetched texels (a
    /// dependent read: `bump_env`'s environment texel).
    pub fn dependent_fetches(&self) -> usize {
        usize::from(self.bump_env.is_some())
    }

    /// Texel words fetched per fragment, all units.
    pub fn texel_fetches(&self) -> usize {
        self.direct_fetches() + FILTER8_TEXELS * self.mipmapped() + self.dependent_fetches()
    }

    /// A name unique to the program (its kernels are registered as `texaddr:…` and
    /// `fragment:…`).
    pub fn name(&self) -> String {
        if let Some(noise) = self.marble {
            return super::turbulence::fragment_name(noise).into();
        }
        if let Some(maps) = &self.bump_env {
            return format!("bump_env_{}", maps.name());
        }
        let mut name = String::new();
        for u in &self.units {
            let f = match u.filter {
                Filter::Nearest => 'n',
                Filter::Linear => 'l',
                Filter::Trilinear => 't',
            };
            let w = match u.wrap {
                Wrap::Repeat => 'r',
                Wrap::Clamp => 'c',
            };
            name.push_str(&format!("{f}{w}{}x{}at{}_", u.width, u.height, u.base));
        }
        name.push_str(match self.mode {
            TextureMode::Modulate => "mod",
            TextureMode::Replace => "rep",
        });
        name
    }

    /// The depth-1 kernel: per fragment (`varyings`: r, g, b, s, t, any further words, and
    /// when mipmapped the derivatives at `derivatives_at`), the texel addresses of every unit — `addr` for point-sampled and
    /// bilinear units (with the bilinear fractions on `weights`), `addr8` for mipmapped
    /// ones (with `filter8`'s weights on `weights5`).
    pub fn texaddr(
        &self,
        fragment_words: usize,
        derivatives_at: usize,
    ) -> Result<Kernel, MachineRequirementError> {
        let mut b = KernelBuilder::new("texaddr");
        let input = b.input("varyings");
        let addr = (self.direct_fetches() > 0).then(|| b.output("addr"));
        let weights = (self.direct_weights() > 0).then(|| b.output("weights"));
        let addr8 = (self.mipmapped() > 0).then(|| b.output("addr8"));
        let weights5 = (self.mipmapped() > 0).then(|| b.output("weights5"));
        let half = b.f32(0.5);
        b.begin_loop(LoopSpec::OverStream(input));
        let v: Vec<Value> = (0..fragment_words).map(|_| b.read_f32(input)).collect();
        let (s, t) = (v[3], v[4]);
        for u in &self.units {
            match u.filter {
                Filter::Nearest => {
                    let a = nearest_address(&mut b, u, s, t);
                    b.write(addr.expect("an address stream"), a);
                }
                Filter::Linear => {
                    let level = Level::constant(&mut b, u, 0);
                    let (addrs, alpha, beta) = bilinear(&mut b, &level, s, t, half, u.wrap);
                    for a in addrs {
                        b.write(addr.expect("an address stream"), a);
                    }
                    let w = weights.expect("a weight stream");
                    b.write(w, alpha);
                    b.write(w, beta);
                }
                Filter::Trilinear => {
                    let (d1, d2, f) =
                        level_of_detail(&mut b, u, &v[derivatives_at..derivatives_at + 4]);
                    let mut fractions = Vec::new();
                    for d in [d1, d2] {
                        let level = Level::at(&mut b, u, d);
                        let (addrs, alpha, beta) = bilinear(&mut b, &level, s, t, half, u.wrap);
                        for a in addrs {
                            b.write(addr8.expect("a mipmap address stream"), a);
                        }
                        fractions.extend([alpha, beta]);
                    }
                    let w = weights5.expect("a mipmap weight stream");
                    for x in fractions.into_iter().chain([f]) {
                        b.write(w, x);
                    }
                }
            }
        }
        b.end_loop();
        Ok(finish(b))
    }

    /// The depth-0 kernel: the vertex colour (`varyings`), then each unit's texel —
    /// fetched (`texels`, with `weights` for bilinear units) or filtered by `filter8`
    /// (`filtered`) — applied in order; out: the packed RGBA8 `colour`.
    pub fn fragment(&self, fragment_words: usize) -> Result<Kernel, MachineRequirementError> {
        let mut b = KernelBuilder::new("fragment");
        let input = b.input("varyings");
        let texels = (self.direct_fetches() > 0).then(|| b.input("texels"));
        let weights = (self.direct_weights() > 0).then(|| b.input("weights"));
        let filtered = (self.mipmapped() > 0).then(|| b.input("filtered"));
        let colour_out = b.output("colour");
        let one = b.f32(1.0);
        b.begin_loop(LoopSpec::OverStream(input));
        let v: Vec<Value> = (0..fragment_words).map(|_| b.read_f32(input)).collect();
        let mut colour = [v[0], v[1], v[2], one];
        // With `replace` only the last unit counts; a point-sampled or mipmapped texel is
        // then the colour word itself (unpacking and packing an RGBA8 word gives it back).
        let last = self.units.len().checked_sub(1);
        let mut word = None;
        for (i, u) in self.units.iter().enumerate() {
            let texel = match u.filter {
                Filter::Nearest => Texel::Word(b.read(texels.expect("a texel stream"))),
                Filter::Trilinear => Texel::Word(b.read(filtered.expect("a filtered stream"))),
                Filter::Linear => {
                    let t: [Value; 4] =
                        std::array::from_fn(|_| b.read(texels.expect("a texel stream")));
                    let w = weights.expect("a weight stream");
                    Texel::Bilinear(t, b.read_f32(w), b.read_f32(w))
                }
            };
            let rgba = |b: &mut KernelBuilder, texel: Texel| match texel {
                Texel::Word(w) => unpack(b, w),
                Texel::Bilinear(t, alpha, beta) => {
                    let t: Vec<[Value; 4]> = t.iter().map(|&w| unpack(b, w)).collect();
                    bilerp(b, &t, alpha, beta)
                }
            };
            match self.mode {
                TextureMode::Modulate => {
                    let t = rgba(&mut b, texel);
                    colour = std::array::from_fn(|c| b.fmul(colour[c], t[c]));
                }
                TextureMode::Replace if Some(i) == last => match texel {
                    Texel::Word(w) => word = Some(w),
                    bilinear => colour = rgba(&mut b, bilinear),
                },
                TextureMode::Replace => {}
            }
        }
        if let Some(w) = word {
            b.write(colour_out, w);
            b.end_loop();
            return Ok(finish(b));
        }
        let packed = pack(&mut b, colour);
        b.write(colour_out, packed);
        b.end_loop();
        Ok(finish(b))
    }
}

/// A unit's texel as `fragment` reads it: one RGBA8 word (point-sampled, or filtered by
/// `filter8`), or the 2 × 2 words and fractions of a bilinear lookup.
enum Texel {
    Word(Value),
    Bilinear([Value; 4], Value, Value),
}

/// `filter8`: per mipmapped access, 8 texels (levels `d_1` then `d_2`, each 2 × 2 in the
/// order (i0, j0), (i1, j0), (i0, j1), (i1, j1)) and 5 weights in, the trilinear sample
/// out, packed RGBA8.
pub fn filter8(_desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("filter8");
    let texels = b.input("texels");
    let weights = b.input("weights");
    let out = b.output("filtered");
    b.begin_loop(LoopSpec::OverStream(weights));
    let t: Vec<[Value; 4]> = (0..FILTER8_TEXELS)
        .map(|_| {
            let w = b.read(texels);
            unpack(&mut b, w)
        })
        .collect();
    let w: Vec<Value> = (0..FILTER8_WEIGHTS).map(|_| b.read_f32(weights)).collect();
    let near = bilerp(&mut b, &t[..4], w[0], w[1]);
    let far = bilerp(&mut b, &t[4..], w[2], w[3]);
    let mixed = std::array::from_fn(|c| lerp(&mut b, near[c], far[c], w[4]));
    let packed = pack(&mut b, mixed);
    b.write(out, packed);
    b.end_loop();
    Ok(finish(b))
}

/// A mipmap level as the address arithmetic needs it.
struct Level {
    /// Its first word in the texture buffer.
    base: Value,
    /// Its side in texels (int32), as a float, and minus one (the repeat mask).
    width: Value,
    width_f: Value,
    width_mask: Value,
    height_f: Value,
    height_mask: Value,
}

impl Level {
    /// Level `d` (a constant) of `u`.
    fn constant(b: &mut KernelBuilder, u: &Unit, d: u32) -> Level {
        let (w, h) = ((u.width >> d).max(1), (u.height >> d).max(1));
        let base = u.base + 2 * (u.width * u.height - w * h);
        Level {
            base: b.i32(base as i32),
            width: b.i32(w as i32),
            width_f: b.f32(w as f32),
            width_mask: b.i32(w as i32 - 1),
            height_f: b.f32(h as f32),
            height_mask: b.i32(h as i32 - 1),
        }
    }

    /// Level `d` (a value) of `u`: sides `max(1, W >> d)`, `max(1, H >> d)`, first word
    /// `base + 2·(A_0 − A_d)`.
    fn at(b: &mut KernelBuilder, u: &Unit, d: Value) -> Level {
        let one = b.i32(1);
        let side = |b: &mut KernelBuilder, n: u32| {
            let n = b.i32(n as i32);
            let s = b.shr(n, d);
            b.imax(s, one)
        };
        let (w, h) = (side(b, u.width), side(b, u.height));
        let area = b.imul(w, h);
        let twice = b.iadd(area, area);
        let end = b.i32((u.base + 2 * u.width * u.height) as i32);
        Level {
            base: b.isub(end, twice),
            width: w,
            width_f: b.itof(w),
            width_mask: b.isub(w, one),
            height_f: b.itof(h),
            height_mask: b.isub(h, one),
        }
    }

    fn address(&self, b: &mut KernelBuilder, i: Value, j: Value) -> Value {
        let row = b.imul(j, self.width);
        let a = b.iadd(self.base, row);
        b.iadd(a, i)
    }
}

/// The level-0 texel of `u` holding `(s, t)` (point sampling, `u`'s wrap): its address.
pub(crate) fn nearest_address(b: &mut KernelBuilder, u: &Unit, s: Value, t: Value) -> Value {
    let level = Level::constant(b, u, 0);
    let i = texel_index(b, s, level.width_f, level.width_mask, u.wrap);
    let j = texel_index(b, t, level.height_f, level.height_mask, u.wrap);
    level.address(b, i, j)
}

/// `⌊x⌋` as an int32 (`ftoi` truncates; one less where that rounded up).
fn floor(b: &mut KernelBuilder, x: Value) -> Value {
    let i = b.ftoi_trunc(x);
    let back = b.itof(i);
    let above = b.flt(x, back);
    let one = b.i32(1);
    let less = b.isub(i, one);
    b.select(above, less, i)
}

/// The wrapped index of the texel holding `coordinate·size` on a side of `size` texels
/// (`mask = size − 1`).
fn texel_index(
    b: &mut KernelBuilder,
    coordinate: Value,
    size: Value,
    mask: Value,
    wrap: Wrap,
) -> Value {
    let x = b.fmul(coordinate, size);
    let i = floor(b, x);
    wrap_index(b, i, mask, wrap)
}

fn wrap_index(b: &mut KernelBuilder, i: Value, mask: Value, wrap: Wrap) -> Value {
    match wrap {
        // Sides are powers of two: the mask is the non-negative remainder.
        Wrap::Repeat => b.and(i, mask),
        Wrap::Clamp => {
            let zero = b.i32(0);
            let i = b.imax(i, zero);
            b.imin(i, mask)
        }
    }
}

/// The 2 × 2 texel addresses around `(s·W − ½, t·H − ½)` on `level`, and the fractions.
fn bilinear(
    b: &mut KernelBuilder,
    level: &Level,
    s: Value,
    t: Value,
    half: Value,
    wrap: Wrap,
) -> ([Value; 4], Value, Value) {
    let one = b.i32(1);
    let corner = |b: &mut KernelBuilder, c: Value, size: Value, mask: Value| {
        let x = b.fmul(c, size);
        let x = b.fsub(x, half);
        let i0 = floor(b, x);
        let fraction = {
            let f = b.itof(i0);
            b.fsub(x, f)
        };
        let i1 = b.iadd(i0, one);
        (
            wrap_index(b, i0, mask, wrap),
            wrap_index(b, i1, mask, wrap),
            fraction,
        )
    };
    let (i0, i1, alpha) = corner(b, s, level.width_f, level.width_mask);
    let (j0, j1, beta) = corner(b, t, level.height_f, level.height_mask);
    let addrs = [
        level.address(b, i0, j0),
        level.address(b, i1, j0),
        level.address(b, i0, j1),
        level.address(b, i1, j1),
    ];
    (addrs, alpha, beta)
}

/// Levels `d_1 = ⌊d⌋`, `d_2 = min(d_1 + 1, q)` and the fraction `d − d_1`, for
/// `d = clamp(λ, 0, q)` with `λ = ½·log2(max(u_x² + v_x², u_y² + v_y²))`; `derivatives` are
/// ∂s/∂X, ∂s/∂Y, ∂t/∂X, ∂t/∂Y.
fn level_of_detail(
    b: &mut KernelBuilder,
    u: &Unit,
    derivatives: &[Value],
) -> (Value, Value, Value) {
    let (w, h) = (b.f32(u.width as f32), b.f32(u.height as f32));
    let ux = b.fmul(derivatives[0], w);
    let uy = b.fmul(derivatives[1], w);
    let vx = b.fmul(derivatives[2], h);
    let vy = b.fmul(derivatives[3], h);
    let square = |b: &mut KernelBuilder, p: Value, q: Value| {
        let a = b.fmul(p, p);
        let c = b.fmul(q, q);
        b.fadd(a, c)
    };
    let rx = square(b, ux, vx);
    let ry = square(b, uy, vy);
    let r2 = b.fmax(rx, ry);
    // log2: the exponent, plus the polynomial in the mantissa's fraction.
    let bits = b.cast(r2, Ty::Word);
    let shift = b.i32(23);
    let exponent = b.shr(bits, shift);
    let exponent = b.cast(exponent, Ty::I32);
    let bias = b.i32(127);
    let exponent = b.isub(exponent, bias);
    let exponent = b.itof(exponent);
    let mantissa_bits = b.word(0x007F_FFFF);
    let one_bits = b.word(0x3F80_0000);
    let m = b.and(bits, mantissa_bits);
    let m = b.or(m, one_bits);
    let m = b.cast(m, Ty::F32);
    let one = b.f32(1.0);
    let x = b.fsub(m, one);
    let mut p = b.f32(LOG2_POLY[3]);
    for &c in LOG2_POLY[..3].iter().rev() {
        let c = b.f32(c);
        let px = b.fmul(p, x);
        p = b.fadd(px, c);
    }
    let p = b.fmul(p, x);
    let log2 = b.fadd(exponent, p);
    let half = b.f32(0.5);
    let lambda = b.fmul(log2, half);
    let last = u.levels() - 1;
    let (zero_f, q) = (b.f32(0.0), b.f32(last as f32));
    let d = b.fmin(lambda, q);
    let d = b.fmax(d, zero_f);
    let d1 = b.ftoi_trunc(d);
    let f = {
        let back = b.itof(d1);
        b.fsub(d, back)
    };
    let next = {
        let one_i = b.i32(1);
        let n = b.iadd(d1, one_i);
        let q_i = b.i32(last as i32);
        b.imin(n, q_i)
    };
    (d1, next, f)
}

/// An RGBA8 word as four channels in [0, 1].
pub(crate) fn unpack(b: &mut KernelBuilder, word: Value) -> [Value; 4] {
    let (mask, scale) = (b.i32(0xFF), b.f32(1.0 / 255.0));
    std::array::from_fn(|c| {
        let shift = b.i32(8 * c as i32);
        let byte = b.shr(word, shift);
        let byte = b.and(byte, mask);
        let f = b.itof(byte);
        b.fmul(f, scale)
    })
}

fn lerp(b: &mut KernelBuilder, a: Value, c: Value, t: Value) -> Value {
    let d = b.fsub(c, a);
    let d = b.fmul(d, t);
    b.fadd(a, d)
}

/// Texels (i0, j0), (i1, j0), (i0, j1), (i1, j1) weighed by fractions `alpha`, `beta`.
fn bilerp(b: &mut KernelBuilder, t: &[[Value; 4]], alpha: Value, beta: Value) -> [Value; 4] {
    std::array::from_fn(|c| {
        let bottom = lerp(b, t[0][c], t[1][c], alpha);
        let top = lerp(b, t[2][c], t[3][c], alpha);
        lerp(b, bottom, top, beta)
    })
}

/// Four channels, clamped to [0, 1], as an RGBA8 word rounded to nearest.
pub(crate) fn pack(b: &mut KernelBuilder, channels: [Value; 4]) -> Value {
    let (zero, one, half, scale) = (b.f32(0.0), b.f32(1.0), b.f32(0.5), b.f32(255.0));
    let mut word = b.word(0);
    for (c, &x) in channels.iter().enumerate() {
        let x = b.fmax(x, zero);
        let x = b.fmin(x, one);
        word = super::or_channel(b, word, x, c, (half, scale));
    }
    word
}

/// The library's example program: a 64 × 32 point-sampled texture (repeat), a 16 × 16
/// bilinear one (clamp) and a 256 × 128 mipmapped one (repeat), modulating the colour.
fn example() -> FragmentProgram {
    let unit = |filter, wrap, width, height, base| Unit {
        filter,
        wrap,
        width,
        height,
        base,
    };
    FragmentProgram {
        units: vec![
            unit(Filter::Nearest, Wrap::Repeat, 64, 32, 0),
            unit(Filter::Linear, Wrap::Clamp, 16, 16, 2048),
            unit(Filter::Trilinear, Wrap::Repeat, 256, 128, 4096),
        ],
        mode: TextureMode::Modulate,
        marble: None,
        bump_env: None,
    }
}

/// Words of the example's fragment records: r, g, b, s, t and the four derivatives.
const EXAMPLE_WORDS: usize = 9;

/// `texaddr` for [`example`].
pub fn texaddr_example(_desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    example().texaddr(EXAMPLE_WORDS, 5)
}

/// `fragment` for [`example`].
pub fn fragment_example(_desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    example().fragment(EXAMPLE_WORDS)
}

/// Fragment records: colour in [0, 1), texture coordinates in [−3, 3) (both wraps reached),
/// derivatives of magnitude 10⁻⁵ to 1 (every level of detail, magnification included).
fn varyings(rng: &mut SplitMix64, n: usize) -> Vec<Vec<u32>> {
    (0..n)
        .map(|_| {
            let mut r = uniform_words(rng, 3, 0.0, 1.0);
            r.extend(uniform_words(rng, 2, -3.0, 3.0));
            for _ in 0..4 {
                let magnitude = 10f32.powf(uniform(rng, -5.0, 0.0));
                let sign = if rng.next_u32() & 1 == 0 { 1.0 } else { -1.0 };
                r.push((sign * magnitude).to_bits());
            }
            r
        })
        .collect()
}

/// Random inputs for `texaddr` (see [`varyings`]).
pub fn texaddr_inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let c = desc.cluster.count;
    let mut rng = SplitMix64::new(seed);
    KernelInputs {
        streams: vec![
            records_to_stream(&varyings(&mut rng, rows * c), c),
            Vec::new(),
            Vec::new(),
            Vec::new(),
            Vec::new(),
        ],
        params: Vec::new(),
    }
}

/// Random texels and weights in [0, 1) for `filter8`.
pub fn filter8_inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let c = desc.cluster.count;
    let mut rng = SplitMix64::new(seed);
    let texels: Vec<Vec<u32>> = (0..rows * c)
        .map(|_| (0..FILTER8_TEXELS).map(|_| rng.next_u32()).collect())
        .collect();
    let weights: Vec<Vec<u32>> = (0..rows * c)
        .map(|_| uniform_words(&mut rng, FILTER8_WEIGHTS, 0.0, 1.0))
        .collect();
    KernelInputs {
        streams: vec![
            records_to_stream(&texels, c),
            records_to_stream(&weights, c),
            Vec::new(),
        ],
        params: Vec::new(),
    }
}

/// Random fragments, texels, bilinear weights and filtered texels for `fragment`.
pub fn fragment_inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let c = desc.cluster.count;
    let n = rows * c;
    let mut rng = SplitMix64::new(seed);
    let p = example();
    let fragments = varyings(&mut rng, n);
    let texels: Vec<Vec<u32>> = (0..n)
        .map(|_| (0..p.direct_fetches()).map(|_| rng.next_u32()).collect())
        .collect();
    let weights: Vec<Vec<u32>> = (0..n)
        .map(|_| uniform_words(&mut rng, p.direct_weights(), 0.0, 1.0))
        .collect();
    let filtered: Vec<Vec<u32>> = (0..n)
        .map(|_| (0..p.mipmapped()).map(|_| rng.next_u32()).collect())
        .collect();
    KernelInputs {
        streams: vec![
            records_to_stream(&fragments, c),
            records_to_stream(&texels, c),
            records_to_stream(&weights, c),
            records_to_stream(&filtered, c),
            Vec::new(),
        ],
        params: Vec::new(),
    }
}
