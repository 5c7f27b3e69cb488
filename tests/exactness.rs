//! Exactness of a faster simulator: every machine in `machines/` (but the Reyes machines,
//! whose `subdiv` takes minutes to compile cold) and the published scenes beside them give
//! the frame, cycle count and statistics recorded with the simulator before its speed work
//! (commit 4822c00, whose results equal those of the commits before it). The scenes of
//! millions of cycles are `#[ignore]`d: `cargo test --release --test exactness -- --ignored`.
//!
//! A case's digest is the FNV-1a hash of its pixels, its frame cycles and the FNV-1a hash
//! of its statistics as JSON, the host's times left out. After a change meant to change
//! results, print the digests again with `IMAGINE_RECORD_DIGESTS=1 cargo test --release
//! --test exactness -- --nocapture --include-ignored`, and say why they changed.

use imagine_pipelines::compile::CompileCache;
use imagine_pipelines::opengl::render::{Frame, Rasterizer, RenderOptions, render_with};
use imagine_pipelines::scene::{self, LoadOptions};
use imagine_units::desc::MachineDesc;

/// One frame: scene, window size, sphere subdivisions, machine, rasterizer.
struct Case {
    scene: &'static str,
    size: u32,
    subdivisions: Option<u32>,
    machine: &'static str,
    scanline: bool,
}

const fn case(scene: &'static str, size: u32, machine: &'static str) -> Case {
    Case {
        scene,
        size,
        subdivisions: None,
        machine,
        scanline: false,
    }
}

const fn sphere(machine: &'static str) -> Case {
    Case {
        subdivisions: Some(2),
        ..case("SPHERE", 32, machine)
    }
}

/// Every OpenGL machine, each on a scene it is for, and the small published scenes on
/// gold8.
const CASES: [Case; 19] = [
    sphere("gold1"),
    sphere("gold2"),
    sphere("gold4"),
    sphere("gold8"),
    sphere("gold16"),
    sphere("gold32"),
    sphere("gold8+F"),
    sphere("gold8+C"),
    sphere("gold8+F+C"),
    sphere("gold8+srf4x"),
    sphere("gold32combo"),
    case("ADVS-1", 24, "gold32combo+tc1"),
    case("ADVS-1", 24, "gold32combo+tc4"),
    case("ADVS-1", 24, "gold32combo+tc32"),
    case("ADVS-8", 32, "gold8+hwrast"),
    case("ADVS-1", 24, "gold8"),
    case("RATE-1", 16, "gold8"),
    case("RATE-8", 32, "gold8"),
    Case {
        subdivisions: Some(2),
        scanline: true,
        ..case("SPHERE-FULL", 32, "gold8")
    },
];

/// `(pixels hash, frame cycles, statistics hash)` of each case, in the order of [`CASES`],
/// as the simulator of commit 4822c00 gave them.
const RECORDED: [(u64, u64, u64); 19] = [
    (0xf875c6affb235c86, 222620, 0x95d045587d55959b),
    (0xf875c6affb235c86, 114186, 0x8453c07d19d2110d),
    (0xf875c6affb235c86, 61728, 0x63e931fe688d37c8),
    (0xf875c6affb235c86, 39925, 0xec8a4659019ff321),
    (0xf875c6affb235c86, 29560, 0x8942a1ab9a4e6618),
    (0xf875c6affb235c86, 27733, 0xf5df321ec5c3cf58),
    (0xf875c6affb235c86, 25730, 0xaca74170c1982370),
    (0xf875c6affb235c86, 39877, 0x9970d8cf047bd1a7),
    (0xf875c6affb235c86, 25479, 0xff4b29e7e9171f68),
    (0xf875c6affb235c86, 39925, 0x5a27790e3e27cc90),
    (0xf875c6affb235c86, 25679, 0xb0e85c0944b3f2f7),
    (0x8ee9ad1b41cab07d, 1420416, 0x2a70404bb643c64a),
    (0x8ee9ad1b41cab07d, 1421255, 0x33719938c17676d0),
    (0x8ee9ad1b41cab07d, 1422258, 0xb9342cce435cf573),
    (0xfa0a3e84fef0a3ff, 1315230, 0xf8c60cf4bdf7673d),
    (0x8ee9ad1b41cab07d, 1472123, 0xf970991a488d562b),
    (0x8d052aab5c2685a5, 16787, 0x7c0a29a0d39c2a12),
    (0xab903a875eb29925, 29949, 0x2e93799f9013d5b8),
    (0xf8e8104a3f70664a, 65533, 0x8d5d425f35bbc048),
];

/// The published scenes of millions of cycles whatever the window (their geometry and
/// textures are the work), on gold8.
const HEAVY: [Case; 5] = [
    case("PIN", 32, "gold8"),
    case("PIN-8", 32, "gold8"),
    case("MARBLE", 24, "gold8"),
    case("VERONA", 32, "gold8"),
    case("SPOT-CAGE", 32, "gold8"),
];

const HEAVY_RECORDED: [(u64, u64, u64); 5] = [
    (0xffbfb91948fc5028, 5688404, 0xf97b12d02f443b47),
    (0x4fd0eb255b3a25a1, 6522485, 0x2905a3a2bff2dd2e),
    (0x4c67afa78a2b9666, 7703464, 0x940ebfffc4379876),
    (0x1efcc394a3dd6755, 12072607, 0x3858404189b24764),
    (0x4eb2d7185f27f2df, 8536647, 0x6d003ca4e8c809bf),
];

/// FNV-1a over bytes.
fn fnv(bytes: impl IntoIterator<Item = u8>) -> u64 {
    bytes.into_iter().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// The frame's statistics without what the host's speed changes.
fn machine_stats(f: &Frame) -> String {
    let mut json = serde_json::to_value(&f.stats).unwrap();
    let obj = json.as_object_mut().unwrap();
    for host in [
        "host_seconds",
        "compile_seconds",
        "simulate_seconds",
        "simulated_cycles_per_second",
        "kernels_from_cache",
    ] {
        obj.remove(host);
    }
    format!("{json}\n{}", f.stats.batches_csv())
}

fn digest(c: &Case) -> (u64, u64, u64) {
    let scene = scene::load(
        c.scene,
        &LoadOptions {
            size: Some(c.size),
            subdivisions: c.subdivisions,
            filter: None,
        },
    )
    .unwrap();
    let desc = MachineDesc::resolve(c.machine).unwrap();
    let options = RenderOptions {
        cache: CompileCache::at(concat!(env!("CARGO_TARGET_TMPDIR"), "/compile-cache")),
        rasterizer: if c.scanline {
            Rasterizer::Scanline
        } else {
            Rasterizer::Barycentric
        },
        ..RenderOptions::default()
    };
    let f = render_with(&scene, &desc, options, None, |_, _| {})
        .unwrap_or_else(|e| panic!("{} on {}: {e}", c.scene, c.machine));
    (
        fnv(f.pixels.iter().flat_map(|p| p.to_le_bytes())),
        f.stats.cycles,
        fnv(machine_stats(&f).into_bytes()),
    )
}

/// Renders every case and names those whose digest differs from the recorded one (or, with
/// `IMAGINE_RECORD_DIGESTS` set, prints the digests instead).
fn check(cases: &[Case], recorded: &[(u64, u64, u64)]) {
    let record = std::env::var_os("IMAGINE_RECORD_DIGESTS").is_some();
    let mut differ = Vec::new();
    for (c, &want) in cases.iter().zip(recorded) {
        let got = digest(c);
        if record {
            println!("    ({:#018x}, {}, {:#018x}),", got.0, got.1, got.2);
        } else if got != want {
            differ.push(format!(
                "{} {}px on {}: (pixels, cycles, stats) {got:x?}, recorded {want:x?}",
                c.scene, c.size, c.machine
            ));
        }
    }
    assert!(differ.is_empty(), "{}", differ.join("\n"));
}

#[test]
fn every_machine_and_small_scene_gives_the_recorded_frame_cycles_and_statistics() {
    check(&CASES, &RECORDED);
}

#[test]
#[ignore = "30 M cycles: cargo test --release --test exactness -- --ignored"]
fn the_heavy_published_scenes_give_the_recorded_frame_cycles_and_statistics() {
    check(&HEAVY, &HEAVY_RECORDED);
}
