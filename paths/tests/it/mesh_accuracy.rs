//! Accuracy of the mesh geodesic tracer against surfaces with known geodesics (the figures are
//! stated in docs/mesh.md; run with `--nocapture` to see them).

use std::f64::consts::{PI, TAU};

use nalgebra::{Point3, Vector3};
use paths::geodesic::{self, Direction, PathStart};
use paths::mesh::trace::{DEFAULT_CREASE_DEG, Mode, Stop, TraceOptions, Tracer};
use paths::mesh::{Closure, DEFAULT_WELD_MM, Mesh, prepare, triasym};
use paths::spine::{SBEND_SMOOTHING_MM, SBEND_TABLE_6_1_MM};
use paths::{Spine, Tube};

fn tracer(mesh: &Mesh, closure: Closure) -> Tracer {
    let (m, adj) = prepare(mesh, DEFAULT_WELD_MM, closure).unwrap();
    Tracer::new(m, &adj, DEFAULT_CREASE_DEG).unwrap()
}

fn wrap(a: f64) -> f64 {
    (a + PI).rem_euclid(TAU) - PI
}

/// Cylinder r = 31.75 mm, 128 facets around, sections every 2 mm: the geodesic at 48.3° to the
/// axis is the helix; the traced path stays within 0.05 mm of it over 178 mm of height.
#[test]
fn cylinder_geodesic_follows_the_helix() {
    let r = 31.75;
    let profile: Vec<(f64, f64)> = (0..=100).map(|i| (-10.0 + 2.0 * i as f64, r)).collect();
    let tr = tracer(
        &triasym::revolution(&profile, 128, true).unwrap(),
        Closure::Closed,
    );
    let psi = 48.3f64.to_radians();
    for mode in [Mode::Smooth, Mode::Exact] {
        for phi0 in [0.0, 0.3, 1.234] {
            let start = Point3::new(r * f64::cos(phi0), r * f64::sin(phi0), 0.0);
            let o = TraceOptions {
                height_range_mm: Some((-1.0, 178.0)),
                mode,
                ..TraceOptions::default()
            };
            let path = tr.trace_heading(&start, psi, 0.1, &o).unwrap();
            assert_eq!(path.stop, Stop::Height);
            assert!((path.points.last().unwrap().z - 178.0).abs() < 1e-9);
            let mut worst = 0.0f64;
            for p in &path.points {
                // Positive headings turn counter-clockwise about the outward normal: −φ here.
                let expect = phi0 - p.z * psi.tan() / r;
                let rho = p.x.hypot(p.y);
                let along = r * wrap(p.y.atan2(p.x) - expect);
                worst = worst.max((rho - r).hypot(along));
            }
            println!("cylinder {mode:?} φ0 = {phi0}: max distance to helix {worst:.4} mm");
            if mode == Mode::Smooth {
                assert!(worst < 0.05, "{worst} mm");
            }
        }
    }
}

/// Cone from r = 40 mm to 20 mm over 100 mm, 256 facets, sections every 1 mm: Clairaut's
/// r · sin α stays constant within 0.5 % along a path that climbs, turns back and descends.
#[test]
fn cone_geodesic_keeps_clairauts_constant() {
    let profile: Vec<(f64, f64)> = (0..=100)
        .map(|i| (i as f64, 40.0 - 0.2 * i as f64))
        .collect();
    let tr = tracer(
        &triasym::revolution(&profile, 256, false).unwrap(),
        Closure::Open,
    );
    let start = Point3::new(39.0, 0.0, 5.0);
    let o = TraceOptions {
        max_length_mm: 600.0,
        ..TraceOptions::default()
    };
    let path = tr
        .trace_heading(&start, 40f64.to_radians(), 0.1, &o)
        .unwrap();
    let clairaut = |a: &Point3<f64>, b: &Point3<f64>| {
        let mid = (a.coords + b.coords) / 2.0;
        let d = (b - a).normalize();
        let rho = mid.x.hypot(mid.y);
        let e_phi = Vector3::new(-mid.y, mid.x, 0.0) / rho;
        rho * d.dot(&e_phi).abs()
    };
    let c0 = clairaut(&path.points[0], &path.points[1]);
    let mut worst = 0.0f64;
    let mut top = 0.0f64;
    for w in path.points.windows(2) {
        if (w[1] - w[0]).norm() > 1e-6 {
            worst = worst.max((clairaut(&w[0], &w[1]) / c0 - 1.0).abs());
        }
        top = top.max(w[1].z);
    }
    println!(
        "cone: r sin α = {c0:.4} mm, max relative change {:.5} %, turned back at z = {top:.2} mm, {} crossings",
        100.0 * worst,
        path.crossings
    );
    assert!(
        top < 90.0 && path.points.last().unwrap().z < 1.0,
        "it turns back"
    );
    assert!(worst < 0.005, "{worst}");
}

/// Icosphere of 81 920 faces: 1.5 turns stay within 1.5e-3 R of a plane through the centre, from
/// several starts and headings.
#[test]
fn sphere_geodesic_stays_on_a_great_circle() {
    let radius = 50.0;
    let tr = tracer(&triasym::icosphere(radius, 6).unwrap(), Closure::Closed);
    assert_eq!(tr.mesh().triangles().len(), 81_920);
    let mut worst_all = [0.0f64; 2];
    for (k, mode) in [Mode::Smooth, Mode::Exact].into_iter().enumerate() {
        for i in 0..8 {
            let a = 0.7 + 1.3 * i as f64;
            let b = 0.4 * i as f64 - 1.2;
            let dir = Vector3::new(a.cos() * b.cos(), a.sin() * b.cos(), b.sin());
            let start = Point3::from(dir * radius);
            let heading = (17.0 + 41.0 * i as f64).to_radians();
            let o = TraceOptions {
                max_length_mm: 1.5 * TAU * radius,
                axis: Vector3::new(0.2, -0.3, 1.0).normalize(),
                mode,
                ..TraceOptions::default()
            };
            let path = tr.trace_heading(&start, heading, 0.5, &o).unwrap();
            assert_eq!(path.stop, Stop::Length);
            // The plane through the centre, the start and the initial direction.
            let n = tr.locate(&start).unwrap().normal;
            let r = (o.axis - n * o.axis.dot(&n)).normalize();
            let t0 = r * heading.cos() + n.cross(&r) * heading.sin();
            let plane = path.points[0].coords.cross(&t0).normalize();
            let worst = path
                .points
                .iter()
                .map(|p| p.coords.dot(&plane).abs() / radius)
                .fold(0.0, f64::max);
            worst_all[k] = worst_all[k].max(worst);
        }
    }
    println!(
        "sphere: max plane deviation smooth {:.2e} R, exact {:.2e} R",
        worst_all[0], worst_all[1]
    );
    assert!(worst_all[0] < 1.5e-3, "{}", worst_all[0]);
}

fn sbend() -> Tube {
    Tube::new(
        Spine::smoothing(&SBEND_TABLE_6_1_MM, SBEND_SMOOTHING_MM).unwrap(),
        28.5,
    )
    .unwrap()
}

/// The analytic swept-tube geodesic's start point and unit direction.
fn analytic_start(tube: &Tube, start: &PathStart) -> (Point3<f64>, Vector3<f64>) {
    let u0 = match start.direction {
        Direction::Down => tube.u_max(),
        Direction::Up => tube.u_min(),
    };
    let sign = if start.direction == Direction::Down {
        -1.0
    } else {
        1.0
    };
    let d = tube.derivatives(u0, start.angle_rad);
    let (s, c) = start.wind_angle_rad.sin_cos();
    let t = d.xu.normalize() * (sign * c) + d.xv.normalize() * s;
    (tube.point(u0, start.angle_rad), t.normalize())
}

/// Largest distance from `points` to the polyline `curve` (both in order along the path).
fn max_distance_to_polyline(points: &[Point3<f64>], curve: &[Point3<f64>]) -> f64 {
    let mut worst = 0.0f64;
    let mut k = 0usize;
    for p in points {
        let mut best = f64::INFINITY;
        let lo = k.saturating_sub(50);
        let hi = (k + 400).min(curve.len() - 1);
        for i in lo..hi {
            let (a, b) = (curve[i], curve[i + 1]);
            let ab = b - a;
            let t = ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
            let d = (a + ab * t - p).norm();
            if d < best {
                best = d;
                k = i;
            }
        }
        worst = worst.max(best);
    }
    worst
}

/// S-bend (Table 6.1, r = 28.5 mm), TRIASYM mesh of 256 facets and 1.25 mm sections: the mesh
/// geodesic stays within 0.15 mm of the analytic swept-tube geodesic, end to end, both ways
/// (within 0.04 mm on the 45° paths; the 60° path is 820 mm long).
#[test]
fn sbend_mesh_geodesic_matches_the_analytic_one() {
    let tube = sbend();
    let tr = tracer(
        &triasym::tube(&tube, 256, 1.25, true).unwrap(),
        Closure::Closed,
    );
    for (direction, angle_deg, wind_deg) in [
        (Direction::Down, 90.0, 45.0),
        (Direction::Up, 90.0, 45.0),
        (Direction::Down, 200.0, 30.0),
        (Direction::Up, 10.0, 60.0),
    ] {
        let start = PathStart {
            angle_rad: f64::to_radians(angle_deg),
            wind_angle_rad: f64::to_radians(wind_deg),
            direction,
        };
        let analytic = geodesic::trace(&tube, &start, 0.25).unwrap();
        let curve: Vec<Point3<f64>> = analytic
            .samples
            .iter()
            .map(|s| tube.point(s.u, s.v))
            .collect();
        let (p0, t0) = analytic_start(&tube, &start);
        let path = tr
            .trace_direction(&p0, &t0, 0.1, &TraceOptions::default())
            .unwrap();
        assert_eq!(path.stop, Stop::Boundary, "{direction:?}");
        let worst = max_distance_to_polyline(&path.points, &curve);
        let end_gap = (path.points.last().unwrap() - curve.last().unwrap()).norm();
        println!(
            "s-bend {direction:?} {angle_deg}° {wind_deg}°: max distance {worst:.4} mm, end gap {end_gap:.4} mm, \
             length {:.2} vs {:.2} mm",
            path.length_mm,
            analytic.length_mm()
        );
        assert!(worst < 0.15, "{worst} mm");
    }
}

/// λ = 0 is the geodesic, bit for bit; λ ≠ 0 bends the path; |λ| > μ is refused.
#[test]
fn slip_ratio_zero_is_the_geodesic() {
    let tube = sbend();
    let tr = tracer(
        &triasym::tube(&tube, 64, 5.0, true).unwrap(),
        Closure::Closed,
    );
    let start = Point3::new(tube.point(100.0, 0.5).x, tube.point(100.0, 0.5).y, 100.0);
    let geodesic = TraceOptions {
        max_length_mm: 300.0,
        ..TraceOptions::default()
    };
    let zero = TraceOptions {
        lambda: 0.0,
        mu: Some(0.3),
        ..geodesic
    };
    let a = tr.trace_heading(&start, 0.8, 1.0, &geodesic).unwrap();
    let b = tr.trace_heading(&start, 0.8, 1.0, &zero).unwrap();
    assert_eq!(a, b);
    let slip = TraceOptions {
        lambda: 0.2,
        mu: Some(0.3),
        ..geodesic
    };
    let c = tr.trace_heading(&start, 0.8, 1.0, &slip).unwrap();
    let gap = (c.points.last().unwrap() - a.points.last().unwrap()).norm();
    assert!(gap > 1.0, "slip moved the end by {gap} mm");
    let refused = TraceOptions {
        lambda: 0.35,
        mu: Some(0.3),
        ..geodesic
    };
    let e = tr.trace_heading(&start, 0.8, 1.0, &refused).unwrap_err();
    assert!(e.to_string().contains("exceeds the friction"), "{e}");
}
