//! `.wind` files: the JSON winding definitions of Cyclone and FiberPath (schema versions 1.0 to
//! 1.3), read into a lathe winding job for our planner.
//!
//! Fields: `schemaVersion` ("1.x", absent = 1.0); `mandrelParameters` {`diameter`, `windLength`,
//! `endDiameter` (1.1+, a reducing cone), `profile` (1.2+)}; `towParameters` {`width`,
//! `thickness`}; `defaultFeedRate` (mm/min on the surface); `layers`: `hoop` {`terminal`},
//! `helical` {`windAngle`, `patternNumber`, `skipIndex`, `lockDegrees`, `leadInMM`,
//! `leadOutDegrees`, `skipInitialNearLock`, `frictionLambda` (1.3+)}, `skip`
//! {`mandrelRotation`}.
//!
//! The rules a `.wind` file implies are checked before anything is planned, each reported at the
//! line and column of the layer (or field) that breaks it: positive numbers, a wind angle within
//! 1°–89°, a terminal hoop only as the last layer, `skipIndex` below and coprime with
//! `patternNumber`, a lead-in shorter than the mandrel, a circuit count divisible by
//! `patternNumber`, and a lock that steps a circuit through every slot of the pattern (with the
//! nearest locks that do). The mandrel keeps its diameter for every layer (no build-up), as the
//! format assumes.
//!
//! Reducing cones (`endDiameter` below `diameter`, 1.1+): the large end (`diameter`) is at the
//! carriage's start; helical layers follow the cone's geodesic with `windAngle` the angle at the
//! large end, where the circuits are counted ([`paths::vessel::cone`]). An `endDiameter` equal
//! to `diameter` is a cylinder. Refused, each with its reason: an expanding cone, a hoop layer
//! on a cone, and a wind angle whose geodesic turns back before the small end (the cases
//! FiberPath refuses).
//!
//! Nose profiles (`profile`, 1.2+; `{ "type": "vonKarman" }`, the only type the format
//! defines): a von Kármán ogive from `diameter` at the carriage's start to its tip at
//! `windLength` ([`paths::vessel::nose`]). Helical layers leave the base at `windAngle` and run
//! on the geodesic (or, with `frictionLambda` λ > 0, 1.3+, on the path whose geodesic
//! curvature is λ times its normal curvature) to the turnaround where the fibre lies along a
//! parallel, then back; circuits are counted on the base. Refused, each with its reason: a
//! negative λ, λ above the machine slip limit ([`paths::vessel::NOSE_SLIP_LIMIT`], 0.2), a
//! non-zero λ on a cylinder or cone, a hoop layer on a nose, and a wind angle whose path turns
//! around within the lead-in (no usable pass).

use std::path::Path;

use paths::motion::{AxisLimit, AxisSet, Limits};
use paths::vessel::{Job, Layer, Machine, Mandrel, Tow, TubeHelical};
use serde::Deserialize;

use crate::Error;

/// The eye's distance from the mandrel surface on a `.wind` job's machine, mm (the format has no
/// cross-feed: the eye stays at this radius).
pub const EYE_CLEARANCE_MM: f64 = 25.0;

/// Acceleration of the carriage and of the mandrel's surface, mm/s² (the format gives none).
pub const SURFACE_ACCELERATION_MM_S2: f64 = 1000.0;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "camelCase")]
struct Definition {
    schema_version: Option<String>,
    layers: Vec<WindLayer>,
    mandrel_parameters: MandrelParameters,
    tow_parameters: TowParameters,
    default_feed_rate: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "camelCase")]
struct MandrelParameters {
    diameter: f64,
    wind_length: f64,
    end_diameter: Option<f64>,
    profile: Option<Profile>,
}

/// A nose profile (1.2+).
#[derive(Debug, Deserialize)]
#[serde(tag = "type", deny_unknown_fields)]
enum Profile {
    /// The von Kármán ogive (Haack series, C = 0).
    #[serde(rename = "vonKarman")]
    VonKarman {},
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TowParameters {
    width: f64,
    thickness: f64,
}

#[derive(Debug, Deserialize)]
#[serde(tag = "windType", rename_all = "camelCase", deny_unknown_fields)]
enum WindLayer {
    Hoop {
        #[serde(default)]
        terminal: bool,
    },
    #[serde(rename_all = "camelCase")]
    Helical {
        wind_angle: f64,
        pattern_number: u32,
        skip_index: u32,
        lock_degrees: f64,
        #[serde(rename = "leadInMM")]
        lead_in_mm: f64,
        lead_out_degrees: f64,
        #[serde(default)]
        skip_initial_near_lock: bool,
        #[serde(default)]
        friction_lambda: f64,
    },
    #[serde(rename_all = "camelCase")]
    Skip { mandrel_rotation: f64 },
}

/// A `.wind` file.
#[derive(Debug)]
pub struct WindFile;

/// Byte offset of the `index`-th element of the top-level `"layers"` array, if found.
fn layer_offset(text: &str, index: usize) -> Option<usize> {
    let key = text.find("\"layers\"")?;
    let open = key + text[key..].find('[')?;
    let bytes = text.as_bytes();
    let (mut depth, mut in_string, mut escaped, mut count) = (0i32, false, false, 0usize);
    for (i, &b) in bytes.iter().enumerate().skip(open + 1) {
        if in_string {
            match b {
                _ if escaped => escaped = false,
                b'\\' => escaped = true,
                b'"' => in_string = false,
                _ => {}
            }
            continue;
        }
        match b {
            b'"' => in_string = true,
            b'{' | b'[' => {
                if depth == 0 {
                    if count == index {
                        return Some(i);
                    }
                    count += 1;
                }
                depth += 1;
            }
            b'}' | b']' => {
                if depth == 0 {
                    return None;
                }
                depth -= 1;
            }
            _ => {}
        }
    }
    None
}

/// Byte offset of the first `"key"` in the text.
fn key_offset(text: &str, key: &str) -> usize {
    text.find(&format!("\"{key}\"")).unwrap_or(0)
}

/// Refuses a key's value at the key.
fn at_key(text: &str, key: &str, message: String) -> Error {
    Error::at_offset(text, key_offset(text, key), message)
}

/// The schema version: 1.x (absent: 1.0).
fn check_version(def: &Definition, text: &str) -> Result<(), Error> {
    let version = def.schema_version.as_deref().unwrap_or("1.0");
    let minor = version
        .strip_prefix("1.")
        .filter(|m| !m.is_empty() && m.bytes().all(|b| b.is_ascii_digit()));
    if minor.is_none() {
        return Err(at_key(
            text,
            "schemaVersion",
            format!("schema version `{version}` is not 1.x"),
        ));
    }
    Ok(())
}

/// The mandrel's and the tow's figures, a profile or an end diameter (a reducing frustum), and at
/// least one layer.
fn check_mandrel(def: &Definition, text: &str) -> Result<(), Error> {
    let m = &def.mandrel_parameters;
    for (key, v) in [
        ("diameter", m.diameter),
        ("windLength", m.wind_length),
        ("width", def.tow_parameters.width),
        ("thickness", def.tow_parameters.thickness),
        ("defaultFeedRate", def.default_feed_rate),
    ] {
        if !(v > 0.0 && v.is_finite()) {
            return Err(at_key(
                text,
                key,
                format!("{key} = {} must be > 0", crate::error::shown(v)),
            ));
        }
        magnitude(text, key, v)?;
    }
    if def.default_feed_rate < crate::vessel::MIN_AXIS_RATE {
        return Err(at_key(
            text,
            "defaultFeedRate",
            format!(
                "defaultFeedRate = {} is below the least of {} mm/min (docs/ARCHITECTURE.md, \
                 \"Limits\")",
                crate::error::shown(def.default_feed_rate),
                crate::vessel::MIN_AXIS_RATE
            ),
        ));
    }
    if def.layers.len() > crate::vessel::MAX_LAYERS as usize {
        return Err(at_key(
            text,
            "layers",
            format!(
                "{} layers, more than the limit of {}",
                def.layers.len(),
                crate::vessel::MAX_LAYERS
            ),
        ));
    }
    if m.profile.is_some() && m.end_diameter.is_some() {
        return Err(at_key(
            text,
            "profile",
            "profile and endDiameter are mutually exclusive (a profile defines the whole \
             surface)"
                .into(),
        ));
    }
    if let Some(end) = m.end_diameter {
        if !(end > 0.0 && end.is_finite()) {
            return Err(at_key(
                text,
                "endDiameter",
                format!("endDiameter = {} must be > 0", crate::error::shown(end)),
            ));
        }
        if end > m.diameter {
            return Err(at_key(
                text,
                "endDiameter",
                format!(
                    "endDiameter {end} mm is larger than diameter {} mm: only a reducing \
                     frustum is planned (mount the large end at the start, as diameter)",
                    m.diameter
                ),
            ));
        }
    }
    if def.layers.is_empty() {
        return Err(at_key(
            text,
            "layers",
            "a .wind file needs at least one layer".into(),
        ));
    }
    Ok(())
}

/// A value within the job files' magnitudes (docs/ARCHITECTURE.md, "Limits"): a length (mm) within
/// ±[`crate::job::MAX_LENGTH_MM`], anything else (degrees, mm/min) within
/// ±[`crate::job::MAX_MAGNITUDE`]. A mandrel 1e308 mm long or a lock of 1e300° sizes no plan.
fn magnitude(text: &str, key: &str, v: f64) -> Result<(), Error> {
    let length = matches!(
        key,
        "diameter" | "windLength" | "endDiameter" | "width" | "thickness" | "leadInMM"
    );
    let limit = if length {
        crate::job::MAX_LENGTH_MM
    } else {
        crate::job::MAX_MAGNITUDE
    };
    if v.abs() > limit {
        return Err(at_key(
            text,
            key,
            format!(
                "{key} = {} exceeds the limit of ±{}{} (docs/ARCHITECTURE.md, \"Limits\")",
                crate::error::shown(v),
                crate::error::shown(limit),
                if length { " mm" } else { "" }
            ),
        ));
    }
    Ok(())
}

/// The planner's layer of the definition's layer `i` (0-based; `last` for the last one).
fn layer_of(l: &WindLayer, i: usize, last: bool, text: &str) -> Result<Layer, Error> {
    let here = |message: String| {
        Error::at_offset(
            text,
            layer_offset(text, i).unwrap_or(0),
            format!("layer {}: {message}", i + 1),
        )
    };
    Ok(match *l {
        WindLayer::Hoop { terminal } => {
            if terminal && !last {
                return Err(here("a terminal layer must be the last layer".into()));
            }
            Layer::Hoop {
                passes: if terminal { 1 } else { 2 },
            }
        }
        WindLayer::Helical {
            wind_angle,
            pattern_number,
            skip_index,
            lock_degrees,
            lead_in_mm,
            lead_out_degrees,
            skip_initial_near_lock,
            friction_lambda,
        } => {
            for (k, v) in [
                ("lockDegrees", lock_degrees),
                ("leadInMM", lead_in_mm),
                ("leadOutDegrees", lead_out_degrees),
            ] {
                if !(v > 0.0 && v.is_finite()) {
                    return Err(here(format!(
                        "{k} = {} must be > 0",
                        crate::error::shown(v)
                    )));
                }
                let limit = if k == "leadInMM" {
                    crate::job::MAX_LENGTH_MM
                } else {
                    crate::job::MAX_MAGNITUDE
                };
                if v > limit {
                    return Err(here(format!(
                        "{k} = {} exceeds the limit of {} (docs/ARCHITECTURE.md, \"Limits\")",
                        crate::error::shown(v),
                        crate::error::shown(limit)
                    )));
                }
            }
            if pattern_number == 0 || skip_index == 0 {
                return Err(here("patternNumber and skipIndex must be ≥ 1".into()));
            }
            Layer::TubeHelical(TubeHelical {
                wind_angle_deg: wind_angle,
                pattern_number,
                skip_index,
                lock_deg: lock_degrees,
                lead_in_mm,
                lead_out_deg: lead_out_degrees,
                initial_lock: !skip_initial_near_lock,
                friction_lambda,
            })
        }
        WindLayer::Skip { mandrel_rotation } => {
            if !mandrel_rotation.is_finite() {
                return Err(here("mandrelRotation must be finite".into()));
            }
            if mandrel_rotation.abs() > crate::job::MAX_MAGNITUDE {
                return Err(here(format!(
                    "mandrelRotation = {} exceeds the limit of ±{} (docs/ARCHITECTURE.md, \
                     \"Limits\")",
                    crate::error::shown(mandrel_rotation),
                    crate::error::shown(crate::job::MAX_MAGNITUDE)
                )));
            }
            Layer::Skip {
                mandrel_deg: mandrel_rotation,
            }
        }
    })
}

/// The mandrel: a Von Kármán nose with a profile, a frustum with a smaller end diameter, else a
/// tube.
fn mandrel_of(m: &MandrelParameters) -> Mandrel {
    let radius = m.diameter / 2.0;
    match m.end_diameter {
        _ if m.profile.is_some() => Mandrel::VonKarman {
            base_radius_mm: radius,
            length_mm: m.wind_length,
        },
        Some(end) if end < m.diameter => Mandrel::Cone {
            large_radius_mm: radius,
            small_radius_mm: end / 2.0,
            length_mm: m.wind_length,
        },
        _ => Mandrel::Tube {
            radius_mm: radius,
            length_mm: m.wind_length,
        },
    }
}

/// The four-axis machine at the definition's feed (mm/min): the carriage at the feed, the
/// mandrel at the feed on its surface of `radius` mm.
fn machine_of(radius: f64, default_feed_rate: f64) -> Machine {
    let feed_mm_s = default_feed_rate / 60.0;
    let deg_per_mm = 360.0 / (std::f64::consts::TAU * radius);
    let linear = AxisLimit {
        velocity: feed_mm_s,
        acceleration: SURFACE_ACCELERATION_MM_S2,
    };
    Machine {
        axes: AxisSet::Four,
        eye_radius_mm: radius + EYE_CLEARANCE_MM,
        limits: Limits {
            axes: [
                AxisLimit {
                    velocity: feed_mm_s * deg_per_mm,
                    acceleration: SURFACE_ACCELERATION_MM_S2 * deg_per_mm,
                },
                linear,
                linear,
                AxisLimit {
                    velocity: 360.0,
                    acceleration: 3600.0,
                },
            ],
            junction_deviation: 0.01,
        },
        dome_steps: 10,
    }
}

impl WindFile {
    /// Parses a `.wind` definition into a job (checked for the format's rules, not yet planned).
    /// Returns the job and a name for its output files.
    pub fn parse(text: &str, name: &str) -> Result<Job, Error> {
        let def: Definition = serde_json::from_str(text)
            .map_err(|e| Error::at(e.line().max(1), e.column().max(1), lower(&e.to_string())))?;
        check_version(&def, text)?;
        check_mandrel(&def, text)?;
        let last = def.layers.len() - 1;
        let layers = def
            .layers
            .iter()
            .enumerate()
            .map(|(i, l)| layer_of(l, i, i == last, text))
            .collect::<Result<Vec<_>, _>>()?;
        let m = &def.mandrel_parameters;
        let job = Job {
            mandrel: mandrel_of(m),
            tow: Tow {
                band_mm: def.tow_parameters.width,
                thickness_mm: def.tow_parameters.thickness,
            },
            machine: machine_of(m.diameter / 2.0, def.default_feed_rate),
            layers,
            build_up: false,
        };
        // The planner's rules (circuits, pattern, lock), reported at the layer.
        job.check().map_err(|e| match e {
            paths::Error::WindRule { layer, reason } => Error::at_offset(
                text,
                layer_offset(text, layer - 1).unwrap_or(0),
                format!("layer {layer}: {reason}"),
            ),
            paths::Error::Layer { layer, source } => Error::at_offset(
                text,
                layer_offset(text, layer - 1).unwrap_or(0),
                format!("layer {layer}: {source}"),
            ),
            other => Error::content(other.to_string()),
        })?;
        let _ = name;
        Ok(job)
    }

    /// Reads and parses a `.wind` file; errors name it. Returns the job and the file's stem.
    pub fn load(path: &Path) -> Result<(Job, String), Error> {
        let text = crate::source::read_text(path, crate::source::MAX_JOB_BYTES)?;
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "wind".into());
        // The stem names the program written from it (`NAME.EXT` in the output folder).
        if name.starts_with('.')
            || name.chars().count() > crate::job::MAX_NAME_CHARS
            || name.chars().any(char::is_control)
        {
            return Err(Error::content(format!(
                "the file's name `{}` names the program written from it: it may not start with \
                 `.`, hold control characters or run past {} characters",
                name.escape_default().take(80).collect::<String>(),
                crate::job::MAX_NAME_CHARS
            ))
            .in_file(path));
        }
        let job = WindFile::parse(&text, &name).map_err(|e| e.in_file(path))?;
        Ok((job, name))
    }
}

/// serde_json's message without its trailing position (we give line and column ourselves).
fn lower(message: &str) -> String {
    match message.rfind(" at line ") {
        Some(i) => message[..i].to_string(),
        None => message.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TUBE: &str = r#"{
  "schemaVersion": "1.3",
  "mandrelParameters": { "diameter": 70, "windLength": 500 },
  "towParameters": { "width": 6.5, "thickness": 0.25 },
  "defaultFeedRate": 6000,
  "layers": [
    { "windType": "hoop" },
    { "windType": "helical", "windAngle": 45, "patternNumber": 3, "skipIndex": 1,
      "lockDegrees": 720, "leadInMM": 10, "leadOutDegrees": 10 },
    { "windType": "skip", "mandrelRotation": 90 },
    { "windType": "hoop", "terminal": true }
  ]
}"#;

    #[test]
    fn parses_every_layer_kind() {
        let job = WindFile::parse(TUBE, "t").unwrap();
        assert_eq!(job.layers.len(), 4);
        assert_eq!(job.layers[0], Layer::Hoop { passes: 2 });
        assert_eq!(job.layers[3], Layer::Hoop { passes: 1 });
        assert!(
            matches!(job.layers[1], Layer::TubeHelical(t) if t.initial_lock && t.pattern_number == 3)
        );
        assert_eq!(job.layers[2], Layer::Skip { mandrel_deg: 90.0 });
        assert!(!job.build_up);
        assert_eq!(job.machine.limits.axes[1].velocity, 100.0);
        // Absent version is 1.0.
        let old = TUBE.replace("\"schemaVersion\": \"1.3\",", "");
        assert!(WindFile::parse(&old, "t").is_ok());
        // The machine: the eye 25 mm off the 35 mm radius; the carriage at the feed (6000 mm/min
        // = 100 mm/s, 1000 mm/s²) and the mandrel at the same surface speed, in degrees.
        assert_eq!(job.machine.eye_radius_mm, 60.0);
        let deg_per_mm = 360.0 / (std::f64::consts::TAU * 35.0);
        let mandrel = job.machine.limits.axes[0];
        assert!((mandrel.velocity - 100.0 * deg_per_mm).abs() < 1e-9);
        assert!((mandrel.acceleration - 1000.0 * deg_per_mm).abs() < 1e-9);
        assert_eq!(job.machine.limits.axes[1].acceleration, 1000.0);
    }

    /// Each `(from, to, expect)`: `base` with `from` replaced by `to` is refused with a message
    /// that begins with `expect` (its line and column first).
    fn refused_as(base: &str, cases: &[(&str, &str, &str)]) {
        for &(from, to, expect) in cases {
            let text = base.replace(from, to);
            assert_ne!(text, base, "{from}");
            let err = WindFile::parse(&text, "t").unwrap_err().to_string();
            assert!(err.starts_with(expect), "{expect}: {err}");
        }
    }

    #[test]
    fn the_parsers_own_checks_come_first() {
        let cases = [
            ("\"1.3\"", "\"1.x\"", "2:3: schema version `1.x` is not 1.x"),
            ("\"1.3\"", "\"1.\"", "2:3: schema version `1.` is not 1.x"),
            (
                "\"diameter\": 70",
                "\"diameter\": 0",
                "3:26: diameter = 0 must be > 0",
            ),
            (
                "\"lockDegrees\": 720",
                "\"lockDegrees\": 0",
                "8:5: layer 2: lockDegrees = 0 must be > 0",
            ),
            (
                "\"lockDegrees\": 720",
                "\"lockDegrees\": -1",
                "8:5: layer 2: lockDegrees = -1 must be > 0",
            ),
            (
                "\"patternNumber\": 3",
                "\"patternNumber\": 0",
                "8:5: layer 2: patternNumber and skipIndex must be ≥ 1",
            ),
        ];
        refused_as(TUBE, &cases);
    }

    #[test]
    fn rules_are_reported_at_the_layer() {
        let cases = [
            (
                "\"skipIndex\": 1",
                "\"skipIndex\": 3",
                "8:5: layer 2: skip index 3 must be smaller",
            ),
            (
                "\"patternNumber\": 3",
                "\"patternNumber\": 5",
                "8:5: layer 2: 24 circuits",
            ),
            (
                "\"lockDegrees\": 720",
                "\"lockDegrees\": 700",
                "8:5: layer 2: lock 700°",
            ),
            (
                "\"leadInMM\": 10",
                "\"leadInMM\": 600",
                "8:5: layer 2: lead-in 600 mm",
            ),
            (
                "\"windAngle\": 45",
                "\"windAngle\": 89.5",
                "8:5: layer 2: wind angle 89.5°",
            ),
            (
                "{ \"windType\": \"hoop\" }",
                "{ \"windType\": \"hoop\", \"terminal\": true }",
                "7:5: layer 1: a terminal layer must be the last",
            ),
            (
                "\"leadOutDegrees\": 10",
                "\"leadOutDegrees\": 10, \"frictionLambda\": 0.1",
                "8:5: layer 2: frictionLambda",
            ),
            ("\"1.3\"", "\"2.0\"", "2:3: schema version `2.0` is not 1.x"),
            (
                "\"windLength\": 500",
                "\"windLength\": 500, \"endDiameter\": 80",
                "3:61: endDiameter 80 mm is larger than diameter 70 mm",
            ),
            (
                "\"windLength\": 500",
                "\"windLength\": 500, \"endDiameter\": 0",
                "3:61: endDiameter = 0 must be > 0",
            ),
            (
                "\"windLength\": 500",
                "\"windLength\": 500, \"endDiameter\": 50, \"profile\": { \"type\": \"vonKarman\" }",
                "3:80: profile and endDiameter are mutually exclusive",
            ),
            (
                "\"windLength\": 500",
                "\"windLength\": 500, \"profile\": { \"type\": \"tangentOgive\" }",
                "3:95: unknown variant `tangentOgive`, expected `vonKarman`",
            ),
            (
                "\"width\": 6.5",
                "\"width\": -1",
                "4:22: width = -1 must be > 0",
            ),
            (
                "\"windType\": \"skip\"",
                "\"windType\": \"polar\"",
                "10:25: unknown variant `polar`",
            ),
            (
                "\"defaultFeedRate\": 6000,",
                "",
                "13:1: missing field `defaultFeedRate`",
            ),
        ];
        refused_as(TUBE, &cases);
    }

    /// FiberPath's cone cases: 98 → 54 mm over 120 mm.
    const CONE: &str = include_str!("../tests/data/reducer.wind");

    #[test]
    fn a_reducing_cone_is_planned_with_the_large_end_first() {
        let job = WindFile::parse(CONE, "c").unwrap();
        assert_eq!(
            job.mandrel,
            Mandrel::Cone {
                large_radius_mm: 49.0,
                small_radius_mm: 27.0,
                length_mm: 120.0
            }
        );
        // An end diameter equal to the diameter is a cylinder.
        let same = CONE.replace("\"endDiameter\": 54.0", "\"endDiameter\": 98.0");
        let job = WindFile::parse(&same, "c").unwrap();
        assert_eq!(
            job.mandrel,
            Mandrel::Tube {
                radius_mm: 49.0,
                length_mm: 120.0
            }
        );
    }

    #[test]
    fn cone_refusals_are_reported_at_the_layer() {
        let cases = [
            (
                "\"windAngle\": 30",
                "\"windAngle\": 40",
                "4:5: layer 1: wind angle 40° is too steep for the cone",
            ),
            (
                "{ \"windType\": \"skip\", \"mandrelRotation\": 45 }",
                "{ \"windType\": \"hoop\" }",
                "6:5: layer 2: hoop layers on a cone are not planned",
            ),
            (
                "\"endDiameter\": 54.0",
                "\"endDiameter\": 154.0",
                "8:65: endDiameter 154 mm is larger than diameter 98 mm",
            ),
        ];
        refused_as(CONE, &cases);
    }

    /// A von Kármán nose: 98 mm base, 300 mm long (the dimensions of FiberPath's example).
    const NOSE: &str = r#"{
  "schemaVersion": "1.3",
  "mandrelParameters": { "diameter": 98, "windLength": 300, "profile": { "type": "vonKarman" } },
  "towParameters": { "width": 7, "thickness": 0.5 },
  "defaultFeedRate": 9000,
  "layers": [
    { "windType": "helical", "windAngle": 30, "patternNumber": 3, "skipIndex": 1,
      "lockDegrees": 180, "leadInMM": 5, "leadOutDegrees": 15, "frictionLambda": 0.15 },
    { "windType": "skip", "mandrelRotation": 45 }
  ]
}"#;

    #[test]
    fn a_nose_profile_is_planned_from_its_base() {
        let job = WindFile::parse(NOSE, "n").unwrap();
        assert_eq!(
            job.mandrel,
            Mandrel::VonKarman {
                base_radius_mm: 49.0,
                length_mm: 300.0
            }
        );
        assert!(matches!(job.layers[0], Layer::TubeHelical(t) if t.friction_lambda == 0.15));
        // Absent, λ is 0 (the geodesic).
        let geodesic = NOSE.replace(", \"frictionLambda\": 0.15", "");
        let job = WindFile::parse(&geodesic, "n").unwrap();
        assert!(matches!(job.layers[0], Layer::TubeHelical(t) if t.friction_lambda == 0.0));
        // ceil(2π·49·cos 30° / 7) = ceil(38.09) = 39 circuits, counted on the base.
        assert_eq!(job.check().unwrap().layers[0].mark.circuits, 39);
    }

    #[test]
    fn nose_refusals_are_reported_at_the_layer() {
        let cases = [
            (
                "\"frictionLambda\": 0.15",
                "\"frictionLambda\": -0.1",
                "7:5: layer 1: frictionLambda = -0.1 must be ≥ 0",
            ),
            (
                "\"frictionLambda\": 0.15",
                "\"frictionLambda\": 0.5",
                "7:5: layer 1: frictionLambda 0.5 exceeds the machine slip limit 0.2",
            ),
            (
                "\"frictionLambda\": 0.15",
                "\"frictionLambda\": 0.2000001",
                "7:5: layer 1: frictionLambda 0.2000001 exceeds the machine slip limit 0.2",
            ),
            (
                "{ \"windType\": \"skip\", \"mandrelRotation\": 45 }",
                "{ \"windType\": \"hoop\" }",
                "9:5: layer 2: hoop layers on a nose profile are not planned",
            ),
            (
                "{ \"type\": \"vonKarman\" }",
                "{ \"type\": \"vonKarman\", \"c\": 0.33 }",
                "3:107: unknown field `c`",
            ),
        ];
        refused_as(NOSE, &cases);
        // FiberPath's unreachable case: 89° on the geodesic turns around 0.955 mm from the base,
        // inside the lead-in (r(5 mm) = 48.9109 mm is R·sin 86.5437°).
        let steep = NOSE
            .replace(", \"frictionLambda\": 0.15", "")
            .replace("\"windAngle\": 30", "\"windAngle\": 89");
        let err = WindFile::parse(&steep, "n").unwrap_err().to_string();
        assert!(
            err.starts_with(
                "7:5: layer 1: wind angle 89° has no usable pass: its path turns around 0.955 mm \
                 from the base (radius 48.993 mm), within the 5 mm lead-in; the geodesic turns \
                 around past the lead-in only below 86.54"
            ),
            "{err}"
        );
        // The slip limit itself is allowed.
        let edge = NOSE.replace("\"frictionLambda\": 0.15", "\"frictionLambda\": 0.2");
        assert!(WindFile::parse(&edge, "n").is_ok());
    }

    #[test]
    fn finds_layer_objects_past_strings_and_nesting() {
        let text = r#"{"a": "[{", "layers": [ {"x": [1, {"y": 2}]}, "s}", {"z": "{"} ]}"#;
        assert_eq!(layer_offset(text, 0), Some(text.find("{\"x\"").unwrap()));
        assert_eq!(layer_offset(text, 1), Some(text.find("{\"z\"").unwrap()));
        assert_eq!(layer_offset(text, 2), None);
        // An escaped quote does not end a string; an escaped backslash does not escape the quote
        // after it.
        let text = r#"{"layers": [ {"x": "a\"{"}, {"y": "b\\"}, {"z": 1} ]}"#;
        assert_eq!(layer_offset(text, 1), Some(text.find("{\"y\"").unwrap()));
        assert_eq!(layer_offset(text, 2), Some(text.find("{\"z\"").unwrap()));
    }
}
