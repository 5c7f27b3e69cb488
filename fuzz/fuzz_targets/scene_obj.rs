//! Wavefront OBJ meshes: `scene::obj::parse`, lit (geometric normals where the file has
//! none) and unlit.
#![no_main]

use imagine_fuzz::{assert_mesh_invariants, text};
use imagine_pipelines::scene::obj::parse;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some(text) = text(data) else { return };
    for lit in [false, true] {
        if let Ok(mesh) = parse(text, lit) {
            assert_mesh_invariants(&mesh);
        }
    }
});
