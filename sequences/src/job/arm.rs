//! The arm's kind and the six-axis keys of `[cell.robot]`, `[cell.tool]` and `[cell.mandrel]`:
//! which keys belong to which kind, their checks (each error at the offending value's line and
//! column) and the `paths::arm` values they describe.

use std::ops::Range;

use paths::arm::opw::{self, Opw};
use paths::arm::ur::{self, UR_JOINT_RANGE_DEG, Ur};
use paths::arm::{JointLimits6, MandrelAxis, SixAxisArm, SixAxisKind, Tool as ArmTool};
use toml::Spanned;

use super::{Cell, Job, MandrelDrive, Robot, RobotKind, check, error_at, finite, positive};
use crate::Error;

type Span = Option<Range<usize>>;

fn span<T>(v: &Option<Spanned<T>>) -> Span {
    v.as_ref().map(Spanned::span)
}

/// The IRB 6/2's own keys.
fn irb_keys(r: &Robot) -> [(&'static str, Span); 10] {
    [
        ("shoulder_height_mm", span(&r.shoulder_height_mm)),
        ("upper_arm_mm", span(&r.upper_arm_mm)),
        ("forearm_mm", span(&r.forearm_mm)),
        ("eye_mechanism_max_mm", span(&r.eye_mechanism_max_mm)),
        ("base_yaw_deg", span(&r.base_yaw_deg)),
        ("shoulder_deg", span(&r.shoulder_deg)),
        ("elbow_deg", span(&r.elbow_deg)),
        ("pitch_deg", span(&r.pitch_deg)),
        ("roll_deg", span(&r.roll_deg)),
        ("entry_angle_max_deg", span(&r.entry_angle_max_deg)),
    ]
}

/// Keys of OPW arms only.
fn opw_keys(r: &Robot) -> [(&'static str, Span); 8] {
    [
        ("a1_mm", span(&r.a1_mm)),
        ("b_mm", span(&r.b_mm)),
        ("c1_mm", span(&r.c1_mm)),
        ("c2_mm", span(&r.c2_mm)),
        ("c3_mm", span(&r.c3_mm)),
        ("c4_mm", span(&r.c4_mm)),
        ("offsets_deg", span(&r.offsets_deg)),
        ("signs", span(&r.signs)),
    ]
}

/// Keys of UR arms only.
fn ur_keys(r: &Robot) -> [(&'static str, Span); 5] {
    [
        ("d1_mm", span(&r.d1_mm)),
        ("a3_mm", span(&r.a3_mm)),
        ("d4_mm", span(&r.d4_mm)),
        ("d5_mm", span(&r.d5_mm)),
        ("d6_mm", span(&r.d6_mm)),
    ]
}

/// Keys of every six-axis arm.
fn six_axis_keys(r: &Robot) -> [(&'static str, Span); 8] {
    [
        ("model", span(&r.model)),
        ("a2_mm", span(&r.a2_mm)),
        ("joint_min_deg", span(&r.joint_min_deg)),
        ("joint_max_deg", span(&r.joint_max_deg)),
        ("link_radii_mm", span(&r.link_radii_mm)),
        ("limit_margin_deg", span(&r.limit_margin_deg)),
        ("wrist_margin_deg", span(&r.wrist_margin_deg)),
        ("joint_step_max_deg", span(&r.joint_step_max_deg)),
    ]
}

fn kind_name(kind: RobotKind) -> &'static str {
    match kind {
        RobotKind::Irb6 => "irb6-2",
        RobotKind::Opw => "opw",
        RobotKind::Ur => "ur",
    }
}

fn refuse(text: &str, keys: &[(&'static str, Span)], kind: RobotKind) -> Result<(), Error> {
    for (name, s) in keys {
        if let Some(s) = s {
            return Err(error_at(
                text,
                s.clone(),
                format!(
                    "`{name}` does not apply to kind = \"{}\"{}",
                    kind_name(kind),
                    if kind == RobotKind::Irb6 {
                        " (the default; set kind = \"opw\" or \"ur\" for a six-axis arm)"
                    } else {
                        ""
                    }
                ),
            ));
        }
    }
    Ok(())
}

/// The array's length must be `n` and every value finite.
fn array(text: &str, v: &Spanned<Vec<f64>>, key: &str, n: usize) -> Result<(), Error> {
    if v.get_ref().len() != n {
        return Err(error_at(
            text,
            v.span(),
            format!(
                "{key} needs {n} values, one per axis; {} given",
                v.get_ref().len()
            ),
        ));
    }
    if let Some(i) = v.get_ref().iter().position(|x| !x.is_finite()) {
        return Err(error_at(
            text,
            v.span(),
            format!("{key}: the value for axis {} is not finite", i + 1),
        ));
    }
    Ok(())
}

/// Checks `[cell.robot]` for its kind (and `[cell.tool]`, which only six-axis arms have): the
/// keys of other kinds refused, a known model or every parameter, each value, the joint ranges
/// against each other, the tool, and last the arm as a whole.
pub(super) fn validate_robot(text: &str, r: &Robot, c: &Cell) -> Result<(), Error> {
    let kind = r.kind.as_ref().map_or(RobotKind::Irb6, |k| *k.get_ref());
    let kind_span = r.kind.as_ref().map(Spanned::span);
    if kind == RobotKind::Irb6 {
        return validate_irb6(text, r, c);
    }
    let kind_span = kind_span.unwrap_or(0..0);
    refuse(text, &irb_keys(r), kind)?;
    match kind {
        RobotKind::Opw => refuse(text, &ur_keys(r), kind)?,
        _ => refuse(text, &opw_keys(r), kind)?,
    }
    validate_model(text, r, kind, &kind_span)?;
    validate_six_axis_values(text, r)?;
    validate_joint_ranges(text, r, kind, &kind_span)?;
    let tool = validate_tool(text, c, kind, &kind_span)?;
    // Whatever the per-key checks let through, the arm itself must accept.
    if let Some(Err(e)) = six_axis(r, Some(tool)).map(|a| a.validate()) {
        return Err(error_at(text, kind_span, e.to_string()));
    }
    Ok(())
}

/// The IRB 6/2 (the default kind): no six-axis key, five joint speeds, no `[cell.tool]`.
fn validate_irb6(text: &str, r: &Robot, c: &Cell) -> Result<(), Error> {
    let kind = RobotKind::Irb6;
    let speeds = r.joint_speed_deg_s.as_ref();
    refuse(text, &opw_keys(r), kind)?;
    refuse(text, &ur_keys(r), kind)?;
    refuse(text, &six_axis_keys(r), kind)?;
    if let Some(s) = speeds {
        array(text, s, "joint_speed_deg_s", 5)?;
    }
    if let Some(t) = &c.tool {
        return Err(error_at(
            text,
            t.tcp_mm.span(),
            "[cell.tool] applies to six-axis arms (kind = \"opw\" or \"ur\"); the IRB 6/2's \
             eye sits on its roll axis at eye_mechanism_length_mm",
        ));
    }
    Ok(())
}

/// A six-axis arm's `model` must be a known one; without a model every parameter is needed.
fn validate_model(
    text: &str,
    r: &Robot,
    kind: RobotKind,
    kind_span: &Range<usize>,
) -> Result<(), Error> {
    if let Some(model) = &r.model {
        let known = match kind {
            RobotKind::Opw => opw::preset(model.get_ref()).is_some(),
            _ => ur::preset(model.get_ref()).is_some(),
        };
        if !known {
            return Err(error_at(
                text,
                model.span(),
                format!(
                    "unknown {} model \"{}\" (known: {}; or give every parameter instead of a \
                     model)",
                    kind_name(kind),
                    model.get_ref(),
                    match kind {
                        RobotKind::Opw => opw::preset_names(),
                        _ => ur::preset_names(),
                    }
                ),
            ));
        }
    } else {
        // Without a model every parameter is needed.
        let required: Vec<(&str, bool)> = match kind {
            RobotKind::Opw => vec![
                ("a1_mm", r.a1_mm.is_some()),
                ("a2_mm", r.a2_mm.is_some()),
                ("b_mm", r.b_mm.is_some()),
                ("c1_mm", r.c1_mm.is_some()),
                ("c2_mm", r.c2_mm.is_some()),
                ("c3_mm", r.c3_mm.is_some()),
                ("c4_mm", r.c4_mm.is_some()),
                ("offsets_deg", r.offsets_deg.is_some()),
                ("signs", r.signs.is_some()),
                ("joint_min_deg", r.joint_min_deg.is_some()),
                ("joint_max_deg", r.joint_max_deg.is_some()),
            ],
            _ => vec![
                ("d1_mm", r.d1_mm.is_some()),
                ("a2_mm", r.a2_mm.is_some()),
                ("a3_mm", r.a3_mm.is_some()),
                ("d4_mm", r.d4_mm.is_some()),
                ("d5_mm", r.d5_mm.is_some()),
                ("d6_mm", r.d6_mm.is_some()),
            ],
        };
        if let Some((name, _)) = required.iter().find(|(_, present)| !present) {
            return Err(error_at(
                text,
                kind_span.clone(),
                format!(
                    "missing `{name}` for kind = \"{}\" (give a `model` or every parameter; \
                     docs/arms.md)",
                    kind_name(kind)
                ),
            ));
        }
    }
    Ok(())
}

/// A six-axis arm's values, key by key: finite lengths, offsets, signs, joint ends and speeds,
/// link radii, margins and the joint step.
fn validate_six_axis_values(text: &str, r: &Robot) -> Result<(), Error> {
    for v in [
        &r.a1_mm, &r.a2_mm, &r.b_mm, &r.c1_mm, &r.c2_mm, &r.c3_mm, &r.c4_mm, &r.d1_mm, &r.a3_mm,
        &r.d4_mm, &r.d5_mm, &r.d6_mm,
    ]
    .into_iter()
    .flatten()
    {
        finite(text, v, "arm length")?;
    }
    if let Some(v) = &r.c2_mm {
        positive(text, v, "upper arm length")?;
    }
    if let Some(o) = &r.offsets_deg {
        array(text, o, "offsets_deg", 6)?;
        if let Some(i) = o.get_ref().iter().position(|x| x.abs() > 720.0) {
            return Err(error_at(
                text,
                o.span(),
                format!("offsets_deg: the offset of axis {} is beyond ±720°", i + 1),
            ));
        }
    }
    if let Some(signs) = &r.signs {
        let s = signs.get_ref();
        if s.len() != 6 {
            return Err(error_at(
                text,
                signs.span(),
                format!("signs needs 6 values, one per axis; {} given", s.len()),
            ));
        }
        if let Some(i) = s.iter().position(|v| *v != 1 && *v != -1) {
            return Err(error_at(
                text,
                signs.span(),
                format!("signs: the sign of axis {} is {}, not 1 or -1", i + 1, s[i]),
            ));
        }
    }
    for (v, key) in [
        (&r.joint_min_deg, "joint_min_deg"),
        (&r.joint_max_deg, "joint_max_deg"),
        (&r.joint_speed_deg_s, "joint_speed_deg_s"),
    ] {
        if let Some(v) = v {
            array(text, v, key, 6)?;
            if let Some(i) = v.get_ref().iter().position(|x| x.abs() > 720.0) {
                return Err(error_at(
                    text,
                    v.span(),
                    format!("{key}: the value for axis {} is beyond ±720", i + 1),
                ));
            }
        }
    }
    if let Some(s) = &r.joint_speed_deg_s
        && let Some(i) = s.get_ref().iter().position(|v| *v <= 0.0)
    {
        return Err(error_at(
            text,
            s.span(),
            format!("joint_speed_deg_s: the speed of axis {} must be > 0", i + 1),
        ));
    }
    if let Some(radii) = &r.link_radii_mm {
        array(text, radii, "link_radii_mm", paths::arm::LINKS)?;
        if let Some(i) = radii
            .get_ref()
            .iter()
            .position(|v| *v < 0.0 || *v > super::MAX_LENGTH_MM)
        {
            return Err(error_at(
                text,
                radii.span(),
                format!(
                    "link_radii_mm: the radius of the {} must lie in 0..100000 mm",
                    paths::arm::LINK_NAMES[i]
                ),
            ));
        }
    }
    for (v, hi, what) in [
        (
            &r.limit_margin_deg,
            30.0,
            "is not a valid joint limit margin: must lie in 0..30°",
        ),
        (
            &r.wrist_margin_deg,
            45.0,
            "is not a valid wrist margin: must lie in 0..45°",
        ),
    ] {
        if let Some(v) = v {
            check(text, v, *v.get_ref() >= 0.0 && *v.get_ref() <= hi, what)?;
        }
    }
    if let Some(v) = &r.joint_step_max_deg {
        check(
            text,
            v,
            *v.get_ref() > 0.0 && *v.get_ref() <= 180.0,
            "is not a valid joint step limit: must lie in (0°, 180°]",
        )?;
    }
    Ok(())
}

/// The joint ranges against each other, once both ends are known (a model's ends for a missing
/// one).
fn validate_joint_ranges(
    text: &str,
    r: &Robot,
    kind: RobotKind,
    kind_span: &Range<usize>,
) -> Result<(), Error> {
    let limits = limits(r, kind);
    for i in 0..6 {
        if limits.min_rad[i] >= limits.max_rad[i] {
            let at = r
                .joint_max_deg
                .as_ref()
                .or(r.joint_min_deg.as_ref())
                .map_or(kind_span.clone(), Spanned::span);
            return Err(error_at(
                text,
                at,
                format!(
                    "axis {}: joint_min_deg {} is not below joint_max_deg {}",
                    i + 1,
                    crate::error::shown(limits.min_rad[i].to_degrees()),
                    crate::error::shown(limits.max_rad[i].to_degrees())
                ),
            ));
        }
    }
    Ok(())
}

/// `[cell.tool]`, which a six-axis arm needs: the payout eye's place (and turn) on the flange.
fn validate_tool<'c>(
    text: &str,
    c: &'c Cell,
    kind: RobotKind,
    kind_span: &Range<usize>,
) -> Result<&'c super::Tool, Error> {
    let Some(tool) = &c.tool else {
        return Err(error_at(
            text,
            kind_span.clone(),
            format!(
                "kind = \"{}\" needs [cell.tool] with tcp_mm, where the payout eye sits on the \
                 flange",
                kind_name(kind)
            ),
        ));
    };
    if !tool
        .tcp_mm
        .get_ref()
        .iter()
        .all(|v| v.is_finite() && v.abs() <= 10_000.0)
    {
        return Err(error_at(
            text,
            tool.tcp_mm.span(),
            "tcp_mm must be finite and within ±10000 mm",
        ));
    }
    if let Some(rpy) = &tool.rpy_deg
        && !rpy
            .get_ref()
            .iter()
            .all(|v| v.is_finite() && v.abs() <= 360.0)
    {
        return Err(error_at(
            text,
            rpy.span(),
            "rpy_deg must be finite and within ±360°",
        ));
    }
    Ok(tool)
}

/// Checks `[cell.mandrel]` and its combination with the arm and the calibration.
pub(super) fn validate_placement(text: &str, c: &Cell) -> Result<(), Error> {
    let Some(m) = &c.mandrel else {
        return Ok(());
    };
    if let Some(o) = &m.axis_origin_mm
        && !o
            .get_ref()
            .iter()
            .all(|v| v.is_finite() && v.abs() <= super::MAX_LENGTH_MM)
    {
        return Err(error_at(
            text,
            o.span(),
            "axis_origin_mm must be finite and within ±100000 mm",
        ));
    }
    if let Some(d) = &m.axis_direction {
        let v = d.get_ref();
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if !(n.is_finite() && n > 1e-9) {
            return Err(error_at(
                text,
                d.span(),
                "axis_direction must be a finite, non-zero vector",
            ));
        }
    }
    if let (Some(k), Some(first)) = (
        &c.calibration,
        m.axis_origin_mm
            .as_ref()
            .map(Spanned::span)
            .or(m.axis_direction.as_ref().map(Spanned::span)),
    ) && (k.axis_offset_mm.is_some() || k.axis_tilt_deg.is_some())
    {
        return Err(error_at(
            text,
            first,
            "[cell.mandrel] places the axis itself; measure it into axis_origin_mm and \
             axis_direction instead of [cell.calibration] axis_offset_mm / axis_tilt_deg",
        ));
    }
    if let Some(d) = &m.drive
        && *d.get_ref() == MandrelDrive::Robot
    {
        let kind = c
            .robot
            .as_ref()
            .and_then(|r| r.kind.as_ref())
            .map_or(RobotKind::Irb6, |k| *k.get_ref());
        if kind != RobotKind::Opw {
            return Err(error_at(
                text,
                d.span(),
                format!(
                    "drive = \"robot\" needs a robot controller with an external axis; kind = \
                     \"{}\" has none (use drive = \"indexer\")",
                    kind_name(kind)
                ),
            ));
        }
    }
    Ok(())
}

/// The joint ranges and speeds: the model's, each array replaced where given; a UR arm without
/// a model ±360° (UR's data sheets), no speeds.
fn limits(r: &Robot, kind: RobotKind) -> JointLimits6 {
    let (mut min, mut max, mut speed) = match kind {
        RobotKind::Opw => match r.model.as_ref().and_then(|m| opw::preset(m.get_ref())) {
            Some(p) => (p.joint_min_deg, p.joint_max_deg, Some(p.joint_speed_deg_s)),
            None => ([0.0; 6], [0.0; 6], None),
        },
        _ => (
            [-UR_JOINT_RANGE_DEG; 6],
            [UR_JOINT_RANGE_DEG; 6],
            r.model
                .as_ref()
                .and_then(|m| ur::preset(m.get_ref()))
                .map(|p| p.joint_speed_deg_s),
        ),
    };
    let six = |v: &Option<Spanned<Vec<f64>>>| {
        v.as_ref()
            .filter(|v| v.get_ref().len() == 6)
            .map(|v| std::array::from_fn::<f64, 6, _>(|i| v.get_ref()[i]))
    };
    if let Some(v) = six(&r.joint_min_deg) {
        min = v;
    }
    if let Some(v) = six(&r.joint_max_deg) {
        max = v;
    }
    if let Some(v) = six(&r.joint_speed_deg_s) {
        speed = Some(v);
    }
    JointLimits6::degrees(min, max, speed)
}

/// The six-axis arm `[cell.robot]` and `[cell.tool]` describe: the model's values (if any), each
/// key given replacing its value. `None` for the IRB 6/2 or an incomplete description (which
/// [`super::Job::parse`] refuses).
fn six_axis(r: &Robot, tool: Option<&super::Tool>) -> Option<SixAxisArm> {
    let kind = r.kind.as_ref().map_or(RobotKind::Irb6, |k| *k.get_ref());
    let value = |v: &Option<Spanned<f64>>| v.as_ref().map(|v| *v.get_ref());
    let kinematics = match kind {
        RobotKind::Irb6 => return None,
        RobotKind::Opw => {
            let base = r.model.as_ref().and_then(|m| opw::preset(m.get_ref()));
            let b = base.map(|p| p.opw);
            let pick =
                |v: &Option<Spanned<f64>>, f: fn(&Opw) -> f64| value(v).or(b.as_ref().map(f));
            SixAxisKind::Opw(Opw {
                a1_mm: pick(&r.a1_mm, |o| o.a1_mm)?,
                a2_mm: pick(&r.a2_mm, |o| o.a2_mm)?,
                b_mm: pick(&r.b_mm, |o| o.b_mm)?,
                c1_mm: pick(&r.c1_mm, |o| o.c1_mm)?,
                c2_mm: pick(&r.c2_mm, |o| o.c2_mm)?,
                c3_mm: pick(&r.c3_mm, |o| o.c3_mm)?,
                c4_mm: pick(&r.c4_mm, |o| o.c4_mm)?,
                offsets_rad: match &r.offsets_deg {
                    Some(v) if v.get_ref().len() == 6 => {
                        std::array::from_fn(|i| v.get_ref()[i].to_radians())
                    }
                    _ => b?.offsets_rad,
                },
                signs: match &r.signs {
                    Some(v) if v.get_ref().len() == 6 => std::array::from_fn(|i| {
                        i8::try_from(v.get_ref()[i].clamp(-2, 2)).unwrap_or(0)
                    }),
                    _ => b?.signs,
                },
            })
        }
        RobotKind::Ur => {
            let b = r
                .model
                .as_ref()
                .and_then(|m| ur::preset(m.get_ref()))
                .map(|p| p.ur);
            let pick = |v: &Option<Spanned<f64>>, f: fn(&Ur) -> f64| value(v).or(b.as_ref().map(f));
            SixAxisKind::Ur(Ur {
                d1_mm: pick(&r.d1_mm, |u| u.d1_mm)?,
                a2_mm: pick(&r.a2_mm, |u| u.a2_mm)?,
                a3_mm: pick(&r.a3_mm, |u| u.a3_mm)?,
                d4_mm: pick(&r.d4_mm, |u| u.d4_mm)?,
                d5_mm: pick(&r.d5_mm, |u| u.d5_mm)?,
                d6_mm: pick(&r.d6_mm, |u| u.d6_mm)?,
            })
        }
    };
    let tool = tool.map_or(ArmTool::default(), |t| ArmTool {
        tcp_mm: *t.tcp_mm.get_ref(),
        rpy_deg: t.rpy_deg.as_ref().map_or([0.0; 3], |v| *v.get_ref()),
    });
    let mut arm = SixAxisArm::new(kinematics, limits(r, kind), tool);
    if let Some(v) = &r.link_radii_mm
        && v.get_ref().len() == paths::arm::LINKS
    {
        arm.link_radii_mm = std::array::from_fn(|i| v.get_ref()[i]);
    }
    if let Some(v) = &r.limit_margin_deg {
        arm.margins.limit_rad = v.get_ref().to_radians();
    }
    if let Some(v) = &r.wrist_margin_deg {
        arm.margins.wrist_rad = v.get_ref().to_radians();
    }
    if let Some(v) = &r.joint_step_max_deg {
        arm.margins.step_max_rad = v.get_ref().to_radians();
    }
    Some(arm)
}

impl Job {
    /// The arm's kind (`[cell.robot] kind`, default the IRB 6/2).
    pub fn robot_kind(&self) -> RobotKind {
        self.cell
            .robot
            .as_ref()
            .and_then(|r| r.kind.as_ref())
            .map_or(RobotKind::Irb6, |k| *k.get_ref())
    }

    /// The six-axis arm of a parsed job (`kind = "opw"` or `"ur"`), `None` for the IRB 6/2
    /// (whose arm `cell::tool::arm` builds from the same table).
    pub fn six_axis_arm(&self) -> Option<SixAxisArm> {
        six_axis(self.cell.robot.as_ref()?, self.cell.tool.as_ref())
    }

    /// Where the mandrel's rotation axis is in the robot base frame and who turns it
    /// (`[cell.mandrel]`, default the thesis cell).
    pub fn mandrel_axis(&self) -> MandrelAxis {
        let c = &self.cell;
        let nominal =
            MandrelAxis::thesis(*c.robot_distance_mm.get_ref(), *c.start_height_mm.get_ref());
        let Some(m) = &c.mandrel else {
            return nominal;
        };
        let drive = match m.drive.as_ref().map(|d| *d.get_ref()) {
            Some(MandrelDrive::Robot) => paths::arm::MandrelDrive::Robot,
            _ => paths::arm::MandrelDrive::Indexer,
        };
        let origin = m
            .axis_origin_mm
            .as_ref()
            .map_or(nominal.origin_mm.coords.into(), |o| *o.get_ref());
        let direction = m
            .axis_direction
            .as_ref()
            .map_or([0.0, 0.0, 1.0], |d| *d.get_ref());
        MandrelAxis::new(origin, direction, drive).unwrap_or(MandrelAxis { drive, ..nominal })
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::CYLINDER;
    use super::*;

    /// The job with `tables` inserted before `[mandrel]`.
    fn with(tables: &str) -> String {
        CYLINDER.replacen("[mandrel]", &format!("{tables}\n[mandrel]"), 1)
    }

    /// `line:column:` of the first character of `needle` in `text` (1-based, characters).
    fn at(text: &str, needle: &str) -> String {
        let offset = text.find(needle).expect("needle in text");
        let before = &text[..offset];
        let line = before.matches('\n').count() + 1;
        let column = before
            .rsplit('\n')
            .next()
            .unwrap_or_default()
            .chars()
            .count()
            + 1;
        format!("{line}:{column}:")
    }

    const IRB2600: &str = "[cell.robot]\nkind = \"opw\"\nmodel = \"irb2600-12/1.65\"\n\n\
                           [cell.tool]\ntcp_mm = [0.0, 0.0, 150.0]\nrpy_deg = [0.0, 90.0, 0.0]\n";

    #[test]
    fn a_job_without_the_new_tables_is_the_thesis_cell() {
        let job = Job::parse(CYLINDER).unwrap();
        assert_eq!(job.robot_kind(), RobotKind::Irb6);
        assert!(job.six_axis_arm().is_none());
        assert_eq!(job.mandrel_axis(), MandrelAxis::thesis(800.0, 300.0));
        assert!(job.cell.tool.is_none() && job.cell.mandrel.is_none());
        let written = job.write().unwrap();
        assert!(
            !written.contains("[cell.robot]") && !written.contains("[cell.tool]"),
            "{written}"
        );
        assert_eq!(Job::parse(&written).unwrap(), job);
    }

    #[test]
    fn an_opw_model_is_taken_with_keys_overriding_it() {
        let text = with(&IRB2600.replace(
            "model = \"irb2600-12/1.65\"\n",
            "model = \"irb2600-12/1.65\"\nc4_mm = 100.0\njoint_max_deg = [170.0, 150.0, 70.0, \
             300.0, 115.0, 300.0]\nwrist_margin_deg = 8.0\n",
        ));
        let job = Job::parse(&text).unwrap();
        assert_eq!(job.robot_kind(), RobotKind::Opw);
        let arm = job.six_axis_arm().unwrap();
        let SixAxisKind::Opw(o) = arm.kind else {
            panic!("{arm:?}")
        };
        // ROS-Industrial's IRB 2600-12/1.65 figures with c4 replaced.
        assert_eq!(
            [o.a1_mm, o.a2_mm, o.b_mm, o.c1_mm, o.c2_mm, o.c3_mm, o.c4_mm],
            [150.0, -115.0, 0.0, 445.0, 700.0, 795.0, 100.0]
        );
        assert!((o.offsets_rad[2] + std::f64::consts::FRAC_PI_2).abs() < 1e-15);
        assert!((arm.limits.max_rad[0] - 170f64.to_radians()).abs() < 1e-15);
        assert!((arm.limits.min_rad[1] + 95f64.to_radians()).abs() < 1e-15);
        assert!((arm.margins.wrist_rad - 8f64.to_radians()).abs() < 1e-15);
        assert_eq!(arm.tool.tcp_mm, [0.0, 0.0, 150.0]);
        assert_eq!(arm.tool.rpy_deg, [0.0, 90.0, 0.0]);
        assert_eq!(Job::parse(&job.write().unwrap()).unwrap(), job);
    }

    #[test]
    fn an_opw_arm_by_its_parameters() {
        let text = with(
            "[cell.robot]\nkind = \"opw\"\na1_mm = 260.0\na2_mm = -35.0\nb_mm = 0.0\nc1_mm = 675.0\n\
             c2_mm = 680.0\nc3_mm = 670.0\nc4_mm = 115.0\noffsets_deg = [0.0, -90.0, 0.0, 0.0, 0.0, 0.0]\n\
             signs = [-1, 1, 1, -1, 1, -1]\njoint_min_deg = [-185.0, -155.0, -130.0, -350.0, -130.0, -350.0]\n\
             joint_max_deg = [185.0, 35.0, 154.0, 350.0, 130.0, 350.0]\n\n[cell.tool]\ntcp_mm = [0.0, 0.0, 200.0]\n\n\
             [cell.mandrel]\naxis_origin_mm = [1200.0, 0.0, 700.0]\naxis_direction = [0.0, 1.0, 0.0]\n\
             drive = \"robot\"\n",
        );
        let job = Job::parse(&text).unwrap();
        let arm = job.six_axis_arm().unwrap();
        let SixAxisKind::Opw(o) = arm.kind else {
            panic!("{arm:?}")
        };
        assert_eq!(o.signs, [-1, 1, 1, -1, 1, -1]);
        assert!(arm.limits.speed_rad_s.is_none());
        let axis = job.mandrel_axis();
        assert_eq!(axis.drive, paths::arm::MandrelDrive::Robot);
        assert_eq!(axis.direction.as_slice(), &[0.0, 1.0, 0.0]);
        assert_eq!(axis.origin_mm.coords.as_slice(), &[1200.0, 0.0, 700.0]);
        assert_eq!(Job::parse(&job.write().unwrap()).unwrap(), job);
    }

    #[test]
    fn a_ur_arm_by_model_or_by_its_dh_table() {
        let text = with(
            "[cell.robot]\nkind = \"ur\"\nmodel = \"UR10e\"\nd6_mm = 120.0\n\n[cell.tool]\ntcp_mm = [0.0, 0.0, 90.0]\n",
        );
        let arm = Job::parse(&text).unwrap().six_axis_arm().unwrap();
        let SixAxisKind::Ur(u) = arm.kind else {
            panic!("{arm:?}")
        };
        // UR's table for the UR10e, d6 replaced.
        assert_eq!(
            [u.d1_mm, u.a2_mm, u.a3_mm, u.d4_mm, u.d5_mm, u.d6_mm],
            [180.7, -612.7, -571.55, 174.15, 119.85, 120.0]
        );
        assert!((arm.limits.max_rad[5] - std::f64::consts::TAU).abs() < 1e-12);
        let text = with(
            "[cell.robot]\nkind = \"ur\"\nd1_mm = 162.5\na2_mm = -425.0\na3_mm = -392.2\nd4_mm = 133.3\n\
             d5_mm = 99.7\nd6_mm = 99.6\njoint_speed_deg_s = [100.0, 100.0, 150.0, 150.0, 150.0, 150.0]\n\n\
             [cell.tool]\ntcp_mm = [0.0, 0.0, 90.0]\n",
        );
        let job = Job::parse(&text).unwrap();
        assert!(job.six_axis_arm().unwrap().limits.speed_rad_s.is_some());
        assert_eq!(Job::parse(&job.write().unwrap()).unwrap(), job);
    }

    #[test]
    fn bad_arm_tables_are_located() {
        let cases: Vec<(String, &str, &str)> = vec![
            (
                IRB2600.replace("\"opw\"", "\"scara\""),
                "\"scara\"",
                "unknown variant `scara`",
            ),
            (
                IRB2600.replace("irb2600-12/1.65", "irb9999"),
                "\"irb9999\"",
                "unknown opw model \"irb9999\" (known: \"irb2600-12/1.65\"",
            ),
            (
                "[cell.robot]\nkind = \"opw\"\na1_mm = 1.0\n\n[cell.tool]\ntcp_mm = [0.0, 0.0, 1.0]\n"
                    .to_string(),
                "\"opw\"",
                "missing `a2_mm` for kind = \"opw\"",
            ),
            (
                IRB2600.replace("model = \"irb2600-12/1.65\"\n", "model = \"irb2600-12/1.65\"\nc2_mm = nan\n"),
                "nan",
                "is not a valid arm length",
            ),
            (
                IRB2600.replace("model = \"irb2600-12/1.65\"\n", "model = \"irb2600-12/1.65\"\nsigns = [1, 1, 2, 1, 1, 1]\n"),
                "[1, 1, 2",
                "signs: the sign of axis 3 is 2, not 1 or -1",
            ),
            (
                IRB2600.replace("model = \"irb2600-12/1.65\"\n", "model = \"irb2600-12/1.65\"\njoint_min_deg = [-180.0, 160.0, -180.0, -400.0, -120.0, -400.0]\n"),
                "[-180.0, 160.0",
                "axis 2: joint_min_deg 160 is not below joint_max_deg 155",
            ),
            (
                IRB2600.replace("model = \"irb2600-12/1.65\"\n", "model = \"irb2600-12/1.65\"\noffsets_deg = [0.0, 0.0, 0.0, 0.0, 0.0]\n"),
                "[0.0, 0.0, 0.0, 0.0, 0.0]",
                "offsets_deg needs 6 values",
            ),
            (
                "[cell.tool]\ntcp_mm = [0.0, 0.0, 1.0]\n".to_string(),
                "[0.0, 0.0, 1.0]",
                "[cell.tool] applies to six-axis arms",
            ),
            (
                "[cell.robot]\nkind = \"ur\"\nmodel = \"ur5e\"\na1_mm = 3.25\n\n[cell.tool]\ntcp_mm = [0.0, 0.0, 1.0]\n".to_string(),
                "3.25",
                "`a1_mm` does not apply to kind = \"ur\"",
            ),
            (
                IRB2600.replace("kind = \"opw\"\n", "kind = \"opw\"\nshoulder_height_mm = 301.5\n"),
                "301.5",
                "`shoulder_height_mm` does not apply to kind = \"opw\"",
            ),
            (
                IRB2600.replace("kind = \"opw\"\n", "kind = \"opw\"\nentry_angle_max_deg = 10.5\n"),
                "10.5",
                "`entry_angle_max_deg` does not apply",
            ),
            (
                "[cell.robot]\nc1_mm = 3.75\n".to_string(),
                "3.75",
                "`c1_mm` does not apply to kind = \"irb6-2\" (the default",
            ),
            (
                "[cell.robot]\njoint_speed_deg_s = [1.0, 1.0, 1.0, 1.0, 1.0, 1.0]\n".to_string(),
                "[1.0",
                "joint_speed_deg_s needs 5 values",
            ),
            (
                "[cell.robot]\nkind = \"ur\"\nmodel = \"ur5e\"\n".to_string(),
                "\"ur\"",
                "kind = \"ur\" needs [cell.tool]",
            ),
            (
                "[cell.robot]\nkind = \"ur\"\nmodel = \"ur5e\"\n\n[cell.tool]\ntcp_mm = [0.0, 0.0, 1.0]\n\n\
                 [cell.mandrel]\ndrive = \"robot\"\n"
                    .to_string(),
                "\"robot\"",
                "drive = \"robot\" needs a robot controller with an external axis; kind = \"ur\"",
            ),
            (
                "[cell.mandrel]\ndrive = \"robot\"\n".to_string(),
                "\"robot\"",
                "kind = \"irb6-2\" has none",
            ),
            (
                "[cell.mandrel]\naxis_direction = [0.0, 0.0, 0.0]\n".to_string(),
                "[0.0, 0.0, 0.0]",
                "axis_direction must be a finite, non-zero vector",
            ),
            (
                "[cell.mandrel]\naxis_origin_mm = [1.0, 0.0, inf]\n".to_string(),
                "[1.0, 0.0, inf]",
                "axis_origin_mm must be finite",
            ),
            (
                "[cell.calibration]\naxis_tilt_deg = [0.1, 0.0]\n\n[cell.mandrel]\naxis_direction = [0.0, 0.0, 1.0]\n"
                    .to_string(),
                "[0.0, 0.0, 1.0]",
                "[cell.mandrel] places the axis itself",
            ),
            (
                IRB2600.replace("tcp_mm = [0.0, 0.0, 150.0]", "tcp_mm = [0.0, nan, 150.0]"),
                "[0.0, nan",
                "tcp_mm must be finite",
            ),
            (
                IRB2600.replace("[cell.tool]", "[cell.tool]\ncolour = 1"),
                "colour",
                "unknown field `colour`",
            ),
        ];
        for (tables, needle, expected) in cases {
            let text = with(&tables);
            let e = Job::parse(&text).unwrap_err().to_string();
            let place = at(&text, needle);
            assert!(e.starts_with(&place), "{e} should start with {place}");
            assert!(e.contains(expected), "{e} should contain {expected}");
        }
    }
}
