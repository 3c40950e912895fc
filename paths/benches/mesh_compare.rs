//! Tracing over 32 different paths per mesh, for `scripts/mesh-compare.py` (which runs the same
//! paths in potpourri3d): for each shape and size it writes the mesh as a binary STL, the paths
//! (start triangle in file order, start point, unit direction, length) as JSON, windcell's traced
//! points as little-endian `f64` triples, and windcell's times.
//!
//! `cargo bench -p paths --bench mesh_compare -- OUT_DIR [SIZES]` (sizes in triangles, comma
//! separated; default 10000,80000,700000,2000000).

#[path = "common/shapes.rs"]
mod shapes;

use std::fmt::Write as _;
use std::io::Write as _;
use std::time::Instant;

use paths::mesh::trace::{DEFAULT_CREASE_DEG, Mode, Tracer};
use paths::mesh::{Closure, prepare_welded, stl};
use shapes::{Shape, starts};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let Some(out) = args.first() else {
        eprintln!("usage: mesh_compare OUT_DIR [SIZES]");
        std::process::exit(2);
    };
    let out = std::path::PathBuf::from(out);
    std::fs::create_dir_all(&out).unwrap();
    let sizes: Vec<usize> = args
        .get(1)
        .map_or("10000,80000,700000,2000000", String::as_str)
        .split(',')
        .map(|s| s.parse().unwrap())
        .collect();
    let mut summary = String::from("[\n");
    for &size in &sizes {
        for shape in Shape::ALL {
            let mesh = shape.mesh(size);
            let name = format!("{}-{}", shape.name(), size);
            let stl_file = out.join(format!("{name}.stl"));
            let mut w = std::io::BufWriter::new(std::fs::File::create(&stl_file).unwrap());
            stl::write_binary_to(&mesh, &name, &mut w).unwrap();
            w.flush().unwrap();
            let starts = starts(shape, &mesh);
            let t0 = Instant::now();
            let (prepared, adjacency) = prepare_welded(mesh.clone(), Closure::Closed).unwrap();
            let tracer = Tracer::new(prepared, &adjacency, DEFAULT_CREASE_DEG).unwrap();
            let prepare_s = t0.elapsed().as_secs_f64();
            let mut paths_json = String::from("[\n");
            let mut points_out = std::io::BufWriter::new(
                std::fs::File::create(out.join(format!("{name}.f64"))).unwrap(),
            );
            let mut result = Vec::new();
            for (mode_name, mode) in [("smooth", Mode::Smooth), ("exact", Mode::Exact)] {
                let o = shape.trace_options(mode);
                let run = |s: &shapes::Start| {
                    tracer
                        .trace_direction(&s.point, &s.direction, 1e-6, &o)
                        .unwrap()
                };
                // The paths once, for their points and crossings.
                let traced: Vec<_> = starts.iter().map(run).collect();
                let crossings: usize = traced.iter().map(|p| p.crossings).sum();
                if mode == Mode::Smooth {
                    for (s, p) in starts.iter().zip(&traced) {
                        let _ = writeln!(
                            paths_json,
                            "  {{\"face\": {}, \"point\": [{:.17e}, {:.17e}, {:.17e}], \
                             \"direction\": [{:.17e}, {:.17e}, {:.17e}], \"length_mm\": {}, \
                             \"points\": {}, \"crossings\": {}, \"stop\": \"{}\"}},",
                            s.face,
                            s.point.x,
                            s.point.y,
                            s.point.z,
                            s.direction.x,
                            s.direction.y,
                            s.direction.z,
                            shape.length_mm(),
                            p.points.len(),
                            p.crossings,
                            p.stop.name()
                        );
                        for q in &p.points {
                            for c in q.iter() {
                                points_out.write_all(&c.to_le_bytes()).unwrap();
                            }
                        }
                    }
                }
                // Five rounds over the 32 different paths; the median round.
                let rounds: Vec<f64> = (0..5)
                    .map(|_| {
                        let t = Instant::now();
                        for s in &starts {
                            std::hint::black_box(run(s));
                        }
                        t.elapsed().as_secs_f64()
                    })
                    .collect();
                let cold = median(rounds);
                // One path retraced 32 times (warm in cache).
                let warm_rounds: Vec<f64> = (0..5)
                    .map(|_| {
                        let t = Instant::now();
                        for _ in 0..32 {
                            std::hint::black_box(run(&starts[0]));
                        }
                        t.elapsed().as_secs_f64()
                    })
                    .collect();
                let warm = median(warm_rounds);
                let warm_crossings = 32 * traced[0].crossings;
                result.push(format!(
                    "\"{mode_name}\": {{\"per_trace_s\": {:e}, \"crossings\": {crossings}, \
                     \"crossings_per_s\": {:e}, \"warm_crossings_per_s\": {:e}}}",
                    cold / 32.0,
                    crossings as f64 / cold,
                    warm_crossings as f64 / warm
                ));
            }
            points_out.flush().unwrap();
            paths_json.pop();
            paths_json.pop();
            paths_json.push_str("\n]\n");
            std::fs::write(out.join(format!("{name}.json")), &paths_json).unwrap();
            let line = format!(
                "  {{\"name\": \"{name}\", \"shape\": \"{}\", \"triangles\": {}, \"prepare_s\": {:e}, {}}}",
                shape.name(),
                mesh.triangles().len(),
                prepare_s,
                result.join(", ")
            );
            eprintln!("{line}");
            let _ = writeln!(summary, "{line},");
        }
    }
    summary.pop();
    summary.pop();
    summary.push_str("\n]\n");
    std::fs::write(out.join("windcell.json"), summary).unwrap();
}
