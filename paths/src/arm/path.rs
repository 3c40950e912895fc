//! Poses for winding with a six-axis arm: the eye's position and the tow direction (the tool's
//! `z`) fix five degrees of freedom; the turn about the tow line is free. For a whole path this
//! chooses, per pose, that turn and the branch so that
//!
//! 1. the path keeps **one configuration** ([`Config`]: no shoulder, elbow or wrist flip),
//! 2. every joint stays [`Margins::limit_rad`] inside its range and the wrist bend
//!    [`Margins::wrist_rad`] away from its singularity,
//! 3. no joint turns more than [`Margins::step_max_rad`] between consecutive poses, and among
//!    the turns that satisfy 1–2 the one is taken that needs the least joint time from the
//!    previous pose (the largest `|Δq_i| / speed_i`; `|Δq_i|` without joint speeds).
//!
//! # Method
//! The tool's `x` axis is carried from pose to pose by the least rotation that takes the previous
//! tow direction onto the next (its part perpendicular to the new direction, normalised); the
//! free turn `Δ` is measured from there. The least joint time is tracked along the path: each
//! pose evaluates the turn the previous pose took (`Δ_g`) and one probe `Δ_g + s`; a probe that
//! lowers the joint time is taken and its step doubles (up to 15°), otherwise `Δ_g` is kept and
//! the next probe goes the other way with half the step (down to 0.25°). Two inverse kinematics
//! per pose; since the best turn moves smoothly along a smooth path, the tracked turn follows it
//! (a test compares every pose with a fine scan of the whole turn). When `Δ_g` is not admissible
//! the other side is probed, and when no probe is, the whole turn is scanned in 5° steps.
//!
//! The first pose's turn is the one (in 10° steps) with the greatest least margin, to the limits
//! and to the wrist singularity; the configurations are tried in the order of that margin at up to five poses
//! spread along the path (a `prefer`red one first), each from up to three starting turns, and
//! the first that keeps the whole path is taken. Where none does, the error names the pose at
//! which the configuration that went furthest stopped, and why.
//!
//! A joint whose range exceeds a turn (ABB axes 4 and 6: ±400°) takes the multiple of 2π that
//! lies in range nearest its previous angle (the first pose: nearest the middle of its range).

use std::f64::consts::{PI, TAU};

use nalgebra::{Matrix3, Point3, Unit, Vector3};

use super::{Config, Joints6, Pose6, SixAxisArm, SixAxisFault};
use crate::Error;

/// Default [`Margins::limit_rad`]: 2° from either end of every joint range (an **assumption**:
/// room for the controller's own soft limits and for the path's interpolation between poses).
pub const DEFAULT_LIMIT_MARGIN_DEG: f64 = 2.0;
/// Default [`Margins::wrist_rad`]: the wrist bend at least 5° from the singularity where axes 4
/// and 6 line up (an **assumption** in line with the ±5° wrist-singularity zones controllers
/// warn about; near it axes 4 and 6 must turn fast for a slow tool motion).
pub const DEFAULT_WRIST_MARGIN_DEG: f64 = 5.0;
/// Default [`Margins::step_max_rad`]: a joint turning more than 45° between consecutive poses is
/// a flip or wrap, not a motion (the same figure as the IRB 6/2's continuity check).
pub const DEFAULT_JOINT_STEP_MAX_DEG: f64 = 45.0;

/// What the pose solver keeps away from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Margins {
    /// Distance kept from either end of every joint range, rad (`limit_margin_deg`).
    pub limit_rad: f64,
    /// Least distance of the wrist bend from its singularity, rad (`wrist_margin_deg`).
    pub wrist_rad: f64,
    /// Largest turn of any joint between consecutive poses, rad (`joint_step_max_deg`).
    pub step_max_rad: f64,
}

impl Default for Margins {
    fn default() -> Self {
        Margins {
            limit_rad: DEFAULT_LIMIT_MARGIN_DEG.to_radians(),
            wrist_rad: DEFAULT_WRIST_MARGIN_DEG.to_radians(),
            step_max_rad: DEFAULT_JOINT_STEP_MAX_DEG.to_radians(),
        }
    }
}

impl Margins {
    /// Checks the margins: limit margin 0–30°, wrist margin 0–45°, joint step 0–180° (above 0).
    pub fn validate(&self) -> Result<(), Error> {
        for (name, v, hi, zero_ok) in [
            ("limit_margin_deg", self.limit_rad, 30.0, true),
            ("wrist_margin_deg", self.wrist_rad, 45.0, true),
            ("joint_step_max_deg", self.step_max_rad, 180.0, false),
        ] {
            let d = v.to_degrees();
            if !(d.is_finite() && d <= hi && (d > 0.0 || (zero_ok && d == 0.0))) {
                return Err(Error::OutOfRange {
                    name,
                    value: d,
                    expected: if zero_ok {
                        "must lie in the documented range (limit 0–30°, wrist 0–45°)"
                    } else {
                        "must lie in (0°, 180°]"
                    },
                });
            }
        }
        Ok(())
    }
}

/// One pose of a path: where the eye is and where the tow goes, base frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EyeTarget {
    /// The payout eye, mm.
    pub eye_mm: Point3<f64>,
    /// The tool `z` axis: from the eye along the free fibre toward the tangent point.
    pub tow: Unit<Vector3<f64>>,
}

/// What a solved path kept.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathReport {
    /// The configuration kept along the whole path.
    pub config: Config,
    /// The least distance of any joint from either end of its range, degrees.
    pub least_limit_margin_deg: f64,
    /// The axis (1–6) where that least distance is.
    pub least_limit_axis: usize,
    /// The least distance of the wrist bend from its singularity, degrees.
    pub least_wrist_margin_deg: f64,
    /// The largest turn of any joint between consecutive poses, degrees.
    pub largest_step_deg: f64,
    /// The axis (1–6) of that turn.
    pub largest_step_axis: usize,
}

/// The joints of every pose of a path and what they kept.
#[derive(Debug, Clone, PartialEq)]
pub struct SolvedPath {
    /// The controller's joint angles per pose, rad.
    pub joints: Vec<Joints6>,
    /// The configuration and margins.
    pub report: PathReport,
}

/// Angular steps of the searches.
const LOCAL_STEP_RAD: f64 = PI / 180.0;
const SCAN_STEPS: usize = 72;
const START_STEPS: usize = 36;
const RANK_STEPS: usize = 12;
const RANK_POSES: usize = 5;
const STARTS: usize = 3;

/// A candidate pose: the joints, the tool `x` axis that gave them, their joint time from the
/// previous pose and the turn from the carried `x` axis.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    q: Joints6,
    x: Vector3<f64>,
    cost: f64,
    turn: Turn,
}

/// A turn as a unit complex number `(cos, sin)`: the tracking search composes, doubles and
/// halves its turns without evaluating a sine.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Turn {
    c: f64,
    s: f64,
}

impl Turn {
    const ZERO: Turn = Turn { c: 1.0, s: 0.0 };

    fn of(rad: f64) -> Turn {
        let (s, c) = rad.sin_cos();
        Turn { c, s }
    }

    fn then(self, o: Turn) -> Turn {
        Turn {
            c: self.c * o.c - self.s * o.s,
            s: self.s * o.c + self.c * o.s,
        }
    }

    fn back(self) -> Turn {
        Turn {
            c: self.c,
            s: -self.s,
        }
    }

    fn double(self) -> Turn {
        self.then(self)
    }

    /// Half the turn (for turns within ±π/2, which the steps are).
    fn half(self) -> Turn {
        let c = (0.5 * (1.0 + self.c)).sqrt();
        Turn {
            c,
            s: self.s / (2.0 * c),
        }
    }
}

/// The cosines of the least (0.25°) and greatest (15°) probe of the tracking search.
const COS_MIN_TRACK_STEP: f64 = 0.999_990_480_720_734_5;
const COS_MAX_TRACK_STEP: f64 = 0.965_925_826_289_068_3;

/// The tracking search's state: the turn taken at the last pose (beyond the carried `x` axis)
/// and the probe, signed in the direction that last helped.
#[derive(Debug, Clone, Copy)]
struct Tracker {
    turn: Turn,
    step: Turn,
}

impl Default for Tracker {
    fn default() -> Self {
        Tracker {
            turn: Turn::ZERO,
            step: Turn::of(LOCAL_STEP_RAD),
        }
    }
}

/// The tool frame with its rotation transposed, as the pose search uses it (`R_flange =
/// R_tool · R_toolᵀ-in-flange` once per candidate without a transpose).
fn inverted_tool(tool: &Pose6) -> Pose6 {
    Pose6 {
        rotation: tool.rotation.transpose(),
        translation_mm: tool.translation_mm,
    }
}

/// A unit vector perpendicular to `d`.
fn perpendicular(d: &Vector3<f64>) -> Vector3<f64> {
    let r = if d.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    (r - d * d.dot(&r)).normalize()
}

/// The part of `x` perpendicular to `d`, normalised (any perpendicular when `x` is along `d`).
fn transported(x: &Vector3<f64>, d: &Vector3<f64>) -> Vector3<f64> {
    let p = x - d * d.dot(x);
    let n = p.norm();
    if n > 1e-9 { p / n } else { perpendicular(d) }
}

impl SixAxisArm {
    /// The flange pose that puts the tool frame at `eye` with axes `x`, `d × x`, `d`; `tool` is
    /// the eye in the flange frame with its rotation **transposed** ([`inverted_tool`]).
    fn flange_for(
        &self,
        eye: &Point3<f64>,
        x: &Vector3<f64>,
        d: &Vector3<f64>,
        tool: &Pose6,
    ) -> Pose6 {
        let y = d.cross(x);
        let r_tool = Matrix3::from_columns(&[*x, y, *d]);
        let rotation = r_tool * tool.rotation;
        Pose6 {
            translation_mm: eye.coords - rotation * tool.translation_mm,
            rotation,
        }
    }

    /// The joints of `config` for the tool frame `(eye, x, d)`, each shifted by whole turns into
    /// its range nearest `reference` (or the range's middle), with the margins checked.
    fn admissible(
        &self,
        eye: &Point3<f64>,
        x: &Vector3<f64>,
        d: &Vector3<f64>,
        tool: &Pose6,
        config: Config,
        reference: Option<&Joints6>,
    ) -> Result<Joints6, SixAxisFault> {
        let flange = self.flange_for(eye, x, d, tool);
        let raw = self.kind.inverse_branch(&flange, config)?;
        let m = &self.margins;
        let mut q = raw;
        for i in 0..6 {
            let lo = self.limits.min_rad[i] + m.limit_rad;
            let hi = self.limits.max_rad[i] - m.limit_rad;
            let target = match reference {
                Some(r) => r[i],
                None => 0.5 * (self.limits.min_rad[i] + self.limits.max_rad[i]),
            };
            // The whole-turn shift of the angle nearest the target, then the in-range one of
            // it and its neighbours nearest the target.
            let mut near = raw[i];
            let gap = target - near;
            if !(-PI..=PI).contains(&gap) {
                near += (gap / TAU).round() * TAU;
            }
            let best = if near >= lo && near <= hi {
                Some(near)
            } else {
                let (below, above) = (near - TAU, near + TAU);
                match (below >= lo && below <= hi, above >= lo && above <= hi) {
                    (true, true) => Some(if target - below < above - target {
                        below
                    } else {
                        above
                    }),
                    (true, false) => Some(below),
                    (false, true) => Some(above),
                    (false, false) => None,
                }
            };
            match best {
                Some(v) => q[i] = v,
                None => {
                    return Err(SixAxisFault::JointLimit {
                        axis: i + 1,
                        value_deg: near.to_degrees(),
                        min_deg: self.limits.min_rad[i].to_degrees(),
                        max_deg: self.limits.max_rad[i].to_degrees(),
                        margin_deg: m.limit_rad.to_degrees(),
                    });
                }
            }
        }
        let wrist = self.kind.wrist_distance_rad(&q);
        if wrist < m.wrist_rad {
            return Err(SixAxisFault::WristSingular {
                distance_deg: wrist.to_degrees(),
                margin_deg: m.wrist_rad.to_degrees(),
            });
        }
        if let Some(r) = reference {
            for i in 0..6 {
                let change = (q[i] - r[i]).abs();
                if change > m.step_max_rad {
                    return Err(SixAxisFault::JointStep {
                        axis: i + 1,
                        change_deg: change.to_degrees(),
                        limit_deg: m.step_max_rad.to_degrees(),
                    });
                }
            }
        }
        Ok(q)
    }

    /// The least distance of the joints from their range ends (rad) and its axis index.
    fn limit_margin(&self, q: &Joints6) -> (f64, usize) {
        let mut least = (f64::INFINITY, 0);
        for (i, ((v, lo), hi)) in q
            .iter()
            .zip(&self.limits.min_rad)
            .zip(&self.limits.max_rad)
            .enumerate()
        {
            let d = (v - lo).min(hi - v);
            if d < least.0 {
                least = (d, i);
            }
        }
        least
    }

    /// The joint time from `a` to `b` in units of the slowest joint's share (rad/(rad/s)), or
    /// the largest joint change when no speeds are known.
    fn step_cost(&self, a: &Joints6, b: &Joints6) -> f64 {
        let mut worst = 0.0f64;
        match &self.limits.speed_rad_s {
            Some(s) => {
                for i in 0..6 {
                    worst = worst.max((b[i] - a[i]).abs() / s[i]);
                }
            }
            None => {
                for i in 0..6 {
                    worst = worst.max((b[i] - a[i]).abs());
                }
            }
        }
        worst
    }

    /// The greater of the least margins (to the limits and to the wrist singularity) of the
    /// joints, rad: how comfortably the arm holds a pose.
    fn comfort(&self, q: &Joints6) -> f64 {
        self.limit_margin(q).0.min(self.kind.wrist_distance_rad(q))
    }

    /// Up to `STARTS` starting tool `x` axes at the first pose, best comfort first, at least 60°
    /// apart, with `config`.
    fn starts(&self, t: &EyeTarget, tool: &Pose6, config: Config) -> Vec<(f64, Vector3<f64>)> {
        let d = t.tow.into_inner();
        let e1 = perpendicular(&d);
        let e2 = d.cross(&e1);
        let mut found: Vec<(f64, f64, Vector3<f64>)> = (0..START_STEPS)
            .filter_map(|k| {
                let g = k as f64 * TAU / START_STEPS as f64;
                let x = e1 * g.cos() + e2 * g.sin();
                self.admissible(&t.eye_mm, &x, &d, tool, config, None)
                    .ok()
                    .map(|q| (self.comfort(&q), g, x))
            })
            .collect();
        found.sort_by(|a, b| b.0.total_cmp(&a.0));
        let mut chosen: Vec<(f64, f64, Vector3<f64>)> = Vec::new();
        for f in found {
            let apart = chosen.iter().all(|c| {
                let diff = (f.1 - c.1).rem_euclid(TAU);
                diff.min(TAU - diff) >= PI / 3.0 - 1e-9
            });
            if apart {
                chosen.push(f);
                if chosen.len() == STARTS {
                    break;
                }
            }
        }
        chosen.into_iter().map(|(c, _, x)| (c, x)).collect()
    }

    /// The configurations in the order to try: `prefer` first, then by their least (over up to
    /// five poses along the path) best comfort (over twelve turns).
    fn ranked_configs(
        &self,
        targets: &[EyeTarget],
        tool: &Pose6,
        prefer: Option<Config>,
    ) -> Vec<Config> {
        let n = targets.len();
        let picks: Vec<usize> = if n <= RANK_POSES {
            (0..n).collect()
        } else {
            (0..RANK_POSES)
                .map(|k| k * (n - 1) / (RANK_POSES - 1))
                .collect()
        };
        let mut scored: Vec<(f64, Config)> = Config::ALL
            .iter()
            .map(|&c| {
                let score = picks
                    .iter()
                    .map(|&i| {
                        let t = &targets[i];
                        let d = t.tow.into_inner();
                        let e1 = perpendicular(&d);
                        let e2 = d.cross(&e1);
                        (0..RANK_STEPS)
                            .filter_map(|k| {
                                let g = k as f64 * TAU / RANK_STEPS as f64;
                                let x = e1 * g.cos() + e2 * g.sin();
                                self.admissible(&t.eye_mm, &x, &d, tool, c, None)
                                    .ok()
                                    .map(|q| self.comfort(&q))
                            })
                            .fold(f64::NEG_INFINITY, f64::max)
                    })
                    .fold(f64::INFINITY, f64::min);
                (score, c)
            })
            .collect();
        scored.sort_by(|a, b| b.0.total_cmp(&a.0));
        let mut order: Vec<Config> = prefer.into_iter().collect();
        order.extend(
            scored
                .into_iter()
                .map(|(_, c)| c)
                .filter(|c| Some(*c) != prefer),
        );
        order
    }

    /// The next pose after `prev` (joints) with tool `x` axis `x_prev`: the admissible turn
    /// that needs the least joint time, tracked from pose to pose (module documentation).
    fn next_pose(
        &self,
        t: &EyeTarget,
        tool: &Pose6,
        config: Config,
        prev: &Joints6,
        x_prev: &Vector3<f64>,
        track: &mut Tracker,
    ) -> Result<Candidate, SixAxisFault> {
        let d = t.tow.into_inner();
        let x0 = transported(x_prev, &d);
        let y0 = d.cross(&x0);
        let eval = |turn: Turn| -> Result<Candidate, SixAxisFault> {
            let x = x0 * turn.c + y0 * turn.s;
            let q = self.admissible(&t.eye_mm, &x, &d, tool, config, Some(prev))?;
            Ok(Candidate {
                q,
                x,
                cost: self.step_cost(prev, &q),
                turn,
            })
        };
        let better =
            |a: &Result<Candidate, SixAxisFault>, b: &Result<Candidate, SixAxisFault>| match (a, b)
            {
                (Ok(a), Ok(b)) => a.cost < b.cost,
                (Ok(_), Err(_)) => true,
                _ => false,
            };
        let guess = eval(track.turn);
        let ahead = eval(track.turn.then(track.step));
        let chosen = if better(&ahead, &guess) {
            let doubled = track.step.double();
            if doubled.c >= COS_MAX_TRACK_STEP {
                track.step = doubled;
            }
            ahead
        } else if guess.is_ok() {
            // The probe overshot or went the wrong way: keep the guess, probe the other way
            // next time, with half the step.
            let halved = track.step.half();
            track.step = if halved.c <= COS_MIN_TRACK_STEP {
                halved.back()
            } else {
                track.step.back()
            };
            guess
        } else {
            let behind = eval(track.turn.then(track.step.back()));
            if behind.is_ok() {
                track.step = track.step.back();
            }
            behind
        };
        let fault = match chosen {
            Ok(c) => {
                track.turn = c.turn;
                return Ok(c);
            }
            Err(f) => f,
        };
        let mut scanned: Option<Candidate> = None;
        for k in 0..SCAN_STEPS {
            if let Ok(c) = eval(Turn::of(k as f64 * TAU / SCAN_STEPS as f64))
                && scanned.is_none_or(|b| c.cost < b.cost)
            {
                scanned = Some(c);
            }
        }
        match scanned {
            Some(c) => {
                *track = Tracker::default();
                Ok(c)
            }
            None => Err(fault),
        }
    }

    /// Solves a whole path (module documentation): one configuration, joints within the margins
    /// and continuous. `prefer` is tried first (the configuration of the path before, say).
    /// Errors: an empty path, a non-finite target, or [`Error::SixAxis`] naming the pose (0 =
    /// the first target) where no configuration could go on.
    pub fn solve_path(
        &self,
        targets: &[EyeTarget],
        prefer: Option<Config>,
    ) -> Result<SolvedPath, Error> {
        if targets.is_empty() {
            return Err(Error::TooFewPoints {
                what: "six-axis path",
                count: 0,
                needed: 1,
            });
        }
        for (i, t) in targets.iter().enumerate() {
            if !(t.eye_mm.coords.iter().all(|v| v.is_finite())
                && t.tow.iter().all(|v| v.is_finite()))
            {
                return Err(Error::NonFinitePoint { index: i });
            }
        }
        let tool = inverted_tool(&self.tool.frame());
        let mut furthest: Option<(usize, Config, SixAxisFault)> = None;
        for config in self.ranked_configs(targets, &tool, prefer) {
            let starts = self.starts(&targets[0], &tool, config);
            if starts.is_empty() {
                let d = targets[0].tow.into_inner();
                if let (Err(fault), None) = (
                    self.admissible(
                        &targets[0].eye_mm,
                        &perpendicular(&d),
                        &d,
                        &tool,
                        config,
                        None,
                    ),
                    &furthest,
                ) {
                    furthest = Some((0, config, fault));
                }
                continue;
            }
            for (_, x_start) in starts {
                match self.follow(targets, &tool, config, &x_start) {
                    Ok(joints) => {
                        let report = self.report(&joints, config);
                        return Ok(SolvedPath { joints, report });
                    }
                    Err((at, fault)) => {
                        if furthest.as_ref().is_none_or(|(f, _, _)| at > *f) {
                            furthest = Some((at, config, fault));
                        }
                    }
                }
            }
        }
        let Some((segment, config, reason)) = furthest else {
            // Every configuration is ranked and tried, so one of them stopped somewhere.
            return Err(Error::TooFewPoints {
                what: "six-axis path",
                count: targets.len(),
                needed: 1,
            });
        };
        Err(Error::SixAxis {
            segment: Some(segment),
            fault: SixAxisFault::NoConfiguration {
                config,
                reason: Box::new(reason),
            },
        })
    }

    /// The whole path in one configuration from a starting tool `x` axis, or the pose index
    /// where it stopped and why.
    fn follow(
        &self,
        targets: &[EyeTarget],
        tool: &Pose6,
        config: Config,
        x_start: &Vector3<f64>,
    ) -> Result<Vec<Joints6>, (usize, SixAxisFault)> {
        let first = &targets[0];
        let q0 = self
            .admissible(
                &first.eye_mm,
                x_start,
                &first.tow.into_inner(),
                tool,
                config,
                None,
            )
            .map_err(|f| (0, f))?;
        let mut joints = Vec::with_capacity(targets.len());
        joints.push(q0);
        let mut x = *x_start;
        let mut track = Tracker::default();
        for (i, t) in targets.iter().enumerate().skip(1) {
            let prev = joints[i - 1];
            let c = self
                .next_pose(t, tool, config, &prev, &x, &mut track)
                .map_err(|f| (i, f))?;
            joints.push(c.q);
            x = c.x;
        }
        Ok(joints)
    }

    fn report(&self, joints: &[Joints6], config: Config) -> PathReport {
        let mut r = PathReport {
            config,
            least_limit_margin_deg: f64::INFINITY,
            least_limit_axis: 1,
            least_wrist_margin_deg: f64::INFINITY,
            largest_step_deg: 0.0,
            largest_step_axis: 1,
        };
        for (k, q) in joints.iter().enumerate() {
            let (m, axis) = self.limit_margin(q);
            if m.to_degrees() < r.least_limit_margin_deg {
                r.least_limit_margin_deg = m.to_degrees();
                r.least_limit_axis = axis + 1;
            }
            r.least_wrist_margin_deg = r
                .least_wrist_margin_deg
                .min(self.kind.wrist_distance_rad(q).to_degrees());
            if k > 0 {
                for i in 0..6 {
                    let s = (q[i] - joints[k - 1][i]).abs().to_degrees();
                    if s > r.largest_step_deg {
                        r.largest_step_deg = s;
                        r.largest_step_axis = i + 1;
                    }
                }
            }
        }
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::arm::Tool;

    fn irb2600() -> SixAxisArm {
        SixAxisArm::opw_preset("irb2600-12/1.65", Tool::default()).unwrap()
    }

    fn deg(q: [f64; 6]) -> Joints6 {
        q.map(f64::to_radians)
    }

    /// [`SixAxisArm::admissible`] at the flange pose of the joints `q` (the eye at the flange,
    /// the tool frame the flange's), in `q`'s configuration.
    fn at(q_deg: [f64; 6], reference_deg: Option<[f64; 6]>) -> Result<[f64; 6], SixAxisFault> {
        let arm = irb2600();
        let q = deg(q_deg);
        let f = arm.kind.forward(&q);
        let tool = inverted_tool(&arm.tool.frame());
        let x = f.rotation.column(0).into_owned();
        let d = f.rotation.column(2).into_owned();
        let reference = reference_deg.map(deg);
        arm.admissible(
            &Point3::from(f.translation_mm),
            &x,
            &d,
            &tool,
            arm.kind.config_of(&q),
            reference.as_ref(),
        )
        .map(|q| q.map(f64::to_degrees))
    }

    fn close(a: [f64; 6], b: [f64; 6]) -> bool {
        a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-6)
    }

    const BASE: [f64; 6] = [20.0, 30.0, -20.0, 40.0, 50.0, 60.0];

    /// The IRB 2600's ranges (`docs/arms.md`): axis 1 ±180°, axis 2 −95..155°, axis 3
    /// −180..75°, axes 4 and 6 ±400°, axis 5 ±120°; the default margins 2° from the ends, 5°
    /// from the wrist singularity, 45° a step.
    #[test]
    fn admissible_joints_are_the_pose_s_own_within_the_margins() {
        assert!(close(at(BASE, Some(BASE)).unwrap(), BASE));
        // Without a reference, the whole-turn shift nearest each range's middle.
        assert!(close(at(BASE, None).unwrap(), BASE));
    }

    /// Axes 4 and 6 turn more than a whole turn: the angle taken is the whole-turn shift of
    /// the inverse kinematics' one nearest the previous pose's, when it lies in range.
    #[test]
    fn a_wrist_axis_past_a_whole_turn_follows_the_previous_pose() {
        let q = [20.0, 30.0, -20.0, 10.0, 50.0, 60.0];
        let reference = [20.0, 30.0, -20.0, 367.0, 50.0, -298.0];
        let got = at(q, Some(reference)).unwrap();
        assert!(
            close(got, [20.0, 30.0, -20.0, 370.0, 50.0, -300.0]),
            "{got:?}"
        );
        // From a reference two turns away the nearest shift is beyond the range (730° > 398°):
        // the one in range is taken, and then the step from the reference is too large.
        let far = [20.0, 30.0, -20.0, 725.0, 50.0, 60.0];
        match at(q, Some(far)) {
            Err(SixAxisFault::JointStep {
                axis: 4,
                change_deg,
                ..
            }) => assert!((change_deg - 355.0).abs() < 1e-6, "{change_deg}"),
            other => panic!("{other:?}"),
        }
        // The same below the range (−710° < −398°: the shift up by a turn, −350°, is taken).
        let far_below = [20.0, 30.0, -20.0, -725.0, 50.0, 60.0];
        match at(q, Some(far_below)) {
            Err(SixAxisFault::JointStep {
                axis: 4,
                change_deg,
                ..
            }) => assert!((change_deg - 375.0).abs() < 1e-6, "{change_deg}"),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_joint_within_the_margin_of_its_end_is_refused_with_its_figures() {
        match at([179.0, 30.0, -20.0, 40.0, 50.0, 60.0], None) {
            Err(SixAxisFault::JointLimit {
                axis: 1,
                value_deg,
                min_deg,
                max_deg,
                margin_deg,
            }) => {
                assert!((value_deg - 179.0).abs() < 1e-6, "{value_deg}");
                assert_eq!((min_deg, max_deg), (-180.0, 180.0));
                assert!((margin_deg - 2.0).abs() < 1e-12);
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(
            at([20.0, 154.0, -20.0, 40.0, 50.0, 60.0], None),
            Err(SixAxisFault::JointLimit { axis: 2, .. })
        ));
        assert!(matches!(
            at([20.0, -94.0, -20.0, 40.0, 50.0, 60.0], None),
            Err(SixAxisFault::JointLimit { axis: 2, .. })
        ));
        // 3° inside the margin's edge is taken.
        assert!(at([20.0, 150.0, -20.0, 40.0, 50.0, 60.0], None).is_ok());
        assert!(at([20.0, -90.0, 70.0, 40.0, 50.0, 60.0], None).is_ok());
        assert!(matches!(
            at([20.0, -90.0, 74.0, 40.0, 50.0, 60.0], None),
            Err(SixAxisFault::JointLimit { axis: 3, .. })
        ));
    }

    #[test]
    fn a_wrist_bend_near_its_singularity_is_refused() {
        match at([20.0, 30.0, -20.0, 40.0, 3.0, 60.0], None) {
            Err(SixAxisFault::WristSingular {
                distance_deg,
                margin_deg,
            }) => {
                assert!((distance_deg - 3.0).abs() < 1e-6, "{distance_deg}");
                assert!((margin_deg - 5.0).abs() < 1e-12);
            }
            other => panic!("{other:?}"),
        }
        assert!(at([20.0, 30.0, -20.0, 40.0, 6.0, 60.0], None).is_ok());
    }

    #[test]
    fn a_joint_step_over_the_limit_is_refused_and_one_under_it_taken() {
        let mut reference = BASE;
        reference[0] = BASE[0] - 46.0;
        match at(BASE, Some(reference)) {
            Err(SixAxisFault::JointStep {
                axis: 1,
                change_deg,
                limit_deg,
            }) => {
                assert!((change_deg - 46.0).abs() < 1e-6, "{change_deg}");
                assert!((limit_deg - 45.0).abs() < 1e-12);
            }
            other => panic!("{other:?}"),
        }
        reference[0] = BASE[0] - 44.0;
        assert!(close(at(BASE, Some(reference)).unwrap(), BASE));
        let mut wrist = BASE;
        wrist[5] = BASE[5] + 46.0;
        assert!(matches!(
            at(BASE, Some(wrist)),
            Err(SixAxisFault::JointStep { axis: 6, .. })
        ));
    }

    #[test]
    fn margins_are_checked_against_their_documented_ranges() {
        let ok = Margins::default();
        ok.validate().unwrap();
        let with = |limit: f64, wrist: f64, step: f64| Margins {
            limit_rad: limit.to_radians(),
            wrist_rad: wrist.to_radians(),
            step_max_rad: step.to_radians(),
        };
        // The ends of each range are taken; zero only where it is allowed.
        with(0.0, 0.0, 180.0).validate().unwrap();
        with(30.0, 45.0, 0.5).validate().unwrap();
        for bad in [
            with(-1.0, 5.0, 45.0),
            with(31.0, 5.0, 45.0),
            with(f64::NAN, 5.0, 45.0),
            with(2.0, -1.0, 45.0),
            with(2.0, 46.0, 45.0),
            with(2.0, 5.0, 0.0),
            with(2.0, 5.0, 181.0),
            with(2.0, 5.0, f64::INFINITY),
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }
}
