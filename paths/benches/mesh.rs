//! Mesh benchmarks: tracing speed (crossings per second), loading a 1 000 000-triangle binary STL,
//! and planning a full S-bend coverage set on a 200 000-triangle mesh. Figures in
//! docs/benchmarks.md ("Triangulated mandrels").

#[path = "common/shapes.rs"]
mod shapes;

#[path = "common/cell.rs"]
mod cell;

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::{Point3, Vector3};
use paths::geodesic::{Direction, PathStart};
use paths::mesh::trace::{DEFAULT_CREASE_DEG, Mode, TraceOptions, Tracer};
use paths::mesh::{
    Closure, DEFAULT_WELD_MM, Mesh, cache, prepare, prepare_welded, resegment, stl, triasym,
};
use paths::spine::{SBEND_SMOOTHING_MM, SBEND_TABLE_6_1_MM};
use shapes::{Shape, starts};

use paths::{Arm, Movement, Spine, Tube};

fn tracer(mesh: &Mesh) -> Tracer {
    let (m, adj) = prepare(mesh, DEFAULT_WELD_MM, Closure::Closed).unwrap();
    Tracer::new(m, &adj, DEFAULT_CREASE_DEG).unwrap()
}

fn trace(c: &mut Criterion) {
    let tr = tracer(&triasym::icosphere(50.0, 6).unwrap());
    let start = Point3::new(30.0, 20.0, (2500.0f64 - 900.0 - 400.0).sqrt());
    let mut group = c.benchmark_group("mesh");
    for (name, mode) in [("smooth", Mode::Smooth), ("exact", Mode::Exact)] {
        let o = TraceOptions {
            max_length_mm: 10.0 * std::f64::consts::TAU * 50.0,
            axis: Vector3::new(0.1, 0.2, 1.0),
            mode,
            ..TraceOptions::default()
        };
        let crossings = tr.trace_heading(&start, 0.7, 1.0, &o).unwrap().crossings;
        group.throughput(Throughput::Elements(crossings as u64));
        group.bench_function(format!("trace_{name}_sphere_81920_10_turns"), |b| {
            b.iter(|| black_box(tr.trace_heading(&start, 0.7, 1.0, &o).unwrap()))
        });
    }
    group.finish();
}

/// A cylinder of radius 28.5 mm and height 400 mm, `facets` around and `rings` sections, with
/// its triangles in `order`: "split" puts the first triangle of every grid quad, then the second
/// of every quad (the two halves of a quad half the file apart); "shuffled" is a fixed random
/// permutation (the order of an arbitrary exporter).
fn cylinder_in_file_order(facets: usize, rings: usize, order: &str) -> Mesh {
    let profile: Vec<(f64, f64)> = (0..rings)
        .map(|i| (400.0 * i as f64 / (rings - 1) as f64, 28.5))
        .collect();
    let mesh = triasym::revolution(&profile, facets, true).unwrap();
    let t = mesh.triangles();
    let quads = 2 * facets * (rings - 1);
    let mut file: Vec<[u32; 3]> = if order == "split" {
        let mut split: Vec<[u32; 3]> = (0..quads).step_by(2).map(|i| t[i]).collect();
        split.extend((1..quads).step_by(2).map(|i| t[i]));
        split.extend_from_slice(&t[quads..]);
        split
    } else {
        t.to_vec()
    };
    if order == "shuffled" {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for i in (1..file.len()).rev() {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            file.swap(i, (state % (i as u64 + 1)) as usize);
        }
    }
    Mesh::new(mesh.vertices().to_vec(), file).unwrap()
}

/// Crossings per second on a large mesh against a small one: triangles in file order against
/// the locality order `prepare` gives them.
fn locality(c: &mut Criterion) {
    let mut group = c.benchmark_group("mesh");
    let o = TraceOptions {
        max_length_mm: 2000.0,
        ..TraceOptions::default()
    };
    let start = Point3::new(28.5 * 0.05f64.cos(), 28.5 * 0.05f64.sin(), 12.3);
    for order in ["split", "shuffled"] {
        for (facets, rings) in [(192, 121), (768, 457)] {
            let file = cylinder_in_file_order(facets, rings, order);
            let adjacency = file.validate(Closure::Closed).unwrap();
            let in_file_order = Tracer::new(file.clone(), &adjacency, DEFAULT_CREASE_DEG).unwrap();
            for (name, tr) in [("file_order", in_file_order), ("sorted", tracer(&file))] {
                let crossings = tr.trace_heading(&start, 1.4, 1.0, &o).unwrap().crossings;
                group.throughput(Throughput::Elements(crossings as u64));
                group.bench_function(
                    format!(
                        "trace_{order}_cylinder_{}_triangles_{name}",
                        tr.mesh().triangles().len()
                    ),
                    |b| b.iter(|| black_box(tr.trace_heading(&start, 1.4, 1.0, &o).unwrap())),
                );
            }
        }
    }
    group.finish();
}

/// Bounding-volume-hierarchy walks on the same two cylinders (shuffled file order, then sorted),
/// through `MeshSolid::inside_beyond` (the BVH walk along the segment and its crossing tests):
/// 1000 tow-like segments from just off the surface along a tangent to 100 mm out. Near its
/// tangent point a segment grazes the surface, through more (smaller) triangles' boxes on the
/// finer mesh, so the throughput is counted in boxes tested
/// (`MeshSolid::segment_walk_work`, printed with the triangles reached): per query the ratio
/// would hold that extra work as well as the memory order.
fn bvh_locality(c: &mut Criterion) {
    use paths::clearance::{MeshSolid, Solid};
    let mut group = c.benchmark_group("mesh");
    let place = |k: usize| {
        let theta = k as f64 * 2.399_963;
        let z = 20.0 + (k as f64 * 37.1) % 360.0;
        (theta.sin_cos(), z)
    };
    let tow: Vec<(Point3<f64>, Point3<f64>)> = (0..1000)
        .map(|k| {
            let ((s, c), z) = place(k);
            let t = Point3::new(28.5 * c, 28.5 * s, z);
            let dir = Vector3::new(-s, c, 0.3).normalize();
            (t + dir * 0.25, t + dir * 100.0)
        })
        .collect();
    for (facets, rings) in [(192, 121), (768, 457)] {
        let file = cylinder_in_file_order(facets, rings, "shuffled");
        let sorted = prepare(&file, DEFAULT_WELD_MM, Closure::Closed).unwrap().0;
        for (name, mesh) in [("file_order", &file), ("sorted", &sorted)] {
            let solid = MeshSolid::new(mesh).unwrap();
            // Throughput in boxes tested: the walk's unit of work, which grows with the mesh's
            // fineness (more, smaller boxes along a grazing segment) apart from memory order.
            let (boxes, triangles) = tow.iter().fold((0, 0), |(b, t), (a, e)| {
                let w = solid.segment_walk_work(a, e);
                (b + w.boxes, t + w.triangles)
            });
            eprintln!(
                "bvh walk, {} triangles, {name}: {} queries test {boxes} boxes and reach {triangles} triangles",
                mesh.triangles().len(),
                tow.len()
            );
            group.throughput(Throughput::Elements(boxes));
            group.bench_function(
                format!(
                    "bvh_tow_queries_shuffled_cylinder_{}_triangles_{name}",
                    mesh.triangles().len()
                ),
                |b| {
                    b.iter(|| {
                        for (a, e) in &tow {
                            black_box(solid.inside_beyond(a, e, 0.5));
                        }
                    })
                },
            );
        }
    }
    group.finish();
}

fn load(c: &mut Criterion) {
    // 1000 facets × 500 intervals × 2 = 1 000 000 triangles, plus 2000 cap triangles.
    let profile: Vec<(f64, f64)> = (0..=500).map(|i| (i as f64 * 0.7, 28.5)).collect();
    let mesh = triasym::revolution(&profile, 1000, true).unwrap();
    let bytes = stl::write_binary(&mesh, "bench");
    let mut group = c.benchmark_group("mesh");
    group.sample_size(10);
    group.bench_function("load_weld_validate_1m_binary_stl", |b| {
        b.iter(|| {
            let welded = stl::read(
                black_box(&bytes[..]),
                bytes.len() as u64,
                DEFAULT_WELD_MM,
                usize::MAX,
            )
            .unwrap();
            black_box(prepare_welded(welded.mesh, Closure::Closed).unwrap())
        })
    });
    let (prepared, adjacency) = prepare(&mesh, DEFAULT_WELD_MM, Closure::Closed).unwrap();
    let key = cache::Key {
        source_bytes: bytes.len() as u64,
        source_checksum: cache::Checksum::of(&bytes),
        weld_mm: DEFAULT_WELD_MM,
        closure: Closure::Closed,
    };
    let cached = cache::encode(&key, &prepared, &adjacency);
    group.bench_function("cached_1m_checksum_and_decode", |b| {
        b.iter(|| {
            let key = cache::Key {
                source_checksum: cache::Checksum::of(black_box(&bytes)),
                ..key
            };
            black_box(cache::decode(&cached, &key).unwrap())
        })
    });
    let (prepared, adjacency) = prepare(&mesh, DEFAULT_WELD_MM, Closure::Closed).unwrap();
    group.bench_function("tracer_new_1m", |b| {
        b.iter(|| black_box(Tracer::new(prepared.clone(), &adjacency, DEFAULT_CREASE_DEG).unwrap()))
    });
    group.finish();
}

/// 32 different paths per iteration (cold in cache on the large meshes), beside one path retraced
/// (warm): smooth and exact mode on the comparison's cylinder, sphere and torus.
fn different_paths(c: &mut Criterion) {
    let mut group = c.benchmark_group("mesh");
    group.sample_size(10);
    for size in [80_000, 700_000] {
        for shape in Shape::ALL {
            let mesh = shape.mesh(size);
            let starts = starts(shape, &mesh);
            let tr = tracer(&mesh);
            for (name, mode) in [("smooth", Mode::Smooth), ("exact", Mode::Exact)] {
                let o = shape.trace_options(mode);
                let run = |s: &shapes::Start| {
                    tr.trace_direction(&s.point, &s.direction, 1e-6, &o)
                        .unwrap()
                };
                let crossings: usize = starts.iter().map(|s| run(s).crossings).sum();
                group.throughput(Throughput::Elements(crossings as u64));
                group.bench_function(
                    format!("trace_{name}_32_paths_{}_{size}", shape.name()),
                    |b| {
                        b.iter(|| {
                            for s in &starts {
                                black_box(run(s));
                            }
                        })
                    },
                );
                let one = run(&starts[0]).crossings;
                group.throughput(Throughput::Elements(32 * one as u64));
                group.bench_function(
                    format!("trace_{name}_1_path_x32_{}_{size}", shape.name()),
                    |b| {
                        b.iter(|| {
                            for _ in 0..32 {
                                black_box(run(&starts[0]));
                            }
                        })
                    },
                );
            }
        }
    }
    group.finish();
}

fn coverage(c: &mut Criterion) {
    let tube = Tube::new(
        Spine::smoothing(&SBEND_TABLE_6_1_MM, SBEND_SMOOTHING_MM).unwrap(),
        28.5,
    )
    .unwrap();
    let mesh = triasym::tube(&tube, 384, 350.0 / 260.0, true).unwrap();
    let tr = tracer(&mesh);
    let setup = cell::setup(Arm::default());
    let speeds = cell::speeds(Movement::Fine);
    let mut group = c.benchmark_group("mesh");
    group.sample_size(10);
    group.bench_function(
        format!(
            "coverage_sbend_40x50_{}_triangles",
            tr.mesh().triangles().len()
        ),
        |b| {
            b.iter(|| {
                for k in 0..40 {
                    let start = PathStart {
                        angle_rad: (9.0 * k as f64).to_radians(),
                        wind_angle_rad: 45f64.to_radians(),
                        direction: Direction::Down,
                    };
                    let (_, cut) =
                        resegment::wind(&tr, &tube, &start, 50, &TraceOptions::default()).unwrap();
                    let plan = paths::plan::plan(
                        &cut.points,
                        |p| tube.distance_to_surface_mm(p),
                        &setup,
                        &speeds,
                    )
                    .unwrap();
                    black_box(plan);
                }
            })
        },
    );
    group.finish();
}

criterion_group!(
    benches,
    trace,
    different_paths,
    locality,
    bvh_locality,
    load,
    coverage
);
criterion_main!(benches);
