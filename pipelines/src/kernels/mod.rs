//! The kernel library: the kernels of the OpenGL-like pipeline and of the benchmark scenes,
//! written with the [`KernelBuilder`](crate::kernel::KernelBuilder) (ARCHITECTURE §5).
//!
//! Each kernel is a function of the machine description (kernels that split a fixed-size
//! problem over the clusters, like [`sort32`], are built for `desc.cluster.count`). A
//! builder first checks what the kernel needs of the machine (see
//! [`Needs`](crate::kernel::Needs)) and returns a
//! [`MachineRequirementError`] for a machine it cannot serve. The
//! [`library`] registry names every kernel with a builder and a generator of random valid
//! inputs, so tools and tests can run any of them by name. Its names differ from those the
//! OpenGL pipeline registers its own kernels under
//! ([`crate::opengl::render::pipeline_kernels`]), which `imagine kernel` lists beside
//! them, but where the pipeline builds the very kernel the library does (`filter8`;
//! VERONA's `vertex_bump_env`).
//!
//! | kernel | computes |
//! |---|---|
//! | [`transform`] | 4×4 matrix times a homogeneous position |
//! | [`vertex`] | the SPHERE vertex program: transform plus three-light Blinn-Phong lighting |
//! | [`turbulence`] | the MARBLE shader: four octaves of Perlin improved noise, marble colour ramp; `turbulence_ward` over Ward's noise ([`ward_noise`]) |
//! | `marble` ([`turbulence::build_fragment`]) | `turbulence` as the OpenGL pipeline's fragment program: `irast`'s varyings in, packed RGBA8 out; `marble_ward` over Ward's noise |
//! | [`prefix_sum`] | inclusive prefix sum of an int32 stream |
//! | [`compact`] | keeps the fp32 words below a threshold, in order |
//! | `load_balance` ([`record_input`]) | load-balanced conditional input of 3-word records: each cluster takes the next when its own is used up |
//! | `hash_xy` ([`hash`]) | the composite stamp test of the OpenGL pipeline (per-cluster 32×32 stamp) on (x, y) records |
//! | `sort32_keys` ([`sort32`]) | bitonic sort of 32-word chunks of u32 keys |
//! | [`merge`] | bitonic merge of pairs of sorted 32-word chunks into 64-word chunks |
//! | [`texture`] | texture sampling: `texaddr` (texel addresses), `filter8` (trilinear filter), `fragment` (texture environment) |
//! | [`bump_env`] | VERONA's shader split at its lookups: `vtexaddr` and `vertex_bump_env` (vertex texture, displacement), `bumpaddr` (depth 2), `envaddr` (depth 1: bumped normal, reflection, sphere map), `envshade` (depth 0) |

pub mod bump_env;
pub mod compact;
pub mod hash;
pub mod merge;
pub mod prefix_sum;
pub mod record_input;
pub mod sort32;
pub mod texture;
pub mod transform;
pub mod turbulence;
pub mod vertex;
pub mod ward_noise;

use imagine_units::arith::fp32::testgen::SplitMix64;
use imagine_units::desc::MachineDesc;
use imagine_units::ops::UnitClass;

use crate::kernel::{Kernel, KernelInputs, MachineRequirementError, Node, Region};

/// A kernel of the library: how to build it and how to make inputs for it.
pub struct LibraryKernel {
    pub name: &'static str,
    pub description: &'static str,
    /// Builds the kernel for a machine, or says what the kernel needs that the machine
    /// lacks.
    pub build: fn(&MachineDesc) -> Result<Kernel, MachineRequirementError>,
    /// Random valid inputs for `rows` iterations of the kernel's main loop, deterministic
    /// from `seed` (one entry per stream: output streams get empty vectors).
    pub inputs: fn(&MachineDesc, rows: usize, seed: u64) -> KernelInputs,
}

static LIBRARY: &[LibraryKernel] = &[
    LibraryKernel {
        name: "transform",
        description: "4x4 fp32 matrix times (x, y, z, w) position records",
        build: transform::build,
        inputs: transform::inputs,
    },
    LibraryKernel {
        name: "vertex",
        description: "SPHERE vertex program: clip-space transform and three-light Blinn-Phong",
        build: vertex::build,
        inputs: vertex::inputs,
    },
    LibraryKernel {
        name: "turbulence",
        description: "MARBLE shader: four octaves of Perlin improved noise and a marble ramp",
        build: turbulence::build_perlin,
        inputs: turbulence::perlin_inputs,
    },
    LibraryKernel {
        name: "turbulence_ward",
        description: "the MARBLE shader over Ward's Perlin noise (the publication's; slow to compile)",
        build: turbulence::build,
        inputs: turbulence::inputs,
    },
    LibraryKernel {
        name: "marble",
        description: "MARBLE fragment program: turbulence on irast's varyings, packed RGBA8 out",
        build: turbulence::build_marble_perlin,
        inputs: turbulence::marble_perlin_inputs,
    },
    LibraryKernel {
        name: "marble_ward",
        description: "the MARBLE fragment program over Ward's Perlin noise (slow to compile)",
        build: turbulence::build_marble,
        inputs: turbulence::marble_inputs,
    },
    LibraryKernel {
        name: "prefix_sum",
        description: "inclusive prefix sum of an int32 stream (wrapping)",
        build: prefix_sum::build,
        inputs: prefix_sum::inputs,
    },
    LibraryKernel {
        name: "load_balance",
        description: "load-balanced conditional input of 3-word records (the scanline rasterizer's)",
        build: record_input::build,
        inputs: record_input::inputs,
    },
    LibraryKernel {
        name: "compact",
        description: "keeps the fp32 words below a threshold parameter, in order",
        build: compact::build,
        inputs: compact::inputs,
    },
    LibraryKernel {
        name: "hash_xy",
        description: "composite stamp test: splits (x, y) fragments into ok and conflict",
        build: hash::build,
        inputs: hash::inputs,
    },
    LibraryKernel {
        name: "sort32_keys",
        description: "bitonic sort of 32-word chunks of u32 keys",
        build: sort32::build,
        inputs: sort32::inputs,
    },
    LibraryKernel {
        name: "texaddr",
        description: "texel addresses of a nearest, a bilinear and a trilinear texture",
        build: texture::texaddr_example,
        inputs: texture::texaddr_inputs,
    },
    LibraryKernel {
        name: "filter8",
        description: "trilinear filter: 8 RGBA8 texels and 5 weights to one RGBA8 texel",
        build: texture::filter8,
        inputs: texture::filter8_inputs,
    },
    LibraryKernel {
        name: "fragment",
        description: "texture environment: vertex colour modulated by three textures",
        build: texture::fragment_example,
        inputs: texture::fragment_inputs,
    },
    LibraryKernel {
        name: "vtexaddr",
        description: "VERONA vertex texture: a vertex's 4 words of the combined bump map",
        build: bump_env::vtexaddr_example,
        inputs: bump_env::vtexaddr_inputs,
    },
    LibraryKernel {
        name: "vertex_bump_env",
        description: "VERONA vertex program: displacement, bumped normal, eye-space frame",
        build: bump_env::vertex_example,
        inputs: bump_env::vertex_inputs,
    },
    LibraryKernel {
        name: "bumpaddr",
        description: "VERONA depth 2: the bump-map normal's 3 word addresses per fragment",
        build: bump_env::bumpaddr_example,
        inputs: bump_env::bumpaddr_inputs,
    },
    LibraryKernel {
        name: "envaddr",
        description: "VERONA depth 1: bumped normal, reflection, sphere-map texel address",
        build: bump_env::envaddr_example,
        inputs: bump_env::envaddr_inputs,
    },
    LibraryKernel {
        name: "envshade",
        description: "VERONA depth 0: environment texel times the vertex colour, RGBA8",
        build: bump_env::shade_example,
        inputs: bump_env::shade_inputs,
    },
    LibraryKernel {
        name: "merge",
        description: "bitonic merge of pairs of sorted 32-word u32 chunks",
        build: merge::build,
        inputs: merge::inputs,
    },
];

/// Every kernel of the library.
pub fn library() -> &'static [LibraryKernel] {
    LIBRARY
}

/// The library kernel called `name`.
pub fn find(name: &str) -> Option<&'static LibraryKernel> {
    LIBRARY.iter().find(|k| k.name == name)
}

/// Arithmetic ops of a region per unit class.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UnitMix {
    pub adder: usize,
    pub multiplier: usize,
    pub divsqrt: usize,
}

/// How the arithmetic ops of `region` split over the unit classes.
pub fn unit_mix(kernel: &Kernel, region: Region) -> UnitMix {
    let mut mix = UnitMix::default();
    for d in kernel.nodes.iter().filter(|d| d.region == region) {
        if let Node::Op { op, .. } = d.node {
            match op.unit() {
                UnitClass::Adder => mix.adder += 1,
                UnitClass::Multiplier => mix.multiplier += 1,
                UnitClass::DivSqrt => mix.divsqrt += 1,
            }
        }
    }
    mix
}

/// Checks a kernel the library built (a failure is a bug of the library).
fn finish(b: crate::kernel::KernelBuilder) -> Kernel {
    match b.finish() {
        Ok(k) => k,
        Err(e) => panic!("library kernel does not verify: {e}"),
    }
}

/// An fp32 uniform in `[lo, hi)` (as bits).
fn uniform(rng: &mut SplitMix64, lo: f32, hi: f32) -> f32 {
    let unit = (rng.next_u32() >> 8) as f32 / (1u32 << 24) as f32;
    lo + (hi - lo) * unit
}

/// `n` fp32 uniforms in `[lo, hi)` as words.
fn uniform_words(rng: &mut SplitMix64, n: usize, lo: f32, hi: f32) -> Vec<u32> {
    (0..n).map(|_| uniform(rng, lo, hi).to_bits()).collect()
}

/// Lays records of `k` words out as a word stream for `clusters` clusters: element `e`'s
/// word `j` goes to `(e / C)·k·C + j·C + e mod C` (the record count must be a multiple of
/// `C`).
pub fn records_to_stream(records: &[Vec<u32>], clusters: usize) -> Vec<u32> {
    let k = records.first().map_or(0, Vec::len);
    assert!(
        records.len().is_multiple_of(clusters),
        "{} records do not fill rows of {clusters}",
        records.len()
    );
    let mut out = vec![0; records.len() * k];
    for (e, r) in records.iter().enumerate() {
        assert_eq!(r.len(), k, "records of different lengths");
        for (j, &w) in r.iter().enumerate() {
            out[(e / clusters) * k * clusters + j * clusters + e % clusters] = w;
        }
    }
    out
}

/// The inverse of [`records_to_stream`]: the records of `k` words of a word stream.
pub fn stream_to_records(words: &[u32], k: usize, clusters: usize) -> Vec<Vec<u32>> {
    assert!(
        words.len().is_multiple_of(k * clusters),
        "{} words do not fill rows of {clusters} records of {k} words",
        words.len()
    );
    let n = words.len() / k;
    (0..n)
        .map(|e| {
            (0..k)
                .map(|j| words[(e / clusters) * k * clusters + j * clusters + e % clusters])
                .collect()
        })
        .collect()
}

/// `word` with channel `channel` (0 red … 3 alpha) of an RGBA8 colour set from `c` in
/// [0, 1]: `⌊c·255 + ½⌋` (`scale` = 255, `half` = ½) shifted into its byte and or-ed in.
pub(crate) fn or_channel(
    b: &mut crate::kernel::KernelBuilder,
    word: crate::kernel::Value,
    c: crate::kernel::Value,
    channel: usize,
    (half, scale): (crate::kernel::Value, crate::kernel::Value),
) -> crate::kernel::Value {
    let c = b.fmul(c, scale);
    let c = b.fadd(c, half);
    let byte = b.ftoi_trunc(c);
    let shift = b.i32(8 * channel as i32);
    let byte = b.shl(byte, shift);
    b.or(word, byte)
}

/// Three values: a point, a direction or a colour.
pub(crate) type Vec3 = [crate::kernel::Value; 3];

/// `u · v` in the order the references use: `(u0·v0 + u1·v1) + u2·v2`.
pub(crate) fn dot(b: &mut crate::kernel::KernelBuilder, u: Vec3, v: Vec3) -> crate::kernel::Value {
    let xx = b.fmul(u[0], v[0]);
    let yy = b.fmul(u[1], v[1]);
    let sum = b.fadd(xx, yy);
    let zz = b.fmul(u[2], v[2]);
    b.fadd(sum, zz)
}

/// `floor(x)` (int32) and `x − floor(x)` (fp32): `ftoi32_trunc`, back to fp32, one less
/// where that rounded up (negative non-integers); for |x| < 2^31.
pub(crate) fn floor_and_offset(
    b: &mut crate::kernel::KernelBuilder,
    x: crate::kernel::Value,
) -> (crate::kernel::Value, crate::kernel::Value) {
    use crate::kernel::Ty;
    let truncated = b.ftoi_trunc(x);
    let truncated_f = b.itof(truncated);
    let rounded_up = b.flt(x, truncated_f);
    let rounded_up = b.cast(rounded_up, Ty::I32);
    let floor = b.isub(truncated, rounded_up);
    let floor_f = b.itof(floor);
    let offset = b.fsub(x, floor_f);
    (floor, offset)
}
