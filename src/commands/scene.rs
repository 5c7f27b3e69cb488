//! `imagine scene`: the built-in scenes and what a scene file holds.

use std::process::ExitCode;

use anyhow::Result;
use clap::Subcommand;
use imagine_pipelines::opengl::render::{PipelinePlan, RenderOptions, plan_pipeline};
use imagine_pipelines::scene::file::{BUILTIN, builtin_description};
use imagine_pipelines::scene::model::{
    Blend, Cull, DepthTest, Filter, PipelineKind, Scene, Shader, Space, TextureMode, Wrap,
};
use imagine_pipelines::scene::{LoadOptions, load};
use imagine_units::desc::MachineDesc;
use imagine_units::limits::MAX_BATCH;
use serde_json::{Value, json};

#[derive(Subcommand)]
pub enum SceneCommand {
    /// List the built-in scenes
    List,
    /// Show what a scene holds (a built-in name, a .toml scene file or a .tri file)
    Show {
        /// Scene name (see `imagine scene list`) or path to a .toml or .tri file
        name: String,
        /// Draw into a SIZE × SIZE window instead of the file's
        #[arg(long, value_name = "N")]
        size: Option<u32>,
        /// Subdivide every icosphere N times instead (at most 7)
        #[arg(long, value_name = "N")]
        subdivisions: Option<u32>,
        /// Machine the pipeline is planned for (name or file)
        #[arg(long, default_value = "gold8")]
        machine: String,
        /// Plan the general pipeline instead of one specialised for the scene
        #[arg(long)]
        no_specialize: bool,
        /// At most N triangles per batch, instead of the scene's `pipeline.batch` or 64
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=i64::from(MAX_BATCH)))]
        batch: Option<u32>,
        /// Print the description as JSON
        #[arg(long)]
        json: bool,
    },
}

pub fn run(c: SceneCommand) -> Result<ExitCode> {
    match c {
        SceneCommand::List => {
            let width = BUILTIN.iter().map(|(n, _)| n.len()).max().unwrap_or(0);
            for (name, text) in BUILTIN {
                let about = builtin_description(text);
                let about = about.strip_prefix(&format!("{name}: ")).unwrap_or(about);
                println!("{name:<width$} {about}");
            }
        }
        SceneCommand::Show {
            name,
            size,
            subdivisions,
            machine,
            no_specialize,
            batch,
            json,
        } => {
            let scene = load(
                &name,
                &LoadOptions {
                    size,
                    subdivisions,
                    filter: None,
                },
            )?;
            let desc = MachineDesc::resolve(&machine)?;
            let mut d = describe(&scene);
            let options = RenderOptions {
                specialise: !no_specialize,
                batch: batch.map(|b| b as usize),
                ..RenderOptions::default()
            };
            match plan_pipeline(&scene, &desc, &options) {
                Ok(p) => describe_pipeline(&mut d, &p, &desc),
                Err(e) => d.push(
                    "plan",
                    vec![format!("cannot be built: {e}")],
                    json!({ "error": e.to_string() }),
                ),
            }
            if json {
                println!("{}", serde_json::to_string_pretty(&d.json())?);
            } else {
                print!("{}", d.text());
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// One titled part of a description: its text lines and the same facts as JSON.
pub struct Section {
    pub title: String,
    pub lines: Vec<String>,
    pub json: Value,
}

/// What `scene show` prints, section by section; more sections may be pushed.
pub struct Description {
    pub sections: Vec<Section>,
}

impl Description {
    pub fn push(&mut self, title: &str, lines: Vec<String>, json: Value) {
        self.sections.push(Section {
            title: title.into(),
            lines,
            json,
        });
    }

    /// Each section's first line after its title, the others indented beneath.
    pub fn text(&self) -> String {
        let mut s = String::new();
        for sec in &self.sections {
            for (i, l) in sec.lines.iter().enumerate() {
                let head = if i == 0 { sec.title.as_str() } else { "" };
                s += &format!("{head:<12} {l}\n");
            }
        }
        s
    }

    /// One object: section title → its JSON.
    pub fn json(&self) -> Value {
        Value::Object(
            self.sections
                .iter()
                .map(|s| (s.title.clone(), s.json.clone()))
                .collect(),
        )
    }
}

fn v3(v: [f32; 3]) -> String {
    format!("({}, {}, {})", v[0], v[1], v[2])
}

fn count(n: usize) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

fn matrix_lines(m: &[f32; 16]) -> Vec<String> {
    m.chunks(4)
        .map(|r| {
            r.iter()
                .map(|x| format!("{x:>12.6}"))
                .collect::<Vec<_>>()
                .join(" ")
        })
        .collect()
}

/// The scene's name, source, window, camera, pipeline settings, lights, materials,
/// textures, objects and totals.
pub fn describe(s: &Scene) -> Description {
    let mut d = Description {
        sections: Vec::new(),
    };
    d.push("scene", vec![s.name.clone()], json!(s.name));
    let source = s
        .source
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_else(|| "(generated)".into());
    d.push("source", vec![source.clone()], json!(source));
    d.push(
        "window",
        vec![format!(
            "{} × {}, background {}, global ambient {}",
            s.width,
            s.height,
            v3(s.background),
            v3(s.ambient)
        )],
        json!({"width": s.width, "height": s.height, "background": s.background, "ambient": s.ambient}),
    );
    let mut cam = vec!["view (row-major)".to_string()];
    cam.extend(matrix_lines(&s.camera.view));
    cam.push("projection (row-major)".into());
    cam.extend(matrix_lines(&s.camera.projection));
    d.push(
        "camera",
        cam,
        json!({"view": s.camera.view, "projection": s.camera.projection}),
    );
    let p = &s.pipeline;
    let kind = match p.kind {
        PipelineKind::OpenGl => "opengl",
        PipelineKind::Reyes => "reyes",
    };
    let depth = match p.depth_test {
        DepthTest::Less => "less",
        DepthTest::Lequal => "lequal",
        DepthTest::Always => "always",
    };
    let cull = match p.cull {
        Cull::Back => "back",
        Cull::Front => "front",
        Cull::None => "none",
    };
    let blend = match p.blend {
        Blend::None => "none",
        Blend::Alpha => "alpha",
        Blend::Add => "add",
    };
    let mut pl = format!("{kind}, depth test {depth}, cull {cull}, blend {blend}");
    if p.kind == PipelineKind::Reyes {
        pl += &format!(", stop length {} px", p.stop_length);
    }
    if let Some(b) = p.batch {
        pl += &format!(", at most {b} triangles per batch");
    }
    d.push(
        "pipeline",
        vec![pl],
        json!({"kind": kind, "depth_test": depth, "cull": cull, "blend": blend, "stop_length": p.stop_length, "batch": p.batch}),
    );
    let mut lines = vec![format!("{}", s.lights.len())];
    let mut js = Vec::new();
    for (i, l) in s.lights.iter().enumerate() {
        lines.push(format!(
            "{i}: position {}, ambient {}, diffuse {}, specular {}",
            v3(l.position),
            v3(l.ambient),
            v3(l.diffuse),
            v3(l.specular)
        ));
        js.push(json!({"position": l.position, "ambient": l.ambient, "diffuse": l.diffuse, "specular": l.specular}));
    }
    d.push("lights", lines, Value::Array(js));
    let mut lines = vec![format!("{}", s.materials.len())];
    let mut js = Vec::new();
    for m in &s.materials {
        let shader = match m.shader {
            Shader::Unlit => "unlit",
            Shader::Lit => "lit",
            Shader::Marble(_) => "marble",
            Shader::BumpEnv(_) => "bump_env",
        };
        let mode = match m.texture_mode {
            TextureMode::Modulate => "modulate",
            TextureMode::Replace => "replace",
        };
        let tex: Vec<&str> = m
            .textures
            .iter()
            .map(|&t| s.textures[t].name.as_str())
            .collect();
        let mut l = format!("{}: {shader}", m.name);
        if m.shader == Shader::Lit {
            l += &format!(
                ", ambient {}, diffuse {}, specular {}, shininess {}",
                v3(m.ambient),
                v3(m.diffuse),
                v3(m.specular),
                m.shininess
            );
        }
        if let Shader::Marble(marble) = m.shader {
            l += &format!(
                ", frequency {}, turbulence_scale {}, noise {}",
                marble.frequency,
                marble.turbulence_scale,
                marble.noise.name()
            );
        }
        if let Shader::BumpEnv(b) = m.shader {
            l += &format!(
                ", displacement {}, bump map {size}×{size} of {cells}×{cells} bumps, slope {}",
                b.displacement,
                b.bump_scale,
                size = b.bump_size,
                cells = b.bump_cells
            );
        }
        if !tex.is_empty() {
            l += &format!(", textures {} ({mode})", tex.join(", "));
        }
        lines.push(l);
        js.push(json!({
            "name": m.name, "shader": shader, "ambient": m.ambient, "diffuse": m.diffuse,
            "specular": m.specular, "shininess": m.shininess, "textures": tex, "texture_mode": mode,
        }));
    }
    d.push("materials", lines, Value::Array(js));
    let mut lines = vec![format!("{}", s.textures.len())];
    let mut js = Vec::new();
    for t in &s.textures {
        let filter = match t.filter {
            Filter::Nearest => "nearest",
            Filter::Linear => "linear",
            Filter::Trilinear => "trilinear",
        };
        let wrap = match t.wrap {
            Wrap::Repeat => "repeat",
            Wrap::Clamp => "clamp",
        };
        lines.push(format!(
            "{}: {} × {}, filter {filter}, wrap {wrap}",
            t.name, t.width, t.height
        ));
        js.push(json!({"name": t.name, "width": t.width, "height": t.height, "filter": filter, "wrap": wrap}));
    }
    d.push("textures", lines, Value::Array(js));
    let mut lines = vec![format!("{}", s.objects.len())];
    let mut js = Vec::new();
    for o in &s.objects {
        let space = match o.space {
            Space::World => "world",
            Space::Window => "window",
        };
        let m = &o.mesh;
        // Patch objects (`.bpt` patches and Catmull-Clark cages): their Bezier patches,
        // which the Reyes pipeline subdivides and the mesh dices.
        let patches = if o.patches.is_empty() {
            String::new()
        } else {
            format!("{} Bezier patches diced into ", count(o.patches.len()))
        };
        lines.push(format!(
            "{}: {patches}{} vertices, {} triangles{}, material {}, {space} space",
            o.name,
            count(m.positions.len()),
            count(m.triangles.len()),
            if m.separate { " (separate)" } else { "" },
            s.materials[o.material].name
        ));
        js.push(json!({
            "name": o.name, "patches": o.patches.len(),
            "vertices": m.positions.len(), "triangles": m.triangles.len(),
            "separate": m.separate, "material": s.materials[o.material].name, "space": space,
            "normals": !m.normals.is_empty(), "colours": !m.colours.is_empty(),
            "texcoords": !m.texcoords.is_empty(), "model": o.model,
        }));
    }
    d.push("objects", lines, Value::Array(js));
    d.push(
        "totals",
        vec![format!(
            "{} objects, {} vertices, {} triangles, {} textures",
            s.objects.len(),
            count(s.vertices()),
            count(s.triangles()),
            s.textures.len()
        )],
        json!({"objects": s.objects.len(), "vertices": s.vertices(), "triangles": s.triangles(), "textures": s.textures.len()}),
    );
    d
}

/// The pipeline `render` builds for the scene: kernels, what is left out, the batch and
/// the SRF plan.
fn describe_pipeline(d: &mut Description, p: &PipelinePlan, desc: &MachineDesc) {
    let kernels = p.kernel_names();
    let left_out = p.left_out();
    let lines = vec![
        format!(
            "{} on {} ({} triangles per batch)",
            if p.specialised() {
                "specialised for the scene"
            } else {
                "general"
            },
            desc.name,
            p.batch
        ),
        format!(
            "kernels      {}{}",
            kernels.join(", "),
            if kernels.iter().any(|k| k == "sort32") {
                " (sort32 and mergefrag compiled only when a composite round first needs them)"
            } else {
                ""
            }
        ),
        format!("left out     {}", left_out.join(", ")),
        format!(
            "per vertex   {} words in; interpolants {}",
            p.words_per_vertex(),
            p.interpolants().join(" ")
        ),
        format!(
            "SRF plan     {} of {} words at the busiest phase",
            p.plan.peak_words(),
            desc.srf.words
        ),
    ];
    let mut lines = lines;
    lines.extend(p.plan.table().lines().map(|l| format!("  {l}")));
    d.push(
        "plan",
        lines,
        json!({
            "specialised": p.specialised(),
            "machine": desc.name,
            "batch_triangles": p.batch,
            "kernels": kernels,
            "left_out": left_out,
            "words_per_vertex": p.words_per_vertex(),
            "interpolants": p.interpolants(),
            "srf_peak_words": p.plan.peak_words(),
            "srf_plan": p.plan.rows(),
        }),
    );
}
