//! The mandrel as a solid: signed distance (negative inside), the nearest surface point, and the
//! least signed distance along a segment. Mandrel frame, mm.

use std::fmt;

use nalgebra::{Point3, Vector3};
use parry3d_f64::math::{Pose, Vector};
use parry3d_f64::query::{self, PointQuery};
use parry3d_f64::shape::{Segment, TriMesh, TriMeshFlags};

use super::minimum::first_below;
use super::{RESOLUTION_MM, certified_min, golden_min};
use crate::mesh::Mesh;
use crate::{Error, Tube};

/// A mandrel solid.
pub trait Solid: fmt::Debug + Send + Sync {
    /// Distance from `p` to the surface, negative inside.
    fn signed_distance_mm(&self, p: &Point3<f64>) -> f64;

    /// The surface point nearest to `p`.
    fn surface_point(&self, p: &Point3<f64>) -> Point3<f64>;

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
    /// Straight spine: bottom centre, unit axis, axial length.
    straight: Option<(Point3<f64>, Vector3<f64>, f64)>,
    /// Bent spine: sample heights for the nearest-point search.
    samples: Vec<f64>,
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
            .map(|i| u0 + (u1 - u0) * i as f64 / count as f64)
            .collect();
        TubeSolid {
            tube: tube.clone(),
            straight,
            samples,
        }
    }

    /// The nearest spine height to `p` (clamped to the spine's ends).
    fn nearest_u(&self, p: &Point3<f64>) -> f64 {
        let spine = self.tube.spine();
        let d2 = |u: f64| {
            let x = spine.offset_mm(u);
            (x - p.x) * (x - p.x) + (u - p.z) * (u - p.z)
        };
        let mut best = self.samples[0];
        let mut best_d2 = d2(best);
        for &u in &self.samples[1..] {
            let d = d2(u);
            if d < best_d2 {
                best = u;
                best_d2 = d;
            }
        }
        let (u0, u1) = (self.tube.u_min(), self.tube.u_max());
        let mut u = best;
        for _ in 0..8 {
            let [x, g, dg, _] = spine.eval(u);
            let first = (x - p.x) * g + (u - p.z);
            let second = g * g + (x - p.x) * dg + 1.0;
            if second <= 0.0 {
                break;
            }
            let next = (u - first / second).clamp(u0, u1);
            if (next - u).abs() < 1e-12 {
                u = next;
                break;
            }
            u = next;
        }
        if d2(u) <= best_d2 { u } else { best }
    }
}

/// Signed distance of a capped cylinder from the radial and axial excesses (`ρ − r`, distance
/// beyond the nearer end, negative inside).
fn capped(radial: f64, axial: f64) -> f64 {
    let outside = radial.max(0.0).hypot(axial.max(0.0));
    outside + radial.max(axial).min(0.0)
}

impl Solid for TubeSolid {
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
        match radial.try_normalize(1e-12) {
            Some(n) => c + n * r,
            None => c + tangent.cross(&Vector3::y()).normalize() * r,
        }
    }

    fn segment_min_mm(&self, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
        let Some((base, axis, length)) = &self.straight else {
            let length = (b - a).norm();
            return certified_min(
                &mut |t| self.signed_distance_mm(&(a + (b - a) * t)),
                length,
                RESOLUTION_MM,
                f64::NEG_INFINITY,
            )
            .value;
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

/// A closed triangle mesh as a solid, through parry3d's bounding-volume hierarchy; inside and
/// outside from its angle-weighted pseudo-normals.
pub struct MeshSolid {
    shape: TriMesh,
}

impl fmt::Debug for MeshSolid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("MeshSolid")
            .field("triangles", &self.shape.indices().len())
            .finish()
    }
}

fn to_parry(p: &Point3<f64>) -> Vector {
    Vector::new(p.x, p.y, p.z)
}

impl MeshSolid {
    /// The solid of a closed, outward-oriented mesh (as [`crate::mesh::prepare`] returns it).
    pub fn new(mesh: &Mesh) -> Result<Self, Error> {
        let vertices = mesh.vertices().iter().map(to_parry).collect();
        let shape =
            TriMesh::with_flags(vertices, mesh.triangles().to_vec(), TriMeshFlags::ORIENTED)
                .map_err(|e| Error::MeshInvalid {
                    triangle: None,
                    reason: format!("the collision mesh cannot be built: {e:?}"),
                })?;
        Ok(MeshSolid { shape })
    }
}

impl Solid for MeshSolid {
    fn inside_beyond(
        &self,
        a: &Point3<f64>,
        b: &Point3<f64>,
        depth_mm: f64,
    ) -> (f64, Option<(f64, f64)>) {
        let segment = Segment::new(to_parry(a), to_parry(b));
        let distance = query::distance(&Pose::IDENTITY, &segment, &Pose::IDENTITY, &self.shape)
            .map_or(0.0, |d| d.distance);
        if distance > 0.0 && self.signed_distance_mm(a) >= 0.0 {
            return (distance, None);
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
        let q = to_parry(p);
        let projection = self.shape.project_local_point(q, false);
        let d = (projection.point - q).length();
        if projection.is_inside { -d } else { d }
    }

    fn surface_point(&self, p: &Point3<f64>) -> Point3<f64> {
        let projection = self.shape.project_local_point(to_parry(p), false);
        Point3::new(projection.point.x, projection.point.y, projection.point.z)
    }

    fn segment_min_mm(&self, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
        let segment = Segment::new(to_parry(a), to_parry(b));
        let distance = query::distance(&Pose::IDENTITY, &segment, &Pose::IDENTITY, &self.shape)
            .map_or(0.0, |d| d.distance);
        if distance > 0.0 {
            // Apart from the surface: wholly outside or wholly inside.
            return if self.signed_distance_mm(a) >= 0.0 {
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
    use crate::Spine;
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
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut uniform = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
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
        let sbend = Tube::new(
            Spine::smoothing(
                &crate::spine::SBEND_TABLE_6_1_MM,
                crate::spine::SBEND_SMOOTHING_MM,
            )
            .unwrap(),
            28.5,
        )
        .unwrap();
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

    #[test]
    fn surface_points_lie_on_the_surface() {
        let tube = Tube::new(
            Spine::smoothing(
                &crate::spine::SBEND_TABLE_6_1_MM,
                crate::spine::SBEND_SMOOTHING_MM,
            )
            .unwrap(),
            28.5,
        )
        .unwrap();
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
