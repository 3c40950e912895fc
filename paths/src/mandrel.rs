//! Analytic mandrel models: a tube of constant radius swept along a planar spine (seed 001 §3.1).
//!
//! # Frames
//! The **mandrel frame** is fixed to the mandrel and turns with it: `z` along the mandrel drive's
//! rotation axis (the mandrel is held vertically, seed 001 §4.1.6), origin on the axis at the
//! spine's first knot (distance 0 of Table 6.1), `x` toward the side the spine is offset to, `y`
//! completing a right-handed frame. The spine lies in the plane `y = 0`.
//!
//! # Surface parameters
//! A surface point is `X(u, v) = c(u) + r (cos v N(u) + sin v B)` where `u` is the height of the
//! spine point `c(u) = (x(u), 0, u)`, `N` the unit spine normal in the `x–z` plane (`+x` where the
//! spine is vertical), `B = +y` and `v` the angle around the spine, counter-clockwise seen from
//! above. The four configurations of seed 001 §6.4 are all tubes: the cylinders have a straight
//! spine (on the axis, offset by k radii, or tilted), the S-bend the spline through Table 6.1.

use nalgebra::{Point3, Vector2, Vector3};

use crate::{Error, Spine};

/// A circular cross-section of the mandrel as the thesis describes it (seed 001 §3.2, Fig. 3.1):
/// centroid offset from the rotation axis and radius, in the horizontal plane at one height.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Section {
    /// Centroid `(x, y)` in the mandrel frame; its length is the thesis's `R`.
    pub centroid_mm: Vector2<f64>,
    /// The thesis's `r`.
    pub radius_mm: f64,
}

impl Section {
    /// `R`, the centroid's distance from the rotation axis.
    pub fn centroid_offset_mm(&self) -> f64 {
        self.centroid_mm.norm()
    }

    /// `Ψ` of eq 3.1: the angle of a point around the centroid, measured from `X'` (the direction of
    /// `R`; the mandrel-frame `x` axis when `R = 0`).
    pub fn psi_rad(&self, point: &Point3<f64>) -> f64 {
        let rel = Vector2::new(point.x, point.y) - self.centroid_mm;
        let reference = if self.centroid_offset_mm() > 1e-12 {
            self.centroid_mm.y.atan2(self.centroid_mm.x)
        } else {
            0.0
        };
        rel.y.atan2(rel.x) - reference
    }
}

/// The spine frame at one height: point, unit normal `N` and their derivatives in `u`.
#[derive(Debug, Clone, Copy)]
struct SpineFrame {
    c: Vector3<f64>,
    dc: Vector3<f64>,
    ddc: Vector3<f64>,
    n: Vector3<f64>,
    dn: Vector3<f64>,
    ddn: Vector3<f64>,
}

/// The surface derivatives the geodesic equation needs.
#[derive(Debug, Clone, Copy)]
pub struct SurfaceDerivatives {
    /// ∂X/∂u.
    pub xu: Vector3<f64>,
    /// ∂X/∂v.
    pub xv: Vector3<f64>,
    /// ∂²X/∂u².
    pub xuu: Vector3<f64>,
    /// ∂²X/∂u∂v.
    pub xuv: Vector3<f64>,
    /// ∂²X/∂v².
    pub xvv: Vector3<f64>,
}

/// The surface at one `(u, v)` as the fibre's contact model uses it ([`Tube::contact_frame`]):
/// the parameters are orthogonal there, so a tangent vector `t` is `a X_u + b X_v` with
/// `a = t·du` and `b = t·dv`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactFrame {
    /// `X(u, v)`.
    pub point: Point3<f64>,
    /// The outward unit normal.
    pub normal: Vector3<f64>,
    /// `E = X_u·X_u` and `G = X_v·X_v` (`F = X_u·X_v` is zero).
    pub first: [f64; 2],
    /// `X_u / E`.
    pub du: Vector3<f64>,
    /// `X_v / G`.
    pub dv: Vector3<f64>,
    /// `X_uu·n` and `X_vv·n` (`X_uv·n` is zero).
    pub second: [f64; 2],
}

/// Where a caller moving over a tube last evaluated it, for [`Tube::contact_frame`]: the
/// spine's interval, tried first ([`Spine::eval_near`]), and an angle around the spine with its
/// sine and cosine ([`sin_cos_anchored`]).
#[derive(Debug, Clone)]
pub struct FrameHints {
    piece: std::cell::Cell<usize>,
    angle: std::cell::Cell<(f64, f64, f64)>,
}

impl Default for FrameHints {
    fn default() -> Self {
        FrameHints {
            piece: std::cell::Cell::new(0),
            angle: std::cell::Cell::new((f64::NAN, f64::NAN, f64::NAN)),
        }
    }
}

/// How far from an angle whose sine and cosine are known [`sin_cos_near`] uses them, rad.
const NEAR_RAD: f64 = 1.0 / 16.0;

/// `(sin x, cos x)` from `(x0, sin x0, cos x0)` for `x` near `x0`: the angle-sum formulas, with
/// the sine of `δ = x − x0` and `cos δ − 1` from their Taylor series to `δ⁷` and `δ⁸`. For
/// `|δ| ≤ 1/16` the first terms left out are below 5·10⁻¹⁷ (under half a unit in the last place
/// of 1), so the result is `x.sin_cos()` to rounding; farther away (or for a NaN) it is
/// `x.sin_cos()`. Cheaper than `sin_cos` where an integrator's stages lie close to where its
/// step began.
pub fn sin_cos_near(x: f64, from: (f64, f64, f64)) -> (f64, f64) {
    near(x, from).unwrap_or_else(|| x.sin_cos())
}

/// [`sin_cos_near`] from `anchor`, which moves to `x` (its sine and cosine from `sin_cos`) when
/// `x` is not near it: a caller whose angle moves steadily pays for one `sin_cos` per `1/16`
/// rad.
pub fn sin_cos_anchored(x: f64, anchor: &std::cell::Cell<(f64, f64, f64)>) -> (f64, f64) {
    near(x, anchor.get()).unwrap_or_else(|| {
        let (s, c) = x.sin_cos();
        anchor.set((x, s, c));
        (s, c)
    })
}

fn near(x: f64, (x0, s0, c0): (f64, f64, f64)) -> Option<(f64, f64)> {
    let d = x - x0;
    if d.is_nan() || d.abs() > NEAR_RAD {
        return None;
    }
    let d2 = d * d;
    let sd = d + d * d2 * (-1.0 / 6.0 + d2 * (1.0 / 120.0 + d2 * (-1.0 / 5040.0)));
    let cm1 = d2 * (-0.5 + d2 * (1.0 / 24.0 + d2 * (-1.0 / 720.0 + d2 * (1.0 / 40320.0))));
    Some((s0 + (s0 * cm1 + c0 * sd), c0 + (c0 * cm1 - s0 * sd)))
}

/// A mandrel of constant radius swept along a planar spine.
#[derive(Debug, Clone, PartialEq)]
pub struct Tube {
    spine: Spine,
    radius_mm: f64,
    /// The spine's tightest bend: its curvature (1/mm) and height (mm), as [`Tube::new`]
    /// found it (kept for [`Tube::with_radius`]).
    tightest: (f64, f64),
}

impl Tube {
    /// A tube of `radius_mm` around `spine`. Rejects a radius that is not positive and a spine that
    /// bends more tightly than the radius (the surface would fold onto itself).
    pub fn new(spine: Spine, radius_mm: f64) -> Result<Self, Error> {
        let tightest = Self::tightest_bend(&spine);
        Self::checked(spine, radius_mm, tightest)
    }

    /// The same spine with another radius, checked as [`Tube::new`] checks it (the spine's
    /// tightest bend is not searched again).
    pub fn with_radius(&self, radius_mm: f64) -> Result<Self, Error> {
        Self::checked(self.spine.clone(), radius_mm, self.tightest)
    }

    /// The spine's largest curvature and its height. The spline's curvature peaks at knots
    /// (f'' is piecewise linear); sample them and between.
    fn tightest_bend(spine: &Spine) -> (f64, f64) {
        let (mut worst, mut worst_z) = (0.0f64, 0.0);
        let knots = spine.knot_heights_mm();
        for pair in knots.windows(2) {
            for i in 0..32 {
                let z = pair[0] + (pair[1] - pair[0]) * i as f64 / 32.0;
                let [_, g, dg, _] = spine.eval(z);
                let curvature = dg.abs() / (1.0 + g * g).powf(1.5);
                if curvature > worst {
                    (worst, worst_z) = (curvature, z);
                }
            }
        }
        let [_, g, dg, _] = spine.eval(spine.z_max_mm());
        if dg.abs() / (1.0 + g * g).powf(1.5) > worst {
            (worst, worst_z) = (dg.abs() / (1.0 + g * g).powf(1.5), spine.z_max_mm());
        }
        (worst, worst_z)
    }

    /// The tube, unless its radius is not positive or the spine bends more tightly than it.
    fn checked(spine: Spine, radius_mm: f64, (worst, worst_z): (f64, f64)) -> Result<Self, Error> {
        if !(radius_mm > 0.0 && radius_mm.is_finite()) {
            return Err(Error::OutOfRange {
                name: "radius_mm",
                value: radius_mm,
                expected: "must be > 0",
            });
        }
        if worst * radius_mm >= 1.0 {
            return Err(Error::SpineTooTight {
                height_mm: worst_z,
                bend_radius_mm: 1.0 / worst,
                radius_mm,
            });
        }
        Ok(Tube {
            spine,
            radius_mm,
            tightest: (worst, worst_z),
        })
    }

    /// A straight cylinder of `diameter_mm` whose axis runs `length_mm` from an offset of
    /// `bottom_offset_mm` at the bottom to `top_offset_mm` at the top (seed 001 §6.4, configurations
    /// 1–3: on the axis, offset by k radii, tilted). `length_mm` is measured along the cylinder's axis.
    pub fn cylinder(
        diameter_mm: f64,
        length_mm: f64,
        bottom_offset_mm: f64,
        top_offset_mm: f64,
    ) -> Result<Self, Error> {
        let tilt = top_offset_mm - bottom_offset_mm;
        if !(length_mm > tilt.abs() && length_mm.is_finite()) {
            return Err(Error::OutOfRange {
                name: "length_mm",
                value: length_mm,
                expected: "must be > 0 and longer than the top/bottom offset difference",
            });
        }
        let height = (length_mm * length_mm - tilt * tilt).sqrt();
        Tube::new(
            Spine::straight(height, bottom_offset_mm, top_offset_mm)?,
            diameter_mm / 2.0,
        )
    }

    /// The mandrel radius `r`.
    pub fn radius_mm(&self) -> f64 {
        self.radius_mm
    }

    /// The spine.
    pub fn spine(&self) -> &Spine {
        &self.spine
    }

    /// Height of the spine's first knot (the lower end of the winding surface).
    pub fn u_min(&self) -> f64 {
        self.spine.z_min_mm()
    }

    /// Height of the spine's last knot (the upper end of the winding surface).
    pub fn u_max(&self) -> f64 {
        self.spine.z_max_mm()
    }

    /// The thesis's circular cross-section at height `z_mm` (seed 001 §3.2): centroid on the spine,
    /// radius `r`. (A horizontal cut through a tilted tube is slightly elliptical; the planner uses
    /// the exact surface normal, see [`crate::tangent`].)
    pub fn section(&self, z_mm: f64) -> Section {
        Section {
            centroid_mm: Vector2::new(self.spine.offset_mm(z_mm), 0.0),
            radius_mm: self.radius_mm,
        }
    }

    fn frame(&self, u: f64) -> SpineFrame {
        Self::frame_of(u, self.spine.eval(u))
    }

    fn frame_of(u: f64, [x, g, dg, ddg]: [f64; 4]) -> SpineFrame {
        let w2 = 1.0 + g * g;
        let w = w2.sqrt();
        let w3 = w2 * w;
        let w5 = w3 * w2;
        let a = Vector3::new(-g, 0.0, -1.0);
        SpineFrame {
            c: Vector3::new(x, 0.0, u),
            dc: Vector3::new(g, 0.0, 1.0),
            ddc: Vector3::new(dg, 0.0, 0.0),
            n: Vector3::new(1.0, 0.0, -g) / w,
            dn: a * (dg / w3),
            ddn: a * (ddg / w3)
                + (Vector3::new(-1.0, 0.0, 0.0) / w3 + Vector3::new(g, 0.0, 1.0) * (3.0 * g / w5))
                    * (dg * dg),
        }
    }

    /// The surface point `X(u, v)`.
    pub fn point(&self, u: f64, v: f64) -> Point3<f64> {
        let f = self.frame(u);
        let (s, c) = v.sin_cos();
        Point3::from(f.c + (f.n * c + Vector3::y() * s) * self.radius_mm)
    }

    /// The outward unit normal at `(u, v)`.
    pub fn normal(&self, u: f64, v: f64) -> Vector3<f64> {
        let f = self.frame(u);
        let (s, c) = v.sin_cos();
        f.n * c + Vector3::y() * s
    }

    /// Point, normal and the derivatives the geodesic equation needs, at `(u, v)`.
    pub fn derivatives(&self, u: f64, v: f64) -> SurfaceDerivatives {
        self.derivatives_of(self.frame(u), v)
    }

    /// [`Tube::point`], [`Tube::normal`] and [`Tube::derivatives`] at `(u, v)` from one
    /// evaluation of the spine and one sine and cosine (the contact model asks for all three at
    /// every step).
    pub fn surface(&self, u: f64, v: f64) -> (Point3<f64>, Vector3<f64>, SurfaceDerivatives) {
        let f = self.frame(u);
        let (s, c) = v.sin_cos();
        let r = self.radius_mm;
        let b = Vector3::y();
        let n = f.n * c + b * s;
        let d = SurfaceDerivatives {
            xu: f.dc + f.dn * (r * c),
            xv: (b * c - f.n * s) * r,
            xuu: f.ddc + f.ddn * (r * c),
            xuv: f.dn * (-r * s),
            xvv: n * (-r),
        };
        (Point3::from(f.c + n * r), n, d)
    }

    /// What the fibre's contact model needs at `(u, v)` ([`ContactFrame`]), in closed form,
    /// from the spine's interval and the angle `hints` hold ([`FrameHints`]).
    ///
    /// With `w = √(1 + x′²)`, the spine's curvature term `k = x″ / w³` and `m = 1 − r k cos v`:
    /// `X_u = m c′(u)` and `X_v = r (cos v B − sin v N)` are orthogonal (`F = 0`), with
    /// `E = m² w²` and `G = r²`; `X_uv·n = 0`, `X_vv·n = −r` and `X_uu·n = m x″ cos v / w`.
    /// These are [`Tube::surface`]'s vectors and the products the contact model takes of them,
    /// without the terms that cancel (the same values, to rounding).
    pub fn contact_frame(&self, hints: &FrameHints, u: f64, v: f64) -> ContactFrame {
        let (s, c) = sin_cos_anchored(v, &hints.angle);
        let piece = &hints.piece;
        let [x, g, dg, _] = self.spine.eval_near(piece, u);
        let r = self.radius_mm;
        let w2 = 1.0 + g * g;
        let inv_w = 1.0 / w2.sqrt();
        let (cw, sw) = (c * inv_w, s * inv_w);
        let normal = Vector3::new(cw, s, -g * cw);
        let m = 1.0 - r * dg * cw * (inv_w * inv_w);
        let mw2 = m * w2;
        ContactFrame {
            point: Point3::new(x + r * cw, r * s, u - r * g * cw),
            normal,
            first: [m * mw2, r * r],
            du: Vector3::new(g, 0.0, 1.0) * (1.0 / mw2),
            dv: Vector3::new(-sw, c, g * sw) * (1.0 / r),
            second: [m * dg * cw, -r],
        }
    }

    /// [`Tube::derivatives`] on the spine polynomial of interval `piece` (see
    /// [`Spine::eval_piece`]): `X_uu` holds the spine's third derivative, which jumps at knots.
    pub fn derivatives_on_piece(&self, piece: usize, u: f64, v: f64) -> SurfaceDerivatives {
        self.derivatives_of(Self::frame_of(u, self.spine.eval_piece(piece, u)), v)
    }

    fn derivatives_of(&self, f: SpineFrame, v: f64) -> SurfaceDerivatives {
        let (s, c) = v.sin_cos();
        let r = self.radius_mm;
        let b = Vector3::y();
        SurfaceDerivatives {
            xu: f.dc + f.dn * (r * c),
            xv: (b * c - f.n * s) * r,
            xuu: f.ddc + f.ddn * (r * c),
            xuv: f.dn * (-r * s),
            xvv: (f.n * c + b * s) * (-r),
        }
    }

    /// The unit spine tangent at height `u`, pointing up.
    pub fn spine_tangent(&self, u: f64) -> Vector3<f64> {
        self.frame(u).dc.normalize()
    }

    /// Distance from `p` (mandrel frame) to the surface: the distance to the nearest spine point
    /// minus `r`, negative inside. The ends are treated as hemispherical caps, so beyond the ends
    /// the value is a lower bound (conservative for clearance checks).
    pub fn distance_to_surface_mm(&self, p: &Point3<f64>) -> f64 {
        let (u0, u1) = (self.u_min(), self.u_max());
        let d2 = |u: f64| (self.frame(u).c - p.coords).norm_squared();
        let samples = 64;
        let step = (u1 - u0) / samples as f64;
        let mut best = u0;
        let mut best_d2 = d2(u0);
        for i in 1..=samples {
            let u = u0 + step * i as f64;
            let d = d2(u);
            if d < best_d2 {
                best = u;
                best_d2 = d;
            }
        }
        // Golden-section refinement in the bracketing interval.
        let (mut a, mut b) = ((best - step).max(u0), (best + step).min(u1));
        let ratio = 0.5 * (5f64.sqrt() - 1.0);
        let mut x1 = b - ratio * (b - a);
        let mut x2 = a + ratio * (b - a);
        let (mut f1, mut f2) = (d2(x1), d2(x2));
        for _ in 0..60 {
            if f1 < f2 {
                b = x2;
                x2 = x1;
                f2 = f1;
                x1 = b - ratio * (b - a);
                f1 = d2(x1);
            } else {
                a = x1;
                x1 = x2;
                f1 = f2;
                x2 = a + ratio * (b - a);
                f2 = d2(x2);
            }
        }
        best_d2 = best_d2.min(f1).min(f2);
        best_d2.sqrt() - self.radius_mm
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spine::{SBEND_SMOOTHING_MM, SBEND_TABLE_6_1_MM};
    use approx::assert_abs_diff_eq;

    fn sbend() -> Tube {
        Tube::new(
            Spine::smoothing(&SBEND_TABLE_6_1_MM, SBEND_SMOOTHING_MM).unwrap(),
            28.5,
        )
        .unwrap()
    }

    #[test]
    fn points_lie_at_radius_from_the_spine_and_normal_is_unit() {
        let tube = sbend();
        for &(u, v) in &[
            (0.0, 0.0),
            (75.0, 1.0),
            (133.0, 2.5),
            (250.0, -1.2),
            (350.0, 3.0),
        ] {
            let p = tube.point(u, v);
            // The combined evaluation gives exactly what the three separate ones give.
            let (x, n, d) = tube.surface(u, v);
            let e = tube.derivatives(u, v);
            assert_eq!((x, n), (p, tube.normal(u, v)));
            assert_eq!(
                [d.xu, d.xv, d.xuu, d.xuv, d.xvv],
                [e.xu, e.xv, e.xuu, e.xuv, e.xvv]
            );
            assert_abs_diff_eq!(tube.distance_to_surface_mm(&p), 0.0, epsilon = 1e-6);
            assert_abs_diff_eq!(tube.normal(u, v).norm(), 1.0, epsilon = 1e-12);
            let d = tube.derivatives(u, v);
            assert_abs_diff_eq!(d.xu.dot(&tube.normal(u, v)), 0.0, epsilon = 1e-9);
            assert_abs_diff_eq!(d.xv.dot(&tube.normal(u, v)), 0.0, epsilon = 1e-9);
        }
    }

    /// The closed form is [`Tube::surface`]'s vectors and the products the contact model took of
    /// them, to rounding, on the S-bend (its tightest bends included) and a tilted cylinder, with
    /// hints carried from one evaluation to the next as the contact carries them.
    #[test]
    fn contact_frame_is_the_surface_in_closed_form() {
        let tilted = Tube::cylinder(63.5, 178.0, 31.75, 95.25).unwrap();
        for tube in [sbend(), tilted] {
            let hints = FrameHints::default();
            let mut worst = 0.0f64;
            for i in 0..=2000 {
                let u =
                    tube.u_min() - 1.0 + (tube.u_max() - tube.u_min() + 2.0) * i as f64 / 2000.0;
                let v = -7.0 + 0.0173 * i as f64;
                let f = tube.contact_frame(&hints, u, v);
                let (x, n, d) = tube.surface(u, v);
                let (e, g) = (d.xu.dot(&d.xu), d.xv.dot(&d.xv));
                let scale = 1.0 + e.abs();
                worst = worst
                    .max((f.point - x).norm() / 400.0)
                    .max((f.normal - n).norm())
                    .max((f.first[0] - e).abs() / scale)
                    .max((f.first[1] - g).abs() / g)
                    .max((f.du - d.xu / e).norm() * e.sqrt())
                    .max((f.dv - d.xv / g).norm() * g.sqrt())
                    .max((f.second[0] - d.xuu.dot(&n)).abs() / (1.0 + d.xuu.norm()))
                    .max((f.second[1] - d.xvv.dot(&n)).abs() / tube.radius_mm())
                    // What the closed form leaves out.
                    .max(d.xu.dot(&d.xv).abs() / (e * g).sqrt())
                    .max(d.xuv.dot(&n).abs() / (1.0 + d.xuv.norm()));
                // A fresh evaluation (no hints) gives the same.
                let fresh = tube.contact_frame(&FrameHints::default(), u, v);
                assert!((fresh.point - f.point).norm() < 1e-12, "u = {u}, v = {v}");
            }
            assert!(worst < 1e-14, "relative difference {worst:e}");
        }
    }

    /// Near an anchor the sine and cosine are `sin_cos`'s to rounding; elsewhere (and for a
    /// NaN) they are `sin_cos`'s, and the anchor moves there.
    #[test]
    fn sines_near_an_anchor_are_sin_cos_to_rounding() {
        let mut worst = 0.0f64;
        for k in 0..200 {
            let x0 = -20.0 + 0.2013 * k as f64;
            let (s0, c0) = x0.sin_cos();
            for j in -100..=100 {
                let x = x0 + NEAR_RAD * j as f64 / 100.0;
                let (s, c) = sin_cos_near(x, (x0, s0, c0));
                let (ws, wc) = x.sin_cos();
                worst = worst.max((s - ws).abs()).max((c - wc).abs());
            }
            // Just past the limit, and far: sin_cos itself.
            for x in [x0 + NEAR_RAD * 1.001, x0 - NEAR_RAD * 1.001, x0 + 3.0] {
                assert_eq!(sin_cos_near(x, (x0, s0, c0)), x.sin_cos());
            }
        }
        assert!(worst <= 4.0 * f64::EPSILON, "{worst:e}");
        let (s, c) = sin_cos_near(f64::NAN, (0.0, 0.0, 1.0));
        assert!(s.is_nan() && c.is_nan());

        let anchor = std::cell::Cell::new((f64::NAN, f64::NAN, f64::NAN));
        assert_eq!(sin_cos_anchored(1.0, &anchor), 1.0f64.sin_cos());
        assert_eq!(anchor.get(), (1.0, 1.0f64.sin(), 1.0f64.cos()));
        // Near: the anchor stays, the values are the angle-sum's.
        let near = sin_cos_anchored(1.05, &anchor);
        assert_eq!(anchor.get().0, 1.0);
        assert_eq!(near, sin_cos_near(1.05, (1.0, 1.0f64.sin(), 1.0f64.cos())));
        // Far: the anchor moves.
        assert_eq!(sin_cos_anchored(1.2, &anchor), 1.2f64.sin_cos());
        assert_eq!(anchor.get().0, 1.2);
    }

    /// Another radius on the same spine is the tube [`Tube::new`] makes, refusals included.
    #[test]
    fn with_radius_is_new_with_that_radius() {
        let tube = sbend();
        for r in [
            28.5,
            1.0,
            30.0,
            55.0,
            61.0,
            70.0,
            0.0,
            -1.0,
            f64::INFINITY,
            f64::NAN,
        ] {
            let a = tube.with_radius(r);
            let b = Tube::new(tube.spine().clone(), r);
            assert_eq!(format!("{a:?}"), format!("{b:?}"), "r = {r}");
        }
        assert!(tube.with_radius(70.0).is_err() && tube.with_radius(28.6).is_ok());
    }

    #[test]
    fn analytic_derivatives_match_finite_differences() {
        let tube = sbend();
        let (u, v, h) = (123.4, 0.7, 1e-4);
        let d = tube.derivatives(u, v);
        let fd_u = (tube.point(u + h, v) - tube.point(u - h, v)) / (2.0 * h);
        let fd_v = (tube.point(u, v + h) - tube.point(u, v - h)) / (2.0 * h);
        let fd_uu = (tube.derivatives(u + h, v).xu - tube.derivatives(u - h, v).xu) / (2.0 * h);
        let fd_uv = (tube.derivatives(u, v + h).xu - tube.derivatives(u, v - h).xu) / (2.0 * h);
        assert_abs_diff_eq!(d.xu, fd_u, epsilon = 1e-6);
        assert_abs_diff_eq!(d.xv, fd_v, epsilon = 1e-6);
        assert_abs_diff_eq!(d.xuu, fd_uu, epsilon = 1e-5);
        assert_abs_diff_eq!(d.xuv, fd_uv, epsilon = 1e-6);
    }

    #[test]
    fn tilted_cylinder_keeps_its_axial_length() {
        let r = 31.75;
        let tube = Tube::cylinder(63.5, 178.0, r, 3.0 * r).unwrap();
        let bottom = Vector3::new(r, 0.0, 0.0);
        let top = Vector3::new(3.0 * r, 0.0, tube.u_max());
        assert_abs_diff_eq!((top - bottom).norm(), 178.0, epsilon = 1e-9);
    }

    #[test]
    fn section_psi_is_measured_from_the_offset_direction() {
        let tube = Tube::cylinder(63.5, 178.0, 63.5, 63.5).unwrap();
        let section = tube.section(50.0);
        assert_abs_diff_eq!(section.centroid_offset_mm(), 63.5, epsilon = 1e-12);
        let p = Point3::new(63.5, 31.75, 50.0);
        assert_abs_diff_eq!(
            section.psi_rad(&p),
            std::f64::consts::FRAC_PI_2,
            epsilon = 1e-12
        );
    }

    #[test]
    fn rejects_bad_radius_and_folding_spine() {
        let spine = Spine::straight(100.0, 0.0, 0.0).unwrap();
        assert!(Tube::new(spine.clone(), 0.0).is_err());
        assert!(Tube::new(spine, -1.0).is_err());
        let kinked = Spine::new(&[(0.0, 0.0), (10.0, 20.0), (20.0, 0.0)]).unwrap();
        assert!(Tube::new(kinked, 28.5).is_err());
    }
}
