//! The OpenGL pipeline's kernels compile on every machine shape.

use imagine_pipelines::compile::compile;
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
    let desc = MachineDesc::gold8();
    let shape = FrameShape {
        width: 32,
        height: 32,
        clusters: 8,
        cull_back: false,
    };
    let k = kernels::xyrast(&desc, shape);
    let c = compile(&k, &desc).unwrap();
    println!("{}", c.report.text());
    let raster: Vec<u32> = vec![
        65537, 196611, 65537, 65537, 65537, 65537, 65537, 65537, 983055, 983055, 0, 0, 0, 0, 0, 0,
        3252682752, 3250585600, 2147483648, 2147483648, 2147483648, 2147483648, 2147483648,
        2147483648, 3252682752, 3242196992, 2147483648, 2147483648, 2147483648, 2147483648,
        2147483648, 2147483648, 1147142144, 1144258560, 2147483648, 2147483648, 2147483648,
        2147483648, 2147483648, 2147483648, 1105199104, 1103101952, 2147483648, 2147483648,
        2147483648, 2147483648, 2147483648, 2147483648, 0, 3242196992, 2147483648, 2147483648,
        2147483648, 2147483648, 2147483648, 2147483648, 3261071360, 3258974208, 2147483648,
        2147483648, 2147483648, 2147483648, 2147483648, 2147483648, 0, 0, 2147483648, 2147483648,
        2147483648, 2147483648, 2147483648, 2147483648, 1105199104, 1103101952, 2147483648,
        2147483648, 2147483648, 2147483648, 2147483648, 2147483648, 3261071360, 3267362816,
        2147483648, 2147483648, 2147483648, 2147483648, 2147483648, 2147483648, 1073741824,
        1073741825, 2, 3, 4, 5, 6, 7,
    ];
    let inputs = KernelInputs {
        streams: vec![
            raster,
            vec![0; 225 * 8],
            vec![],
            vec![],
            vec![],
            vec![],
            vec![],
        ],
        params: vec![],
    };
    let golden = imagine_pipelines::kernel::interpret(&k, &inputs, &desc).unwrap();
    println!("interp fragments {}", golden[2].len());
    let r = imagine_pipelines::run::check(&k, &c, &desc, &inputs).unwrap();
    assert!(r.mismatch.is_none(), "{:?}", r.mismatch);
}
