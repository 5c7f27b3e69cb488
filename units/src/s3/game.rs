//! Generated game-like traces: the paper's Direct3D frames (FIFA 99, MotoRacer 2, Shogo,
//! Turok 2; l.217–236) are not available, so these stand in for them with the published
//! statistics in mind (spec §1.4): a 640×480 window, a few thousand triangles mostly in
//! strips (the chains of §4.6), triangles of a few hundred pixels, depth complexity of a
//! few, a large background drawn first, and an alpha-blended subset (particles) drawn
//! last. Deterministic: a fixed seed drives a xorshift generator.
//!
//! * `game-strips` — a full-window background (two triangles, 307,200 pixels) under
//!   strips of small triangles and blended particles (a MotoRacer/Shogo-like frame);
//! * `game-sky` — a sky of two triangles covering 92,160 pixels (turok3's two sky
//!   triangles cover about 92,000, l.256), then strips and particles: a frame dominated
//!   by one huge primitive, where splitting is the paper's big win.

use super::raster::{Mode, TraceTriangle};

/// The built-in traces: name and what it is.
pub const BUILTIN: &[(&str, &str)] = &[
    (
        "game-strips",
        "640×480: full-window background, 64 strips of 40 small triangles, 200 blended particles",
    ),
    (
        "game-sky",
        "640×480: a 92,160-pixel sky of two triangles, 64 strips of 40 triangles, 200 particles",
    ),
];

/// The parameters of a generated frame.
#[derive(Clone, Debug)]
pub struct GameParams {
    pub width: u32,
    pub height: u32,
    pub seed: u64,
    /// The background's rows: the top `background_rows` rows of the window, two
    /// triangles, drawn first (0: none).
    pub background_rows: u32,
    pub strips: usize,
    pub strip_triangles: usize,
    /// Strip width and step along the strip, in pixels.
    pub strip_width: f32,
    pub strip_step: f32,
    /// Blended particles (small triangles), drawn last.
    pub particles: usize,
    /// Depth levels strips are drawn at (few levels: many equal depths).
    pub depth_levels: u32,
}

impl GameParams {
    /// The built-in trace `name`.
    pub fn builtin(name: &str) -> Option<GameParams> {
        let base = GameParams {
            width: 640,
            height: 480,
            seed: 0x5EED_0001,
            background_rows: 480,
            strips: 64,
            strip_triangles: 40,
            strip_width: 24.0,
            strip_step: 14.0,
            particles: 200,
            depth_levels: 1 << 16,
        };
        match name {
            "game-strips" => Some(base),
            "game-sky" => Some(GameParams {
                seed: 0x5EED_0002,
                background_rows: 144,
                ..base
            }),
            _ => None,
        }
    }
}

struct XorShift(u64);

impl XorShift {
    fn next(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        self.0 = x;
        x
    }
    /// Uniform in [0, 1), from the top 24 bits (exact in f32).
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
}

/// Generates a frame.
pub fn generate(p: &GameParams) -> Vec<TraceTriangle> {
    let mut rng = XorShift(p.seed | 1);
    let (w, h) = (p.width as f32, p.height as f32);
    let mut tris = Vec::new();
    let colour = |rng: &mut XorShift| [rng.unit(), rng.unit(), rng.unit()];
    if p.background_rows > 0 {
        let y0 = h - p.background_rows as f32;
        let z = 0.999;
        let quad = [[0.0, y0], [w, y0], [w, h], [0.0, h]];
        for idx in [[0, 1, 2], [0, 2, 3]] {
            tris.push(TraceTriangle {
                positions: idx.map(|i| [quad[i][0], quad[i][1], z]),
                colours: [colour(&mut rng), colour(&mut rng), colour(&mut rng)],
                mode: Mode::Opaque,
            });
        }
    }
    for _ in 0..p.strips {
        let (sx, sy) = (rng.range(0.0, w), rng.range(0.0, h));
        // Heading roughly toward the window's centre, so that most strips stay in view.
        let to_centre = (h / 2.0 - sy).atan2(w / 2.0 - sx);
        let angle = to_centre + rng.range(-1.0, 1.0);
        let (dx, dy) = (angle.cos(), angle.sin());
        let (nx, ny) = (-dy * p.strip_width / 2.0, dx * p.strip_width / 2.0);
        let level = (rng.next() % p.depth_levels as u64) as f32;
        let z = 0.05 + 0.9 * level / p.depth_levels as f32;
        let mut verts = Vec::new();
        for i in 0..p.strip_triangles + 2 {
            let along =
                p.strip_step * (i / 2) as f32 + if i % 2 == 1 { p.strip_step / 2.0 } else { 0.0 };
            let side = if i % 2 == 0 { 1.0 } else { -1.0 };
            verts.push([sx + dx * along + side * nx, sy + dy * along + side * ny, z]);
        }
        for i in 0..p.strip_triangles {
            tris.push(TraceTriangle {
                positions: [verts[i], verts[i + 1], verts[i + 2]],
                colours: [colour(&mut rng), colour(&mut rng), colour(&mut rng)],
                mode: Mode::Opaque,
            });
        }
    }
    for _ in 0..p.particles {
        let (cx, cy) = (rng.range(0.0, w), rng.range(0.0, h));
        let r = rng.range(4.0, 12.0);
        let z = rng.range(0.05, 0.95);
        let a = rng.range(0.0, std::f32::consts::TAU);
        let third = std::f32::consts::TAU / 3.0;
        let positions = [0.0, 1.0, 2.0].map(|k| {
            let t = a + k * third;
            [cx + r * t.cos(), cy + r * t.sin(), z]
        });
        tris.push(TraceTriangle {
            positions,
            colours: [colour(&mut rng), colour(&mut rng), colour(&mut rng)],
            mode: Mode::Blended,
        });
    }
    tris
}
