//! `windcell geodesic MESH --start X,Y,Z --heading DEG …`: trace a geodesic (or a path with a slip
//! ratio) on a mesh mandrel and print it, one point and its triangle per line.

use std::path::PathBuf;

use cell::plan::mesh;
use clap::Args;
use nalgebra::{Point3, Vector3};
use paths::mesh::trace::{
    DEFAULT_CREASE_DEG, DEFAULT_START_TOLERANCE_MM, Mode, Stop, TraceOptions,
};
use paths::mesh::{Closure, DEFAULT_WELD_MM};
use serde::Serialize;

use super::Failure;

/// Trace a geodesic on a triangulated mandrel (STL or OBJ) and print the polyline.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct GeodesicArgs {
    /// The mesh file (.stl, binary or ASCII, or .obj).
    pub mesh: PathBuf,
    /// Start point, mm (`X,Y,Z`), within 1 mm of the surface (it is moved onto the nearest
    /// surface point; farther away, the message gives that point). On examples/sbend.stl:
    /// `--start 2.5,28.5,100`.
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    pub start: [f64; 3],
    /// Heading, degrees, from the axis projected into the tangent plane, counter-clockwise seen
    /// from outside.
    #[arg(long, allow_hyphen_values = true)]
    pub heading: f64,
    /// Reference axis (`X,Y,Z`), also the direction heights are measured along.
    #[arg(long, value_parser = parse_triple, default_value = "0,0,1", allow_hyphen_values = true)]
    pub axis: [f64; 3],
    /// Longest path, mm (at most 100000).
    #[arg(long, default_value_t = 1000.0, allow_negative_numbers = true)]
    pub length: f64,
    /// Stop at these heights along the axis (`LO,HI`, mm); the path stops at boundary and crease
    /// edges (end caps) anyway.
    #[arg(long, value_parser = parse_pair, allow_hyphen_values = true)]
    pub heights: Option<[f64; 2]>,
    /// Slip ratio λ = k_g/k_n (0: geodesic); needs --mu.
    #[arg(
        long,
        default_value_t = 0.0,
        allow_hyphen_values = true,
        requires = "mu"
    )]
    pub lambda: f64,
    /// Friction coefficient μ; |λ| must not exceed it.
    #[arg(long, allow_negative_numbers = true)]
    pub mu: Option<f64>,
    /// Trace the polyhedron's straightest geodesic instead of the smooth surface's.
    #[arg(long)]
    pub exact: bool,
    /// Vertex welding tolerance, mm.
    #[arg(long, default_value_t = DEFAULT_WELD_MM, allow_negative_numbers = true)]
    pub weld_mm: f64,
    /// Edges sharper than this (degrees) are boundaries.
    #[arg(long, default_value_t = DEFAULT_CREASE_DEG, allow_negative_numbers = true)]
    pub crease_deg: f64,
    /// Smooth the traced path (B-spline) and print it cut into this many equal-length segments,
    /// end points projected onto the mesh, with the largest raw-to-smoothed distance (1–10000).
    #[arg(long, allow_negative_numbers = true)]
    pub segments: Option<usize>,
    /// Print one JSON document instead of text.
    #[arg(long)]
    pub json: bool,
}

fn parse_numbers<const N: usize>(text: &str) -> Result<[f64; N], String> {
    let parts: Vec<&str> = text.split(',').collect();
    if parts.len() != N {
        return Err(format!(
            "expected {N} comma-separated numbers, got `{text}`"
        ));
    }
    let mut out = [0.0; N];
    for (slot, p) in out.iter_mut().zip(parts) {
        let v: f64 = p
            .trim()
            .parse()
            .map_err(|_| format!("`{p}` is not a number"))?;
        if !v.is_finite() {
            return Err(format!("`{p}` is not finite"));
        }
        *slot = v;
    }
    Ok(out)
}

fn parse_triple(text: &str) -> Result<[f64; 3], String> {
    parse_numbers::<3>(text)
}

fn parse_pair(text: &str) -> Result<[f64; 2], String> {
    parse_numbers::<2>(text)
}

#[derive(Debug, Serialize)]
struct Report {
    points_mm: Vec<[f64; 3]>,
    faces: Vec<u32>,
    length_mm: f64,
    crossings: usize,
    stop: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    segments: Option<Segments>,
}

#[derive(Debug, Serialize)]
struct Segments {
    points_mm: Vec<[f64; 3]>,
    normals: Vec<[f64; 3]>,
    faces: Vec<u32>,
    length_mm: f64,
    max_deviation_mm: f64,
}

/// Why the trace stopped, in words for the summary line.
fn stop_reason(stop: Stop) -> &'static str {
    match stop {
        Stop::Length => "at the --length limit",
        Stop::Boundary => "at a boundary or crease edge (an end cap's rim)",
        Stop::Height => "at the edge of the --heights range",
        Stop::Stuck => "at a vertex it cannot pass",
        Stop::CrossingLimit => "at the limit of edge crossings",
    }
}

/// Runs `windcell geodesic`.
pub fn run(args: GeodesicArgs) -> Result<(), Failure> {
    let options = TraceOptions {
        max_length_mm: args.length,
        axis: Vector3::from(args.axis),
        height_range_mm: args.heights.map(|[lo, hi]| (lo, hi)),
        lambda: args.lambda,
        mu: args.mu,
        mode: if args.exact {
            Mode::Exact
        } else {
            Mode::Smooth
        },
    };
    // Check the options and limits before the (possibly long) load.
    options
        .validate()
        .map_err(|e| Failure::input(format!("geodesic: {e}")))?;
    // A heading is an angle: beyond a turn either way it is a wrong value (1e300° has no
    // meaning a sine can give back).
    if !(args.heading.is_finite() && args.heading.abs() <= 360.0) {
        return Err(Failure::input(format!(
            "geodesic: --heading {} must lie in -360 … 360 degrees",
            paths::limits::shown(args.heading)
        )));
    }
    if let Some(n) = args.segments
        && !(1..=paths::limits::MAX_SEGMENTS).contains(&n)
    {
        return Err(Failure::input(format!(
            "geodesic: --segments {n} must lie in 1..={} (docs/ARCHITECTURE.md, \"Limits\")",
            paths::limits::MAX_SEGMENTS
        )));
    }
    let tracer = mesh::load(&args.mesh, args.weld_mm, Closure::Open, args.crease_deg)
        .map_err(Failure::from_cell)?;
    let path = tracer
        .trace_heading(
            &Point3::from(args.start),
            args.heading.to_radians(),
            DEFAULT_START_TOLERANCE_MM,
            &options,
        )
        .map_err(|e| {
            let [x, y, z] = args.start;
            Failure::input(format!(
                "geodesic --start {x},{y},{z} on {}: {e}",
                args.mesh.display()
            ))
        })?;
    // Faces as the file numbers them (the loader sorts triangles for locality).
    let file_face = |f: &u32| tracer.mesh().file_triangle(*f as usize) as u32;
    let segments = match args.segments {
        Some(n) => {
            let cut = paths::mesh::resegment::smooth_and_cut(
                &tracer,
                &path.points,
                n,
                paths::mesh::resegment::DEFAULT_SPACING_MM,
            )
            .map_err(|e| Failure::input(format!("{}: {e}", args.mesh.display())))?;
            Some(Segments {
                points_mm: cut.points.iter().map(|p| p.point.coords.into()).collect(),
                normals: cut.points.iter().map(|p| p.normal.into()).collect(),
                faces: cut.faces.iter().map(file_face).collect(),
                length_mm: cut.length_mm,
                max_deviation_mm: cut.max_deviation_mm,
            })
        }
        None => None,
    };
    let mut out = String::new();
    if args.json {
        let report = Report {
            points_mm: path.points.iter().map(|p| [p.x, p.y, p.z]).collect(),
            faces: path.faces.iter().map(file_face).collect(),
            length_mm: path.length_mm,
            crossings: path.crossings,
            stop: path.stop.name(),
            segments,
        };
        out = serde_json::to_string(&report).map_err(Failure::runtime)?;
        out.push('\n');
    } else {
        out += "# x_mm y_mm z_mm face\n";
        for (p, f) in path.points.iter().zip(&path.faces) {
            let f = file_face(f);
            out += &format!("{:.4} {:.4} {:.4} {f}\n", p.x, p.y, p.z);
        }
        out += &format!(
            "# {} points, {:.3} mm long, {} triangle edges crossed, stopped {}\n",
            path.points.len(),
            path.length_mm,
            path.crossings,
            stop_reason(path.stop)
        );
        if let Some(seg) = &segments {
            out += "# smoothed, equal-length segment ends: x_mm y_mm z_mm face\n";
            for (p, f) in seg.points_mm.iter().zip(&seg.faces) {
                out += &format!("{:.4} {:.4} {:.4} {f}\n", p[0], p[1], p[2]);
            }
            out += &format!(
                "# {} segments of {:.4} mm, largest raw-to-smoothed distance {:.4} mm\n",
                seg.points_mm.len() - 1,
                seg.length_mm / (seg.points_mm.len() - 1) as f64,
                seg.max_deviation_mm
            );
        }
    }
    super::print(&out)
}
