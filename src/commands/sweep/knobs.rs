//! The knobs `imagine sweep` turns: each has a name, the values it accepts, and the part
//! of a point's render a value changes (the machine description, the render options or
//! how the scene is loaded). `--knob NAME=V1,V2,…` gives one knob's values.

use anyhow::{Context, Result, bail};
use imagine_pipelines::opengl::render::Rasterizer;
use imagine_pipelines::reyes::frame::check_stop_length;
use imagine_pipelines::reyes::kernels::MAX_STOP_LENGTH;
use imagine_pipelines::scene::model::Filter;
use imagine_units::desc::{BUILTIN, MachineDesc};
use imagine_units::limits::{MAX_BATCH, MAX_NEWTON_STEPS};

/// A knob of the sweep.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Knob {
    /// The machine description: a built-in name or a TOML file.
    Machine,
    /// At most N triangles per batch (`render --batch`).
    Batch,
    /// Every texture's filter, whatever the scene file says.
    Filter,
    /// The machine's `arithmetic.flush_to_zero`.
    FlushToZero,
    /// The scene's `pipeline.normalise_clip` (exact clip-corner scaling in `assemble_clip`).
    NormaliseClip,
    /// The scene's `pipeline.reference_depth` (depth interpolated from each triangle's own).
    ReferenceDepth,
    /// The scene's `pipeline.newton_raphson` (`irast`'s reciprocal: 0 the divide unit).
    NewtonRaphson,
    /// Reyes's stop length (`render --pipeline reyes --stop-length`): the point renders
    /// through the Reyes pipeline.
    StopLength,
    /// The OpenGL pipeline's rasterizer: its barycentric or its scanline kernels (`render
    /// --rasterizer`), or the thesis's hardware rasterizer (`gold8+hwrast`'s
    /// `[rasterizer]` table) on the chosen machine.
    Rasterizer,
}

impl Knob {
    pub const ALL: [Knob; 9] = [
        Knob::Machine,
        Knob::Batch,
        Knob::Filter,
        Knob::FlushToZero,
        Knob::NormaliseClip,
        Knob::ReferenceDepth,
        Knob::NewtonRaphson,
        Knob::StopLength,
        Knob::Rasterizer,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Knob::Machine => "machine",
            Knob::Batch => "batch",
            Knob::Filter => "filter",
            Knob::FlushToZero => "flush_to_zero",
            Knob::NormaliseClip => "normalise_clip",
            Knob::ReferenceDepth => "reference_depth",
            Knob::NewtonRaphson => "newton_raphson",
            Knob::StopLength => "stop_length",
            Knob::Rasterizer => "rasterizer",
        }
    }

    /// The values the knob accepts, for error messages.
    fn accepted(self) -> String {
        match self {
            Knob::Machine => format!(
                "a built-in machine ({}) or a machine TOML file",
                BUILTIN
                    .iter()
                    .map(|(n, _)| *n)
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            Knob::Batch => format!("triangles per batch, 1 to {MAX_BATCH}"),
            Knob::Filter => "nearest, bilinear (or linear), trilinear".into(),
            Knob::FlushToZero | Knob::NormaliseClip | Knob::ReferenceDepth => "true, false".into(),
            Knob::NewtonRaphson => {
                format!("Newton–Raphson steps, 0 (the divide unit) to {MAX_NEWTON_STEPS}")
            }
            Knob::StopLength => {
                format!("Reyes's largest quad side in pixels, above 0 and up to {MAX_STOP_LENGTH}")
            }
            Knob::Rasterizer => "barycentric (or kernels), scanline, hardware".into(),
        }
    }

    fn value(self, text: &str) -> Result<KnobValue> {
        let value = match self {
            Knob::Machine => {
                // Resolved now, so that a misspelt machine fails before any point renders.
                MachineDesc::resolve(text).map_err(|e| anyhow::anyhow!("{e}"))?;
                KnobValue::Machine(text.to_string())
            }
            Knob::Batch => match text.parse::<u32>() {
                Ok(n) if (1..=MAX_BATCH).contains(&n) => KnobValue::Batch(n as usize),
                _ => bail!("`{text}` is not a batch size"),
            },
            Knob::Filter => KnobValue::Filter(match text {
                "nearest" => Filter::Nearest,
                "bilinear" | "linear" => Filter::Linear,
                "trilinear" => Filter::Trilinear,
                _ => bail!("`{text}` is not a filter"),
            }),
            Knob::FlushToZero => KnobValue::FlushToZero(boolean(text)?),
            Knob::NormaliseClip => KnobValue::NormaliseClip(boolean(text)?),
            Knob::ReferenceDepth => KnobValue::ReferenceDepth(boolean(text)?),
            Knob::NewtonRaphson => match text.parse::<u8>() {
                Ok(n) if n <= MAX_NEWTON_STEPS => KnobValue::NewtonRaphson(n),
                _ => bail!("`{text}` is not a number of Newton–Raphson steps"),
            },
            Knob::Rasterizer => match text {
                "kernels" => KnobValue::Rasterizer(Some(Rasterizer::Barycentric)),
                "hardware" => KnobValue::Rasterizer(None),
                _ => match text.parse::<Rasterizer>() {
                    Ok(r) => KnobValue::Rasterizer(Some(r)),
                    Err(_) => bail!("`{text}` is not a rasterizer"),
                },
            },
            Knob::StopLength => match text.parse::<f32>() {
                Ok(l) if check_stop_length(l).is_ok() => KnobValue::StopLength(l),
                _ => bail!("`{text}` is not a stop length"),
            },
        };
        Ok(value)
    }
}

fn boolean(text: &str) -> Result<bool> {
    match text {
        "true" => Ok(true),
        "false" => Ok(false),
        _ => bail!("`{text}` is not true or false"),
    }
}

/// One value of a knob.
#[derive(Clone, Debug, PartialEq)]
pub enum KnobValue {
    Machine(String),
    Batch(usize),
    Filter(Filter),
    FlushToZero(bool),
    NormaliseClip(bool),
    ReferenceDepth(bool),
    NewtonRaphson(u8),
    StopLength(f32),
    /// The rasterizer kernels, or `None` for the hardware rasterizer.
    Rasterizer(Option<Rasterizer>),
}

/// A knob and its values in the order given: one axis of the grid.
#[derive(Clone, Debug)]
pub struct Axis {
    pub knob: Knob,
    /// Each value as given on the command line (the CSV's and the plot's text) and parsed.
    pub values: Vec<(String, KnobValue)>,
}

/// Parses `NAME=V1,V2,…`.
pub fn parse_axis(arg: &str) -> Result<Axis> {
    let known = || {
        Knob::ALL
            .iter()
            .map(|k| format!("{} ({})", k.name(), k.accepted()))
            .collect::<Vec<_>>()
            .join("; ")
    };
    let Some((name, list)) = arg.split_once('=') else {
        bail!(
            "--knob `{arg}`: give NAME=V1,V2,…; the knobs are {}",
            known()
        );
    };
    let Some(knob) = Knob::ALL.into_iter().find(|k| k.name() == name.trim()) else {
        bail!(
            "--knob `{arg}`: no knob is named `{name}`; the knobs are {}",
            known()
        );
    };
    let mut values: Vec<(String, KnobValue)> = Vec::new();
    for text in list.split(',').map(str::trim) {
        if text.is_empty() {
            bail!(
                "--knob `{arg}`: an empty value; {} takes {}",
                knob.name(),
                knob.accepted()
            );
        }
        let value = knob.value(text).with_context(|| {
            format!(
                "--knob {}: {} takes {}",
                knob.name(),
                knob.name(),
                knob.accepted()
            )
        })?;
        if values.iter().any(|(_, v)| *v == value) {
            bail!("--knob `{arg}`: `{text}` is given twice");
        }
        values.push((text.to_string(), value));
    }
    Ok(Axis { knob, values })
}

/// The knobs that set what only the OpenGL pipeline has, refused beside `stop_length`
/// (which renders through Reyes).
pub fn check_pipeline(axes: &[Axis]) -> Result<()> {
    if !axes.iter().any(|a| a.knob == Knob::StopLength) {
        return Ok(());
    }
    for a in axes {
        if matches!(
            a.knob,
            Knob::Batch
                | Knob::Filter
                | Knob::NormaliseClip
                | Knob::ReferenceDepth
                | Knob::NewtonRaphson
                | Knob::Rasterizer
        ) {
            bail!(
                "--knob {} is a setting of the OpenGL pipeline; --knob stop_length renders \
                 through Reyes (machine and flush_to_zero apply to both)",
                a.knob.name()
            );
        }
    }
    Ok(())
}

/// The built-in machine whose `[rasterizer]` table `rasterizer=hardware` adds to a machine
/// that has none.
const HARDWARE_RASTERIZER_MACHINE: &str = "gold8+hwrast";

/// What a point's knob values make of the base machine and the render: the machine
/// description, the batch limit, the texture filter override and the overrides of the
/// scene's clip normalisation, reference depth and Newton–Raphson steps.
#[derive(Clone, Debug)]
pub struct Setup {
    pub machine: MachineDesc,
    pub batch: Option<usize>,
    pub filter: Option<Filter>,
    pub normalise_clip: Option<bool>,
    pub reference_depth: Option<bool>,
    pub newton_raphson: Option<u8>,
    /// Reyes at this stop length (else the OpenGL pipeline).
    pub stop_length: Option<f32>,
    /// The rasterizer kernels (where the machine has no hardware rasterizer).
    pub rasterizer: Rasterizer,
}

impl Setup {
    /// The setup of `values` (one per axis) over the machine `base_machine`. The machine
    /// is chosen before `flush_to_zero` and `rasterizer` change it, whatever the knobs'
    /// order.
    pub fn of(base_machine: &str, values: &[&KnobValue]) -> Result<Setup> {
        let machine_name = values
            .iter()
            .find_map(|v| match v {
                KnobValue::Machine(m) => Some(m.as_str()),
                _ => None,
            })
            .unwrap_or(base_machine);
        let mut setup = Setup {
            machine: MachineDesc::resolve(machine_name).map_err(|e| anyhow::anyhow!("{e}"))?,
            batch: None,
            filter: None,
            normalise_clip: None,
            reference_depth: None,
            newton_raphson: None,
            stop_length: None,
            rasterizer: Rasterizer::Barycentric,
        };
        for value in values {
            match value {
                KnobValue::Machine(_) => {}
                KnobValue::Batch(n) => setup.batch = Some(*n),
                KnobValue::Filter(f) => setup.filter = Some(*f),
                KnobValue::FlushToZero(on) => setup.machine.arithmetic.flush_to_zero = *on,
                KnobValue::NormaliseClip(on) => setup.normalise_clip = Some(*on),
                KnobValue::ReferenceDepth(on) => setup.reference_depth = Some(*on),
                KnobValue::NewtonRaphson(n) => setup.newton_raphson = Some(*n),
                KnobValue::StopLength(l) => setup.stop_length = Some(*l),
                KnobValue::Rasterizer(Some(kernels)) => {
                    setup.machine.rasterizer = None;
                    setup.rasterizer = *kernels;
                }
                KnobValue::Rasterizer(None) => {
                    if setup.machine.rasterizer.is_none() {
                        let hwrast = MachineDesc::resolve(HARDWARE_RASTERIZER_MACHINE)
                            .map_err(|e| anyhow::anyhow!("{e}"))?;
                        setup.machine.rasterizer = hwrast.rasterizer;
                        setup
                            .machine
                            .validate()
                            .map_err(|e| anyhow::anyhow!("--knob rasterizer=hardware: {e}"))?;
                    }
                }
            }
        }
        Ok(setup)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_parse_and_refuse_what_they_do_not_know() {
        let a = parse_axis("batch=8,64").unwrap();
        assert_eq!(a.knob, Knob::Batch);
        assert_eq!(a.values[1], ("64".into(), KnobValue::Batch(64)));
        let f = parse_axis("filter=nearest,bilinear").unwrap();
        assert_eq!(f.values[1].1, KnobValue::Filter(Filter::Linear));
        for (bad, says) in [
            ("stop_size=1,2", "no knob is named `stop_size`"),
            ("stop_length=0", "above 0 and up to 7"),
            ("stop_length=1.5,nan", "not a stop length"),
            (
                "rasterizer=edge",
                "barycentric (or kernels), scanline, hardware",
            ),
            ("batch", "NAME=V1,V2"),
            ("batch=0", "triangles per batch"),
            ("batch=8,,16", "an empty value"),
            ("batch=8,8", "given twice"),
            ("filter=cubic", "nearest, bilinear"),
            ("flush_to_zero=yes", "true, false"),
            ("normalise_clip=1", "true, false"),
            ("reference_depth=on", "true, false"),
            ("newton_raphson=4", "0 (the divide unit) to 3"),
            ("machine=gold7", "gold8"),
        ] {
            let e = format!("{:#}", parse_axis(bad).unwrap_err());
            assert!(e.contains(says), "{bad}: {e}");
        }
    }

    #[test]
    fn flush_to_zero_changes_the_chosen_machine() {
        let values = [
            KnobValue::FlushToZero(true),
            KnobValue::Machine("gold16".into()),
            KnobValue::Batch(32),
        ];
        let setup = Setup::of("gold8", &values.iter().collect::<Vec<_>>()).unwrap();
        assert_eq!(setup.machine.name, "gold16");
        assert!(setup.machine.arithmetic.flush_to_zero);
        assert_eq!(setup.batch, Some(32));
        assert_eq!(setup.filter, None);
        assert_eq!(setup.normalise_clip, None);
        assert_eq!(setup.reference_depth, None);
        let on = [
            KnobValue::NormaliseClip(true),
            KnobValue::ReferenceDepth(false),
            KnobValue::NewtonRaphson(2),
        ];
        let setup = Setup::of("gold8", &on.iter().collect::<Vec<_>>()).unwrap();
        assert_eq!(setup.normalise_clip, Some(true));
        assert_eq!(setup.reference_depth, Some(false));
        assert_eq!(setup.newton_raphson, Some(2));
        let hardware = [
            KnobValue::Rasterizer(None),
            KnobValue::Machine("gold16".into()),
        ];
        let setup = Setup::of("gold8", &hardware.iter().collect::<Vec<_>>()).unwrap();
        assert_eq!(setup.machine.name, "gold16");
        assert!(setup.machine.rasterizer.is_some());
        for (text, kernels) in [
            ("kernels", Rasterizer::Barycentric),
            ("barycentric", Rasterizer::Barycentric),
            ("scanline", Rasterizer::Scanline),
        ] {
            let value = Knob::Rasterizer.value(text).unwrap();
            let setup = Setup::of("gold8+hwrast", &[&value]).unwrap();
            assert!(setup.machine.rasterizer.is_none());
            assert_eq!(setup.rasterizer, kernels);
        }
    }
}
