//! Closed test meshes of a chosen size for the tracing comparison (`mesh_compare`, `mesh`):
//! a capped cylinder, a geodesic sphere and a torus, each with the 32 different paths traced on it.

#![allow(dead_code)]

use std::f64::consts::{PI, TAU};

use nalgebra::{Point3, Vector3};
use paths::mesh::trace::{Mode, TraceOptions};
use paths::mesh::{DEFAULT_WELD_MM, Mesh, triasym};

/// The three surfaces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// Radius 30 mm, height 400 mm, capped.
    Cylinder,
    /// Radius 50 mm.
    Sphere,
    /// Major radius 60 mm, minor 20 mm, about `z`.
    Torus,
}

impl Shape {
    /// Tracing options for the shape: its length limit and axis, in `mode`.
    pub fn trace_options(self, mode: Mode) -> TraceOptions {
        TraceOptions {
            max_length_mm: self.length_mm(),
            axis: self.axis(),
            mode,
            ..TraceOptions::default()
        }
    }

    pub const ALL: [Shape; 3] = [Shape::Cylinder, Shape::Sphere, Shape::Torus];

    pub fn name(self) -> &'static str {
        match self {
            Shape::Cylinder => "cylinder",
            Shape::Sphere => "icosphere",
            Shape::Torus => "torus",
        }
    }

    /// A closed mesh of about `triangles` triangles (file order: ring by ring, face by face).
    pub fn mesh(self, triangles: usize) -> Mesh {
        let t = triangles as f64;
        match self {
            Shape::Cylinder => {
                // Square quads: 2 f k ≈ t with k ≈ f · 400 / (2π 30).
                let ratio = 400.0 / (TAU * 30.0);
                let f = (t / (2.0 * ratio)).sqrt().round().max(8.0) as usize;
                let k = (f as f64 * ratio).round().max(1.0) as usize;
                let profile: Vec<(f64, f64)> = (0..=k)
                    .map(|i| (400.0 * i as f64 / k as f64, 30.0))
                    .collect();
                triasym::revolution(&profile, f, true).unwrap()
            }
            Shape::Sphere => geodesic_sphere(50.0, (t / 20.0).sqrt().round().max(1.0) as usize),
            Shape::Torus => {
                // 2 u v ≈ t with u / v = 60 / 20.
                let v = (t / 6.0).sqrt().round().max(8.0) as usize;
                torus(60.0, 20.0, 3 * v, v)
            }
        }
    }

    /// Length of each path, mm: about two turns, within the cylinder's side.
    pub fn length_mm(self) -> f64 {
        match self {
            Shape::Cylinder => 380.0,
            Shape::Sphere => 1.5 * TAU * 50.0,
            Shape::Torus => 600.0,
        }
    }

    /// Axis of the heading (the cylinder's and torus's axis, a tilted axis on the sphere).
    pub fn axis(self) -> Vector3<f64> {
        match self {
            Shape::Sphere => Vector3::new(0.1, 0.2, 1.0).normalize(),
            _ => Vector3::z(),
        }
    }
}

/// One path to trace: a start triangle (file order), its centroid, a unit tangent direction.
#[derive(Debug, Clone, Copy)]
pub struct Start {
    pub face: usize,
    pub point: Point3<f64>,
    pub direction: Vector3<f64>,
}

/// 32 different paths on `mesh` of `shape`: start triangles spread by a fixed pseudo-random
/// sequence (on the cylinder's side between heights 150 and 250 mm), headings 75°–89° from the
/// axis on the cylinder (so two turns stay on its side) and anywhere on the others.
pub fn starts(shape: Shape, mesh: &Mesh) -> Vec<Start> {
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut out = Vec::with_capacity(32);
    while out.len() < 32 {
        let face = (next() * mesh.triangles().len() as f64) as usize;
        let [a, b, c] = mesh.corners(face);
        let point = Point3::from((a.coords + b.coords + c.coords) / 3.0);
        let n = (b - a).cross(&(c - a)).normalize();
        let axis = shape.axis();
        let along = (axis - n * axis.dot(&n)).normalize();
        let across = n.cross(&along);
        let heading = match shape {
            Shape::Cylinder => {
                if !(150.0..=250.0).contains(&point.z) || n.z.abs() > 0.5 {
                    continue;
                }
                let deg = 75.0 + 14.0 * next();
                let sign = if next() < 0.5 { -1.0 } else { 1.0 };
                sign * deg.to_radians()
            }
            _ => (next() - 0.5) * TAU,
        };
        let direction = along * heading.cos() + across * heading.sin();
        out.push(Start {
            face,
            point,
            direction,
        });
    }
    out
}

/// A geodesic sphere: each icosahedron face divided into `n²` triangles, vertices pushed onto the
/// sphere (`20 n²` triangles), welded.
pub fn geodesic_sphere(radius_mm: f64, n: usize) -> Mesh {
    let g = (1.0 + 5f64.sqrt()) / 2.0;
    let v: Vec<Vector3<f64>> = [
        [-1.0, g, 0.0],
        [1.0, g, 0.0],
        [-1.0, -g, 0.0],
        [1.0, -g, 0.0],
        [0.0, -1.0, g],
        [0.0, 1.0, g],
        [0.0, -1.0, -g],
        [0.0, 1.0, -g],
        [g, 0.0, -1.0],
        [g, 0.0, 1.0],
        [-g, 0.0, -1.0],
        [-g, 0.0, 1.0],
    ]
    .iter()
    .map(|p| Vector3::from(*p))
    .collect();
    let faces: [[usize; 3]; 20] = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let mut soup = Vec::with_capacity(20 * n * n);
    let on_sphere = |p: Vector3<f64>| Point3::from(p.normalize() * radius_mm);
    for f in faces {
        let (a, b, c) = (v[f[0]], v[f[1]], v[f[2]]);
        // Lattice point (i, j): a + (b − a) i / n + (c − a) j / n, i + j ≤ n.
        let at = |i: usize, j: usize| {
            let (i, j) = (i as f64 / n as f64, j as f64 / n as f64);
            on_sphere(a * (1.0 - i - j) + b * i + c * j)
        };
        for j in 0..n {
            for i in 0..n - j {
                soup.push([at(i, j), at(i + 1, j), at(i, j + 1)]);
                if i + j + 1 < n {
                    soup.push([at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
                }
            }
        }
    }
    Mesh::from_soup(&soup)
        .unwrap()
        .weld(DEFAULT_WELD_MM)
        .unwrap()
}

/// A torus about `z`: `u` quads around the axis, `v` around the tube, two triangles each.
pub fn torus(major_mm: f64, minor_mm: f64, u: usize, v: usize) -> Mesh {
    let mut vertices = Vec::with_capacity(u * v);
    for i in 0..u {
        let (s, c) = (TAU * i as f64 / u as f64).sin_cos();
        for j in 0..v {
            let (sv, cv) = (2.0 * PI * j as f64 / v as f64).sin_cos();
            let r = major_mm + minor_mm * cv;
            vertices.push(Point3::new(r * c, r * s, minor_mm * sv));
        }
    }
    let id = |i: usize, j: usize| ((i % u) * v + (j % v)) as u32;
    let mut triangles = Vec::with_capacity(2 * u * v);
    for i in 0..u {
        for j in 0..v {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    Mesh::new(vertices, triangles).unwrap()
}
