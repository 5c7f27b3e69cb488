//! No crack and no pinhole in a closed patch model no one here wrote, through the Reyes
//! pipeline: Keenan Crane's cow Spot, her Catmull-Clark control mesh (`SPOT-CAGE`: 732
//! patches after one Catmull-Clark step; 100 extraordinary vertices, of valence 3, 5 and
//! 6, where patches of different subdivision depths meet at odd angles).
//!
//! Against the f64 reference drawing the same patches diced 64 × 64: every pixel the
//! reference covers whose eight neighbours it covers too (inside the silhouette) is
//! covered by Reyes. Along the silhouette the two may differ by a pixel: Reyes subdivides
//! the patches projected to window space (the projected polynomial, not the rational
//! patch), so a few silhouette pixels' centres fall on the other side.
//!
//! `#[ignore]`d: the Reyes kernels for the window take minutes to compile cold (`cargo
//! test -p imagine-verif --test reyes_cracks -- --ignored`).

use imagine_pipelines::compile::CompileCache;
use imagine_pipelines::reyes::frame::{ReyesOptions, render};
use imagine_pipelines::scene::bpt::{self, Basis};
use imagine_pipelines::scene::{LoadOptions, load};
use imagine_units::desc::MachineDesc;
use imagine_verif::reference_model;

#[test]
#[ignore = "compiles the Reyes kernels for a 96x96 window: minutes cold"]
fn a_closed_cage_through_reyes_has_no_crack_or_pinhole() {
    let size = 96u32;
    let desc = MachineDesc::resolve("reyes").unwrap();
    let scene = load(
        "SPOT-CAGE",
        &LoadOptions {
            size: Some(size),
            subdivisions: None,
            filter: None,
        },
    )
    .unwrap();
    let options = ReyesOptions {
        cache: CompileCache::at(concat!(env!("CARGO_TARGET_TMPDIR"), "/compile-cache")),
        ..ReyesOptions::default()
    };
    let frame = render(&scene, &desc, &options).unwrap_or_else(|e| panic!("{e}"));
    let mut dense = scene.clone();
    for o in &mut dense.objects {
        let patches: Vec<bpt::Patch> = o
            .patches
            .iter()
            .map(|p| p.map(|q| q.map(f64::from)))
            .collect();
        o.mesh = bpt::tessellate(&patches, Basis::Bezier, 64, false);
    }
    let (_, shown) = reference_model::render_visible(&dense).unwrap();
    let w = size as i64;
    let at = |x: i64, y: i64| (0..w).contains(&x) && (0..w).contains(&y);
    let reference = |x: i64, y: i64| at(x, y) && shown[(y * w + x) as usize].is_some();
    let drawn = |x: i64, y: i64| frame.depth[(y * w + x) as usize] < 1.0;
    let (mut covered, mut missing, mut holes) = (0, 0, Vec::new());
    for y in 0..w {
        for x in 0..w {
            if !reference(x, y) {
                continue;
            }
            covered += 1;
            if drawn(x, y) {
                continue;
            }
            missing += 1;
            let inside = (-1..=1).all(|dy| (-1..=1).all(|dx| reference(x + dx, y + dy)));
            if inside {
                holes.push((x, y));
            }
        }
    }
    assert!(covered > 1000, "{covered} pixels covered");
    assert!(
        holes.is_empty(),
        "pinholes inside the silhouette: {holes:?}"
    );
    assert!(
        missing * 100 < covered,
        "{missing} of {covered} silhouette pixels missing"
    );
}
