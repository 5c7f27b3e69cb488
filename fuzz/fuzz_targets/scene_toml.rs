//! Scene files (TOML): `scene::file::parse` as the CLI calls it (no size or subdivision
//! override), assets from [`scene_assets`] (the OBJ meshes of `verif/tests/scenes/`, patch
//! files and PNG textures).
#![no_main]

use imagine_fuzz::{
    assert_scene_invariants, scene_assets, scene_seeds, text, write_seeds_if_asked,
};
use imagine_pipelines::scene::LoadOptions;
use imagine_pipelines::scene::file::parse;
use libfuzzer_sys::fuzz_target;

fuzz_target!(init: write_seeds_if_asked(scene_seeds), |data: &[u8]| {
    let Some(text) = text(data) else { return };
    let path = scene_assets().join("fuzz.toml");
    if let Ok(scene) = parse(text, &path, &LoadOptions::default()) {
        assert_scene_invariants(&scene);
    }
});
