//! Where the fibre lands: the placement model behind the prediction of a winding's error (seed 001
//! §6.2, the "bow" between the desired and the wound path).
//!
//! The planner works forwards: for a desired surface point it finds the mandrel angle at which the
//! robot sees the point on the tangent (eq 3.7) and puts the eye on the tow line (eqs 3.8–3.14).
//! This module works backwards: given where the eye really is and how the mandrel really turns over
//! time, it finds where the fibre touches the mandrel. The laid path is the locus of those contact
//! points, in the mandrel frame.
//!
//! # The contact model
//! The free fibre runs straight from the contact point `C` on the surface to the eye `E`
//! (both in the mandrel frame) and leaves the surface tangentially: `(E − C)·n(C) = 0`, `n` the
//! outward normal. The fibre does not slip on the resin-wet surface, so the laid fibre at `C` points
//! along the free fibre: the contact moves along `d = E − C`, `Ċ = λ d`. Differentiating the
//! tangency condition, with `W = ∂n/∂C` the shape operator and `Ċ·n = 0`:
//!
//! ```text
//! Ė·n + λ dᵀ W d = 0    ⇒    λ = −Ė·n / (dᵀ W d)
//! ```
//!
//! `dᵀ W d = −II(d)` is the normal curvature along `d` times `|d|²` (positive on a convex
//! surface). When `λ` would be negative the eye is moving out of the tangent plane: the fibre
//! would have to unwind, but laid fibre sticks to the resin, so the contact stays where it is and
//! the free fibre pivots about it until the eye comes back to the tangent plane (`(E − C)·n ≤ 0`).
//!
//! On an analytic tube ([`Tube`]) the contact is integrated in the surface parameters `(u, v)` by
//! fourth-order Runge–Kutta, and after each step it is put back onto the tangency condition by one
//! Newton step along `d`, so the integration cannot drift off the silhouette.
//!
//! # Frames
//! Everything here is in the **mandrel frame** ([`crate::mandrel`]). [`to_mandrel_frame`] turns a
//! cell-frame eye position and velocity and the mandrel angle and rate into mandrel-frame ones,
//! with the cell frame of [`crate::plan`]: `p_cell = origin + R_z(φ) p_mandrel`.

#[cfg(test)]
use nalgebra::Matrix2;
use nalgebra::{Point3, Vector2, Vector3};

use crate::calibration::CellTransform;
use crate::mandrel::{ContactFrame, FrameHints};
use crate::mesh::trace::Tracer;
use crate::{Error, Tube};

/// The eye's position and velocity in the mandrel frame at time `t_s`.
pub trait EyeTrack {
    /// Eye position (mm) and velocity (mm/s), mandrel frame, at `t_s`.
    fn at(&self, t_s: f64) -> (Point3<f64>, Vector3<f64>);
}

impl<F: Fn(f64) -> (Point3<f64>, Vector3<f64>)> EyeTrack for F {
    fn at(&self, t_s: f64) -> (Point3<f64>, Vector3<f64>) {
        self(t_s)
    }
}

/// Turns an eye position and velocity in the cell frame, and the mandrel angle `phi_rad` and its
/// rate `phi_rate_rad_s`, into the mandrel frame: `p_m = R_z(−φ)(p − origin)`,
/// `ṗ_m = R_z(−φ) ṗ − φ̇ ẑ × p_m`.
pub fn to_mandrel_frame(
    origin_mm: &Vector3<f64>,
    eye_mm: &Point3<f64>,
    eye_velocity_mm_s: &Vector3<f64>,
    phi_rad: f64,
    phi_rate_rad_s: f64,
) -> (Point3<f64>, Vector3<f64>) {
    rotated_to_mandrel_frame(
        origin_mm,
        eye_mm,
        eye_velocity_mm_s,
        phi_rad.sin_cos(),
        phi_rate_rad_s,
    )
}

/// [`to_mandrel_frame`] with `(sin φ, cos φ)` given.
fn rotated_to_mandrel_frame(
    origin_mm: &Vector3<f64>,
    eye_mm: &Point3<f64>,
    eye_velocity_mm_s: &Vector3<f64>,
    (s, c): (f64, f64),
    phi_rate_rad_s: f64,
) -> (Point3<f64>, Vector3<f64>) {
    let rel = eye_mm - origin_mm;
    let p = Point3::new(c * rel.x + s * rel.y, -s * rel.x + c * rel.y, rel.z);
    let v = eye_velocity_mm_s;
    let v_rot = Vector3::new(c * v.x + s * v.y, -s * v.x + c * v.y, v.z);
    let v_m = v_rot - Vector3::new(-p.y, p.x, 0.0) * phi_rate_rad_s;
    (p, v_m)
}

/// Whether the fibre is being laid or pivots about its last contact.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ContactState {
    /// The free fibre is tangent at the contact, which moves along the surface.
    Wrapping,
    /// The eye has left the tangent plane: the contact stays, the free fibre pivots about it.
    Pivoting,
}

/// The fibre's contact with an analytic tube, advanced in time.
#[derive(Debug, Clone)]
pub struct TubeContact<'a> {
    tube: &'a Tube,
    u: f64,
    v: f64,
    t_s: f64,
    state: ContactState,
    /// The surface where the last step ended (the bits of `(u, v)` beside it): the contact
    /// point asked for after a step, and where the next step starts.
    start: Option<([u64; 2], ContactFrame)>,
    /// Where the last surface was evaluated, for the next ([`Tube::contact_frame`]).
    hints: FrameHints,
    /// Tests: the contact geometry from [`Tube::surface`]'s vectors and the general
    /// first and second fundamental forms (the method before [`Tube::contact_frame`]).
    #[cfg(test)]
    general: bool,
}

/// The eye's position and velocity at a time, carried from the end of one step to the start
/// of the next (the same instant).
type EyeAt = Option<(f64, (Point3<f64>, Vector3<f64>))>;

#[cfg(test)]
thread_local! {
    /// Tests: contacts made on this thread use the general geometry ([`TubeContact::general`]).
    static GENERAL: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Contact geometry at one `(u, v)` for an eye at `e` moving at `e_dot`.
struct Local {
    /// `(u̇, v̇)` while wrapping, before the `λ ≥ 0` rule.
    rate_per_lambda: Vector2<f64>,
    /// `λ` of the module doc (may be negative).
    lambda: f64,
    /// Tangency residual `(E − C)·n`, mm.
    residual_mm: f64,
    /// `dᵀ W d`, the curvature term, mm.
    curvature_mm: f64,
}

impl<'a> TubeContact<'a> {
    /// Starts at surface parameters `(u, v)` (height of the spine point and angle around it, see
    /// [`crate::mandrel`]) at time `t_s`, wrapping.
    pub fn new(tube: &'a Tube, u: f64, v: f64, t_s: f64) -> Self {
        TubeContact {
            tube,
            u,
            v,
            t_s,
            state: ContactState::Wrapping,
            start: None,
            hints: FrameHints::default(),
            #[cfg(test)]
            general: GENERAL.get(),
        }
    }

    /// The contact point, mandrel frame.
    pub fn point(&self) -> Point3<f64> {
        match self.start_surface() {
            Some(s) => s.point,
            None => self.tube.point(self.u, self.v),
        }
    }

    /// Where the contact is: `(u, v, t_s, state)` (its remembered surface stays valid: it is
    /// keyed by `(u, v)`).
    fn position(&self) -> (f64, f64, f64, ContactState) {
        (self.u, self.v, self.t_s, self.state)
    }

    /// Puts the contact back where [`TubeContact::position`] found it.
    fn set_position(&mut self, (u, v, t_s, state): (f64, f64, f64, ContactState)) {
        (self.u, self.v, self.t_s, self.state) = (u, v, t_s, state);
    }

    /// The surface at the contact, when the last step left it there.
    fn start_surface(&self) -> Option<&ContactFrame> {
        self.start
            .as_ref()
            .filter(|(at, _)| *at == [self.u.to_bits(), self.v.to_bits()])
            .map(|(_, s)| s)
    }

    /// The surface parameters `(u, v)` of the contact.
    pub fn parameters(&self) -> (f64, f64) {
        (self.u, self.v)
    }

    /// The time the contact was last advanced to, s.
    pub fn time_s(&self) -> f64 {
        self.t_s
    }

    /// Whether the fibre is being laid or pivoting.
    pub fn state(&self) -> ContactState {
        self.state
    }

    /// Holds the contact where it is until `t_s` (the free fibre pivots about it): how
    /// [`lay_on_tube`] passes a stretch where the fibre would bridge a concave part of the surface.
    pub fn hold_until(&mut self, t_s: f64) {
        if t_s > self.t_s {
            self.t_s = t_s;
        }
        self.state = ContactState::Pivoting;
    }

    /// The surface at `(u, v)`, from the spine interval of the last one.
    fn surface(&self, u: f64, v: f64) -> ContactFrame {
        self.tube.contact_frame(&self.hints, u, v)
    }

    /// [`TubeContact::local`] on the surface `frame` evaluated at `(u, v)`. The parameters are
    /// orthogonal ([`ContactFrame`]): the free fibre's tangential part is `a X_u + b X_v` with
    /// `a = d·X_u / E` and `b = d·X_v / G`, and `dᵀ W d = −(a² X_uu·n + b² X_vv·n)`.
    fn local_on(
        &self,
        frame: &ContactFrame,
        u: f64,
        #[allow(unused_variables)] v: f64,
        e: &Point3<f64>,
        e_dot: &Vector3<f64>,
    ) -> Result<Local, Error> {
        #[cfg(test)]
        if self.general {
            return Self::local_general(&self.tube.surface(u, v), u, e, e_dot);
        }
        let n = &frame.normal;
        let d = e - frame.point;
        let residual_mm = d.dot(n);
        let dt = d - n * residual_mm;
        if frame.first[0] * frame.first[1] == 0.0 {
            return Err(Error::ContactUndefined {
                height_mm: u,
                reason: "the surface parametrisation is singular",
            });
        }
        let ab = Vector2::new(dt.dot(&frame.du), dt.dot(&frame.dv));
        let (a, b) = (ab.x, ab.y);
        let curvature_mm = -(a * a * frame.second[0] + b * b * frame.second[1]);
        Self::local_of(
            ab,
            curvature_mm,
            residual_mm,
            dt.norm_squared(),
            u,
            n,
            e_dot,
        )
    }

    /// The contact's rates from the tangential direction `ab`, the curvature term and the
    /// residual; refused where the free fibre would bridge.
    fn local_of(
        ab: Vector2<f64>,
        curvature_mm: f64,
        residual_mm: f64,
        dt_squared: f64,
        u: f64,
        n: &Vector3<f64>,
        e_dot: &Vector3<f64>,
    ) -> Result<Local, Error> {
        if curvature_mm <= 1e-12 * dt_squared.max(1e-300) {
            return Err(Error::ContactUndefined {
                height_mm: u,
                reason: "the free fibre runs along a flat or concave direction (it would bridge)",
            });
        }
        Ok(Local {
            rate_per_lambda: ab,
            lambda: -e_dot.dot(n) / curvature_mm,
            residual_mm,
            curvature_mm,
        })
    }

    /// [`TubeContact::local_on`] as it was before [`Tube::contact_frame`]: the general first
    /// fundamental form inverted and the general second one, on [`Tube::surface`]'s vectors.
    #[cfg(test)]
    fn local_general(
        &(x, n, dv): &(
            Point3<f64>,
            Vector3<f64>,
            crate::mandrel::SurfaceDerivatives,
        ),
        u: f64,
        e: &Point3<f64>,
        e_dot: &Vector3<f64>,
    ) -> Result<Local, Error> {
        let d = e - x;
        let residual_mm = d.dot(&n);
        let dt = d - n * residual_mm;
        let first = Matrix2::new(
            dv.xu.dot(&dv.xu),
            dv.xu.dot(&dv.xv),
            dv.xu.dot(&dv.xv),
            dv.xv.dot(&dv.xv),
        );
        let ab = first
            .try_inverse()
            .map(|inv| inv * Vector2::new(dt.dot(&dv.xu), dt.dot(&dv.xv)))
            .ok_or(Error::ContactUndefined {
                height_mm: u,
                reason: "the surface parametrisation is singular",
            })?;
        let (a, b) = (ab.x, ab.y);
        let second = a * a * dv.xuu.dot(&n) + 2.0 * a * b * dv.xuv.dot(&n) + b * b * dv.xvv.dot(&n);
        Self::local_of(ab, -second, residual_mm, dt.norm_squared(), u, &n, e_dot)
    }

    /// Advances the contact to `t_end_s` in steps of at most `max_step_s`, returning the contact
    /// point. Refuses a contact that leaves the tube's ends (`u` outside the spine's range).
    pub fn advance(
        &mut self,
        eye: &impl EyeTrack,
        t_end_s: f64,
        max_step_s: f64,
    ) -> Result<Point3<f64>, Error> {
        self.advance_carrying(eye, t_end_s, max_step_s, &mut None)
    }

    /// [`TubeContact::advance`] with `carry` holding the eye where the last step along the same
    /// eye track ended (the next step starts at that instant; looked up again otherwise).
    fn advance_carrying(
        &mut self,
        eye: &impl EyeTrack,
        t_end_s: f64,
        max_step_s: f64,
        carry: &mut EyeAt,
    ) -> Result<Point3<f64>, Error> {
        if max_step_s.is_nan() || max_step_s <= 0.0 || !t_end_s.is_finite() {
            return Err(Error::OutOfRange {
                name: "max_step_s",
                value: max_step_s,
                expected: "must be > 0 with a finite end time",
            });
        }
        let span = t_end_s - self.t_s;
        if span <= 0.0 {
            return Ok(self.point());
        }
        let steps = (span / max_step_s).ceil().max(1.0);
        if steps > MAX_STEPS_PER_ADVANCE {
            return Err(Error::OutOfRange {
                name: "placement steps",
                value: steps,
                expected: "at most 10 000 000 per call (a larger max_step_s)",
            });
        }
        let h = span / steps;
        for _ in 0..steps as usize {
            self.step(eye, h, carry)?;
        }
        Ok(self.point())
    }

    fn step(&mut self, eye: &impl EyeTrack, h: f64, carry: &mut EyeAt) -> Result<(), Error> {
        let t = self.t_s;
        // The state for this step: pivot while the eye is outside the tangent plane or moving out
        // of it; wrap otherwise.
        let (e, e_dot) = match carry.take() {
            Some((at, e)) if at.to_bits() == t.to_bits() => e,
            _ => eye.at(t),
        };
        let here = match self.start_surface() {
            Some(surface) => self.local_on(surface, self.u, self.v, &e, &e_dot)?,
            None => self.local_on(&self.surface(self.u, self.v), self.u, self.v, &e, &e_dot)?,
        };
        self.state = if here.residual_mm > TANGENCY_TOLERANCE_MM
            || (here.lambda < 0.0 && here.residual_mm >= -TANGENCY_TOLERANCE_MM)
        {
            ContactState::Pivoting
        } else {
            ContactState::Wrapping
        };
        let (u, v) = (self.u, self.v);
        // Classical RK4 on (u̇, v̇). While pivoting the rate is zero. While wrapping, k1 is the
        // rate of `here` (the same time and place), the eye is looked up once for both midpoint
        // stages, and the end's eye serves the correction below too.
        let (du, end) = if self.state == ContactState::Pivoting {
            (Vector2::zeros(), eye.at(t + h))
        } else {
            let rate = |e: &(Point3<f64>, Vector3<f64>), u: f64, v: f64| {
                self.local_on(&self.surface(u, v), u, v, &e.0, &e.1)
                    .map(|l| l.rate_per_lambda * l.lambda.max(0.0))
            };
            let k1 = here.rate_per_lambda * here.lambda.max(0.0);
            let mid = eye.at(t + 0.5 * h);
            let end = eye.at(t + h);
            let k2 = rate(&mid, u + 0.5 * h * k1.x, v + 0.5 * h * k1.y)?;
            let k3 = rate(&mid, u + 0.5 * h * k2.x, v + 0.5 * h * k2.y)?;
            let k4 = rate(&end, u + h * k3.x, v + h * k3.y)?;
            ((k1 + 2.0 * k2 + 2.0 * k3 + k4) * (h / 6.0), end)
        };
        self.u += du.x;
        self.v += du.y;
        self.t_s = t + h;
        // Back onto the tangency condition: one Newton step along the free fibre, forwards only
        // while pivoting (the laid fibre never unwinds).
        let (e, e_dot) = end;
        *carry = Some((self.t_s, end));
        // The surface here: where the step started when it did not move (pivoting).
        let key = [self.u.to_bits(), self.v.to_bits()];
        let surface = self
            .start_surface()
            .copied()
            .unwrap_or_else(|| self.surface(self.u, self.v));
        let l = self.local_on(&surface, self.u, self.v, &e, &e_dot)?;
        let corrected = self.state == ContactState::Wrapping || l.residual_mm < 0.0;
        if corrected {
            let correction = -l.residual_mm / l.curvature_mm;
            self.u += l.rate_per_lambda.x * correction;
            self.v += l.rate_per_lambda.y * correction;
        }
        let moved = [self.u.to_bits(), self.v.to_bits()];
        self.start = Some(if moved == key {
            (key, surface)
        } else {
            (moved, self.surface(self.u, self.v))
        });
        if !(self.tube.u_min() - END_MARGIN_MM..=self.tube.u_max() + END_MARGIN_MM)
            .contains(&self.u)
        {
            return Err(Error::ContactOffSurface {
                time_s: self.t_s,
                height_mm: self.u,
            });
        }
        Ok(())
    }
}

/// The fibre's contact with a triangulated mandrel, advanced in steps.
///
/// On a mesh the surface has no second derivatives to integrate with, so each step solves the
/// tangency condition directly: from the last contact `C₀` the fibre is laid along the free
/// fibre's direction `d̂` (projected into the tangent plane), and the new contact is the nearest
/// surface point to `C₀ + s d̂` for the `s ≥ 0` at which `(E − C(s))·n(C(s)) = 0`, `n` the smooth
/// (interpolated) normal of [`Tracer::normal_at`]. `s` is bracketed by doubling and found by the
/// Illinois false-position method. Each call lays straight chords toward the eye's new position,
/// so the laid path follows the continuous model of [`TubeContact`] to first order in how far the
/// contact moves per call: call it at eye samples close enough that the contact moves a
/// millimetre or less (the tests compare both models on the S-bend), on top of the mesh's own
/// distance from the true surface.
#[derive(Debug, Clone)]
pub struct MeshContact<'a> {
    tracer: &'a Tracer,
    point: Point3<f64>,
    normal: Vector3<f64>,
    state: ContactState,
}

impl<'a> MeshContact<'a> {
    /// Starts at the surface point nearest to `start` (mandrel frame).
    pub fn new(tracer: &'a Tracer, start: &Point3<f64>) -> Result<Self, Error> {
        let at = tracer
            .locate(start)
            .ok_or(Error::NonFinitePoint { index: 0 })?;
        Ok(MeshContact {
            tracer,
            point: at.point,
            normal: at.normal,
            state: ContactState::Wrapping,
        })
    }

    /// The contact point, mandrel frame.
    pub fn point(&self) -> Point3<f64> {
        self.point
    }

    /// Whether the fibre is being laid or pivoting.
    pub fn state(&self) -> ContactState {
        self.state
    }

    /// Moves the contact for the eye now at `eye` (mandrel frame), laying at most `max_step_mm`
    /// per chord; returns the contact point.
    pub fn advance(&mut self, eye: &Point3<f64>, max_step_mm: f64) -> Result<Point3<f64>, Error> {
        if max_step_mm.is_nan() || max_step_mm <= 0.0 || !eye.iter().all(|c| c.is_finite()) {
            return Err(Error::OutOfRange {
                name: "max_step_mm",
                value: max_step_mm,
                expected: "must be > 0 with a finite eye position",
            });
        }
        let residual = (eye - self.point).dot(&self.normal);
        if residual >= -TANGENCY_TOLERANCE_MM {
            // The eye is on or outside the tangent plane: nothing more is laid.
            self.state = ContactState::Pivoting;
            return Ok(self.point);
        }
        self.state = ContactState::Wrapping;
        // Lay chords of at most max_step_mm until the free fibre is tangent again.
        for _ in 0..MAX_CHORDS_PER_ADVANCE {
            let d = eye - self.point;
            let dt = d - self.normal * d.dot(&self.normal);
            let len = dt.norm();
            if len < 1e-12 {
                return Err(Error::ContactUndefined {
                    height_mm: self.point.z,
                    reason: "the eye lies on the surface normal of the contact",
                });
            }
            let dir = dt / len;
            let g = |s: f64| -> Result<(f64, Point3<f64>, Vector3<f64>), Error> {
                let at = self
                    .tracer
                    .locate(&(self.point + dir * s))
                    .ok_or(Error::NonFinitePoint { index: 0 })?;
                Ok(((eye - at.point).dot(&at.normal), at.point, at.normal))
            };
            let (g_step, p_step, n_step) = g(max_step_mm)?;
            if g_step < 0.0 {
                // Still short of tangency after a whole chord: lay it and go on.
                self.point = p_step;
                self.normal = n_step;
                continue;
            }
            // Tangency lies within this chord: Illinois false position on [0, max_step_mm],
            // keeping g(a) < 0 ≤ g(b).
            let (mut a, mut ga) = (0.0, (eye - self.point).dot(&self.normal));
            let (mut b, mut gb) = (max_step_mm, g_step);
            let mut retained = 0i8;
            let mut best = (p_step, n_step);
            for _ in 0..100 {
                let s = (a * gb - b * ga) / (gb - ga);
                let (gs, ps, ns) = g(s)?;
                best = (ps, ns);
                if gs.abs() < 1e-10 || b - a < 1e-12 {
                    break;
                }
                if gs < 0.0 {
                    (a, ga) = (s, gs);
                    if retained == -1 {
                        gb *= 0.5;
                    }
                    retained = -1;
                } else {
                    (b, gb) = (s, gs);
                    if retained == 1 {
                        ga *= 0.5;
                    }
                    retained = 1;
                }
            }
            self.point = best.0;
            self.normal = best.1;
            return Ok(self.point);
        }
        Err(Error::OutOfRange {
            name: "placement chords",
            value: MAX_CHORDS_PER_ADVANCE as f64,
            expected: "the eye moved farther in one call than the chords allow (a larger max_step_mm)",
        })
    }
}

/// Bound on chords laid in one [`MeshContact::advance`] call.
const MAX_CHORDS_PER_ADVANCE: usize = 100_000;

/// How far the tangency residual may be from zero before the contact counts as pivoting, mm.
const TANGENCY_TOLERANCE_MM: f64 = 1e-9;
/// How far past the tube's ends the contact may move before it has left the mandrel, mm.
const END_MARGIN_MM: f64 = 1.0;
/// Bound on integration steps in one call (bounded time on any input).
const MAX_STEPS_PER_ADVANCE: f64 = 1e7;

/// An eye track sampled in the cell frame with the mandrel angle sampled beside it: the devices'
/// true motion as a simulator (or a recording) gives it. Both series are interpolated linearly in
/// time, so the track's velocity is piecewise constant; the eye is seen in the mandrel frame
/// through the cell's transform: `p_cell = origin + R · R_z(φ) p_mandrel` ([`CellTransform`]).
///
/// The integrator asks for times that mostly increase: each series remembers where the last
/// query fell ([`samples_near`]), so a query costs a comparison or two instead of a search.
#[derive(Debug, Clone)]
pub struct SampledEye<'a> {
    /// `(t_s, eye)`, cell frame, mm; times increasing.
    pub eye_mm: &'a [(f64, [f64; 3])],
    /// `(t_s, φ)`: the mandrel angle (mandrel frame `x` against the drive frame), rad; times
    /// increasing.
    pub mandrel_rad: &'a [(f64, f64)],
    /// Drive frame to cell frame.
    pub transform: &'a CellTransform,
    /// Added to every mandrel sample (a drive whose zero lies elsewhere), rad.
    mandrel_offset_rad: Option<f64>,
    /// Where the last query of each series fell (eye, mandrel): a hint, never a result.
    hints: [std::cell::Cell<usize>; 2],
    /// A mandrel angle with its sine and cosine, for those of angles near it
    /// ([`crate::mandrel::sin_cos_anchored`]).
    angle: std::cell::Cell<(f64, f64, f64)>,
}

impl<'a> SampledEye<'a> {
    /// The eye track of the samples `eye_mm` and `mandrel_rad`, seen through `transform`.
    pub fn new(
        eye_mm: &'a [(f64, [f64; 3])],
        mandrel_rad: &'a [(f64, f64)],
        transform: &'a CellTransform,
    ) -> Self {
        SampledEye {
            eye_mm,
            mandrel_rad,
            transform,
            mandrel_offset_rad: None,
            hints: Default::default(),
            angle: std::cell::Cell::new((f64::NAN, f64::NAN, f64::NAN)),
        }
    }

    /// The same track with `offset_rad` added to every mandrel sample: what the track of the
    /// samples `(t, φ + offset_rad)` gives, without copying them.
    pub fn with_mandrel_offset(self, offset_rad: f64) -> Self {
        SampledEye {
            mandrel_offset_rad: Some(offset_rad),
            ..self
        }
    }
}

/// The number of samples of `series` at or before `t` (`series.partition_point(|s| s.0 <= t)`),
/// searched from `hint` outwards by doubling steps (the
/// integrator's next query is nearly always a few samples after the last), and `hint` moved to
/// the answer: a query costs the logarithm of how far it moved, not of the series' length.
fn samples_near<T>(series: &[(f64, T)], t: f64, hint: &std::cell::Cell<usize>) -> usize {
    let n = series.len();
    let h = hint.get().min(n);
    // The answer is the number of samples at or before t: h itself when
    // series[h - 1].0 <= t < series[h].0.
    let at_or_before = |i: usize| series[i].0 <= t;
    let i = if h < n && at_or_before(h) {
        // Forward: find a bound past t, doubling the step.
        let (mut lo, mut step) = (h + 1, 1usize);
        loop {
            let probe = h + step;
            if probe >= n {
                break lo + series[lo..].partition_point(|s| s.0 <= t);
            }
            if !at_or_before(probe) {
                break lo + series[lo..probe].partition_point(|s| s.0 <= t);
            }
            lo = probe + 1;
            step *= 2;
        }
    } else if h > 0 && !at_or_before(h - 1) {
        // Backward: find a sample at or before t, doubling the step.
        let (mut hi, mut step) = (h - 1, 1usize);
        loop {
            if step > hi {
                break series[..hi].partition_point(|s| s.0 <= t);
            }
            let probe = hi - step;
            if at_or_before(probe) {
                break probe + 1 + series[probe + 1..hi].partition_point(|s| s.0 <= t);
            }
            hi = probe;
            step *= 2;
        }
    } else {
        h
    };
    hint.set(i);
    i
}

/// Linear interpolation of a sampled series at `t` (held constant outside it), with the slope.
fn interpolate<const N: usize>(
    series: &[(f64, [f64; N])],
    t: f64,
    hint: &std::cell::Cell<usize>,
) -> ([f64; N], [f64; N]) {
    let n = series.len();
    if n == 0 {
        return ([0.0; N], [0.0; N]);
    }
    let i = samples_near(series, t, hint);
    if i == 0 {
        return (series[0].1, [0.0; N]);
    }
    if i >= n {
        return (series[n - 1].1, [0.0; N]);
    }
    let (a, b) = (&series[i - 1], &series[i]);
    let h = b.0 - a.0;
    // One division: the slope is the change times 1/h.
    let per_s = if h > 0.0 { 1.0 / h } else { 0.0 };
    let w = if h > 0.0 { (t - a.0) * per_s } else { 1.0 };
    let mut value = [0.0; N];
    let mut slope = [0.0; N];
    for k in 0..N {
        let change = b.1[k] - a.1[k];
        value[k] = a.1[k] + change * w;
        slope[k] = change * per_s;
    }
    (value, slope)
}

impl SampledEye<'_> {
    /// The mandrel angle and its rate at `t_s`.
    pub fn mandrel_at(&self, t_s: f64) -> (f64, f64) {
        // A one-element view of the scalar series.
        let n = self.mandrel_rad.len();
        if n == 0 {
            return (0.0, 0.0);
        }
        let shifted = |k: usize| {
            let (t, phi) = self.mandrel_rad[k];
            (t, self.mandrel_offset_rad.map_or(phi, |o| phi + o))
        };
        let i = samples_near(self.mandrel_rad, t_s, &self.hints[1]);
        if i == 0 {
            return (shifted(0).1, 0.0);
        }
        if i >= n {
            return (shifted(n - 1).1, 0.0);
        }
        let (a, b) = (shifted(i - 1), shifted(i));
        let h = b.0 - a.0;
        if h <= 0.0 {
            return (b.1, 0.0);
        }
        let per_s = 1.0 / h;
        let change = b.1 - a.1;
        (a.1 + change * ((t_s - a.0) * per_s), change * per_s)
    }
}

impl EyeTrack for SampledEye<'_> {
    fn at(&self, t_s: f64) -> (Point3<f64>, Vector3<f64>) {
        let (p, v) = interpolate(self.eye_mm, t_s, &self.hints[0]);
        let (phi, phi_rate) = self.mandrel_at(t_s);
        let rt = self.transform.rotation.transpose();
        let p_drive = Point3::from(rt * (Vector3::from(p) - self.transform.origin));
        let v_drive = rt * Vector3::from(v);
        let sin_cos = crate::mandrel::sin_cos_anchored(phi, &self.angle);
        rotated_to_mandrel_frame(&Vector3::zeros(), &p_drive, &v_drive, sin_cos, phi_rate)
    }
}

/// The surface parameters `(u, v)` of a point on (or near) `tube`: `u` the height of the spine
/// point whose normal plane holds it (Newton on `(p − c(u))·c′(u) = 0` from `u = p.z`), `v` its
/// angle around the spine ([`Tube::point`]).
pub fn tube_parameters(tube: &Tube, p: &Point3<f64>) -> (f64, f64) {
    let mut u = p.z.clamp(tube.u_min(), tube.u_max());
    for _ in 0..50 {
        let [x, g, dg, _] = tube.spine().eval(u);
        let d = Vector3::new(p.x - x, p.y, p.z - u);
        let f = d.x * g + d.z;
        // d/du of (p − c)·c′ = −|c′|² + (p − c)·c″.
        let df = -(1.0 + g * g) + d.x * dg;
        if df.abs() < 1e-12 {
            break;
        }
        let step = f / df;
        u -= step;
        if step.abs() < 1e-12 {
            break;
        }
    }
    let u = u.clamp(tube.u_min(), tube.u_max());
    let [x, g, _, _] = tube.spine().eval(u);
    let w = (1.0 + g * g).sqrt();
    let n = Vector3::new(1.0, 0.0, -g) / w;
    let d = Vector3::new(p.x - x, p.y, p.z - u);
    (u, d.y.atan2(d.dot(&n)))
}

/// The laid path on `tube` of the eye track `eye` from `t0_s` to `t1_s`, the contact starting at
/// `start` (mandrel frame, on the surface): the contact point every `step_s` (the integrator's
/// step), with its time. When the contact leaves the tube past an end the path stops there and
/// the time it left is returned beside it (the fibre runs off the mandrel's end). Where the free
/// fibre would bridge a concave stretch the contact is held and the time counted
/// ([`LaidPath::bridged_s`]).
pub fn lay_on_tube(
    tube: &Tube,
    eye: &impl EyeTrack,
    start: &Point3<f64>,
    t0_s: f64,
    t1_s: f64,
    step_s: f64,
) -> Result<LaidPath, Error> {
    if !(step_s > 0.0 && t1_s.is_finite() && t0_s.is_finite()) {
        return Err(Error::OutOfRange {
            name: "step_s",
            value: step_s,
            expected: "must be > 0 with finite start and end times",
        });
    }
    let steps = ((t1_s - t0_s) / step_s).ceil().max(0.0);
    crate::limits::at_most("placement steps", steps, MAX_STEPS_PER_ADVANCE)?;
    let (u, v) = tube_parameters(tube, start);
    let mut contact = TubeContact::new(tube, u, v, t0_s);
    let mut out = LaidPath {
        points: Vec::with_capacity(steps as usize + 1),
        left_at_s: None,
        bridged_s: 0.0,
    };
    out.points.push((t0_s, contact.point()));
    let h = if steps > 0.0 {
        (t1_s - t0_s) / steps
    } else {
        0.0
    };
    let mut carry = None;
    for k in 1..=steps as usize {
        let t = t0_s + h * k as f64;
        let before = contact.position();
        match contact.advance_carrying(eye, t, h, &mut carry) {
            Ok(p) => out.points.push((t, p)),
            Err(Error::ContactOffSurface { time_s, .. }) => {
                out.left_at_s = Some(time_s);
                break;
            }
            Err(Error::ContactUndefined { .. }) => {
                // The free fibre would bridge a concave stretch: the contact is held (the fibre
                // pivots about it) for this step, and the time is counted.
                contact.set_position(before);
                contact.hold_until(t);
                out.bridged_s += h;
                out.points.push((t, contact.point()));
            }
            Err(e) => return Err(e),
        }
    }
    Ok(out)
}

/// A laid path: the contact over time.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LaidPath {
    /// `(t_s, contact)`, mandrel frame, mm.
    pub points: Vec<(f64, Point3<f64>)>,
    /// When the contact left the tube past one of its ends (the path stops there), s.
    pub left_at_s: Option<f64>,
    /// How long the free fibre ran along a flat or concave direction (it would bridge the
    /// surface there; the model holds the contact meanwhile), s.
    pub bridged_s: f64,
}

/// The largest distance from a laid path to a desired one (the thesis's "bow", seed 001 §6.2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Deviation {
    /// The largest distance from a laid point to the desired polyline, mm.
    pub max_mm: f64,
    /// Index of the laid point where it occurs.
    pub at: usize,
}

/// The largest distance from each point of `laid` to the polyline `desired` (both mandrel frame,
/// both ordered along the path). `None` for an empty input.
///
/// A point cannot raise the largest distance found so far if it already lies within it of the
/// segment the last searched point matched (its distance is at most that); only the others are
/// searched ([`Nearest`]). A path whose error grows steadily searches every point; a typical
/// one, a few.
pub fn deviation(laid: &[Point3<f64>], desired: &[Point3<f64>]) -> Option<Deviation> {
    if laid.is_empty() || desired.is_empty() {
        return None;
    }
    let mut search = Nearest::new(desired);
    let mut worst = Deviation { max_mm: 0.0, at: 0 };
    let mut worst_sq = 0.0;
    for (i, p) in laid.iter().enumerate() {
        search.moved_to(p);
        // Follow the path from the last match while the distance falls (the laid point has
        // usually moved on by a few desired segments): a segment's distance bounds the point's.
        let at_cursor = search.descend(p);
        if at_cursor <= worst_sq {
            continue;
        }
        let best_sq = search.search(p, at_cursor);
        if best_sq > worst_sq {
            worst_sq = best_sq;
            worst = Deviation {
                max_mm: best_sq.sqrt(),
                at: i,
            };
        }
    }
    Some(worst)
}

/// Segment `k` of the polyline `desired` (a point's degenerate segment for a single point).
fn segment_of(desired: &[Point3<f64>], k: usize) -> (Point3<f64>, Point3<f64>) {
    (desired[k], desired[(k + 1).min(desired.len() - 1)])
}

/// The squared distance from `p` to the nearest of the `segments` segments of `desired`, and
/// that segment, searched in a window around `cursor` widened while the best lies on its edge
/// (so a point is never matched to a farther segment only because the window was short): the
/// plain search, which the tests hold [`Nearest::search`] to, bit for bit.
#[cfg(test)]
fn nearest_segment(
    p: &Point3<f64>,
    desired: &[Point3<f64>],
    segments: usize,
    cursor: usize,
) -> (f64, usize) {
    let (mut lo, mut hi) = (
        cursor.saturating_sub(WINDOW),
        (cursor + WINDOW).min(segments - 1),
    );
    loop {
        // Compared squared; the root taken once, of the best.
        let (mut best, mut best_k) = (f64::INFINITY, lo);
        for k in lo..=hi {
            let (a, b) = segment_of(desired, k);
            let d = squared_distance_to_segment(p, &a, &b);
            if d < best {
                best = d;
                best_k = k;
            }
        }
        let at_low_edge = best_k == lo && lo > 0;
        let at_high_edge = best_k == hi && hi < segments - 1;
        if !(at_low_edge || at_high_edge) {
            return (best, best_k);
        }
        lo = lo.saturating_sub(WINDOW);
        hi = (hi + WINDOW).min(segments - 1);
    }
}

/// The distance from each point of `laid` to the polyline `desired` (both ordered along the
/// path; empty when either is). Both paths run the same way: each point is searched from the
/// segment the last one matched ([`Nearest`]).
///
/// A point's distance to a segment changes by at most how far the point moved (it is
/// 1-Lipschitz), so each segment keeps the last distance computed to it and the laid path's
/// length at that time: a segment whose distance, less the path travelled since, still exceeds
/// the distance to the last match cannot be the nearest and is not computed. Laid points come a
/// fraction of a millimetre apart, so most segments of the window are passed over.
pub fn distances(laid: &[Point3<f64>], desired: &[Point3<f64>]) -> Vec<f64> {
    if laid.is_empty() || desired.is_empty() {
        return Vec::new();
    }
    let mut search = Nearest::new(desired);
    laid.iter()
        .map(|p| {
            search.moved_to(p);
            let at_cursor = search.exact(p, search.cursor);
            search.search(p, at_cursor).sqrt()
        })
        .collect()
}

/// The search of [`distances`] and [`deviation`]: the nearest segment of `desired` to each
/// point of a laid path in turn, from the segment the last point matched, in a window around it
/// widened while the best lies on its edge (so a point is never matched to a farther segment
/// only because the window was short), segments too far to matter passed over.
struct Nearest<'a> {
    desired: &'a [Point3<f64>],
    segments: usize,
    /// Per segment: the distance when last computed plus `travelled` at that time (a segment
    /// never computed: −∞).
    known: Vec<f64>,
    /// Length of the laid path so far, mm.
    travelled: f64,
    previous: Option<Point3<f64>>,
    points: usize,
    /// The segment the last searched point matched.
    cursor: usize,
}

impl<'a> Nearest<'a> {
    fn new(desired: &'a [Point3<f64>]) -> Self {
        let segments = desired.len().saturating_sub(1).max(1);
        Nearest {
            desired,
            segments,
            known: vec![f64::NEG_INFINITY; segments],
            travelled: 0.0,
            previous: None,
            points: 0,
            cursor: 0,
        }
    }

    /// The laid path moves on to `p`.
    fn moved_to(&mut self, p: &Point3<f64>) {
        if let Some(q) = self.previous {
            self.travelled += (p - q).norm();
        }
        self.previous = Some(*p);
        self.points += 1;
    }

    /// Moves the cursor from the last match to neighbouring segments while they are nearer to
    /// `p` (forwards, or else backwards); returns the squared distance to the cursor's segment.
    fn descend(&mut self, p: &Point3<f64>) -> f64 {
        let start = self.cursor;
        let mut d = self.exact(p, start);
        let mut k = start;
        while k + 1 < self.segments {
            let next = self.exact(p, k + 1);
            if next >= d {
                break;
            }
            (k, d) = (k + 1, next);
        }
        if k == start {
            while k > 0 {
                let next = self.exact(p, k - 1);
                if next >= d {
                    break;
                }
                (k, d) = (k - 1, next);
            }
        }
        self.cursor = k;
        d
    }

    /// The squared distance from `p` to segment `k`, remembered.
    fn exact(&mut self, p: &Point3<f64>, k: usize) -> f64 {
        let (a, b) = segment_of(self.desired, k);
        let d2 = squared_distance_to_segment(p, &a, &b);
        self.known[k] = d2.sqrt() + self.travelled;
        d2
    }

    /// The squared distance from `p` to its nearest segment, searched from the cursor (`at_cursor`: the squared distance to the cursor's segment);
    /// the cursor moves to the match.
    ///
    /// A point's distance to a segment changes by at most how far the point moved, so a
    /// segment whose remembered distance, less the path travelled since, still exceeds the
    /// distance to the cursor's segment cannot be the nearest (nor tie with it) and is not
    /// computed. The margin covers rounding: of the root (relative) and of the travelled sum
    /// (one unit in the last place per point added).
    fn search(&mut self, p: &Point3<f64>, at_cursor: f64) -> f64 {
        let cursor = self.cursor;
        let margin = 1e-9 + self.travelled * f64::EPSILON * 2.0 * self.points as f64;
        let ceiling = at_cursor.sqrt() * (1.0 + 1e-12) + margin;
        let (mut lo, mut hi) = (
            cursor.saturating_sub(WINDOW),
            (cursor + WINDOW).min(self.segments - 1),
        );
        let (best, best_k) = loop {
            let (mut best, mut best_k) = (f64::INFINITY, lo);
            for k in lo..=hi {
                let d = if k == cursor {
                    at_cursor
                } else if self.known[k] - self.travelled > ceiling {
                    continue;
                } else {
                    self.exact(p, k)
                };
                if d < best {
                    best = d;
                    best_k = k;
                }
            }
            let at_low_edge = best_k == lo && lo > 0;
            let at_high_edge = best_k == hi && hi < self.segments - 1;
            if !(at_low_edge || at_high_edge) {
                break (best, best_k);
            }
            lo = lo.saturating_sub(WINDOW);
            hi = (hi + WINDOW).min(self.segments - 1);
        };
        self.cursor = best_k;
        best
    }
}

/// Half-width of the first search window of [`deviation`], in desired segments.
const WINDOW: usize = 32;

/// Distance from `p` to the segment `ab`.
pub fn distance_to_segment(p: &Point3<f64>, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
    squared_distance_to_segment(p, a, b).sqrt()
}

/// Squared distance from `p` to the segment `ab`.
fn squared_distance_to_segment(p: &Point3<f64>, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let t = if len2 > 0.0 {
        ((p - a).dot(&ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + ab * t)).norm_squared()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Spine;
    use crate::spine::{SBEND_SMOOTHING_MM, SBEND_TABLE_6_1_MM};

    const R: f64 = 31.75;

    /// The helix at wind angle `alpha` (from the axis) on the axis-symmetric cylinder of seed 001
    /// §6.4: `H(θ) = (r cos θ, r sin θ, z₀ + θ r / tan α)`, with its derivative in `θ`.
    fn helix(theta: f64, alpha: f64) -> (Point3<f64>, Vector3<f64>) {
        let (s, c) = theta.sin_cos();
        let lead = R / alpha.tan(); // dz/dθ
        let p = Point3::new(R * c, R * s, 10.0 + lead * theta);
        let dp = Vector3::new(-R * s, R * c, lead);
        (p, dp)
    }

    /// An eye that stays on the helix's tangent, `offset` ahead of the point at `θ = rate·t`.
    fn ideal_eye(
        alpha: f64,
        rate: f64,
        offset: f64,
    ) -> impl Fn(f64) -> (Point3<f64>, Vector3<f64>) {
        move |t: f64| {
            let theta = rate * t;
            let (p, dp) = helix(theta, alpha);
            let speed = dp.norm();
            let tangent = dp / speed;
            // d/dθ of the unit tangent: the helix's curvature vector times its speed.
            let (s, c) = theta.sin_cos();
            let ddp = Vector3::new(-R * c, -R * s, 0.0);
            let dtangent = (ddp - tangent * tangent.dot(&ddp)) / speed;
            let e = p + tangent * offset;
            let e_dot = (dp + dtangent * offset) * rate;
            (e, e_dot)
        }
    }

    fn cylinder() -> Tube {
        Tube::cylinder(2.0 * R, 178.0, 0.0, 0.0).unwrap()
    }

    #[test]
    fn an_ideal_eye_lays_the_helix_exactly() {
        let tube = cylinder();
        let alpha = 48.3f64.to_radians();
        let rate = 2.0; // rad/s around the axis
        let eye = ideal_eye(alpha, rate, 100.0);
        let (p0, _) = helix(0.0, alpha);
        let mut contact = TubeContact::new(&tube, p0.z, 0.0, 0.0);
        let mut worst = 0.0f64;
        for k in 1..=200 {
            let t = k as f64 * 0.01;
            let laid = contact.advance(&eye, t, 1e-3).unwrap();
            let (want, _) = helix(rate * t, alpha);
            worst = worst.max((laid - want).norm());
            assert_eq!(contact.state(), ContactState::Wrapping);
        }
        assert!(worst < 1e-6, "laid path off the helix by {worst} mm");
    }

    #[test]
    fn a_lagging_eye_lays_a_steeper_path_and_a_receding_eye_pivots() {
        // The eye moves along the helix's tangent but with the wind angle of a steeper helix: the
        // laid path is no longer the desired helix, and the deviation is what the check measures.
        let tube = cylinder();
        let alpha = 48.3f64.to_radians();
        let eye = ideal_eye(60f64.to_radians(), 2.0, 100.0);
        let mut contact = TubeContact::new(&tube, helix(0.0, alpha).0.z, 0.0, 0.0);
        let mut laid = vec![contact.point()];
        for k in 1..=100 {
            laid.push(contact.advance(&eye, k as f64 * 0.01, 1e-3).unwrap());
        }
        let desired: Vec<Point3<f64>> = (0..=400)
            .map(|k| helix(k as f64 * 0.005, alpha).0)
            .collect();
        let dev = deviation(&laid, &desired).unwrap();
        assert!(dev.max_mm > 1.0, "{dev:?}");

        // An eye pulled straight out along the normal: the contact must not move.
        let start = tube.point(50.0, 0.0);
        let away = move |t: f64| {
            (
                start
                    + Vector3::new(1.0, 0.0, 0.0) * (1.0 + 10.0 * t)
                    + Vector3::new(0.0, 50.0, 0.0),
                Vector3::new(10.0, 0.0, 0.0),
            )
        };
        let mut contact = TubeContact::new(&tube, 50.0, 0.0, 0.0);
        let end = contact.advance(&away, 1.0, 1e-2).unwrap();
        assert_eq!(contact.state(), ContactState::Pivoting);
        assert!((end - start).norm() < 1e-12);
    }

    /// Brute force, independent of the integrator: at the contact's height, scan the angle around
    /// the section for sign changes of the tangency residual and bisect them; the contact must be
    /// one of those silhouette points, and the laid path's direction must point at the eye.
    #[test]
    fn contacts_agree_with_a_brute_force_tangent_search_on_the_s_bend() {
        brute_force_on_the_s_bend(2e-4);
    }

    /// Steps 100 times longer: the Newton step after each RK4 step keeps the contact on the
    /// silhouette.
    #[test]
    fn coarse_steps_stay_on_the_silhouette() {
        brute_force_on_the_s_bend(2e-2);
    }

    fn brute_force_on_the_s_bend(max_step_s: f64) {
        let tube = Tube::new(
            Spine::smoothing(&SBEND_TABLE_6_1_MM, SBEND_SMOOTHING_MM).unwrap(),
            28.5,
        )
        .unwrap();
        // An eye sweeping around and up the S-bend, 100 mm out.
        let eye = |t: f64| {
            let theta = 1.2 * t;
            let z = 60.0 + 40.0 * t;
            let off = tube.spine().offset_mm(z);
            let (s, c) = theta.sin_cos();
            let p = Point3::new(off + 120.0 * c, 120.0 * s, z + 30.0);
            let [_, g, _, _] = tube.spine().eval(z);
            let v = Vector3::new(g * 40.0 - 120.0 * 1.2 * s, 120.0 * 1.2 * c, 40.0);
            (p, v)
        };
        // Start on the silhouette at the start height: brute-force the start angle too.
        let u0 = 60.0;
        let v0 = silhouette(&tube, u0, &eye(0.0).0)
            .into_iter()
            .find(|&v| {
                // The flank where the eye's motion wraps the fibre on.
                let n = tube.normal(u0, v);
                eye(0.0).1.dot(&n) < 0.0
            })
            .expect("a wrapping flank");
        let mut contact = TubeContact::new(&tube, u0, v0, 0.0);
        let mut previous = contact.point();
        for k in 1..=60 {
            let t = k as f64 * 0.02;
            let p = contact.advance(&eye, t, max_step_s).unwrap();
            let (u, v) = contact.parameters();
            let (e, _) = eye(t);
            let candidates = silhouette(&tube, u, &e);
            let nearest = candidates
                .iter()
                .map(|&w| (tube.point(u, w) - p).norm())
                .fold(f64::INFINITY, f64::min);
            assert!(
                nearest < 1e-6,
                "t = {t}: {nearest} mm from the silhouette (v = {v})"
            );
            let travel = p - previous;
            let fibre = (e - p).normalize();
            if travel.norm() > 1e-3 {
                assert!(travel.normalize().dot(&fibre) > 0.999, "t = {t}");
            }
            previous = p;
        }
    }

    /// The eye track as [`SampledEye`] gave it before it remembered an angle and took one
    /// division per query: every query searched, both series divided, `sin_cos` of the mandrel
    /// angle, and the mandrel samples shifted by `offset` in a copy.
    fn previous_sampled_eye<'a>(
        eye: &'a [(f64, [f64; 3])],
        mandrel: &[(f64, f64)],
        transform: &'a CellTransform,
        offset: f64,
    ) -> impl Fn(f64) -> (Point3<f64>, Vector3<f64>) + 'a {
        fn lerp<const N: usize>(series: &[(f64, [f64; N])], t: f64) -> ([f64; N], [f64; N]) {
            let n = series.len();
            let i = series.partition_point(|s| s.0 <= t);
            if i == 0 {
                return (series[0].1, [0.0; N]);
            }
            if i >= n {
                return (series[n - 1].1, [0.0; N]);
            }
            let (a, b) = (&series[i - 1], &series[i]);
            let h = b.0 - a.0;
            let w = if h > 0.0 { (t - a.0) / h } else { 1.0 };
            let mut value = [0.0; N];
            let mut slope = [0.0; N];
            for k in 0..N {
                value[k] = a.1[k] + (b.1[k] - a.1[k]) * w;
                slope[k] = if h > 0.0 { (b.1[k] - a.1[k]) / h } else { 0.0 };
            }
            (value, slope)
        }
        let shifted: Vec<(f64, [f64; 1])> =
            mandrel.iter().map(|&(t, p)| (t, [p + offset])).collect();
        move |t: f64| {
            let (p, v) = lerp(eye, t);
            let ([phi], [rate]) = lerp(&shifted, t);
            let rt = transform.rotation.transpose();
            let p_drive = Point3::from(rt * (Vector3::from(p) - transform.origin));
            to_mandrel_frame(
                &Vector3::zeros(),
                &p_drive,
                &(rt * Vector3::from(v)),
                phi,
                rate,
            )
        }
    }

    /// An eye given in the mandrel frame, seen from a cell whose mandrel turns at `rate`
    /// (rad/s) through `transform`: the eye's and the mandrel's samples every millisecond
    /// from 0 to `t1`, as the simulated cell's trace holds them.
    #[allow(clippy::type_complexity)]
    fn traced(
        eye: impl Fn(f64) -> (Point3<f64>, Vector3<f64>),
        rate: f64,
        t1: f64,
        transform: &CellTransform,
    ) -> (Vec<(f64, [f64; 3])>, Vec<(f64, f64)>) {
        let n = (t1 * 1000.0).round() as usize;
        let mut eye_cell = Vec::with_capacity(n + 1);
        let mut mandrel = Vec::with_capacity(n + 1);
        for k in 0..=n {
            let t = k as f64 * 1e-3;
            let phi = -rate * t;
            let (p, _) = eye(t);
            let (s, c) = phi.sin_cos();
            let q = transform.to_cell(&Point3::new(c * p.x - s * p.y, s * p.x + c * p.y, p.z));
            eye_cell.push((t, [q.x, q.y, q.z]));
            mandrel.push((t, phi));
        }
        (eye_cell, mandrel)
    }

    /// The Monte Carlo of `predict` (its tolerances ten times over): per sample, the largest
    /// distance of the path laid on the perturbed cell, with 20 ms steps, from `desired`;
    /// `general`: the contact geometry and the eye track as they were before the closed form
    /// ([`TubeContact::local_general`], [`previous_sampled_eye`]). Also the laid points.
    #[allow(clippy::type_complexity)]
    fn monte_carlo(
        tube: &Tube,
        eye: &[(f64, [f64; 3])],
        mandrel: &[(f64, f64)],
        start: &Point3<f64>,
        desired: &[Point3<f64>],
        general: bool,
    ) -> (Vec<f64>, Vec<Vec<Point3<f64>>>) {
        let t1 = eye.last().unwrap().0;
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut symmetric = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let (mut errors, mut laid_paths) = (Vec::new(), Vec::new());
        for _ in 0..40 {
            let cal = crate::Calibration {
                axis_offset_mm: [1.0 * symmetric(), 1.5 * symmetric()],
                axis_tilt_rad: [0.0056 * symmetric(), 0.0084 * symmetric()],
                ..crate::Calibration::default()
            };
            let zero = 0.035 * symmetric();
            let radius = tube.radius_mm() + 0.25 * symmetric();
            let true_tube = tube.with_radius(radius).unwrap();
            let transform = cal.transform(800.0, 300.0);
            GENERAL.set(general);
            let laid = if general {
                let track = previous_sampled_eye(eye, mandrel, &transform, zero);
                lay_on_tube(&true_tube, &track, start, 0.0, t1, 0.02)
            } else {
                let track = SampledEye::new(eye, mandrel, &transform).with_mandrel_offset(zero);
                lay_on_tube(&true_tube, &track, start, 0.0, t1, 0.02)
            };
            GENERAL.set(false);
            let pts: Vec<Point3<f64>> = laid.unwrap().points.iter().map(|p| p.1).collect();
            errors.push(deviation(&pts, desired).unwrap().max_mm);
            laid_paths.push(pts);
        }
        (errors, laid_paths)
    }

    /// The closed-form contact geometry ([`Tube::contact_frame`]), the sines from an anchor and
    /// the sampled eye's one division change a Monte Carlo's figures on the S-bend and the
    /// cylinder by rounding only: every laid point, every sample's largest error, and the
    /// median, 95th percentile and largest of those, by under 1e-9 mm against the method
    /// before (3e-13 mm at most when this was written).
    #[test]
    fn closed_form_contact_changes_the_monte_carlo_by_rounding_only() {
        let nominal = crate::Calibration::default().transform(800.0, 300.0);
        // The S-bend, with the eye sweeping around and up it (as in the brute-force test).
        let sbend = Tube::new(
            Spine::smoothing(&SBEND_TABLE_6_1_MM, SBEND_SMOOTHING_MM).unwrap(),
            28.5,
        )
        .unwrap();
        let sweep = |t: f64| {
            let theta = 1.2 * t;
            let z = 60.0 + 40.0 * t;
            let (s, c) = theta.sin_cos();
            let off = sbend.spine().offset_mm(z);
            (
                Point3::new(off + 120.0 * c, 120.0 * s, z + 30.0),
                Vector3::zeros(),
            )
        };
        let (eye, mandrel) = traced(sweep, 1.2, 5.0, &nominal);
        let v0 = silhouette(&sbend, 60.0, &sweep(0.0).0)
            .into_iter()
            .find(|&v| (sweep(1e-3).0 - sweep(0.0).0).dot(&sbend.normal(60.0, v)) < 0.0)
            .unwrap();
        let sbend_start = sbend.point(60.0, v0);
        // The cylinder, with the eye 100 mm ahead on the helix's tangent.
        let cyl = cylinder();
        let alpha = 48.3f64.to_radians();
        let (eye_c, mandrel_c) = traced(ideal_eye(alpha, 2.0, 100.0), 2.0, 5.0, &nominal);
        let cyl_start = helix(0.0, alpha).0;
        for (tube, eye, mandrel, start) in [
            (&sbend, &eye, &mandrel, sbend_start),
            (&cyl, &eye_c, &mandrel_c, cyl_start),
        ] {
            let track = SampledEye::new(eye, mandrel, &nominal);
            let desired: Vec<Point3<f64>> = lay_on_tube(tube, &track, &start, 0.0, 5.0, 2e-3)
                .unwrap()
                .points
                .iter()
                .map(|p| p.1)
                .collect();
            let (now, laid_now) = monte_carlo(tube, eye, mandrel, &start, &desired, false);
            let (before, laid_before) = monte_carlo(tube, eye, mandrel, &start, &desired, true);
            for (a, b) in laid_now.iter().zip(&laid_before) {
                assert_eq!(a.len(), b.len());
                let worst = a
                    .iter()
                    .zip(b)
                    .map(|(p, q)| (p - q).norm())
                    .fold(0.0, f64::max);
                assert!(worst < 1e-9, "a laid point moved by {worst:e} mm");
            }
            let figures = |mut e: Vec<f64>| {
                e.sort_by(f64::total_cmp);
                let q = |q: f64| e[((e.len() - 1) as f64 * q).round() as usize];
                [q(0.5), q(0.95), e[e.len() - 1]]
            };
            let worst_sample = now
                .iter()
                .zip(&before)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(worst_sample < 1e-9, "{worst_sample:e} mm");
            let (a, b) = (figures(now), figures(before));
            for k in 0..3 {
                assert!((a[k] - b[k]).abs() < 1e-9, "{a:?} against {b:?}");
            }
            // The samples differ: the comparison is not of one path.
            assert!(b[2] - b[0] > 0.01, "{b:?}");
        }
    }

    /// A mandrel offset is the track of the shifted samples, bit for bit.
    #[test]
    fn a_mandrel_offset_is_the_shifted_samples() {
        let transform = crate::Calibration::default().transform(800.0, 300.0);
        let eye: Vec<(f64, [f64; 3])> = (0..50)
            .map(|k| (k as f64 * 0.1, [650.0 + k as f64, -3.0 * k as f64, 390.0]))
            .collect();
        let mandrel: Vec<(f64, f64)> = (0..40)
            .map(|k| (k as f64 * 0.13, -0.7 * k as f64 + 0.01 * (k * k) as f64))
            .collect();
        let zero = 0.003_7;
        let shifted: Vec<(f64, f64)> = mandrel.iter().map(|&(t, p)| (t, p + zero)).collect();
        let a = SampledEye::new(&eye, &mandrel, &transform).with_mandrel_offset(zero);
        let b = SampledEye::new(&eye, &shifted, &transform);
        for k in -10..600 {
            let t = k as f64 * 0.0097;
            assert_eq!(a.mandrel_at(t), b.mandrel_at(t), "t = {t}");
            assert_eq!(a.at(t), b.at(t), "t = {t}");
        }
        // Without an offset the samples are the samples; held before and after them.
        let c = SampledEye::new(&eye, &mandrel, &transform);
        assert_eq!(c.mandrel_at(mandrel[5].0).0, mandrel[5].1);
        assert_eq!(a.mandrel_at(mandrel[5].0).0, mandrel[5].1 + zero);
        assert_eq!(a.mandrel_at(-1.0), (mandrel[0].1 + zero, 0.0));
        assert_eq!(a.mandrel_at(100.0), (mandrel[39].1 + zero, 0.0));
    }

    /// Every `v` at height `u` where the line to `e` is tangent: sign changes of `(e − X)·n` on
    /// a fine scan, each bisected to 1e-13 rad.
    fn silhouette(tube: &Tube, u: f64, e: &Point3<f64>) -> Vec<f64> {
        let f = |v: f64| (e - tube.point(u, v)).dot(&tube.normal(u, v));
        let n = 3600;
        let mut out = Vec::new();
        for i in 0..n {
            let (mut a, mut b) = (
                -std::f64::consts::PI + std::f64::consts::TAU * i as f64 / n as f64,
                -std::f64::consts::PI + std::f64::consts::TAU * (i + 1) as f64 / n as f64,
            );
            let (mut fa, fb) = (f(a), f(b));
            if fa == 0.0 || fa * fb < 0.0 {
                for _ in 0..200 {
                    let m = 0.5 * (a + b);
                    let fm = f(m);
                    if fa * fm <= 0.0 {
                        b = m;
                    } else {
                        a = m;
                        fa = fm;
                    }
                    if b - a < 1e-13 {
                        break;
                    }
                }
                out.push(0.5 * (a + b));
            }
        }
        out
    }

    /// An eye fixed in the cell while the mandrel turns at a constant rate: the free fibre wraps
    /// the cylinder in the eye's horizontal plane, so the laid path is that plane's circle (its
    /// contact at the tangent point from the eye, `acos(r/D)` from the eye's direction).
    #[test]
    fn a_fixed_eye_over_a_turning_cylinder_lays_a_circle() {
        let tube = cylinder();
        let transform = crate::Calibration::default().transform(800.0, 300.0);
        // The eye 150 mm from the axis toward the robot, at mandrel height 90 mm.
        let eye_cell = [800.0 - 150.0, 0.0, 390.0];
        let eye = [(0.0, eye_cell), (10.0, eye_cell)];
        // The mandrel turns clockwise seen from above at 1 rad/s: the eye moves
        // counter-clockwise in the mandrel frame.
        let mandrel = [(0.0, 0.0), (10.0, -10.0)];
        let track = SampledEye::new(&eye, &mandrel, &transform);
        // Exact interpolation of a linear motion.
        let (p, v) = track.at(2.5);
        let (s, c) = 2.5f64.sin_cos();
        let want = Point3::new(-150.0 * c, -150.0 * s, 90.0);
        assert!((p - want).norm() < 1e-9, "{p} vs {want}");
        assert!((v - Vector3::new(150.0 * s, -150.0 * c, 0.0)).norm() < 1e-9);
        // Start at the tangent point for the eye at t = 0, on the wrapping flank (the contact
        // trails the eye's motion).
        let beta = (R / 150.0).acos();
        let start = Point3::new(
            R * (std::f64::consts::PI - beta).cos(),
            R * (std::f64::consts::PI - beta).sin(),
            90.0,
        );
        let laid = lay_on_tube(&tube, &track, &start, 0.0, 3.0, 1e-3).unwrap();
        assert!(laid.left_at_s.is_none());
        for &(t, q) in &laid.points {
            assert!((q.z - 90.0).abs() < 1e-6, "t = {t}: z = {}", q.z);
            assert!((q.x.hypot(q.y) - R).abs() < 1e-6);
            // The tangent point of the eye at time t.
            let angle = std::f64::consts::PI + t - beta;
            let want = Point3::new(R * angle.cos(), R * angle.sin(), 90.0);
            assert!((q - want).norm() < 1e-6, "t = {t}: {q} vs {want}");
        }
    }

    /// A bridge that begins inside a step: the contact is held where the step began. A tube of
    /// radius 28.5 mm around a spine bending with radius 150 mm at `u = 100` (`x = (z − 100)² /
    /// 300`); at its inner side the surface is a saddle, concave along the spine. The contact
    /// starts at `(100, 0.6)`, the eye 100 mm out along the tangent 25° from the spine (near the
    /// saddle's flat direction, still convex), still for 60 ms, then pressed 5 mm inward along
    /// the normal over the step's last 40 ms. At the step's start the fibre toward the step's end
    /// eye wraps (its normal curvature, by finite differences of [`Tube::point`], is positive),
    /// so the step moves the contact; but nearly flat, it slides far along the fibre into the
    /// concave stretch, where the step's end refuses (the fibre would bridge). The laid point
    /// after the step is where the step began, the brute-force tangent point of the first eye,
    /// and the step is counted as bridged.
    #[test]
    fn a_bridge_that_begins_inside_a_step_holds_the_contact_where_the_step_began() {
        let knots: Vec<(f64, f64)> = (0..=20)
            .map(|i| {
                let z = i as f64 * 10.0;
                (z, (z - 100.0).powi(2) / 300.0)
            })
            .collect();
        let tube = Tube::new(Spine::new(&knots).unwrap(), 28.5).unwrap();
        let (u0, v0) = (100.0, 0.6);
        let c0 = tube.point(u0, v0);
        let n = tube.normal(u0, v0);
        // The surface's tangents and second derivatives by central differences.
        let q = 1e-3;
        let x = |du: f64, dv: f64| tube.point(u0 + du, v0 + dv).coords;
        let xu = (x(q, 0.0) - x(-q, 0.0)) / (2.0 * q);
        let xv = (x(0.0, q) - x(0.0, -q)) / (2.0 * q);
        let xuu = (x(q, 0.0) + x(-q, 0.0) - 2.0 * x(0.0, 0.0)) / (q * q);
        let xvv = (x(0.0, q) + x(0.0, -q) - 2.0 * x(0.0, 0.0)) / (q * q);
        let xuv = (x(q, q) - x(q, -q) - x(-q, q) + x(-q, -q)) / (4.0 * q * q);
        let along = xu.normalize();
        let across = n.cross(&along);
        let angle = 25f64.to_radians();
        let e0 = c0 + (along * angle.cos() + across * angle.sin()) * 100.0;
        let e1 = e0 - n * 5.0;
        let (h, still) = (0.1, 0.06);
        let velocity = (e1 - e0) / (h - still);
        let eye = move |t: f64| {
            if t < still {
                (e0, Vector3::zeros())
            } else {
                (e0 + velocity * (t - still), velocity)
            }
        };
        // The start is a tangent point of the first eye (brute force).
        assert!(
            silhouette(&tube, u0, &e0)
                .iter()
                .any(|&v| (v - v0).abs() < 1e-9),
            "{:?}",
            silhouette(&tube, u0, &e0)
        );
        // The fibre from the start toward the step's end eye runs along a convex direction: its
        // tangential part `a X_u + b X_v` has `n · (a² X_uu + 2ab X_uv + b² X_vv) < 0` (the
        // surface bends away from the fibre), so the step begins by wrapping.
        let d = e1 - c0;
        let dt = d - n * d.dot(&n);
        let g = Matrix2::new(xu.dot(&xu), xu.dot(&xv), xu.dot(&xv), xv.dot(&xv));
        let ab = g.try_inverse().unwrap() * Vector2::new(dt.dot(&xu), dt.dot(&xv));
        let second = n.dot(&(xuu * ab.x * ab.x + xuv * (2.0 * ab.x * ab.y) + xvv * ab.y * ab.y));
        let curvature = -second / dt.norm_squared();
        assert!(curvature > 1e-4, "normal curvature {curvature} /mm");
        // One step of the placement model.
        let laid = lay_on_tube(&tube, &eye, &c0, 0.0, h, h).unwrap();
        assert_eq!(laid.points.len(), 2);
        assert!(laid.left_at_s.is_none());
        assert!((laid.bridged_s - h).abs() < 1e-12, "{}", laid.bridged_s);
        let (t, held) = laid.points[1];
        assert!((t - h).abs() < 1e-12);
        assert!(
            (held - c0).norm() < 1e-9,
            "the contact left the step's start by {} mm",
            (held - c0).norm()
        );
    }

    #[test]
    fn surface_parameters_round_trip_on_the_s_bend() {
        let tube = Tube::new(
            Spine::smoothing(&SBEND_TABLE_6_1_MM, SBEND_SMOOTHING_MM).unwrap(),
            28.5,
        )
        .unwrap();
        for (u, v) in [(10.0, 0.3), (130.0, -2.0), (200.0, 3.0), (340.0, 1.0)] {
            let p = tube.point(u, v);
            let (u2, v2) = tube_parameters(&tube, &p);
            assert!(
                (u2 - u).abs() < 1e-9 && (v2 - v).abs() < 1e-9,
                "{u},{v} -> {u2},{v2}"
            );
        }
    }

    #[test]
    fn mandrel_frame_conversion_inverts_the_plan_frame() {
        let origin = Vector3::new(800.0, 0.0, 300.0);
        let p_m = Point3::new(40.0, -20.0, 55.0);
        let phi = 0.7f64;
        let (s, c) = phi.sin_cos();
        let p_cell = Point3::new(c * p_m.x - s * p_m.y, s * p_m.x + c * p_m.y, p_m.z) + origin;
        // An eye fixed in the cell while the mandrel turns at 2 rad/s: in the mandrel frame it
        // turns at −2 rad/s about z.
        let (back, v) = to_mandrel_frame(&origin, &p_cell, &Vector3::zeros(), phi, 2.0);
        assert!((back - p_m).norm() < 1e-12);
        let expected = Vector3::new(p_m.y, -p_m.x, 0.0) * 2.0;
        assert!((v - expected).norm() < 1e-12, "{v} vs {expected}");
    }

    #[test]
    fn deviation_is_the_largest_point_to_polyline_distance() {
        let desired = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(10.0, 0.0, 0.0),
            Point3::new(10.0, 10.0, 0.0),
        ];
        let laid = [
            Point3::new(0.0, 0.5, 0.0),
            Point3::new(5.0, -2.0, 0.0),
            Point3::new(9.0, 5.0, 0.0),
            Point3::new(12.0, 10.0, 0.0),
        ];
        let d = deviation(&laid, &desired).unwrap();
        assert!((d.max_mm - 2.0).abs() < 1e-12);
        assert_eq!(d.at, 1);
        assert!(deviation(&[], &desired).is_none());
    }

    /// The hinted search finds what bisection finds, on uniform, jittered, uneven and repeated
    /// sample times, at, between, before and after the samples, and for NaN, with queries in
    /// random and in increasing order.
    #[test]
    fn samples_near_is_partition_point() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let uniform: Vec<(f64, ())> = (0..1000).map(|k| (k as f64 * 1e-3, ())).collect();
        let jittered: Vec<(f64, ())> = (0..1000)
            .map(|k| (k as f64 * 5e-3 + 4e-3 * next(), ()))
            .collect();
        // Dense at the start, sparse after (a trace whose sampling changed), with repeats.
        let mut uneven: Vec<(f64, ())> = (0..500).map(|k| (k as f64 * 1e-4, ())).collect();
        uneven.extend((0..50).map(|k| (0.05 + k as f64 * 2.0, ())));
        uneven.extend([(100.0, ()), (100.0, ()), (100.0, ()), (101.0, ())]);
        let few: Vec<(f64, ())> = vec![(1.0, ())];
        for series in [&uniform, &jittered, &uneven, &few] {
            let lo = series[0].0 - 1.0;
            let hi = series[series.len() - 1].0 + 1.0;
            let mut ts: Vec<f64> = (0..4000).map(|_| lo + (hi - lo) * next()).collect();
            ts.extend(series.iter().map(|s| s.0));
            ts.extend([lo, hi, f64::NAN, f64::INFINITY, f64::NEG_INFINITY]);
            let hint = std::cell::Cell::new(0);
            for &t in &ts {
                let want = series.partition_point(|s| s.0 <= t);
                // With the hint of a query anywhere else (these times are in random order).
                assert_eq!(samples_near(series, t, &hint), want, "t = {t}");
            }
            // In increasing order, as the integrator asks.
            ts.sort_by(f64::total_cmp);
            for &t in &ts {
                let want = series.partition_point(|s| s.0 <= t);
                assert_eq!(samples_near(series, t, &hint), want, "t = {t}");
            }
        }
        let empty: Vec<(f64, ())> = Vec::new();
        assert_eq!(samples_near(&empty, 1.0, &std::cell::Cell::new(3)), 0);
    }

    /// The largest distance, found while skipping the points that cannot raise it, equals a
    /// brute-force search over every segment for every point: along a helix polyline with laid
    /// points whose error wanders, and with an error growing steadily (every point searched).
    #[test]
    fn deviation_equals_a_brute_force_search() {
        let desired: Vec<Point3<f64>> = (0..=400).map(|k| helix(k as f64 * 0.05, 0.6).0).collect();
        let brute = |laid: &[Point3<f64>]| -> (f64, usize) {
            let mut worst = (0.0f64, 0usize);
            for (i, p) in laid.iter().enumerate() {
                let d = desired
                    .windows(2)
                    .map(|w| distance_to_segment(p, &w[0], &w[1]))
                    .fold(f64::INFINITY, f64::min);
                if d > worst.0 {
                    worst = (d, i);
                }
            }
            worst
        };
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for growing in [false, true] {
            let laid: Vec<Point3<f64>> = (0..3000)
                .map(|k| {
                    let (p, _) = helix(k as f64 * 20.0 / 3000.0, 0.6);
                    let size = if growing { k as f64 * 1e-3 } else { 0.8 };
                    p + Vector3::new(next(), next(), next()) * size
                })
                .collect();
            let d = deviation(&laid, &desired).unwrap();
            let (max, at) = brute(&laid);
            assert!((d.max_mm - max).abs() < 1e-12, "{} vs {max}", d.max_mm);
            assert_eq!(d.at, at);
            let from_distances = distances(&laid, &desired)
                .into_iter()
                .fold(0.0f64, f64::max);
            assert!((from_distances - max).abs() < 1e-12);
        }
    }

    /// The pruned search gives, bit for bit, what searching every segment of the window gives
    /// ([`nearest_segment`] from the last match): on a helix polyline with laid points that
    /// wander, that jump, that sit exactly on its vertices (equidistant from two segments), and
    /// that stand still.
    #[test]
    fn distances_prune_without_changing_a_bit() {
        let desired: Vec<Point3<f64>> = (0..=600).map(|k| helix(k as f64 * 0.05, 0.6).0).collect();
        let plain = |laid: &[Point3<f64>]| -> Vec<f64> {
            let segments = desired.len() - 1;
            let mut cursor = 0;
            laid.iter()
                .map(|p| {
                    let (d, k) = nearest_segment(p, &desired, segments, cursor);
                    cursor = k;
                    d.sqrt()
                })
                .collect()
        };
        let mut state = 0x1234_5678_9abc_def1u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut laid: Vec<Point3<f64>> = (0..5000)
            .map(|k| {
                let (p, _) = helix(k as f64 * 30.0 / 5000.0, 0.6);
                p + Vector3::new(next(), next(), next()) * 2.0
            })
            .collect();
        // Jumps back and forth, vertices, and a point repeated.
        laid.extend(desired.iter().step_by(7).copied());
        laid.extend((0..50).map(|k| desired[(k * 97) % desired.len()]));
        laid.extend([desired[300]; 5]);
        let got = distances(&laid, &desired);
        let want = plain(&laid);
        assert_eq!(got.len(), want.len());
        for (i, (g, w)) in got.iter().zip(&want).enumerate() {
            assert_eq!(g.to_bits(), w.to_bits(), "point {i}: {g} vs {w}");
        }
    }

    /// Laid points that advance several desired segments per point: the segment now nearest was
    /// computed last from far behind, so only its distance less the path travelled since lets it
    /// be searched again. Bit for bit against the plain search; and an empty polyline or path
    /// gives no distances.
    #[test]
    fn distances_follow_a_path_that_outruns_its_remembered_bounds() {
        let desired: Vec<Point3<f64>> = (0..=600).map(|k| helix(k as f64 * 0.05, 0.6).0).collect();
        for stride in [2.5, 5.0, 9.0] {
            let laid: Vec<Point3<f64>> = (0..(600.0 / stride) as usize)
                .map(|k| helix(k as f64 * stride * 0.05, 0.6).0 + Vector3::new(0.0, 0.0, 0.01))
                .collect();
            let got = distances(&laid, &desired);
            let segments = desired.len() - 1;
            let mut cursor = 0;
            for (i, p) in laid.iter().enumerate() {
                let (d, k) = nearest_segment(p, &desired, segments, cursor);
                cursor = k;
                assert_eq!(
                    got[i].to_bits(),
                    d.sqrt().to_bits(),
                    "stride {stride}, point {i}"
                );
            }
        }
        assert!(distances(&desired, &[]).is_empty());
        assert!(distances(&[], &desired).is_empty());
        assert!(deviation(&desired, &[]).is_none());
    }

    /// Two laid points equally far from the desired path, the largest: the first is named.
    #[test]
    fn deviation_names_the_first_of_equal_largest_distances() {
        let desired = [Point3::new(0.0, 0.0, 0.0), Point3::new(100.0, 0.0, 0.0)];
        let laid = [
            Point3::new(10.0, 1.0, 0.0),
            Point3::new(20.0, 3.0, 0.0),
            Point3::new(30.0, 2.0, 0.0),
            Point3::new(40.0, 0.0, 3.0),
            Point3::new(50.0, 1.0, 0.0),
        ];
        let d = deviation(&laid, &desired).unwrap();
        assert_eq!((d.max_mm, d.at), (3.0, 1));
    }
}
