//! The hardware rasterizer (`gold8+hwrast`) in whole frames: it takes the place of the
//! rasterizer kernels and leaves every framebuffer word as gold8's kernels leave it — on a
//! mipmapped textured scene (fragments into a fragment program, with derivatives) and an
//! untextured blending one (packed colour, fragments in primitive order), also on an SRF
//! small enough that calls overflow and tiles are split.

use imagine_pipelines::compile::CompileCache;
use imagine_pipelines::opengl::render::{Frame, RenderOptions, render_with};
use imagine_pipelines::scene::model::{Blend, Scene};
use imagine_pipelines::scene::{self, LoadOptions, parse_tri, window_scene};
use imagine_units::desc::MachineDesc;

fn cached() -> RenderOptions {
    RenderOptions {
        cache: CompileCache::at(concat!(env!("CARGO_TARGET_TMPDIR"), "/compile-cache")),
        ..RenderOptions::default()
    }
}

fn builtin(name: &str, size: u32) -> Scene {
    scene::load(
        name,
        &LoadOptions {
            size: Some(size),
            subdivisions: None,
            filter: None,
        },
    )
    .unwrap()
}

/// Three overlapping triangles, the last two half transparent.
fn blended() -> Scene {
    let mut s = window_scene(
        parse_tri(
            "three",
            "32 32\n\
             2 2 0.5 1 0 0  30 2 0.5 1 0 0  2 30 0.5 1 0 0\n\
             4 4 0.25 0 1 0  28 4 0.25 0 1 0  16 28 0.75 0 1 0\n\
             1 20 0.4 0 0 1  31 10 0.6 0 0 1  25 31 0.1 0 0 1\n",
        )
        .unwrap(),
    );
    s.pipeline.blend = Blend::Add;
    s
}

/// Fails naming how many words differ and the first, not printing whole framebuffers.
fn same<T: PartialEq + std::fmt::Debug>(a: &[T], b: &[T], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: sizes");
    let differ: Vec<usize> = (0..a.len()).filter(|&i| a[i] != b[i]).collect();
    if let Some(&i) = differ.first() {
        panic!(
            "{what}: {} of {} words differ, the first at {i}: {:?} against {:?}",
            differ.len(),
            a.len(),
            a[i],
            b[i]
        );
    }
}

fn render(scene: &Scene, desc: &MachineDesc) -> Frame {
    render_with(scene, desc, cached(), None, |_, _| {})
        .unwrap_or_else(|e| panic!("{} on {}: {e}", scene.name, desc.name))
}

#[test]
fn the_hardware_rasterizer_draws_gold8s_frames_bit_for_bit() {
    let gold8 = MachineDesc::gold8();
    let hwrast = MachineDesc::resolve("gold8+hwrast").unwrap();
    // ADVS-8: a fragment program with a mipmapped texture (varyings and derivatives);
    // the .tri scene: packed colour, blended (primitive order), and again with each
    // triangle's depth interpolated from its reference depth (`pipeline.reference_depth`)
    // and 1/ΣE by a Newton–Raphson step (`pipeline.newton_raphson`).
    let mut from_reference = blended();
    from_reference.pipeline.reference_depth = true;
    from_reference.pipeline.newton_raphson = 1;
    from_reference.name = "three, reference depth, a Newton step".into();
    for scene in [builtin("ADVS-8", 48), blended(), from_reference] {
        let (a, b) = (render(&scene, &gold8), render(&scene, &hwrast));
        let what = &scene.name;
        assert!(b.stats.fragments > 0, "{what}: nothing drawn");
        assert_eq!(a.stats.fragments, b.stats.fragments, "{what}");
        same(&a.pixels, &b.pixels, &format!("{what}: colour"));
        same(&a.depths, &b.depths, &format!("{what}: depth"));
        same(&a.triangles, &b.triangles, &format!("{what}: primitives"));
        // The unit did the rasterizer kernels' work: they never ran, and it appears in the
        // breakdown and in its own occupancy, not the clusters'.
        let ran = |f: &Frame, k: &str| f.stats.kernels.iter().any(|s| s.kernel == k);
        for k in ["baryprep", "xyprep", "xyrast", "irast"] {
            assert!(ran(&a, k) && !ran(&b, k), "{what}: {k}");
        }
        assert!(ran(&b, "hwrast") && !ran(&a, "hwrast"), "{what}");
        let occupancy = b.stats.rasterizer_occupancy.expect("the unit's occupancy");
        assert!(occupancy > 0.0 && occupancy < 1.0, "{what}: {occupancy}");
        assert!(a.stats.rasterizer_occupancy.is_none(), "{what}");
        assert_eq!(
            b.stats.attribution.total(),
            b.stats.cycles,
            "{what}: {:?}",
            b.stats.attribution
        );
    }
}

/// With a small SRF the unit's output streams fill: the call stops, the host splits the
/// scissor tile and calls again, and the frame is still gold8's.
#[test]
fn an_overflowing_call_is_split_into_tiles_and_draws_the_same_frame() {
    let small = |base: &str| {
        let text = format!("name = \"small\"\nbase = \"{base}\"\n[srf]\nwords = 7168\n");
        MachineDesc::parse(&text, "small").unwrap()
    };
    let scene = blended();
    let (a, b) = (
        render(&scene, &small("gold8")),
        render(&scene, &small("gold8+hwrast")),
    );
    assert!(b.stats.tile_splits > 0, "no call overflowed");
    assert_eq!(a.stats.fragments, b.stats.fragments);
    same(&a.pixels, &b.pixels, "colour");
    same(&a.depths, &b.depths, "depth");
    same(&a.triangles, &b.triangles, "primitives");
}
