//! The knobs `imagine sweep` turns: each has a name, the values it accepts, and the part
//! of a point's render a value changes (the machine description, the render options or
//! how the scene is loaded). `--knob NAME=V1,V2,…` gives one knob's values.

use anyhow::{Context, Result, bail};
use imagine_pipelines::scene::model::Filter;
use imagine_units::desc::{BUILTIN, MachineDesc};
use imagine_units::limits::MAX_BATCH;

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
}

impl Knob {
    pub const ALL: [Knob; 5] = [
        Knob::Machine,
        Knob::Batch,
        Knob::Filter,
        Knob::FlushToZero,
        Knob::NormaliseClip,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Knob::Machine => "machine",
            Knob::Batch => "batch",
            Knob::Filter => "filter",
            Knob::FlushToZero => "flush_to_zero",
            Knob::NormaliseClip => "normalise_clip",
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
            Knob::FlushToZero | Knob::NormaliseClip => "true, false".into(),
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

/// What a point's knob values make of the base machine and the render: the machine
/// description, the batch limit, the texture filter override and the clip normalisation
/// override.
#[derive(Clone, Debug)]
pub struct Setup {
    pub machine: MachineDesc,
    pub batch: Option<usize>,
    pub filter: Option<Filter>,
    pub normalise_clip: Option<bool>,
}

impl Setup {
    /// The setup of `values` (one per axis) over the machine `base_machine`. The machine
    /// is chosen before `flush_to_zero` changes it, whatever the knobs' order.
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
        };
        for value in values {
            match value {
                KnobValue::Machine(_) => {}
                KnobValue::Batch(n) => setup.batch = Some(*n),
                KnobValue::Filter(f) => setup.filter = Some(*f),
                KnobValue::FlushToZero(on) => setup.machine.arithmetic.flush_to_zero = *on,
                KnobValue::NormaliseClip(on) => setup.normalise_clip = Some(*on),
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
            ("stop_length=1,2", "no knob is named `stop_length`"),
            ("batch", "NAME=V1,V2"),
            ("batch=0", "triangles per batch"),
            ("batch=8,,16", "an empty value"),
            ("batch=8,8", "given twice"),
            ("filter=cubic", "nearest, bilinear"),
            ("flush_to_zero=yes", "true, false"),
            ("normalise_clip=1", "true, false"),
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
        let on = [KnobValue::NormaliseClip(true)];
        let setup = Setup::of("gold8", &on.iter().collect::<Vec<_>>()).unwrap();
        assert_eq!(setup.normalise_clip, Some(true));
    }
}
