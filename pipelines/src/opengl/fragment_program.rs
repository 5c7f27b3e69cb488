//! A scene's textures on the machine: their mipmap pyramids and the `bump_env` materials'
//! combined displacement/bump maps laid out in one DRAM buffer (written by the host before
//! the frame, a load phase, not frame time) and each textured material's fragment program
//! ([`crate::kernels::texture`], [`crate::kernels::bump_env`]) over that layout.
//!
//! **Marble** (`shader = "marble"`, MARBLE's procedural shader, Owens 2002 §5.1.1) is a
//! depth-0 program without lookups: one kernel, `marble`
//! ([`crate::kernels::turbulence::build_fragment`]), the project's `turbulence` shader
//! reading `irast`'s varyings (the object-space shading position and normal) and writing
//! the packed colour. The material's `noise` chooses the kernel: `marble_ward` over Ward's
//! noise (no table: [`crate::kernels::ward_noise`]) or `marble` over Perlin's improved
//! noise, whose permutation table is Perlin's
//! ([`crate::kernels::turbulence::PERLIN_PERMUTATION`]), written by the host into DRAM
//! when the scene loads (each word once per cluster, the layout the kernel reads) and
//! loaded from there into the SRF once per frame (only in frames with a Perlin marble).
//! Its parameters ([`marble_params`]) are
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

use glam::{DMat3, DMat4, DVec3};

use imagine_units::desc::TextureCacheDesc;

use crate::kernels::bump_env::Maps;
use crate::kernels::texture::{FragmentProgram, Unit};
use crate::scene::model::{Filter, Marble, Object, Scene, Shader, Texture, TextureMode};
use crate::scene::{bump_map, mipmap};

/// Where a scene's textures lie in the texture buffer: the textures in order, then the
/// combined displacement/bump map of each `bump_env` material ([`bump_map`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TextureMemory {
    /// Per scene texture: its level 0's first word.
    pub base: Vec<u32>,
    /// Per material: its combined map's first word (`bump_env` materials).
    pub bump_base: Vec<Option<u32>>,
    /// The buffer's words (every level of every texture, at their offsets).
    pub words: Vec<u32>,
}

impl TextureMemory {
    /// Lays out `scene`'s textures (their pyramids built here, at load time). Without a
    /// texture cache they are packed one after another. With one (`cache`), texture `k` of
    /// `n` starts `k·⌊words / n⌋` words (whole lines) past a multiple of the cache's size:
    /// a fragment samples all its textures at about the same coordinates, and packed
    /// textures whose sizes are multiples of the cache's (a mipmapped 256² takes 2·256²
    /// words) would put those texels on the same sets of a direct-mapped cache, evicting
    /// one another (PIN-8 on gold32combo+tc1: 83.9 % hits packed, 96.4 % staggered).
    pub fn new(scene: &Scene, cache: Option<&TextureCacheDesc>) -> TextureMemory {
        let mut base = Vec::new();
        let mut words: Vec<u32> = Vec::new();
        let n = scene.textures.len();
        for (k, t) in scene.textures.iter().enumerate() {
            if let Some(c) = cache {
                let step = c.words / n / c.line_words * c.line_words;
                let pad = (k * step + c.words - words.len() % c.words) % c.words;
                words.resize(words.len() + pad, 0);
            }
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
        let bump_base = scene
            .materials
            .iter()
            .map(|m| match m.shader {
                Shader::BumpEnv(b) => {
                    let at = words.len() as u32;
                    words.extend(bump_map::build(&b));
                    Some(at)
                }
                _ => None,
            })
            .collect();
        TextureMemory {
            base,
            bump_base,
            words,
        }
    }
}

/// The `bump_env` program of material `material` (its one texture the environment map),
/// its maps at their places in `memory`.
pub fn for_bump_env(
    scene: &Scene,
    material: usize,
    memory: &TextureMemory,
) -> Option<FragmentProgram> {
    let m = &scene.materials[material];
    let (Shader::BumpEnv(b), Some(bump_base), [environment]) =
        (m.shader, memory.bump_base[material], m.textures.as_slice())
    else {
        return None;
    };
    let mut units = for_material(scene, &[*environment], m.texture_mode, memory).units;
    Some(FragmentProgram::bump_env(Maps {
        bump_base,
        bump_size: b.bump_size,
        environment: units.remove(0),
    }))
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
    FragmentProgram {
        units,
        mode,
        marble: None,
        bump_env: None,
    }
}

/// The marble shader's parameters for `object` of `scene` (see the module notes), in the
/// kernel's order: frequency, turbulence scale, L, H, ambient, specular.
pub fn marble_params(scene: &Scene, object: &Object, marble: &Marble) -> Vec<u32> {
    let m = &scene.materials[object.material];
    // Row-major f32 matrices, widened: glam's are column-major.
    let matrix = |m: &[f32; 16]| DMat4::from_cols_array(&m.map(f64::from)).transpose();
    let model = matrix(&object.model);
    let view = matrix(&scene.camera_for(object).view);
    let origin = model.w_axis.truncate();
    let eye = view.inverse().transform_point3(DVec3::ZERO);
    let to_object = DMat3::from_mat4(model).inverse();
    let direction = |to: DVec3| (to_object * (to - origin)).normalize_or_zero();
    let (light, half) = match scene.lights.first() {
        Some(l) => {
            let light = direction(DVec3::from(l.position.map(f64::from)));
            let viewer = direction(eye);
            (light, (light + viewer).normalize_or_zero())
        }
        None => (DVec3::ZERO, DVec3::ZERO),
    };
    let mean = |c: [f32; 3]| c.iter().map(|&x| f64::from(x)).sum::<f64>() / 3.0;
    [
        f64::from(marble.frequency),
        f64::from(marble.turbulence_scale),
    ]
    .into_iter()
    .chain(light.to_array())
    .chain(half.to_array())
    .chain([mean(m.ambient), mean(m.specular)])
    .map(|x| (x as f32).to_bits())
    .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn with_a_texture_cache_the_textures_start_on_sets_spread_over_it() {
        let scene = crate::scene::file::load("PIN-8", &Default::default()).expect("PIN-8");
        let packed = TextureMemory::new(&scene, None);
        let n = scene.textures.len();
        assert_eq!(n, 5);
        for k in 1..n {
            assert_eq!(
                packed.base[k] % 16384,
                0,
                "PIN-8's pyramids are whole 16K-word blocks"
            );
        }
        let cache = TextureCacheDesc {
            words: 16384,
            line_words: 2,
            hit_words_per_cycle: 1,
        };
        let staggered = TextureMemory::new(&scene, Some(&cache));
        let step = 16384 / 5 / 2 * 2;
        for (k, &base) in staggered.base.iter().enumerate() {
            assert_eq!(base as usize % 16384, k * step, "texture {k}");
            // The texels are the packed layout's, moved.
            let size = |m: &TextureMemory| {
                m.base.get(k + 1).map_or(m.words.len(), |&b| b as usize) - m.base[k] as usize
            };
            let at = packed.base[k] as usize;
            let texels = &packed.words[at..at + size(&packed)];
            assert_eq!(
                &staggered.words[base as usize..base as usize + texels.len()],
                texels
            );
        }
    }
}
