//! Lathe winding plans: layers of hoop, helical and skip winding on a cylinder with hemispherical
//! domes (seed 002), on an open tube, or helical and skip layers on a reducing cone (geodesics,
//! [`cone`]) or a von Kármán nose (geodesic or friction paths to a turnaround, [`nose`]), turned
//! into one stream of axis moves ([`crate::motion`]).
//!
//! A [`Job`] is checked whole before anything is emitted ([`Job::check`]): every layer's pattern
//! must close, the eye must clear the laminate, and the counts must be countable; only then does
//! [`Plan::emit`] stream the moves, so a job that fails writes nothing.
//!
//! Layer build-up: with [`Job::build_up`], each layer winds on the mandrel plus the laminate
//! below it — a helical layer (two plies, ±β) adds twice the tow thickness, a hoop pass adds one.
//! The domes are taken to grow by the same amount as the cylinder (a sphere of the new radius
//! with the same polar opening); seed 002's Eqs. 10–11 show the dome really thickens towards the
//! opening ([`crate::pattern::dome_thickness_ratio`]: 4.32 times the cylinder's at the opening of
//! seed 002's vessel with a 4 mm band), so this understates the dome's growth near the pole.
//!
//! Dome strokes (seed 002 Eq. 17, Appendix A; `docs/seed-readings.md` R002-1). One stroke runs pole → cylinder →
//! pole: the departure from the near dome (α from 90° to 180°), one straight move along the
//! cylinder (Eq. 20: the helix is linear in carriage and mandrel angle, so it needs no
//! segmentation), and the arrival on the far dome (α from 0° to 90°). Each dome part is split at
//! α* = arcsin(Rc/Re) into [`Machine::dome_steps`] equal steps on either side, as the seed did.
//! A cycle is a forward and a backward stroke; the backward stroke mirrors the carriage and the
//! eye rotation. The dwell Φf and, at the end of a pattern, the advance Φw are added to the
//! mandrel turn of the stroke's last dome move, as the seed's O0006/O0007 do.

use crate::Error;
use crate::delivery::{EyePath, EyePoint};
use crate::motion::{Axes, AxisSet, LayerKind, LayerMark, Limits, MotionSink, Move, MoveKind};
use crate::pattern::{Pattern, PatternRequest};
use std::f64::consts::{PI, TAU};

pub mod cone;
pub mod nose;
pub mod polar;
use cone::{ConeGeodesic, ConeRefusal};
use nose::{NosePass, NoseRefusal, VonKarman};
use polar::{PolarPlane, PolarStation};

/// The mandrel's shape.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Mandrel {
    /// A cylinder with hemispherical ends and equal polar openings (seed 002).
    Vessel {
        /// Rc.
        cylinder_radius_mm: f64,
        /// Lc.
        cylinder_length_mm: f64,
        /// rp.
        polar_radius_mm: f64,
    },
    /// An open cylinder wound between its ends with lock turns (the tube of `.wind` files).
    Tube {
        /// Radius.
        radius_mm: f64,
        /// The wound length.
        length_mm: f64,
    },
    /// A reducing cone (frustum) wound between its ends with lock turns, the large end at the
    /// carriage's start (`.wind` files with `endDiameter`); helical layers follow geodesics.
    Cone {
        /// Radius of the large end (at the carriage's start).
        large_radius_mm: f64,
        /// Radius of the small end.
        small_radius_mm: f64,
        /// The wound length along the axis.
        length_mm: f64,
    },
    /// A von Kármán ogive (nose) from its base, at the carriage's start, to its tip
    /// (`.wind` files with `profile`); helical layers run from the base to a turnaround.
    VonKarman {
        /// Radius of the base.
        base_radius_mm: f64,
        /// Axial length from the base to the tip.
        length_mm: f64,
    },
}

impl Mandrel {
    /// The bare mandrel's winding radius.
    pub fn radius_mm(&self) -> f64 {
        match *self {
            Mandrel::Vessel {
                cylinder_radius_mm, ..
            } => cylinder_radius_mm,
            Mandrel::Tube { radius_mm, .. } => radius_mm,
            Mandrel::Cone {
                large_radius_mm, ..
            } => large_radius_mm,
            Mandrel::VonKarman { base_radius_mm, .. } => base_radius_mm,
        }
    }

    /// The cylinder's length.
    pub fn length_mm(&self) -> f64 {
        match *self {
            Mandrel::Vessel {
                cylinder_length_mm, ..
            } => cylinder_length_mm,
            Mandrel::Tube { length_mm, .. }
            | Mandrel::Cone { length_mm, .. }
            | Mandrel::VonKarman { length_mm, .. } => length_mm,
        }
    }
}

/// The tow band.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Tow {
    /// Band width b, mm.
    pub band_mm: f64,
    /// Thickness of one ply, mm.
    pub thickness_mm: f64,
}

/// The winder.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Machine {
    /// The axes it has.
    pub axes: AxisSet,
    /// On a vessel with cross-feed: Re, the radius of the eye's circle about the dome centre
    /// (Eq. 12). Otherwise: the eye's fixed distance from the mandrel axis.
    pub eye_radius_mm: f64,
    /// Velocity and acceleration limits (feeds and the time estimate).
    pub limits: Limits,
    /// Moves on each side of α* in each dome part (the seed used 10).
    pub dome_steps: usize,
}

/// A helical layer on a tube at a set wind angle, in the terms of `.wind` files.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct TubeHelical {
    /// Wind angle from the mandrel axis, degrees.
    pub wind_angle_deg: f64,
    /// Circuits per pattern.
    pub pattern_number: u32,
    /// How many pattern slots the next circuit skips ahead.
    pub skip_index: u32,
    /// Mandrel turn at each end with the carriage still, degrees.
    pub lock_deg: f64,
    /// Length at the start of a pass over which the eye swings to the wind angle, mm.
    pub lead_in_mm: f64,
    /// Mandrel turn at the end of a pass while the eye swings back, degrees.
    pub lead_out_deg: f64,
    /// Whether the layer begins with a lock turn at the near end.
    pub initial_lock: bool,
    /// The friction ratio λ = |k_g| / k_n the path may use: 0 winds the geodesic; above 0 only
    /// on a nose ([`nose`]), at most [`NOSE_SLIP_LIMIT`].
    pub friction_lambda: f64,
}

/// One layer of a job.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Layer {
    /// Hoop winding over the cylinder at a pitch of one band per turn, `passes` plies.
    Hoop {
        /// 1 (one ply, ends at the other end) or 2 (out and back).
        passes: u32,
    },
    /// Geodesic helical winding over a vessel's domes (seed 002 Eqs. 1–9).
    Helical(PatternRequest),
    /// Helical winding of a tube at a set angle.
    TubeHelical(TubeHelical),
    /// The mandrel turns with no tow laid.
    Skip {
        /// The turn, degrees.
        mandrel_deg: f64,
    },
    /// Polar (planar) winding of a vessel, the fibre tangent to both openings ([`polar`]).
    Polar {
        /// The largest ratio of geodesic to normal curvature the tow may need (the friction
        /// coefficient it can rely on, μ).
        slip_limit: f64,
    },
}

/// The default slip limit of a polar layer: λ of seed 002's mandrel (Rc 60, rp 21) at a
/// length-to-diameter ratio of 2.0, the top of the range the seed gives for in-plane winders
/// (`docs/seed-readings.md` R002-5).
pub const POLAR_SLIP_LIMIT: f64 = 0.18;

/// The slip limit μ a nose layer's friction ratio may not exceed: the default machine slip
/// limit of the `.wind` format's machine profile (FiberPath's `slipLimit`, 0.2).
pub const NOSE_SLIP_LIMIT: f64 = 0.2;

/// A job: what to wind and on what.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Job {
    /// The mandrel.
    pub mandrel: Mandrel,
    /// The tow.
    pub tow: Tow,
    /// The winder.
    pub machine: Machine,
    /// The layers, innermost first.
    pub layers: Vec<Layer>,
    /// Whether each layer winds on the laminate below it.
    pub build_up: bool,
}

/// One point of a stroke template: absolute carriage, cross-feed and eye for a forward stroke,
/// and the mandrel turn since the stroke began.
#[derive(Debug, Clone, Copy, PartialEq)]
struct StrokePoint {
    mandrel_deg: f64,
    carriage_mm: f64,
    cross_feed_mm: f64,
    eye_deg: f64,
}

#[derive(Debug, Clone, PartialEq)]
enum Detail {
    Dome {
        pattern: Pattern,
        start: StrokePoint,
        stroke: Vec<StrokePoint>,
    },
    Hoop {
        passes: u32,
        start_mm: f64,
        end_mm: f64,
        turn_per_pass_deg: f64,
        cross_feed_mm: f64,
        eye_deg: f64,
    },
    Tube {
        layer: TubeHelical,
        circuits: u32,
        half_length_mm: f64,
        pass: Pass,
        turnaround_deg: f64,
        cross_feed_mm: f64,
    },
    Nose {
        layer: TubeHelical,
        circuits: u32,
        half_length_mm: f64,
        stations: Vec<cone::Station>,
        base_turn_deg: f64,
        cross_feed_mm: f64,
    },
    Skip {
        mandrel_deg: f64,
    },
    Polar {
        circuits: u32,
        advance_deg: f64,
        stations: Vec<PolarStation>,
    },
}

/// How the mandrel turns with the carriage over a pass of a tube or cone helical layer.
#[derive(Debug, Clone, PartialEq)]
enum Pass {
    /// A helix on a cylinder: a constant turn per mm (seed 002 Eq. 20).
    Helix { deg_per_mm: f64 },
    /// A geodesic on a cone: the stations from the large end ([`ConeGeodesic::stations`]).
    Geodesic(Vec<cone::Station>),
}

/// A checked layer, ready to emit.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedLayer {
    /// Its mark (counts, tow length, radius, angle).
    pub mark: LayerMark,
    /// The helical pattern, for dome layers.
    pub pattern: Option<Pattern>,
    detail: Detail,
}

/// A checked job: emitting it cannot fail except in the sink.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// The layers in order.
    pub layers: Vec<PlannedLayer>,
    limits: Limits,
}

/// Mandrel turn during a transition between layers that moves the carriage by more than a band:
/// one full turn, so the tow wraps (locks) rather than being dragged along the surface.
pub const TRANSITION_TURN_DEG: f64 = 360.0;

fn positive(name: &'static str, value: f64) -> Result<(), Error> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(Error::OutOfRange {
            name,
            value,
            expected: "must be > 0",
        })
    }
}

impl Job {
    /// Checks every layer and precomputes its strokes; nothing is emitted.
    pub fn check(&self) -> Result<Plan, Error> {
        positive("band_width_mm", self.tow.band_mm)?;
        if !(self.tow.thickness_mm >= 0.0 && self.tow.thickness_mm.is_finite()) {
            return Err(Error::OutOfRange {
                name: "thickness_mm",
                value: self.tow.thickness_mm,
                expected: "must be ≥ 0",
            });
        }
        positive("eye_radius_mm", self.machine.eye_radius_mm)?;
        positive("cylinder_radius_mm", self.mandrel.radius_mm())?;
        if !(self.mandrel.length_mm() >= 0.0 && self.mandrel.length_mm().is_finite()) {
            return Err(Error::OutOfRange {
                name: "cylinder_length_mm",
                value: self.mandrel.length_mm(),
                expected: "must be ≥ 0",
            });
        }
        for l in &self.machine.limits.axes {
            positive("velocity", l.velocity)?;
            positive("acceleration", l.acceleration)?;
        }
        if self.machine.dome_steps == 0 || self.machine.dome_steps > 10_000 {
            return Err(Error::OutOfRange {
                name: "dome_steps",
                value: self.machine.dome_steps as f64,
                expected: "must be 1..=10000",
            });
        }
        if self.layers.is_empty() {
            return Err(Error::OutOfRange {
                name: "layers",
                value: 0.0,
                expected: "a job needs at least one layer",
            });
        }
        let mut radius = self.mandrel.radius_mm();
        let mut layers = Vec::with_capacity(self.layers.len());
        for (i, layer) in self.layers.iter().enumerate() {
            let number = i + 1;
            if radius >= self.machine.eye_radius_mm {
                return Err(Error::EyeInsideLaminate {
                    layer: number,
                    eye_radius_mm: self.machine.eye_radius_mm,
                    winding_radius_mm: radius,
                });
            }
            let planned = self
                .check_layer(number, layer, radius)
                .map_err(|e| match e {
                    e @ (Error::WindRule { .. } | Error::EyeInsideLaminate { .. }) => e,
                    e => Error::Layer {
                        layer: number,
                        source: Box::new(e),
                    },
                })?;
            if self.build_up {
                radius += self.tow.thickness_mm
                    * match planned.detail {
                        Detail::Dome { .. }
                        | Detail::Tube { .. }
                        | Detail::Nose { .. }
                        | Detail::Polar { .. } => 2.0,
                        Detail::Hoop { passes, .. } => f64::from(passes),
                        Detail::Skip { .. } => 0.0,
                    };
            }
            layers.push(planned);
        }
        Ok(Plan {
            layers,
            limits: self.machine.limits,
        })
    }

    fn check_layer(
        &self,
        number: usize,
        layer: &Layer,
        radius: f64,
    ) -> Result<PlannedLayer, Error> {
        let length = self.mandrel.length_mm();
        let band = self.tow.band_mm;
        let mark = |kind, circuits, tow_length_mm, wind_angle_deg| LayerMark {
            number,
            kind,
            circuits,
            tow_length_mm,
            winding_radius_mm: radius,
            wind_angle_deg,
        };
        match (layer, self.mandrel) {
            (
                Layer::Helical(request),
                Mandrel::Vessel {
                    polar_radius_mm, ..
                },
            ) => {
                let pattern = Pattern::plan(radius, polar_radius_mm, length, band, request)?;
                let (start, stroke) =
                    self.dome_stroke(number, radius, polar_radius_mm, &pattern)?;
                let beta = pattern.wind_angle_deg.to_radians();
                let cycles = u64::from(pattern.cycles_per_layer());
                let per_stroke = length / beta.cos() + PI * radius;
                let dwell_arcs = polar_radius_mm
                    * (2.0 * cycles as f64 * pattern.dwell_deg.to_radians()
                        + f64::from(pattern.patterns_per_layer) * pattern.advance_deg.to_radians());
                Ok(PlannedLayer {
                    mark: mark(
                        LayerKind::Helical,
                        cycles,
                        2.0 * cycles as f64 * per_stroke + dwell_arcs,
                        pattern.wind_angle_deg,
                    ),
                    pattern: Some(pattern),
                    detail: Detail::Dome {
                        pattern,
                        start,
                        stroke,
                    },
                })
            }
            (
                &Layer::Polar { slip_limit },
                Mandrel::Vessel {
                    polar_radius_mm, ..
                },
            ) => self.check_polar(number, slip_limit, radius, polar_radius_mm),
            (Layer::Polar { .. }, _) => Err(Error::WindRule {
                layer: number,
                reason: "a polar layer needs a vessel with polar openings".to_string(),
            }),
            (Layer::Helical(_), Mandrel::Cone { .. }) => Err(Error::WindRule {
                layer: number,
                reason: "a geodesic dome layer needs a vessel with polar openings, not a cone"
                    .to_string(),
            }),
            (Layer::Helical(_), Mandrel::VonKarman { .. }) => Err(Error::WindRule {
                layer: number,
                reason: "a geodesic dome layer needs a vessel with polar openings, not a nose"
                    .to_string(),
            }),
            (Layer::Hoop { .. }, Mandrel::VonKarman { .. }) => Err(Error::WindRule {
                layer: number,
                reason: "hoop layers on a nose profile are not planned: a hoop on a tapering \
                         surface is not a geodesic and would slip toward the tip"
                    .to_string(),
            }),
            (Layer::Hoop { .. }, Mandrel::Cone { .. }) => Err(Error::WindRule {
                layer: number,
                reason: "hoop layers on a cone are not planned: a hoop (near 90°) on a taper is \
                         not a geodesic and would slip toward the small end"
                    .to_string(),
            }),
            (Layer::Helical(_), Mandrel::Tube { .. }) => Err(Error::OutOfRange {
                name: "layer",
                value: number as f64,
                expected: "a geodesic dome layer needs a vessel with polar openings (use a tube \
                           helical layer with a wind angle)",
            }),
            (Layer::TubeHelical(t), _) => {
                self.check_tube(number, t, radius)
                    .map(|(detail, m)| PlannedLayer {
                        mark: m,
                        pattern: None,
                        detail,
                    })
            }
            (&Layer::Hoop { passes }, _) => {
                if !(1..=2).contains(&passes) {
                    return Err(Error::OutOfRange {
                        name: "passes",
                        value: f64::from(passes),
                        expected: "a hoop layer has 1 or 2 passes",
                    });
                }
                positive("cylinder_length_mm", length)?;
                let turns = length / band;
                let beta = (TAU * radius).atan2(band);
                let eye_deg = if self.machine.axes.eye_rotation() {
                    90.0 - beta.to_degrees()
                } else {
                    0.0
                };
                let cross = self.machine.eye_radius_mm;
                let pass_len = length.hypot(TAU * radius * turns);
                Ok(PlannedLayer {
                    mark: mark(
                        LayerKind::Hoop,
                        0,
                        f64::from(passes) * pass_len,
                        beta.to_degrees(),
                    ),
                    pattern: None,
                    detail: Detail::Hoop {
                        passes,
                        start_mm: -length / 2.0,
                        end_mm: length / 2.0,
                        turn_per_pass_deg: turns * 360.0,
                        cross_feed_mm: cross,
                        eye_deg,
                    },
                })
            }
            (&Layer::Skip { mandrel_deg }, _) => {
                if !mandrel_deg.is_finite() {
                    return Err(Error::OutOfRange {
                        name: "mandrel_rotation_deg",
                        value: mandrel_deg,
                        expected: "must be finite",
                    });
                }
                Ok(PlannedLayer {
                    mark: mark(LayerKind::Skip, 0, 0.0, 0.0),
                    pattern: None,
                    detail: Detail::Skip { mandrel_deg },
                })
            }
        }
    }

    /// The forward stroke of a dome layer: its start (near pole station) and its points.
    fn dome_stroke(
        &self,
        layer: usize,
        radius: f64,
        polar: f64,
        pattern: &Pattern,
    ) -> Result<(StrokePoint, Vec<StrokePoint>), Error> {
        let re = self.machine.eye_radius_mm;
        let axes = self.machine.axes;
        let path = EyePath::on_circle(radius, polar, re).ok_or(Error::EyeInsideLaminate {
            layer,
            eye_radius_mm: re,
            winding_radius_mm: radius,
        })?;
        let at = |alpha: f64| -> Result<EyePoint, Error> {
            if axes.cross_feed() {
                Ok(path.dome(alpha))
            } else {
                path.dome_fixed_radius(alpha, re)
                    .ok_or(Error::EyeInsideLaminate {
                        layer,
                        eye_radius_mm: re,
                        winding_radius_mm: radius,
                    })
            }
        };
        let half = self.mandrel.length_mm() / 2.0;
        let star = path.split_alpha_rad();
        let n = self.machine.dome_steps;
        let grid = |from: f64, mid: f64, to: f64| {
            (1..=n)
                .map(move |i| from + (mid - from) * i as f64 / n as f64)
                .chain((1..=n).map(move |i| mid + (to - mid) * i as f64 / n as f64))
        };
        let eye = |p: &EyePoint| {
            if axes.eye_rotation() {
                p.rotation_rad.to_degrees()
            } else {
                0.0
            }
        };
        let first = at(PI / 2.0)?;
        let start = StrokePoint {
            mandrel_deg: 0.0,
            carriage_mm: -half - first.axial_mm,
            cross_feed_mm: first.radius_mm,
            eye_deg: eye(&first),
        };
        let mut points = Vec::with_capacity(4 * n + 1);
        let mut prev_angle = first.angle_rad;
        let mut turned = 0.0;
        // The mandrel turns against the eye's angle in the mandrel frame.
        let mut advance = |angle: f64| {
            let d = (angle - prev_angle + PI).rem_euclid(TAU) - PI;
            prev_angle = angle;
            turned -= d;
            turned.to_degrees()
        };
        for alpha in grid(PI / 2.0, PI / 2.0 + star, PI) {
            let p = at(alpha)?;
            points.push(StrokePoint {
                mandrel_deg: advance(p.angle_rad),
                carriage_mm: -half - p.axial_mm,
                cross_feed_mm: p.radius_mm,
                eye_deg: eye(&p),
            });
        }
        let arrive = at(0.0)?;
        let before_cylinder = points.last().map_or(0.0, |p| p.mandrel_deg);
        points.push(StrokePoint {
            mandrel_deg: before_cylinder + pattern.cylinder_angle_deg,
            carriage_mm: half + arrive.axial_mm,
            cross_feed_mm: arrive.radius_mm,
            eye_deg: eye(&arrive),
        });
        prev_angle = arrive.angle_rad;
        let base = before_cylinder + pattern.cylinder_angle_deg;
        let mut turned_far = 0.0f64;
        for alpha in grid(0.0, star, PI / 2.0) {
            let p = at(alpha)?;
            let d = (p.angle_rad - prev_angle + PI).rem_euclid(TAU) - PI;
            prev_angle = p.angle_rad;
            turned_far -= d;
            points.push(StrokePoint {
                mandrel_deg: base + turned_far.to_degrees(),
                carriage_mm: half + p.axial_mm,
                cross_feed_mm: p.radius_mm,
                eye_deg: eye(&p),
            });
        }
        Ok((start, points))
    }

    /// A polar layer: the plane, the slip check, the circuits and one circuit's eye stations.
    fn check_polar(
        &self,
        number: usize,
        slip_limit: f64,
        radius: f64,
        polar_radius_mm: f64,
    ) -> Result<PlannedLayer, Error> {
        if !(slip_limit >= 0.0 && slip_limit.is_finite()) {
            return Err(Error::OutOfRange {
                name: "slip_limit",
                value: slip_limit,
                expected: "must be ≥ 0",
            });
        }
        let length = self.mandrel.length_mm();
        if polar_radius_mm >= radius {
            return Err(Error::WindRule {
                layer: number,
                reason: format!(
                    "the polar opening {polar_radius_mm} mm must be smaller than the winding \
                     radius {radius:.3} mm"
                ),
            });
        }
        let plane = PolarPlane::new(radius, length, polar_radius_mm);
        let slip = plane.slip_ratio();
        if slip > slip_limit {
            return Err(Error::WindRule {
                layer: number,
                reason: format!(
                    "the polar plane at {:.4}° is not a geodesic on the domes: it needs a \
                     friction ratio of {slip:.4}, above the slip limit {slip_limit} (a shorter \
                     cylinder or a larger opening lowers it; seed 002 keeps in-plane winding to \
                     length-to-diameter ratios up to 1.8–2.0)",
                    plane.wind_angle_deg()
                ),
            });
        }
        let circuits_f = plane.circuits(self.tow.band_mm);
        if circuits_f > 1e7 {
            return Err(Error::WindRule {
                layer: number,
                reason: format!("{circuits_f} circuits is too many to wind"),
            });
        }
        let circuits = circuits_f as u32;
        let axes = self.machine.axes;
        let (a_u, a_w) = plane.eye_ellipse(
            self.machine.eye_radius_mm,
            axes.cross_feed(),
            polar_radius_mm,
        );
        let stations =
            plane
                .stations(a_u, a_w, axes.eye_rotation())
                .ok_or(Error::EyeInsideLaminate {
                    layer: number,
                    eye_radius_mm: self.machine.eye_radius_mm,
                    winding_radius_mm: radius,
                })?;
        Ok(PlannedLayer {
            mark: LayerMark {
                number,
                kind: LayerKind::Polar,
                circuits: u64::from(circuits),
                tow_length_mm: f64::from(circuits) * plane.circuit_length_mm(),
                winding_radius_mm: radius,
                wind_angle_deg: plane.wind_angle_deg(),
            },
            pattern: None,
            detail: Detail::Polar {
                circuits,
                advance_deg: 360.0 / f64::from(circuits),
                stations,
            },
        })
    }

    /// A helical layer on a tube, cone or nose: the format's rules, the circuits that cover the
    /// surface in whole patterns, the lock that steps through every slot, then the layer's passes
    /// and the tow it lays.
    fn check_tube(
        &self,
        number: usize,
        t: &TubeHelical,
        radius: f64,
    ) -> Result<(Detail, LayerMark), Error> {
        let length = self.mandrel.length_mm();
        self.check_tube_rules(number, t, length)?;
        let geodesic = self.cone_geodesic(number, t, radius, length)?;
        let nose_pass = match self.mandrel {
            Mandrel::VonKarman {
                base_radius_mm,
                length_mm,
            } => Some(self.nose_pass(number, t, radius, base_radius_mm, length_mm)?),
            _ => None,
        };
        let circuits = tube_circuits(number, t, radius, self.tow.band_mm)?;
        check_lock_stride(number, t)?;
        if let Some((pass, stations)) = nose_pass {
            return Ok(nose_layer(
                number,
                t,
                circuits,
                radius,
                length,
                &pass,
                stations,
                self.machine.eye_radius_mm,
            ));
        }
        Ok(self.tube_layer(number, t, circuits, radius, length, geodesic))
    }

    /// The helical layer's own figures: the angle, the lock, lead-in and lead-out, the friction
    /// (a nose only, within the slip limit), the pattern and skip (coprime), a lead-in shorter
    /// than the wound length.
    fn check_tube_rules(&self, number: usize, t: &TubeHelical, length: f64) -> Result<(), Error> {
        let reject = |reason: String| Error::WindRule {
            layer: number,
            reason,
        };
        positive("cylinder_length_mm", length)?;
        if !(1.0..=89.0).contains(&t.wind_angle_deg) {
            return Err(reject(format!(
                "wind angle {}° is outside 1°..=89°",
                t.wind_angle_deg
            )));
        }
        for (name, v) in [
            ("lock_deg", t.lock_deg),
            ("lead_in_mm", t.lead_in_mm),
            ("lead_out_deg", t.lead_out_deg),
        ] {
            positive(name, v)?;
        }
        if !(t.friction_lambda >= 0.0 && t.friction_lambda.is_finite()) {
            return Err(reject(format!(
                "frictionLambda = {} must be ≥ 0 (0 winds the geodesic)",
                t.friction_lambda
            )));
        }
        let nose = matches!(self.mandrel, Mandrel::VonKarman { .. });
        if t.friction_lambda != 0.0 && !nose {
            return Err(reject(format!(
                "frictionLambda = {}: a cylinder or cone is wound on its geodesic, set it to 0 \
                 (friction paths are planned on a nose profile only)",
                t.friction_lambda
            )));
        }
        if t.friction_lambda > NOSE_SLIP_LIMIT {
            return Err(reject(format!(
                "frictionLambda {} exceeds the machine slip limit {NOSE_SLIP_LIMIT}: the tow \
                 would slip",
                t.friction_lambda
            )));
        }
        if t.pattern_number == 0 || t.skip_index == 0 {
            return Err(reject(
                "pattern number and skip index must be ≥ 1".to_string(),
            ));
        }
        if t.skip_index >= t.pattern_number {
            return Err(reject(format!(
                "skip index {} must be smaller than the pattern number {}",
                t.skip_index, t.pattern_number
            )));
        }
        if gcd(t.skip_index, t.pattern_number) != 1 {
            return Err(reject(format!(
                "skip index {} and pattern number {} share a factor, so the circuits of a \
                 pattern land on the same slots and leave gaps",
                t.skip_index, t.pattern_number
            )));
        }
        if t.lead_in_mm >= length {
            return Err(reject(format!(
                "lead-in {} mm must be shorter than the wound length {length} mm",
                t.lead_in_mm
            )));
        }
        Ok(())
    }

    /// On a cone, the geodesic the layer winds: on the large end's radius grown by the laminate
    /// below; the small end grows by the same. `None` on a tube or nose.
    fn cone_geodesic(
        &self,
        number: usize,
        t: &TubeHelical,
        radius: f64,
        length: f64,
    ) -> Result<Option<ConeGeodesic>, Error> {
        let reject = |reason: String| Error::WindRule {
            layer: number,
            reason,
        };
        Ok(match self.mandrel {
            Mandrel::Cone {
                large_radius_mm,
                small_radius_mm,
                ..
            } => {
                let small = small_radius_mm + (radius - large_radius_mm);
                Some(
                    ConeGeodesic::new(radius, small, length, t.wind_angle_deg).map_err(
                        |e| match e {
                            ConeRefusal::NotReducing => reject(format!(
                                "the cone must be a reducing frustum: the far end's radius \
                                 {small} mm is not below the near end's {radius} mm (mount the \
                                 large end at the start)"
                            )),
                            ConeRefusal::TooSteep {
                                clairaut_mm,
                                steepest_deg,
                            } => reject(format!(
                                "wind angle {}° is too steep for the cone: its geodesic \
                                 (r·sin α = {clairaut_mm:.4} mm) turns back before the small \
                                 end of radius {small} mm; at most {steepest_deg:.4}° reaches it",
                                t.wind_angle_deg
                            )),
                        },
                    )?,
                )
            }
            _ => None,
        })
    }

    /// The passes of a helical layer of `circuits` on a tube (a helix) or cone (its geodesic):
    /// the turnaround that brings each pass to the lock, and the tow laid.
    fn tube_layer(
        &self,
        number: usize,
        t: &TubeHelical,
        circuits: u32,
        radius: f64,
        length: f64,
        geodesic: Option<ConeGeodesic>,
    ) -> (Detail, LayerMark) {
        let alpha = t.wind_angle_deg.to_radians();
        let circumference = TAU * radius;
        let deg_per_mm = (length * alpha.tan() / circumference * 360.0) / length;
        let pass_deg = match &geodesic {
            Some(g) => g.turn_deg(length),
            None => deg_per_mm * length,
        };
        // Smallest turn at the end of a pass, not less than the lead-out, that brings the pass's
        // advance to the lock (mod 360°): the mandrel never turns back.
        let mut turnaround = (t.lock_deg - pass_deg).rem_euclid(360.0);
        while turnaround < t.lead_out_deg - 1e-9 {
            turnaround += 360.0;
        }
        let passes = 2.0 * f64::from(circuits);
        let patterns = f64::from(circuits / t.pattern_number);
        let total_turn = if t.initial_lock { 2.0 } else { 1.0 } * t.lock_deg
            + passes * (pass_deg + turnaround)
            + f64::from(circuits) * f64::from(t.skip_index) * 360.0 / f64::from(t.pattern_number)
            + patterns * 360.0 / f64::from(circuits);
        let end_turns_deg = total_turn - passes * pass_deg;
        let (laid, pass) = match geodesic {
            None => (
                passes * length.hypot(radius * pass_deg.to_radians())
                    + radius * end_turns_deg.to_radians(),
                Pass::Helix { deg_per_mm },
            ),
            // The turnaround after each outward pass wraps the small end; every other end turn
            // (the locks, the return turnarounds, the skips and steps) the large end.
            Some(g) => {
                let small_end_deg = f64::from(circuits) * turnaround;
                (
                    passes * g.length_mm()
                        + g.small_radius_mm() * small_end_deg.to_radians()
                        + radius * (end_turns_deg - small_end_deg).to_radians(),
                    Pass::Geodesic(g.stations(&[t.lead_in_mm, length - t.lead_in_mm])),
                )
            }
        };
        (
            Detail::Tube {
                layer: *t,
                circuits,
                half_length_mm: length / 2.0,
                pass,
                turnaround_deg: turnaround,
                cross_feed_mm: self.machine.eye_radius_mm,
            },
            LayerMark {
                number,
                kind: LayerKind::Helical,
                circuits: u64::from(circuits),
                tow_length_mm: laid,
                winding_radius_mm: radius,
                wind_angle_deg: t.wind_angle_deg,
            },
        )
    }
}

impl Job {
    /// A nose layer's pass, traced and checked: from the base past the lead-in to a turnaround.
    fn nose_pass(
        &self,
        number: usize,
        t: &TubeHelical,
        radius: f64,
        base_radius_mm: f64,
        length_mm: f64,
    ) -> Result<(NosePass, Vec<cone::Station>), Error> {
        let reject = |reason: String| Error::WindRule {
            layer: number,
            reason,
        };
        if radius != base_radius_mm {
            return Err(reject(
                "layer build-up on a nose profile is not planned (the surface would be an \
                 offset of the ogive)"
                    .to_string(),
            ));
        }
        let ogive = VonKarman {
            base_radius_mm,
            length_mm,
        };
        let pass = NosePass::trace(&ogive, t.wind_angle_deg, t.friction_lambda, &[t.lead_in_mm])
            .map_err(|e| match e {
                NoseRefusal::ReachesTip { .. } => reject(format!(
                    "wind angle {}° with frictionLambda {}: {e}; a pass must turn around on a \
                     radius above {:.4} mm ({}% of the base radius; the geodesic turns at the \
                     base radius times sin α, {:.4} mm): raise the wind angle",
                    t.wind_angle_deg,
                    t.friction_lambda,
                    nose::TIP_FRACTION * base_radius_mm,
                    nose::TIP_FRACTION * 100.0,
                    base_radius_mm * t.wind_angle_deg.to_radians().sin(),
                )),
                e => reject(format!(
                    "wind angle {}° with frictionLambda {}: {e}",
                    t.wind_angle_deg, t.friction_lambda
                )),
            })?;
        let end = pass.turnaround();
        if end.along_mm <= t.lead_in_mm {
            // The geodesic turns at r = R·sin α: past the lead-in only while R·sin α < r(lead-in).
            let steepest = (ogive.radius_at(t.lead_in_mm) / base_radius_mm)
                .asin()
                .to_degrees();
            return Err(reject(format!(
                "wind angle {}° has no usable pass: its path turns around {:.3} mm from the base \
                 (radius {:.3} mm), within the {} mm lead-in; the geodesic turns around past the \
                 lead-in only below {steepest:.4}°",
                t.wind_angle_deg, end.along_mm, end.radius_mm, t.lead_in_mm
            )));
        }
        let stations = pass.stations(&ogive);
        Ok((pass, stations))
    }
}

/// A nose layer from its traced pass: circuits counted on the base's parallel; all end turns
/// at the base (the pass turns back by itself at its turnaround, [`nose`]).
#[allow(clippy::too_many_arguments)]
fn nose_layer(
    number: usize,
    t: &TubeHelical,
    circuits: u32,
    radius: f64,
    length: f64,
    pass: &NosePass,
    stations: Vec<cone::Station>,
    cross: f64,
) -> (Detail, LayerMark) {
    let pass_deg = pass.turn_deg();
    // Smallest turn at the base after a circuit (out and back), not less than the lead-out,
    // that brings the circuit's advance to twice the lock (mod 360°), as on a tube or cone.
    let mut base_turn = (2.0 * t.lock_deg - 2.0 * pass_deg).rem_euclid(360.0);
    while base_turn < t.lead_out_deg - 1e-9 {
        base_turn += 360.0;
    }
    let patterns = f64::from(circuits / t.pattern_number);
    let end_turns_deg = if t.initial_lock { 2.0 } else { 1.0 } * t.lock_deg
        + f64::from(circuits) * base_turn
        + f64::from(circuits) * f64::from(t.skip_index) * 360.0 / f64::from(t.pattern_number)
        + patterns * 360.0 / f64::from(circuits);
    let laid = 2.0 * f64::from(circuits) * pass.length_mm() + radius * end_turns_deg.to_radians();
    (
        Detail::Nose {
            layer: *t,
            circuits,
            half_length_mm: length / 2.0,
            stations,
            base_turn_deg: base_turn,
            cross_feed_mm: cross,
        },
        LayerMark {
            number,
            kind: LayerKind::Helical,
            circuits: u64::from(circuits),
            tow_length_mm: laid,
            winding_radius_mm: radius,
            wind_angle_deg: t.wind_angle_deg,
        },
    )
}

fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// The circuits of a helical layer at `radius`: enough bands of `band_mm` (across the fibre) to
/// cover the circumference, in whole patterns.
fn tube_circuits(number: usize, t: &TubeHelical, radius: f64, band_mm: f64) -> Result<u32, Error> {
    let reject = |reason: String| Error::WindRule {
        layer: number,
        reason,
    };
    let alpha = t.wind_angle_deg.to_radians();
    let circumference = TAU * radius;
    let arc = band_mm / alpha.cos();
    let circuits_f = (circumference / arc - 1e-9).ceil();
    if circuits_f > 1e7 {
        return Err(reject(format!("{circuits_f} circuits is too many to wind")));
    }
    let circuits = circuits_f as u32;
    if !circuits.is_multiple_of(t.pattern_number) {
        let near: Vec<String> = (1..=circuits)
            .filter(|p| circuits.is_multiple_of(*p))
            .map(|p| p.to_string())
            .collect();
        return Err(reject(format!(
            "{circuits} circuits (at radius {radius:.3} mm) do not divide into patterns of {}; \
             pattern numbers that divide them: {}",
            t.pattern_number,
            near.join(", ")
        )));
    }
    Ok(circuits)
}

/// With more than one pattern slot, the lock must turn each circuit by a whole number of slots
/// that, with the skip, steps through all of them.
fn check_lock_stride(number: usize, t: &TubeHelical) -> Result<(), Error> {
    if t.pattern_number <= 1 {
        return Ok(());
    }
    let slot = 360.0 / f64::from(t.pattern_number);
    let per_circuit = (2.0 * t.lock_deg).rem_euclid(360.0);
    let slots = per_circuit / slot;
    let stride_ok = (slots - slots.round()).abs() < 1e-6 && {
        let j = (slots.round() as u64 + u64::from(t.skip_index)) % u64::from(t.pattern_number);
        gcd(j as u32, t.pattern_number) == 1
    };
    if stride_ok {
        return Ok(());
    }
    let valid: Vec<String> = nearest_locks(t, slot)
        .into_iter()
        .map(|v| format!("{v}°"))
        .collect();
    Err(Error::WindRule {
        layer: number,
        reason: format!(
            "lock {}° turns a circuit by {per_circuit}° (mod 360°), which does not step \
             through all {} slots of {slot}°; nearest valid locks: {}",
            t.lock_deg,
            t.pattern_number,
            valid.join(", ")
        ),
    })
}

/// Up to three locks nearest the requested one that step through every slot.
fn nearest_locks(t: &TubeHelical, slot: f64) -> Vec<f64> {
    let half = slot / 2.0;
    let centre = (t.lock_deg / half).round() as i64;
    let mut found: Vec<f64> = (0..64i64)
        .flat_map(|d| [centre + d, centre - d])
        .filter(|&k| k > 0)
        .map(|k| k as f64 * half)
        .filter(|&v| {
            let slots = ((2.0 * v).rem_euclid(360.0) / slot).round() as u64;
            let j = (slots + u64::from(t.skip_index)) % u64::from(t.pattern_number);
            gcd(j as u32, t.pattern_number) == 1
        })
        .collect();
    found.dedup();
    found.truncate(3);
    found
}

/// Emits moves from a position, computing each feed move's nominal duration.
struct Cursor<'a, S: MotionSink> {
    sink: &'a mut S,
    at: Axes,
    limits: Limits,
}

impl<S: MotionSink> Cursor<'_, S> {
    fn go(&mut self, kind: MoveKind, to: Axes) -> Result<(), S::Error> {
        let a = to.to_array();
        let b = self.at.to_array();
        let delta = [a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3]];
        if delta.iter().all(|d| *d == 0.0) {
            return Ok(());
        }
        let duration_s = match kind {
            MoveKind::Feed => self.limits.duration_s(delta),
            MoveKind::Rapid => 0.0,
        };
        self.sink.motion(&Move {
            kind,
            to,
            duration_s,
        })?;
        self.at = to;
        Ok(())
    }

    fn feed(&mut self, to: Axes) -> Result<(), S::Error> {
        self.go(MoveKind::Feed, to)
    }

    /// Feed to a layer's start; a rapid if nothing has moved yet (the tow is tied on after);
    /// with a lock turn if the carriage moves by more than `band_mm`.
    fn approach(&mut self, to: Axes, first: bool, band_mm: f64) -> Result<(), S::Error> {
        if first {
            return self.go(
                MoveKind::Rapid,
                Axes {
                    mandrel_deg: self.at.mandrel_deg,
                    ..to
                },
            );
        }
        let turn = if (to.carriage_mm - self.at.carriage_mm).abs() > band_mm {
            TRANSITION_TURN_DEG
        } else {
            0.0
        };
        self.feed(Axes {
            mandrel_deg: self.at.mandrel_deg + turn,
            ..to
        })
    }
}

impl Plan {
    /// Where every plan starts: all axes at zero (the mandrel's phase is arbitrary; the first
    /// move is a rapid of the other axes to the first layer's start).
    pub fn start(&self) -> Axes {
        Axes::default()
    }

    /// The machine's limits.
    pub fn limits(&self) -> Limits {
        self.limits
    }

    /// Streams the plan into `sink`: a layer mark, then the layer's moves, for each layer.
    pub fn emit<S: MotionSink>(&self, sink: &mut S) -> Result<(), S::Error> {
        let mut c = Cursor {
            sink,
            at: self.start(),
            limits: self.limits,
        };
        for (i, layer) in self.layers.iter().enumerate() {
            c.sink.layer(&layer.mark)?;
            let first = i == 0;
            match &layer.detail {
                Detail::Dome {
                    pattern,
                    start,
                    stroke,
                } => emit_dome(&mut c, pattern, start, stroke, first)?,
                &Detail::Hoop {
                    passes,
                    start_mm,
                    end_mm,
                    turn_per_pass_deg,
                    cross_feed_mm,
                    eye_deg,
                } => {
                    // Start from the end nearer the carriage.
                    let forward =
                        (c.at.carriage_mm - start_mm).abs() <= (c.at.carriage_mm - end_mm).abs();
                    let (mut from, mut to) = if forward {
                        (start_mm, end_mm)
                    } else {
                        (end_mm, start_mm)
                    };
                    let band = (end_mm - start_mm).abs() / (turn_per_pass_deg / 360.0);
                    let sign = |a: f64, b: f64| if b > a { 1.0 } else { -1.0 };
                    c.approach(
                        Axes {
                            mandrel_deg: c.at.mandrel_deg,
                            carriage_mm: from,
                            cross_feed_mm,
                            eye_deg: sign(from, to) * eye_deg,
                        },
                        first,
                        band,
                    )?;
                    for _ in 0..passes {
                        let e = sign(from, to) * eye_deg;
                        if c.at.eye_deg != e {
                            c.feed(Axes { eye_deg: e, ..c.at })?;
                        }
                        c.feed(Axes {
                            mandrel_deg: c.at.mandrel_deg + turn_per_pass_deg,
                            carriage_mm: to,
                            cross_feed_mm,
                            eye_deg: e,
                        })?;
                        std::mem::swap(&mut from, &mut to);
                    }
                }
                Detail::Tube {
                    layer: t,
                    circuits,
                    half_length_mm,
                    pass,
                    turnaround_deg,
                    cross_feed_mm,
                } => emit_tube(
                    &mut c,
                    t,
                    *circuits,
                    *half_length_mm,
                    pass,
                    *turnaround_deg,
                    *cross_feed_mm,
                    first,
                )?,
                Detail::Nose {
                    layer: t,
                    circuits,
                    half_length_mm,
                    stations,
                    base_turn_deg,
                    cross_feed_mm,
                } => emit_nose(
                    &mut c,
                    t,
                    *circuits,
                    *half_length_mm,
                    stations,
                    *base_turn_deg,
                    *cross_feed_mm,
                    first,
                )?,
                Detail::Polar {
                    circuits,
                    advance_deg,
                    stations,
                } => {
                    let base = c.at.mandrel_deg;
                    let at = |k: u32, s: &PolarStation| Axes {
                        mandrel_deg: base
                            + f64::from(k) * (360.0 + advance_deg)
                            + s.mandrel_deg
                            + s.fraction * advance_deg,
                        carriage_mm: s.carriage_mm,
                        cross_feed_mm: s.cross_feed_mm,
                        eye_deg: s.eye_deg,
                    };
                    let start = at(0, &stations[0]);
                    c.approach(
                        Axes {
                            mandrel_deg: c.at.mandrel_deg,
                            ..start
                        },
                        first,
                        f64::INFINITY,
                    )?;
                    for k in 0..*circuits {
                        for s in &stations[1..] {
                            c.feed(at(k, s))?;
                        }
                    }
                }
                &Detail::Skip { mandrel_deg } => {
                    c.feed(Axes {
                        mandrel_deg: c.at.mandrel_deg + mandrel_deg,
                        ..c.at
                    })?;
                }
            }
        }
        Ok(())
    }
}

fn emit_dome<S: MotionSink>(
    c: &mut Cursor<'_, S>,
    pattern: &Pattern,
    start: &StrokePoint,
    stroke: &[StrokePoint],
    first: bool,
) -> Result<(), S::Error> {
    c.approach(
        Axes {
            mandrel_deg: c.at.mandrel_deg,
            carriage_mm: start.carriage_mm,
            cross_feed_mm: start.cross_feed_mm,
            eye_deg: start.eye_deg,
        },
        first,
        f64::INFINITY,
    )?;
    let n = pattern.cycles_per_pattern();
    let last = stroke.len() - 1;
    for _ in 0..pattern.patterns_per_layer {
        for cycle in 0..n {
            for dir in [1.0, -1.0] {
                let base = c.at.mandrel_deg;
                for (i, p) in stroke.iter().enumerate() {
                    let extra = if i == last {
                        pattern.dwell_deg
                            + if dir < 0.0 && cycle + 1 == n {
                                pattern.advance_deg
                            } else {
                                0.0
                            }
                    } else {
                        0.0
                    };
                    c.feed(Axes {
                        mandrel_deg: base + p.mandrel_deg + extra,
                        carriage_mm: dir * p.carriage_mm,
                        cross_feed_mm: p.cross_feed_mm,
                        eye_deg: dir * p.eye_deg,
                    })?;
                }
            }
        }
    }
    Ok(())
}

/// One pass along a cone's geodesic: outward (`dir` 1) from the large end at `-half`, or back
/// (`dir` −1) from the small end. The mandrel turns by the geodesic's turn between stations;
/// the eye swings from 0 to the local lay angle `90° − α(z)` over the lead-in (as on the tube)
/// and then follows it.
fn emit_geodesic_pass<S: MotionSink>(
    c: &mut Cursor<'_, S>,
    stations: &[cone::Station],
    dir: f64,
    half: f64,
    lead_in_mm: f64,
    cross: f64,
) -> Result<(), S::Error> {
    let length = 2.0 * half;
    let base = c.at.mandrel_deg;
    let total = stations.last().map_or(0.0, |s| s.turn_deg);
    let lay = |s: &cone::Station, c: &mut Cursor<'_, S>| {
        let (travelled, turned) = if dir > 0.0 {
            (s.along_mm, s.turn_deg)
        } else {
            (length - s.along_mm, total - s.turn_deg)
        };
        let swing = (travelled / lead_in_mm).min(1.0);
        c.feed(Axes {
            mandrel_deg: base + turned,
            carriage_mm: -half + s.along_mm,
            cross_feed_mm: cross,
            eye_deg: dir * swing * (90.0 - s.wind_angle_deg),
        })
    };
    if dir > 0.0 {
        stations[1..].iter().try_for_each(|s| lay(s, c))
    } else {
        stations[..stations.len() - 1]
            .iter()
            .rev()
            .try_for_each(|s| lay(s, c))
    }
}

/// The start of a tube, cone or nose layer: the approach to the near end (carriage at `−half`,
/// the eye at 0) and, if the layer asks for it, the lock turn there before the first pass.
fn begin_tube_layer<S: MotionSink>(
    c: &mut Cursor<'_, S>,
    t: &TubeHelical,
    half: f64,
    cross: f64,
    first: bool,
) -> Result<(), S::Error> {
    c.approach(
        Axes {
            mandrel_deg: c.at.mandrel_deg,
            carriage_mm: -half,
            cross_feed_mm: cross,
            eye_deg: 0.0,
        },
        first,
        f64::INFINITY,
    )?;
    if t.initial_lock {
        c.feed(Axes {
            mandrel_deg: c.at.mandrel_deg + t.lock_deg,
            ..c.at
        })?;
    }
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn emit_tube<S: MotionSink>(
    c: &mut Cursor<'_, S>,
    t: &TubeHelical,
    circuits: u32,
    half: f64,
    pass: &Pass,
    turnaround: f64,
    cross: f64,
    first: bool,
) -> Result<(), S::Error> {
    let lay_eye = 90.0 - t.wind_angle_deg;
    begin_tube_layer(c, t, half, cross, first)?;
    let mut pending = 0.0;
    let slot = 360.0 / f64::from(t.pattern_number);
    let step = 360.0 / f64::from(circuits);
    let length = 2.0 * half;
    for _ in 0..circuits / t.pattern_number {
        for _ in 0..t.pattern_number {
            for dir in [1.0, -1.0] {
                let (from, to) = (-dir * half, dir * half);
                if pending != 0.0 {
                    c.feed(Axes {
                        mandrel_deg: c.at.mandrel_deg + pending,
                        carriage_mm: from,
                        cross_feed_mm: cross,
                        eye_deg: 0.0,
                    })?;
                    pending = 0.0;
                }
                match pass {
                    &Pass::Helix { deg_per_mm } => {
                        c.feed(Axes {
                            mandrel_deg: c.at.mandrel_deg + deg_per_mm * t.lead_in_mm,
                            carriage_mm: from + dir * t.lead_in_mm,
                            cross_feed_mm: cross,
                            eye_deg: dir * lay_eye,
                        })?;
                        c.feed(Axes {
                            mandrel_deg: c.at.mandrel_deg + deg_per_mm * (length - t.lead_in_mm),
                            carriage_mm: to,
                            ..c.at
                        })?;
                    }
                    Pass::Geodesic(stations) => {
                        emit_geodesic_pass(c, stations, dir, half, t.lead_in_mm, cross)?
                    }
                }
                c.feed(Axes {
                    mandrel_deg: c.at.mandrel_deg + t.lead_out_deg,
                    eye_deg: 0.0,
                    ..c.at
                })?;
                pending += turnaround - t.lead_out_deg;
            }
            pending += f64::from(t.skip_index) * slot;
        }
        pending += step;
    }
    c.feed(Axes {
        mandrel_deg: c.at.mandrel_deg + pending + t.lock_deg,
        ..c.at
    })?;
    Ok(())
}

/// A nose layer: each circuit runs out from the base along the stations to the turnaround
/// and back along their mirror image (the same turn again, the eye through 0 at the
/// turnaround, where the fibre lies along the parallel), then turns at the base: the lead-out
/// (the eye back to 0), the rest of the base turn, the pattern's skip and, after each pattern,
/// the step. The eye swings to the lay angle `90° − α(z)` over the lead-in, as on a cone.
#[allow(clippy::too_many_arguments)]
fn emit_nose<S: MotionSink>(
    c: &mut Cursor<'_, S>,
    t: &TubeHelical,
    circuits: u32,
    half: f64,
    stations: &[cone::Station],
    base_turn: f64,
    cross: f64,
    first: bool,
) -> Result<(), S::Error> {
    begin_tube_layer(c, t, half, cross, first)?;
    let pass = stations.last().map_or(0.0, |s| s.turn_deg);
    let slot = 360.0 / f64::from(t.pattern_number);
    let step = 360.0 / f64::from(circuits);
    let mut pending = 0.0;
    for _ in 0..circuits / t.pattern_number {
        for _ in 0..t.pattern_number {
            if pending != 0.0 {
                c.feed(Axes {
                    mandrel_deg: c.at.mandrel_deg + pending,
                    ..c.at
                })?;
                pending = 0.0;
            }
            let base = c.at.mandrel_deg;
            for s in &stations[1..] {
                let swing = (s.along_mm / t.lead_in_mm).min(1.0);
                c.feed(Axes {
                    mandrel_deg: base + s.turn_deg,
                    carriage_mm: -half + s.along_mm,
                    cross_feed_mm: cross,
                    eye_deg: swing * (90.0 - s.wind_angle_deg),
                })?;
            }
            for s in stations[..stations.len() - 1].iter().rev() {
                c.feed(Axes {
                    mandrel_deg: base + 2.0 * pass - s.turn_deg,
                    carriage_mm: -half + s.along_mm,
                    cross_feed_mm: cross,
                    eye_deg: -(90.0 - s.wind_angle_deg),
                })?;
            }
            c.feed(Axes {
                mandrel_deg: c.at.mandrel_deg + t.lead_out_deg,
                eye_deg: 0.0,
                ..c.at
            })?;
            pending += base_turn - t.lead_out_deg + f64::from(t.skip_index) * slot;
        }
        pending += step;
    }
    c.feed(Axes {
        mandrel_deg: c.at.mandrel_deg + pending + t.lock_deg,
        ..c.at
    })?;
    Ok(())
}

#[cfg(test)]
mod tests;
