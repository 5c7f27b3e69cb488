//! The rasterizing arithmetic of the S3 accelerators, as pure functions on fixed-point
//! values: the triangle setup, the span generator's endpoints, the pixel interpolator, the
//! depth test and the blend. The clocked blocks ([`super::accel`], [`super::fetch`]) call
//! these; [`reference_frame`] draws a trace in order with the same functions, the golden
//! model the clocked machine must match bit for bit.
//!
//! Number formats (ours: the paper gives none):
//! * positions: two's-complement with 4 fraction bits (1/16 pixel), 26 bits wide for the
//!   ±10⁶-pixel coordinates a `.tri` file may hold; pixel centres at (x + ½, y + ½);
//! * depth: 24-bit unsigned (`round(z · (2²⁴ − 1))`), colour channels 8-bit
//!   (`round(c · 255)`);
//! * the depth buffer word: depth in bits 47..24 and the primitive's 24-bit **order tag**
//!   in bits 23..0. The depth test is "new word < stored word": LESS on depth, and on equal
//!   depths the earlier primitive wins — exactly what in-order LESS gives, whatever order
//!   the primitives ran in (the spec's tie pitfall, §1.5). The clear word is depth 2²⁴ − 1
//!   with tag 0, so nothing at the far plane passes, as with LESS against 1.0.
//!
//! Coverage: a pixel is inside when every edge function at its centre is positive, or zero
//! on a top or left edge (the usual tie rule, so shared edges are drawn once). Attributes
//! are the barycentric blend `Σ wᵢ·aᵢ / Σ wᵢ` of the edge functions, floored: exact integer
//! arithmetic (a hardware interpolator holds 56-bit edge values and an 82-bit numerator).

/// Fraction bits of a fixed-point position.
pub const SUBPIXEL_BITS: u32 = 4;
const ONE: i64 = 1 << SUBPIXEL_BITS;
const HALF: i64 = ONE / 2;

/// Largest depth value (the clear depth).
pub const DEPTH_MAX: u32 = (1 << 24) - 1;
/// The depth buffer's clear word: far depth, order tag 0.
pub const CLEAR_DEPTH_WORD: u64 = (DEPTH_MAX as u64) << 24;
/// The colour buffer's clear value: black, opaque (RGBA8, red in the low byte).
pub const CLEAR_COLOUR: u32 = 0xFF00_0000;

/// A primitive's drawing mode (the paper's mode state).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Z-buffered, not blended: depth test, depth write, colour write. These are the
    /// *independent* primitives of dependence-chain breaking.
    Opaque,
    /// Z-tested, blended 50/50 with the destination, no depth write: reads the destination
    /// (its one source region), so order against overlapping primitives matters.
    Blended,
}

/// A window-space triangle of a trace, as the host hands it over.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceTriangle {
    /// x, y in window pixels (origin bottom-left), z in [0, 1].
    pub positions: [[f32; 3]; 3],
    /// r, g, b in [0, 1].
    pub colours: [[f32; 3]; 3],
    pub mode: Mode,
}

/// A triangle in the accelerators' fixed-point formats (what fetch decodes a command into).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FixedTriangle {
    /// x, y with [`SUBPIXEL_BITS`] fraction bits.
    pub xy: [[i32; 2]; 3],
    /// 24-bit depths.
    pub z: [u32; 3],
    /// RGB8 per vertex.
    pub rgb: [[u8; 3]; 3],
    pub mode: Mode,
}

impl FixedTriangle {
    /// Converts a trace triangle (round to nearest; coordinates already bounded by the
    /// trace reader).
    pub fn from_trace(t: &TraceTriangle) -> Self {
        let mut f = FixedTriangle {
            xy: [[0; 2]; 3],
            z: [0; 3],
            rgb: [[0; 3]; 3],
            mode: t.mode,
        };
        for v in 0..3 {
            let p = t.positions[v];
            f.xy[v] = [fixed(p[0]), fixed(p[1])];
            f.z[v] = (p[2].clamp(0.0, 1.0) as f64 * DEPTH_MAX as f64).round() as u32;
            f.rgb[v] = t.colours[v].map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8);
        }
        f
    }
}

fn fixed(x: f32) -> i32 {
    (x as f64 * ONE as f64).round() as i32
}

/// An inclusive rectangle of pixels: a primitive's operand region (the paper's bbox).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Region {
    pub x0: u16,
    pub x1: u16,
    pub y0: u16,
    pub y1: u16,
}

impl Region {
    /// The paper's inclusive overlap test (l.143–160).
    pub fn overlaps(&self, o: &Region) -> bool {
        self.x0 <= o.x1 && self.x1 >= o.x0 && self.y0 <= o.y1 && self.y1 >= o.y0
    }

    pub fn contains(&self, x: u16, y: u16) -> bool {
        (self.x0..=self.x1).contains(&x) && (self.y0..=self.y1).contains(&y)
    }

    pub fn pixels(&self) -> u64 {
        (self.x1 - self.x0 + 1) as u64 * (self.y1 - self.y0 + 1) as u64
    }
}

/// Smallest pixel index whose centre is at or right of fixed-point `v`: ⌈(v − ½)/1⌉.
fn first_centre(v: i64) -> i64 {
    ceil_div(v - HALF, ONE)
}

/// Largest pixel index whose centre is at or left of fixed-point `v`.
fn last_centre(v: i64) -> i64 {
    (v - HALF).div_euclid(ONE)
}

fn ceil_div(n: i64, d: i64) -> i64 {
    -((-n).div_euclid(d))
}

/// The region of the pixel centres of `t` in rows `rows` (inclusive, `None` = all rows),
/// clamped to a `w × h` window; `None` if it holds no pixel centre. With a row band, the
/// x extent is that of the triangle cut to the band (vertices inside it and the edges'
/// crossings of its first and last centre lines, rounded outward): each slice of a split
/// triangle gets its own, tighter box.
pub fn region(t: &FixedTriangle, rows: Option<(u16, u16)>, w: u32, h: u32) -> Option<Region> {
    let ys = t.xy.map(|v| v[1] as i64);
    let (ymin, ymax) = (*ys.iter().min().unwrap(), *ys.iter().max().unwrap());
    let mut r0 = first_centre(ymin).max(0);
    let mut r1 = last_centre(ymax).min(h as i64 - 1);
    if let Some((a, b)) = rows {
        r0 = r0.max(a as i64);
        r1 = r1.min(b as i64);
    }
    if r0 > r1 {
        return None;
    }
    // The band between the first and last centre lines, in fixed point.
    let (by0, by1) = (r0 * ONE + HALF, r1 * ONE + HALF);
    let (mut xmin, mut xmax) = (i64::MAX, i64::MIN);
    for v in &t.xy {
        let (x, y) = (v[0] as i64, v[1] as i64);
        if (by0..=by1).contains(&y) {
            xmin = xmin.min(x);
            xmax = xmax.max(x);
        }
    }
    for i in 0..3 {
        let (a, b) = (t.xy[i], t.xy[(i + 1) % 3]);
        let (ax, ay, bx, by) = (a[0] as i64, a[1] as i64, b[0] as i64, b[1] as i64);
        for yl in [by0, by1] {
            if ay == by || yl < ay.min(by) || yl > ay.max(by) {
                continue;
            }
            // x = ax + (yl − ay)(bx − ax)/(by − ay), rounded outward.
            let num = ax as i128 * (by - ay) as i128 + (yl - ay) as i128 * (bx - ax) as i128;
            let den = (by - ay) as i128;
            let (num, den) = if den < 0 { (-num, -den) } else { (num, den) };
            xmin = xmin.min(num.div_euclid(den) as i64);
            xmax = xmax.max((-((-num).div_euclid(den))) as i64);
        }
    }
    if xmin > xmax {
        return None;
    }
    let x0 = first_centre(xmin).max(0);
    let x1 = last_centre(xmax).min(w as i64 - 1);
    if x0 > x1 {
        return None;
    }
    Some(Region {
        x0: x0 as u16,
        x1: x1 as u16,
        y0: r0 as u16,
        y1: r1 as u16,
    })
}

/// A triangle's setup: counter-clockwise vertex order and three edge functions
/// `E(x, y) = a·x + b·y + c` (fixed-point x, y), each with its tie bias (0 on a top or left
/// edge, −1 otherwise). Edge `i` runs from vertex `i` to `i + 1` and weights vertex `i + 2`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Setup {
    pub tri: FixedTriangle,
    pub a: [i64; 3],
    pub b: [i64; 3],
    pub c: [i64; 3],
    pub bias: [i64; 3],
    /// Σ of the edge functions anywhere: twice the area, in 1/256 pixel².
    pub area2: i64,
}

impl Setup {
    /// `None` for a triangle of zero area (it covers no pixel).
    pub fn new(t: &FixedTriangle) -> Option<Setup> {
        let mut tri = *t;
        let p = tri.xy.map(|v| [v[0] as i64, v[1] as i64]);
        let area2 =
            (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]);
        if area2 == 0 {
            return None;
        }
        if area2 < 0 {
            // Clockwise: swap two vertices (attributes with them) so inside is E ≥ 0.
            tri.xy.swap(1, 2);
            tri.z.swap(1, 2);
            tri.rgb.swap(1, 2);
        }
        let p = tri.xy.map(|v| [v[0] as i64, v[1] as i64]);
        let mut s = Setup {
            tri,
            a: [0; 3],
            b: [0; 3],
            c: [0; 3],
            bias: [0; 3],
            area2: area2.abs(),
        };
        for i in 0..3 {
            let (a, b) = (p[i], p[(i + 1) % 3]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            // E = dx·(y − ay) − dy·(x − ax): positive left of the edge (inside, CCW).
            s.a[i] = -dy;
            s.b[i] = dx;
            s.c[i] = dy * a[0] - dx * a[1];
            // Counter-clockwise with y up: a left edge runs down, a top edge runs left.
            let top_left = dy < 0 || (dy == 0 && dx < 0);
            s.bias[i] = if top_left { 0 } else { -1 };
        }
        Some(s)
    }

    /// Edge function `i` at the centre of pixel (`px`, `py`).
    pub fn edge(&self, i: usize, px: i64, py: i64) -> i64 {
        self.a[i] * (px * ONE + HALF) + self.b[i] * (py * ONE + HALF) + self.c[i]
    }

    pub fn covers(&self, px: i64, py: i64) -> bool {
        (0..3).all(|i| self.edge(i, px, py) + self.bias[i] >= 0)
    }

    /// The span generator: the covered pixels of row `py` within `x0..=x1`, as an
    /// inclusive range, from each edge's crossing (a division per edge, no pixel walk).
    pub fn span(&self, py: u16, x0: u16, x1: u16) -> Option<(u16, u16)> {
        let (mut lo, mut hi) = (x0 as i64, x1 as i64);
        for i in 0..3 {
            // E + bias at pixel px is α·px + β.
            let alpha = self.a[i] * ONE;
            let beta =
                self.a[i] * HALF + self.b[i] * (py as i64 * ONE + HALF) + self.c[i] + self.bias[i];
            if alpha > 0 {
                lo = lo.max(ceil_div(-beta, alpha));
            } else if alpha < 0 {
                hi = hi.min(beta.div_euclid(-alpha));
            } else if beta < 0 {
                return None;
            }
        }
        (lo <= hi).then_some((lo as u16, hi as u16))
    }

    /// Depth and colour (RGBA8, opaque) at the centre of a covered pixel.
    pub fn shade(&self, px: u16, py: u16) -> (u32, u32) {
        let w = [0, 1, 2].map(|i| self.edge(i, px as i64, py as i64) as i128);
        // Edge i weights vertex i + 2.
        let blend = |v: [i128; 3]| -> i128 {
            let num = w[0] * v[2] + w[1] * v[0] + w[2] * v[1];
            num.div_euclid(self.area2 as i128)
        };
        let t = &self.tri;
        let z = blend(t.z.map(|z| z as i128)).clamp(0, DEPTH_MAX as i128) as u32;
        let mut rgba = 0xFF00_0000u32;
        for ch in 0..3 {
            let c = blend([0, 1, 2].map(|v| t.rgb[v][ch] as i128)).clamp(0, 255) as u32;
            rgba |= c << (8 * ch);
        }
        (z, rgba)
    }
}

/// The depth buffer word of a fragment: depth above the primitive's order tag.
pub fn depth_word(z: u32, order: u32) -> u64 {
    ((z as u64) << 24) | order as u64
}

/// The 50/50 blend of a blended primitive's colour over the destination (alpha stays
/// opaque).
pub fn blend(src: u32, dst: u32) -> u32 {
    let mut out = 0xFF00_0000u32;
    for ch in 0..3 {
        let s = (src >> (8 * ch)) & 0xFF;
        let d = (dst >> (8 * ch)) & 0xFF;
        out |= ((s + d) >> 1) << (8 * ch);
    }
    out
}

/// A frame: colour (RGBA8 words, red in the low byte) and depth-buffer words, row 0 at
/// the bottom.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    pub colour: Vec<u32>,
    pub depth: Vec<u64>,
}

impl Frame {
    pub fn cleared(width: u32, height: u32) -> Frame {
        let n = (width * height) as usize;
        Frame {
            width,
            height,
            colour: vec![CLEAR_COLOUR; n],
            depth: vec![CLEAR_DEPTH_WORD; n],
        }
    }
}

/// One fragment through the depth test and the colour write, as the pixel pipeline does
/// it (`order` is the primitive's tag).
pub fn apply_fragment(
    mode: Mode,
    z: u32,
    colour: u32,
    order: u32,
    old_depth: u64,
    old_colour: u32,
) -> Option<(Option<u64>, u32)> {
    let word = depth_word(z, order);
    if word >= old_depth {
        return None;
    }
    Some(match mode {
        Mode::Opaque => (Some(word), colour),
        Mode::Blended => (None, blend(colour, old_colour)),
    })
}

/// The trace drawn in order, one triangle after another, by the same arithmetic: the
/// golden frame. Primitive `i` has order tag `i + 1`.
pub fn reference_frame(tris: &[TraceTriangle], width: u32, height: u32) -> Frame {
    let mut f = Frame::cleared(width, height);
    for (i, t) in tris.iter().enumerate() {
        let ft = FixedTriangle::from_trace(t);
        let (Some(s), Some(r)) = (Setup::new(&ft), region(&ft, None, width, height)) else {
            continue;
        };
        for py in r.y0..=r.y1 {
            let Some((xl, xr)) = s.span(py, r.x0, r.x1) else {
                continue;
            };
            for px in xl..=xr {
                let (z, c) = s.shade(px, py);
                let a = py as usize * width as usize + px as usize;
                if let Some((d, c)) =
                    apply_fragment(ft.mode, z, c, i as u32 + 1, f.depth[a], f.colour[a])
                {
                    if let Some(d) = d {
                        f.depth[a] = d;
                    }
                    f.colour[a] = c;
                }
            }
        }
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(p: [[f32; 2]; 3]) -> FixedTriangle {
        FixedTriangle::from_trace(&TraceTriangle {
            positions: p.map(|v| [v[0], v[1], 0.5]),
            colours: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            mode: Mode::Opaque,
        })
    }

    #[test]
    fn spans_are_exactly_the_covered_pixels_and_inside_the_region() {
        for p in [
            [[0.3, 0.2], [37.9, 5.1], [12.2, 40.7]],
            [[37.9, 5.1], [0.3, 0.2], [12.2, 40.7]],
            [[-10.0, -3.0], [70.0, 20.0], [5.0, 90.0]],
            [[4.0, 4.0], [20.0, 4.0], [4.0, 20.0]],
        ] {
            let t = tri(p);
            let s = Setup::new(&t).unwrap();
            let r = region(&t, None, 64, 64).unwrap();
            for py in 0..64u16 {
                let span = if (r.y0..=r.y1).contains(&py) {
                    s.span(py, r.x0, r.x1)
                } else {
                    None
                };
                for px in 0..64u16 {
                    let inside = span.is_some_and(|(a, b)| (a..=b).contains(&px));
                    assert_eq!(inside, s.covers(px as i64, py as i64), "{p:?} at {px},{py}");
                    if inside {
                        assert!(r.contains(px, py));
                    }
                }
            }
        }
    }

    #[test]
    fn slice_regions_cover_their_rows_of_the_triangle_and_are_tighter() {
        let t = tri([[0.3, 0.2], [60.0, 30.0], [2.0, 63.0]]);
        let s = Setup::new(&t).unwrap();
        let whole = region(&t, None, 64, 64).unwrap();
        let mut tighter = false;
        for band in [(0, 15), (16, 31), (32, 47), (48, 63)] {
            let r = region(&t, Some(band), 64, 64).unwrap();
            tighter |= r.pixels() < whole.pixels() / 4;
            for py in band.0..=band.1 {
                for px in 0..64u16 {
                    if s.covers(px as i64, py as i64) {
                        assert!(r.contains(px, py), "{band:?}: {px},{py} outside {r:?}");
                    }
                }
            }
        }
        assert!(tighter);
    }

    #[test]
    fn shared_edges_are_drawn_once() {
        let a = Setup::new(&tri([[1.0, 1.0], [30.0, 3.0], [9.0, 29.0]])).unwrap();
        let b = Setup::new(&tri([[30.0, 3.0], [31.0, 31.0], [9.0, 29.0]])).unwrap();
        for py in 0..40 {
            for px in 0..40 {
                assert!(!(a.covers(px, py) && b.covers(px, py)), "{px},{py}");
            }
        }
    }

    #[test]
    fn equal_depths_go_to_the_earlier_primitive_in_any_order() {
        let early = depth_word(100, 3);
        let late = depth_word(100, 7);
        assert!(early < late && late < CLEAR_DEPTH_WORD);
        assert!(depth_word(DEPTH_MAX, 1) > CLEAR_DEPTH_WORD);
    }
}
