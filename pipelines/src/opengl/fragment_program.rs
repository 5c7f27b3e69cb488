//! The fragment program of a textured material, split at its texture lookups as the thesis
//! splits RTSL fragment programs (Owens 2002, §4.2 and §4.4.4): kernels never address
//! memory, so the work feeding the lookups (dependence depth 1) is one kernel, `texaddr`,
//! which emits the texel addresses; the memory system gathers the texels (indexed loads,
//! each texel written over its address in the SRF); the depth-0 kernel, `fragment`,
//! consumes them and computes the colour. A material whose textures are all point-sampled
//! or bilinear is 2 kernels and 1 gather; mipmapped textures add the `filter8` kernel
//! between the gather and `fragment` (8 texels and 5 weights in, 1 filtered texel out per
//! access, as §6.5.1's traffic implies).
//!
//! **Sampling** follows OpenGL 1.2 (`../shared/SCENE_FORMAT.md`): level 0 is `W × H`
//! (powers of two), `u = s·W`, `v = t·H`; `nearest` fetches texel `(⌊u⌋, ⌊v⌋)`; `linear`
//! fetches the 2 × 2 texels around `(u − ½, v − ½)` and weighs them by its fractions;
//! `trilinear` (`GL_LINEAR_MIPMAP_LINEAR`) finds the level of detail
//! `λ = log2 ρ`, `ρ = max(√(u_x² + v_x²), √(u_y² + v_y²))` from the screen-space
//! derivatives `irast` computes, and blends the bilinear samples of levels `⌊d⌋` and
//! `min(⌊d⌋ + 1, q)`, `d = clamp(λ, 0, q)`, by `d − ⌊d⌋` (`λ ≤ 0` is magnification:
//! level 0 alone). `log2` is the exponent plus a quartic in the mantissa (error below
//! 1.5·10⁻⁴, far below a level fraction an 8-bit texel can show). Wrap `repeat` masks the
//! texel index by the level's side, `clamp` (to edge) clamps it.
//!
//! **Texture memory**: every scene texture's pyramid ([`crate::scene::mipmap`]) lies in one
//! DRAM buffer, written by the host before the frame. Level `d` of a texture whose level 0
//! has `A_0` texels starts `2·(A_0 − A_d)` words after it: each level at most halves, so
//! the levels do not overlap, the texture takes at most `2·A_0` words, and the kernel
//! finds a level's start from its size alone (shifts and a multiply, no table).
//!
//! **Marble** (`shader = "marble"`, MARBLE's procedural shader, Owens 2002 §5.1.1) is a
//! depth-0 program without lookups: one kernel, `marble`
//! ([`crate::kernels::turbulence::build_fragment`]), the project's `turbulence` shader
//! reading `irast`'s varyings (the object-space shading position and normal) and writing
//! the packed colour. Its permutation table is Perlin's
//! ([`crate::kernels::turbulence::PERLIN_PERMUTATION`]), written by the host into DRAM
//! when the scene loads (each word once per cluster, the layout the kernel reads) and
//! loaded from there into the SRF once per frame. Its parameters ([`marble_params`]) are
//! the material's `frequency` and `turbulence_scale`, lighting in object space from the
//! scene's first light and the camera, treated as the shader's directional light and
//! viewer at infinity: with `o` the object's origin in the world, `l` the light's
//! position, `e` the eye (the view's inverse applied to the origin) and `A` the model
//! matrix's upper 3 × 3, the light direction is `L = normalize(A⁻¹·(l − o))`, the
//! direction to the viewer `V = normalize(A⁻¹·(e − o))`, the half vector
//! `H = normalize(L + V)` (`n·(A⁻¹·d)` is `(A⁻ᵀ·n)·d`: the cosines are the world's, up to
//! the normalisations, exact for rotations and uniform scales). Without a light
//! `L = H = 0`. The ambient and specular intensities are the means of the material's
//! `ambient` and `specular` colours; the diffuse weight is 1 and the exponent 16 (the
//! material's `diffuse` and `shininess` and the lights' colours are not used). All of
//! these are computed in f64 on the host and rounded to f32.
//!
//! **Environment**: the colour starts as the interpolated vertex colour with alpha 1; each
//! texture in order multiplies it (`modulate`, alpha too) or replaces it (`replace`). The
//! result is packed to RGBA8 with rounding, as `irast` packs an untextured colour.

use imagine_units::desc::MachineDesc;

use super::kernels::{Varyings, finish};
use crate::kernel::{Kernel, KernelBuilder, LoopSpec, MachineRequirementError, Ty, Value};
use crate::scene::mipmap;
use crate::scene::model::{Filter, Marble, Object, Scene, Texture, TextureMode, Wrap};

/// Words `filter8` reads per mipmapped access: 8 texels, then the weights
/// `α_1, β_1, α_2, β_2, f` (the two levels' bilinear fractions and the level fraction).
pub const FILTER8_TEXELS: usize = 8;
pub const FILTER8_WEIGHTS: usize = 5;

/// `log2(1 + x)` on [0, 1) as `x·(a + x·(b + x·(c + x·d)))`, least squares with
/// `p(1) = 1` (maximum error 1.46·10⁻⁴).
const LOG2_POLY: [f32; 4] = [1.438_073_2, -0.674_766_7, 0.317_000_7, -0.080_307_3];

/// Where a scene's textures lie in the texture buffer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TextureMemory {
    /// Per scene texture: its level 0's first word.
    pub base: Vec<u32>,
    /// The buffer's words (every level of every texture, at their offsets).
    pub words: Vec<u32>,
}

impl TextureMemory {
    /// Lays out `scene`'s textures (their pyramids built here, at load time).
    pub fn new(scene: &Scene) -> TextureMemory {
        let mut base = Vec::new();
        let mut words: Vec<u32> = Vec::new();
        for t in &scene.textures {
            let start = words.len();
            base.push(start as u32);
            let a0 = (t.width * t.height) as usize;
            let levels = if t.filter == Filter::Trilinear {
                mipmap::pyramid(t)
            } else {
                vec![mipmap::Level {
                    width: t.width,
                    height: t.height,
                    texels: t.texels.clone(),
                }]
            };
            words.resize(start + if levels.len() > 1 { 2 * a0 } else { a0 }, 0);
            for l in &levels {
                let at = start + 2 * (a0 - l.texels.len());
                words[at..at + l.texels.len()].copy_from_slice(&l.texels);
            }
        }
        TextureMemory { base, words }
    }
}

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

/// A textured material's fragment program, or (`marble`) the marble shader.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct FragmentProgram {
    pub units: Vec<Unit>,
    pub mode: TextureMode,
    pub marble: bool,
}

impl FragmentProgram {
    /// The program of a material with textures `textures` (indices into the scene's).
    pub fn new(
        scene: &Scene,
        textures: &[usize],
        mode: TextureMode,
        memory: &TextureMemory,
    ) -> FragmentProgram {
        let units = textures
            .iter()
            .map(|&i| {
                let t: &Texture = &scene.textures[i];
                Unit {
                    filter: t.filter,
                    wrap: t.wrap,
                    width: t.width,
                    height: t.height,
                    base: memory.base[i],
                }
            })
            .collect();
        FragmentProgram {
            units,
            mode,
            marble: false,
        }
    }

    /// The marble shader's program.
    pub fn marble() -> FragmentProgram {
        FragmentProgram {
            units: Vec::new(),
            mode: TextureMode::Modulate,
            marble: true,
        }
    }

    /// Texel words `texaddr` asks for per fragment outside mipmapped units (1 per
    /// point-sampled unit, 4 per bilinear one).
    pub fn direct_fetches(&self) -> usize {
        self.units
            .iter()
            .map(|u| match u.filter {
                Filter::Nearest => 1,
                Filter::Linear => 4,
                Filter::Trilinear => 0,
            })
            .sum()
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

    /// Texel words fetched per fragment, all units.
    pub fn texel_fetches(&self) -> usize {
        self.direct_fetches() + FILTER8_TEXELS * self.mipmapped()
    }

    /// A name unique to the program (its kernels are `texaddr_…` and `fragment_…`).
    pub fn name(&self) -> String {
        if self.marble {
            return "marble".into();
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

    /// The depth-1 kernel: per fragment (`varyings`: r, g, b, s, t, any further extras
    /// and, when mipmapped, the derivatives), the texel addresses of every unit — `addr` for point-sampled and
    /// bilinear units (with the bilinear fractions on `weights`), `addr8` for mipmapped
    /// ones (with `filter8`'s weights on `weights5`).
    pub fn texaddr(&self, varyings: Varyings) -> Result<Kernel, MachineRequirementError> {
        let mut b = KernelBuilder::new("texaddr");
        let input = b.input("varyings");
        let addr = (self.direct_fetches() > 0).then(|| b.output("addr"));
        let weights = (self.direct_weights() > 0).then(|| b.output("weights"));
        let addr8 = (self.mipmapped() > 0).then(|| b.output("addr8"));
        let weights5 = (self.mipmapped() > 0).then(|| b.output("weights5"));
        let half = b.f32(0.5);
        b.begin_loop(LoopSpec::OverStream(input));
        let v: Vec<Value> = (0..varyings.fragment_words())
            .map(|_| b.read_f32(input))
            .collect();
        let (s, t) = (v[3], v[4]);
        for u in &self.units {
            match u.filter {
                Filter::Nearest => {
                    let level = Level::constant(&mut b, u, 0);
                    let i = texel_index(&mut b, s, level.width_f, level.width_mask, u.wrap);
                    let j = texel_index(&mut b, t, level.height_f, level.height_mask, u.wrap);
                    let a = level.address(&mut b, i, j);
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
                    let at = varyings.derivatives_at();
                    let (d1, d2, f) = level_of_detail(&mut b, u, &v[at..at + 4]);
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
    pub fn fragment(&self, varyings: Varyings) -> Result<Kernel, MachineRequirementError> {
        let mut b = KernelBuilder::new("fragment");
        let input = b.input("varyings");
        let texels = (self.direct_fetches() > 0).then(|| b.input("texels"));
        let weights = (self.direct_weights() > 0).then(|| b.input("weights"));
        let filtered = (self.mipmapped() > 0).then(|| b.input("filtered"));
        let colour_out = b.output("colour");
        let one = b.f32(1.0);
        b.begin_loop(LoopSpec::OverStream(input));
        let v: Vec<Value> = (0..varyings.fragment_words())
            .map(|_| b.read_f32(input))
            .collect();
        let mut colour = [v[0], v[1], v[2], one];
        for u in &self.units {
            let texel = match u.filter {
                Filter::Nearest => {
                    let w = b.read(texels.expect("a texel stream"));
                    unpack(&mut b, w)
                }
                Filter::Linear => {
                    let t: Vec<[Value; 4]> = (0..4)
                        .map(|_| {
                            let w = b.read(texels.expect("a texel stream"));
                            unpack(&mut b, w)
                        })
                        .collect();
                    let w = weights.expect("a weight stream");
                    let (alpha, beta) = (b.read_f32(w), b.read_f32(w));
                    bilerp(&mut b, &t, alpha, beta)
                }
                Filter::Trilinear => {
                    let w = b.read(filtered.expect("a filtered stream"));
                    unpack(&mut b, w)
                }
            };
            colour = match self.mode {
                TextureMode::Modulate => std::array::from_fn(|c| b.fmul(colour[c], texel[c])),
                TextureMode::Replace => texel,
            };
        }
        let packed = pack(&mut b, colour);
        b.write(colour_out, packed);
        b.end_loop();
        Ok(finish(b))
    }
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
fn unpack(b: &mut KernelBuilder, word: Value) -> [Value; 4] {
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
fn pack(b: &mut KernelBuilder, channels: [Value; 4]) -> Value {
    let (zero, one, half, scale) = (b.f32(0.0), b.f32(1.0), b.f32(0.5), b.f32(255.0));
    let mut word = b.word(0);
    for (c, &x) in channels.iter().enumerate() {
        let x = b.fmax(x, zero);
        let x = b.fmin(x, one);
        let x = b.fmul(x, scale);
        let x = b.fadd(x, half);
        let byte = b.ftoi_trunc(x);
        let shift = b.i32(8 * c as i32);
        let byte = b.shl(byte, shift);
        word = b.or(word, byte);
    }
    word
}

/// The marble shader's parameters for `object` of `scene` (see the module notes), in the
/// kernel's order: frequency, turbulence scale, L, H, ambient, specular.
pub fn marble_params(scene: &Scene, object: &Object, marble: &Marble) -> Vec<u32> {
    let m = &scene.materials[object.material];
    let model = object.model.map(f64::from);
    let view = scene.camera_for(object).view.map(f64::from);
    let upper = |m: &[f64; 16]| -> [[f64; 3]; 3] {
        std::array::from_fn(|i| std::array::from_fn(|j| m[4 * i + j]))
    };
    let column = |m: &[f64; 16]| [m[3], m[7], m[11]];
    let origin = column(&model);
    // The eye: V⁻¹·(0, 0, 0, 1) = −A_V⁻¹·t_V.
    let eye = apply(&inverse3(&upper(&view)), column(&view)).map(|c| -c);
    let to_object = inverse3(&upper(&model));
    let direction = |to: [f64; 3]| {
        let d = apply(&to_object, std::array::from_fn(|k| to[k] - origin[k]));
        normalized(d)
    };
    let (light, half) = match scene.lights.first() {
        Some(l) => {
            let light = direction(l.position.map(f64::from));
            let viewer = direction(eye);
            (
                light,
                normalized(std::array::from_fn(|k| light[k] + viewer[k])),
            )
        }
        None => ([0.0; 3], [0.0; 3]),
    };
    let mean = |c: [f32; 3]| c.iter().map(|&x| f64::from(x)).sum::<f64>() / 3.0;
    [
        f64::from(marble.frequency),
        f64::from(marble.turbulence_scale),
    ]
    .into_iter()
    .chain(light)
    .chain(half)
    .chain([mean(m.ambient), mean(m.specular)])
    .map(|x| (x as f32).to_bits())
    .collect()
}

/// The inverse of a 3 × 3 matrix (its adjugate over its determinant).
fn inverse3(a: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let cof = |i: usize, j: usize| {
        let (r0, r1) = ((i + 1) % 3, (i + 2) % 3);
        let (c0, c1) = ((j + 1) % 3, (j + 2) % 3);
        a[r0][c0] * a[r1][c1] - a[r0][c1] * a[r1][c0]
    };
    let det = a[0][0] * cof(0, 0) + a[0][1] * cof(0, 1) + a[0][2] * cof(0, 2);
    // The inverse is the transposed cofactor matrix over the determinant.
    std::array::from_fn(|i| std::array::from_fn(|j| cof(j, i) / det))
}

fn apply(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
}

/// `v / |v|`, or zero for a zero vector.
fn normalized(v: [f64; 3]) -> [f64; 3] {
    let length = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if length > 0.0 {
        v.map(|c| c / length)
    } else {
        [0.0; 3]
    }
}
