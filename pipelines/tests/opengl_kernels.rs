//! The OpenGL pipeline's kernels compile on every machine shape.

use imagine_pipelines::compile::compile;
use imagine_pipelines::kernels::{records_to_stream, stream_to_records};
use imagine_pipelines::opengl::kernels::{self, FrameShape};
use imagine_units::desc::MachineDesc;

#[test]
fn pipeline_kernels_compile_on_gold1_gold8_gold32() {
    for name in ["gold1", "gold8", "gold32"] {
        let desc = MachineDesc::resolve(name).unwrap();
        let shape = FrameShape {
            width: 64,
            height: 48,
            clusters: desc.cluster.count,
            cull_back: true,
        };
        for k in [
            kernels::vertex_unlit(&desc),
            kernels::setup(&desc, shape),
            kernels::xyrast(&desc, shape),
            kernels::irast(&desc),
            kernels::zcompare(&desc, shape),
            kernels::compact_recycle(&desc, [0, 1]),
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
}

#[test]
fn xyrast_machine_matches_interpreter() {
    use imagine_pipelines::kernel::KernelInputs;
    for name in ["gold1", "gold8"] {
        let desc = MachineDesc::resolve(name).unwrap();
        let c = desc.cluster.count;
        let shape = FrameShape {
            width: 32,
            height: 32,
            clusters: c,
            cull_back: false,
        };
        let k = kernels::xyrast(&desc, shape);
        let compiled = compile(&k, &desc).unwrap();
        // Three rows of triangles whose boxes differ in size; zero edge functions with
        // every top-left flag set cover every candidate.
        let rows = 3;
        let mut records = Vec::new();
        let mut iterations = 0;
        for r in 0..rows {
            let boxes: Vec<(u32, u32)> = (0..c)
                .map(|t| ((t as u32 * 7 + r) % 5, (t as u32 * 3 + r) % 4))
                .collect();
            let row_max = boxes.iter().map(|(w, h)| w * h).max().unwrap().max(1);
            iterations += row_max as usize;
            for (t, (w, h)) in boxes.iter().enumerate() {
                let (x0, y0) = (t as u32 * 2, r * 3);
                let (lo, hi) = if w * h == 0 {
                    (1 | 1 << 16, 0)
                } else {
                    (x0 | y0 << 16, (x0 + w - 1) | (y0 + h - 1) << 16)
                };
                let mut rec = vec![lo, hi];
                rec.extend([0u32; 9]);
                rec.push(t as u32 | 7 << 29);
                rec.push(row_max);
                records.push(rec);
            }
        }
        let raster = records_to_stream(&records, c);
        let inputs = KernelInputs {
            streams: vec![
                raster,
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
        let want: u32 = records
            .iter()
            .map(|r| {
                if r[1] == 0 {
                    0
                } else {
                    ((r[1] & 0xFFFF) - (r[0] & 0xFFFF) + 1) * ((r[1] >> 16) - (r[0] >> 16) + 1)
                }
            })
            .sum();
        assert_eq!(
            golden[2].len(),
            want as usize + c,
            "{name}: every candidate and a null row"
        );
        let r = imagine_pipelines::run::check(&k, &compiled, &desc, &inputs).unwrap();
        assert!(r.mismatch.is_none(), "{name}: {:?}", r.mismatch);
    }
}

#[test]
fn setup_machine_matches_interpreter_on_sphere_triangles() {
    use imagine_pipelines::kernel::KernelInputs;
    for name in ["gold1", "gold8"] {
        let desc = MachineDesc::resolve(name).unwrap();
        let c = desc.cluster.count;
        let scene = imagine_pipelines::scene::sphere(3, 128);
        let shape = FrameShape {
            width: 128,
            height: 128,
            clusters: c,
            cull_back: true,
        };
        let k = kernels::setup(&desc, shape);
        let compiled = compile(&k, &desc).unwrap();
        let tris = 8 * c;
        let mut records = Vec::new();
        for t in 0..tris {
            let mut rec = Vec::new();
            for kk in 0..3 {
                let p = scene.positions[3 * t + kk];
                let m = scene.mvp;
                for r in 0..4 {
                    rec.push(
                        (m[4 * r] * p[0]
                            + m[4 * r + 1] * p[1]
                            + m[4 * r + 2] * p[2]
                            + m[4 * r + 3])
                            .to_bits(),
                    );
                }
                rec.extend([0.5f32; 3].map(f32::to_bits));
            }
            records.push(rec);
        }
        let stream = records_to_stream(&records, c);
        let inputs = KernelInputs {
            streams: vec![stream, vec![], vec![], vec![]],
            params: vec![0, 0, 127, 127, 0],
        };
        let golden = imagine_pipelines::kernel::interpret(&k, &inputs, &desc).unwrap();
        assert_eq!(
            golden[1].len(),
            tris * kernels::RASTER_WORDS,
            "raster records"
        );
        assert_eq!(
            golden[2].len(),
            tris * kernels::INTERP_WORDS,
            "interp records"
        );
        // The counts: the iterations in every cluster, then candidates whose sum is the
        // boxes' total area (the host's bound on xyrast's fragments).
        let box_area: u64 = stream_to_records(&golden[1], kernels::RASTER_WORDS, c)
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
        let counts = &golden[3];
        assert_eq!(counts.len(), 2 * c, "{name}: two rows of counts");
        assert!(counts[..c].iter().all(|&w| w == counts[0]), "{name}");
        let candidates: u64 = counts[c..].iter().map(|&w| u64::from(w)).sum();
        assert!(box_area > 0, "{name}: some triangles are kept");
        assert_eq!(candidates, box_area, "{name}: candidate pixels");
        let r = imagine_pipelines::run::check(&k, &compiled, &desc, &inputs).unwrap();
        assert!(r.mismatch.is_none(), "{name}: {:?}", r.mismatch);
    }
}
