//! A scene's textures on the machine: their mipmap pyramids laid out in one DRAM buffer
//! (written by the host before the frame, a load phase, not frame time) and each textured
//! material's fragment program ([`crate::kernels::texture`]) over that layout.

use crate::kernels::texture::{FragmentProgram, Unit};
use crate::scene::mipmap;
use crate::scene::model::{Filter, Scene, Texture, TextureMode};

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

/// The fragment program of a material with textures `textures` (indices into the scene's)
/// and environment `mode`, its units at their places in `memory`.
pub fn for_material(
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
    FragmentProgram { units, mode }
}
