//! The Reyes pipeline: its kernels on the clocked machine against their interpretation,
//! its refusals, and small frames (coverage with no cracks, counts, textures).
//!
//! Every frame here is [`W`]×[`W`] pixels, so that the frames' kernels are the same
//! microcode. The tests that need `subdiv` compiled are `#[ignore]`d: cold, compiling it
//! takes minutes (warm, from the compile cache under `target/`, the textured frames take
//! about a minute, the rest seconds). Run them with `cargo test -p imagine-pipelines --test reyes -- --include-ignored`;
//! they compile every frame kernel once per test process ([`frame_cache`]) before any of
//! them runs.

use imagine_pipelines::compile::{CompileCache, Compiled};
use imagine_pipelines::kernel::KernelInputs;
use imagine_pipelines::kernels::records_to_stream;
use imagine_pipelines::reyes::frame::{self, BezierPatch, ReyesOptions};
use imagine_pipelines::reyes::kernels::{self, PATCH_WORDS, Records};
use imagine_pipelines::run::check;
use imagine_units::desc::MachineDesc;

fn reyes() -> MachineDesc {
    MachineDesc::resolve("reyes").expect("built-in machine")
}

/// The window of every frame and of `sample`'s check.
const W: u32 = 44;

fn cache() -> CompileCache {
    CompileCache::at(concat!(env!("CARGO_TARGET_TMPDIR"), "/compile-cache"))
}

/// The compile cache, with every kernel of a frame compiled into it once (two at a time),
/// so that tests running at once do not each compile `subdiv`.
fn frame_cache() -> CompileCache {
    static WARM: std::sync::OnceLock<()> = std::sync::OnceLock::new();
    let cache = cache();
    WARM.get_or_init(|| {
        let desc = reyes();
        let shape = imagine_pipelines::opengl::kernels::FrameShape {
            width: W,
            height: W,
            clusters: desc.cluster.count,
            cull: imagine_pipelines::scene::model::Cull::None,
            depth_test: imagine_pipelines::scene::model::DepthTest::Less,
            batch: desc.cluster.count,
            blend: imagine_pipelines::scene::model::Blend::None,
        };
        use imagine_pipelines::opengl::kernels as gl;
        let all = vec![
            kernels::subdiv(&desc, Records::default()).unwrap(),
            kernels::project(&desc, Records::default()).unwrap(),
            kernels::subdiv_split(&desc, Records::default()).unwrap(),
            kernels::shade(&desc, kernels::Shading::Flat).unwrap(),
            kernels::sample(&desc, W, W, 1.5, false).unwrap(),
            gl::hash(&desc, shape).unwrap(),
            gl::zcompare(&desc, shape).unwrap(),
            gl::compact_recycle(&desc, [gl::NULL_DEPTH, 0]).unwrap(),
            gl::compact_recycle(&desc, [shape.trash(), 0]).unwrap(),
            gl::clear(&desc).unwrap(),
        ];
        // `subdiv` on one thread, the rest on another.
        let (first, rest) = all.split_at(1);
        std::thread::scope(|s| {
            s.spawn(|| {
                cache.compile(&first[0], &desc).unwrap();
            });
            for k in rest {
                cache.compile(k, &desc).unwrap_or_else(|e| panic!("{e}"));
            }
        });
    });
    cache
}

fn compiled(k: &imagine_pipelines::kernel::Kernel, desc: &MachineDesc) -> Compiled {
    cache().compile(k, desc).unwrap_or_else(|e| panic!("{e}"))
}

/// `k` on the machine equals its interpretation on `inputs` word for word (`what` names it
/// in the failure); the interpretation's streams.
fn machine_as_interpreted(
    k: &imagine_pipelines::kernel::Kernel,
    inputs: &KernelInputs,
    desc: &MachineDesc,
    what: &str,
) -> Vec<Vec<u32>> {
    let r = check(k, &compiled(k, desc), desc, inputs).unwrap();
    assert!(r.mismatch.is_none(), "{what}: {}", r.mismatch.unwrap());
    imagine_pipelines::kernel::interpret(k, inputs, desc).unwrap()
}

/// A bilinear-ish Bezier patch: the grid `x0 + col·dx`, `y0 + row·dy`, with the inner
/// points lifted in z by `bulge` (window space when the matrix is the identity).
fn grid(x0: f32, y0: f32, dx: f32, dy: f32, bulge: f32) -> BezierPatch {
    std::array::from_fn(|k| {
        let (r, c) = ((k / 4) as f32, (k % 4) as f32);
        let inner = (1.0..=2.0).contains(&r) && (1.0..=2.0).contains(&c);
        [x0 + c * dx, y0 + r * dy, if inner { bulge } else { 0.0 }]
    })
}

/// The matrix that takes window pixels (x, y) and depth z in [0, 1] to clip space, for a
/// `w × h` window.
fn window_to_clip(w: u32, h: u32) -> [f32; 16] {
    imagine_pipelines::scene::window_to_clip(w, h)
}

/// The quad records of a `shade` output stream.
fn shaded_quads(stream: &[u32], desc: &MachineDesc) -> impl Iterator<Item = Vec<u32>> {
    imagine_pipelines::kernels::stream_to_records(stream, kernels::QUAD_WORDS, desc.cluster.count)
        .into_iter()
        .filter(|r| r[kernels::Q_FLAGS] & kernels::FLAG_QUAD != 0)
}

fn patch_record(p: &BezierPatch, colour: u32) -> Vec<u32> {
    let mut r: Vec<u32> = p.iter().flatten().map(|v| v.to_bits()).collect();
    r.push(colour);
    r.push(1);
    r
}

/// A patch record with a place (textured frames): cell `(u, v)` as `u | v << 16`.
fn placed_record(p: &BezierPatch, colour: u32, place: u32) -> Vec<u32> {
    let mut r = patch_record(p, colour);
    r.push(place);
    r
}

/// `subdiv`'s inputs for fresh walks of `patches` (a record per cluster, with `records`'
/// shape), `iterations` quads a cluster, at stop length `stop`.
fn walk_inputs(
    records: Records,
    patches: &[Vec<u32>],
    iterations: usize,
    stop: f32,
    c: usize,
) -> KernelInputs {
    KernelInputs {
        streams: vec![
            vec![0; records.state_words() * c],
            records_to_stream(patches, c),
            vec![0; iterations * c],
            Vec::new(),
            Vec::new(),
        ],
        params: vec![(stop * stop).to_bits()],
    }
}

#[test]
#[ignore = "compiles `subdiv_split`: minutes cold"]
fn subdiv_split_machine_equals_interpretation() {
    let desc = reyes();
    let c = desc.cluster.count;
    let records: Vec<Vec<u32>> = (0..2 * c)
        .map(|i| patch_record(&grid(i as f32, 1.0, 0.5, 0.25, 0.1), i as u32))
        .collect();
    let split = kernels::subdiv_split(&desc, Records::default()).unwrap();
    let inputs = KernelInputs {
        streams: vec![records_to_stream(&records, c), Vec::new()],
        params: vec![],
    };
    let _ = frame_cache();
    let r = check(&split, &compiled(&split, &desc), &desc, &inputs).unwrap();
    assert!(
        r.mismatch.is_none(),
        "subdiv_split: {}",
        r.mismatch.unwrap()
    );
    assert_eq!(r.words, 2 * c * 4 * PATCH_WORDS);

    // With places: each child's is its parent's cell, doubled, plus its quadrant.
    let placed = Records { places: true };
    let records: Vec<Vec<u32>> = (0..2 * c)
        .map(|i| {
            let place = (i as u32 % 3) | (i as u32 % 2) << 16;
            placed_record(&grid(i as f32, 1.0, 0.5, 0.25, 0.1), 5, place)
        })
        .collect();
    let split = kernels::subdiv_split(&desc, placed).unwrap();
    let inputs = KernelInputs {
        streams: vec![records_to_stream(&records, c), Vec::new()],
        params: vec![],
    };
    let r = check(&split, &compiled(&split, &desc), &desc, &inputs).unwrap();
    assert!(r.mismatch.is_none(), "{}", r.mismatch.unwrap());
    let out = imagine_pipelines::kernel::interpret(&split, &inputs, &desc).unwrap();
    let words = placed.patch_words();
    let children = imagine_pipelines::kernels::stream_to_records(&out[1], 4 * words, c);
    for (parent, kids) in records.iter().zip(&children) {
        let (u, v) = (parent[PATCH_WORDS] & 0xFFFF, parent[PATCH_WORDS] >> 16);
        for (k, kid) in kids.chunks(words).enumerate() {
            let (row, col) = (k as u32 / 2, k as u32 % 2);
            assert_eq!(kid[PATCH_WORDS], (2 * u + col) | (2 * v + row) << 16);
        }
    }
}

#[test]
#[ignore = "compiles `subdiv`: minutes cold"]
fn subdiv_machine_equals_interpretation() {
    let desc = reyes();
    let c = desc.cluster.count;
    let k = kernels::subdiv(&desc, Records::default()).unwrap();
    let _ = frame_cache();
    let compiled = compiled(&k, &desc);
    // Patches of different sizes, so the clusters' walks differ; one inactive.
    let mut records: Vec<Vec<u32>> = (0..c - 1)
        .map(|i| {
            let s = 1.0 + i as f32;
            patch_record(
                &grid(3.0 * i as f32, 2.0, s, 0.7 * s, 0.3),
                0xFF00_0000 + i as u32,
            )
        })
        .collect();
    records.push(vec![0; PATCH_WORDS]);
    let inputs = walk_inputs(Records::default(), &records, 40, 1.5, c);
    let r = check(&k, &compiled, &desc, &inputs).unwrap();
    assert!(r.mismatch.is_none(), "{}", r.mismatch.unwrap());
    assert!(r.words > 40 * c * kernels::QUAD_WORDS);

    // With places (a textured frame's records): the same walks, each record one word more.
    let placed = Records { places: true };
    let k = kernels::subdiv(&desc, placed).unwrap();
    let records: Vec<Vec<u32>> = records
        .iter()
        .enumerate()
        .map(|(i, r)| [r.as_slice(), &[i as u32]].concat())
        .collect();
    let inputs = walk_inputs(placed, &records, 40, 1.5, c);
    let r = check(&k, &self::compiled(&k, &desc), &desc, &inputs).unwrap();
    assert!(r.mismatch.is_none(), "with places: {}", r.mismatch.unwrap());
}

#[test]
fn project_and_sample_machine_equal_interpretation() {
    let desc = reyes();
    let c = desc.cluster.count;
    let p = kernels::project(&desc, Records::default()).unwrap();
    let records: Vec<Vec<u32>> = (0..2 * c)
        .map(|i| patch_record(&grid(i as f32, 1.0, 0.5, 0.25, 0.1), i as u32))
        .collect();
    let mut params: Vec<u32> = window_to_clip(W, W).iter().map(|v| v.to_bits()).collect();
    params.extend([22.0f32.to_bits(), 22.0f32.to_bits()]);
    let inputs = KernelInputs {
        streams: vec![records_to_stream(&records, c), Vec::new()],
        params,
    };
    let r = check(&p, &compiled(&p, &desc), &desc, &inputs).unwrap();
    assert!(r.mismatch.is_none(), "project: {}", r.mismatch.unwrap());
    assert_eq!(r.words, 2 * c * PATCH_WORDS);
    // With places: passed through.
    let placed = Records { places: true };
    let p = kernels::project(&desc, placed).unwrap();
    let records: Vec<Vec<u32>> = (0..2 * c)
        .map(|i| placed_record(&grid(i as f32, 1.0, 0.5, 0.25, 0.1), 3, i as u32 | 7 << 16))
        .collect();
    let inputs = KernelInputs {
        streams: vec![records_to_stream(&records, c), Vec::new()],
        params: inputs.params.clone(),
    };
    let out = machine_as_interpreted(&p, &inputs, &desc, "project");
    let window = imagine_pipelines::kernels::stream_to_records(&out[1], placed.patch_words(), c);
    for (i, w) in window.iter().enumerate() {
        assert_eq!(w[PATCH_WORDS], i as u32 | 7 << 16);
    }

    // Quads straight from subdiv's interpretation, so that the sampler sees real ones; at
    // stop length 0.5, whose sampler (2×2 centres a quad) compiles in about a second (that
    // of 1.5, 4×4, in minutes: the frames' tests, ignored, run it).
    let stop = 0.5f32;
    let s = kernels::subdiv(&desc, Records::default()).unwrap();
    let patches: Vec<Vec<u32>> = (0..c)
        .map(|i| patch_record(&grid(2.0 + 5.0 * i as f32, 3.0, 1.5, 2.0, 0.5), 7))
        .collect();
    let out = imagine_pipelines::kernel::interpret(
        &s,
        &walk_inputs(Records::default(), &patches, 24, stop, c),
        &desc,
    )
    .unwrap();
    // Shaded, flat and lit (two lights, one specular term), each on the machine as
    // interpreted; the lit quads go on to the sampler.
    let flat = kernels::shade(&desc, kernels::Shading::Flat).unwrap();
    let inputs = KernelInputs {
        streams: vec![out[3].clone(), vec![]],
        params: vec![],
    };
    machine_as_interpreted(&flat, &inputs, &desc, "shade (flat)");
    let lit_shading = kernels::Shading::Lit {
        lights: 2,
        specular: true,
        shininess: 12,
        textured: false,
    };
    let lit = kernels::shade(&desc, lit_shading).unwrap();
    // 2/W, 2/H and a perspective projection's P00, P11, P22, P23 (fov 60°, near 1, far
    // 10), padded; per light its eye-space position, d·d and s·s; then the base colour.
    let own: Vec<f32> = vec![2.0 / W as f32, 2.0 / W as f32, 1.732, 1.732, -1.222, -2.222];
    let mut lights: Vec<f32> = vec![3.0, 4.0, 2.0, 0.6, 0.5, 0.4, 0.3, 0.3, 0.3];
    lights.extend([-5.0, 1.0, -1.0, 0.2, 0.25, 0.3, 0.0, 0.1, 0.2]);
    lights.extend([0.05, 0.05, 0.08]);
    let mut params: Vec<u32> = own.iter().map(|v| v.to_bits()).collect();
    params.resize(kernels::shade_own_rows(&desc, lit_shading), 0);
    params.extend(lights.iter().map(|v| v.to_bits()));
    let inputs = KernelInputs {
        streams: vec![out[3].clone(), vec![]],
        params,
    };
    let shaded = machine_as_interpreted(&lit, &inputs, &desc, "shade (lit)");
    let colours: std::collections::BTreeSet<u32> = shaded_quads(&shaded[1], &desc)
        .map(|r| r[kernels::Q_COLOUR])
        .collect();
    assert!(
        colours.len() > 4,
        "lit quads take their own colours: {colours:?}"
    );

    let sampler = kernels::sample(&desc, W, W, stop, false).unwrap();
    let inputs = KernelInputs {
        streams: vec![shaded[1].clone(), vec![], vec![], vec![], vec![], vec![]],
        params: vec![],
    };
    let golden = machine_as_interpreted(&sampler, &inputs, &desc, "sample");
    assert!(golden[1].len() > c, "the quads cover pixels");

    // Marble: `shade` writes each quad's centre and normal in object space, on the
    // machine as interpreted, and they are the f64 inverse of its window-space corners.
    let marble = kernels::Shading::Marble;
    let shade = kernels::shade(&desc, marble).unwrap();
    // Object space to eye space: a rotation about y, a scale of 2 and a translation.
    let (sin, cos) = (0.6f64, 0.8f64);
    let model_view = [
        [2.0 * cos, 0.0, 2.0 * sin, 0.5],
        [0.0, 2.0, 0.0, -0.25],
        [-2.0 * sin, 0.0, 2.0 * cos, -4.0],
    ];
    // Its inverse: the transposed rotation over the scale, after the translation.
    let to_object: [[f64; 4]; 3] = std::array::from_fn(|r| {
        let column: [f64; 3] = std::array::from_fn(|i| model_view[i][r] / 4.0);
        let t = -(0..3).map(|i| column[i] * model_view[i][3]).sum::<f64>();
        [column[0], column[1], column[2], t]
    });
    let mut params: Vec<u32> = own.iter().map(|v| v.to_bits()).collect();
    params.extend(to_object.iter().flatten().map(|&v| (v as f32).to_bits()));
    params.resize(kernels::shade_own_rows(&desc, marble), 0);
    let inputs = KernelInputs {
        streams: vec![out[3].clone(), vec![], vec![]],
        params,
    };
    let shaded = machine_as_interpreted(&shade, &inputs, &desc, "shade (marble)");
    let quads =
        imagine_pipelines::kernels::stream_to_records(&out[3], kernels::SUBDIV_QUAD_WORDS, c);
    let varyings =
        imagine_pipelines::kernels::stream_to_records(&shaded[2], marble.varyings_words(), c);
    let to_eye_space = |x: f64, y: f64, z: f64| {
        let p: Vec<f64> = own.iter().map(|&v| f64::from(v)).collect();
        let (xn, yn, zn) = (x * p[0] - 1.0, y * p[1] - 1.0, 2.0 * z - 1.0);
        let w = p[5] / (zn + p[4]);
        [xn * w / p[2], yn * w / p[3], -w]
    };
    let apply = |v: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|r| {
            (0..3).map(|i| to_object[r][i] * v[i]).sum::<f64>() + to_object[r][3]
        })
    };
    let mut checked = 0;
    for (q, v) in quads.iter().zip(&varyings) {
        if q[kernels::Q_FLAGS] & kernels::FLAG_QUAD == 0 {
            continue;
        }
        let corner = |k: usize| {
            let w = |i: usize| f64::from(f32::from_bits(q[kernels::Q_CORNERS + 3 * k + i]));
            apply(to_eye_space(w(0), w(1), w(2)))
        };
        let corners: [[f64; 3]; 4] = std::array::from_fn(corner);
        let centre: [f64; 3] =
            std::array::from_fn(|i| corners.iter().map(|c| c[i]).sum::<f64>() / 4.0);
        let got: Vec<f64> = v[3..9]
            .iter()
            .map(|&w| f64::from(f32::from_bits(w)))
            .collect();
        for i in 0..3 {
            assert!(
                (got[i] - centre[i]).abs() < 1e-4,
                "object-space centre {:?}, f64 {centre:?}",
                &got[..3]
            );
        }
        // The normal: along the diagonals' cross product, facing the eye.
        let d1: [f64; 3] = std::array::from_fn(|i| corners[2][i] - corners[0][i]);
        let d2: [f64; 3] = std::array::from_fn(|i| corners[3][i] - corners[1][i]);
        let cross = [
            d1[1] * d2[2] - d1[2] * d2[1],
            d1[2] * d2[0] - d1[0] * d2[2],
            d1[0] * d2[1] - d1[1] * d2[0],
        ];
        let n = &got[3..6];
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let cosine = dot(n, &cross).abs() / (dot(n, n) * dot(&cross, &cross)).sqrt();
        assert!(cosine > 0.999, "normal {n:?} against {cross:?}");
        let eye: Vec<f64> = to_object.iter().map(|r| r[3]).collect();
        let to_eye: Vec<f64> = (0..3).map(|i| eye[i] - got[i]).collect();
        assert!(dot(n, &to_eye) >= 0.0, "the normal faces the eye");
        checked += 1;
    }
    assert!(checked > 8, "{checked} marble quads");

    // Textured: `subdiv` with places (interpreted), `shade` writing varyings, `sample`
    // taking each quad's colour from a stream, both on the machine as interpreted.
    let placed = Records { places: true };
    let s = kernels::subdiv(&desc, placed).unwrap();
    let patches: Vec<Vec<u32>> = (0..c)
        .map(|i| placed_record(&grid(2.0 + 5.0 * i as f32, 3.0, 1.5, 2.0, 0.5), 7, 0))
        .collect();
    let out = imagine_pipelines::kernel::interpret(
        &s,
        &walk_inputs(placed, &patches, 24, stop, c),
        &desc,
    )
    .unwrap();
    let textured = kernels::Shading::Lit {
        lights: 2,
        specular: true,
        shininess: 12,
        textured: true,
    };
    let shade = kernels::shade(&desc, textured).unwrap();
    let split_levels = 1u32;
    let mut params: Vec<u32> = own.iter().map(|v| v.to_bits()).collect();
    params.push(split_levels);
    params.resize(kernels::shade_own_rows(&desc, textured), 0);
    params.extend(lights.iter().map(|v| v.to_bits()));
    let inputs = KernelInputs {
        streams: vec![out[3].clone(), vec![], vec![]],
        params,
    };
    let shaded = machine_as_interpreted(&shade, &inputs, &desc, "shade (textured)");
    // Each quad's (s, t) is its cell's centre: inside the patch's parameter square at
    // the level the record says, plus the breadth-first one.
    let quads =
        imagine_pipelines::kernels::stream_to_records(&out[3], placed.subdiv_quad_words(), c);
    let varyings =
        imagine_pipelines::kernels::stream_to_records(&shaded[2], kernels::SHADE_VARYINGS, c);
    let mut cells = std::collections::BTreeSet::new();
    for (q, v) in quads.iter().zip(&varyings) {
        if q[kernels::Q_FLAGS] & kernels::FLAG_QUAD == 0 {
            continue;
        }
        let place = q[kernels::SUBDIV_QUAD_WORDS];
        let side = 2f32.powi(-((q[kernels::Q_LEVEL] + split_levels) as i32));
        let (u, v_) = ((place & 0xFFFF) as f32, (place >> 16) as f32);
        assert_eq!(
            [f32::from_bits(v[3]), f32::from_bits(v[4])],
            [(u + 0.5) * side, (v_ + 0.5) * side]
        );
        assert!((0.0..=1.0).contains(&f32::from_bits(v[0])));
        cells.insert(place);
    }
    assert!(cells.len() > 8, "quads have their own places: {cells:?}");
    let colours: Vec<u32> = (0..varyings.len() as u32)
        .map(|i| 0xFF00_0000 | i)
        .collect();
    let sampler = kernels::sample(&desc, W, W, stop, true).unwrap();
    let inputs = KernelInputs {
        streams: vec![
            shaded[1].clone(),
            colours,
            vec![],
            vec![],
            vec![],
            vec![],
            vec![],
        ],
        params: vec![],
    };
    machine_as_interpreted(&sampler, &inputs, &desc, "sample (colours)");
}

#[test]
fn subdiv_needs_the_reyes_scratchpad_and_a_good_stop_length() {
    let gold8 = MachineDesc::resolve("gold8").unwrap();
    let e = kernels::subdiv(&gold8, Records::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("subdiv") && e.contains("scratchpad"), "{e}");
    for bad in [0.0, -1.0, f32::NAN, f32::INFINITY, 100.0] {
        let e = frame::check_stop_length(bad).unwrap_err().to_string();
        assert!(
            e.contains("stop length") && e.contains("subdiv"),
            "{bad}: {e}"
        );
    }
}

/// What quads are shaded with: SPOT-CAGE is marble, its `shade` taking the inverse of the
/// model-view matrix; one marble frame has one object space, and mipmapped textures are
/// refused naming the texture.
#[test]
fn the_shading_setup_takes_marble_and_refuses_what_quads_cannot_draw() {
    use imagine_pipelines::scene::model::Filter;
    use imagine_pipelines::scene::{LoadOptions, load, mat_mul};
    let spot = load("SPOT-CAGE", &LoadOptions::default()).unwrap();
    let setup = frame::ShadeSetup::of(&spot, 8).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(setup.shading, kernels::Shading::Marble);
    assert!(setup.perlight.is_none());
    let t = setup.texturing.as_ref().expect("marble's fragment program");
    assert_eq!(t.kernel_name(), "marble");
    assert_eq!(
        t.marble_params.len(),
        imagine_pipelines::kernels::turbulence::SCALAR_PARAMS
    );
    // The transform's rows times the model-view are the identity's rows.
    assert_eq!(setup.params.len(), 6 + kernels::TO_OBJECT_WORDS);
    let to_object: Vec<f64> = setup.params[6..]
        .iter()
        .map(|&w| f64::from(f32::from_bits(w)))
        .collect();
    let object = &spot.objects[0];
    let mv = mat_mul(&spot.camera_for(object).view, &object.model);
    for r in 0..3 {
        for c in 0..4 {
            let product: f64 = (0..4)
                .map(|k| to_object[4 * r + k] * f64::from(mv[4 * k + c]))
                .sum();
            let identity = if r == c { 1.0 } else { 0.0 };
            assert!((product - identity).abs() < 1e-5, "({r}, {c}): {product}");
        }
    }

    let mut two = spot.clone();
    let mut moved = two.objects[0].clone();
    moved.name = "moved".into();
    moved.model[3] += 1.0;
    two.objects.push(moved);
    let e = frame::ShadeSetup::of(&two, 8).unwrap_err().to_string();
    assert!(
        e.contains("`spot`") && e.contains("`moved`") && e.contains("marble"),
        "{e}"
    );

    let mut pin = load("PIN-PATCHES", &LoadOptions::default()).unwrap();
    assert!(frame::ShadeSetup::of(&pin, 8).unwrap().shading.textured());
    pin.textures[0].filter = Filter::Trilinear;
    let e = frame::ShadeSetup::of(&pin, 8).unwrap_err().to_string();
    assert!(
        e.contains(&format!("`{}`", pin.textures[0].name)) && e.contains("mipmapped"),
        "{e}"
    );
}

/// Two patches that share a curved edge, one five times wider than the other (so their
/// quads along the edge come from different levels), whose union is the square
/// [4, 40]²: every pixel centre inside it is covered, none outside.
#[test]
#[ignore = "compiles `subdiv`: minutes cold"]
fn shared_edges_at_different_depths_leave_no_crack() {
    let desc = reyes();
    // Column 3 of `a` is column 0 of `b`: x = 34 at the corners, bowed to 37 inside.
    let seam = |r: usize| if r == 1 || r == 2 { 37.0 } else { 34.0 };
    let a: BezierPatch = std::array::from_fn(|k| {
        let (r, c) = (k / 4, k % 4);
        let y = 4.0 + 12.0 * r as f32;
        let x = if c == 3 {
            seam(r)
        } else {
            4.0 + 10.0 * c as f32
        };
        // A warp inside, so that the map is not affine.
        let (x, y) = if (1..=2).contains(&r) && (1..=2).contains(&c) {
            (x + 3.0, y - 2.0)
        } else {
            (x, y)
        };
        [x, y, 0.25 + 0.01 * c as f32]
    });
    let b: BezierPatch = std::array::from_fn(|k| {
        let (r, c) = (k / 4, k % 4);
        let y = 4.0 + 12.0 * r as f32;
        let x = if c == 0 {
            seam(r)
        } else {
            34.0 + 2.0 * c as f32
                + if c < 3 && (r == 1 || r == 2) {
                    1.0
                } else {
                    0.0
                }
        };
        [x, y, 0.5]
    });
    let (w, h) = (W, W);
    let m = window_to_clip(w, h);
    // As many iterations a call as the SRF holds (`iterations_for`).
    let options = ReyesOptions {
        cache: frame_cache(),
        ..ReyesOptions::default()
    };
    let f = frame::render_patches(
        &[(a, m, 0xFF00_00FF), (b, m, 0xFF00_FF00)],
        &frame::ShadeSetup::flat(),
        w,
        h,
        0,
        &desc,
        &options,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let mut holes = Vec::new();
    let mut spill = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let (cx, cy) = (x as f32 + 0.5, y as f32 + 0.5);
            let drawn = f.colour[(y * w + x) as usize] != 0;
            let inside = (4.05..=39.95).contains(&cx) && (4.05..=39.95).contains(&cy);
            let outside = !((3.7..=40.3).contains(&cx) && (3.7..=40.3).contains(&cy));
            if inside && !drawn {
                holes.push((x, y));
            }
            if outside && drawn {
                spill.push((x, y));
            }
        }
    }
    assert!(holes.is_empty(), "uncovered pixels inside: {holes:?}");
    assert!(spill.is_empty(), "covered pixels outside: {spill:?}");
    let s = &f.stats;
    assert!(s.quads > 500, "{s:?}");
    // Every quad once: a leaf of level l is one of the 4^l of its patch.
    let bound: u64 = s
        .levels
        .iter()
        .enumerate()
        .map(|(l, _)| 2 * 4u64.pow(l as u32))
        .max()
        .unwrap();
    assert!(
        s.quads <= bound,
        "{} quads from two patches of at most {} levels",
        s.quads,
        s.levels.len()
    );
    // Calls of a few iterations (each walk saved and resumed many times, one patch done
    // long before the other) give the same quads and the same image.
    let short = ReyesOptions {
        iterations: Some(5),
        ..options.clone()
    };
    let g = frame::render_patches(
        &[(a, m, 0xFF00_00FF), (b, m, 0xFF00_FF00)],
        &frame::ShadeSetup::flat(),
        w,
        h,
        0,
        &desc,
        &short,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(g.stats.quads, s.quads);
    assert_eq!(g.stats.levels, s.levels);
    assert_eq!(g.colour, f.colour);
    assert!(
        g.stats
            .kernels
            .iter()
            .find(|k| k.kernel == "subdiv")
            .unwrap()
            .calls
            > 10
    );
    assert!(s.levels.len() >= 6, "levels {:?}", s.levels);
    assert_eq!(s.visible_pixels, 36 * 36);
    assert!(s.zero_pixel_quads > 0 && s.zero_pixel_quads < s.quads);
    assert!(s.kernel_cycles("subdiv") > 0 && s.cycles > s.kernel_cycles("subdiv"));
    // A breadth-first level first: eight patches, still no crack.
    let split = ReyesOptions {
        split_levels: Some(1),
        ..options.clone()
    };
    let g = frame::render_patches(
        &[(a, m, 0xFF00_00FF), (b, m, 0xFF00_FF00)],
        &frame::ShadeSetup::flat(),
        w,
        h,
        0,
        &desc,
        &split,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let holes = (0..w * h)
        .filter(|&p| {
            let (cx, cy) = ((p % w) as f32 + 0.5, (p / w) as f32 + 0.5);
            (4.05..=39.95).contains(&cx)
                && (4.05..=39.95).contains(&cy)
                && g.colour[p as usize] == 0
        })
        .count();
    assert_eq!(holes, 0);
    assert!(g.stats.quads >= s.quads && g.stats.levels[0] == 0);
}

/// A patch 1,800 pixels across at stop length 1.5 needs 11 levels: more frames than the
/// scratchpad holds. The frame stops with an error naming the kernel and the scratchpad.
#[test]
#[ignore = "compiles `subdiv`: minutes cold"]
fn a_walk_deeper_than_the_stack_is_an_error() {
    let desc = reyes();
    let (w, h) = (W, W);
    let m = window_to_clip(w, h);
    let options = ReyesOptions {
        cache: frame_cache(),
        ..ReyesOptions::default()
    };
    let e = frame::render_patches(
        &[(grid(0.0, 0.0, 600.0, 600.0, 0.0), m, 1)],
        &frame::ShadeSetup::flat(),
        w,
        h,
        0,
        &desc,
        &options,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("`subdiv`") && e.contains("scratchpad.words") && e.contains("7 frames"),
        "{e}"
    );
}

/// PIN-PATCHES (a lit material with two point-sampled textures, modulated) through Reyes
/// at W×W, against the same scene with its textures taken away: the textured frame's
/// walks carry places, its quads go through the fragment program, yet its quads, levels
/// and depths are the untextured frame's exactly (texturing changes no geometry); no
/// channel of a pixel is brighter than untextured beyond rounding (modulating by texels of
/// at most 1); and the red bands show (pixels whose red is over twice their green).
#[test]
#[ignore = "compiles the textured `subdiv` and `sample`: minutes cold"]
fn textured_quads_take_their_texels_and_keep_their_geometry() {
    use imagine_pipelines::scene::{LoadOptions, load};
    let desc = reyes();
    let scene = |textured: bool| {
        let mut s = load(
            "PIN-PATCHES",
            &LoadOptions {
                size: Some(W),
                subdivisions: None,
                filter: None,
            },
        )
        .unwrap();
        if !textured {
            s.materials[0].textures.clear();
        }
        s
    };
    let options = ReyesOptions {
        cache: frame_cache(),
        ..ReyesOptions::default()
    };
    let plain = frame::render(&scene(false), &desc, &options).unwrap_or_else(|e| panic!("{e}"));
    let textured = frame::render(&scene(true), &desc, &options).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(textured.stats.quads, plain.stats.quads);
    assert_eq!(textured.stats.levels, plain.stats.levels);
    assert_eq!(textured.depth, plain.depth);
    assert!(textured.stats.texel_words > 0 && plain.stats.texel_words == 0);
    let channel = |w: u32, c: u32| (w >> (8 * c)) & 0xFF;
    let mut red = 0;
    for (&t, &p) in textured.colour.iter().zip(&plain.colour) {
        for c in 0..3 {
            assert!(
                channel(t, c) <= channel(p, c) + 1,
                "{t:08x} brighter than {p:08x}"
            );
        }
        if channel(t, 0) > 2 * channel(t, 1) {
            red += 1;
        }
    }
    assert!(red > 0, "no band shows");
}
