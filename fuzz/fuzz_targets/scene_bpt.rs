//! Bicubic patch files (`.bpt`): `scene::bpt::parse`, then each patch diced into a few
//! quads per side in both bases, plain and stitched.
#![no_main]

use imagine_fuzz::{assert_mesh_invariants, bpt_seeds, text, write_seeds_if_asked};
use imagine_pipelines::scene::bpt::{Basis, parse, tessellate};
use libfuzzer_sys::fuzz_target;

fuzz_target!(init: write_seeds_if_asked(seeds), |data: &[u8]| {
    let Some(text) = text(data) else { return };
    let Ok(patches) = parse(text) else { return };
    let n = 1 + (data.len() % 4) as u32;
    for basis in [Basis::Bezier, Basis::BSpline] {
        for stitch in [false, true] {
            let mesh = tessellate(&patches, basis, n, stitch);
            let per_row = 2 * n + 2 * u32::from(stitch);
            assert_eq!(mesh.triangles.len(), patches.len() * (per_row * n) as usize);
            assert_mesh_invariants(&mesh);
        }
    }
});

/// The patch files of [`bpt_seeds`].
fn seeds() -> Vec<(String, Vec<u8>)> {
    bpt_seeds()
        .into_iter()
        .map(|(n, t)| (n, t.into_bytes()))
        .collect()
}
