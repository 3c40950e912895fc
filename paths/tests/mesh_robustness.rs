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
