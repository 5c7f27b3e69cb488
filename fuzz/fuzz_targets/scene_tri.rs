//! `.tri` window-space triangle files: `scene::parse_tri`, the scene's own validation, and
//! the scene model `load_tri` makes of it.
#![no_main]

use imagine_fuzz::{assert_scene_invariants, text, write_seeds_if_asked};
use imagine_pipelines::scene::{parse_tri, window_scene};
use libfuzzer_sys::fuzz_target;

fuzz_target!(init: write_seeds_if_asked(seeds), |data: &[u8]| {
    let Some(text) = text(data) else { return };
    let Ok(scene) = parse_tri("fuzz.tri", text) else {
        return;
    };
    scene.validate().expect("a parsed .tri scene is valid");
    assert_scene_invariants(&window_scene(scene));
});

/// Small `.tri` files in the format of the `scene` module's documentation.
fn seeds() -> Vec<(String, Vec<u8>)> {
    [
        (
            "one.tri",
            "16 16\n1 1 0.5 1 0 0  14 2 0.5 0 1 0  8 14 0.5 0 0 1\n",
        ),
        (
            "two.tri",
            "# two overlapping triangles\n32 24\n\
             0 0 0.2 1 1 1  31.5 0 0.2 1 1 1  0 23.5 0.2 1 1 1   # back\n\
             4.25 3 0.1 0 0.5 1  30 20 0.9 1 0.5 0  2 22 0.1 0.3 0.3 0.3\n",
        ),
        (
            "edge.tri",
            "1 1\n0 0 0 0 0 0  1 0 1 1 1 1  0 1 0 0.5 0.5 0.5\n",
        ),
    ]
    .map(|(n, t)| (n.to_string(), t.as_bytes().to_vec()))
    .to_vec()
}
