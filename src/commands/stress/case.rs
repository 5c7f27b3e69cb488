//! A stress case: a scene (built in code, so that each case states its numbers where it is
//! defined) or a set of invalid input files, and the properties it must keep; and how a
//! case is run and judged.
//!
//! Every rendered case keeps, besides its own expectations: no panic (the runner catches
//! one and reports it), the render succeeds, the same frame and cycles on a second render,
//! and no NaN or infinity in any pixel ([`check::valid_values`]).

use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use imagine_pipelines::compile::CompileCache;
use imagine_pipelines::opengl::render::{Frame, RenderOptions, render_with};
use imagine_pipelines::scene::model::Scene;
use imagine_units::desc::MachineDesc;
use imagine_verif::image::Image;
use serde::Serialize;

use super::check::{self, Bound, FrameWords, ReferenceFrame};
use crate::commands::reference_error;

/// The machine every rendered case runs on (with its `flush_to_zero` set by the case).
pub const MACHINE: &str = "gold8";

/// What a rendered case's frame must show besides the common properties.
#[derive(Clone, Copy, Debug)]
pub enum Expect {
    /// Error against the f64 reference within the bound.
    Reference(Bound),
    /// Drawn with additive blending in grey `level`, every pixel covered exactly once.
    TilesOnce { level: u8 },
    /// Nothing drawn.
    Empty,
    /// At least this share of the window drawn.
    Covers(f64),
    /// The same frame (pixels, depths, triangles) with flush-to-zero switched over.
    SameWithFlushToZeroSwitched,
    /// The same frame (pixels, depths, triangles) as this other scene's.
    SameFrameAs(fn() -> Result<Scene>),
    /// Every drawn pixel's RGB one of these (the texels of a nearest, replacing texture).
    OnlyColours(&'static [[u8; 3]]),
}

/// A scene to render and what its frame must show.
pub struct Render {
    pub scene: Box<dyn Fn() -> Result<Scene> + Send + Sync>,
    pub flush_to_zero: bool,
    pub expect: Vec<Expect>,
}

/// Files that must be refused: written into a fresh directory, the first loaded; the
/// error must name every one of `must_name` (the file and the key or line).
pub struct Invalid {
    pub files: Vec<(&'static str, String)>,
    pub must_name: Vec<&'static str>,
}

pub enum Kind {
    Render(Render),
    Invalid(Invalid),
}

pub struct Case {
    pub name: &'static str,
    pub family: &'static str,
    /// One line: the extreme the case holds and the property it keeps.
    pub about: &'static str,
    pub kind: Kind,
    /// Why the case fails today, when it does for a reason the README explains: it is then
    /// reported as a known failure, and as a failure once it passes (so the mark goes).
    pub known_failure: Option<&'static str>,
}

impl Case {
    /// A rendered case of `family`: `scene` built and rendered on the suite's machine, with
    /// flush-to-zero as given, held to `expect` besides the common properties.
    pub fn render(
        family: &'static str,
        name: &'static str,
        about: &'static str,
        flush_to_zero: bool,
        scene: impl Fn() -> Result<Scene> + Send + Sync + 'static,
        expect: Vec<Expect>,
    ) -> Case {
        Case {
            name,
            family,
            about,
            kind: Kind::Render(Render {
                scene: Box::new(scene),
                flush_to_zero,
                expect,
            }),
            known_failure: None,
        }
    }

    /// The case marked as a known failure for `why`.
    pub fn known(mut self, why: &'static str) -> Case {
        self.known_failure = Some(why);
        self
    }
}

/// What a case measured: its verdict's reason, and for a rendered case its cycles and the
/// error against the reference where it was measured.
#[derive(Clone, Debug, Serialize)]
pub struct Measured {
    pub reason: String,
    pub cycles: Option<u64>,
    /// Share of the window covered in one frame only.
    pub coverage_error_share: Option<f64>,
    /// Share of the window showing another triangle than the reference's.
    pub visibility_error_share: Option<f64>,
    /// Largest RGB difference where both show the same triangle.
    pub same_triangle_error_levels: Option<u8>,
    /// The frames, for `--images` (boxed: the `Err` of a case's result stays small).
    #[serde(skip)]
    pub images: Box<Images>,
}

/// A rendered case's frame and, where it was compared, the reference's.
#[derive(Clone, Debug, Default)]
pub struct Images {
    pub machine: Option<Image>,
    pub reference: Option<Image>,
}

impl Measured {
    pub fn said(reason: impl Into<String>) -> Measured {
        Measured {
            reason: reason.into(),
            cycles: None,
            coverage_error_share: None,
            visibility_error_share: None,
            same_triangle_error_levels: None,
            images: Box::default(),
        }
    }
}

/// Runs a case: `Ok` when it keeps its properties, `Err` with the first it breaks. `dir`
/// is a directory of the case's own for its files; kernels are compiled through `cache`.
pub fn run(case: &Case, dir: &Path, cache: &CompileCache) -> Result<Measured, Measured> {
    match &case.kind {
        Kind::Render(r) => run_render(r, cache),
        Kind::Invalid(i) => run_invalid(i, dir, cache).map_err(Measured::said),
    }
}

fn render(scene: &Scene, desc: &MachineDesc, cache: &CompileCache) -> Result<Frame, String> {
    let options = RenderOptions {
        cache: cache.clone(),
        ..RenderOptions::default()
    };
    render_with(scene, desc, options, None, |_, _| {}).map_err(|e| format!("render failed: {e}"))
}

fn run_render(r: &Render, cache: &CompileCache) -> Result<Measured, Measured> {
    let mut measured = Measured::said("");
    let fail = |m: &Measured, reason: String| Measured {
        reason,
        ..m.clone()
    };
    let scene = (r.scene)().map_err(|e| Measured::said(format!("scene: {e:#}")))?;
    let mut desc = MachineDesc::resolve(MACHINE).map_err(|e| Measured::said(e.to_string()))?;
    desc.arithmetic.flush_to_zero = r.flush_to_zero;
    let frame = render(&scene, &desc, cache).map_err(Measured::said)?;
    measured.cycles = Some(frame.stats.cycles);
    measured.images.machine = Some(reference_error::image_of(&frame));
    let again = render(&scene, &desc, cache).map_err(|e| fail(&measured, e))?;
    check::same_frames(&frame, &again).map_err(|e| fail(&measured, e))?;
    let words = FrameWords::of(&frame);
    check::valid_values(&words).map_err(|e| fail(&measured, e))?;
    let mut said = Vec::new();
    for expect in &r.expect {
        match *expect {
            Expect::Reference(bound) => {
                let error = reference_error::measure(&scene, &frame)
                    .map_err(|e| fail(&measured, format!("reference: {e:#}")))?;
                let m = &error.metrics;
                let levels = check::same_triangle_error(
                    &words,
                    &ReferenceFrame {
                        pixels: &error.reference.pixels,
                        triangles: &error.triangles,
                    },
                );
                measured.coverage_error_share = Some(m.wrongly_covered_share + m.missed_share);
                measured.visibility_error_share = m.visibility_differing_share;
                measured.same_triangle_error_levels = Some(levels);
                measured.images.reference = Some(error.reference.clone());
                check::within(m, levels, bound).map_err(|e| fail(&measured, e))?;
                said.push(format!(
                    "reference: coverage {:.3} %, visibility {:.3} %, colour ≤ {levels} levels",
                    100.0 * (m.wrongly_covered_share + m.missed_share),
                    100.0 * m.visibility_differing_share.unwrap_or(0.0),
                ));
            }
            Expect::TilesOnce { level } => {
                check::tiles_once(&words, level).map_err(|e| fail(&measured, e))?;
                said.push("tiles once".into());
            }
            Expect::Empty => {
                check::empty(&words).map_err(|e| fail(&measured, e))?;
                said.push("nothing drawn".into());
            }
            Expect::Covers(share) => {
                let drawn = frame.triangles.iter().filter(|t| t.is_some()).count();
                let have = drawn as f64 / frame.triangles.len() as f64;
                if have < share {
                    return Err(fail(
                        &measured,
                        format!(
                            "{:.1} % of the window drawn, at least {:.1} % expected",
                            100.0 * have,
                            100.0 * share
                        ),
                    ));
                }
                said.push(format!("{:.0} % drawn", 100.0 * have));
            }
            Expect::SameFrameAs(other) => {
                let other = other().map_err(|e| fail(&measured, format!("scene: {e:#}")))?;
                let b = render(&other, &desc, cache).map_err(|e| fail(&measured, e))?;
                check::same_image(&frame, &b).map_err(|e| fail(&measured, e))?;
                said.push(format!("the same frame as `{}`", other.name));
            }
            Expect::OnlyColours(colours) => {
                check::only_colours(&words, colours).map_err(|e| fail(&measured, e))?;
                said.push(format!("only the {} texel colours", colours.len()));
            }
            Expect::SameWithFlushToZeroSwitched => {
                let mut other = desc.clone();
                other.arithmetic.flush_to_zero = !r.flush_to_zero;
                let b = render(&scene, &other, cache).map_err(|e| fail(&measured, e))?;
                check::same_image(&frame, &b).map_err(|e| {
                    let ftz = if r.flush_to_zero { "off" } else { "on" };
                    fail(&measured, format!("with flush-to-zero {ftz}: {e}"))
                })?;
                said.push(format!(
                    "same frame with flush-to-zero {}",
                    if r.flush_to_zero { "off" } else { "on" }
                ));
            }
        }
    }
    measured.reason = format!(
        "{} cycles, deterministic, no invalid value{}{}",
        frame.stats.cycles,
        if said.is_empty() { "" } else { "; " },
        said.join("; ")
    );
    Ok(measured)
}

fn run_invalid(i: &Invalid, dir: &Path, cache: &CompileCache) -> Result<Measured, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create `{}`: {e}", dir.display()))?;
    for (name, text) in &i.files {
        let path = dir.join(name);
        std::fs::write(&path, text)
            .map_err(|e| format!("cannot write `{}`: {e}", path.display()))?;
    }
    let first = dir.join(i.files[0].0);
    let loaded = imagine_pipelines::scene::load(
        &first.display().to_string(),
        &imagine_pipelines::scene::LoadOptions::default(),
    );
    let error = match loaded {
        Ok(scene) => {
            // Refused at the latest by the render, before the machine starts.
            let desc = MachineDesc::resolve(MACHINE).map_err(|e| e.to_string())?;
            let start = Instant::now();
            match render(&scene, &desc, cache) {
                Ok(frame) => {
                    return Err(format!(
                        "accepted: rendered {} pixels in {:.1} s instead of an error",
                        frame.pixels.len(),
                        start.elapsed().as_secs_f64()
                    ));
                }
                Err(e) => e,
            }
        }
        Err(e) => e.to_string(),
    };
    let missing: Vec<&&str> = i
        .must_name
        .iter()
        .filter(|n| !error.contains(**n))
        .collect();
    if !missing.is_empty() {
        return Err(format!(
            "the error does not name {}: {error}",
            missing
                .iter()
                .map(|n| format!("`{n}`"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    Ok(Measured::said(format!("clean error: {error}")))
}
