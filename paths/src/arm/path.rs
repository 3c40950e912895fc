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
//! free turn `Δ` is measured from there. The least joint time is tracked along the path with
//! about one inverse kinematics per pose:
//!
//! - Each pose first evaluates the turn the previous pose took, carried on by the trend of the
//!   recent corrections (the guess).
//! - Near the guess the joints are linear in a correction `δ` of the turn, `Δq_i + r_i·δ`, with
//!   the rates `r_i = ∂q_i/∂Δ` measured from the last two poses evaluated at one target. The
//!   joint time `max_i |Δq_i + r_i·δ| / speed_i` is then convex and piecewise linear in `δ`,
//!   and its least is found in closed form (Helly's theorem on the line: the largest of the
//!   pairs' least values, [`least_max_abs`]).
//! - Only where that least is worth it (0.5 % of the guess's joint time, [`WORTHWHILE_GAIN`]),
//!   or the rates are 32 poses old, is the correction evaluated (a second inverse kinematics);
//!   the better of the two poses is taken and the rates are measured afresh from them.
//!
//! A test compares every pose of three paths with a brute-force scan of the whole turn: over a
//! path the joint time is within 1 % of the scan's. When the guess is not admissible, a degree
//! to either side is tried, and when neither is, the whole turn is scanned in 5° steps.
//!
//! The first pose's turn is the one (in 10° steps) with the greatest least margin, to the limits
//! and to the wrist singularity; the configurations are tried in the order of that margin at up to five poses
//! spread along the path (a `prefer`red one first), each from up to three starting turns, and
//! the first that keeps the whole path is taken. Where none does, the error names the pose at
//! which the configuration that went furthest (the first tried, on a tie) stopped, and why.
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
    /// The axis (1–6) where that least distance is (the first pose's, the lowest, on a tie).
    pub least_limit_axis: usize,
    /// The least distance of the wrist bend from its singularity, degrees.
    pub least_wrist_margin_deg: f64,
    /// The largest turn of any joint between consecutive poses, degrees.
    pub largest_step_deg: f64,
    /// The axis (1–6) of that turn (the first pose's, the lowest, on a tie).
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

/// Angular steps of the searches: the side steps and first probe of the tracking search, the
/// fallback scan, the first pose's starting turns and the configuration ranking.
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
}

/// The largest correction of the turn the tracking search makes at one pose, rad (15°).
const MAX_TRACK_STEP_RAD: f64 = PI / 12.0;
/// The largest correction that is taken as a trend and carried on to the next pose (0.5°).
const MAX_DRIFT_RAD: f64 = PI / 360.0;
/// The least probe that measures the joints' rates with the turn, rad (0.25°).
const MIN_TRACK_PROBE_RAD: f64 = PI / 720.0;
/// The least correction evaluated as such (smaller ones probe [`MIN_TRACK_PROBE_RAD`] instead:
/// the rates are measured from the difference of the two poses).
const LEAST_CORRECTION_RAD: f64 = 1e-9;
/// Poses after which the joints' rates with the turn are measured again even when the linear
/// model sees nothing to gain.
const SLOPE_REFRESH_POSES: u32 = 32;
/// The share of the joint time below which a correction the linear model predicts is not worth
/// a second inverse kinematics (0.5 %).
const WORTHWHILE_GAIN: f64 = 0.005;

/// The tracking search's state.
#[derive(Debug, Clone, Copy)]
struct Tracker {
    /// The turn taken at the last pose, beyond the carried `x` axis.
    turn: Turn,
    /// The pair of joints that last showed no correction worth it ([`least_max_abs_reaches`]).
    binding: (usize, usize),
    /// The trend of the corrections: their sum, each spread over the poses since the one
    /// before, rad; and as a turn.
    drift_rad: f64,
    drift: Turn,
    /// The joints' rates with the turn `∂q/∂Δ` (rad/rad) as last measured, and how many poses
    /// ago.
    slope: Option<Joints6>,
    age: u32,
    /// What makes joint changes joint time: `1/speed_i` (s/rad), or 1 without speeds.
    weights: Joints6,
}

impl Tracker {
    fn new(weights: Joints6) -> Self {
        Tracker {
            turn: Turn::ZERO,
            binding: (0, 1),
            drift_rad: 0.0,
            drift: Turn::ZERO,
            slope: None,
            age: 0,
            weights,
        }
    }
}

/// The joint time from `a` to `b`: the largest `|b_i − a_i|·weight_i` (`weight_i = 1/speed_i`,
/// s; or 1, the largest joint change in rad, when no speeds are known).
fn joint_time(weights: &Joints6, a: &Joints6, b: &Joints6) -> f64 {
    let mut worst = 0.0f64;
    for i in 0..6 {
        worst = worst.max((b[i] - a[i]).abs() * weights[i]);
    }
    worst
}

/// Whether the least over all `δ` of `f(δ) = max_j |a_j + b_j·δ|` is at least `t`: some pair's
/// own least is ([`least_max_abs`]). The pair that showed it last time is tried first (it
/// changes rarely along a path) and kept in `hint`.
fn least_max_abs_reaches(a: &Joints6, b: &Joints6, t: f64, hint: &mut (usize, usize)) -> bool {
    let reaches = |j: usize, k: usize| {
        let rates = b[j].abs() + b[k].abs();
        if rates > 0.0 {
            (a[j] * b[k] - a[k] * b[j]).abs() >= t * rates
        } else {
            // Two flat terms: their least is the larger.
            a[j].abs().max(a[k].abs()) >= t
        }
    };
    if reaches(hint.0, hint.1) {
        return true;
    }
    for j in 0..a.len() {
        for k in j + 1..a.len() {
            if reaches(j, k) {
                *hint = (j, k);
                return true;
            }
        }
    }
    false
}

/// The `δ` in `[−limit, limit]` that minimises `f(δ) = max_j |a_j + b_j·δ|`, and `f` there.
///
/// The sets `{δ : |a_j + b_j·δ| ≤ t}` are intervals, and intervals on a line share a point when
/// every two of them do (Helly's theorem in one dimension), so the least of `f` is the largest
/// over pairs of the pair's own least, `|a_j·b_k − a_k·b_j| / (|b_j| + |b_k|)`; the `δ` taken is
/// the one nearest zero where every term is within it. Beyond `limit` the least (f being
/// convex) is at the limit. With every `b_j` zero, `f` is flat and `δ = 0`.
fn least_max_abs(a: &Joints6, b: &Joints6, limit: f64) -> (f64, f64) {
    // The binding pair, compared as fractions num/den without dividing.
    let (mut num, mut den, mut pair) = (0.0f64, 1.0f64, None);
    for j in 0..a.len() {
        for k in j + 1..a.len() {
            let n = (a[j] * b[k] - a[k] * b[j]).abs();
            let m = b[j].abs() + b[k].abs();
            if m > 0.0 && n * den > num * m {
                (num, den, pair) = (n, m, Some((j, k)));
            }
        }
    }
    // The least, and the correction nearest zero that reaches it: the common part of the
    // intervals where each moving term stays within it (one point unless terms are flat;
    // rounding may leave the ends a hair apart).
    let least = if pair.is_some() { num / den } else { 0.0 };
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    for (aj, bj) in a.iter().zip(b) {
        if *bj != 0.0 {
            let (e1, e2) = ((-least - aj) / bj, (least - aj) / bj);
            lo = lo.max(e1.min(e2));
            hi = hi.min(e1.max(e2));
        }
    }
    let d = if lo <= hi {
        0.0f64.clamp(lo, hi)
    } else if lo.is_finite() && hi.is_finite() {
        0.5 * (lo + hi)
    } else {
        0.0
    }
    .clamp(-limit, limit);
    let top = a
        .iter()
        .zip(b)
        .fold(0.0f64, |m, (aj, bj)| m.max((aj + bj * d).abs()));
    (d, top)
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

    /// The least distance of the joints from their range ends (rad) and its (lowest) axis index.
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

    /// The admissible `guess` (the turn the last pose took) or a better turn near it: the joint
    /// time as a function of the correction `δ` of the turn is modelled as
    /// `max_i |Δq_i + ∂q_i/∂Δ·δ| / speed_i` with the rates last measured; where the model's least
    /// is worth it ([`WORTHWHILE_GAIN`]), or the rates are [`SLOPE_REFRESH_POSES`] old, the
    /// correction is evaluated (a second inverse kinematics), the rates re-measured from the two
    /// poses, and the better of the two taken.
    fn refine(
        &self,
        guess: Candidate,
        prev: &Joints6,
        track: &mut Tracker,
        eval: impl Fn(Turn) -> Result<Candidate, SixAxisFault>,
    ) -> Candidate {
        let w = &track.weights;
        let probe = match track.slope {
            Some(rate) => {
                let a: Joints6 = std::array::from_fn(|i| (guess.q[i] - prev[i]) * w[i]);
                let b: Joints6 = std::array::from_fn(|i| rate[i] * w[i]);
                let worth = guess.cost * (1.0 - WORTHWHILE_GAIN);
                if least_max_abs_reaches(&a, &b, worth, &mut track.binding) {
                    (track.age >= SLOPE_REFRESH_POSES).then(|| {
                        let (delta, _) = least_max_abs(&a, &b, MAX_TRACK_STEP_RAD);
                        if delta.abs() >= MIN_TRACK_PROBE_RAD {
                            delta
                        } else {
                            MIN_TRACK_PROBE_RAD
                        }
                    })
                } else {
                    let (delta, _) = least_max_abs(&a, &b, MAX_TRACK_STEP_RAD);
                    Some(if delta.abs() >= LEAST_CORRECTION_RAD {
                        delta
                    } else {
                        MIN_TRACK_PROBE_RAD
                    })
                }
            }
            None => Some(LOCAL_STEP_RAD),
        };
        let Some(delta) = probe else {
            track.age += 1;
            track.turn = guess.turn;
            return guess;
        };
        let chosen = match eval(guess.turn.then(Turn::of(delta))) {
            Ok(p) => {
                track.slope = Some(std::array::from_fn(|i| (p.q[i] - guess.q[i]) / delta));
                let since = f64::from(track.age + 1);
                track.age = 0;
                if p.cost < guess.cost {
                    track.drift_rad = if delta.abs() < MAX_DRIFT_RAD {
                        track.drift_rad + delta / since
                    } else {
                        0.0
                    };
                    track.drift = Turn::of(track.drift_rad);
                    p
                } else {
                    guess
                }
            }
            Err(_) => {
                track.age += 1;
                guess
            }
        };
        track.turn = chosen.turn;
        chosen
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
        let weights = track.weights;
        let eval = |turn: Turn| -> Result<Candidate, SixAxisFault> {
            let x = x0 * turn.c + y0 * turn.s;
            let q = self.admissible(&t.eye_mm, &x, &d, tool, config, Some(prev))?;
            Ok(Candidate {
                q,
                x,
                cost: joint_time(&weights, prev, &q),
                turn,
            })
        };
        let predicted = track.turn.then(track.drift);
        let chosen = match eval(predicted) {
            Ok(guess) => Ok(self.refine(guess, prev, track, eval)),
            Err(fault) => {
                // The turn the last pose took is not admissible here: a degree to either side,
                // and the rates are measured afresh.
                track.slope = None;
                match eval(predicted.then(Turn::of(LOCAL_STEP_RAD))) {
                    Ok(c) => Ok(c),
                    Err(_) => eval(predicted.then(Turn::of(-LOCAL_STEP_RAD))).map_err(|_| fault),
                }
            }
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
                *track = Tracker::new(track.weights);
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
        let weights = match &self.limits.speed_rad_s {
            Some(speed) => speed.map(|v| 1.0 / v),
            None => [1.0; 6],
        };
        let mut track = Tracker::new(weights);
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

    /// The least distance to a range end, by hand from the IRB 2600's ranges (docs/arms.md:
    /// ±180, −95..155, −180..75, ±400, ±120, ±400): at zero, axis 3's 75° (index 2); with axis 1
    /// at 170°, its 10° (index 0); with axis 2 at −90°, its 5°; with axis 5 at 118°, its 2°.
    #[test]
    fn the_limit_margin_is_the_nearest_range_end_and_its_axis() {
        let arm = irb2600();
        for (q_deg, least_deg, axis) in [
            ([0.0; 6], 75.0, 2),
            ([170.0, 0.0, 0.0, 0.0, 0.0, 0.0], 10.0, 0),
            ([0.0, -90.0, 0.0, 0.0, 0.0, 0.0], 5.0, 1),
            ([0.0, 0.0, 0.0, 0.0, 118.0, 0.0], 2.0, 4),
        ] {
            let (m, i) = arm.limit_margin(&deg(q_deg));
            assert!(
                (m.to_degrees() - least_deg).abs() < 1e-9,
                "{q_deg:?}: {}",
                m.to_degrees()
            );
            assert_eq!(i, axis, "{q_deg:?}");
        }
        // Axes 1 and 2 both at their lower ends: a tie at zero, the lower axis named.
        let mut q = [0.0; 6];
        q[0] = arm.limits.min_rad[0];
        q[1] = arm.limits.min_rad[1];
        assert_eq!(arm.limit_margin(&q), (0.0, 0));
    }

    /// How comfortably a pose is held: the lesser of the least range-end distance and the wrist
    /// bend's distance from its singularities (the IRB 2600's bend is axis 5, singular at 0°
    /// and ±180°). `BASE`'s range-end distances are 160, 125, 95, 360, 70, 340° and its bend
    /// 50°: 50°. With axis 5 at 110°, 10° from its end at 120° and 70° from 180°: 10°.
    #[test]
    fn comfort_is_the_lesser_of_the_limit_and_wrist_margins() {
        let arm = irb2600();
        let mut q = BASE;
        assert!((arm.comfort(&deg(q)).to_degrees() - 50.0).abs() < 1e-9);
        q[4] = 110.0;
        assert!((arm.comfort(&deg(q)).to_degrees() - 10.0).abs() < 1e-9);
    }

    /// The joint time is the slowest joint's, `|Δq_i|·weight_i` at its largest: by hand, changes
    /// 1.0, 0.3, 0.2, 0.4, 0 and 2.0 weighted 0.5, 2, 1, 1, 1 and 0.25 take 0.5, 0.6, 0.2, 0.4,
    /// 0 and 0.5: axis 2's 0.6.
    #[test]
    fn the_joint_time_is_the_slowest_joint_s() {
        let w = [0.5, 2.0, 1.0, 1.0, 1.0, 0.25];
        let a = [0.1, 0.2, 0.3, 0.0, 0.0, 0.0];
        let b = [1.1, 0.5, 0.1, -0.4, 0.0, 2.0];
        assert!((joint_time(&w, &a, &b) - 0.6).abs() < 1e-12);
    }

    /// Turns compose as angles add: `of(a).then(of(b))` is `of(a + b)` (the angle-sum formulas),
    /// for angles of every quadrant and of either sign.
    #[test]
    fn turns_compose_as_their_angles_add() {
        for a in [-2.9, -1.1, -0.3, 0.0, 0.7, 1.9, 3.0] {
            for b in [-2.5, -0.8, 0.2, 1.3, 2.8] {
                let t = Turn::of(a).then(Turn::of(b));
                let want = Turn::of(a + b);
                assert!(
                    (t.c - want.c).abs() < 1e-12 && (t.s - want.s).abs() < 1e-12,
                    "{a} then {b}: {t:?}, want {want:?}"
                );
            }
        }
    }

    /// The perpendicular of a unit direction is a unit vector at a right angle to it, for
    /// directions along and near each axis (where the helper axis must change) and oblique
    /// ones; a vector along the direction is carried to such a perpendicular, any other to its
    /// own part across the direction.
    #[test]
    fn perpendiculars_are_unit_and_at_right_angles() {
        let directions = [
            Vector3::x(),
            -Vector3::x(),
            Vector3::y(),
            Vector3::z(),
            Vector3::new(0.95, 0.3, 0.1).normalize(),
            Vector3::new(0.85, -0.5, 0.2).normalize(),
            Vector3::new(-0.3, 0.4, -0.866).normalize(),
        ];
        for d in directions {
            let p = perpendicular(&d);
            assert!((p.norm() - 1.0).abs() < 1e-12, "{d:?}: {p:?}");
            assert!(p.dot(&d).abs() < 1e-12, "{d:?}: {p:?}");
            let along = transported(&(d * 3.0), &d);
            assert!((along.norm() - 1.0).abs() < 1e-12 && along.dot(&d).abs() < 1e-12);
            // (1, 2, 3) less its part along d, by hand, then normalised.
            let x = Vector3::new(1.0, 2.0, 3.0);
            let across = x - d * d.dot(&x);
            let t = transported(&x, &d);
            assert!((t - across / across.norm()).norm() < 1e-12, "{d:?}: {t:?}");
        }
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
        // the one in range is taken, and then the step from the reference is too large. The
        // same below the range (−710° < −398°: the shift up by a turn, −350°, is taken).
        for (axis_4_deg, step_deg) in [(725.0, 355.0), (-725.0, 375.0)] {
            match at(q, Some([20.0, 30.0, -20.0, axis_4_deg, 50.0, 60.0])) {
                Err(SixAxisFault::JointStep {
                    axis: 4,
                    change_deg,
                    ..
                }) => assert!((change_deg - step_deg).abs() < 1e-6, "{change_deg}"),
                other => panic!("{other:?}"),
            }
        }
    }

    /// The whole-turn shift is measured from the target to the raw angle: by hand, axis 6 at
    /// −170° after a pose at 180° is taken as 190° (10° on, not 350° back), and without a
    /// reference −170° stays −170°, nearer the middle of axis 6's ±400° (0°) than 190°.
    #[test]
    fn a_wrist_axis_past_half_a_turn_is_shifted_toward_its_target() {
        let q = [20.0, 30.0, -20.0, 40.0, 50.0, -170.0];
        let after = [20.0, 30.0, -20.0, 40.0, 50.0, 180.0];
        let got = at(q, Some(after)).unwrap();
        assert!(
            close(got, [20.0, 30.0, -20.0, 40.0, 50.0, 190.0]),
            "{got:?}"
        );
        let got = at(q, None).unwrap();
        assert!(close(got, q), "{got:?}");
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

    /// [`SixAxisArm::refine`] on joints exactly linear in the turn, `q(Δ) = a + rate·Δ`, every
    /// joint speed 1 and the previous pose at zero, with the rates known (`slope`) or not, `age`
    /// poses old: the pose chosen, the tracker after, and the turns evaluated (rad).
    fn refine_on_linear(
        a: Joints6,
        rate: Joints6,
        slope: Option<Joints6>,
        age: u32,
    ) -> (Candidate, Tracker, Vec<f64>) {
        use std::cell::RefCell;
        let calls = RefCell::new(Vec::new());
        let mut track = Tracker::new([1.0; 6]);
        track.slope = slope;
        track.age = age;
        let at = |turn: Turn| -> Candidate {
            let d = turn.s.atan2(turn.c);
            let q: Joints6 = std::array::from_fn(|i| a[i] + rate[i] * d);
            Candidate {
                q,
                x: Vector3::x(),
                cost: joint_time(&[1.0; 6], &[0.0; 6], &q),
                turn,
            }
        };
        let eval = |turn: Turn| {
            calls.borrow_mut().push(turn.s.atan2(turn.c));
            Ok(at(turn))
        };
        let chosen = irb2600().refine(at(Turn::ZERO), &[0.0; 6], &mut track, eval);
        (chosen, track, calls.into_inner())
    }

    /// `refine`'s decisions on joints that are exactly linear in the turn, `q(Δ) = a + r·Δ`
    /// (every joint speed 1, the previous pose at zero), where the least joint time is known by
    /// hand: no second inverse kinematics where nothing is worth gaining and the rates are
    /// fresh; one, at the model's least, where it is; a refresh probe of 0.25° once the rates
    /// are 32 poses old.
    #[test]
    fn refine_spends_a_second_inverse_kinematics_only_where_it_pays() {
        let rate: Joints6 = [1.0, -1.0, 0.0, 0.0, 0.0, 0.0];
        let run = |a: Joints6, age: u32| refine_on_linear(a, rate, Some(rate), age);
        // max(|0.1 + δ|, |0.1 − δ|): least 0.1 at δ = 0, the guess itself.
        let balanced = [0.1, 0.1, 0.0, 0.0, 0.0, 0.0];
        let (c, t, evals) = run(balanced, 0);
        assert!(evals.is_empty(), "{evals:?}");
        assert_eq!((c.cost, t.age), (0.1, 1));
        let (_, t, evals) = run(balanced, SLOPE_REFRESH_POSES - 1);
        assert!(evals.is_empty(), "{evals:?}");
        assert_eq!(t.age, SLOPE_REFRESH_POSES);
        // Rates 32 poses old: a 0.25° probe, worse than the guess, which is kept; the rates
        // are measured afresh from the two poses.
        let (c, t, evals) = run(balanced, SLOPE_REFRESH_POSES);
        assert_eq!(evals.len(), 1);
        assert!((evals[0] - 0.25f64.to_radians()).abs() < 1e-12, "{evals:?}");
        assert_eq!((c.cost, t.age), (0.1, 0));
        let measured = t.slope.unwrap();
        assert!((measured[0] - 1.0).abs() < 1e-9 && (measured[1] + 1.0).abs() < 1e-9);
        // max(|0.2 + δ|, |δ|): least 0.1 at δ = −0.1, half the guess's 0.2: evaluated and taken.
        let (c, t, evals) = run([0.2, 0.0, 0.0, 0.0, 0.0, 0.0], 3);
        assert_eq!(evals.len(), 1);
        assert!((evals[0] + 0.1).abs() < 1e-12, "{evals:?}");
        assert!((c.cost - 0.1).abs() < 1e-12, "{}", c.cost);
        assert_eq!(t.age, 0);
        // 0.1 rad is beyond the 0.5° a trend may carry.
        assert_eq!(t.drift_rad, 0.0);
        // A gain under 0.5 %: max(|0.2 + δ|, |0.199 − δ|)'s least 0.1995 is 0.25 % under 0.2.
        let (_, _, evals) = run([0.2, 0.199, 0.0, 0.0, 0.0, 0.0], 0);
        assert!(evals.is_empty(), "{evals:?}");
        // ... and one over it: max(|0.2 + δ|, |0.19 − δ|), least 0.195, 2.5 % under.
        // A correction under 0.5° is a trend, spread over the poses since the last measurement.
        let (c, t, evals) = run([0.2, 0.19, 0.0, 0.0, 0.0, 0.0], 0);
        assert_eq!(evals.len(), 1);
        assert!((evals[0] + 0.005).abs() < 1e-12 && (c.cost - 0.195).abs() < 1e-12);
        assert!((t.drift_rad + 0.005).abs() < 1e-12, "{}", t.drift_rad);
        let (_, t, _) = run([0.2, 0.19, 0.0, 0.0, 0.0, 0.0], 4);
        assert!((t.drift_rad + 0.001).abs() < 1e-12, "{}", t.drift_rad);
    }

    /// Where the turn the last pose took and a degree either side of it are refused (here: a
    /// half turn of the tool, a 140° step of axis 6), the whole turn is scanned in 5° steps and
    /// the least joint time taken: the pose itself, 40° round from the carried `x` axis.
    #[test]
    fn a_refused_guess_falls_back_to_the_scan_and_its_least() {
        let arm = irb2600();
        let q0 = deg([10.0, 20.0, -10.0, 30.0, 45.0, 20.0]);
        let flange = arm.kind.forward(&q0);
        let (x, y, d) = (
            flange.rotation.column(0).into_owned(),
            flange.rotation.column(1).into_owned(),
            flange.rotation.column(2).into_owned(),
        );
        let target = EyeTarget {
            eye_mm: Point3::from(flange.translation_mm),
            tow: Unit::new_normalize(d),
        };
        let (s40, c40) = 40f64.to_radians().sin_cos();
        let x_prev = x * c40 - y * s40;
        let tool = inverted_tool(&arm.tool.frame());
        let config = arm.kind.config_of(&q0);
        let mut track = Tracker::new([1.0; 6]);
        track.turn = Turn::of(PI);
        let c = arm
            .next_pose(&target, &tool, config, &q0, &x_prev, &mut track)
            .unwrap();
        assert!(c.cost < 1e-9, "{}", c.cost);
        assert!(close(c.q, q0), "{:?}", c.q);
        assert!((c.turn.s.atan2(c.turn.c) - 40f64.to_radians()).abs() < 1e-12);
        assert!((c.x - x).norm() < 1e-12);
        // The search starts afresh from there.
        assert_eq!(track.turn, Turn::ZERO);
        assert!(track.slope.is_none());
    }

    /// `max_j |a_j + b_j·δ|` at `d`, written out.
    fn max_abs(a: &Joints6, b: &Joints6, d: f64) -> f64 {
        (0..6).map(|j| (a[j] + b[j] * d).abs()).fold(0.0, f64::max)
    }

    /// The closed form's least against a brute-force scan of `δ` (then refined about the scan's
    /// best), for random terms, some with zero rates, some with the least beyond the limit; the
    /// quick test agrees with the least on either side of it.
    #[test]
    fn least_max_abs_is_the_least_a_scan_finds() {
        let mut rng = crate::clearance::test_support::uniform(77);
        for case in 0..2000 {
            let a: Joints6 = std::array::from_fn(|_| rng() * 2.0 - 1.0);
            let b: Joints6 = std::array::from_fn(|j| {
                if case % 7 == 0 && j % 2 == 0 {
                    0.0
                } else {
                    (rng() * 2.0 - 1.0) * 3.0
                }
            });
            let limit = if case % 5 == 0 { 0.05 } else { 4.0 };
            let (d, least) = least_max_abs(&a, &b, limit);
            assert!(d.abs() <= limit, "case {case}: δ {d}");
            assert!((max_abs(&a, &b, d) - least).abs() < 1e-12, "case {case}");
            let mut best = (0.0, f64::INFINITY);
            for k in -2000..=2000 {
                let x = limit * k as f64 / 2000.0;
                let f = max_abs(&a, &b, x);
                if f < best.1 {
                    best = (x, f);
                }
            }
            for k in -1000..=1000 {
                let x = (best.0 + limit * k as f64 / 2e6).clamp(-limit, limit);
                best.1 = best.1.min(max_abs(&a, &b, x));
            }
            assert!(
                least <= best.1 + 1e-9,
                "case {case}: {least} > scan {}",
                best.1
            );
            // The scan's own resolution: 2·10⁻⁶ in δ, slopes up to 6.
            assert!(
                least >= best.1 - 1.5e-5,
                "case {case}: {least} < scan {}",
                best.1
            );
            if limit > 1.0 {
                let mut hint = (0, 1);
                assert!(least_max_abs_reaches(
                    &a,
                    &b,
                    least * (1.0 - 1e-9),
                    &mut hint
                ));
                assert!(!least_max_abs_reaches(
                    &a,
                    &b,
                    least * (1.0 + 1e-6) + 1e-12,
                    &mut hint
                ));
            }
        }
        // Every rate zero: flat, no correction.
        let a = [0.3, -0.1, 0.0, 0.2, 0.0, 0.0];
        assert_eq!(least_max_abs(&a, &[0.0; 6], 1.0), (0.0, 0.3));
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

    /// Without rates (the first pose after a start or after a fallback) the probe is one degree
    /// ([`LOCAL_STEP_RAD`]) and the rates are measured from it; a correction the model puts
    /// beyond 15° ([`MAX_TRACK_STEP_RAD`]) is evaluated at 15°. By hand, with rates 1 and −1:
    /// max(|0.1 + δ|, |0.1 − δ|) at 1° is 0.1175, over the guess's 0.1, which is kept;
    /// max(|1 + δ|, |δ|) is least at δ = −0.5 rad (28.6°), and at −15° (−0.2618 rad) it is
    /// 1 − 0.2618, under the guess's 1: taken.
    #[test]
    fn refine_probes_a_degree_without_rates_and_corrects_at_most_15_degrees() {
        let rate: Joints6 = [1.0, -1.0, 0.0, 0.0, 0.0, 0.0];
        let (c, t, evals) = refine_on_linear([0.1, 0.1, 0.0, 0.0, 0.0, 0.0], rate, None, 0);
        assert_eq!(evals.len(), 1);
        assert!((evals[0] - 1f64.to_radians()).abs() < 1e-12, "{evals:?}");
        assert_eq!((c.cost, t.age), (0.1, 0));
        let measured = t.slope.unwrap();
        assert!(
            (measured[0] - 1.0).abs() < 1e-9 && (measured[1] + 1.0).abs() < 1e-9,
            "{measured:?}"
        );
        let cap = 15f64.to_radians();
        let (c, _, evals) = refine_on_linear([1.0, 0.0, 0.0, 0.0, 0.0, 0.0], rate, Some(rate), 0);
        assert_eq!(evals.len(), 1);
        assert!((evals[0] + cap).abs() < 1e-12, "{evals:?}");
        assert!((c.cost - (1.0 - cap)).abs() < 1e-12, "{}", c.cost);
    }

    /// The report by hand from the IRB 2600's ranges (`docs/arms.md`) for the poses (°)
    /// `[0, 10, 0, 0, 30, 0]`, `[10, 20, −10, 0, 40, 5]`, `[10, 40, −10, 0, 20, 5]`: least
    /// range-end distances 75 (axis 3), 80 (axis 5), 85 (axis 3), so 75° at axis 3; wrist bends
    /// 30, 40 and 20°, so 20°; steps of 10° (axes 1, 2, 3, 5), then 20° on axes 2 and 5 (the
    /// same two angles swapped, an exact tie): 20° at axis 2, the lower. Then two poses, axis 1
    /// at its lower end and then axis 2 at its: a tie at 0°, the first pose's axis 1 named; the
    /// step, axis 1's 180°.
    #[test]
    fn the_report_holds_the_least_margins_and_the_largest_step_and_their_axes() {
        let arm = irb2600();
        let joints = [
            [0.0, 10.0, 0.0, 0.0, 30.0, 0.0],
            [10.0, 20.0, -10.0, 0.0, 40.0, 5.0],
            [10.0, 40.0, -10.0, 0.0, 20.0, 5.0],
        ]
        .map(deg);
        let config = Config::from_index(5);
        let r = arm.report(&joints, config);
        assert_eq!(r.config, config);
        assert!((r.least_limit_margin_deg - 75.0).abs() < 1e-9, "{r:?}");
        assert_eq!(r.least_limit_axis, 3, "{r:?}");
        assert!((r.least_wrist_margin_deg - 20.0).abs() < 1e-9, "{r:?}");
        assert!((r.largest_step_deg - 20.0).abs() < 1e-9, "{r:?}");
        assert_eq!(r.largest_step_axis, 2, "{r:?}");
        let (lo1, lo2) = (arm.limits.min_rad[0], arm.limits.min_rad[1]);
        let ends = [
            [lo1, 0.0, 0.0, 0.0, 30f64.to_radians(), 0.0],
            [0.0, lo2, 0.0, 0.0, 30f64.to_radians(), 0.0],
        ];
        let r = arm.report(&ends, config);
        assert_eq!((r.least_limit_margin_deg, r.least_limit_axis), (0.0, 1));
        assert!((r.largest_step_deg - 180.0).abs() < 1e-9, "{r:?}");
        assert_eq!(r.largest_step_axis, 1, "{r:?}");
    }

    /// A path with an eye or a tow direction that is not finite is refused naming the point,
    /// whichever of the two it is.
    #[test]
    fn a_path_with_a_coordinate_not_finite_is_refused_with_its_index() {
        let arm = irb2600();
        let good = EyeTarget {
            eye_mm: Point3::new(1000.0, 0.0, 800.0),
            tow: -Vector3::z_axis(),
        };
        let mut eye_nan = good;
        eye_nan.eye_mm.y = f64::NAN;
        let tow_inf = EyeTarget {
            tow: Unit::new_unchecked(Vector3::new(0.0, f64::INFINITY, 1.0)),
            ..good
        };
        for bad in [eye_nan, tow_inf] {
            match arm.solve_path(&[good, good, bad], None) {
                Err(Error::NonFinitePoint { index: 2 }) => {}
                other => panic!("{bad:?}: {other:?}"),
            }
        }
    }

    /// The IRB 2600 with the eye 150 mm out of the flange, its axis along the flange's `x`: the
    /// turn about the tow line then moves the wrist centre, and every joint's margin with it.
    fn irb2600_eye_across() -> SixAxisArm {
        let tool = Tool {
            tcp_mm: [0.0, 0.0, 150.0],
            rpy_deg: [0.0, 90.0, 0.0],
        };
        SixAxisArm::opw_preset("irb2600-12/1.65", tool).unwrap()
    }

    /// The eye target the tool frame makes at the joints `q_deg`.
    fn target_at(arm: &SixAxisArm, q_deg: [f64; 6]) -> EyeTarget {
        let f = arm.kind.forward(&deg(q_deg));
        let t = arm.tool.frame();
        EyeTarget {
            eye_mm: Point3::from(f.rotation * t.translation_mm + f.translation_mm),
            tow: Unit::new_normalize(f.rotation * t.rotation.column(2)),
        }
    }

    /// Comfort written out for the IRB 2600: the least distance of any joint from its range's
    /// ends, and of axis 5 (the wrist bend: offset 0, sign +1) from 0° and ±180°.
    fn irb2600_comfort(arm: &SixAxisArm, q: &Joints6) -> f64 {
        let limit = (0..6)
            .map(|i| (q[i] - arm.limits.min_rad[i]).min(arm.limits.max_rad[i] - q[i]))
            .fold(f64::INFINITY, f64::min);
        let bend = q[4].rem_euclid(PI);
        limit.min(bend.min(PI - bend))
    }

    /// The admissible turns of a 10°·k grid (k = 0..36, from `perpendicular(tow)` toward
    /// `tow × perpendicular`) at `t` in `config`, without a previous pose: (k, comfort, x).
    fn grid_comfort(
        arm: &SixAxisArm,
        t: &EyeTarget,
        config: Config,
        steps: usize,
    ) -> Vec<(usize, f64, Vector3<f64>)> {
        let tool = inverted_tool(&arm.tool.frame());
        let d = t.tow.into_inner();
        let e1 = perpendicular(&d);
        let e2 = d.cross(&e1);
        (0..steps)
            .filter_map(|k| {
                let g = (360.0 * k as f64 / steps as f64).to_radians();
                let x = e1 * g.cos() + e2 * g.sin();
                arm.admissible(&t.eye_mm, &x, &d, &tool, config, None)
                    .ok()
                    .map(|q| (k, irb2600_comfort(arm, &q), x))
            })
            .collect()
    }

    /// The starting turns are the grid's most comfortable, at least 60° (six grid steps) apart,
    /// best first, three of them: the choice made again here greedily over the grid, the
    /// separation counted in whole steps.
    #[test]
    fn the_starts_are_the_most_comfortable_grid_turns_60_degrees_apart() {
        let arm = irb2600_eye_across();
        let tool = inverted_tool(&arm.tool.frame());
        // The last pose is admissible over a narrow span of turns only: two starts.
        for (q, count) in [
            (BASE, 3),
            ([-30.0, 10.0, 10.0, -60.0, -70.0, 10.0], 3),
            ([60.0, 40.0, -40.0, 120.0, 30.0, -90.0], 2),
        ] {
            let t = target_at(&arm, q);
            let config = arm.kind.config_of(&deg(q));
            let mut grid = grid_comfort(&arm, &t, config, 36);
            grid.sort_by(|a, b| b.1.total_cmp(&a.1));
            let mut want: Vec<(usize, f64, Vector3<f64>)> = Vec::new();
            for g in grid {
                if want.iter().all(|w| {
                    let steps = (g.0 + 36 - w.0) % 36;
                    steps.min(36 - steps) >= 6
                }) && want.len() < 3
                {
                    want.push(g);
                }
            }
            let got = arm.starts(&t, &tool, config);
            assert_eq!((got.len(), want.len()), (count, count), "{q:?}");
            for ((c, x), w) in got.iter().zip(&want) {
                assert!((c - w.1).abs() < 1e-9, "{q:?}: {c} {}", w.1);
                assert!((x - w.2).norm() < 1e-9, "{q:?}: {x:?} {:?}", w.2);
            }
        }
    }

    /// The configurations' order: the preferred first, then by the least over up to five poses
    /// (all of up to five; else poses k·(n − 1)/4, k = 0..4) of the best comfort over twelve
    /// turns (30° apart), an unreachable configuration last; the same scoring done here from
    /// the grid.
    #[test]
    fn configurations_are_ranked_by_their_least_best_comfort_at_five_poses() {
        let arm = irb2600_eye_across();
        let tool = inverted_tool(&arm.tool.frame());
        // Poses 0, 2, 4, 6 and 8 (the five scored) reach every configuration, and rank them
        // otherwise than pose 0 alone; pose 3 only the front, elbow-up ones.
        let path: Vec<EyeTarget> = [
            [76.0, -66.0, -24.0, 165.0, 2.0, 109.0],
            [-64.0, 81.0, -128.0, -16.0, -82.0, -126.0],
            [108.0, -16.0, -111.0, 168.0, -77.0, 113.0],
            [22.0, 125.0, -14.0, -85.0, 65.0, -45.0],
            [-40.0, -26.0, -57.0, 174.0, 68.0, 11.0],
            [-47.0, 65.0, -146.0, 98.0, 18.0, -14.0],
            [-88.0, -41.0, -35.0, 53.0, -4.0, -108.0],
            [-40.0, -6.0, -34.0, -159.0, 63.0, 65.0],
            [-76.0, -32.0, -92.0, 10.0, -47.0, 118.0],
        ]
        .map(|q| target_at(&arm, q))
        .to_vec();
        let score = |c: Config, picks: &[usize]| {
            picks
                .iter()
                .map(|&i| {
                    grid_comfort(&arm, &path[i], c, 12)
                        .iter()
                        .map(|g| g.1)
                        .fold(f64::NEG_INFINITY, f64::max)
                })
                .fold(f64::INFINITY, f64::min)
        };
        // The order got: every configuration once, the preferred first, then the scores
        // (written out above) never rising; the wrist-flip twins score alike but for rounding.
        let check = |got: Vec<Config>, picks: &[usize], prefer: Option<Config>| {
            let mut seen = got.clone();
            seen.sort_by_key(|c| c.index());
            assert_eq!(seen, Config::ALL.to_vec());
            let rest = match prefer {
                Some(p) => {
                    assert_eq!(got[0], p);
                    &got[1..]
                }
                None => &got[..],
            };
            let scores: Vec<f64> = rest.iter().map(|&c| score(c, picks)).collect();
            for w in scores.windows(2) {
                assert!(
                    w[0] >= w[1] - 1e-9,
                    "{picks:?} {prefer:?}: {got:?} {scores:?}"
                );
            }
        };
        for prefer in [None, Some(Config::from_index(6))] {
            check(
                arm.ranked_configs(&path, &tool, prefer),
                &[0, 2, 4, 6, 8],
                prefer,
            );
            check(
                arm.ranked_configs(&path[..4], &tool, prefer),
                &[0, 1, 2, 3],
                prefer,
            );
        }
    }

    /// Where no configuration keeps the whole path, the error names the furthest pose any
    /// reached and the configuration that reached it, the first tried on a tie. The path lies
    /// along a smooth joint path in one configuration, axis 1 turning from 40° to 20°, but pose
    /// 12 is out of reach; axis 1's range is cut to −150..180°, so the shoulder-back
    /// configurations (axis 1 near −140° and turning down) stop before pose 12.
    #[test]
    fn a_path_no_configuration_keeps_names_the_furthest_pose_reached() {
        let mut arm = irb2600_eye_across();
        arm.limits.min_rad[0] = (-150f64).to_radians();
        let at = |s: f64| {
            [
                40.0 - 20.0 * s,
                30.0 + 10.0 * s,
                -20.0 + 10.0 * s,
                40.0,
                50.0,
                60.0,
            ]
        };
        let mut path: Vec<EyeTarget> = (0..20)
            .map(|k| target_at(&arm, at(k as f64 / 19.0)))
            .collect();
        path[12].eye_mm = Point3::new(4000.0, 0.0, 500.0);
        let own = arm.kind.config_of(&deg(at(0.0)));
        let back = Config::ALL
            .into_iter()
            .find(|c| c.shoulder != own.shoulder)
            .unwrap();
        for prefer in [own, back] {
            match arm.solve_path(&path, Some(prefer)) {
                Err(Error::SixAxis {
                    segment: Some(12),
                    fault: SixAxisFault::NoConfiguration { config, reason },
                }) => {
                    assert!(
                        matches!(*reason, SixAxisFault::OutOfReach { .. }),
                        "{reason:?}"
                    );
                    if prefer == own {
                        assert_eq!(config, own);
                    } else {
                        assert_eq!(config.shoulder, own.shoulder);
                    }
                }
                other => panic!("{prefer}: {other:?}"),
            }
        }
        // The shoulder-back configurations do start, and stop before pose 12.
        let tool = inverted_tool(&arm.tool.frame());
        let starts = arm.starts(&path[0], &tool, back);
        assert!(!starts.is_empty());
        for (_, x) in starts {
            let stop = arm.follow(&path, &tool, back, &x).unwrap_err();
            assert!(stop.0 < 12, "{stop:?}");
        }
    }

    /// The turn taken needs the least joint time with each joint's change weighed by its speed
    /// (the IRB 2600's, `docs/arms.md`: 175, 175, 175, 360, 360, 510 °/s), not the least joint
    /// change: along a smooth path (one configuration, 80 poses), from pose 10 on (the first
    /// poses start from the most comfortable turn), the path's joint time is within 2 % of a
    /// 0.1° scan of the whole turn from the same previous pose. The turns of least unweighted
    /// change would take 5 % longer or more here (checked on the scan).
    #[test]
    fn the_turn_taken_needs_the_least_joint_time_by_the_joint_speeds() {
        let arm = irb2600_eye_across();
        let speed = arm.limits.speed_rad_s.unwrap();
        let tool = inverted_tool(&arm.tool.frame());
        let at = |s: f64| {
            [
                20.0 + 40.0 * s,
                30.0 + 15.0 * (6.0 * s).sin(),
                -20.0 + 10.0 * s,
                40.0 - 60.0 * s,
                50.0 + 20.0 * (4.0 * s).sin(),
                60.0 + 90.0 * s,
            ]
        };
        let n = 80;
        let path: Vec<EyeTarget> = (0..n)
            .map(|k| target_at(&arm, at(k as f64 / (n - 1) as f64)))
            .collect();
        let solved = arm.solve_path(&path, None).unwrap();
        let time = |a: &Joints6, b: &Joints6, w: &Joints6| {
            (0..6)
                .map(|i| (b[i] - a[i]).abs() * w[i])
                .fold(0.0, f64::max)
        };
        let by_speed: Joints6 = std::array::from_fn(|i| 1.0 / speed[i]);
        let (mut taken, mut least, mut least_change) = (0.0, 0.0, 0.0);
        for (k, t) in path.iter().enumerate().skip(10) {
            let prev = solved.joints[k - 1];
            let d = t.tow.into_inner();
            let e1 = perpendicular(&d);
            let e2 = d.cross(&e1);
            let scan: Vec<Joints6> = (0..3600)
                .filter_map(|j| {
                    let g = (j as f64 / 10.0).to_radians();
                    let x = e1 * g.cos() + e2 * g.sin();
                    let config = solved.report.config;
                    arm.admissible(&t.eye_mm, &x, &d, &tool, config, Some(&prev))
                        .ok()
                })
                .collect();
            let best = |w: &Joints6| {
                *scan
                    .iter()
                    .min_by(|a, b| time(&prev, a, w).total_cmp(&time(&prev, b, w)))
                    .unwrap()
            };
            taken += time(&prev, &solved.joints[k], &by_speed);
            least += time(&prev, &best(&by_speed), &by_speed);
            least_change += time(&prev, &best(&[1.0; 6]), &by_speed);
        }
        assert!(taken <= 1.02 * least, "{taken} {least}");
        assert!(least_change >= 1.05 * least, "{least_change} {least}");
    }
}
