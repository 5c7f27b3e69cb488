//! Frames through the OpenGL-like pipeline on the clocked machine: what the pipeline built
//! for a scene computes and leaves out.

use imagine_pipelines::compile::CompileCache;
use imagine_pipelines::opengl::render::{RenderOptions, render_with};
use imagine_pipelines::scene::model::{Cull, DepthTest, Scene};
use imagine_pipelines::scene::{self, LoadOptions, parse_tri, window_scene};
use imagine_units::desc::MachineDesc;
use imagine_units::ops::Datapath;

/// Render options with a compile cache under the target directory, so that the tests share
/// the kernels they compile (and a re-run compiles nothing).
fn cached() -> RenderOptions {
    RenderOptions {
        cache: CompileCache::at(concat!(env!("CARGO_TARGET_TMPDIR"), "/compile-cache")),
        ..RenderOptions::default()
    }
}

fn two_triangles() -> Scene {
    window_scene(
        parse_tri(
            "two",
            "32 32\n\
             2 2 0.5 1 0 0  30 2 0.5 1 0 0  2 30 0.5 1 0 0\n\
             4 4 0.25 0 1 0  28 4 0.25 0 1 0  16 28 0.75 0 1 0\n",
        )
        .unwrap(),
    )
}

#[test]
fn two_overlapping_triangles() {
    let scene = two_triangles();
    let desc = MachineDesc::gold8();
    let f = render_with(&scene, &desc, cached(), None, |_, _| {}).unwrap();
    assert_eq!(f.pixels[3 * 32 + 3] & 0xFFFFFF, 0xFF, "red corner");
    assert_eq!(
        f.pixels[8 * 32 + 16] & 0xFFFFFF,
        0xFF00,
        "green in front at the bottom"
    );
    assert_eq!(f.pixels[31 * 32 + 31], 0xFF00_0000, "the clear colour");
    assert!(f.stats.phases.clear_cycles > 0 && f.stats.phases.readback_cycles > 0);
    assert!(f.stats.phases.frame_plus_clear_cycles == f.stats.cycles + f.stats.phases.clear_cycles);
}

#[test]
fn depth_tests_and_culling_follow_the_scene() {
    let desc = MachineDesc::gold8();
    let mut scene = two_triangles();
    // ALWAYS: the later (green) triangle wins where they overlap, even behind.
    scene.pipeline.depth_test = DepthTest::Always;
    let f = render_with(&scene, &desc, cached(), None, |_, _| {}).unwrap();
    assert_eq!(
        f.pixels[17 * 32 + 12] & 0xFFFFFF,
        0xFF00,
        "ALWAYS: the later triangle"
    );
    scene.pipeline.depth_test = DepthTest::Less;
    let f = render_with(&scene, &desc, cached(), None, |_, _| {}).unwrap();
    assert_eq!(
        f.pixels[17 * 32 + 12] & 0xFFFFFF,
        0xFF,
        "LESS: the nearer triangle"
    );
    // Both triangles are counter-clockwise (front-facing): culling front faces leaves the
    // clear colour.
    scene.pipeline.cull = Cull::Front;
    let f = render_with(&scene, &desc, cached(), None, |_, _| {}).unwrap();
    assert!(
        f.pixels.iter().all(|&p| p == 0xFF00_0000),
        "front faces culled"
    );
    scene.pipeline.cull = Cull::Back;
    scene.background = [1.0, 0.0, 0.0];
    let f = render_with(&scene, &desc, cached(), None, |_, _| {}).unwrap();
    assert_eq!(
        f.pixels[8 * 32 + 16] & 0xFFFFFF,
        0xFF00,
        "back culling keeps them"
    );
    assert_eq!(
        f.pixels[31 * 32 + 31],
        0xFF00_00FF,
        "the background clears red"
    );
}

/// A 12×12 grid of quads in window space (288 triangles) with colours per vertex, as a
/// mesh of shared vertices or as separate triangles.
fn grid(separate: bool) -> Scene {
    let mut text = String::from("48 48\n");
    let colour = |x: u32, y: u32| [x as f32 / 48.0, y as f32 / 48.0, 0.5];
    for j in 0..12u32 {
        for i in 0..12u32 {
            let (x0, y0) = (i * 4, j * 4);
            let corners = [(x0, y0), (x0 + 4, y0), (x0 + 4, y0 + 4), (x0, y0 + 4)];
            for tri in [[0, 1, 2], [0, 2, 3]] {
                for k in tri {
                    let (x, y) = corners[k];
                    let [r, g, b] = colour(x, y);
                    text += &format!("{x} {y} 0.5 {r} {g} {b}  ");
                }
                text += "\n";
            }
        }
    }
    let mut scene = window_scene(parse_tri("grid", &text).unwrap());
    if !separate {
        // Merge equal positions into shared vertices.
        let mesh = &mut scene.objects[0].mesh;
        let mut positions: Vec<[f32; 3]> = Vec::new();
        let mut colours = Vec::new();
        let mut index = Vec::new();
        for (p, c) in mesh.positions.iter().zip(&mesh.colours) {
            let i = positions.iter().position(|q| q == p).unwrap_or_else(|| {
                positions.push(*p);
                colours.push(*c);
                positions.len() - 1
            });
            index.push(i as u32);
        }
        mesh.triangles = index.chunks(3).map(|t| [t[0], t[1], t[2]]).collect();
        mesh.positions = positions;
        mesh.colours = colours;
        mesh.separate = false;
    }
    scene
}

#[test]
fn a_mesh_shades_each_vertex_once_per_batch_and_draws_what_separate_triangles_draw() {
    let desc = MachineDesc::gold8();
    let shared = render_with(&grid(false), &desc, cached(), None, |_, _| {}).unwrap();
    let separate = render_with(&grid(true), &desc, cached(), None, |_, _| {}).unwrap();
    assert_eq!(shared.pixels, separate.pixels, "the same image");
    assert_eq!(separate.stats.vertices, 3 * 288);
    // 169 distinct vertices; a batch of 64 triangles (about 2.7 rows of the grid) uses
    // about 4.7 rows of 13: far fewer than 3 per triangle.
    assert!(
        shared.stats.vertices < 288 + 13 * 5 * 5,
        "{} vertices shaded",
        shared.stats.vertices
    );
    let kernels = |f: &imagine_pipelines::opengl::render::Frame| {
        f.stats
            .kernels
            .iter()
            .map(|k| k.kernel.clone())
            .collect::<Vec<_>>()
    };
    assert!(kernels(&shared).contains(&"vertex_unlit".to_string()));
}

#[test]
fn an_unlit_scene_builds_no_lighting_and_no_merge_it_never_reaches() {
    let desc = MachineDesc::gold8();
    let scene = scene::load(
        "RATE-8",
        &LoadOptions {
            size: Some(32),
            subdivisions: None,
            filter: None,
        },
    )
    .unwrap();
    let f = render_with(&scene, &desc, cached(), None, |_, _| {}).unwrap();
    let sp = &f.stats.specialisation;
    assert!(sp.specialised);
    assert!(
        sp.kernels_built
            .iter()
            .all(|k| !k.contains("lit") || k.contains("unlit")),
        "{:?}",
        sp.kernels_built
    );
    assert!(
        sp.kernels_built
            .iter()
            .all(|k| k != "sort32" && k != "mergefrag")
    );
    assert_eq!(sp.kernels_not_reached, ["sort32", "mergefrag"]);
    assert!(sp.left_out.iter().any(|f| f == "lighting"));
    let general = render_with(
        &scene,
        &desc,
        RenderOptions {
            specialise: false,
            ..cached()
        },
        None,
        |_, _| {},
    )
    .unwrap();
    assert_eq!(
        general.pixels, f.pixels,
        "the general pipeline draws the same"
    );
    assert!(
        general
            .stats
            .specialisation
            .kernels_built
            .iter()
            .any(|k| k == "sort32")
    );
}

#[test]
fn unsupported_scenes_and_shapes_are_refused_by_name() {
    let desc = MachineDesc::gold8();
    let mut scene = two_triangles();
    scene.pipeline.kind = imagine_pipelines::scene::model::PipelineKind::Reyes;
    let e = render_with(&scene, &desc, cached(), None, |_, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("Reyes"), "{e}");
    let mut lit = scene::load(
        "SPHERE-FULL",
        &LoadOptions {
            size: Some(16),
            subdivisions: Some(0),
            filter: None,
        },
    )
    .unwrap();
    lit.materials[0].shininess = 12.5;
    let e = render_with(&lit, &desc, cached(), None, |_, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("shininess"), "{e}");
}

#[test]
fn the_general_pipeline_lights_a_lit_scene_to_the_same_bits() {
    let desc = MachineDesc::gold8();
    let scene = scene::load(
        "SPHERE-FULL",
        &LoadOptions {
            size: Some(24),
            subdivisions: Some(1),
            filter: None,
        },
    )
    .unwrap();
    let special = render_with(&scene, &desc, cached(), None, |_, _| {}).unwrap();
    let general = render_with(
        &scene,
        &desc,
        RenderOptions {
            specialise: false,
            ..cached()
        },
        None,
        |_, _| {},
    )
    .unwrap();
    assert_eq!(
        general.pixels, special.pixels,
        "the same image, bit for bit"
    );
    let built = &general.stats.specialisation.kernels_built;
    assert!(
        built.iter().any(|k| k == "vertex_general3_s16"),
        "{built:?}"
    );
    assert_eq!(general.stats.specialisation.words_per_vertex, 9);
    assert_eq!(special.stats.specialisation.words_per_vertex, 6);
}

#[test]
fn five_lights_are_shaded_in_two_passes_and_add_light() {
    use imagine_pipelines::scene::model::Light;
    let desc = MachineDesc::gold8();
    let mut three = scene::load(
        "SPHERE-FULL",
        &LoadOptions {
            size: Some(24),
            subdivisions: Some(1),
            filter: None,
        },
    )
    .unwrap();
    assert_eq!(three.lights.len(), 3);
    // A small matte sphere in front: its program has no specular term, so its records
    // between passes are shorter than the big sphere's.
    let mut matte = three.materials[0].clone();
    matte.name = "matte".into();
    matte.specular = [0.0; 3];
    three.materials.push(matte);
    let mut small = three.objects[0].clone();
    small.name = "small".into();
    small.material = 1;
    #[rustfmt::skip]
    let model = [
        0.3, 0.0, 0.0, 0.6,
        0.0, 0.3, 0.0, 0.6,
        0.0, 0.0, 0.3, 1.0,
        0.0, 0.0, 0.0, 1.0,
    ];
    small.model = model;
    three.objects.push(small);
    let mut five = three.clone();
    five.lights.push(Light {
        position: [6.0, -2.0, 2.0],
        ambient: [0.0; 3],
        diffuse: [0.3, 0.6, 0.3],
        specular: [0.3, 0.6, 0.3],
    });
    five.lights.push(Light {
        position: [-3.0, 5.0, 5.0],
        ambient: [0.0; 3],
        diffuse: [0.4, 0.2, 0.4],
        specular: [0.4, 0.2, 0.4],
    });
    let before = render_with(&three, &desc, cached(), None, |_, _| {}).unwrap();
    let after = render_with(&five, &desc, cached(), None, |_, _| {}).unwrap();
    let built = &after.stats.specialisation.kernels_built;
    for k in [
        "vertex_lit5_s16",
        "vertex_lit5_s16:pass1",
        "vertex_lit5_diffuse",
        "vertex_lit5_diffuse:pass1",
    ] {
        assert!(built.iter().any(|b| b == k), "{k} not in {built:?}");
    }
    assert!(
        !before
            .stats
            .specialisation
            .kernels_built
            .iter()
            .any(|k| k.contains(":pass")),
        "three lights take one kernel"
    );
    assert_ne!(before.pixels, after.pixels);
    let brightness = |f: &imagine_pipelines::opengl::render::Frame| -> u64 {
        f.pixels
            .iter()
            .map(|&p| (0..3).map(|i| u64::from(p >> (8 * i) & 0xFF)).sum::<u64>())
            .sum()
    };
    assert!(
        brightness(&after) > brightness(&before),
        "two more lights brighten the sphere"
    );
    // Every channel of every pixel: the same geometry, only more light.
    for (i, (&a, &b)) in after.pixels.iter().zip(&before.pixels).enumerate() {
        for ch in 0..3 {
            let (a, b) = (a >> (8 * ch) & 0xFF, b >> (8 * ch) & 0xFF);
            assert!(a >= b, "pixel {i} channel {ch}: {a} < {b}");
        }
    }
}

#[test]
fn kernels_a_small_microcode_store_evicts_are_loaded_again() {
    // 288 triangles in 5 batches: every batch calls `xyrast` (344 instructions on gold8)
    // and the kernels after it, which do not fit beside it in 400 words.
    let desc = MachineDesc::gold8();
    let mut small = desc.clone();
    small.microcontroller.store_words = 400;
    let scene = grid(true);
    let want = render_with(&scene, &desc, cached(), None, |_, _| {}).unwrap();
    let got = render_with(&scene, &small, cached(), None, |_, _| {}).unwrap();
    assert_eq!(got.pixels, want.pixels);
    assert!(got.stats.cycles > want.stats.cycles, "reloads cost cycles");
}

/// Everything a frame reports but the host's own timings and cache use.
fn machine_results(f: &imagine_pipelines::opengl::render::Frame) -> (serde_json::Value, String) {
    let mut json = serde_json::to_value(&f.stats).unwrap();
    let obj = json.as_object_mut().unwrap();
    for host in [
        "host_seconds",
        "compile_seconds",
        "simulate_seconds",
        "simulated_cycles_per_second",
        "kernels_from_cache",
    ] {
        assert!(obj.remove(host).is_some(), "{host}");
    }
    (json, f.stats.batches_csv())
}

/// RATE-1 in a 16 × 16 window: a frame of many short kernel calls.
fn rate1_16x16() -> Scene {
    scene::load(
        "RATE-1",
        &LoadOptions {
            size: Some(16),
            subdivisions: None,
            filter: None,
        },
    )
    .unwrap()
}

/// A frame whose kernels hold the clusters far longer than they run: stepping through the
/// idle cycles and jumping over them give the same frame and every statistic.
#[test]
fn jumping_over_idle_time_changes_nothing_in_the_frame() {
    let scene = rate1_16x16();
    let gold8 = MachineDesc::gold8();
    let refi = gold8.dram.refresh_interval as u64 * gold8.clocks.core_mhz / gold8.clocks.dram_mhz;
    for min in [20_011, refi + 1] {
        let mut desc = gold8.clone();
        desc.stream_controller.min_kernel_cycles = min;
        let render = |step_idle| {
            let options = RenderOptions {
                step_idle,
                ..cached()
            };
            render_with(&scene, &desc, options, None, |_, _| {}).unwrap()
        };
        let (jumped, stepped) = (render(false), render(true));
        assert_eq!(jumped.pixels, stepped.pixels);
        assert_eq!(machine_results(&jumped), machine_results(&stepped));
        let calls: u64 = jumped.stats.kernels.iter().map(|k| k.calls).sum();
        assert!(jumped.stats.cycles >= calls * min);
        assert!(jumped.stats.skipped_cycles > jumped.stats.cycles / 2);
        assert_eq!(stepped.stats.skipped_cycles, 0);
    }
}

/// ADVS-1 (textured) at 24 × 24.
fn advs1_24x24() -> Scene {
    scene::load(
        "ADVS-1",
        &LoadOptions {
            size: Some(24),
            subdivisions: None,
            filter: None,
        },
    )
    .unwrap()
}

/// The two-phase contract on whole frames: every block computes its next state from
/// committed state only, so evaluating the blocks in the reverse order, and stepping every
/// idle cycle as well, gives the same image, cycles and statistics — on an untextured and a
/// textured scene, on two cluster counts, with a texture cache and with the hardware
/// rasterizer (a mipmapped scene: its fragments carry varyings and derivatives).
#[test]
fn frames_are_the_same_cycle_for_cycle_in_either_evaluation_order() {
    let cases = [
        (rate1_16x16(), MachineDesc::gold8()),
        (rate1_16x16(), MachineDesc::resolve("gold16").unwrap()),
        (advs1_24x24(), MachineDesc::gold8()),
        (advs1_24x24(), gold8_with_texture_cache(1)),
        (
            scene::load(
                "ADVS-8",
                &LoadOptions {
                    size: Some(48),
                    subdivisions: None,
                    filter: None,
                },
            )
            .unwrap(),
            MachineDesc::resolve("gold8+hwrast").unwrap(),
        ),
    ];
    for (scene, desc) in cases {
        let render = |reverse| {
            let options = RenderOptions {
                reverse_eval_order: reverse,
                step_idle: reverse,
                ..cached()
            };
            render_with(&scene, &desc, options, None, |_, _| {}).unwrap()
        };
        let (forward, reversed) = (render(false), render(true));
        let what = format!("{} on {}", scene.name, desc.name);
        assert_eq!(forward.pixels, reversed.pixels, "{what}");
        assert_eq!(
            machine_results(&forward),
            machine_results(&reversed),
            "{what}"
        );
        assert!(
            forward.stats.cycles > 0 && reversed.stats.skipped_cycles == 0,
            "{what}"
        );
    }
}

/// Reads every probe change and keeps none: a tracer attached for the whole run.
struct Discard;

impl imagine_hdl::Tracer for Discard {
    fn start(
        &mut self,
        _: &imagine_hdl::ProbeRegistry,
        _: &[imagine_hdl::ClockDomain],
    ) -> std::io::Result<()> {
        Ok(())
    }
    fn time(&mut self, _: u64, _: u64) {}
    fn change(&mut self, _: imagine_hdl::SignalId, _: &[u64]) {}
    fn finish(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Speed changes nothing else: the host's floating point in place of the bit-level
/// datapath, and a tracer attached (which makes every block latch what its probes show,
/// step the divider's recurrence each cycle, keep the clusters awake and take the bit-level
/// datapath), give the same image, cycles and statistics — on an untextured and a textured
/// scene (the textured one divides).
#[test]
fn frames_are_the_same_with_a_tracer_and_on_either_datapath() {
    let cases = [
        (rate1_16x16(), MachineDesc::gold8()),
        (advs1_24x24(), MachineDesc::resolve("gold16").unwrap()),
    ];
    for (scene, desc) in cases {
        let render = |datapath, traced: bool| {
            let options = RenderOptions {
                datapath,
                ..cached()
            };
            let on_start = traced.then(|| -> imagine_units::runner::OnStart {
                Box::new(|sim| sim.attach(Box::new(Discard)).map_err(|e| e.to_string()))
            });
            render_with(&scene, &desc, options, on_start, |_, _| {}).unwrap()
        };
        let fast = render(Datapath::Host, false);
        for (datapath, traced) in [(Datapath::BitLevel, false), (Datapath::Host, true)] {
            let other = render(datapath, traced);
            let what = format!(
                "{} on {}, {datapath}, traced {traced}",
                scene.name, desc.name
            );
            assert_eq!(fast.pixels, other.pixels, "{what}");
            assert_eq!(machine_results(&fast), machine_results(&other), "{what}");
        }
    }
}

/// gold8 with the thesis's texture cache (16K words, 2-word lines), hits at
/// `hit_words_per_cycle`.
fn gold8_with_texture_cache(hit_words_per_cycle: usize) -> MachineDesc {
    MachineDesc::parse(
        &format!(
            "name = \"gold8+tc\"\nbase = \"gold8\"\n[texture_cache]\nwords = 16384\n\
             line_words = 2\nhit_words_per_cycle = {hit_words_per_cycle}\n"
        ),
        "gold8+tc",
    )
    .unwrap()
}

/// The texture cache serves every texel gather and changes no pixel: each texel word is a
/// hit or a miss, most are hits (neighbouring texels share lines, and fragments texels),
/// and with hits faster than DRAM the gathers wait less than without it.
#[test]
fn a_texture_cache_serves_the_texels_and_changes_no_pixel() {
    let scene = advs1_24x24();
    let render = |desc: &MachineDesc| render_with(&scene, desc, cached(), None, |_, _| {}).unwrap();
    let plain = render(&MachineDesc::gold8());
    assert!(plain.stats.texture_cache.is_none());
    for n in [1, 4] {
        let f = render(&gold8_with_texture_cache(n));
        assert_eq!(f.pixels, plain.pixels, "hits at {n} words per cycle");
        let tc = f
            .stats
            .texture_cache
            .as_ref()
            .expect("the cache's counters");
        let c = &tc.counts;
        assert_eq!(c.hits + c.misses, f.stats.texel_words, "{c:?}");
        assert!(tc.hit_rate > 0.5, "{tc:?}");
        // At ×1 hits come no faster than DRAM words (the generator issues 2 a cycle), so
        // only the wider cache is sure to shorten this small frame's gathers.
        assert!(
            n == 1 || f.stats.attribution.waiting_gather < plain.stats.attribution.waiting_gather,
            "{n}: {} against {}",
            f.stats.attribution.waiting_gather,
            plain.stats.attribution.waiting_gather
        );
    }
}

/// Every frame cycle falls in exactly one category: the categories sum to the frame's cycles
/// and each batch's to its cycles, and kernels run exactly the breakdown's cycles.
#[test]
fn every_frame_cycle_is_attributed_once() {
    let advs = advs1_24x24();
    for scene in [rate1_16x16(), advs] {
        let options = RenderOptions {
            timeline: true,
            ..cached()
        };
        let f = render_with(&scene, &MachineDesc::gold8(), options, None, |_, _| {}).unwrap();
        let s = &f.stats;
        let a = &s.attribution;
        assert_eq!(a.total(), s.cycles, "{}: {a:?}", scene.name);
        let kernels: u64 = s.kernels.iter().map(|k| k.cycles).sum();
        assert_eq!(a.kernel_running, kernels, "{}", scene.name);
        // Depth (and texels) come by gathers; short kernels are held for the minimum time.
        assert!(
            a.waiting_gather > 0 && a.kernel_dispatch > 0,
            "{}: {a:?}",
            scene.name
        );
        // What the waits waited on covers them exactly; gathers wait for DRAM to move data.
        assert_eq!(s.waiting_on.total(), a.waiting(), "{}", scene.name);
        assert!(
            s.waiting_on.dram_bandwidth > 0,
            "{}: {:?}",
            scene.name,
            s.waiting_on
        );
        for row in &s.batch_rows {
            let what = format!("{} batch {}", scene.name, row.batch);
            assert_eq!(row.attribution.total(), row.cycles, "{what}");
            assert_eq!(row.waiting_on.total(), row.attribution.waiting(), "{what}");
        }
        let csv = s.batches_csv();
        let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
        assert!(header.contains(&"waiting_gather_cycles"), "{header:?}");
        // Table 5.3's model on the batches: depth counts with the interpolants, and what
        // the frame held lies within its SRF plan.
        let m = &s.srf_model;
        assert_eq!(m.interpolants, 1 + s.specialisation.interpolants.len());
        assert!(
            0 < m.measured_words && m.measured_words <= m.plan_words,
            "{}: {m:?}",
            scene.name
        );
        let peak = imagine_pipelines::opengl::srf_model::ModelBatch {
            triangles: m.peak_batch_triangles as f64,
            interpolants: m.interpolants as f64,
            fragments_per_triangle: m.peak_batch_fragments_per_triangle,
        };
        assert!(m.barycentric_words > 0.0 && peak.barycentric() == m.barycentric_words);

        // The timeline, read back as plain JSON: its kernel slices ran the breakdown's
        // cycles, and the kernel calls and the waits cover the frame once.
        let text = serde_json::to_string(f.timeline.as_ref().unwrap()).unwrap();
        let t: serde_json::Value = serde_json::from_str(&text).unwrap();
        let events = t["traceEvents"].as_array().unwrap();
        fn slices<'a>(
            events: &'a [serde_json::Value],
            cat: &'a str,
        ) -> impl Iterator<Item = &'a serde_json::Value> + 'a {
            events
                .iter()
                .filter(move |e| e["ph"] == "X" && e["cat"] == cat)
                .map(|e| &e["args"])
        }
        let running: u64 = slices(events, "kernel")
            .map(|a| a["running_cycles"].as_u64().unwrap())
            .sum();
        assert_eq!(running, kernels, "{}", scene.name);
        // Every kernel loops: its calls show their passes.
        let passes: u64 = slices(events, "kernel")
            .map(|a| a["loop_passes"].as_u64().unwrap())
            .sum();
        assert!(passes > 0, "{}", scene.name);
        let cycles = |a: &serde_json::Value| {
            a["to_cycle"].as_u64().unwrap() - a["from_cycle"].as_u64().unwrap()
        };
        let covered: u64 = slices(events, "kernel")
            .chain(slices(events, "attribution"))
            .map(cycles)
            .sum();
        assert_eq!(covered, s.cycles, "{}", scene.name);
        assert!(slices(events, "memory").count() > 0, "{}", scene.name);
        // The waits' slices say what they waited on, and DRAM's row hits are a counter.
        let waited_on: u64 = slices(events, "attribution")
            .flat_map(|a| a.as_object().unwrap().iter())
            .filter(|(k, _)| k.starts_with("waiting_on_"))
            .map(|(_, v)| v.as_u64().unwrap())
            .sum();
        assert_eq!(waited_on, s.waiting_on.total(), "{}", scene.name);
        let row_hits: f64 = events
            .iter()
            .filter(|e| e["ph"] == "C" && e["name"] == "DRAM row hits and misses per µs")
            .map(|e| e["args"]["row hits"].as_f64().unwrap())
            .sum();
        assert!(row_hits > 0.0, "{}", scene.name);
        assert_eq!(t["displayTimeUnit"], "ns");
    }
}

/// Slower row switches show as bank conflicts: with precharge and activate four times as
/// long, the clusters wait more cycles on them.
#[test]
fn slower_row_switches_are_waited_on_as_bank_conflicts() {
    let scene = advs1_24x24();
    let quick = render_with(&scene, &MachineDesc::gold8(), cached(), None, |_, _| {}).unwrap();
    let mut desc = MachineDesc::gold8();
    desc.dram.t_rp *= 4;
    desc.dram.t_rcd *= 4;
    desc.dram.t_ras *= 4;
    desc.dram.t_rc *= 4;
    desc.validate().unwrap();
    let slow = render_with(&scene, &desc, cached(), None, |_, _| {}).unwrap();
    let (q, s) = (&quick.stats.waiting_on, &slow.stats.waiting_on);
    assert!(
        s.bank_conflicts > 2 * q.bank_conflicts.max(1),
        "{q:?} then {s:?}"
    );
    assert_eq!(quick.pixels, slow.pixels);
}

/// The longest minimum kernel time a machine may ask for: the frame finishes (its idle
/// time is jumped over), every kernel call holding the clusters for it.
#[test]
fn a_frame_of_kernels_held_for_the_longest_minimum_time_finishes() {
    let scene = rate1_16x16();
    let mut desc = MachineDesc::gold8();
    desc.stream_controller.min_kernel_cycles = 1 << 24;
    desc.validate().unwrap();
    let f = render_with(&scene, &desc, cached(), None, |_, _| {}).unwrap();
    let calls: u64 = f.stats.kernels.iter().map(|k| k.calls).sum();
    assert!(calls > 10);
    assert!(f.stats.cycles >= calls << 24, "{} cycles", f.stats.cycles);
    let quick = render_with(&scene, &MachineDesc::gold8(), cached(), None, |_, _| {}).unwrap();
    assert_eq!(f.pixels, quick.pixels);
}

/// Marble materials: their keys parse with defaults, only marble takes them, a bad `noise`
/// names the file, key and choices, marble takes no textures, and a marble object needs
/// normals (the error names it).
#[test]
fn marble_materials_are_checked_by_name() {
    use imagine_pipelines::scene::model::{Marble, Noise, Shader};
    let text = |material: &str| {
        format!(
            "[window]\nwidth = 16\nheight = 16\n\
             [[texture]]\nname = \"t\"\nprocedural = {{ kind = \"checker\" }}\n\
             [[material]]\nname = \"m\"\n{material}\n\
             [[object]]\nname = \"ball\"\nprimitive = {{ kind = \"icosphere\", subdivisions = 1 }}\n\
             material = \"m\"\n"
        )
    };
    let parse = |material: &str| {
        scene::file::parse(
            &text(material),
            std::path::Path::new("m.toml"),
            &LoadOptions::default(),
        )
    };
    let s = parse("shader = \"marble\"").unwrap();
    assert_eq!(s.materials[0].shader, Shader::Marble(Marble::DEFAULT));
    let s = parse("shader = \"marble\"\nfrequency = 2.5").unwrap();
    let Shader::Marble(m) = s.materials[0].shader else {
        panic!("marble")
    };
    assert_eq!((m.frequency, m.turbulence_scale), (2.5, 5.0));
    // Perlin's improved noise by default, Ward's (the publication's) on request.
    assert_eq!(m.noise, Noise::Perlin);
    let s = parse("shader = \"marble\"\nnoise = \"ward\"").unwrap();
    let Shader::Marble(m) = s.materials[0].shader else {
        panic!("marble")
    };
    assert_eq!(m.noise, Noise::Ward);
    for (material, words) in [
        (
            "shader = \"lit\"\nfrequency = 2.0",
            &["material[0].frequency", "marble"][..],
        ),
        (
            "shader = \"lit\"\nnoise = \"ward\"",
            &["m.toml", "material[0].noise", "marble"],
        ),
        (
            "shader = \"marble\"\nnoise = \"simplex\"",
            &["m.toml", "material[0].noise", "ward", "perlin"],
        ),
        (
            "shader = \"marble\"\ntextures = [\"t\"]",
            &["material[0].textures", "no textures"],
        ),
    ] {
        let e = parse(material).unwrap_err().to_string();
        assert!(words.iter().all(|w| e.contains(w)), "{e}");
    }
    let mut s = parse("shader = \"marble\"").unwrap();
    s.objects[0].mesh.normals.clear();
    let e = render_with(&s, &MachineDesc::gold8(), cached(), None, |_, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("`ball`") && e.contains("normals"), "{e}");
}

/// The batch size is the scene's (`pipeline.batch`) or the options' (which win), rounded
/// to whole rows of clusters and bounded by what the machine holds; the image does not
/// depend on it (each depth test is an extremum over depth and primitive).
#[test]
fn the_batch_size_is_asked_for_and_changes_no_pixel() {
    let desc = MachineDesc::gold8();
    let mut scene = scene::load(
        "SPHERE-FULL",
        &LoadOptions {
            size: Some(48),
            subdivisions: Some(2),
            filter: None,
        },
    )
    .unwrap();
    let default = render_with(&scene, &desc, cached(), None, |_, _| {}).unwrap();
    assert_eq!(default.stats.batch_triangles, 64);
    scene.pipeline.batch = Some(20);
    let from_scene = render_with(&scene, &desc, cached(), None, |_, _| {}).unwrap();
    assert_eq!(
        from_scene.stats.batch_triangles, 24,
        "whole rows of 8 clusters"
    );
    let asked = RenderOptions {
        batch: Some(8),
        ..cached()
    };
    let from_options = render_with(&scene, &desc, asked, None, |_, _| {}).unwrap();
    assert_eq!(from_options.stats.batch_triangles, 8, "the options win");
    // More than xyrast's scratchpad holds: the largest batch it does.
    let huge = RenderOptions {
        batch: Some(100_000),
        ..cached()
    };
    let largest = render_with(&scene, &desc, huge, None, |_, _| {}).unwrap();
    let rows = imagine_pipelines::opengl::kernels::xyrast_rows(&desc);
    assert!(largest.stats.batch_triangles <= rows * 8);
    assert!(largest.stats.batch_triangles > 64);
    for f in [&from_scene, &from_options, &largest] {
        assert_eq!(f.pixels, default.pixels, "the same image, bit for bit");
        assert_ne!(f.stats.cycles, default.stats.cycles);
    }
}

/// The largest batch a machine takes leaves its fragment streams room for a one-pixel tile
/// of it, a fragment of every triangle: MARBLE's and VERONA's strips meet at their poles,
/// and on gold16 their largest batches by the SRF alone (304 and 224 triangles) left room
/// for 64 fragments, so a tile split down to one pixel was refused.
#[test]
fn the_largest_batch_leaves_room_for_a_one_pixel_tile() {
    use imagine_pipelines::opengl::render::plan_pipeline;
    for machine in ["gold16", "gold32"] {
        let desc = MachineDesc::resolve(machine).unwrap();
        for name in ["MARBLE", "VERONA"] {
            let scene = scene::load(name, &LoadOptions::default()).unwrap();
            let huge = RenderOptions {
                batch: Some(65_536),
                ..cached()
            };
            let plan = plan_pipeline(&scene, &desc, &huge).unwrap();
            let c = desc.cluster.count;
            assert!(plan.batch > 8 * c, "{machine} {name}: {}", plan.batch);
            assert!(
                plan.fragment_capacity() >= plan.batch + c,
                "{machine} {name}: a batch of {} and room for {} fragments",
                plan.batch,
                plan.fragment_capacity()
            );
        }
    }
}
