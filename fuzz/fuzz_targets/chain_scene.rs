//! The scene chain: a scene file's text → `scene::file::parse` into a 16 × 16 window with
//! icospheres of at most one subdivision → `plan_pipeline` on gold8 (vertex programs,
//! batch size, SRF plan). Rendering is left out: it compiles kernels for each new pipeline
//! (seconds) and its cycle budget is not a parameter.
#![no_main]

use imagine_fuzz::{
    assert_scene_invariants, gold8, scene_assets, scene_seeds, text, write_seeds_if_asked,
};
use imagine_pipelines::opengl::render::{RenderOptions, plan_pipeline};
use imagine_pipelines::scene::LoadOptions;
use imagine_pipelines::scene::file::parse;
use libfuzzer_sys::fuzz_target;

fuzz_target!(init: write_seeds_if_asked(scene_seeds), |data: &[u8]| {
    let Some(text) = text(data) else { return };
    let path = scene_assets().join("fuzz.toml");
    let opts = LoadOptions {
        size: Some(16),
        subdivisions: Some((data.len() % 2) as u32),
        filter: None,
    };
    let Ok(scene) = parse(text, &path, &opts) else {
        return;
    };
    assert_scene_invariants(&scene);
    let Ok(plan) = plan_pipeline(&scene, gold8(), &RenderOptions::default()) else {
        return;
    };
    assert!(plan.batch > 0);
    let _ = (
        plan.kernel_names(),
        plan.left_out(),
        plan.words_per_vertex(),
        plan.interpolants(),
    );
});
