//! No input makes the mesh readers or the tracer panic.

use nalgebra::{Point3, Vector3};
use paths::mesh::trace::{DEFAULT_CREASE_DEG, Mode, TraceOptions, Tracer};
use paths::mesh::{Closure, DEFAULT_WELD_MM, Mesh, obj, prepare, stl, triasym};
use proptest::prelude::*;

fn sphere() -> &'static Tracer {
    static T: std::sync::OnceLock<Tracer> = std::sync::OnceLock::new();
    T.get_or_init(|| {
        let (m, adj) = prepare(
            &triasym::icosphere(40.0, 3).unwrap(),
            DEFAULT_WELD_MM,
            Closure::Closed,
        )
        .unwrap();
        Tracer::new(m, &adj, DEFAULT_CREASE_DEG).unwrap()
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn readers_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let _ = stl::parse(&bytes);
        if let Ok(text) = std::str::from_utf8(&bytes) {
            let _ = obj::parse(text);
        }
    }

    #[test]
    fn ascii_readers_never_panic_on_near_valid_text(
        words in proptest::collection::vec(
            prop_oneof![
                Just("solid"), Just("facet"), Just("normal"), Just("outer"), Just("loop"),
                Just("vertex"), Just("endloop"), Just("endfacet"), Just("endsolid"), Just("\n"),
                Just("1"), Just("-2.5"), Just("nan"), Just("v"), Just("f"), Just("-1"), Just("3/1/2"),
            ],
            0..80,
        )
    ) {
        let text = words.join(" ");
        let _ = stl::parse(text.as_bytes());
        if let Ok(m) = obj::parse(&text) {
            let _ = prepare(&m, DEFAULT_WELD_MM, Closure::Open);
        }
    }

    #[test]
    fn random_soups_weld_and_validate_without_panicking(
        coords in proptest::collection::vec(-3i32..3, 9..90)
    ) {
        let pts: Vec<Point3<f64>> = coords
            .chunks_exact(3)
            .map(|c| Point3::new(c[0] as f64, c[1] as f64, c[2] as f64))
            .collect();
        let soup: Vec<[Point3<f64>; 3]> = pts.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        if let Ok(m) = Mesh::from_soup(&soup)
            && let Ok((m, adj)) = prepare(&m, DEFAULT_WELD_MM, Closure::Open)
        {
            let tr = Tracer::new(m, &adj, DEFAULT_CREASE_DEG).unwrap();
            let _ = tr.trace_heading(&Point3::new(0.0, 0.0, 0.0), 0.3, 10.0, &TraceOptions::default());
        }
    }

    #[test]
    fn traces_from_any_start_and_heading_end_cleanly(
        x in -1.0f64..1.0, y in -1.0f64..1.0, z in -1.0f64..1.0,
        heading in -10.0f64..10.0, exact in any::<bool>(), length in 0.0f64..600.0,
    ) {
        let dir = Vector3::new(x, y, z);
        prop_assume!(dir.norm() > 1e-3);
        let start = Point3::from(dir.normalize() * 40.0);
        let o = TraceOptions {
            max_length_mm: length,
            axis: Vector3::new(0.3, 0.1, 1.0),
            mode: if exact { Mode::Exact } else { Mode::Smooth },
            ..TraceOptions::default()
        };
        // The axis may be normal to the surface at the start: an error, not a panic.
        if let Ok(path) = sphere().trace_heading(&start, heading, 1.0, &o) {
            prop_assert_eq!(path.points.len(), path.faces.len());
            prop_assert!((path.length_mm - length).abs() < 1e-6);
            for p in &path.points {
                prop_assert!((p.coords.norm() - 40.0).abs() < 0.2);
            }
        }
    }

    #[test]
    fn traces_start_exactly_at_vertices_and_along_edges(v in 0usize..642, heading_step in 0usize..12) {
        let tr = sphere();
        let p = tr.mesh().vertices()[v];
        let heading = (heading_step as f64) * std::f64::consts::PI / 6.0;
        let o = TraceOptions { max_length_mm: 100.0, ..TraceOptions::default() };
        if let Ok(path) = tr.trace_heading(&p, heading, 1e-6, &o) {
            prop_assert!((path.length_mm - 100.0).abs() < 1e-6);
        }
    }
}

/// A flat grid whose bottom-row triangles are each split by a point a nanometre off the bottom
/// edge, leaving slivers of almost no area along it: paths that start in the slivers and run
/// nearly along them stay straight and reach the grid's edge.
#[test]
fn slivers_do_not_bend_or_stop_a_path() {
    let n = 16;
    let mut v = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            v.push(Point3::new(i as f64, j as f64, 0.0));
        }
    }
    let mut tris: Vec<[u32; 3]> = Vec::new();
    let mut slivers = 0;
    for j in 0..n {
        for i in 0..n {
            let a = (j * (n + 1) + i) as u32;
            let (b, c, d) = (a + 1, a + n as u32 + 1, a + n as u32 + 2);
            if j == 0 {
                // Split [a, b, d] at a point just above the boundary edge a–b.
                let mid = Point3::from((v[a as usize].coords + v[b as usize].coords) / 2.0);
                let m = mid + (v[d as usize] - mid) * 1e-9;
                v.push(m);
                let mi = (v.len() - 1) as u32;
                tris.extend_from_slice(&[[a, b, mi], [a, mi, d], [mi, b, d]]);
                slivers += 1;
            } else {
                tris.push([a, b, d]);
            }
            tris.push([a, d, c]);
        }
    }
    assert_eq!(slivers, n);
    let (m, adj) = prepare(&Mesh::new(v, tris).unwrap(), 1e-12, Closure::Open).unwrap();
    let tr = Tracer::new(m, &adj, DEFAULT_CREASE_DEG).unwrap();
    for mode in [Mode::Smooth, Mode::Exact] {
        for (x0, heading_deg) in [
            (0.25, -80.0),
            (3.5, -89.9),
            (7.0, 45.0),
            (0.5, 60.0),
            (9.5, 89.99),
        ] {
            let start = Point3::new(x0, 1e-10, 0.0);
            let o = TraceOptions {
                axis: Vector3::y(),
                max_length_mm: 100.0,
                mode,
                ..TraceOptions::default()
            };
            let path = tr
                .trace_heading(&start, f64::to_radians(heading_deg), 1e-6, &o)
                .unwrap();
            let (p0, p1) = (path.points[0], *path.points.last().unwrap());
            let dir = (p1 - p0).normalize();
            for p in &path.points {
                let off = (p - p0) - dir * (p - p0).dot(&dir);
                assert!(off.norm() < 1e-6, "{mode:?} {heading_deg}: {}", off.norm());
            }
            let on_edge = p1.x.abs() < 1e-9
                || (p1.x - n as f64).abs() < 1e-9
                || (p1.y - n as f64).abs() < 1e-9
                || p1.y.abs() < 1e-6;
            assert!(
                on_edge,
                "{mode:?} {heading_deg}: stopped inside at {p1}, {:?}",
                path.stop
            );
            assert!(
                path.length_mm > 0.2,
                "{mode:?} {heading_deg}: {}",
                path.length_mm
            );
        }
    }
}
