//! Helpers shared by the fuzz targets of `fuzz_targets/`: gold8 parsed once per process,
//! deterministic inputs for the simulations, the invariants loaded scenes keep, and the
//! seeds the targets make themselves (see `.ci/fuzz`).

use std::path::PathBuf;
use std::sync::OnceLock;

use imagine_units::desc::MachineDesc;
use imagine_units::microcode::{Program, StreamDir};

/// Core cycles a fuzzed simulation may take: a few thousand, then it is given up.
pub const MAX_CYCLES: u64 = 4000;

/// gold8, parsed once per process.
pub fn gold8() -> &'static MachineDesc {
    static DESC: OnceLock<MachineDesc> = OnceLock::new();
    DESC.get_or_init(MachineDesc::gold8)
}

/// The text of a fuzz input, or `None` for bytes that are not UTF-8 (text parsers are
/// given `&str` by their callers).
pub fn text(data: &[u8]) -> Option<&str> {
    std::str::from_utf8(data).ok()
}

/// The source tree's root (the parent of `fuzz/`).
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("fuzz/ sits in the source tree")
        .to_path_buf()
}

/// Deterministic words for the input streams of `program`: `len` each, a mix of small
/// floats, negatives and integers.
pub fn input_streams(program: &Program, len: usize) -> Vec<Vec<u32>> {
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    program
        .streams
        .iter()
        .filter(|s| s.dir == StreamDir::In)
        .map(|_| {
            (0..len)
                .map(|i| {
                    state = state
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    match i % 4 {
                        0 => (i as f32 - 8.0).to_bits(),
                        1 => i as u32,
                        _ => ((state >> 40) as u32 & 0x007F_FFFF) | 0x3F00_0000,
                    }
                })
                .collect()
        })
        .collect()
}

/// What every scene the loaders return guarantees the renderer: each object's material
/// exists and its mesh keeps [`assert_mesh_invariants`].
pub fn assert_scene_invariants(scene: &imagine_pipelines::scene::model::Scene) {
    for o in &scene.objects {
        assert_mesh_invariants(&o.mesh);
        assert!(o.material < scene.materials.len(), "object `{}`", o.name);
    }
}

/// Per-vertex arrays as long as the positions or empty, triangles naming existing vertices.
pub fn assert_mesh_invariants(m: &imagine_pipelines::scene::model::Mesh) {
    let n = m.positions.len();
    for len in [m.normals.len(), m.colours.len(), m.texcoords.len()] {
        assert!(
            len == 0 || len == n,
            "{len} per-vertex values for {n} vertices"
        );
    }
    for t in &m.triangles {
        assert!(t.iter().all(|&i| (i as usize) < n), "triangle {t:?} of {n}");
    }
}

/// The environment variable that makes a target write its generated seeds and exit.
pub const SEEDS_VAR: &str = "IMAGINE_FUZZ_SEEDS";

/// Seeds that have no file in the source tree are made by the targets themselves, from
/// the project's own code (microcode images of the example programs, DRAM traces of the
/// microbenchmarks, …): run with `IMAGINE_FUZZ_SEEDS=DIR`, a target calls this from its
/// `init`, writes `seeds()` into `DIR` and exits before fuzzing. `.ci/fuzz` does this to
/// build each target's seed corpus.
pub fn write_seeds_if_asked(seeds: impl FnOnce() -> Vec<(String, Vec<u8>)>) {
    let Some(dir) = std::env::var_os(SEEDS_VAR) else {
        return;
    };
    let dir = PathBuf::from(dir);
    std::fs::create_dir_all(&dir).expect("cannot create the seed directory");
    for (name, bytes) in seeds() {
        std::fs::write(dir.join(&name), bytes).expect("cannot write a seed");
    }
    std::process::exit(0);
}

/// The example programs of `units/tests/microcode/`, by name.
pub const EXAMPLE_PROGRAMS: [(&str, &str); 7] = [
    (
        "cond_input",
        include_str!("../../units/tests/microcode/cond_input.uc"),
    ),
    (
        "filter",
        include_str!("../../units/tests/microcode/filter.uc"),
    ),
    (
        "lookup",
        include_str!("../../units/tests/microcode/lookup.uc"),
    ),
    ("madd", include_str!("../../units/tests/microcode/madd.uc")),
    (
        "plus1_passes",
        include_str!("../../units/tests/microcode/plus1_passes.uc"),
    ),
    (
        "prefix_sum",
        include_str!("../../units/tests/microcode/prefix_sum.uc"),
    ),
    (
        "saxpy",
        include_str!("../../units/tests/microcode/saxpy.uc"),
    ),
];

/// The directory the scene targets read a scene's assets from (a scene's OBJ, `.bpt` and
/// PNG files are named relative to its file): made once per process under the system's
/// temporary directory, with the OBJ meshes of `verif/tests/scenes/`, two patch files and
/// two small PNG textures, so that mutated scenes reach every kind of asset. Scene files
/// themselves are fuzzed; the assets are fixed (their parsers have targets of their own).
pub fn scene_assets() -> &'static std::path::Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        // One directory per source tree (worktrees fuzz side by side); files are written
        // under a temporary name and renamed into place.
        let tree = repo_root().display().to_string();
        let tag = tree.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
        });
        let dir = std::env::temp_dir().join(format!("imagine-fuzz-assets-{tag:016x}"));
        std::fs::create_dir_all(&dir).expect("cannot create the asset directory");
        let put = |name: &str, bytes: Vec<u8>| {
            let tmp = dir.join(format!(".{name}.{}", std::process::id()));
            std::fs::write(&tmp, bytes).expect("cannot write an asset");
            std::fs::rename(&tmp, dir.join(name)).expect("cannot rename an asset");
        };
        let scenes = repo_root().join("verif/tests/scenes");
        for obj in ["teapot.obj", "suzanne.obj", "woody.obj"] {
            put(
                obj,
                std::fs::read(scenes.join(obj)).expect("an OBJ of verif/tests/scenes"),
            );
        }
        for (name, text) in bpt_seeds() {
            put(&name, text.into_bytes());
        }
        put(
            "rgba.png",
            png_bytes(4, 4, png::ColorType::Rgba, png::BitDepth::Eight),
        );
        put(
            "grey16.png",
            png_bytes(3, 2, png::ColorType::Grayscale, png::BitDepth::Sixteen),
        );
        dir
    })
}

fn png_bytes(w: u32, h: u32, colour: png::ColorType, depth: png::BitDepth) -> Vec<u8> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, w, h);
    enc.set_color(colour);
    enc.set_depth(depth);
    let bytes = (w * h) as usize * colour.samples() * (depth as usize).div_ceil(8);
    let data: Vec<u8> = (0..bytes).map(|i| (i * 37) as u8).collect();
    let mut writer = enc.write_header().expect("a PNG header");
    writer.write_image_data(&data).expect("PNG data");
    writer.finish().expect("a PNG");
    out
}

/// `.bpt` files: a flat patch, a bumped one with a pole (a row of coincident points, like
/// the top of the teapot's lid), and both with comments.
pub fn bpt_seeds() -> Vec<(String, String)> {
    let patch = |z: &dyn Fn(usize, usize) -> f64, pole: bool| {
        let mut s = String::from("3 3\n");
        for row in 0..4 {
            for col in 0..4 {
                let x = if pole && row == 3 { 1.5 } else { col as f64 };
                s += &format!("{x} {row} {}\n", z(row, col));
            }
        }
        s
    };
    let flat = patch(&|_, _| 0.0, false);
    let bumped = patch(&|r, c| ((r * c) as f64 - 2.0) * 0.25, true);
    vec![
        ("flat.bpt".into(), format!("1\n{flat}")),
        ("pole.bpt".into(), format!("1\n{bumped}")),
        (
            "two.bpt".into(),
            format!("# two patches\n2\n{flat}\n# the second\n{bumped}"),
        ),
    ]
}

/// Scene files that reach what the files of `scenes/` and `verif/tests/scenes/` do not:
/// the other primitives, patches, textures (procedural and PNG), orthographic and matrix
/// cameras, per-object transforms, and the settings the renderer refuses.
pub fn scene_seeds() -> Vec<(String, Vec<u8>)> {
    let scenes = [
        (
            "uv_sphere.toml",
            r#"name = "uv"
ambient = [0.1, 0.1, 0.1]
[window]
width = 64
height = 48
background = [0.2, 0.3, 0.4]
[camera]
eye = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
ortho = [-2.0, 2.0, -1.5, 1.5, 0.5, 10.0]
[pipeline]
depth_test = "always"
cull = "front"
stop_length = 2.0
[[light]]
position = [1.0, 2.0, 3.0]
[[texture]]
name = "check"
procedural = { kind = "checker", size = 64, cells = 4, colours = [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]] }
filter = "linear"
wrap = "clamp"
[[texture]]
name = "photo"
image = "rgba.png"
[[material]]
name = "m"
shader = "lit"
shininess = 8.0
textures = ["check", "photo"]
texture_mode = "replace"
[[object]]
primitive = { kind = "uv_sphere", rings = 6, segments = 8 }
material = "m"
translate = [0.5, 0.0, 0.0]
rotate = [30.0, 1.0, 0.0, 0.0]
scale = [1.0, 2.0, 1.0]
triangles = "separate"
"#,
        ),
        (
            "patches.toml",
            r#"name = "patches"
[window]
width = 32
height = 32
[camera]
modelview = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, -5.0, 0.0, 0.0, 0.0, 1.0]
projection = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.2, -2.2, 0.0, 0.0, -1.0, 0.0]
[pipeline]
kind = "opengl"
depth_test = "lequal"
blend = "none"
[[texture]]
name = "grey"
image = "grey16.png"
filter = "trilinear"
[[object]]
name = "flat"
patches = "flat.bpt"
tessellate = 3
basis = "bspline"
colour = [0.5, 0.5, 1.0]
[[object]]
patches = "two.bpt"
tessellate = 2
"#,
        ),
        (
            "rate.toml",
            r#"[window]
width = 40
height = 20
[pipeline]
blend = "alpha"
kind = "reyes"
cull = "none"
[[object]]
primitive = { kind = "rate", size = 4 }
triangles = "shared"
[[object]]
primitive = { kind = "icosphere", subdivisions = 1 }
cage = "cage.obj"
"#,
        ),
    ];
    scenes
        .map(|(n, t)| (n.to_string(), t.as_bytes().to_vec()))
        .to_vec()
}

/// A program for gold8 that uses every op on its unit, every slot kind (scratchpad loads
/// and stores, each kind of intercluster permutation, conditional stream accesses) and
/// every kind of loop, as a seed beside the example programs.
pub fn every_op_program() -> String {
    use imagine_units::ops::{Op, UnitClass};
    let mut s = String::from("kernel every_op\nin x\nin y\nout z\n\n");
    s += "    imm 1.5 -> add0.a[0], add0.b[0] | sp0 ld 3 -> mul0.a[0]\n";
    s += "    imm cid -> comm0.perm[0], sp0.addr[0]\n";
    s += "    imm 0x7f -> mul0.b[0], dsq0.a[0]\n    imm 3e-2 -> dsq0.b[0], sp0.data[1]\n";
    s += "    imm -2 -> add1.a[0], add1.b[0] | sp0 st 8, addr[0], data[1]\n";
    for &op in Op::ALL {
        let unit = match op.unit() {
            UnitClass::Adder => "add0",
            UnitClass::Multiplier => "mul0",
            UnitClass::DivSqrt => "dsq0",
        };
        let operands = match op.arity() {
            1 => "a[0]",
            2 => "a[0], b[0]",
            _ => "cc[0], a[0], b[0]",
        };
        s += &format!("    {unit} {} {operands} -> add1.a[1], cc[1]\n", op.name());
    }
    s += "    comm0 data[0], rotate 1 -> add1.b[2]\n    comm0 data[0], perm[0] -> add0.a[3]\n";
    s += "    comm0 data[0], xor 2 -> add1.b[3]\n    comm0 data[0], bcast 5 -> add1.b[4]\n";
    s += "loop count 3, stages 2:\n    sin0 x -> add0.a[2] | add0 fadd a[2], b[0] -> stream z @1\n";
    s += "pass\n    sin0 x if cc[1] -> add0.a[2]\n    sout z, data[0] if cc[1] @1\nend\n";
    s += "loop stream y:\n    sin1 y -> sout.data[0]\n    nop\n    nop\n    nop\n";
    s += "    sout z, data[0]\nend\n";
    s += "loop until cc[2]:\n    add0 ieq a[0], b[0] -> cc[2]\n    nop\n    nop\nend\ndone\n";
    s
}
