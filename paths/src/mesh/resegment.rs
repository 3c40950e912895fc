//! Smoothing and resegmentation of a traced or imported path (seed 001 §5.5: the path is fitted by
//! a spline and divided into equal-length segments whose end points lie on the surface).
//!
//! The raw path (edge crossings, or DXF points) is resampled at equal arc length every
//! `spacing_mm` or less, a cubic B-spline ([`crate::spline::BSpline::interpolate`], the spline core
//! shared with the lathe winder) is passed through the samples, cut into `segments` pieces of equal
//! arc length, and each end point is projected back onto the surface ([`Projection`]: the mesh's
//! nearest point with its smooth normal, or the analytic tube's exact nearest point and normal). Each end point's angle around the mandrel axis is the path's own,
//! followed along the smoothed path between end points (never the nearest to the previous end
//! point's, which would fold a segment turning more than half a revolution back). The largest distance between the raw and the smoothed path is measured at
//! every raw point between two samples and at the midpoint of every sample interval.

use nalgebra::{Point3, Vector3};

use super::trace::{MeshPath, Stop, TraceOptions, Tracer};
use crate::clearance::TubeSolid;
use crate::geodesic::{Direction, PathStart};
use crate::limits;
use crate::spline::BSpline;
use crate::{Error, SurfacePoint, Tube};

/// Default resampling spacing, mm.
pub const DEFAULT_SPACING_MM: f64 = 2.0;

/// A surface that cut points are projected onto.
pub trait Projection {
    /// The surface point nearest to `p` with the outward unit normal there, and the mesh
    /// triangle holding it (`None` on an analytic surface); `None` for a point with no nearest
    /// point (not finite).
    fn project(&self, p: &Point3<f64>) -> Option<(Point3<f64>, Vector3<f64>, Option<u32>)>;
}

impl Projection for Tracer {
    fn project(&self, p: &Point3<f64>) -> Option<(Point3<f64>, Vector3<f64>, Option<u32>)> {
        self.locate(p)
            .map(|at| (at.point, at.normal, Some(at.face as u32)))
    }
}

impl Projection for TubeSolid {
    fn project(&self, p: &Point3<f64>) -> Option<(Point3<f64>, Vector3<f64>, Option<u32>)> {
        if !p.iter().all(|c| c.is_finite()) {
            return None;
        }
        let (point, normal) = self.nearest_surface(p);
        Some((point, normal, None))
    }
}

/// A path cut into equal-length segments on the surface.
#[derive(Debug, Clone, PartialEq)]
pub struct Resegmented {
    /// `segments + 1` end points on the surface, with their normals.
    pub points: Vec<SurfacePoint>,
    /// The mesh triangle of each end point (empty on an analytic surface).
    pub faces: Vec<u32>,
    /// Largest distance between the raw path and the smoothed one, mm.
    pub max_deviation_mm: f64,
    /// Arc length of the smoothed path, mm.
    pub length_mm: f64,
}

/// Resampled points, their arc lengths, and the raw points' arc lengths.
type Resampled = (Vec<Point3<f64>>, Vec<f64>, Vec<f64>);

/// Points at equal arc length along a polyline (both ends kept), at most `spacing_mm` apart, and
/// their arc lengths.
/// The path's length and the sample count are checked against [`limits`] before anything is
/// allocated for the samples.
fn resample(raw: &[Point3<f64>], spacing_mm: f64) -> Result<Resampled, Error> {
    let mut cum = Vec::with_capacity(raw.len());
    let mut total = 0.0;
    cum.push(0.0);
    for w in raw.windows(2) {
        total += (w[1] - w[0]).norm();
        cum.push(total);
    }
    limits::at_most("path length_mm", total, limits::MAX_PATH_LENGTH_MM)?;
    let n = (total / spacing_mm).ceil().max(3.0);
    limits::at_most("path samples", n, limits::MAX_PATH_SAMPLES as f64)?;
    let n = n as usize;
    let mut out = Vec::with_capacity(n + 1);
    let mut at = Vec::with_capacity(n + 1);
    let mut k = 0;
    for i in 0..=n {
        let s = total * i as f64 / n as f64;
        while k + 2 < cum.len() && cum[k + 1] < s {
            k += 1;
        }
        let span = cum[k + 1] - cum[k];
        let f = if span > 0.0 {
            ((s - cum[k]) / span).clamp(0.0, 1.0)
        } else {
            0.0
        };
        out.push(raw[k] + (raw[k + 1] - raw[k]) * f);
        at.push(s);
    }
    Ok((out, at, cum))
}

/// Smooths `raw` and cuts it into `segments` equal-length pieces with end points on `surface`
/// (see the module documentation).
pub fn smooth_and_cut(
    surface: &dyn Projection,
    raw: &[Point3<f64>],
    segments: usize,
    spacing_mm: f64,
) -> Result<Resegmented, Error> {
    if segments == 0 {
        return Err(Error::OutOfRange {
            name: "segments",
            value: 0.0,
            expected: "must be at least 1",
        });
    }
    limits::at_most("segments", segments as f64, limits::MAX_SEGMENTS as f64)?;
    if !(spacing_mm > 0.0 && spacing_mm.is_finite()) {
        return Err(Error::OutOfRange {
            name: "spacing_mm",
            value: spacing_mm,
            expected: "must be > 0",
        });
    }
    // Drop repeated points; a path needs some length.
    let mut clean: Vec<Point3<f64>> = Vec::with_capacity(raw.len());
    for (index, p) in raw.iter().enumerate() {
        if !p.iter().all(|c| c.is_finite()) {
            return Err(Error::NonFinitePoint { index });
        }
        if clean.last().is_none_or(|q| (p - q).norm() > 1e-9) {
            clean.push(*p);
        }
    }
    if clean.len() < 2 {
        return Err(Error::TooFewPoints {
            what: "path to smooth",
            count: clean.len(),
            needed: 2,
        });
    }
    let (samples, at, cum) = resample(&clean, spacing_mm)?;
    let coords: Vec<Vector3<f64>> = samples.iter().map(|p| p.coords).collect();
    let spline = BSpline::<3>::interpolate(&coords)?;
    // Chord-length parameters of the samples (the interpolant's own).
    let mut params = Vec::with_capacity(coords.len());
    let mut chord = 0.0;
    params.push(0.0);
    for w in coords.windows(2) {
        chord += (w[1] - w[0]).norm();
        params.push(chord);
    }
    for p in &mut params {
        *p /= chord.max(f64::MIN_POSITIVE);
    }
    // Deviation: each raw point against the spline at its interpolated parameter, and the
    // interval midpoints.
    let mut max_dev = 0.0f64;
    let mut j = 0;
    for (i, p) in clean.iter().enumerate() {
        let s = cum[i];
        while j + 2 < at.len() && at[j + 1] < s {
            j += 1;
        }
        let span = at[j + 1] - at[j];
        let f = if span > 0.0 {
            ((s - at[j]) / span).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let t = params[j] + (params[j + 1] - params[j]) * f;
        max_dev = max_dev.max((spline.eval(t) - p.coords).norm());
    }
    let params = spline.equal_length_parameters(segments)?;
    let cut: Vec<Vector3<f64>> = params.iter().map(|&t| spline.eval(t)).collect();
    // The path's own angle around the axis: followed along the smoothed path between the cut
    // points, at most `spacing_mm` of arc per look (a few degrees on any mandrel this cell winds),
    // so a segment that turns the path by more than half a revolution keeps its whole turn.
    let between = ((spline.length() / segments as f64) / spacing_mm)
        .ceil()
        .max(1.0);
    limits::at_most(
        "path samples",
        between * segments as f64,
        limits::MAX_PATH_SAMPLES as f64,
    )?;
    let between = between as usize;
    let mut points = Vec::with_capacity(cut.len());
    let mut faces = Vec::with_capacity(cut.len());
    let last = cut.len() - 1;
    let mut around = 0.0;
    for (index, c) in cut.iter().enumerate() {
        if index > 0 {
            let (t0, t1) = (params[index - 1], params[index]);
            for i in 1..between {
                let t = t0 + (t1 - t0) * i as f64 / between as f64;
                // A look that lands on an end cap (normal nearly vertical) has no angle.
                if let Some((_, normal, _)) = surface.project(&Point3::from(spline.eval(t)))
                    && normal.xy().norm() > 0.5
                {
                    around = crate::segment::around_near(&normal, around);
                }
            }
        }
        // The end points sit on the rim of an end cap: look a micrometre inward along the path so
        // they take the winding surface's triangle and normal, not the cap's.
        let inward = match index {
            0 => (cut[1] - c).try_normalize(0.0).unwrap_or_default() * 1e-3,
            i if i == last => (cut[last - 1] - c).try_normalize(0.0).unwrap_or_default() * 1e-3,
            _ => Vector3::zeros(),
        };
        let (point, normal, face) = surface
            .project(&Point3::from(c + inward))
            .ok_or(Error::NonFinitePoint { index })?;
        around = crate::segment::around_near(&normal, around);
        points.push(SurfacePoint {
            point,
            normal,
            around_rad: around,
        });
        faces.extend(face);
    }
    Ok(Resegmented {
        points,
        faces,
        max_deviation_mm: max_dev,
        length_mm: spline.length(),
    })
}

/// Where and in which direction a path of `start` begins on the analytic `tube` the mesh models:
/// the spine end it starts from, at `start.angle_rad` around the spine, at the wind angle to the
/// spine (the same start as [`crate::geodesic::trace`]).
pub fn tube_start(tube: &Tube, start: &PathStart) -> (Point3<f64>, Vector3<f64>) {
    let (u0, sign) = match start.direction {
        Direction::Down => (tube.u_max(), -1.0),
        Direction::Up => (tube.u_min(), 1.0),
    };
    let d = tube.derivatives(u0, start.angle_rad);
    let (s, c) = start.wind_angle_rad.sin_cos();
    let t = d.xu.normalize() * (sign * c) + d.xv.normalize() * s;
    (tube.point(u0, start.angle_rad), t.normalize())
}

/// One fibre path on a mesh mandrel: traced from the start `tube` gives (its spine is the mesh's)
/// until the far end cap's rim, smoothed and cut into `segments` equal-length pieces on the mesh.
pub fn wind(
    tracer: &Tracer,
    tube: &Tube,
    start: &PathStart,
    segments: usize,
    options: &TraceOptions,
) -> Result<(MeshPath, Resegmented), Error> {
    let (p0, t0) = tube_start(tube, start);
    let path = tracer.trace_direction(&p0, &t0, 0.5, options)?;
    if matches!(path.stop, Stop::Length | Stop::Stuck | Stop::CrossingLimit) {
        let last = path.points.last().copied().unwrap_or(p0);
        return Err(Error::PathTurnedBack { height_mm: last.z });
    }
    let cut = smooth_and_cut(tracer, &path.points, segments, DEFAULT_SPACING_MM)?;
    Ok((path, cut))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::trace::{DEFAULT_CREASE_DEG, TraceOptions};
    use crate::mesh::{Closure, DEFAULT_WELD_MM, prepare, triasym};

    /// Points drawn 0.3 mm off the S-bend tube (a helix-like curve around the spine, as a DXF
    /// drawn slightly off the surface) are projected onto the analytic tube itself: every end
    /// point on the surface by the tube's own distance (an independent search), its normal the
    /// unit direction from the spine's nearest point, no mesh triangles.
    #[test]
    fn imported_points_are_projected_onto_the_analytic_tube() {
        let tube = crate::clearance::test_support::sbend_tube();
        let (u0, u1) = (tube.u_min(), tube.u_max());
        let raw: Vec<Point3<f64>> = (0..=200)
            .map(|i| {
                let u = u0 + 5.0 + (u1 - u0 - 10.0) * i as f64 / 200.0;
                let v = 0.02 * (u - u0);
                tube.point(u, v) + tube.normal(u, v) * 0.3
            })
            .collect();
        let solid = TubeSolid::new(&tube);
        let r = smooth_and_cut(&solid, &raw, 40, DEFAULT_SPACING_MM).unwrap();
        assert_eq!(r.points.len(), 41);
        assert!(r.faces.is_empty());
        for p in &r.points {
            assert!(
                tube.distance_to_surface_mm(&p.point).abs() < 1e-6,
                "{}",
                p.point
            );
            assert!((p.normal.norm() - 1.0).abs() < 1e-12);
            // The normal points from the surface point away from the spine: one radius back
            // along it is a spine point (the nearest one).
            let centre = p.point - p.normal * tube.radius_mm();
            let [x, g, _, _] = tube.spine().eval(centre.z);
            assert!(
                (centre.x - x).abs() < 1e-6 && centre.y.abs() < 1e-9,
                "{centre}"
            );
            // ... and the normal is square to the spine there.
            assert!(p.normal.dot(&Vector3::new(g, 0.0, 1.0)).abs() < 1e-9);
        }
        // The projection of a point that is not finite is refused, not made up.
        assert!(solid.project(&Point3::new(f64::NAN, 0.0, 1.0)).is_none());
    }

    #[test]
    fn helix_on_a_meshed_cylinder_is_cut_into_equal_chords_on_the_surface() {
        let profile: Vec<(f64, f64)> = (0..=45).map(|i| (4.0 * i as f64, 31.75)).collect();
        let (m, adj) = prepare(
            &triasym::revolution(&profile, 128, true).unwrap(),
            DEFAULT_WELD_MM,
            Closure::Closed,
        )
        .unwrap();
        let tr = Tracer::new(m, &adj, DEFAULT_CREASE_DEG).unwrap();
        let o = TraceOptions {
            height_range_mm: Some((0.0, 178.0)),
            ..TraceOptions::default()
        };
        let path = tr
            .trace_heading(&Point3::new(31.75, 0.0, 1.0), 0.843, 0.1, &o)
            .unwrap();
        let r = smooth_and_cut(&tr, &path.points, 50, DEFAULT_SPACING_MM).unwrap();
        assert_eq!(r.points.len(), 51);
        assert!(r.max_deviation_mm < 0.01, "{}", r.max_deviation_mm);
        let chords: Vec<f64> = r
            .points
            .windows(2)
            .map(|w| (w[1].point - w[0].point).norm())
            .collect();
        let mean = chords.iter().sum::<f64>() / 50.0;
        for c in &chords {
            assert!((c / mean - 1.0).abs() < 1e-3, "{c} vs {mean}");
        }
        for p in &r.points {
            assert!((p.point.x.hypot(p.point.y) - 31.75).abs() < 0.02);
            assert!((p.normal.norm() - 1.0).abs() < 1e-12);
        }
        assert!(smooth_and_cut(&tr, &path.points, 0, 2.0).is_err());
        assert!(smooth_and_cut(&tr, &path.points[..1], 5, 2.0).is_err());
    }

    #[test]
    fn each_end_points_angle_follows_the_path_however_far_a_segment_turns() {
        // A helix drawn every 2° on a meshed cylinder, cut into 2 segments: each end point's
        // angle around the axis is the path's own, the whole turn per segment (0.4 or 0.6
        // revolution, counter-clockwise or clockwise), never folded to within half a turn.
        let profile: Vec<(f64, f64)> = (0..=45).map(|i| (4.0 * i as f64, 31.75)).collect();
        let (m, adj) = prepare(
            &triasym::revolution(&profile, 256, true).unwrap(),
            DEFAULT_WELD_MM,
            Closure::Closed,
        )
        .unwrap();
        let tr = Tracer::new(m, &adj, DEFAULT_CREASE_DEG).unwrap();
        for turns in [0.8, 1.2, -0.8, -1.2] {
            let n = (f64::abs(turns) * 180.0) as usize;
            let raw: Vec<Point3<f64>> = (0..=n)
                .map(|k| {
                    let f = k as f64 / n as f64;
                    let a = std::f64::consts::TAU * turns * f;
                    Point3::new(31.75 * a.cos(), 31.75 * a.sin(), 178.0 * (1.0 - f))
                })
                .collect();
            let r = smooth_and_cut(&tr, &raw, 2, DEFAULT_SPACING_MM).unwrap();
            let per_segment = std::f64::consts::TAU * turns / 2.0;
            for (k, p) in r.points.iter().enumerate() {
                let expected = per_segment * k as f64;
                assert!(
                    (p.around_rad - expected).abs() < 1e-3,
                    "{turns}: point {k} at {} rad, expected {expected}",
                    p.around_rad
                );
            }
        }
    }

    #[test]
    fn paths_longer_than_the_limits_are_refused_before_resampling() {
        let profile: Vec<(f64, f64)> = (0..=10).map(|i| (10.0 * i as f64, 20.0)).collect();
        let (m, adj) = prepare(
            &triasym::revolution(&profile, 32, true).unwrap(),
            DEFAULT_WELD_MM,
            Closure::Closed,
        )
        .unwrap();
        let tr = Tracer::new(m, &adj, DEFAULT_CREASE_DEG).unwrap();
        let on = |z: f64| Point3::new(20.0, 0.0, z);
        for far in [1e9, 1e308, f64::MAX] {
            let raw = [on(10.0), on(20.0), Point3::new(20.0, far, 30.0), on(40.0)];
            assert!(
                matches!(
                    smooth_and_cut(&tr, &raw, 5, DEFAULT_SPACING_MM),
                    Err(Error::OverLimit { .. })
                ),
                "{far}"
            );
        }
        // Samples: a 50 mm path at a spacing that needs more than the most samples.
        let spacing = 50.0 / crate::limits::MAX_PATH_SAMPLES as f64;
        let raw = [on(10.0), on(60.0)];
        assert!(matches!(
            smooth_and_cut(&tr, &raw, 2, spacing * 0.99),
            Err(Error::OverLimit { .. })
        ));
    }
}
