//! Mipmap pyramids, built when a scene loads (not frame time): level 0 is the texture, each
//! further level a 2 × 2 box filter of the one before, down to 1 × 1 (OpenGL 1.2's
//! `GL_LINEAR_MIPMAP_LINEAR` needs the whole chain). A side of 1 stays 1, and the filter
//! then averages the 2 texels along the other side. Each channel of an RGBA8 texel is
//! averaged with rounding half up, `(a + b + c + d + 2) / 4` (or `(a + b + 1) / 2`),
//! the usual choice of `gluBuild2DMipmaps`-style box filters. Both the machine (which
//! stores every level in DRAM) and the reference renderers sample these same levels, so a
//! difference between them is never the pyramid's.

use super::model::Texture;

/// One level of a pyramid: `texels[row * width + col]`, RGBA8 with red in the low byte,
/// row 0 at the bottom.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Level {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<u32>,
}

/// The levels of `texture`, level 0 first and the 1 × 1 level last.
pub fn pyramid(texture: &Texture) -> Vec<Level> {
    let mut levels = vec![Level {
        width: texture.width,
        height: texture.height,
        texels: texture.texels.clone(),
    }];
    while let Some(last) = levels.last().filter(|l| l.width > 1 || l.height > 1) {
        levels.push(reduce(last));
    }
    levels
}

/// How many levels [`pyramid`] builds for a `width × height` texture.
pub fn level_count(width: u32, height: u32) -> usize {
    (32 - width.max(height).max(1).leading_zeros()) as usize
}

/// The next level: each texel the rounded mean of the 2 × 2 (or 2 × 1) texels below it.
fn reduce(level: &Level) -> Level {
    let (w, h) = (level.width, level.height);
    let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
    let (sx, sy) = (u32::from(w > 1) + 1, u32::from(h > 1) + 1);
    let mut texels = Vec::with_capacity((nw * nh) as usize);
    for row in 0..nh {
        for col in 0..nw {
            let mut sum = [0u32; 4];
            for dy in 0..sy {
                for dx in 0..sx {
                    let (x, y) = ((col * sx + dx).min(w - 1), (row * sy + dy).min(h - 1));
                    let t = level.texels[(y * w + x) as usize].to_le_bytes();
                    for (s, byte) in sum.iter_mut().zip(t) {
                        *s += u32::from(byte);
                    }
                }
            }
            let n = sx * sy;
            let mean = sum.map(|s| ((s + n / 2) / n) as u8);
            texels.push(u32::from_le_bytes(mean));
        }
    }
    Level {
        width: nw,
        height: nh,
        texels,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::model::{Filter, Wrap};

    fn texture(width: u32, height: u32, texels: Vec<u32>) -> Texture {
        Texture {
            name: "t".into(),
            width,
            height,
            texels,
            filter: Filter::Trilinear,
            wrap: Wrap::Repeat,
        }
    }

    #[test]
    fn levels_halve_down_to_one_texel() {
        let t = texture(8, 2, vec![0; 16]);
        let sizes: Vec<_> = pyramid(&t).iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(sizes, [(8, 2), (4, 1), (2, 1), (1, 1)]);
        assert_eq!(level_count(8, 2), 4);
        assert_eq!(level_count(1, 1), 1);
        assert_eq!(level_count(512, 512), 10);
    }

    #[test]
    fn box_filter_rounds_each_channel_half_up() {
        // Red 0, 1, 1, 1 → (3 + 2) / 4 = 1; green 255, 255, 255, 0 → (765 + 2) / 4 = 191.
        let t = texture(
            2,
            2,
            vec![0x0000_FF00, 0x0000_FF01, 0x0000_FF01, 0x0000_0001],
        );
        let top = &pyramid(&t)[1];
        assert_eq!(top.texels, [u32::from_le_bytes([1, 191, 0, 0])]);
        // A 2 × 1 pair: (0 + 255 + 1) / 2 = 128 in red.
        let t = texture(2, 1, vec![0x0000_0000, 0x0000_00FF]);
        assert_eq!(pyramid(&t)[1].texels, [0x0000_0080]);
    }
}
