//! The mandrel as a solid: signed distance (negative inside), the nearest surface point, and the
//! least signed distance along a segment. Mandrel frame, mm.

use std::fmt;

use super::bvh::{Box3, Bvh};
use nalgebra::{Point3, Vector3};

use super::minimum::{RELATIVE, first_below};
use super::{RESOLUTION_MM, certified_min, certified_min_below, golden_min};
use crate::mesh::{Adjacency, Closure, Mesh, NO_NEIGHBOUR};
use crate::{Error, Tube};

/// A mandrel solid.
pub trait Solid: fmt::Debug + Send + Sync {
    /// Distance from `p` to the surface, negative inside.
    fn signed_distance_mm(&self, p: &Point3<f64>) -> f64;

    /// The surface point nearest to `p`.
    fn surface_point(&self, p: &Point3<f64>) -> Point3<f64>;

    /// The largest distance of any point of the solid from the rotation axis (the frame's `z`
    /// axis), mm, or infinity when not known. Turning the solid by `δφ` about that axis moves
    /// none of its points by more than `δφ` times this, so no distance to it changes by more.
    fn axis_radius_mm(&self) -> f64 {
        f64::INFINITY
    }

    /// The least signed distance over the segment `a–b`, to within [`RESOLUTION_MM`] (exact for
    /// the straight tube and for a segment that stays outside a mesh).
    fn segment_min_mm(&self, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
        let length = (b - a).norm();
        certified_min(
            &mut |t| self.signed_distance_mm(&(a + (b - a) * t)),
            length,
            RESOLUTION_MM,
            f64::NEG_INFINITY,
        )
        .value
    }

    /// [`Solid::segment_min_mm`], or any value from `cap` up to it when it is at least `cap`
    /// (a search that needs only to know that the segment is that far out stops early).
    fn segment_min_capped_mm(&self, a: &Point3<f64>, b: &Point3<f64>, cap: f64) -> f64 {
        let _ = cap;
        self.segment_min_mm(a, b)
    }

    /// The earliest point of the segment `a–b` (as a fraction of it) more than `depth_mm` inside
    /// the solid, with its signed distance, found to within [`RESOLUTION_MM`] of that depth; and
    /// the least signed distance evaluated (see [`first_below`]).
    fn inside_beyond(
        &self,
        a: &Point3<f64>,
        b: &Point3<f64>,
        depth_mm: f64,
    ) -> (f64, Option<(f64, f64)>) {
        let length = (b - a).norm();
        let m = first_below(
            &mut |t| self.signed_distance_mm(&(a + (b - a) * t)),
            length,
            RESOLUTION_MM,
            -depth_mm,
        );
        (m.value, m.first_below)
    }
}

/// Spacing of the spine heights sampled before Newton's method, mm.
const SAMPLE_MM: f64 = 10.0;

/// The analytic tube of [`Tube`] as a solid, closed by flat ends normal to the spine (as
/// [`crate::mesh::triasym`] closes its meshes).
///
/// Straight spines (the cylinders of seed 001 §6.4, on the axis, offset or tilted) use the capped
/// cylinder's closed form. A bent spine (the S-bend) finds the nearest spine height by sampling
/// every [`SAMPLE_MM`] and Newton's method on the spine polynomial; inside the tube the end planes are
/// taken at the arc length from the nearest spine point to the end (the S-bend is straight at
/// its ends to well under a micrometre over the radius).
#[derive(Debug, Clone)]
pub struct TubeSolid {
    tube: Tube,
    /// Largest distance from the `z` axis (straight spines; infinity for a bent one).
    axis_radius_mm: f64,
    /// Straight spine: bottom centre, unit axis, axial length.
    straight: Option<(Point3<f64>, Vector3<f64>, f64)>,
    /// Bent spine: sample heights and the spine's offset there, for the nearest-point search.
    samples: Vec<(f64, f64)>,
    /// Bent spine: bounds on `|x'(u)|` and `|x''(u)|` over the tube's heights, for the free
    /// fibre's certificate ([`TubeSolid::spine_clearance`]).
    slope_bend: (f64, f64),
}

impl TubeSolid {
    /// The solid of `tube`.
    pub fn new(tube: &Tube) -> Self {
        let (u0, u1) = (tube.u_min(), tube.u_max());
        let centre = |u: f64| Point3::new(tube.spine().offset_mm(u), 0.0, u);
        let straight = tube.spine().is_straight().then(|| {
            let (a, b) = (centre(u0), centre(u1));
            let axis = b - a;
            let length = axis.norm();
            (a, axis / length, length)
        });
        let count = ((u1 - u0) / SAMPLE_MM).ceil().max(1.0) as usize;
        let samples = (0..=count)
            .map(|i| {
                let u = u0 + (u1 - u0) * i as f64 / count as f64;
                (u, tube.spine().offset_mm(u))
            })
            .collect();
        // Every point of the tube (and of its flat ends) lies within the radius of a spine point
        // between the ends, and a spine point lies `|offset|` from the axis.
        let axis_radius_mm = max_abs_offset_mm(tube.spine(), u0, u1) + tube.radius_mm();
        TubeSolid {
            tube: tube.clone(),
            axis_radius_mm,
            straight,
            samples,
            slope_bend: max_slope_and_bend(tube.spine(), u0, u1),
        }
    }

    /// The point of the tube's side nearest to `p` (mandrel frame) and the outward unit normal
    /// there: on the circle of the nearest spine point (the bent spine's global nearest height,
    /// the straight one's closed form, clamped to the ends), in the direction of `p` (any
    /// direction when `p` is on the spine).
    pub fn nearest_surface(&self, p: &Point3<f64>) -> (Point3<f64>, Vector3<f64>) {
        let r = self.tube.radius_mm();
        let (c, tangent) = match &self.straight {
            Some((a, axis, length)) => {
                let t = (p - a).dot(axis).clamp(0.0, *length);
                (a + axis * t, *axis)
            }
            None => {
                let u = self.nearest_u(p);
                let [x, g, _, _] = self.tube.spine().eval(u);
                (
                    Point3::new(x, 0.0, u),
                    Vector3::new(g, 0.0, 1.0).normalize(),
                )
            }
        };
        let w = p - c;
        let radial = w - tangent * w.dot(&tangent);
        let n = radial
            .try_normalize(1e-12)
            .unwrap_or_else(|| tangent.cross(&Vector3::y()).normalize());
        (c + n * r, n)
    }

    /// The free fibre's certificate on a bent spine: `Some(clearance)` when no point of the
    /// segment `a–b` lies more than `depth_mm + RESOLUTION_MM` inside the tube, `None` when that
    /// is not shown (then [`Solid::inside_beyond`] searches the segment itself). `clearance` is
    /// the segment's least distance from the spine (between the tube's ends) less the radius, to
    /// within `max(RESOLUTION_MM, RELATIVE · |clearance|)` above the true one: no more than the
    /// least signed distance along the segment, which it equals wherever the nearest point is
    /// between the end planes.
    ///
    /// A point more than `δ` inside lies within `r − δ` of a spine point `C(u)` with `u` between
    /// the tube's ends (beyond an end plane it is outside), and then `|u − z| < r − δ`. So it is
    /// enough that `f(u) = dist(C(u), a–b)²` stays at or above `(r − δ)²` for `u` within `r` of
    /// the segment's heights. `f` is the least over the segment's points `L(t)` of
    /// `g_t(u) = |C(u) − L(t)|²`, and `g_t'' = 2|C'|² + 2 (C − L(t))·C'' ≤ M` with `|C'|² = 1 +
    /// x'²`, `|C''| = |x''|` and `|C − L(t)|` bounded over the heights searched: `f` is
    /// `M`-semiconcave, so on `[u_a, u_b]` it lies above the chord of its end values less
    /// `M (u − u_a)(u_b − u)/2`. Intervals are halved until that bound clears `(r − δ)²`. Where the
    /// fibre leaves its tangent point `f` has a smooth minimum near `r²`, which the quadratic
    /// bound clears with intervals of about `√(16 r δ / M)`: a few dozen evaluations of the
    /// spine's cubic, where searching the fibre with its 1-Lipschitz signed distance takes
    /// steps of `δ` and a nearest-spine search at each.
    pub fn spine_clearance(&self, a: &Point3<f64>, b: &Point3<f64>, depth_mm: f64) -> Option<f64> {
        let r = self.tube.radius_mm();
        let reach = r - depth_mm - RESOLUTION_MM;
        let finite = a.iter().chain(b.iter()).all(|c| c.is_finite());
        if self.straight.is_some() || !finite || reach.is_nan() || reach <= 0.0 {
            return None;
        }
        let level = reach * reach;
        let spine = self.tube.spine();
        let (u0, u1) = (self.tube.u_min(), self.tube.u_max());
        let lo = (a.z.min(b.z) - r).max(u0);
        let hi = (a.z.max(b.z) + r).min(u1);
        let d = b - a;
        let dd = d.norm_squared();
        let f = |u: f64| {
            let c = Point3::new(spine.offset_mm(u), 0.0, u);
            let w = c - a;
            let t = if dd > 0.0 {
                (w.dot(&d) / dd).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (w - d * t).norm_squared()
        };
        if lo >= hi {
            // No spine height within the radius of the segment's.
            return Some(f(u0.max(a.z.min(u1))).sqrt() - r);
        }
        let (slope, bend) = self.slope_bend;
        let speed2 = 1.0 + slope * slope;
        let mid = Point3::new(spine.offset_mm(0.5 * (lo + hi)), 0.0, 0.5 * (lo + hi));
        let far = (mid - a).norm().max((mid - b).norm()) + speed2.sqrt() * 0.5 * (hi - lo);
        let m = 2.0 * speed2 + 2.0 * far * bend;
        if !m.is_finite() {
            return None;
        }
        let (fl, fh) = (f(lo), f(hi));
        let mut least = fl.min(fh);
        if least < level {
            return None;
        }
        let mut stack = vec![(lo, hi, fl, fh)];
        let mut evaluations = 2usize;
        while let Some((ua, ub, fa, fb)) = stack.pop() {
            // Least of `fa + (fb − fa) s − k s (1 − s)` over `s ∈ [0, 1]`, `k = M w²/2`.
            let k = 0.5 * m * (ub - ua) * (ub - ua);
            let s = if k > 0.0 {
                ((k - (fb - fa)) / (2.0 * k)).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let bound = fa + (fb - fa) * s - k * s * (1.0 - s);
            // Searched to the dip's level everywhere, and to the reported clearance's
            // resolution where the minimum could be.
            let value = least.sqrt();
            let tolerance = RESOLUTION_MM.max(RELATIVE * (value - r).abs());
            let floor = (value - tolerance).max(0.0);
            if bound >= level.max(floor * floor) {
                continue;
            }
            if evaluations >= SPINE_CERTIFICATE_EVALUATIONS || ub - ua < 1e-9 {
                return None;
            }
            let um = 0.5 * (ua + ub);
            let fm = f(um);
            evaluations += 1;
            if fm < level {
                return None;
            }
            least = least.min(fm);
            stack.push((um, ub, fm, fb));
            stack.push((ua, um, fa, fm));
        }
        Some(least.sqrt() - r)
    }

    /// The nearest spine height to `p` (clamped to the spine's ends): Newton's method on the
    /// squared distance from every sample that is a local minimum of the sampled distances,
    /// among the samples that could be nearest.
    fn nearest_u(&self, p: &Point3<f64>) -> f64 {
        let spine = self.tube.spine();
        let d2 = |u: f64| {
            let x = spine.offset_mm(u);
            (x - p.x) * (x - p.x) + (u - p.z) * (u - p.z)
        };
        let at = |(u, x): (f64, f64)| (x - p.x) * (x - p.x) + (u - p.z) * (u - p.z);
        let samples = &self.samples;
        let n = samples.len();
        // The samples are evenly spaced in height and a sample's squared distance is at least
        // its squared height difference: start at the sample level with `p` and stop on each
        // side once the height difference alone exceeds the best distance.
        let (first, last) = (samples[0].0, samples[n - 1].0);
        let start = if n > 1 && last > first {
            let k = ((p.z - first) / (last - first) * (n - 1) as f64).round();
            if k.is_nan() {
                0
            } else {
                k.clamp(0.0, (n - 1) as f64) as usize
            }
        } else {
            0
        };
        let mut best_d2 = at(samples[start]);
        let (mut lo, mut hi) = (start, start);
        while hi + 1 < n && (samples[hi + 1].0 - p.z).powi(2) < best_d2 {
            hi += 1;
            best_d2 = best_d2.min(at(samples[hi]));
        }
        while lo > 0 && (samples[lo - 1].0 - p.z).powi(2) < best_d2 {
            lo -= 1;
            best_d2 = best_d2.min(at(samples[lo]));
        }
        let (u0, u1) = (self.tube.u_min(), self.tube.u_max());
        // Newton's method from a sample; `None` where the squared distance is not convex on the
        // way or it does not settle.
        let newton = |mut u: f64| {
            for _ in 0..8 {
                let [x, g, dg, _] = spine.eval(u);
                let first = (x - p.x) * g + (u - p.z);
                let second = g * g + (x - p.x) * dg + 1.0;
                if second <= 0.0 {
                    return None;
                }
                let next = (u - first / second).clamp(u0, u1);
                if (next - u).abs() < 1e-12 {
                    return Some(next);
                }
                u = next;
            }
            None
        };
        // Golden-section search of a bracket, to a nanometre.
        let golden = |mut a: f64, mut b: f64| {
            let ratio = 0.5 * (5f64.sqrt() - 1.0);
            let (mut x1, mut x2) = (b - ratio * (b - a), a + ratio * (b - a));
            let (mut f1, mut f2) = (d2(x1), d2(x2));
            while b - a > 1e-9 {
                if f1 < f2 {
                    (b, x2, f2) = (x2, x1, f1);
                    x1 = b - ratio * (b - a);
                    f1 = d2(x1);
                } else {
                    (a, x1, f1) = (x1, x2, f2);
                    x2 = a + ratio * (b - a);
                    f2 = d2(x2);
                }
            }
            if f1 < f2 { x1 } else { x2 }
        };
        let (mut best, mut best_value) = (samples[start].0, f64::INFINITY);
        for k in lo..=hi {
            let v = at(samples[k]);
            let left = k == 0 || at(samples[k - 1]) >= v;
            let right = k + 1 == n || at(samples[k + 1]) >= v;
            if !(left && right) {
                continue;
            }
            // A minimum lies between the neighbouring samples: Newton from the sample, or the
            // bracket searched where Newton cannot be trusted; kept only where it improves on
            // the sample itself.
            let bracket = (
                samples[k.saturating_sub(1)].0,
                samples[(k + 1).min(n - 1)].0,
            );
            let u = newton(samples[k].0)
                .filter(|u| (bracket.0..=bracket.1).contains(u))
                .unwrap_or_else(|| golden(bracket.0, bracket.1));
            let (u, d) = match d2(u) {
                d if d <= v => (u, d),
                _ => (samples[k].0, v),
            };
            if d < best_value {
                best = u;
                best_value = d;
            }
        }
        best
    }
}

/// The largest `|offset|` of the spine over heights `u0 … u1`, mm, bounded from above: each
/// cubic piece is sampled every [`OFFSET_STEP_MM`] and, from each sample, its Taylor expansion
/// (exact on the piece) bounds the offset up to the next sample.
fn max_abs_offset_mm(spine: &crate::Spine, u0: f64, u1: f64) -> f64 {
    let knots = spine.knot_heights_mm();
    let mut bound = spine.offset_mm(u0).abs().max(spine.offset_mm(u1).abs());
    let pieces = knots.len().saturating_sub(1);
    for piece in 0..pieces {
        // The end pieces extend beyond the end knots.
        let lo = if piece == 0 { u0 } else { knots[piece].max(u0) };
        let hi = if piece + 1 == pieces {
            u1
        } else {
            knots[piece + 1].min(u1)
        };
        if lo > hi {
            continue;
        }
        let count = ((hi - lo) / OFFSET_STEP_MM).ceil().max(1.0) as usize;
        let h = (hi - lo) / count as f64;
        for k in 0..count {
            let [x, g, dg, d3] = spine.eval_piece(piece, lo + h * k as f64);
            let reach = x.abs() + g.abs() * h + dg.abs() * h * h / 2.0 + d3.abs() * h * h * h / 6.0;
            bound = bound.max(reach);
        }
    }
    bound
}

/// Bounds on `|x'|` and `|x''|` of the spine over heights `u0 … u1`, from each cubic piece's
/// Taylor expansion from samples every [`OFFSET_STEP_MM`] (as [`max_abs_offset_mm`]).
fn max_slope_and_bend(spine: &crate::Spine, u0: f64, u1: f64) -> (f64, f64) {
    let knots = spine.knot_heights_mm();
    let pieces = knots.len().saturating_sub(1);
    let (mut slope, mut bend) = (0.0f64, 0.0f64);
    for piece in 0..pieces {
        let lo = if piece == 0 { u0 } else { knots[piece].max(u0) };
        let hi = if piece + 1 == pieces {
            u1
        } else {
            knots[piece + 1].min(u1)
        };
        if lo > hi {
            continue;
        }
        let count = ((hi - lo) / OFFSET_STEP_MM).ceil().max(1.0) as usize;
        let h = (hi - lo) / count as f64;
        for k in 0..count {
            let [_, g, dg, d3] = spine.eval_piece(piece, lo + h * k as f64);
            slope = slope.max(g.abs() + dg.abs() * h + d3.abs() * h * h / 2.0);
            bend = bend.max(dg.abs() + d3.abs() * h);
        }
    }
    (slope, bend)
}

/// Most spine evaluations of one [`TubeSolid::spine_clearance`] before it leaves the segment to
/// the search along it.
const SPINE_CERTIFICATE_EVALUATIONS: usize = 4096;

/// Sample spacing of [`max_abs_offset_mm`], mm.
const OFFSET_STEP_MM: f64 = 1.0;

/// Signed distance of a capped cylinder from the radial and axial excesses (`ρ − r`, distance
/// beyond the nearer end, negative inside).
fn capped(radial: f64, axial: f64) -> f64 {
    let outside = radial.max(0.0).hypot(axial.max(0.0));
    outside + radial.max(axial).min(0.0)
}

impl Solid for TubeSolid {
    fn axis_radius_mm(&self) -> f64 {
        self.axis_radius_mm
    }

    fn inside_beyond(
        &self,
        a: &Point3<f64>,
        b: &Point3<f64>,
        depth_mm: f64,
    ) -> (f64, Option<(f64, f64)>) {
        if self.straight.is_some() {
            // Closed form first; search only a segment that does reach that deep.
            let least = self.segment_min_mm(a, b);
            if least >= -depth_mm {
                return (least, None);
            }
        } else if let Some(clearance) = self.spine_clearance(a, b, depth_mm) {
            return (clearance, None);
        }
        let length = (b - a).norm();
        let m = first_below(
            &mut |t| self.signed_distance_mm(&(a + (b - a) * t)),
            length,
            RESOLUTION_MM,
            -depth_mm,
        );
        (m.value, m.first_below)
    }

    fn signed_distance_mm(&self, p: &Point3<f64>) -> f64 {
        let r = self.tube.radius_mm();
        if let Some((a, axis, length)) = &self.straight {
            let w = p - a;
            let t = w.dot(axis);
            let radial = (w - axis * t).norm() - r;
            return capped(radial, (-t).max(t - length));
        }
        let u = self.nearest_u(p);
        let spine = self.tube.spine();
        let [x, g, _, _] = spine.eval(u);
        let c = Point3::new(x, 0.0, u);
        let tangent = Vector3::new(g, 0.0, 1.0).normalize();
        let w = p - c;
        let along = w.dot(&tangent);
        let radial = (w - tangent * along).norm() - r;
        let (u0, u1) = (self.tube.u_min(), self.tube.u_max());
        let slope = (1.0 + g * g).sqrt();
        // Beyond an end the foot sits on the end plane: `along` is the distance past it.
        let axial = if u <= u0 && along < 0.0 {
            -along
        } else if u >= u1 && along > 0.0 {
            along
        } else {
            -((u - u0).min(u1 - u) * slope)
        };
        capped(radial, axial)
    }

    fn surface_point(&self, p: &Point3<f64>) -> Point3<f64> {
        self.nearest_surface(p).0
    }

    fn segment_min_mm(&self, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
        self.segment_min_capped_mm(a, b, f64::INFINITY)
    }

    fn segment_min_capped_mm(&self, a: &Point3<f64>, b: &Point3<f64>, cap: f64) -> f64 {
        let Some((base, axis, length)) = &self.straight else {
            // Bent spine: the signed distance is `length`-Lipschitz along the segment; its
            // minimum is searched to the resolution only where it could lie below `cap`.
            let length = (b - a).norm();
            let m = certified_min_below(
                &mut |t, _| self.signed_distance_mm(&(a + (b - a) * t)),
                length,
                RESOLUTION_MM,
                f64::NEG_INFINITY,
                cap,
            );
            return if m.value < cap { m.value } else { cap };
        };
        // Closed form: the segment's least distance from the axis line, when there the point lies
        // between the end planes (then the radial excess is the signed distance, and nowhere on
        // the segment is the signed distance below the radial excess).
        let r = self.tube.radius_mm();
        let wa = a - base;
        let d = b - a;
        let wa_perp = wa - axis * wa.dot(axis);
        let d_perp = d - axis * d.dot(axis);
        let dd = d_perp.norm_squared();
        let s = if dd > 1e-18 {
            (-wa_perp.dot(&d_perp) / dd).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let radial = (wa_perp + d_perp * s).norm() - r;
        let t = (wa + d * s).dot(axis);
        let axial = (-t).max(t - length);
        if axial <= radial.min(0.0) {
            return radial;
        }
        // Near an end: the capped cylinder is convex, so its signed distance is convex along
        // the segment.
        let f = |t: f64| self.signed_distance_mm(&(a + d * t));
        golden_min(f, 0.0, 1.0, 1e-10).min(f(0.0)).min(f(1.0))
    }
}

/// A closed triangle mesh as a solid: its triangles in a bounding-volume hierarchy, and
/// inside and outside from the angle-weighted pseudo-normals of Bærentzen and Aanæs (2005): the
/// nearest surface point's feature (a face, an edge or a vertex) has a pseudo-normal whose sign
/// against the offset to the query point is the point's side.
pub struct MeshSolid {
    vertices: Vec<Point3<f64>>,
    triangles: Vec<[u32; 3]>,
    /// Per triangle, the unit outward normal.
    face_normals: Vec<Vector3<f64>>,
    /// Per triangle and edge (corner `e` to corner `e + 1`), the sum of the unit normals of the
    /// triangles that share it (the angle each subtends is π, so no weights are needed).
    edge_normals: Vec<[Vector3<f64>; 3]>,
    /// Per vertex, the sum of its triangles' unit normals, each weighted by its angle there.
    vertex_normals: Vec<Vector3<f64>>,
    bvh: Bvh,
    /// The mesh's axis-aligned bounds.
    bounds: Box3,
    /// Largest distance of a vertex from the `z` axis (the surface lies in their convex hull).
    axis_radius_mm: f64,
}

impl fmt::Debug for MeshSolid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("MeshSolid")
            .field("triangles", &self.triangles.len())
            .finish()
    }
}

/// The box of a segment or a triangle's corners.
fn box_of(points: &[Point3<f64>]) -> Box3 {
    points.iter().fold(Box3::EMPTY, |b, p| Box3 {
        lo: std::array::from_fn(|i| b.lo[i].min(p[i])),
        hi: std::array::from_fn(|i| b.hi[i].max(p[i])),
    })
}

/// Distance from `p` to the box, mm (0 inside it).
fn point_box_mm(p: &Point3<f64>, b: &Box3) -> f64 {
    let gap = |i: usize| (b.lo[i] - p[i]).max(p[i] - b.hi[i]).max(0.0);
    Vector3::new(gap(0), gap(1), gap(2)).norm()
}

/// The feature of a triangle a point lies nearest to ([`closest_on_triangle`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Feature {
    /// Corner 0, 1 or 2.
    Corner(usize),
    /// Edge `e`, from corner `e` to corner `e + 1`.
    Edge(usize),
    /// The inside of the face.
    Face,
}

impl MeshSolid {
    /// The solid of a closed, outward-oriented mesh (as [`crate::mesh::prepare`] returns it).
    pub fn new(mesh: &Mesh) -> Result<Self, Error> {
        let adjacency = mesh.validate(Closure::Open)?;
        Self::with_adjacency(mesh, &adjacency)
    }

    /// [`MeshSolid::new`] with the mesh's edge adjacency already found (as
    /// [`crate::mesh::prepare`] returns it with the mesh).
    pub fn with_adjacency(mesh: &Mesh, adjacency: &Adjacency) -> Result<Self, Error> {
        let vertices = mesh.vertices().to_vec();
        let triangles = mesh.triangles().to_vec();
        if triangles.is_empty() || adjacency.across.len() != triangles.len() {
            return Err(Error::MeshInvalid {
                triangle: None,
                reason: "the collision mesh has no triangles, or not those of its adjacency"
                    .to_string(),
            });
        }
        let corners = |t: usize| triangles[t].map(|i| vertices[i as usize]);
        let face_normals: Vec<Vector3<f64>> = (0..triangles.len())
            .map(|t| {
                let [a, b, c] = corners(t);
                (b - a)
                    .cross(&(c - a))
                    .try_normalize(0.0)
                    .unwrap_or_default()
            })
            .collect();
        let mut vertex_normals = vec![Vector3::zeros(); vertices.len()];
        for (t, tri) in triangles.iter().enumerate() {
            let p = corners(t);
            for k in 0..3 {
                let (u, v) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
                let angle = crate::arm::atan2(u.cross(&v).norm(), u.dot(&v));
                vertex_normals[tri[k] as usize] += face_normals[t] * angle;
            }
        }
        let edge_normals = adjacency
            .across
            .iter()
            .enumerate()
            .map(|(t, across)| {
                across.map(|h| {
                    let other = if h == NO_NEIGHBOUR {
                        Vector3::zeros()
                    } else {
                        face_normals[(h >> 2) as usize]
                    };
                    face_normals[t] + other
                })
            })
            .collect();
        let boxes: Vec<Box3> = (0..triangles.len()).map(|t| box_of(&corners(t))).collect();
        let bvh = Bvh::new(&boxes);
        let bounds = bvh.bounds().unwrap_or(Box3::EMPTY);
        let axis_radius_mm = vertices.iter().map(|v| v.x.hypot(v.y)).fold(0.0, f64::max);
        Ok(MeshSolid {
            vertices,
            triangles,
            face_normals,
            edge_normals,
            vertex_normals,
            bvh,
            bounds,
            axis_radius_mm,
        })
    }
}

/// What one walk of the bounding-volume hierarchy tested ([`MeshSolid::segment_walk_work`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct WalkWork {
    /// Bounding boxes (inner nodes and leaves) tested against the segment.
    pub boxes: u64,
    /// Triangles reached (their leaf box meets the segment), each tested for a crossing.
    pub triangles: u64,
}

/// Crossings of a segment with the surface closer together than this (in mm along the segment)
/// are one crossing (an edge or a vertex shared by several triangles).
const SAME_CROSSING_MM: f64 = 1e-7;

/// Where a segment crosses a triangle: the fraction of the segment, and whether it enters the
/// solid there (against the triangle's outward normal). `None` when it misses; `Some(None)` when
/// it lies in the triangle's plane and touches it (no crossing can be named).
fn crossing(
    a: &Point3<f64>,
    d: &Vector3<f64>,
    [v0, v1, v2]: [Point3<f64>; 3],
) -> Option<Option<(f64, bool)>> {
    // Möller and Trumbore (1997).
    let e1 = v1 - v0;
    let e2 = v2 - v0;
    let p = d.cross(&e2);
    let det = e1.dot(&p);
    let w = a - v0;
    let n = e1.cross(&e2);
    if det.abs() <= 1e-12 * d.norm() * n.norm() {
        // Parallel: it touches only when it lies in the plane.
        let off_plane = w.dot(&n).abs() / n.norm();
        return (off_plane <= SAME_CROSSING_MM && point_triangle_mm(a, [v0, v1, v2]) <= d.norm())
            .then_some(None);
    }
    let eps = 1e-12;
    let u = w.dot(&p) / det;
    if !(-eps..=1.0 + eps).contains(&u) {
        return None;
    }
    let q = w.cross(&e1);
    let v = d.dot(&q) / det;
    if v < -eps || u + v > 1.0 + eps {
        return None;
    }
    let s = e2.dot(&q) / det;
    (0.0..=1.0).contains(&s).then_some(Some((s, det > 0.0)))
}

/// Distance from `p` to the triangle `abc`, mm ([`closest_on_triangle`]).
pub fn point_triangle_mm(p: &Point3<f64>, corners: [Point3<f64>; 3]) -> f64 {
    (p - closest_on_triangle(p, corners).0).norm()
}

/// The point of the triangle `abc` closest to `p`, and the feature it lies on (the closest point
/// by Voronoi regions, Ericson, Real-Time Collision Detection §5.1.5).
fn closest_on_triangle(p: &Point3<f64>, [a, b, c]: [Point3<f64>; 3]) -> (Point3<f64>, Feature) {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Feature::Corner(0));
    }
    let bp = p - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Feature::Corner(1));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, Feature::Edge(0));
    }
    let cp = p - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Feature::Corner(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, Feature::Edge(2));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, Feature::Edge(1));
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    (a + ab * v + ac * w, Feature::Face)
}

/// Distance from the segment `a–b` to the triangle, mm: 0 when it crosses the triangle, else the
/// least of its ends' distances to the triangle and its distances to the triangle's edges.
pub fn segment_triangle_mm(a: &Point3<f64>, b: &Point3<f64>, corners: [Point3<f64>; 3]) -> f64 {
    if crossing(a, &(b - a), corners).is_some() {
        return 0.0;
    }
    let [p, q, r] = corners;
    let ends = point_triangle_mm(a, corners).min(point_triangle_mm(b, corners));
    let edges = super::segment_segment(a, b, &p, &q)
        .2
        .min(super::segment_segment(a, b, &q, &r).2)
        .min(super::segment_segment(a, b, &r, &p).2);
    ends.min(edges)
}

/// True when the segment from `a` along `d` (`inv` = 1/d per axis) meets the box.
fn segment_meets_box(a: &Point3<f64>, inv: &Vector3<f64>, b: &Box3) -> bool {
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for axis in 0..3 {
        let (o, i, l, h) = (a[axis], inv[axis], b.lo[axis], b.hi[axis]);
        if i.is_infinite() {
            if o < l || o > h {
                return false;
            }
            continue;
        }
        let (mut near, mut far) = ((l - o) * i, (h - o) * i);
        if near > far {
            std::mem::swap(&mut near, &mut far);
        }
        t0 = t0.max(near);
        t1 = t1.min(far);
        if t0 > t1 {
            return false;
        }
    }
    true
}

impl MeshSolid {
    fn corners(&self, triangle: u32) -> [Point3<f64>; 3] {
        self.triangles[triangle as usize].map(|i| self.vertices[i as usize])
    }

    /// The nearest surface point to `p`, the triangle it lies on, and whether `p` is inside (by
    /// the pseudo-normal of the feature the nearest point lies on).
    fn project(&self, p: &Point3<f64>) -> (Point3<f64>, u32, bool) {
        let found = self.bvh.find_best(
            f64::INFINITY,
            |b| point_box_mm(p, b),
            |triangle, _best| {
                let (point, feature) = closest_on_triangle(p, self.corners(triangle));
                Some(((point - p).norm(), (point, feature)))
            },
        );
        let Some((triangle, _, (point, feature))) = found else {
            // No triangle: `with_adjacency` refuses such a mesh.
            return (*p, 0, false);
        };
        let t = triangle as usize;
        let normal = match feature {
            Feature::Face => self.face_normals[t],
            Feature::Edge(e) => self.edge_normals[t][e],
            Feature::Corner(k) => self.vertex_normals[self.triangles[t][k] as usize],
        };
        (point, triangle, (p - point).dot(&normal) < 0.0)
    }

    /// Signed distance at `p` and the triangle nearest to it.
    fn nearest(&self, p: &Point3<f64>) -> (f64, u32) {
        let (point, triangle, inside) = self.project(p);
        let d = (p - point).norm();
        (if inside { -d } else { d }, triangle)
    }

    /// The work of walking the bounding-volume hierarchy along the segment `a–b`, as
    /// [`Solid::inside_beyond`] walks it to find the segment's crossings: the boxes tested and
    /// the triangles whose boxes the segment meets (each then tested for a crossing). A measure
    /// of work, not of geometry: the benchmarks divide query time by it (`docs/benchmarks.md`,
    /// "Face order and locality"), so that a finer mesh's larger walk is not counted as a loss
    /// of memory locality.
    pub fn segment_walk_work(&self, a: &Point3<f64>, b: &Point3<f64>) -> WalkWork {
        let d = b - a;
        let inv = d.map(|x| 1.0 / x);
        let mut boxes = 0u64;
        let triangles = self
            .bvh
            .leaves(|node| {
                boxes += 1;
                segment_meets_box(a, &inv, node)
            })
            .count() as u64;
        WalkWork { boxes, triangles }
    }

    /// True when `p` is inside: outside the mesh's bounding box without a query; within it, by
    /// the first surface crossing of a ray from `p` away from the rotation axis (leaving the
    /// solid there: inside; entering: outside; none: outside). Where that is not clear-cut (the
    /// ray grazes a face or meets an edge whose faces disagree, or `p` lies on the surface) the
    /// nearest surface point decides, as [`Solid::signed_distance_mm`] does.
    fn is_inside(&self, p: &Point3<f64>) -> bool {
        let Box3 { lo, hi } = self.bounds;
        if (0..3).any(|i| p[i] < lo[i] || p[i] > hi[i]) {
            return false;
        }
        let nearest = || self.nearest(p).0 < 0.0;
        let out = Vector3::new(p.x, p.y, 0.0)
            .try_normalize(1e-9)
            .unwrap_or_else(Vector3::x);
        let diagonal = Vector3::from(hi) - Vector3::from(lo);
        let d = out * (diagonal.norm() + 1.0);
        let inv = d.map(|x| 1.0 / x);
        let same = SAME_CROSSING_MM / d.norm();
        // The first crossing along the ray, and whether another at the same place disagrees.
        let mut first: Option<(f64, bool)> = None;
        let mut split = false;
        for triangle in self.bvh.leaves(|node| segment_meets_box(p, &inv, node)) {
            match crossing(p, &d, self.corners(triangle)) {
                None => {}
                Some(None) => return nearest(),
                Some(Some((s, entering))) => match first {
                    Some((f, e)) if (s - f).abs() <= same => split |= e != entering,
                    Some((f, _)) if s > f => {}
                    _ => {
                        // A new first crossing; the old one was farther by more than `same`.
                        split = false;
                        first = Some((s, entering));
                    }
                },
            }
        }
        match first {
            None => false,
            Some((s, _)) if split || s <= same => nearest(),
            Some((_, entering)) => !entering,
        }
    }

    /// Distance from the segment `a–b` to the surface, mm (0 when it crosses it): a best-first
    /// walk of the bounding-volume hierarchy, nearest box first, skipping every box that lies
    /// farther from the segment than the nearest triangle found so far. A box lies no nearer
    /// than the gap between it and the segment's own box, nor than the distance from its centre
    /// less its half-diagonal.
    pub fn segment_distance_mm(&self, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
        self.segment_distance_capped_mm(a, b, f64::INFINITY)
    }

    /// [`MeshSolid::segment_distance_mm`] when it is below `cap`; otherwise `cap` (no triangle
    /// lies nearer: the walk skips every box no nearer than `cap`).
    pub fn segment_distance_capped_mm(&self, a: &Point3<f64>, b: &Point3<f64>, cap: f64) -> f64 {
        let d = b - a;
        let dd = d.norm_squared();
        let inv = d.map(|x| 1.0 / x);
        let (seg_lo, seg_hi) = (a.inf(b), a.sup(b));
        let box_cost = |node: &Box3| {
            let (lo, hi) = (Point3::from(node.lo), Point3::from(node.hi));
            let gap = (lo - seg_hi)
                .sup(&(seg_lo - hi))
                .sup(&Vector3::zeros())
                .norm();
            let c = Point3::from((lo.coords + hi.coords) * 0.5);
            let s = if dd > 0.0 {
                ((c - a).dot(&d) / dd).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let sphere = (c - (a + d * s)).norm() - 0.5 * (hi - lo).norm();
            let bound = gap.max(sphere);
            if bound <= 0.0 && segment_meets_box(a, &inv, node) {
                0.0
            } else {
                bound.max(0.0)
            }
        };
        self.bvh
            .find_best(cap, box_cost, |triangle, _best| {
                Some((segment_triangle_mm(a, b, self.corners(triangle)), ()))
            })
            .map_or(cap, |(_, distance, ())| distance)
    }

    /// The free fibre's check on a mesh ([`Solid::inside_beyond`]) from the segment's crossings
    /// with the surface: the stretches inside lie between an entering and an exiting crossing
    /// (the bounding-volume hierarchy finds the few triangles near the segment). A point of a
    /// stretch is no deeper than its distance to any one triangle, and that distance is convex
    /// along the segment, so over a piece `[x, y]` the depth is at most
    /// `max(dist(p(x), T), dist(p(y), T))` for the triangle `T` nearest either end; pieces whose
    /// bound exceeds the depth by more than [`RESOLUTION_MM`] are halved (left first). A dip
    /// more than `depth_mm + RESOLUTION_MM` deep is always found, and the earliest one reported.
    /// `None` when the crossings do not pair up (a segment in a triangle's plane, or one that
    /// ends inside): then the caller searches the signed distance itself.
    fn chord_depths(
        &self,
        a: &Point3<f64>,
        b: &Point3<f64>,
        depth_mm: f64,
    ) -> Option<(f64, Option<(f64, f64)>)> {
        let d = b - a;
        let length = d.norm();
        if length == 0.0 {
            return None;
        }
        let inv = d.map(|x| 1.0 / x);
        let mut hits: Vec<(f64, bool, u32)> = Vec::new();
        for triangle in self.bvh.leaves(|node| segment_meets_box(a, &inv, node)) {
            match crossing(a, &d, self.corners(triangle)) {
                None => {}
                Some(None) => return None,
                Some(Some((s, entering))) => hits.push((s, entering, triangle)),
            }
        }
        if hits.is_empty() {
            // Wholly outside or wholly inside.
            return if self.is_inside(b) {
                None
            } else {
                Some((0.0, None))
            };
        }
        hits.sort_by(|x, y| x.0.total_cmp(&y.0));
        // One crossing per place: an edge or vertex shared by several triangles is crossed once;
        // a segment that touches a ridge (enters and leaves at one place) does not cross.
        let same = SAME_CROSSING_MM / length;
        let mut crossings: Vec<(f64, bool, u32)> = Vec::with_capacity(hits.len());
        let mut i = 0;
        while i < hits.len() {
            let mut j = i + 1;
            while j < hits.len() && hits[j].0 - hits[j - 1].0 <= same {
                j += 1;
            }
            let group = &hits[i..j];
            if group.iter().all(|h| h.1 == group[0].1) {
                crossings.push(group[0]);
            }
            i = j;
        }
        // Inside stretches: (start, end, triangle at the start if a crossing, at the end).
        let mut inside = !crossings.first().is_none_or(|c| c.1);
        let mut stretches: Vec<(f64, Option<u32>, f64, u32)> = Vec::new();
        let mut from: (f64, Option<u32>) = (0.0, None);
        for &(s, entering, triangle) in &crossings {
            if entering == inside {
                return None;
            }
            if entering {
                from = (s, Some(triangle));
            } else {
                stretches.push((from.0, from.1, s, triangle));
            }
            inside = entering;
        }
        if inside {
            return None;
        }
        let at = |s: f64| a + d * s;
        let mut value = 0.0f64;
        let limit = depth_mm + RESOLUTION_MM;
        for (s0, t0, s1, t1) in stretches {
            let (depth0, t0) = match t0 {
                Some(t) => (0.0, t),
                None => {
                    let (sd, t) = self.nearest(&at(s0));
                    value = value.min(sd);
                    if sd < -depth_mm {
                        return Some((value, Some((s0, sd))));
                    }
                    (-sd.min(0.0), t)
                }
            };
            // No point of a stretch is deeper than half its length (plus the depth where it
            // starts, when it starts inside).
            if 0.5 * (depth0 + (s1 - s0) * length) <= limit {
                continue;
            }
            let mut stack = vec![(s0, s1, t0, t1)];
            let mut first: Option<(f64, f64)> = None;
            while let Some((x, y, tx, ty)) = stack.pop() {
                // Once a snag is found, only the pieces before it can hold an earlier one.
                if first.is_some_and(|(at_s, _)| x >= at_s) {
                    continue;
                }
                let (px, py) = (at(x), at(y));
                let bound = |t: u32| {
                    let c = self.corners(t);
                    point_triangle_mm(&px, c).max(point_triangle_mm(&py, c))
                };
                if bound(tx).min(bound(ty)) <= limit || (y - x) * length <= RESOLUTION_MM {
                    continue;
                }
                let m = 0.5 * (x + y);
                let (sd, tm) = self.nearest(&at(m));
                value = value.min(sd);
                if sd < -depth_mm {
                    first = Some((m, sd));
                } else {
                    stack.push((m, y, tm, ty));
                }
                stack.push((x, m, tx, tm));
            }
            if first.is_some() {
                return Some((value, first));
            }
        }
        Some((value, None))
    }
}

impl Solid for MeshSolid {
    fn axis_radius_mm(&self) -> f64 {
        self.axis_radius_mm
    }

    fn inside_beyond(
        &self,
        a: &Point3<f64>,
        b: &Point3<f64>,
        depth_mm: f64,
    ) -> (f64, Option<(f64, f64)>) {
        if let Some(found) = self.chord_depths(a, b, depth_mm) {
            return found;
        }
        // The crossings did not pair up (a segment along an edge, or ending inside): search
        // the signed distance itself.
        let length = (b - a).norm();
        let m = first_below(
            &mut |t| self.signed_distance_mm(&(a + (b - a) * t)),
            length,
            RESOLUTION_MM,
            -depth_mm,
        );
        (m.value, m.first_below)
    }

    fn signed_distance_mm(&self, p: &Point3<f64>) -> f64 {
        self.nearest(p).0
    }

    fn surface_point(&self, p: &Point3<f64>) -> Point3<f64> {
        self.project(p).0
    }

    fn segment_min_mm(&self, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
        self.segment_min_capped_mm(a, b, f64::INFINITY)
    }

    fn segment_min_capped_mm(&self, a: &Point3<f64>, b: &Point3<f64>, cap: f64) -> f64 {
        // Apart from the surface by `cap` or more, the segment is wholly outside (then `cap`
        // will do) or wholly inside (then the value is negative and is searched in full). A cap
        // at or below zero saves nothing: the distance is found in full.
        let walk_cap = if cap > 0.0 { cap } else { f64::INFINITY };
        let distance = self.segment_distance_capped_mm(a, b, walk_cap);
        if distance > 0.0 {
            // Apart from the surface: wholly outside or wholly inside.
            return if !self.is_inside(a) {
                distance
            } else {
                let length = (b - a).norm();
                certified_min(
                    &mut |t| self.signed_distance_mm(&(a + (b - a) * t)),
                    length,
                    RESOLUTION_MM,
                    f64::NEG_INFINITY,
                )
                .value
            };
        }
        let length = (b - a).norm();
        certified_min(
            &mut |t| self.signed_distance_mm(&(a + (b - a) * t)),
            length,
            RESOLUTION_MM,
            f64::NEG_INFINITY,
        )
        .value
        .min(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clearance::test_support::{sbend_tube, uniform};
    use crate::mesh::{Closure, DEFAULT_WELD_MM, prepare, triasym};

    /// Distance from `p` to triangle `abc`: to the plane when the foot lies inside (signed areas),
    /// else to the nearest of the three edges (a different route from parry's Voronoi regions).
    fn brute_triangle(p: &Point3<f64>, [a, b, c]: [Point3<f64>; 3]) -> f64 {
        // Exact distance to the plane when the projection is inside, else to the three edges.
        let n = (b - a).cross(&(c - a));
        let n2 = n.norm_squared();
        let t = (p - a).dot(&n) / n2;
        let q = p - n * t;
        let area =
            |x: &Point3<f64>, y: &Point3<f64>, z: &Point3<f64>| (y - x).cross(&(z - x)).dot(&n);
        let (wa, wb, wc) = (area(&q, &b, &c), area(&a, &q, &c), area(&a, &b, &q));
        if wa >= 0.0 && wb >= 0.0 && wc >= 0.0 {
            return (p - q).norm();
        }
        let edge = |x: &Point3<f64>, y: &Point3<f64>| {
            let d = y - x;
            let s = ((p - x).dot(&d) / d.norm_squared()).clamp(0.0, 1.0);
            (p - (x + d * s)).norm()
        };
        edge(&a, &b).min(edge(&b, &c)).min(edge(&c, &a))
    }

    #[test]
    fn mesh_distance_agrees_with_brute_force_over_10000_random_points() {
        let tube = Tube::cylinder(57.0, 120.0, 0.0, 0.0).unwrap();
        let raw = triasym::tube(&tube, 24, 10.0, true).unwrap();
        let (mesh, _) = prepare(&raw, DEFAULT_WELD_MM, Closure::Closed).unwrap();
        let solid = MeshSolid::new(&mesh).unwrap();
        let mut uniform = uniform(0x2545_f491_4f6c_dd1du64);
        let mut worst = 0.0f64;
        for _ in 0..10_000 {
            let p = Point3::new(
                -60.0 + 120.0 * uniform(),
                -60.0 + 120.0 * uniform(),
                -30.0 + 180.0 * uniform(),
            );
            let brute = (0..mesh.triangles().len())
                .map(|t| brute_triangle(&p, mesh.corners(t)))
                .fold(f64::INFINITY, f64::min);
            // Inside or outside: the analytic cylinder decides away from the surface.
            let analytic = TubeSolid::new(&tube).signed_distance_mm(&p);
            let d = solid.signed_distance_mm(&p);
            worst = worst.max((d.abs() - brute).abs());
            if analytic.abs() > 2.0 {
                assert_eq!(d < 0.0, analytic < 0.0, "{p}");
            }
        }
        assert!(worst < 1e-6, "largest difference {worst} mm");
    }

    #[test]
    fn mesh_segment_distance_agrees_with_dense_sampling_and_brute_force() {
        let tube = Tube::cylinder(57.0, 120.0, 0.0, 0.0).unwrap();
        let raw = triasym::tube(&tube, 24, 10.0, true).unwrap();
        let (mesh, _) = prepare(&raw, DEFAULT_WELD_MM, Closure::Closed).unwrap();
        let solid = MeshSolid::new(&mesh).unwrap();
        let mut uniform = uniform(0x9e37_79b9_7f4a_7c15u64);
        let point = |u: &mut dyn FnMut() -> f64| {
            Point3::new(
                -90.0 + 180.0 * u(),
                -90.0 + 180.0 * u(),
                -40.0 + 200.0 * u(),
            )
        };
        let mut crossing_seen = false;
        for _ in 0..60 {
            let a = point(&mut uniform);
            let b = point(&mut uniform);
            let d = solid.segment_distance_mm(&a, &b);
            let n = 400;
            let brute = (0..=n)
                .map(|i| {
                    let p = a + (b - a) * (i as f64 / n as f64);
                    (0..mesh.triangles().len())
                        .map(|t| brute_triangle(&p, mesh.corners(t)))
                        .fold(f64::INFINITY, f64::min)
                })
                .fold(f64::INFINITY, f64::min);
            let step = (b - a).norm() / n as f64;
            assert!(d <= brute + 1e-9, "{a} {b}: {d} above sampled {brute}");
            assert!(brute - d <= 0.5 * step + 1e-9, "{a} {b}: {d} vs {brute}");
            crossing_seen |= d == 0.0;
        }
        assert!(crossing_seen, "no segment crossed the surface");
    }

    /// The walk's work counter: every triangle a segment crosses (found by testing all of them)
    /// is among those the walk reaches; a segment far from the mesh reaches none after the
    /// root's boxes; and the walk reaches far fewer than all triangles.
    #[test]
    fn walk_work_reaches_every_crossed_triangle_and_few_others() {
        let tube = Tube::cylinder(57.0, 120.0, 0.0, 0.0).unwrap();
        let raw = triasym::tube(&tube, 48, 5.0, true).unwrap();
        let (mesh, _) = prepare(&raw, DEFAULT_WELD_MM, Closure::Closed).unwrap();
        let solid = MeshSolid::new(&mesh).unwrap();
        let all = mesh.triangles().len() as u64;
        let mut uniform = uniform(0x5851_f42d_4c95_7f2du64);
        let mut crossed_total = 0;
        for _ in 0..40 {
            let mut p = || {
                Point3::new(
                    -60.0 + 120.0 * uniform(),
                    -60.0 + 120.0 * uniform(),
                    -10.0 + 140.0 * uniform(),
                )
            };
            let (a, b) = (p(), p());
            let crossed = (0..mesh.triangles().len())
                .filter(|&t| matches!(crossing(&a, &(b - a), mesh.corners(t)), Some(Some(_))))
                .count() as u64;
            crossed_total += crossed;
            let work = solid.segment_walk_work(&a, &b);
            assert!(work.triangles >= crossed, "{a} {b}: {work:?} < {crossed}");
            // Each triangle reached sits in a leaf box that was tested.
            assert!(
                work.boxes * super::super::bvh::LEAF_ITEMS as u64 >= work.triangles,
                "{work:?}"
            );
            assert!(work.triangles < all / 4, "{a} {b}: {work:?} of {all}");
        }
        assert!(crossed_total > 20, "too few crossings: {crossed_total}");
        let far =
            solid.segment_walk_work(&Point3::new(500.0, 0.0, 0.0), &Point3::new(600.0, 0.0, 0.0));
        // The root's box is tested and not met.
        assert_eq!(
            far,
            WalkWork {
                boxes: 1,
                triangles: 0
            }
        );
    }

    /// The free fibre on a mesh: a straight line through a cylinder mesh at a known distance from
    /// the axis dips in by the analytic depth (less the facets' sagitta); the first point deeper
    /// than the tolerance is where the analytic circle says; a line clear of the surface and one
    /// leaving it tangentially are clear.
    #[test]
    fn mesh_free_fibre_depth_matches_the_cylinder() {
        let r = 28.5;
        let tube = Tube::cylinder(2.0 * r, 120.0, 0.0, 0.0).unwrap();
        let facets = 128;
        let raw = triasym::tube(&tube, facets, 5.0, true).unwrap();
        let (mesh, _) = prepare(&raw, DEFAULT_WELD_MM, Closure::Closed).unwrap();
        let solid = MeshSolid::new(&mesh).unwrap();
        let sagitta = r * (1.0 - (std::f64::consts::PI / facets as f64).cos());
        let tolerance = 0.01;
        // A chord at r − 0.5 from the axis, at 60 mm height, along y.
        for depth in [0.5, 0.05] {
            let x = r - depth;
            let a = Point3::new(x, -80.0, 60.0);
            let b = Point3::new(x, 80.0, 60.0);
            let (value, first) = solid.inside_beyond(&a, &b, tolerance);
            let (s, d) = first.expect("a dip of {depth} mm snags");
            assert!(d < -tolerance && d > -depth - 1e-9, "{d}");
            // Analytic: the chord is deeper than the tolerance from y = −√((r − tol)² − x²);
            // the mesh lies inside the circle by at most the sagitta.
            let y = -((r - tolerance).powi(2) - x * x).sqrt();
            let y_mesh = -((r - tolerance - sagitta).powi(2) - x * x).sqrt();
            let found = -80.0 + 160.0 * s;
            assert!(
                found >= y - 0.05 && found <= y_mesh + 0.05,
                "first snag at y = {found}, expected in [{y}, {y_mesh}]"
            );
            assert!(value <= d);
        }
        // Clear of the surface by 0.5 mm.
        let a = Point3::new(r + 0.5, -80.0, 60.0);
        let b = Point3::new(r + 0.5, 80.0, 60.0);
        assert_eq!(solid.inside_beyond(&a, &b, tolerance), (0.0, None));
        // From a vertex of the mesh (on the circle) along the circle's tangent: clear.
        let t = Point3::new(r, 0.0, 60.0);
        let away = Point3::new(r, 100.0, 80.0);
        let (_, first) =
            solid.inside_beyond(&(t + (away - t).normalize() * 0.005), &away, tolerance);
        assert!(first.is_none());
        // The same tangent line started inside by 0.3 mm: a snag.
        let t = Point3::new(r - 0.3, 0.0, 60.0);
        let (_, first) = solid.inside_beyond(&t, &Point3::new(r - 0.3, 100.0, 80.0), tolerance);
        assert!(first.is_some_and(|(s, _)| s == 0.0));
    }

    /// The mesh's free-fibre check agrees with the analytic cylinder's on 400 random lines near
    /// the surface: the mesh lies inside the circle by at most the facets' sagitta, so a line
    /// deeper than the tolerance by more than the sagitta and the resolution snags, and a line
    /// not as deep as the tolerance is clear.
    #[test]
    fn mesh_free_fibre_check_agrees_with_the_cylinder_on_random_lines() {
        let r = 28.5;
        let tube = Tube::cylinder(2.0 * r, 120.0, 0.0, 0.0).unwrap();
        let raw = triasym::tube(&tube, 128, 5.0, true).unwrap();
        let (mesh, _) = prepare(&raw, DEFAULT_WELD_MM, Closure::Closed).unwrap();
        let solid = MeshSolid::new(&mesh).unwrap();
        let analytic = TubeSolid::new(&tube);
        let sagitta = r * (1.0 - (std::f64::consts::PI / 128.0).cos());
        let tolerance = 0.01;
        let mut uniform = uniform(0x2545_f491_4f6c_dd1du64);
        let (mut snags, mut clear) = (0, 0);
        for _ in 0..400 {
            // A line through a point at r + ρ from the axis, in a random direction across it.
            let angle = std::f64::consts::TAU * uniform();
            let rho = -0.3 + 0.6 * uniform();
            let z = 20.0 + 80.0 * uniform();
            let n = Vector3::new(angle.cos(), angle.sin(), 0.0);
            let c = Point3::new(0.0, 0.0, z) + n * (r + rho);
            let across = Vector3::new(-angle.sin(), angle.cos(), 0.0);
            let dir = (across + Vector3::z() * (uniform() - 0.5)).normalize();
            let (a, b) = (c - dir * 40.0, c + dir * 40.0);
            let deepest = -analytic.segment_min_mm(&a, &b);
            let (_, first) = solid.inside_beyond(&a, &b, tolerance);
            // The mesh lies inside the circle by at most the sagitta.
            if deepest - sagitta > tolerance + RESOLUTION_MM + 1e-6 {
                assert!(first.is_some(), "{a} {b}: {deepest} mm deep");
                snags += 1;
            } else if deepest < tolerance - 1e-6 {
                assert!(first.is_none(), "{a} {b}: {deepest} mm deep");
                clear += 1;
            }
        }
        assert!(snags > 50 && clear > 50, "{snags} snags, {clear} clear");
    }

    #[test]
    fn cylinder_distance_is_the_closed_form() {
        // Tilted cylinder: axis from (31.75, 0, 0) to (95.25, 0, h).
        let tube = Tube::cylinder(63.5, 178.0, 31.75, 95.25).unwrap();
        let solid = TubeSolid::new(&tube);
        let a = Point3::new(31.75, 0.0, 0.0);
        let b = Point3::new(95.25, 0.0, tube.u_max());
        let axis = (b - a).normalize();
        for p in [
            Point3::new(150.0, 20.0, 80.0),
            Point3::new(60.0, 5.0, 50.0),
            Point3::new(-40.0, -30.0, 120.0),
        ] {
            let t = (p - a).dot(&axis);
            assert!(t > 0.0 && t < 178.0);
            let expected = ((p - a) - axis * t).norm() - 31.75;
            let got = solid.signed_distance_mm(&p);
            assert!((got - expected).abs() < 0.01, "{got} vs {expected}");
        }
        // Beyond the bottom end, straight below the axis: the distance to the end plane.
        assert!((solid.signed_distance_mm(&(a - axis * 7.0)) - 7.0).abs() < 1e-9);
    }

    #[test]
    fn segment_minimum_matches_dense_sampling_on_tubes_and_meshes() {
        let sbend = sbend_tube();
        let cylinder = Tube::cylinder(57.0, 200.0, 30.0, 30.0).unwrap();
        let mesh = {
            let raw = triasym::tube(&cylinder, 64, 5.0, true).unwrap();
            prepare(&raw, DEFAULT_WELD_MM, Closure::Closed).unwrap().0
        };
        let solids: Vec<Box<dyn Solid>> = vec![
            Box::new(TubeSolid::new(&sbend)),
            Box::new(TubeSolid::new(&cylinder)),
            Box::new(MeshSolid::new(&mesh).unwrap()),
        ];
        let segments = [
            (
                Point3::new(90.0, -40.0, 20.0),
                Point3::new(-60.0, 50.0, 180.0),
            ),
            (
                Point3::new(70.0, 40.0, -20.0),
                Point3::new(70.0, 40.0, 230.0),
            ),
            (
                Point3::new(10.0, 0.0, 100.0),
                Point3::new(150.0, 0.0, 110.0),
            ),
            (Point3::new(40.0, 5.0, 190.0), Point3::new(45.0, 5.0, 260.0)),
        ];
        for solid in &solids {
            for (a, b) in &segments {
                let got = solid.segment_min_mm(a, b);
                let dense = (0..=20_000)
                    .map(|i| solid.signed_distance_mm(&(a + (b - a) * (i as f64 / 20_000.0))))
                    .fold(f64::INFINITY, f64::min);
                let step = (b - a).norm() / 20_000.0;
                let allowed =
                    (step + RESOLUTION_MM).max(super::super::minimum::RELATIVE * dense.abs());
                assert!(
                    (got - dense).abs() <= allowed + 1e-9,
                    "{solid:?} {a} {b}: {got} vs {dense}"
                );
            }
        }
    }

    /// The capped minimum: the plain one below the cap; at or above it, a value between the cap
    /// and the plain one (a true lower bound). Caps below, near and above each segment's minimum.
    #[test]
    fn capped_segment_minimum_is_exact_below_the_cap_and_a_bound_above() {
        let sbend = sbend_tube();
        let cylinder = Tube::cylinder(57.0, 200.0, 30.0, 30.0).unwrap();
        let mesh = {
            let raw = triasym::tube(&cylinder, 64, 5.0, true).unwrap();
            prepare(&raw, DEFAULT_WELD_MM, Closure::Closed).unwrap().0
        };
        let solids: Vec<Box<dyn Solid>> = vec![
            Box::new(TubeSolid::new(&sbend)),
            Box::new(MeshSolid::new(&mesh).unwrap()),
        ];
        let mut next = uniform(0x2545_f491_4f6c_dd1du64);
        let mut capped_below = 0;
        for solid in &solids {
            for _ in 0..60 {
                let mut p = || {
                    Point3::new(
                        -150.0 + 300.0 * next(),
                        -150.0 + 300.0 * next(),
                        -50.0 + 350.0 * next(),
                    )
                };
                let (a, b) = (p(), p());
                let exact = solid.segment_min_mm(&a, &b);
                let tol = RESOLUTION_MM.max(super::super::minimum::RELATIVE * exact.abs());
                for cap in [exact - 10.0, exact - 0.5, exact + 0.5, exact + 10.0, 0.0] {
                    let got = solid.segment_min_capped_mm(&a, &b, cap);
                    if exact < cap - tol {
                        assert!((got - exact).abs() <= 1e-9, "{solid:?}: {got} vs {exact}");
                    } else {
                        assert!(got >= cap - tol, "{solid:?}: {got} below cap {cap}");
                        assert!(got <= exact + 1e-9, "{solid:?}: {got} above {exact}");
                        capped_below += usize::from(got < exact - 1e-6);
                    }
                }
            }
        }
        // The caps save work: some answers stop at the cap.
        assert!(capped_below > 20, "{capped_below}");
    }

    /// A solid that gives only the two required answers: a ball of radius 10 mm at the origin.
    #[derive(Debug)]
    struct Ball;

    impl Solid for Ball {
        fn signed_distance_mm(&self, p: &Point3<f64>) -> f64 {
            p.coords.norm() - 10.0
        }
        fn surface_point(&self, p: &Point3<f64>) -> Point3<f64> {
            Point3::from(p.coords.normalize() * 10.0)
        }
    }

    /// The trait's defaults: no radius about the axis is known (so the mandrel's turn is bounded
    /// by the moving part's own radius), and the capped minimum is the plain one, which any cap
    /// allows.
    #[test]
    fn a_solid_without_its_own_bounds_gets_the_safe_defaults() {
        assert_eq!(Ball.axis_radius_mm(), f64::INFINITY);
        let (a, b) = (Point3::new(-30.0, 15.0, 0.0), Point3::new(30.0, 15.0, 0.0));
        let plain = Ball.segment_min_mm(&a, &b);
        assert!((plain - 5.0).abs() <= RESOLUTION_MM, "{plain}");
        for cap in [0.0, 3.0, 5.0, 100.0] {
            assert_eq!(Ball.segment_min_capped_mm(&a, &b, cap), plain);
        }
    }

    /// The nearest spine height on the S-bend against a dense scan of the spine (every 0.01 mm
    /// of height) from random points around the tube: never farther than the scan's best.
    #[test]
    fn nearest_spine_height_is_the_global_one() {
        let tube = sbend_tube();
        let solid = TubeSolid::new(&tube);
        let spine = tube.spine();
        let (u0, u1) = (tube.u_min(), tube.u_max());
        let steps = ((u1 - u0) / 0.01) as usize;
        let heights: Vec<(f64, f64)> = (0..=steps)
            .map(|i| {
                let u = u0 + (u1 - u0) * i as f64 / steps as f64;
                (u, spine.offset_mm(u))
            })
            .collect();
        let mut next = uniform(0x1234_5678_9abc_def1u64);
        for _ in 0..300 {
            let p = Point3::new(
                -120.0 + 300.0 * next(),
                -60.0 + 120.0 * next(),
                u0 - 60.0 + (u1 - u0 + 120.0) * next(),
            );
            let d2 = |u: f64, x: f64| (x - p.x).powi(2) + (u - p.z).powi(2);
            let scan = heights
                .iter()
                .map(|&(u, x)| d2(u, x))
                .fold(f64::INFINITY, f64::min);
            let u = solid.nearest_u(&p);
            let got = d2(u, spine.offset_mm(u));
            assert!(got <= scan + 1e-6, "{p}: {got} vs {scan}");
        }
    }

    /// Inside or outside by the ray agrees with the sign of the nearest-point query on random
    /// points in and around two meshes, many within a millimetre of the surface.
    #[test]
    fn ray_inside_test_agrees_with_the_nearest_point() {
        let sbend = sbend_tube();
        let tilted = Tube::cylinder(57.0, 200.0, 30.0, -20.0).unwrap();
        let mut next = uniform(0x9e37_79b9_7f4a_7c15u64);
        let (mut inside, mut near) = (0, 0);
        for tube in [&sbend, &tilted] {
            let mesh = {
                let raw = triasym::tube(tube, 48, 4.0, true).unwrap();
                prepare(&raw, DEFAULT_WELD_MM, Closure::Closed).unwrap().0
            };
            let solid = MeshSolid::new(&mesh).unwrap();
            let (u0, u1) = (tube.u_min(), tube.u_max());
            for k in 0..4000 {
                let p = if k % 2 == 0 {
                    // Within a millimetre of the surface, either side.
                    let u = u0 + (u1 - u0) * next();
                    let v = next() * std::f64::consts::TAU;
                    let s = tube.point(u, v);
                    let n = tube.normal(u, v);
                    s + n * (2.0 * next() - 1.0)
                } else {
                    Point3::new(
                        -150.0 + 300.0 * next(),
                        -150.0 + 300.0 * next(),
                        -30.0 + 360.0 * next(),
                    )
                };
                let (d, _) = solid.nearest(&p);
                let want = d < 0.0;
                assert_eq!(solid.is_inside(&p), want, "{p} at {d} mm");
                inside += usize::from(want);
                near += usize::from(d.abs() < 1.0);
            }
        }
        assert!(inside > 1000 && near > 2000, "{inside} inside, {near} near");
        // A point on the surface (a vertex: the ray starts on a crossing, so the nearest point
        // decides) is not inside, as the signed distance (0) says.
        let mesh = {
            let raw = triasym::tube(&tilted, 48, 4.0, true).unwrap();
            prepare(&raw, DEFAULT_WELD_MM, Closure::Closed).unwrap().0
        };
        let solid = MeshSolid::new(&mesh).unwrap();
        for v in mesh.vertices().iter().step_by(97) {
            assert!(!solid.is_inside(v), "vertex {v}");
        }
    }

    /// The distance from the rotation axis bounds every surface point (dense sampling of the
    /// S-bend, offset and tilted tubes and a mesh) and is loose by no more than 2 mm (the
    /// tilted section's circle and the sampling step's slope term).
    #[test]
    fn axis_radius_bounds_every_surface_point() {
        let sbend = sbend_tube();
        let tilted = Tube::cylinder(57.0, 200.0, 30.0, -20.0).unwrap();
        for tube in [&sbend, &tilted] {
            let solid = TubeSolid::new(tube);
            let mut largest = 0.0f64;
            let (u0, u1) = (tube.u_min(), tube.u_max());
            for i in 0..=2000 {
                let u = u0 + (u1 - u0) * i as f64 / 2000.0;
                for j in 0..72 {
                    let v = j as f64 * std::f64::consts::TAU / 72.0;
                    let q = tube.point(u, v);
                    largest = largest.max(q.x.hypot(q.y));
                }
            }
            let r = solid.axis_radius_mm();
            assert!(r >= largest - 1e-9, "{r} < {largest}");
            assert!(r <= largest + 2.0, "{r} loose against {largest}");
        }
        let mesh = {
            let raw = triasym::tube(&tilted, 64, 5.0, true).unwrap();
            prepare(&raw, DEFAULT_WELD_MM, Closure::Closed).unwrap().0
        };
        let largest = mesh
            .vertices()
            .iter()
            .map(|v| v.x.hypot(v.y))
            .fold(0.0, f64::max);
        assert_eq!(MeshSolid::new(&mesh).unwrap().axis_radius_mm(), largest);
    }

    /// The spine certificate of the free fibre against the search along it (the 1-Lipschitz
    /// signed distance, [`first_below`]) and dense sampling, on lines tangent to the S-bend at
    /// random points in random directions (on the inner side of the bends the surface is
    /// saddle-shaped and some dip in), some started inside, and random segments: it never
    /// certifies a fibre that dips deeper than the tolerance, and it certifies nearly every
    /// tangent fibre that does not (else the check falls back to the slow search).
    #[test]
    fn spine_certificate_never_clears_a_fibre_that_dips() {
        let tube = sbend_tube();
        let solid = TubeSolid::new(&tube);
        let depth = 0.01;
        let mut next = uniform(0x5eed_f1b2_0000_0001u64);
        let (u0, u1) = (tube.u_min(), tube.u_max());
        let (mut tangent_clear, mut tangent_certified, mut dips) = (0, 0, 0);
        for k in 0..1200 {
            let (a, b, tangent) = if k % 3 == 2 {
                let p = |next: &mut dyn FnMut() -> f64| {
                    Point3::new(
                        -100.0 + 200.0 * next(),
                        -60.0 + 120.0 * next(),
                        u0 - 30.0 + (u1 - u0 + 60.0) * next(),
                    )
                };
                (p(&mut next), p(&mut next), false)
            } else {
                let u = u0 + (u1 - u0) * next();
                let v = std::f64::consts::TAU * next();
                let s = tube.point(u, v);
                let n = tube.normal(u, v);
                let e1 = n.cross(&Vector3::z()).normalize();
                let e2 = n.cross(&e1);
                let angle = std::f64::consts::TAU * next();
                let w = e1 * angle.cos() + e2 * angle.sin();
                // One in three starts 0.05 mm inside.
                let start = if k % 3 == 1 { s - n * 0.05 } else { s };
                let length = 20.0 + 280.0 * next();
                (start + w * (0.5 * depth), start + w * length, k % 3 == 0)
            };
            let length = (b - a).norm();
            let along = |t: f64| solid.signed_distance_mm(&(a + (b - a) * t));
            let exact = first_below(&mut |t| along(t), length, RESOLUTION_MM, -depth);
            let dense = (0..=4000)
                .map(|i| along(i as f64 / 4000.0))
                .fold(f64::INFINITY, f64::min);
            let certified = solid.spine_clearance(&a, &b, depth);
            if let Some(c) = certified {
                assert!(exact.first_below.is_none(), "{a} {b}: certified {c}, dips");
                assert!(dense >= -depth - RESOLUTION_MM, "{a} {b}: dense {dense}");
                // The least spine distance less the radius is no more than the signed
                // distance anywhere (to the resolution).
                let tolerance = RESOLUTION_MM.max(RELATIVE * c.abs()) + 1e-9;
                assert!(
                    c <= exact.value + tolerance,
                    "{a} {b}: {c} over {}",
                    exact.value
                );
                assert!(c <= dense + tolerance, "{a} {b}: {c} over dense {dense}");
            }
            if dense < -depth - 2.0 * RESOLUTION_MM {
                dips += 1;
                assert!(certified.is_none());
            }
            if tangent && exact.first_below.is_none() {
                tangent_clear += 1;
                tangent_certified += usize::from(certified.is_some());
            }
        }
        eprintln!("{dips} dip, {tangent_certified} of {tangent_clear} clear tangent certified");
        assert!(dips > 150, "{dips} dipping fibres");
        assert!(tangent_clear > 250, "{tangent_clear} clear tangent fibres");
        assert!(
            tangent_certified * 100 >= tangent_clear * 95,
            "{tangent_certified} of {tangent_clear} certified"
        );
        // A straight tube has its closed form: no certificate.
        let cylinder = TubeSolid::new(&Tube::cylinder(57.0, 200.0, 30.0, 0.0).unwrap());
        let (a, b) = (Point3::new(30.0, 0.0, 50.0), Point3::new(30.0, 100.0, 60.0));
        assert_eq!(cylinder.spine_clearance(&a, &b, depth), None);
    }

    #[test]
    fn surface_points_lie_on_the_surface() {
        let tube = sbend_tube();
        let solid = TubeSolid::new(&tube);
        for p in [
            Point3::new(10.0, 10.0, 100.0),
            Point3::new(-50.0, 3.0, 250.0),
            Point3::new(0.0, 40.0, 175.0),
        ] {
            let s = solid.surface_point(&p);
            assert!(solid.signed_distance_mm(&s).abs() < 1e-6);
            assert!(tube.distance_to_surface_mm(&s).abs() < 1e-6);
            // The analytic tube's own distance, an independent search.
            assert!((solid.signed_distance_mm(&p) - tube.distance_to_surface_mm(&p)).abs() < 1e-6);
        }
    }
}
