//! Equal-length segmentation of a fibre path (seed 001 §3.2, §5.5: the path is divided into
//! segments of equal length, 50 in the experiments; the end points lie on the surface).

use nalgebra::{Point3, Vector3};

use crate::{Error, SurfacePath, Tube};

/// A point on the mandrel surface with its outward unit normal, in the mandrel frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// The point, mm.
    pub point: Point3<f64>,
    /// The outward unit normal.
    pub normal: Vector3<f64>,
    /// The angle of the normal's horizontal part about the mandrel frame's `z` axis, continuous
    /// along the path (not wrapped): the path's own angle, by which the planner unwraps the
    /// mandrel angle. Rad.
    pub around_rad: f64,
}

/// `atan2(n_y, n_x)` moved by whole revolutions to lie within half a revolution of `near_rad`.
pub fn around_near(normal: &Vector3<f64>, near_rad: f64) -> f64 {
    let raw = normal.y.atan2(normal.x);
    raw + std::f64::consts::TAU * ((near_rad - raw) / std::f64::consts::TAU).round()
}

/// Cuts `path` into `segments` pieces of equal arc length and returns the `segments + 1` end
/// points, each exactly on the surface (the parameters are interpolated, then mapped).
pub fn equal_length(
    tube: &Tube,
    path: &SurfacePath,
    segments: usize,
) -> Result<Vec<SurfacePoint>, Error> {
    if segments == 0 {
        return Err(Error::OutOfRange {
            name: "segments",
            value: 0.0,
            expected: "must be at least 1",
        });
    }
    crate::limits::at_most(
        "segments",
        segments as f64,
        crate::limits::MAX_SEGMENTS as f64,
    )?;
    let length = path.length_mm();
    Ok((0..=segments)
        .map(|k| {
            let (u, v) = path.at(length * k as f64 / segments as f64);
            let normal = tube.normal(u, v);
            // v, the angle around the spine, is continuous along the traced path; the normal's
            // angle stays within a quarter revolution of it on any tube the spine check accepts.
            SurfacePoint {
                point: tube.point(u, v),
                normal,
                around_rad: around_near(&normal, v),
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geodesic::{Direction, PathStart, helix};
    use approx::assert_abs_diff_eq;

    #[test]
    fn helix_segments_have_equal_chords_and_lie_on_the_surface() {
        let tube = Tube::cylinder(63.5, 178.0, 0.0, 0.0).unwrap();
        let start = PathStart {
            angle_rad: 0.3,
            wind_angle_rad: 48.3f64.to_radians(),
            direction: Direction::Down,
        };
        let path = helix(&tube, &start, 1.0).unwrap();
        let points = equal_length(&tube, &path, 50).unwrap();
        assert_eq!(points.len(), 51);
        let chord = (points[1].point - points[0].point).norm();
        for pair in points.windows(2) {
            assert_abs_diff_eq!(
                (pair[1].point - pair[0].point).norm(),
                chord,
                epsilon = 1e-9
            );
        }
        for p in &points {
            let radial = (p.point.x.powi(2) + p.point.y.powi(2)).sqrt();
            assert_abs_diff_eq!(radial, 31.75, epsilon = 1e-9);
        }
        assert_abs_diff_eq!(points[0].point.z, 178.0, epsilon = 1e-9);
        assert_abs_diff_eq!(points[50].point.z, 0.0, epsilon = 1e-9);
        assert!(equal_length(&tube, &path, 0).is_err());
    }
}
