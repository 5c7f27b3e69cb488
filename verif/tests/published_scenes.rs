//! The analogs of the thesis's published OpenGL scenes (Owens 2002, Table 5.1) in
//! `scenes/`: their vertex and triangle counts exactly as published, and their fragments
//! — every pixel centre covered by a front-facing, unculled triangle, summed over the
//! triangles, before the depth test — within 10 % of the published counts, measured with
//! the f64 reference's rasterization.

use imagine_pipelines::scene::model::{Scene, Shader};
use imagine_pipelines::scene::{LoadOptions, load};
use imagine_verif::reference::TieRule;
use imagine_verif::reference_model;

/// Rasterized fragments before the depth test. Only coverage counts, so the materials'
/// textures are left out (sampling them would only take time), except a `bump_env`
/// material's environment map, which its shader needs (VERONA's coverage includes its
/// displacement).
fn fragments(scene: &Scene) -> u64 {
    let mut plain = scene.clone();
    for m in &mut plain.materials {
        if !matches!(m.shader, Shader::BumpEnv(_)) {
            m.textures.clear();
        }
    }
    let mut n = 0;
    reference_model::for_each_fragment(&plain, TieRule::TopLeft, |_| n += 1).unwrap();
    n
}

/// Table 5.1: (scene, vertices, triangles, fragments).
const PUBLISHED: [(&str, usize, usize, u64); 7] = [
    ("SPHERE", 245_760, 81_920, 180_909),
    ("ADVS-1", 62_576, 25_704, 70_384),
    ("ADVS-8", 62_576, 25_704, 70_384),
    ("PIN", 80_000, 80_000, 91_591),
    ("PIN-8", 80_000, 80_000, 91_591),
    ("MARBLE", 80_000, 80_000, 91_594),
    ("VERONA", 80_000, 80_000, 266_810),
];

/// Checks the counts, printing the fragments; a fragment count off by more than 10 % is
/// returned as a message.
fn check(scene: &Scene, (v, t, f): (usize, usize, u64)) -> Option<String> {
    assert_eq!(
        (scene.vertices(), scene.triangles()),
        (v, t),
        "{}",
        scene.name
    );
    let measured = fragments(scene);
    let off = measured as f64 / f as f64 - 1.0;
    println!(
        "{}: {} vertices, {} triangles, {measured} fragments ({:+.1} % of {f})",
        scene.name,
        scene.vertices(),
        scene.triangles(),
        100.0 * off
    );
    (off.abs() > 0.10).then(|| format!("{}: {measured} fragments, {f} published", scene.name))
}

#[test]
fn published_scenes_have_the_published_counts() {
    let mut wrong = Vec::new();
    for (name, v, t, f) in PUBLISHED {
        let scene = load(name, &LoadOptions::default()).unwrap();
        assert_eq!((scene.width, scene.height), (720, 720), "{name}");
        wrong.extend(check(&scene, (v, t, f)));
    }
    assert!(wrong.is_empty(), "{wrong:#?}");
}

/// The pixels `scene` shows after the depth test (the f64 reference) and how far that is
/// from `published`, as a fraction.
fn visible_against(scene: &Scene, published: f64) -> (usize, f64) {
    let (_, shown) = reference_model::render_visible(scene).unwrap();
    let visible = shown.iter().filter(|t| t.is_some()).count();
    (visible, visible as f64 / published - 1.0)
}

/// Table 8.1's TEAPOT-N (Owens et al. 2002; the thesis's ch. 8): 28 patches diced N × N and
/// sent as stitched strips, `56·N·(N + 1)` triangles, and about 137k visible fragments
/// (pixels showing the teapot after the depth test) whatever N, within 10 %.
#[test]
fn teapot_n_has_the_published_triangles_and_visible_fragments() {
    let mut wrong = Vec::new();
    for n in [20usize, 30, 40, 64] {
        let scene = load(&format!("TEAPOT-{n}"), &LoadOptions::default()).unwrap();
        assert_eq!((scene.width, scene.height), (720, 720));
        assert_eq!(scene.triangles(), 56 * n * (n + 1), "TEAPOT-{n}");
        let (visible, off) = visible_against(&scene, 137_000.0);
        println!(
            "TEAPOT-{n}: {visible} visible fragments ({:+.1} %)",
            100.0 * off
        );
        if off.abs() > 0.10 {
            wrong.push(format!(
                "TEAPOT-{n}: {visible} visible fragments, 137k published"
            ));
        }
    }
    assert!(wrong.is_empty(), "{wrong:#?}");
}

/// Table 8.1's PIN (through Reyes: 12 B-spline patches): PIN-PATCHES is 12 patches, diced
/// 58 × 58 for OpenGL (80,736 triangles, as PIN's 80,000 within 1 %), and shows about the
/// published 91.6k fragments, within 10 %.
#[test]
fn pin_patches_has_twelve_patches_and_the_published_fragments() {
    let scene = load("PIN-PATCHES", &LoadOptions::default()).unwrap();
    assert_eq!((scene.width, scene.height), (720, 720));
    assert_eq!(scene.objects[0].patches.len(), 12);
    assert_eq!(scene.triangles(), 12 * 58 * 58 * 2);
    let (visible, off) = visible_against(&scene, 91_600.0);
    assert!(
        off.abs() <= 0.10,
        "{visible} visible fragments, 91.6k published"
    );
}

/// Table 8.1's ARMADILLO stand-in: SPOT-CAGE, Spot's Catmull-Clark control mesh (180
/// faces: 160 quads, 16 pentagons, 4 triangles) refined once into 732 quads, a patch each,
/// diced 8 × 8 for OpenGL, showing about ARMADILLO's published 93.7k fragments, within
/// 10 %.
#[test]
fn spot_cage_has_its_patches_and_the_published_fragments() {
    let scene = load("SPOT-CAGE", &LoadOptions::default()).unwrap();
    assert_eq!(scene.objects[0].patches.len(), 160 * 4 + 16 * 5 + 4 * 3);
    assert_eq!(scene.triangles(), 732 * 8 * 8 * 2);
    let (visible, off) = visible_against(&scene, 93_700.0);
    assert!(
        off.abs() <= 0.10,
        "{visible} visible fragments, 93.7k published"
    );
}
