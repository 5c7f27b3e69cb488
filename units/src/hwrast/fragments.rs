//! What the rasterizer computes (no timing): a triangle's records in, its fragments out.
//!
//! The arithmetic is the OpenGL pipeline's barycentric rasterizer, op for op, through the
//! machine's op functions ([`Op::eval`], the ones the interpreter and the clusters'
//! functional units execute), so that a frame rasterized here is bit for bit the frame the
//! kernels rasterize (`pipelines/src/opengl/kernels.rs`):
//!
//! * **setup** (`baryprep`): `q_k = z_k · (1 / |det|)` (`z_k` is `z_k − ζ·w_k` when the
//!   frame has reference depths), the primitive number
//!   `prim_base + index + 1`, and, for mipmapped frames, the derivative sums `ΣA`, `ΣB`,
//!   `Σs·A`, `Σs·B`, `Σt·A`, `Σt·B`;
//! * **box** (`xyprep`): the triangle's bounding box clamped to the scissor tile; a
//!   triangle not kept (culled, rejected) or whose box misses the tile has none;
//! * **coverage** (`xyrast`): at pixel centre `(x + ½, y + ½)` each edge's
//!   `E = (A·X + B·Y) + C`; covered when every `E > 0`, or `E ≥ 0` on a top-left edge
//!   (`E > −2⁻¹⁴⁹` without flushing, two compares with it);
//! * **interpolation** (`irast`): `λ_k = E_k · (1 / ΣE)`, depth `(ζ + Σ E_k·q_k)·½ + ½`
//!   (without ζ, `(Σ E_k·q_k)·½ + ½`), the
//!   clamped colour (packed RGBA8) or, with a fragment program, the colour channels, the
//!   extras and the texture-coordinate derivatives.
//!
//! Fragments come out triangle by triangle in input order, each box row by row from the
//! bottom, pixels left to right: primitive order, as a blending frame needs.

use crate::arith::fp32::{FpMode, RECIPROCAL_GUESS};
use crate::ops::Op;

/// Words of a triangle's window record (`viewport_cull`): nine edge coefficients (A, B, C
/// per edge), the box (x0, y0, x1, y1) and the flags (bit 0 kept, bits 29..31 top-left).
pub const WINDOW_WORDS: usize = 14;
/// Words of a triangle's attribute record (`assemble_clip`) before the extras, without a
/// reference depth: z per corner, then r, g, b per corner. With one, the triangle's
/// reference depth ζ comes first and the corners' words are `z − ζ·w`.
pub const ATTRIB_WORDS: usize = 12;
/// Bit of the flags word where the three top-left flags start.
const TOP_LEFT_BIT: u32 = 29;
/// A null fragment's depth: NaN fails every depth test.
pub const NULL_DEPTH: u32 = 0x7FC0_0000;
const ONE: u32 = 0x3F80_0000;
const HALF: u32 = 0x3F00_0000;
const TWO: u32 = 0x4000_0000;
const ZERO: u32 = 0;
const SCALE_255: u32 = 0x437F_0000;
/// −2⁻¹⁴⁹, the negative subnormal next to −0: `E > −2⁻¹⁴⁹` is `E ≥ 0`.
const BELOW_ZERO: u32 = 0x8000_0001;
const ALPHA: u32 = 0xFF00_0000;

/// How the unit is set for one call: its state registers, which the host sends with the
/// stream instruction (as it sends a kernel's parameters).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct RasterState {
    /// The framebuffer's width: a fragment's address is `y·width + x`.
    pub width: u32,
    /// The address of null fragments (one past the window).
    pub trash: u32,
    /// The scissor tile, inclusive: x0, y0, x1, y1.
    pub tile: [i32; 4],
    /// Primitive numbers are `prim_base + index + 1` (index in this call's triangles).
    pub prim_base: u32,
    /// Values per vertex beyond the colour, interpolated for the fragment program.
    pub extras: usize,
    /// Whether the texture-coordinate derivatives are written (mipmapped frames).
    pub derivatives: bool,
    /// Whether fragments go to a fragment program (the interpolated values) or straight
    /// to the composite (the packed colour).
    pub fragment_program: bool,
    /// Whether each attribute record starts with its triangle's reference depth ζ, which
    /// the depth is interpolated from (`z_ndc = ζ + Σ E_k·q_k`; the scene's
    /// `pipeline.reference_depth`).
    pub reference_depth: bool,
    /// Newton–Raphson steps for `1/ΣE` from the bit-level guess, or 0 for a divide (the
    /// scene's `pipeline.newton_raphson`, as `irast` takes it).
    pub newton_steps: u8,
}

impl RasterState {
    /// Words of a triangle's attribute record.
    pub fn attrib_words(&self) -> usize {
        usize::from(self.reference_depth) + ATTRIB_WORDS + 3 * self.extras
    }

    /// Words of a fragment's last field: the packed colour, or r, g, b, the extras and the
    /// derivatives.
    pub fn value_words(&self) -> usize {
        if self.fragment_program {
            3 + self.extras + 4 * usize::from(self.derivatives)
        } else {
            1
        }
    }

    /// Words of a whole fragment: address, depth, primitive, then its values.
    pub fn fragment_words(&self) -> usize {
        3 + self.value_words()
    }

    /// A null fragment: the trash address, a depth that fails every test, primitive 0,
    /// values 0.
    pub fn null_fragment(&self, out: &mut Vec<u32>) {
        out.extend([self.trash, NULL_DEPTH, 0]);
        out.extend(std::iter::repeat_n(0, self.value_words()));
    }
}

/// A triangle after setup: what the scan and the interpolation need.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Setup {
    /// The box clamped to the tile (x0, y0, x1, y1), `None` when nothing is scanned.
    pub bounds: Option<[i32; 4]>,
    /// A, B, C of each edge.
    edges: [[u32; 3]; 3],
    /// Whether each edge is top-left.
    top_left: [bool; 3],
    /// The reference depth ζ, when the frame has one.
    zeta: Option<u32>,
    /// `z_k / |det|` (or `(z_k − ζ·w_k) / |det|`) of each corner.
    q: [u32; 3],
    /// r, g, b of each corner (corner-major).
    colours: [u32; 9],
    /// The extras of each corner (corner-major).
    extras: Vec<u32>,
    /// ΣA, ΣB, Σs·A, Σs·B, Σt·A, Σt·B (mipmapped frames).
    sums: [u32; 6],
    prim: u32,
}

impl Setup {
    /// Candidate pixels of the box.
    pub fn candidates(&self) -> u64 {
        self.bounds.map_or(0, |[x0, y0, x1, y1]| {
            (x1 - x0 + 1) as u64 * (y1 - y0 + 1) as u64
        })
    }
}

/// The machine's op `op` on `a`, `b`: the same function the clusters execute.
#[inline]
fn op(o: Op, a: u32, b: u32, mode: FpMode) -> u32 {
    o.eval(a, b, 0, mode).0
}

/// `(w0·v0 + w1·v1) + w2·v2`, rounded in that order (the kernels' `weighted`).
fn weighted(w: [u32; 3], v: [u32; 3], mode: FpMode) -> u32 {
    let a = op(Op::FMul, w[0], v[0], mode);
    let c = op(Op::FMul, w[1], v[1], mode);
    let s = op(Op::FAdd, a, c, mode);
    let d = op(Op::FMul, w[2], v[2], mode);
    op(Op::FAdd, s, d, mode)
}

/// `(t0 + t1) + t2`.
fn sum3(t: [u32; 3], mode: FpMode) -> u32 {
    let s = op(Op::FAdd, t[0], t[1], mode);
    op(Op::FAdd, s, t[2], mode)
}

/// `1/x` as `irast` takes it: a divide, or `steps` Newton–Raphson steps `y·(2 − x·y)` from
/// the guess [`RECIPROCAL_GUESS`]` − bits(x)` (integer subtract).
fn reciprocal_of(x: u32, steps: u8, mode: FpMode) -> u32 {
    if steps == 0 {
        return op(Op::FDiv, ONE, x, mode);
    }
    let mut y = op(Op::ISub, RECIPROCAL_GUESS, x, mode);
    for _ in 0..steps {
        let xy = op(Op::FMul, x, y, mode);
        let t = op(Op::FSub, TWO, xy, mode);
        y = op(Op::FMul, y, t, mode);
    }
    y
}

/// Sets up triangle `index` of the call from its window record, `|det|` and attribute
/// record.
pub fn setup(
    state: &RasterState,
    index: u32,
    window: &[u32],
    det: u32,
    attribs: &[u32],
    mode: FpMode,
) -> Setup {
    debug_assert_eq!(window.len(), WINDOW_WORDS);
    debug_assert_eq!(attribs.len(), state.attrib_words());
    let edges: [[u32; 3]; 3] = std::array::from_fn(|e| std::array::from_fn(|k| window[3 * e + k]));
    let flags = window[13];
    // The box clamped to the tile (signed compares, as `xyprep`'s imax/imin).
    let b: [i32; 4] = std::array::from_fn(|slot| {
        let v = window[9 + slot] as i32;
        if slot < 2 {
            v.max(state.tile[slot])
        } else {
            v.min(state.tile[slot])
        }
    });
    let kept = flags & 1 == 1 && b[0] <= b[2] && b[1] <= b[3];
    let inv_det = op(Op::FDiv, ONE, det, mode);
    let (zeta, attribs) = if state.reference_depth {
        (Some(attribs[0]), &attribs[1..])
    } else {
        (None, attribs)
    };
    let q = std::array::from_fn(|k| op(Op::FMul, attribs[k], inv_det, mode));
    let colours = std::array::from_fn(|k| attribs[3 + k]);
    let extras = attribs[ATTRIB_WORDS..].to_vec();
    let prim = state.prim_base.wrapping_add(index).wrapping_add(1);
    let mut sums = [0; 6];
    if state.derivatives {
        let n = state.extras;
        for coefficient in 0..2 {
            sums[coefficient] = sum3(std::array::from_fn(|k| edges[k][coefficient]), mode);
        }
        for channel in 0..2 {
            for coefficient in 0..2 {
                let terms = std::array::from_fn(|k| {
                    op(
                        Op::FMul,
                        extras[n * k + channel],
                        edges[k][coefficient],
                        mode,
                    )
                });
                sums[2 + 2 * channel + coefficient] = sum3(terms, mode);
            }
        }
    }
    Setup {
        bounds: kept.then_some(b),
        edges,
        top_left: std::array::from_fn(|i| (flags >> (TOP_LEFT_BIT + i as u32)) & 1 == 1),
        zeta,
        q,
        colours,
        extras,
        sums,
        prim,
    }
}

/// Appends the fragments of `s` (each [`RasterState::fragment_words`] words: address,
/// depth, primitive, values) to `out`; returns how many.
pub fn rasterize(s: &Setup, state: &RasterState, mode: FpMode, out: &mut Vec<u32>) -> usize {
    let Some([x0, y0, x1, y1]) = s.bounds else {
        return 0;
    };
    let mut n = 0;
    for y in y0..=y1 {
        // Pixel centres are exact: coordinates below 2^16 plus ½ need 17 bits of the
        // 24-bit significand, so `itof(x) + ½` is `xyrast`'s `itof(x0) + ½ + j`.
        let fy = op(Op::FAdd, op(Op::I32ToF, y as u32, 0, mode), HALF, mode);
        for x in x0..=x1 {
            let fx = op(Op::FAdd, op(Op::I32ToF, x as u32, 0, mode), HALF, mode);
            let e: [u32; 3] = std::array::from_fn(|i| {
                let ax = op(Op::FMul, s.edges[i][0], fx, mode);
                let by = op(Op::FMul, s.edges[i][1], fy, mode);
                let sum = op(Op::FAdd, ax, by, mode);
                op(Op::FAdd, sum, s.edges[i][2], mode)
            });
            let covered = (0..3).all(|i| {
                if mode.flush_to_zero {
                    let o = if s.top_left[i] { Op::FLe } else { Op::FLt };
                    op(o, ZERO, e[i], mode) == 1
                } else {
                    let t = if s.top_left[i] { BELOW_ZERO } else { ZERO };
                    op(Op::FLt, t, e[i], mode) == 1
                }
            });
            if covered {
                let addr = (y as u32).wrapping_mul(state.width).wrapping_add(x as u32);
                interpolate(s, state, e, addr, mode, out);
                n += 1;
            }
        }
    }
    n
}

/// One fragment's record from its edge values (`irast`).
fn interpolate(
    s: &Setup,
    state: &RasterState,
    e: [u32; 3],
    addr: u32,
    mode: FpMode,
    out: &mut Vec<u32>,
) {
    let sum = sum3(e, mode);
    let inv = reciprocal_of(sum, state.newton_steps, mode);
    let lambda = e.map(|x| op(Op::FMul, x, inv, mode));
    let from_zeta = weighted(e, s.q, mode);
    let z_ndc = match s.zeta {
        Some(zeta) => op(Op::FAdd, zeta, from_zeta, mode),
        None => from_zeta,
    };
    let z = op(Op::FAdd, op(Op::FMul, z_ndc, HALF, mode), HALF, mode);
    out.extend([addr, z, s.prim]);
    let channel = |ch: usize| {
        let c = weighted(lambda, std::array::from_fn(|k| s.colours[3 * k + ch]), mode);
        op(Op::FMin, op(Op::FMax, c, ZERO, mode), ONE, mode)
    };
    if !state.fragment_program {
        let mut colour = ALPHA;
        for ch in 0..3 {
            let c = op(Op::FMul, channel(ch), SCALE_255, mode);
            let c = op(Op::FAdd, c, HALF, mode);
            let byte = op(Op::FToI32Trunc, c, 0, mode);
            let byte = op(Op::Shl, byte, 8 * ch as u32, mode);
            colour = op(Op::Or, colour, byte, mode);
        }
        out.push(colour);
        return;
    }
    out.extend((0..3).map(channel));
    let n = state.extras;
    let extras: Vec<u32> = (0..n)
        .map(|ch| weighted(lambda, std::array::from_fn(|k| s.extras[n * k + ch]), mode))
        .collect();
    out.extend(&extras);
    if state.derivatives {
        // ∂s/∂X = (Σs·A − s·ΣA)/ΣE, and so on.
        for (ch, &value) in extras[..2].iter().enumerate() {
            for k in 0..2 {
                let p = op(Op::FMul, value, s.sums[k], mode);
                let d = op(Op::FSub, s.sums[2 + 2 * ch + k], p, mode);
                out.push(op(Op::FMul, d, inv, mode));
            }
        }
    }
}
