//! The placement model on a triangulated mandrel against the analytic one: the same eye motion
//! over the S-bend tube and over its TRIASYM mesh lays the same fibre, within the mesh's own
//! distance from the tube.

use nalgebra::{Point3, Vector3};
use paths::mesh::trace::{DEFAULT_CREASE_DEG, Tracer};
use paths::mesh::{Closure, DEFAULT_WELD_MM, prepare, triasym};
use paths::placement::{ContactState, MeshContact, TubeContact, deviation};
use paths::spine::{SBEND_SMOOTHING_MM, SBEND_TABLE_6_1_MM};
use paths::{Spine, Tube};

fn sbend() -> Tube {
    Tube::new(
        Spine::smoothing(&SBEND_TABLE_6_1_MM, SBEND_SMOOTHING_MM).unwrap(),
        28.5,
    )
    .unwrap()
}

/// An eye circling the S-bend 120 mm from its spine while rising 40 mm/s, mandrel frame.
fn eye(tube: &Tube, t: f64) -> (Point3<f64>, Vector3<f64>) {
    let theta = 1.2 * t;
    let z = 60.0 + 40.0 * t;
    let off = tube.spine().offset_mm(z);
    let (s, c) = theta.sin_cos();
    let [_, g, _, _] = tube.spine().eval(z);
    (
        Point3::new(off + 120.0 * c, 120.0 * s, z + 30.0),
        Vector3::new(g * 40.0 - 144.0 * s, 144.0 * c, 40.0),
    )
}

#[test]
fn mesh_and_tube_lay_the_same_fibre_on_the_s_bend() {
    let tube = sbend();
    let (mesh, adjacency) = prepare(
        &triasym::tube(&tube, 256, 1.25, true).unwrap(),
        DEFAULT_WELD_MM,
        Closure::Closed,
    )
    .unwrap();
    let tracer = Tracer::new(mesh, &adjacency, DEFAULT_CREASE_DEG).unwrap();

    // Start both on the wrapping flank of the silhouette at height 60 mm: the analytic contact
    // by scanning the section, the mesh one from the same point.
    let u0 = 60.0;
    let (e0, e0_dot) = eye(&tube, 0.0);
    let v0 = (0..36_000)
        .map(|i| -std::f64::consts::PI + std::f64::consts::TAU * i as f64 / 36_000.0)
        .filter(|&v| e0_dot.dot(&tube.normal(u0, v)) < 0.0)
        .min_by(|&a, &b| {
            let r = |v: f64| (e0 - tube.point(u0, v)).dot(&tube.normal(u0, v)).abs();
            r(a).total_cmp(&r(b))
        })
        .unwrap();
    let track = |t: f64| eye(&tube, t);
    let mut analytic = TubeContact::new(&tube, u0, v0, 0.0);
    let mut on_mesh = MeshContact::new(&tracer, &tube.point(u0, v0)).unwrap();
    let (mut laid_tube, mut laid_mesh) = (vec![analytic.point()], vec![on_mesh.point()]);
    for k in 1..=1200 {
        let t = k as f64 * 1e-3;
        laid_tube.push(analytic.advance(&track, t, 2e-4).unwrap());
        laid_mesh.push(on_mesh.advance(&eye(&tube, t).0, 1.0).unwrap());
        assert_eq!(on_mesh.state(), ContactState::Wrapping, "t = {t}");
    }
    let length: f64 = laid_tube.windows(2).map(|w| (w[1] - w[0]).norm()).sum();
    assert!(length > 30.0, "the fibre was laid over {length} mm only");
    let dev = deviation(&laid_mesh, &laid_tube).unwrap();
    println!(
        "S-bend: {length:.1} mm laid; mesh vs tube placement {:.4} mm at point {}",
        dev.max_mm, dev.at
    );
    // The 256-facet mesh lies within r(1 − cos(π/256)) = 0.002 mm of the tube between vertices;
    // its smooth normals and the contact's sensitivity to them (a normal off by ε moves the
    // tangency by about ε·|E − C|) bound the difference.
    assert!(dev.max_mm < 0.1, "{dev:?}");
}
