//! The OpenGL pipeline's kernels compile on every machine shape (through the tests'
//! compile cache under `target/tmp`, keyed by the compiler's fingerprint).

use imagine_pipelines::compile::{CompileCache, CompileError, Compiled};
use imagine_pipelines::kernels::{records_to_stream, stream_to_records};
use imagine_pipelines::opengl::kernels::{self, FrameShape, Varyings};
use imagine_pipelines::opengl::vertex_program::VertexProgram;
use imagine_pipelines::scene::model::{Blend, Cull, DepthTest};
use imagine_units::desc::MachineDesc;

/// `kernel` compiled for `desc` through the tests' compile cache.
fn compile(
    kernel: &imagine_pipelines::kernel::Kernel,
    desc: &MachineDesc,
) -> Result<Compiled, CompileError> {
    CompileCache::at(concat!(env!("CARGO_TARGET_TMPDIR"), "/compile-cache")).compile(kernel, desc)
}

// One test per machine, so that the test threads compile them side by side.
#[test]
fn pipeline_kernels_compile_on_gold1() {
    pipeline_kernels_compile_on("gold1");
}

#[test]
fn pipeline_kernels_compile_on_gold8() {
    pipeline_kernels_compile_on("gold8");
}

#[test]
fn pipeline_kernels_compile_on_gold32() {
    pipeline_kernels_compile_on("gold32");
}

fn pipeline_kernels_compile_on(name: &str) {
    let desc = MachineDesc::resolve(name).unwrap();
    let c = desc.cluster.count;
    // The largest batch xyrast's scratchpad holds.
    let rows = kernels::xyrast_rows(&desc);
    assert!(rows >= 2, "{name}: {rows} raster records per cluster");
    let shape = FrameShape {
        width: 64,
        height: 48,
        clusters: c,
        cull: Cull::Back,
        depth_test: DepthTest::Less,
        batch: rows * c,
        blend: Blend::None,
    };
    let lit = VertexProgram::Lit {
        lights: 3,
        specular: true,
        shininess: 16,
        extras: 0,
    };
    // The most lights a scene has: the first kernel's three, then a pass of five.
    let lit8 = VertexProgram::Lit {
        lights: 8,
        specular: true,
        shininess: 16,
        extras: 0,
    };
    let textured = Varyings {
        extras: 2,
        derivatives: true,
        reference_depth: false,
    };
    let with_reference_depth = Varyings {
        reference_depth: true,
        ..Varyings::default()
    };

    let lit8_passes = lit8.passes(&desc);
    assert_eq!(lit8_passes.len(), 1);
    for k in [
        lit.perbegin(&desc),
        lit.perlight(&desc).unwrap(),
        lit.build(&desc),
        lit8.build(&desc),
        lit8_passes[0].clone(),
        VertexProgram::Unlit {
            per_vertex_colour: true,
            extras: 0,
        }
        .build(&desc),
        kernels::clear(&desc).unwrap(),
        kernels::assemble_clip(&desc, Varyings::default(), false).unwrap(),
        kernels::assemble_clip(&desc, Varyings::default(), true).unwrap(),
        kernels::assemble_clip(&desc, with_reference_depth, false).unwrap(),
        kernels::viewport_cull(&desc, shape).unwrap(),
        kernels::xyprep(&desc, shape).unwrap(),
        kernels::baryprep(&desc, Varyings::default()).unwrap(),
        kernels::baryprep(&desc, with_reference_depth).unwrap(),
        kernels::xyrast(&desc, shape).unwrap(),
        kernels::irast(&desc, Varyings::default(), 0).unwrap(),
        kernels::irast(&desc, with_reference_depth, 0).unwrap(),
        kernels::irast(&desc, Varyings::default(), 2).unwrap(),
        // A textured frame's (texture coordinates and their derivatives).
        kernels::baryprep(&desc, textured).unwrap(),
        kernels::irast(&desc, textured, 0).unwrap(),
        kernels::hash(&desc, shape).unwrap(),
        kernels::zcompare(&desc, shape).unwrap(),
        kernels::compact_recycle(&desc, [0, 1]).unwrap(),
        imagine_pipelines::opengl::mergefrag::sort32(&desc, shape).unwrap(),
        imagine_pipelines::opengl::mergefrag::mergefrag(&desc, shape).unwrap(),
    ] {
        let c = compile(&k, &desc).unwrap_or_else(|e| panic!("{name}: {e}"));
        println!(
            "{name} {}: II {:?} (bound {}), {} instructions",
            k.name,
            c.report.ii,
            c.report.res_mii.max(c.report.rec_mii),
            c.program.code.len()
        );
    }
}

/// A raster record as `xyprep` writes it: box `w × h` at `(x0, y0)` (empty if `w` or `h` is
/// 0), triangle `t` with top-left flags `top_left` (bit i: edge i), edge coefficients
/// `edges[i] = [A, B, C]`.
fn raster_record(
    (x0, y0, w, h): (u32, u32, u32, u32),
    t: u32,
    top_left: u32,
    edges: [[f32; 3]; 3],
) -> Vec<u32> {
    let (lo, hi) = if w * h == 0 {
        (1 | 1 << 16, 0)
    } else {
        (x0 | y0 << 16, (x0 + w - 1) | (y0 + h - 1) << 16)
    };
    let mut rec = vec![lo, hi, t | top_left << kernels::TRI_BITS];
    rec.extend(edges.iter().flatten().map(|x| x.to_bits()));
    assert_eq!(rec.len(), kernels::RASTER_WORDS);
    rec
}

/// The fragments xyrast must write for `records`: (address, triangle, E0, E1, E2) of
/// every box pixel whose centre every edge covers (E > 0, or E = 0 on a top-left edge).
fn covered_pixels(records: &[Vec<u32>], width: u32) -> Vec<[u32; 5]> {
    let mut out = Vec::new();
    for r in records {
        let (lo, hi) = (r[0], r[1]);
        if lo > hi {
            continue;
        }
        for y in lo >> 16..=hi >> 16 {
            for x in lo & 0xFFFF..=hi & 0xFFFF {
                let (fx, fy) = (x as f32 + 0.5, y as f32 + 0.5);
                let e: Vec<f32> = (0..3)
                    .map(|i| {
                        let c = |k: usize| f32::from_bits(r[3 + 3 * i + k]);
                        (c(0) * fx + c(1) * fy) + c(2)
                    })
                    .collect();
                let covered = (0..3).all(|i| {
                    let top_left = r[2] >> (kernels::TRI_BITS + i as u32) & 1 == 1;
                    e[i] > 0.0 || (e[i] == 0.0 && top_left)
                });
                if covered {
                    let tri = r[2] & ((1 << kernels::TRI_BITS) - 1);
                    out.push([
                        y * width + x,
                        tri,
                        e[0].to_bits(),
                        e[1].to_bits(),
                        e[2].to_bits(),
                    ]);
                }
            }
        }
    }
    out.sort_unstable();
    out
}

#[test]
fn xyrast_covers_exactly_the_pixels_the_edges_cover() {
    use imagine_pipelines::kernel::KernelInputs;
    let mut flushing = MachineDesc::resolve("gold8").unwrap();
    flushing.name = "gold8 with flush-to-zero".into();
    flushing.arithmetic.flush_to_zero = true;
    let machines = ["gold1", "gold8", "gold8+F"].map(|n| MachineDesc::resolve(n).unwrap());
    let blends = [Blend::None, Blend::Alpha];
    let cases = machines
        .into_iter()
        .chain([flushing])
        .flat_map(|d| blends.map(|b| (d.clone(), b)));
    for (desc, blend) in cases {
        let name = &format!("{} ({blend:?})", desc.name);
        let c = desc.cluster.count;
        let width = 40;
        let rows = kernels::xyrast_rows(&desc).min(8);
        let shape = FrameShape {
            width,
            height: 32,
            clusters: c,
            cull: Cull::None,
            depth_test: DepthTest::Less,
            batch: rows * c,
            blend,
        };
        let ordered = shape.ordered();
        let k = kernels::xyrast(&desc, shape).unwrap();
        let compiled = compile(&k, &desc).unwrap();
        // Boxes of many widths (runs that end inside and past the box) and heights, empty
        // ones among them; four kinds of edges.
        let mut records = Vec::new();
        for r in 0..rows as u32 {
            for t in 0..c as u32 {
                let n = r * c as u32 + t;
                let (w, h) = ((n * 7 + 3) % 10, (n * 5 + r) % 4);
                let (x0, y0) = ((n * 5) % 30, (n * 11) % 28);
                let (fx0, fy0) = (x0 as f32, y0 as f32);
                let edges = match n % 4 {
                    // Everything: E = 0 on top-left edges.
                    0 => [[0.0; 3]; 3],
                    // A column boundary through pixel centres: x = x0 + 2.5 is covered only
                    // when edge 0 is a top-left edge.
                    1 => [[1.0, 0.0, -(fx0 + 2.5)], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]],
                    // A triangle with its corners near the box.
                    2 => [
                        [-0.75, 1.25, fx0 * 0.75 - fy0 * 1.25 + 0.3],
                        [0.5, -1.0, fy0 - fx0 * 0.5 + 1.7],
                        [0.25, -0.25, 2.0 + (fy0 - fx0) * 0.25],
                    ],
                    // Nothing.
                    _ => [[0.0, 0.0, -1.0], [0.0; 3], [0.0; 3]],
                };
                records.push(raster_record((x0, y0, w, h), n, (n * 5) % 8, edges));
            }
        }
        // Each cluster walks its own boxes: the iterations are the most runs of any cluster.
        // In primitive order the clusters walk every box together, runs of 4·C pixels,
        // and step over an empty one in one iteration.
        let run = kernels::XYRAST_RUN * if ordered { c } else { 1 };
        let runs = |rec: &Vec<u32>| -> usize {
            let (lo, hi) = (rec[0], rec[1]);
            if lo > hi {
                return usize::from(ordered);
            }
            let (w, h) = (
                (hi & 0xFFFF) - (lo & 0xFFFF) + 1,
                (hi >> 16) - (lo >> 16) + 1,
            );
            (w as usize).div_ceil(run) * h as usize
        };
        let iterations = if ordered {
            records.iter().map(runs).sum::<usize>()
        } else {
            (0..c)
                .map(|t| records.iter().skip(t).step_by(c).map(runs).sum::<usize>())
                .max()
                .unwrap()
        }
        .max(1);
        let inputs = KernelInputs {
            streams: vec![
                records_to_stream(&records, c),
                vec![0; iterations * c],
                vec![],
                vec![],
                vec![],
                vec![],
                vec![],
            ],
            params: vec![],
        };
        let golden = imagine_pipelines::kernel::interpret(&k, &inputs, &desc).unwrap();
        let fragments = golden[2].len() - c;
        assert!(golden[2][fragments..].iter().all(|&a| a == shape.trash()));
        let mut got: Vec<[u32; 5]> = (0..fragments)
            .map(|i| std::array::from_fn(|s| golden[2 + s][i]))
            .collect();
        let want = covered_pixels(&records, width);
        if ordered {
            // Triangle by triangle, as OpenGL draws them (within one, any order: a
            // triangle covers a pixel once).
            assert!(
                got.is_sorted_by_key(|f| f[1]),
                "{name}: the fragments in primitive order"
            );
        }
        got.sort_unstable();
        let candidates: usize = records
            .iter()
            .filter(|rec| rec[0] <= rec[1])
            .map(|rec| {
                let w = (rec[1] & 0xFFFF) - (rec[0] & 0xFFFF) + 1;
                (w * ((rec[1] >> 16) - (rec[0] >> 16) + 1)) as usize
            })
            .sum();
        assert!(
            want.len() > 8 && want.len() < candidates,
            "{name}: {} of {candidates} candidates covered",
            want.len()
        );
        assert_eq!(got, want, "{name}: the covered pixels");
        let r = imagine_pipelines::run::check(&k, &compiled, &desc, &inputs).unwrap();
        assert!(r.mismatch.is_none(), "{name}: {:?}", r.mismatch);
    }
}

/// Runs `k` on `inputs` in the interpreter, checks the machine's output equals it word for
/// word, and returns the interpreter's streams.
fn run_checked(
    k: &imagine_pipelines::kernel::Kernel,
    desc: &MachineDesc,
    inputs: &imagine_pipelines::kernel::KernelInputs,
) -> Vec<Vec<u32>> {
    let compiled = compile(k, desc).unwrap();
    let golden = imagine_pipelines::kernel::interpret(k, inputs, desc).unwrap();
    let r = imagine_pipelines::run::check(k, &compiled, desc, inputs).unwrap();
    assert!(
        r.mismatch.is_none(),
        "{} on {}: {:?}",
        k.name,
        desc.name,
        r.mismatch
    );
    golden
}

/// The setup kernels in a chain, on the shaded vertices of SPHERE triangles (about half
/// face away): `assemble_clip` gathers each triangle's corners into one cluster (scaled by
/// a power of two that brings the largest x, y or w near 1), `viewport_cull` and `xyprep` count the boxes as
/// `xyrast` walks them, `baryprep` numbers the primitives; the machine matches the
/// interpreter at every step.
#[test]
fn setup_kernels_assemble_and_count_sphere_triangles_as_the_interpreter_does() {
    use imagine_pipelines::kernel::KernelInputs;
    // gold8's frame normalises its clip corners (`pipeline.normalise_clip`), the others'
    // pass them on as they are; gold1's and gold8's interpolate depth from each triangle's
    // reference depth (`pipeline.reference_depth`), gold32's from 0.
    for (name, normalise, reference_depth) in [
        ("gold1", false, true),
        ("gold8", true, true),
        ("gold32", false, false),
    ] {
        let varyings = Varyings {
            reference_depth,
            ..Varyings::default()
        };
        let desc = MachineDesc::resolve(name).unwrap();
        let c = desc.cluster.count;
        let scene = imagine_pipelines::scene::sphere(3, 128);
        let shape = FrameShape {
            width: 128,
            height: 128,
            clusters: c,
            cull: Cull::Back,
            depth_test: DepthTest::Less,
            batch: 8 * c,
            blend: Blend::None,
        };
        let tris = 64.max(8 * c);
        let m = scene.mvp();
        // Shaded vertices in drawing order: clip position, then a colour that names the
        // vertex.
        let vertices: Vec<Vec<u32>> = (0..3 * tris)
            .map(|v| {
                let p = scene.positions[v];
                let mut rec: Vec<u32> = (0..4)
                    .map(|r| {
                        (m[4 * r] * p[0] + m[4 * r + 1] * p[1] + m[4 * r + 2] * p[2] + m[4 * r + 3])
                            .to_bits()
                    })
                    .collect();
                rec.extend([v as f32, 0.5, 0.25].map(f32::to_bits));
                rec
            })
            .collect();
        let assembled = run_checked(
            &kernels::assemble_clip(&desc, varyings, normalise).unwrap(),
            &desc,
            &KernelInputs {
                streams: vec![records_to_stream(&vertices, c), vec![], vec![]],
                params: vec![],
            },
        );
        let clipped = stream_to_records(&assembled[1], kernels::CLIPPED_WORDS, c);
        let attribs = stream_to_records(&assembled[2], varyings.attrib_words(), c);
        assert_eq!((clipped.len(), attribs.len()), (tris, tris), "{name}");
        for t in 0..tris {
            let corner = |k: usize| &vertices[3 * t + k];
            // Normalised, the corners come out scaled by 2^-k, k half the exponent of the
            // largest square of an x, y or w (exact).
            let largest = (0..3)
                .flat_map(|k| [0, 1, 3].map(|i| f32::from_bits(corner(k)[i])))
                .map(|x| x * x)
                .fold(0f32, f32::max);
            let scale = if normalise {
                f32::from_bits(((382 - (largest.to_bits() >> 23)) >> 1) << 23)
            } else {
                1.0
            };
            let scaled = |w: u32| (f32::from_bits(w) * scale).to_bits();
            let xyw: Vec<u32> = (0..3)
                .flat_map(|k| [corner(k)[0], corner(k)[1], corner(k)[3]].map(scaled))
                .collect();
            assert_eq!(clipped[t][..9], xyw[..], "{name}: triangle {t}'s corners");
            let biggest = xyw
                .iter()
                .map(|&w| f32::from_bits(w).abs())
                .fold(0f32, f32::max);
            assert!(
                !normalise || (0.99..2.0).contains(&biggest),
                "{name}: {biggest}"
            );
            // With a reference depth, ζ (corner 0's z/w within [-1, 1]) and each corner's
            // z − ζ·w (fp32, rounded after the multiply and after the subtract); without,
            // each corner's z.
            let f = |w: u32| f32::from_bits(scaled(w));
            let depths: Vec<u32> = if reference_depth {
                let zeta = (f(corner(0)[2]) / f(corner(0)[3])).clamp(-1.0, 1.0);
                std::iter::once(zeta.to_bits())
                    .chain((0..3).map(|k| (f(corner(k)[2]) - zeta * f(corner(k)[3])).to_bits()))
                    .collect()
            } else {
                (0..3).map(|k| scaled(corner(k)[2])).collect()
            };
            let depth = varyings.depth_words();
            let colours: Vec<u32> = (0..3).flat_map(|k| corner(k)[4..7].to_vec()).collect();
            assert_eq!(
                attribs[t][..depth],
                depths[..],
                "{name}: triangle {t}'s depths"
            );
            assert_eq!(
                attribs[t][depth..],
                colours[..],
                "{name}: triangle {t}'s colours"
            );
        }
        // SPHERE at this size: about half the triangles face away, none lies wholly
        // outside one clip plane.
        assert!(clipped.iter().all(|r| r[9] == 1), "{name}: trivial reject");
        let viewed = run_checked(
            &kernels::viewport_cull(&desc, shape).unwrap(),
            &desc,
            &KernelInputs {
                streams: vec![assembled[1].clone(), vec![], vec![]],
                params: vec![],
            },
        );
        let window = stream_to_records(&viewed[1], kernels::WINDOW_WORDS, c);
        let kept = window.iter().filter(|r| r[13] & 1 == 1).count();
        assert!(
            kept > tris / 8 && kept < 7 * tris / 8,
            "{name}: {kept} of {tris} triangles face the eye"
        );
        let bary = run_checked(
            &kernels::baryprep(&desc, varyings).unwrap(),
            &desc,
            &KernelInputs {
                streams: vec![assembled[2].clone(), viewed[2].clone(), vec![]],
                params: vec![1000],
            },
        );
        let interp = stream_to_records(&bary[2], varyings.interp_words(), c);
        let depth = varyings.depth_words();
        for (t, rec) in interp.iter().enumerate() {
            assert_eq!(
                rec[varyings.prim_at()],
                1001 + t as u32,
                "{name}: triangle {t}'s primitive"
            );
            if reference_depth {
                assert_eq!(
                    rec[0], attribs[t][0],
                    "{name}: triangle {t}'s reference depth"
                );
            }
            assert_eq!(
                rec[depth..varyings.prim_at()],
                attribs[t][depth..],
                "{name}: triangle {t}'s colours"
            );
        }
        let prepped = run_checked(
            &kernels::xyprep(&desc, shape).unwrap(),
            &desc,
            &KernelInputs {
                streams: vec![viewed[1].clone(), vec![], vec![]],
                params: vec![0, 0, 127, 127],
            },
        );
        let records = stream_to_records(&prepped[1], kernels::RASTER_WORDS, c);
        assert_eq!(records.len(), tris, "{name}: raster records");
        // Only kept triangles have boxes; every record names its triangle.
        for (t, rec) in records.iter().enumerate() {
            assert_eq!(
                rec[2] as usize & ((1 << kernels::TRI_BITS) - 1),
                t,
                "{name}"
            );
            if window[t][13] & 1 == 0 {
                assert!(rec[0] > rec[1], "{name}: triangle {t} is culled");
            }
        }
        // The counts: the iterations in every cluster, then candidates whose sum is the
        // boxes' total area (the host's bound on xyrast's fragments).
        let box_area: u64 = records
            .iter()
            .map(|rec| {
                let (lo, hi) = (rec[0], rec[1]);
                let span = |a: u32, b: u32| u64::from(b.saturating_sub(a) + 1);
                if hi == 0 {
                    0
                } else {
                    span(lo & 0xFFFF, hi & 0xFFFF) * span(lo >> 16, hi >> 16)
                }
            })
            .sum();
        let counts = &prepped[2];
        assert_eq!(counts.len(), 2 * c, "{name}: two rows of counts");
        assert!(counts[..c].iter().all(|&w| w == counts[0]), "{name}");
        // xyrast's iterations: the most runs of box pixels any cluster has.
        let runs = (0..c)
            .map(|t| {
                records
                    .iter()
                    .skip(t)
                    .step_by(c)
                    .filter(|rec| rec[0] <= rec[1])
                    .map(|rec| {
                        let w = (rec[1] & 0xFFFF) - (rec[0] & 0xFFFF) + 1;
                        let h = (rec[1] >> 16) - (rec[0] >> 16) + 1;
                        (w as usize).div_ceil(kernels::XYRAST_RUN) * h as usize
                    })
                    .sum::<usize>()
            })
            .max()
            .unwrap();
        assert_eq!(counts[0] as usize, runs.max(1), "{name}: xyrast iterations");
        let candidates: u64 = counts[c..].iter().map(|&w| u64::from(w)).sum();
        assert!(box_area > 0, "{name}: some triangles are kept");
        assert_eq!(candidates, box_area, "{name}: candidate pixels");
        // Blending: the clusters walk every box together, runs of 4·C pixels, and step
        // over a culled triangle in one iteration.
        let ordered = FrameShape {
            blend: Blend::Add,
            ..shape
        };
        let prepped_in_order = run_checked(
            &kernels::xyprep(&desc, ordered).unwrap(),
            &desc,
            &KernelInputs {
                streams: vec![viewed[1].clone(), vec![], vec![]],
                params: vec![0, 0, 127, 127],
            },
        );
        assert_eq!(prepped_in_order[1], prepped[1], "{name}: the same records");
        let runs_in_order: usize = records
            .iter()
            .map(|rec| {
                if rec[0] > rec[1] {
                    return 1;
                }
                let w = (rec[1] & 0xFFFF) - (rec[0] & 0xFFFF) + 1;
                let h = (rec[1] >> 16) - (rec[0] >> 16) + 1;
                (w as usize).div_ceil(kernels::XYRAST_RUN * c) * h as usize
            })
            .sum();
        let counts_in_order = &prepped_in_order[2];
        assert!(
            counts_in_order[..c]
                .iter()
                .all(|&w| w as usize == runs_in_order)
        );
        assert_eq!(
            counts_in_order[c..],
            counts[c..],
            "{name}: candidate pixels"
        );
    }
}

#[test]
fn perbegin_composes_the_matrices_on_the_machine_as_mat_mul_does() {
    use imagine_pipelines::kernel::KernelInputs;
    use imagine_pipelines::scene::{LoadOptions, load, mat_mul};
    use imagine_units::arith::fp32::testgen::SplitMix64;
    let mut sphere = load(
        "SPHERE-FULL",
        &LoadOptions {
            size: Some(64),
            subdivisions: Some(1),
            filter: None,
        },
    )
    .unwrap();
    let mut rng = SplitMix64::new(7);
    let mut random = || f32::from_bits(rng.next_u32() & 0xBFFF_FFFF) - 1.5;
    let random_matrix: [f32; 16] = std::array::from_fn(|_| random());
    sphere.objects[0].model = random_matrix;
    let unlit = VertexProgram::Unlit {
        per_vertex_colour: false,
        extras: 0,
    };
    let lit = VertexProgram::for_object(&sphere, &sphere.objects[0], false).unwrap();
    for name in ["gold1", "gold8", "gold32"] {
        let desc = MachineDesc::resolve(name).unwrap();
        let c = desc.cluster.count;
        for vp in [&lit, &unlit] {
            let k = vp.perbegin(&desc);
            let compiled = compile(&k, &desc).unwrap();
            let state = vp.state_words(&sphere, &sphere.objects[0], c);
            let inputs = KernelInputs {
                streams: vec![state, vec![]],
                params: vec![],
            };
            let out = imagine_pipelines::kernel::interpret(&k, &inputs, &desc).unwrap();
            assert_eq!(
                out[1].len(),
                vp.perbegin_rows(&desc) * c,
                "{name}: one row per parameter it computes (perlight writes the rest)"
            );
            let cam = sphere.camera;
            let mvp = mat_mul(&cam.projection, &mat_mul(&cam.view, &random_matrix));
            let want: Vec<u32> = mvp
                .iter()
                .flat_map(|x| std::iter::repeat_n(x.to_bits(), c))
                .collect();
            assert_eq!(out[1][..16 * c], want[..], "{name}: P·(V·M), row by row");
            let r = imagine_pipelines::run::check(&k, &compiled, &desc, &inputs).unwrap();
            assert!(r.mismatch.is_none(), "{name}: {:?}", r.mismatch);
        }
    }
}

#[test]
fn reciprocal_divides_every_pixel_address_exactly() {
    for d in [3u32, 5, 7, 40, 100, 640, 720, 1000, 1023, 4095] {
        let (m, s) = kernels::reciprocal(d);
        let quotient = |n: u32| ((u64::from(n) * u64::from(m)) >> 32) as u32 >> s;
        // Every address of a 4096 × 512 window, and the largest ones the proof covers.
        let big = (1u32 << 31) - 4096..1 << 31;
        for n in (0..1 << 21).chain(big) {
            assert_eq!(quotient(n), n / d, "{n} / {d}");
        }
    }
}

/// Whether each fragment of `addrs` conflicts with an earlier one: the same stamp row
/// `(y + ⌊5x / 32⌋) mod 32` and bit `x mod 32`, the trash pixel excepted.
fn conflicts(addrs: &[u32], width: u32, trash: u32) -> Vec<u32> {
    let mut seen = std::collections::HashSet::new();
    addrs
        .iter()
        .map(|&a| {
            let (x, y) = (a % width, a / width);
            let key = ((y + kernels::STAMP_SKEW * x / 32) & 31, x & 31);
            u32::from(a != trash && !seen.insert(key))
        })
        .collect()
}

#[test]
fn hash_holds_back_exactly_the_fragments_an_earlier_one_shares_a_stamp_key_with() {
    use imagine_pipelines::kernel::KernelInputs;
    for (name, width) in [("gold1", 40), ("gold8", 40), ("gold8", 64), ("gold32", 720)] {
        let desc = MachineDesc::resolve(name).unwrap();
        let c = desc.cluster.count;
        let shape = FrameShape {
            width,
            height: 70,
            clusters: c,
            cull: Cull::None,
            depth_test: DepthTest::Less,
            batch: c,
            blend: Blend::None,
        };
        let k = kernels::hash(&desc, shape).unwrap();
        let compiled = compile(&k, &desc).unwrap();
        // 256 fragments in a 40 × 8 corner ((x + 32, y) and (x, y + 1) alias), many of them on the same
        // pixel, some in the same row of clusters; and nulls (the trash pixel).
        let rows = 256 / c;
        let mut state = 0x9E37_79B9u32;
        let addrs: Vec<u32> = (0..rows * c)
            .map(|i| {
                state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                let r = state >> 8;
                match i % 11 {
                    10 => shape.trash(),
                    _ => (r % 8) * width + (r >> 12) % 40,
                }
            })
            .collect();
        let inputs = KernelInputs {
            streams: vec![addrs.clone(), vec![], vec![]],
            params: vec![],
        };
        let golden = imagine_pipelines::kernel::interpret(&k, &inputs, &desc).unwrap();
        let mut want = conflicts(&addrs, width, shape.trash());
        let held: u32 = want.iter().sum();
        // Then rows of zeros up to a whole group of 32 for sort32.
        want.resize(addrs.len() + 32 - c, 0);
        assert!(
            held as usize > addrs.len() / 8 && (held as usize) < addrs.len() / 2,
            "{name}: {held} of {} conflict",
            addrs.len()
        );
        assert_eq!(golden[1], want, "{name}, width {width}: conflict flags");
        assert_eq!(golden[2], vec![held; c], "{name}: the count row");
        let r = imagine_pipelines::run::check(&k, &compiled, &desc, &inputs).unwrap();
        assert!(r.mismatch.is_none(), "{name}: {:?}", r.mismatch);
    }
}

/// Fragments for the merge stage: `n` slots (whole rows) of a round's streams, conflict
/// flags, addresses, depths, colours and primitives, with many fragments per pixel, equal
/// depths, depths outside [0, 1] and nulls; then `hash`'s rows of zeros and garbage in
/// the other streams up to whole groups of 32.
struct Round {
    conflict: Vec<u32>,
    addr: Vec<u32>,
    z: Vec<u32>,
    colour: Vec<u32>,
    prim: Vec<u32>,
}

fn merge_round(n: usize, shape: FrameShape, seed: u32) -> Round {
    let groups = n.next_multiple_of(32);
    let mut state = seed;
    let mut next = || {
        state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        state >> 4
    };
    let mut r = Round {
        conflict: vec![],
        addr: vec![],
        z: vec![],
        colour: vec![],
        prim: vec![],
    };
    for i in 0..groups {
        let (a, b, c) = (next(), next(), next());
        if i >= n {
            // Past the stream: hash's zeros, anything else.
            r.conflict.push(0);
            r.addr.push(a % 64);
            r.z.push(b);
            r.colour.push(c);
            r.prim.push(a);
            continue;
        }
        let null = i % 13 == 12;
        r.conflict.push(u32::from(!null && a % 8 != 0));
        r.addr
            .push(if null { shape.trash() } else { (a >> 8) % 12 });
        let depths = [0.25f32, 0.5, 0.75, 1.0, 0.0, -0.0, 1.5, -0.5];
        r.z.push(match b % 16 {
            _ if null => kernels::NULL_DEPTH,
            0..=7 => depths[(b >> 8) as usize % 8].to_bits(),
            8 => kernels::NULL_DEPTH,
            _ => (((b >> 8) % 1000) as f32 / 1000.0).to_bits(),
        });
        r.colour.push(c);
        r.prim.push(if null { 0 } else { 1 + (c >> 8) % 6 });
    }
    r
}

/// What `sort32` must write: per group of `n`, the keys `addr·32 + position` (the trash address
/// for slots not held back) ascending, and each key's depth and primitive.
fn sorted_model(r: &Round, trash: u32, n: usize) -> [Vec<u32>; 3] {
    let mut out = [vec![], vec![], vec![]];
    for g in (0..r.conflict.len()).step_by(n) {
        let mut keys: Vec<u32> = (0..n)
            .map(|p| {
                let addr = if r.conflict[g + p] != 0 {
                    r.addr[g + p]
                } else {
                    trash
                };
                addr << 5 | p as u32
            })
            .collect();
        keys.sort_unstable();
        for key in keys {
            let p = g + (key & 31) as usize;
            out[0].push(key);
            out[1].push(r.z[p]);
            out[2].push(r.prim[p]);
        }
    }
    out
}

/// What `mergefrag` must write: per group of `n`, per address held back (ascending), the
/// fragment with the smallest (depth, primitive) as unsigned words (the first of equal
/// ones in stream order): z, colour, addr, prim; then a row of nulls.
fn merged_model(r: &Round, trash: u32, clusters: usize, n: usize) -> [Vec<u32>; 4] {
    let mut out = [vec![], vec![], vec![], vec![]];
    for g in (0..r.conflict.len()).step_by(n) {
        let mut best: std::collections::BTreeMap<u32, usize> = Default::default();
        for p in g..g + n {
            if r.conflict[p] == 0 {
                continue;
            }
            let e = best.entry(r.addr[p]).or_insert(p);
            if (r.z[p], r.prim[p]) < (r.z[*e], r.prim[*e]) {
                *e = p;
            }
        }
        for (addr, p) in best {
            assert_ne!(addr, trash);
            out[0].push(r.z[p]);
            out[1].push(r.colour[p]);
            out[2].push(addr);
            out[3].push(r.prim[p]);
        }
    }
    for (s, null) in out.iter_mut().zip([kernels::NULL_DEPTH, 0, trash, 0]) {
        s.extend(std::iter::repeat_n(null, clusters));
    }
    out
}

#[test]
fn sort32_and_mergefrag_keep_the_fragment_zcompare_would_keep_per_pixel_and_group() {
    use imagine_pipelines::kernel::KernelInputs;
    use imagine_pipelines::opengl::mergefrag;
    for name in ["gold1", "gold8", "gold32"] {
        let desc = MachineDesc::resolve(name).unwrap();
        let c = desc.cluster.count;
        let shape = FrameShape {
            width: 40,
            height: 30,
            clusters: c,
            cull: Cull::None,
            depth_test: DepthTest::Less,
            batch: c,
            blend: Blend::None,
        };
        let trash = shape.trash();
        // Not whole groups: the last group is part stream, part padding.
        let n = (200usize).next_multiple_of(c).max(c) + if c < 32 { c } else { 0 };
        let round = merge_round(n, shape, 0x1234_5678 + c as u32);
        let groups = round.conflict.len();
        assert!(groups > n || c == 32);
        let sort = mergefrag::sort32(&desc, shape).unwrap();
        let merge = mergefrag::mergefrag(&desc, shape).unwrap();
        let sort_inputs = KernelInputs {
            streams: vec![
                round.conflict.clone(),
                round.addr.clone(),
                round.z.clone(),
                round.prim.clone(),
                vec![],
                vec![],
                vec![],
            ],
            params: vec![],
        };
        let sorted = imagine_pipelines::kernel::interpret(&sort, &sort_inputs, &desc).unwrap();
        let group = mergefrag::group(c);
        let want = sorted_model(&round, trash, group);
        for (s, w) in sorted[4..].iter().zip(&want) {
            assert_eq!(s, w, "{name}: sort32");
        }
        let merge_inputs = KernelInputs {
            streams: vec![
                want[0].clone(),
                want[1].clone(),
                want[2].clone(),
                round.colour.clone(),
                vec![],
                vec![],
                vec![],
                vec![],
            ],
            params: vec![],
        };
        let merged = imagine_pipelines::kernel::interpret(&merge, &merge_inputs, &desc).unwrap();
        let want_merged = merged_model(&round, trash, c, group);
        let held: u32 = round.conflict.iter().sum();
        let kept = want_merged[0].len() - c;
        // Groups of 32 merge most of the fragments held back (12 pixels); groups of 8 some.
        let most = if group == 32 { 2 } else { 1 };
        assert!(
            kept * (1 + most) < 2 * held as usize && kept > 20,
            "{name}: {kept} of {held} kept"
        );
        for (s, w) in merged[4..].iter().zip(&want_merged) {
            assert_eq!(s, w, "{name}: mergefrag");
        }
        for (k, inputs) in [(&sort, &sort_inputs), (&merge, &merge_inputs)] {
            let compiled = compile(k, &desc).unwrap();
            println!(
                "{name} {}: II {:?} (bound {} {}, recurrence {}), {} stages, {} instructions, {:?}",
                k.name,
                compiled.report.ii,
                compiled.report.res_mii,
                compiled.report.res_limit,
                compiled.report.rec_mii,
                compiled.report.stages,
                compiled.program.code.len(),
                compiled.report.loop_ops
            );
            let _ = ();
            let r = imagine_pipelines::run::check(k, &compiled, &desc, inputs).unwrap();
            assert!(r.mismatch.is_none(), "{name} {}: {:?}", k.name, r.mismatch);
        }
    }
}

/// `zcompare` under blending, on the machine and in the interpreter, against the blend
/// equations in integers: `alpha` rounds `(s·a + d·(255 − a)) / 255` to nearest, `add`
/// saturates `s + d`, every channel (alpha too); a fragment that fails the depth test or
/// waits (`conflict`) leaves the pixel as it was.
#[test]
fn zcompare_blends_each_channel_as_the_equations_say() {
    use imagine_pipelines::kernel::KernelInputs;
    use imagine_units::arith::fp32::testgen::SplitMix64;
    let desc = MachineDesc::resolve("gold8").unwrap();
    let c = desc.cluster.count;
    let n = 32 * c;
    let mut rng = SplitMix64::new(29);
    // Colours with channels at 0 and 255 among random ones.
    let mut colour = || -> u32 {
        (0..4).fold(0, |w, k| {
            let byte = match rng.below(4) {
                0 => 0,
                1 => 255,
                _ => rng.below(256),
            };
            w | byte << (8 * k)
        })
    };
    let src: Vec<u32> = (0..n).map(|_| colour()).collect();
    let dst: Vec<u32> = (0..n).map(|_| colour()).collect();
    // Every fourth fragment behind the pixel, every seventh waiting.
    let z: Vec<u32> = (0..n)
        .map(|i| if i % 4 == 3 { 0.75f32 } else { 0.25 }.to_bits())
        .collect();
    let conflict: Vec<u32> = (0..n).map(|i| u32::from(i % 7 == 6)).collect();
    let pixels: Vec<Vec<u32>> = (0..n).map(|i| vec![dst[i], 0.5f32.to_bits(), 1]).collect();
    for blend in [Blend::Alpha, Blend::Add] {
        let shape = FrameShape {
            width: 64,
            height: 64,
            clusters: c,
            cull: Cull::None,
            depth_test: DepthTest::Less,
            batch: 8 * c,
            blend,
        };
        let inputs = KernelInputs {
            streams: vec![
                z.clone(),
                src.clone(),
                (0..n as u32).collect(),
                vec![2; n],
                records_to_stream(&pixels, c),
                conflict.clone(),
                vec![],
                vec![],
            ],
            params: vec![],
        };
        let out = run_checked(&kernels::zcompare(&desc, shape).unwrap(), &desc, &inputs);
        let written = stream_to_records(&out[6], kernels::PIXEL_WORDS, c);
        for i in 0..n {
            let passes = i % 4 != 3 && i % 7 != 6;
            let want = if !passes {
                dst[i]
            } else {
                let a = src[i] >> 24;
                (0..4).fold(0, |w, k| {
                    let (s, d) = (src[i] >> (8 * k) & 255, dst[i] >> (8 * k) & 255);
                    let byte = match blend {
                        Blend::Add => (s + d).min(255),
                        _ => ((s * a + d * (255 - a)) as f64 / 255.0).round() as u32,
                    };
                    w | byte << (8 * k)
                })
            };
            assert_eq!(written[i][0], want, "{blend:?}: fragment {i}");
            let at = if passes { i as u32 } else { shape.trash() };
            assert_eq!(out[7][i], at, "{blend:?}: fragment {i}'s address");
        }
    }
}

/// The kernels `imagine kernel list|show|check` take from the pipeline (built by its own
/// registration) are those its plan names (`scene show`, and the render's `kernels built`
/// and kernel breakdown), for every built-in scene, specialised and general.
#[test]
fn pipeline_kernels_are_the_ones_the_plan_names() {
    use imagine_pipelines::opengl::render::{RenderOptions, pipeline_kernels, plan_pipeline};
    use imagine_pipelines::scene::{LoadOptions, file::BUILTIN, load};
    let desc = MachineDesc::gold8();
    for (name, _) in BUILTIN {
        let scene = load(
            name,
            &LoadOptions {
                size: Some(64),
                subdivisions: Some(1),
                filter: None,
            },
        )
        .unwrap();
        for specialise in [true, false] {
            let options = RenderOptions {
                specialise,
                ..RenderOptions::default()
            };
            let kernels = pipeline_kernels(&scene, &desc, &options);
            let Ok(plan) = plan_pipeline(&scene, &desc, &options) else {
                assert!(kernels.is_err(), "{name}: built without a plan");
                continue;
            };
            let kernels = kernels.unwrap_or_else(|e| panic!("{name}: {e}"));
            let mut built: Vec<&str> = kernels.iter().map(|(n, _)| n.as_str()).collect();
            let mut planned = plan.kernel_names();
            built.sort_unstable();
            planned.sort_unstable();
            assert_eq!(built, planned, "{name} (specialised: {specialise})");
        }
    }
}
