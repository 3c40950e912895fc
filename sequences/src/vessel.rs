//! The lathe winding job file (TOML): the mandrel (a vessel with hemispherical domes, or a tube),
//! the tow, the winder (axes, eye radius, axis limits) and the layers. `docs/file-formats.md`
//! lists every field; `examples/seed002-vessel.toml` is seed 002's groove mandrel.
//!
//! Every value keeps its place in the text, so a value the planner refuses is reported at its
//! line and column, and a layer that does not close at its `[[layer]]` entry.

use std::ops::Range;
use std::path::Path;

use paths::motion::{AxisLimit, AxisSet, Limits};
use paths::pattern::PatternRequest;
use paths::vessel::{Job, Layer, Machine, Mandrel, Tow, TubeHelical};
use serde::Deserialize;
use toml::Spanned;

use crate::Error;

/// A lathe winding job file.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VesselFile {
    /// Names the output files.
    pub name: Spanned<String>,
    /// The mandrel.
    pub mandrel: MandrelSpec,
    /// The tow.
    pub tow: TowSpec,
    /// The winder.
    pub machine: MachineSpec,
    /// The layers, innermost first.
    #[serde(rename = "layer")]
    pub layers: Vec<LayerSpec>,
}

/// `[mandrel]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MandrelSpec {
    /// `vessel` or `tube`.
    pub kind: Spanned<String>,
    /// Vessel: Rc.
    pub cylinder_radius_mm: Option<Spanned<f64>>,
    /// Vessel: Lc.
    pub cylinder_length_mm: Option<Spanned<f64>>,
    /// Vessel: rp.
    pub polar_opening_radius_mm: Option<Spanned<f64>>,
    /// Tube: radius.
    pub radius_mm: Option<Spanned<f64>>,
    /// Tube: wound length.
    pub length_mm: Option<Spanned<f64>>,
}

/// `[tow]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TowSpec {
    /// Band width b.
    pub band_width_mm: Spanned<f64>,
    /// Ply thickness.
    pub thickness_mm: Spanned<f64>,
}

/// One axis's limits.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisSpec {
    /// Units (mm or degrees) per second.
    pub velocity: Spanned<f64>,
    /// Units per second squared.
    pub acceleration: Spanned<f64>,
}

/// `[machine]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MachineSpec {
    /// 2, 3 or 4.
    pub axes: Spanned<u8>,
    /// Re (vessel with cross-feed) or the eye's fixed distance from the axis.
    pub eye_radius_mm: Spanned<f64>,
    /// Moves on each side of α* per dome part (default 10, as seed 002).
    pub dome_steps: Option<Spanned<u32>>,
    /// Cornering tolerance of the time estimate (default 0.01).
    pub junction_deviation: Option<Spanned<f64>>,
    /// Wind each layer on the laminate below it (default true).
    pub build_up: Option<bool>,
    /// Mandrel limits, degrees.
    pub mandrel: AxisSpec,
    /// Carriage limits, mm.
    pub carriage: AxisSpec,
    /// Cross-feed limits, mm.
    pub cross_feed: AxisSpec,
    /// Eye-rotation limits, degrees.
    pub eye: AxisSpec,
}

/// `[[layer]]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LayerSpec {
    /// `hoop`, `helical`, `tube-helical`, `polar` or `skip`.
    pub kind: Spanned<String>,
    /// How many such layers (default 1).
    pub count: Option<Spanned<u32>>,
    /// Hoop: 1 or 2 plies.
    pub passes: Option<Spanned<u32>>,
    /// Helical: cycles per pattern (default: Eq. 7's next allowed pitch).
    pub cycles_per_pattern: Option<Spanned<u32>>,
    /// Helical: dwell per turnaround, degrees (default: Eq. 8's).
    pub dwell_deg: Option<Spanned<f64>>,
    /// Helical: advance per pattern, degrees (default: Eq. 9 from the band).
    pub advance_deg: Option<Spanned<f64>>,
    /// Tube helical: wind angle, degrees.
    pub wind_angle_deg: Option<Spanned<f64>>,
    /// Tube helical: circuits per pattern.
    pub pattern_number: Option<Spanned<u32>>,
    /// Tube helical: skip index.
    pub skip_index: Option<Spanned<u32>>,
    /// Tube helical: lock turn at each end, degrees.
    pub lock_deg: Option<Spanned<f64>>,
    /// Tube helical: lead-in length, mm.
    pub lead_in_mm: Option<Spanned<f64>>,
    /// Tube helical: lead-out turn, degrees.
    pub lead_out_deg: Option<Spanned<f64>>,
    /// Skip: mandrel turn, degrees.
    pub mandrel_deg: Option<Spanned<f64>>,
    /// Polar: the largest ratio of geodesic to normal curvature the tow may need (default
    /// [`paths::vessel::POLAR_SLIP_LIMIT`]).
    pub slip_limit: Option<Spanned<f64>>,
}

/// The most cycles per pattern a helical layer may ask for (bounded time: the planner steps
/// through every cycle; seed 002's patterns have a few dozen).
pub const MAX_CYCLES_PER_PATTERN: u32 = 10_000;

/// The most layers a file may expand to (bounded time and memory).
pub const MAX_LAYERS: u32 = 10_000;

fn at(text: &str, span: Range<usize>, message: impl Into<String>) -> Error {
    Error::at_offset(text, span.start, message)
}

fn need<'a, T>(
    text: &str,
    value: &'a Option<Spanned<T>>,
    owner: &Spanned<String>,
    name: &str,
) -> Result<&'a Spanned<T>, Error> {
    value.as_ref().ok_or_else(|| {
        at(
            text,
            owner.span(),
            format!("a `{}` needs `{name}`", owner.get_ref()),
        )
    })
}

/// A value's first check: finite, and within the job file's magnitudes (a length, `…_mm`, within
/// ±[`crate::job::MAX_LENGTH_MM`]; anything else within ±[`crate::job::MAX_MAGNITUDE`]):
/// docs/ARCHITECTURE.md, "Limits". A winder 1e300 mm long sizes no plan.
fn finite(text: &str, v: &Spanned<f64>, name: &str) -> Result<f64, Error> {
    let x = *v.get_ref();
    if !x.is_finite() {
        return Err(at(text, v.span(), format!("{name} must be finite")));
    }
    let (limit, unit) = if name.ends_with("_mm") {
        (crate::job::MAX_LENGTH_MM, " mm")
    } else {
        (crate::job::MAX_MAGNITUDE, "")
    };
    if x.abs() > limit {
        return Err(at(
            text,
            v.span(),
            format!(
                "{name} = {} exceeds the limit of ±{}{unit} (docs/ARCHITECTURE.md, \"Limits\")",
                crate::error::shown(x),
                crate::error::shown(limit)
            ),
        ));
    }
    Ok(x)
}

/// The least axis velocity and acceleration a vessel file may give, units/s and units/s²: a
/// slower axis makes a plan of more than 30 years (docs/ARCHITECTURE.md, "Limits").
pub const MIN_AXIS_RATE: f64 = 1e-3;

/// A parsed job: the planner's job, and where each expanded layer came from.
#[derive(Debug, Clone)]
pub struct Loaded {
    /// The name.
    pub name: String,
    /// The job.
    pub job: Job,
    /// For each expanded layer (0-based), the span of its `kind` in the text.
    pub layer_spans: Vec<Range<usize>>,
}

impl Loaded {
    /// Checks the job with the planner, reporting a refused layer at its `[[layer]]` entry and a
    /// refused value at its field.
    pub fn check(&self, text: &str) -> Result<paths::vessel::Plan, Error> {
        self.job.check().map_err(|e| {
            let layer = match &e {
                paths::Error::Layer { layer, .. }
                | paths::Error::WindRule { layer, .. }
                | paths::Error::EyeInsideLaminate { layer, .. } => Some(*layer),
                _ => None,
            };
            match layer.and_then(|l| self.layer_spans.get(l.wrapping_sub(1))) {
                Some(span) => at(text, span.clone(), e.to_string()),
                None => Error::content(e.to_string()),
            }
        })
    }
}

impl VesselFile {
    /// Parses the text of a job file into the planner's job (values checked, not yet planned).
    pub fn parse(text: &str) -> Result<Loaded, Error> {
        let file: VesselFile = toml::from_str(text).map_err(|e| {
            let (offset, message) = crate::error::toml_refusal(&e);
            Error::at_offset(text, offset, message)
        })?;
        file.convert(text)
    }

    /// Reads and parses a job file; errors name the file.
    pub fn load(path: &Path) -> Result<(Loaded, String), Error> {
        let text = crate::source::read_text(path, crate::source::MAX_JOB_BYTES)?;
        let loaded = VesselFile::parse(&text).map_err(|e| e.in_file(path))?;
        Ok((loaded, text))
    }

    /// The job the file describes: the mandrel, the tow, the machine, the layers, each checked
    /// at its place in the text.
    fn convert(&self, text: &str) -> Result<Loaded, Error> {
        // The name names the program file (`NAME.EXT` in the output folder): the job file's
        // rule, so that no name reaches outside that folder or hides its file.
        let name = self.name.get_ref();
        if name.chars().count() > crate::job::MAX_NAME_CHARS {
            return Err(at(
                text,
                self.name.span(),
                format!(
                    "name has {} characters, more than the limit of {} (it names the program \
                     file)",
                    name.chars().count(),
                    crate::job::MAX_NAME_CHARS
                ),
            ));
        }
        if !crate::sequence::is_valid_name(name) {
            return Err(at(
                text,
                self.name.span(),
                "name must be letters, digits, `_` or `-` (it names the program file)",
            ));
        }
        let mandrel = self.mandrel_of(text)?;
        let tow = self.tow_of(text)?;
        let machine = self.machine_of(text)?;
        let (layers, spans) = self.layers_of(text)?;
        Ok(Loaded {
            name: self.name.get_ref().clone(),
            job: Job {
                mandrel,
                tow,
                machine,
                layers,
                build_up: self.machine.build_up.unwrap_or(true),
            },
            layer_spans: spans,
        })
    }

    /// `[mandrel]`: a vessel or a tube, its fields finite and positive, the polar opening inside
    /// the cylinder.
    fn mandrel_of(&self, text: &str) -> Result<Mandrel, Error> {
        let m = &self.mandrel;
        let mandrel = match m.kind.get_ref().as_str() {
            "vessel" => Mandrel::Vessel {
                cylinder_radius_mm: finite(
                    text,
                    need(text, &m.cylinder_radius_mm, &m.kind, "cylinder_radius_mm")?,
                    "cylinder_radius_mm",
                )?,
                cylinder_length_mm: finite(
                    text,
                    need(text, &m.cylinder_length_mm, &m.kind, "cylinder_length_mm")?,
                    "cylinder_length_mm",
                )?,
                polar_radius_mm: finite(
                    text,
                    need(
                        text,
                        &m.polar_opening_radius_mm,
                        &m.kind,
                        "polar_opening_radius_mm",
                    )?,
                    "polar_opening_radius_mm",
                )?,
            },
            "tube" => Mandrel::Tube {
                radius_mm: finite(
                    text,
                    need(text, &m.radius_mm, &m.kind, "radius_mm")?,
                    "radius_mm",
                )?,
                length_mm: finite(
                    text,
                    need(text, &m.length_mm, &m.kind, "length_mm")?,
                    "length_mm",
                )?,
            },
            other => {
                return Err(at(
                    text,
                    m.kind.span(),
                    format!("unknown mandrel kind `{other}` (vessel or tube)"),
                ));
            }
        };
        // Field checks the planner would make, here with their place in the text.
        for v in [
            (&m.cylinder_radius_mm, "cylinder_radius_mm"),
            (&m.polar_opening_radius_mm, "polar_opening_radius_mm"),
            (&m.radius_mm, "radius_mm"),
            (&m.length_mm, "length_mm"),
        ] {
            if let Some(s) = v.0 {
                positive(text, s, v.1)?;
            }
        }
        if let (Some(rc), Some(rp)) = (&m.cylinder_radius_mm, &m.polar_opening_radius_mm)
            && rp.get_ref() >= rc.get_ref()
        {
            return Err(at(
                text,
                rp.span(),
                "the polar opening must be smaller than the cylinder radius",
            ));
        }
        Ok(mandrel)
    }

    /// `[tow]`: a positive band width, a thickness ≥ 0.
    fn tow_of(&self, text: &str) -> Result<Tow, Error> {
        let tow = Tow {
            band_mm: positive(text, &self.tow.band_width_mm, "band_width_mm")?,
            thickness_mm: finite(text, &self.tow.thickness_mm, "thickness_mm")?,
        };
        if tow.thickness_mm < 0.0 {
            return Err(at(
                text,
                self.tow.thickness_mm.span(),
                "thickness_mm must be ≥ 0",
            ));
        }
        Ok(tow)
    }

    /// `[machine]`: the axes, each axis's limits, the eye radius, the dome steps.
    fn machine_of(&self, text: &str) -> Result<Machine, Error> {
        let mc = &self.machine;
        let axes = match mc.axes.get_ref() {
            2 => AxisSet::Two,
            3 => AxisSet::Three,
            4 => AxisSet::Four,
            n => return Err(at(text, mc.axes.span(), format!("axes = {n}: 2, 3 or 4"))),
        };
        let rate = |v: &Spanned<f64>, name: String| -> Result<f64, Error> {
            let x = positive(text, v, &name)?;
            if x < MIN_AXIS_RATE {
                return Err(at(
                    text,
                    v.span(),
                    format!(
                        "{name} = {} is below the least of {MIN_AXIS_RATE} (docs/ARCHITECTURE.md, \
                         \"Limits\")",
                        crate::error::shown(x)
                    ),
                ));
            }
            Ok(x)
        };
        let limit = |a: &AxisSpec, name: &str| -> Result<AxisLimit, Error> {
            Ok(AxisLimit {
                velocity: rate(&a.velocity, format!("{name}.velocity"))?,
                acceleration: rate(&a.acceleration, format!("{name}.acceleration"))?,
            })
        };
        let dome_steps = match &mc.dome_steps {
            None => 10,
            Some(s) if (1..=10_000).contains(s.get_ref()) => *s.get_ref() as usize,
            Some(s) => return Err(at(text, s.span(), "dome_steps must be 1..=10000")),
        };
        Ok(Machine {
            axes,
            eye_radius_mm: positive(text, &mc.eye_radius_mm, "eye_radius_mm")?,
            limits: Limits {
                axes: [
                    limit(&mc.mandrel, "mandrel")?,
                    limit(&mc.carriage, "carriage")?,
                    limit(&mc.cross_feed, "cross_feed")?,
                    limit(&mc.eye, "eye")?,
                ],
                junction_deviation: match &mc.junction_deviation {
                    None => 0.01,
                    Some(j) => positive(text, j, "junction_deviation")?,
                },
            },
            dome_steps,
        })
    }

    /// `[[layer]]`s, each repeated `count` times, at most MAX_LAYERS in all; with each the span
    /// of its `kind`.
    fn layers_of(&self, text: &str) -> Result<(Vec<Layer>, Vec<Range<usize>>), Error> {
        if self.layers.is_empty() {
            return Err(Error::at(1, 1, "a job needs at least one [[layer]]"));
        }
        let mut layers = Vec::new();
        let mut spans = Vec::new();
        let mut total = 0u32;
        for l in &self.layers {
            let count = match &l.count {
                None => 1,
                Some(c) if *c.get_ref() >= 1 => *c.get_ref(),
                Some(c) => return Err(at(text, c.span(), "count must be ≥ 1")),
            };
            total = total.saturating_add(count);
            if total > MAX_LAYERS {
                return Err(at(
                    text,
                    l.kind.span(),
                    format!("more than {MAX_LAYERS} layers"),
                ));
            }
            let layer = layer(text, l)?;
            for _ in 0..count {
                layers.push(layer);
                spans.push(l.kind.span());
            }
        }
        Ok((layers, spans))
    }
}

/// A value's check: finite and > 0, refused at its place in the text.
fn positive(text: &str, v: &Spanned<f64>, name: &str) -> Result<f64, Error> {
    let x = finite(text, v, name)?;
    if x > 0.0 {
        Ok(x)
    } else {
        Err(at(
            text,
            v.span(),
            format!("{name} = {} must be > 0", crate::error::shown(x)),
        ))
    }
}

fn layer(text: &str, l: &LayerSpec) -> Result<Layer, Error> {
    let kind = &l.kind;
    // Fields that do not belong to the kind are refused, not ignored.
    let fields: [(&str, bool); 13] = [
        ("passes", l.passes.is_some()),
        ("cycles_per_pattern", l.cycles_per_pattern.is_some()),
        ("dwell_deg", l.dwell_deg.is_some()),
        ("advance_deg", l.advance_deg.is_some()),
        ("wind_angle_deg", l.wind_angle_deg.is_some()),
        ("pattern_number", l.pattern_number.is_some()),
        ("skip_index", l.skip_index.is_some()),
        ("lock_deg", l.lock_deg.is_some()),
        ("lead_in_mm", l.lead_in_mm.is_some()),
        ("lead_out_deg", l.lead_out_deg.is_some()),
        ("mandrel_deg", l.mandrel_deg.is_some()),
        ("slip_limit", l.slip_limit.is_some()),
        ("count", false),
    ];
    let allowed: &[&str] = match kind.get_ref().as_str() {
        "hoop" => &["passes"],
        "helical" => &["cycles_per_pattern", "dwell_deg", "advance_deg"],
        "tube-helical" => &[
            "wind_angle_deg",
            "pattern_number",
            "skip_index",
            "lock_deg",
            "lead_in_mm",
            "lead_out_deg",
        ],
        "skip" => &["mandrel_deg"],
        "polar" => &["slip_limit"],
        other => {
            return Err(at(
                text,
                kind.span(),
                format!(
                    "unknown layer kind `{other}` (hoop, helical, tube-helical, polar or skip)"
                ),
            ));
        }
    };
    if let Some((name, _)) = fields.iter().find(|(n, set)| *set && !allowed.contains(n)) {
        return Err(at(
            text,
            kind.span(),
            format!("a `{}` layer has no `{name}`", kind.get_ref()),
        ));
    }
    Ok(match kind.get_ref().as_str() {
        "hoop" => Layer::Hoop {
            passes: match &l.passes {
                None => 1,
                Some(p) if (1..=2).contains(p.get_ref()) => *p.get_ref(),
                Some(p) => return Err(at(text, p.span(), "passes must be 1 or 2")),
            },
        },
        "helical" => Layer::Helical(PatternRequest {
            cycles_per_pattern: match &l.cycles_per_pattern {
                Some(c) if !(1..=MAX_CYCLES_PER_PATTERN).contains(c.get_ref()) => {
                    return Err(at(
                        text,
                        c.span(),
                        format!("cycles_per_pattern must be 1..={MAX_CYCLES_PER_PATTERN}"),
                    ));
                }
                c => c.as_ref().map(|c| *c.get_ref()),
            },
            dwell_deg: l
                .dwell_deg
                .as_ref()
                .map(|d| finite(text, d, "dwell_deg"))
                .transpose()?,
            advance_deg: l
                .advance_deg
                .as_ref()
                .map(|a| positive(text, a, "advance_deg"))
                .transpose()?,
        }),
        "tube-helical" => Layer::TubeHelical(TubeHelical {
            wind_angle_deg: finite(
                text,
                need(text, &l.wind_angle_deg, kind, "wind_angle_deg")?,
                "wind_angle_deg",
            )?,
            pattern_number: *need(text, &l.pattern_number, kind, "pattern_number")?.get_ref(),
            skip_index: *need(text, &l.skip_index, kind, "skip_index")?.get_ref(),
            lock_deg: positive(text, need(text, &l.lock_deg, kind, "lock_deg")?, "lock_deg")?,
            lead_in_mm: positive(
                text,
                need(text, &l.lead_in_mm, kind, "lead_in_mm")?,
                "lead_in_mm",
            )?,
            lead_out_deg: positive(
                text,
                need(text, &l.lead_out_deg, kind, "lead_out_deg")?,
                "lead_out_deg",
            )?,
            initial_lock: true,
            friction_lambda: 0.0,
        }),
        "polar" => Layer::Polar {
            slip_limit: match &l.slip_limit {
                None => paths::vessel::POLAR_SLIP_LIMIT,
                Some(v) => {
                    let x = finite(text, v, "slip_limit")?;
                    if x < 0.0 {
                        return Err(at(text, v.span(), format!("slip_limit = {x} must be ≥ 0")));
                    }
                    x
                }
            },
        },
        _ => Layer::Skip {
            mandrel_deg: finite(
                text,
                need(text, &l.mandrel_deg, kind, "mandrel_deg")?,
                "mandrel_deg",
            )?,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const SEED: &str = r#"
name = "seed002"

[mandrel]
kind = "vessel"
cylinder_radius_mm = 60.0
cylinder_length_mm = 84.1
polar_opening_radius_mm = 21.0

[tow]
band_width_mm = 4.0
thickness_mm = 0.2

[machine]
axes = 4
eye_radius_mm = 90.0
mandrel = { velocity = 100.0, acceleration = 500.0 }
carriage = { velocity = 100.0, acceleration = 500.0 }
cross_feed = { velocity = 100.0, acceleration = 500.0 }
eye = { velocity = 100.0, acceleration = 500.0 }

[[layer]]
kind = "helical"
count = 2
"#;

    #[test]
    fn parses_and_expands_counts() {
        let loaded = VesselFile::parse(SEED).unwrap();
        assert_eq!(loaded.name, "seed002");
        assert_eq!(loaded.job.layers.len(), 2);
        assert_eq!(loaded.job.machine.dome_steps, 10);
        assert!(loaded.job.build_up);
        let plan = loaded.check(SEED).unwrap();
        assert_eq!(plan.layers.len(), 2);
    }

    #[test]
    fn bad_values_are_reported_at_their_place() {
        let cases = [
            (
                "cylinder_radius_mm = 60.0",
                "cylinder_radius_mm = -60.0",
                "6:22: ",
            ),
            (
                "polar_opening_radius_mm = 21.0",
                "polar_opening_radius_mm = 70.0",
                "8:27: ",
            ),
            ("axes = 4", "axes = 5", "15:8: axes = 5"),
            (
                "kind = \"helical\"",
                "kind = \"polar-ish\"",
                "23:8: unknown layer kind",
            ),
            (
                "count = 2",
                "slip_limit = 0.2",
                "23:8: a `helical` layer has no `slip_limit`",
            ),
            (
                "kind = \"helical\"\ncount = 2",
                "kind = \"polar\"\nslip_limit = -0.1",
                "24:14: slip_limit = -0.1 must be ≥ 0",
            ),
            (
                "count = 2",
                "count = 2\npasses = 2",
                "23:8: a `helical` layer has no `passes`",
            ),
            (
                "kind = \"vessel\"",
                "kind = \"cone\"",
                "5:8: unknown mandrel kind",
            ),
            (
                "band_width_mm = 4.0",
                "band_width_mm = 4.0\nwidth = 3",
                "12:1: unknown field",
            ),
        ];
        for (from, to, expect) in cases {
            let text = SEED.replace(from, to);
            let err = VesselFile::parse(&text).unwrap_err().to_string();
            assert!(err.starts_with(expect), "{err}");
        }
    }

    #[test]
    fn a_polar_layer_that_would_slip_is_reported_at_its_entry() {
        // Seed 002's mandrel with Lc 84.1 needs λ = 0.1481 (computed by hand in
        // `paths::vessel::polar`): within the default 0.18, beyond a limit of 0.1.
        let text = SEED.replace("kind = \"helical\"\ncount = 2", "kind = \"polar\"");
        let loaded = VesselFile::parse(&text).unwrap();
        let plan = loaded.check(&text).unwrap();
        assert_eq!(plan.layers[0].mark.kind, paths::motion::LayerKind::Polar);
        let text = SEED.replace(
            "kind = \"helical\"\ncount = 2",
            "kind = \"polar\"\nslip_limit = 0.1",
        );
        let loaded = VesselFile::parse(&text).unwrap();
        let err = loaded.check(&text).unwrap_err().to_string();
        assert!(
            err.starts_with("23:8: layer 1: the polar plane at 12.0643° is not a geodesic"),
            "{err}"
        );
        assert!(err.contains("friction ratio of 0.1481"), "{err}");
        // A tube has no openings.
        let text = SEED
            .replace("kind = \"helical\"\ncount = 2", "kind = \"polar\"")
            .replace(
                "kind = \"vessel\"\ncylinder_radius_mm = 60.0\ncylinder_length_mm = 84.1\n\
                 polar_opening_radius_mm = 21.0",
                "kind = \"tube\"\nradius_mm = 60.0\nlength_mm = 84.1",
            );
        let loaded = VesselFile::parse(&text).unwrap();
        let err = loaded.check(&text).unwrap_err().to_string();
        assert!(err.contains("a polar layer needs a vessel"), "{err}");
    }

    #[test]
    fn a_layer_that_does_not_close_is_reported_at_its_entry() {
        let text = SEED.replace("count = 2", "cycles_per_pattern = 4\ndwell_deg = 0.0");
        let loaded = VesselFile::parse(&text).unwrap();
        let err = loaded.check(&text).unwrap_err().to_string();
        assert!(
            err.starts_with("23:8: layer 1: the winding pattern does not close"),
            "{err}"
        );
        assert!(err.contains("nearest valid"), "{err}");
    }
}
