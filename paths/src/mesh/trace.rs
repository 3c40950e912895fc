//! Geodesic tracing on a triangle mesh (seed 001 §2.1: the fibre follows the geodesic; seed 000
//! §2.9: a non-geodesic path holds only while its slippage tendency stays within the friction).
//!
//! The path runs straight across each triangle and is handed from triangle to triangle across the
//! shared edge. What happens to its direction at an edge defines the two modes:
//!
//! - [`Mode::Exact`]: the straightest geodesic of the polyhedron (the two triangles unfolded into
//!   one plane, i.e. the direction turned about the edge by the dihedral angle).
//! - [`Mode::Smooth`] (default): the geodesic of the smooth surface the mesh approximates. Each
//!   corner carries a vertex normal (angle-weighted over the triangles meeting there, stopping at
//!   crease edges) and the normal along an edge is interpolated between its two corners. The
//!   path's unit tangent `t` is carried from one crossing to the next by the smallest rotation that
//!   takes the surface normal at the previous crossing to the normal at this one. That is
//!   parallel transport of `t` along itself, `dt/ds = κ_n n`, the geodesic equation, so the
//!   angle defects concentrated at the mesh vertices do not bend the path. In a triangle the path
//!   runs along `t` projected into the triangle's plane.
//!
//! A slip ratio `λ = k_g / k_n` adds a turn of `λ · |Δn · t|` about the normal at each crossing
//! (counter-clockwise seen from outside for `λ > 0`); `λ = 0` is the geodesic itself.
//!
//! The crossing loop uses a flat per-triangle record (plane normal, inward edge normals and
//! offsets, edge parameters, corner normals, neighbours), no allocation but the output push, and two
//! square roots per crossing in smooth mode.
//!
//! At a vertex the path walks around it, triangle by triangle, until one admits its direction;
//! nearly degenerate triangles are crossed in zero or tiny steps. Tracing stops at a length, a
//! boundary or crease edge (an end cap), a height limit along an axis, or (never seen in the tests)
//! after a long walk around a vertex that admits no direction.

use nalgebra::{Point3, Vector3};

use super::{Adjacency, Mesh, NO_NEIGHBOUR};
use crate::Error;

/// Default crease angle, degrees: edges whose triangles meet at more than this are a boundary
/// (the rim of an end cap), and vertex normals do not average across them.
pub const DEFAULT_CREASE_DEG: f64 = 30.0;

/// Default largest distance from a start point to the surface, mm.
pub const DEFAULT_START_TOLERANCE_MM: f64 = 1.0;

/// How the direction is carried across an edge (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Mode {
    /// The geodesic of the smooth surface the mesh approximates.
    #[default]
    Smooth,
    /// The straightest geodesic of the polyhedron (edge unfolding).
    Exact,
}

/// Why a trace stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stop {
    /// It reached the requested length.
    Length,
    /// It reached a boundary edge or a crease (an end cap's rim).
    Boundary,
    /// It reached a height limit.
    Height,
    /// It met a vertex whose triangles admit no direction.
    Stuck,
    /// It crossed [`MAX_CROSSINGS`] edges (a length far beyond the mesh's scale).
    CrossingLimit,
}

/// Most edge crossings of one trace.
pub const MAX_CROSSINGS: usize = 2_000_000;

impl Stop {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Stop::Length => "length",
            Stop::Boundary => "boundary",
            Stop::Height => "height",
            Stop::Stuck => "vertex",
            Stop::CrossingLimit => "crossing limit",
        }
    }
}

/// What to trace.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceOptions {
    /// Longest path, mm.
    pub max_length_mm: f64,
    /// Unit axis along which heights are measured (the mandrel axis).
    pub axis: Vector3<f64>,
    /// Stop when the height `p · axis` leaves this range, mm.
    pub height_range_mm: Option<(f64, f64)>,
    /// Slip ratio `λ = k_g / k_n`; 0 for the geodesic.
    pub lambda: f64,
    /// Friction coefficient μ; required when `lambda` is not 0, and `|λ| ≤ μ`.
    pub mu: Option<f64>,
    /// Smooth or exact.
    pub mode: Mode,
}

impl Default for TraceOptions {
    fn default() -> Self {
        TraceOptions {
            max_length_mm: 1000.0,
            axis: Vector3::z(),
            height_range_mm: None,
            lambda: 0.0,
            mu: None,
            mode: Mode::Smooth,
        }
    }
}

impl TraceOptions {
    /// Checks the length, the axis and the slip ratio against the friction (seed 000 §2.9:
    /// the slippage tendency `k = tan ψ = |k_g / k_n|` must not exceed μ).
    pub fn validate(&self) -> Result<(), Error> {
        if !(self.max_length_mm >= 0.0 && self.max_length_mm.is_finite()) {
            return Err(Error::OutOfRange {
                name: "length_mm",
                value: self.max_length_mm,
                expected: "must be ≥ 0 and finite",
            });
        }
        crate::limits::at_most(
            "length_mm",
            self.max_length_mm,
            crate::limits::MAX_PATH_LENGTH_MM,
        )?;
        if !(self.axis.iter().all(|c| c.is_finite()) && self.axis.norm() > 1e-9) {
            return Err(Error::OutOfRange {
                name: "axis",
                value: self.axis.norm(),
                expected: "must be a finite non-zero vector",
            });
        }
        if let Some((lo, hi)) = self.height_range_mm
            && (lo.is_nan() || hi.is_nan() || lo > hi)
        {
            return Err(Error::OutOfRange {
                name: "height_range_mm",
                value: lo,
                expected: "must be an increasing pair",
            });
        }
        if !self.lambda.is_finite() {
            return Err(Error::OutOfRange {
                name: "lambda",
                value: self.lambda,
                expected: "must be finite",
            });
        }
        match self.mu {
            Some(mu) if !(mu >= 0.0 && mu.is_finite()) => Err(Error::OutOfRange {
                name: "mu",
                value: mu,
                expected: "must be ≥ 0 and finite",
            }),
            Some(mu) if self.lambda.abs() > mu => Err(Error::SlipExceedsFriction {
                lambda: self.lambda.abs(),
                mu,
            }),
            None if self.lambda != 0.0 => Err(Error::OutOfRange {
                name: "lambda",
                value: self.lambda,
                expected: "needs a friction coefficient mu to check it against",
            }),
            _ => Ok(()),
        }
    }
}

/// A traced path.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshPath {
    /// The start point, then every edge crossing, then the end point, mm.
    pub points: Vec<Point3<f64>>,
    /// For each point, the triangle the path runs through after it (the last: where it ends).
    pub faces: Vec<u32>,
    /// Arc length, mm.
    pub length_mm: f64,
    /// Number of edge crossings.
    pub crossings: usize,
    /// Why it stopped.
    pub stop: Stop,
}

/// One triangle as the crossing loop reads it: everything a crossing needs in one record of three
/// cache lines (192 bytes, aligned), so a crossing touches one record in either mode. The edge
/// normals and parameters are derived from the corners at each crossing (a cross product and a
/// dot product per edge) rather than stored.
#[derive(Debug, Clone, Copy, Default)]
#[repr(C, align(64))]
struct Face {
    /// Unit plane normal.
    n: Vector3<f64>,
    /// The corners, mm.
    corners: [Vector3<f64>; 3],
    /// Smooth unit normals at the corners.
    corner_normals: [Vector3<f64>; 3],
    /// Neighbour across each edge (`4 · triangle + edge`) or [`NO_NEIGHBOUR`].
    next: [u32; 3],
}

/// A uniform grid of triangle lists for nearest-point queries.
#[derive(Debug, Clone)]
struct Grid {
    origin: Vector3<f64>,
    cell_mm: f64,
    dims: [usize; 3],
    start: Vec<u32>,
    items: Vec<u32>,
}

/// A mesh prepared for tracing: per-triangle records, vertex normals, a locating grid.
#[derive(Debug, Clone)]
pub struct Tracer {
    mesh: Mesh,
    faces: Vec<Face>,
    grid: Grid,
}

/// Where a point lands on the mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Located {
    /// The triangle.
    pub face: usize,
    /// The nearest surface point.
    pub point: Point3<f64>,
    /// The smooth (interpolated) unit normal there.
    pub normal: Vector3<f64>,
    /// Distance from the query point, mm.
    pub distance_mm: f64,
}

impl Tracer {
    /// Prepares a mesh that [`Mesh::validate`] accepted (its adjacency given), with edges sharper
    /// than `crease_deg` treated as boundaries.
    pub fn new(mesh: Mesh, adjacency: &Adjacency, crease_deg: f64) -> Result<Self, Error> {
        if !(0.0..=180.0).contains(&crease_deg) {
            return Err(Error::OutOfRange {
                name: "crease_deg",
                value: crease_deg,
                expected: "must lie in [0, 180]",
            });
        }
        if adjacency.across.len() != mesh.triangles().len() {
            return Err(Error::OutOfRange {
                name: "adjacency",
                value: adjacency.across.len() as f64,
                expected: "must have one row per triangle",
            });
        }
        let cos_crease = crease_deg.to_radians().cos();
        let normals = mesh.face_normals();
        let verts = mesh.vertices();
        let tris = mesh.triangles();
        // Incident (triangle, corner) lists per vertex, CSR.
        let mut count = vec![0u32; verts.len() + 1];
        for t in tris {
            for &v in t {
                count[v as usize + 1] += 1;
            }
        }
        for i in 0..verts.len() {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        let mut incident = vec![0u32; 3 * tris.len()];
        for (f, t) in tris.iter().enumerate() {
            for (c, &v) in t.iter().enumerate() {
                incident[fill[v as usize] as usize] = (f as u32) << 2 | c as u32;
                fill[v as usize] += 1;
            }
        }
        // Interior angle at every corner, once.
        let corner_angle: Vec<f64> = tris
            .iter()
            .flat_map(|t| {
                (0..3).map(move |c| {
                    let p = verts[t[c] as usize];
                    let a = verts[t[(c + 1) % 3] as usize] - p;
                    let b = verts[t[(c + 2) % 3] as usize] - p;
                    a.cross(&b).norm().atan2(a.dot(&b))
                })
            })
            .collect();
        let build = |f: usize| {
            let t = &tris[f];
            let n = normals[f];
            let mut face = Face {
                n,
                corners: t.map(|i| verts[i as usize].coords),
                ..Face::default()
            };
            for (i, &v) in t.iter().enumerate() {
                let h = adjacency.across[f][i];
                face.next[i] =
                    if h != NO_NEIGHBOUR && normals[(h >> 2) as usize].dot(&n) >= cos_crease {
                        h
                    } else {
                        NO_NEIGHBOUR
                    };
                // Corner normal: angle-weighted over the triangles at this vertex within the crease.
                let v = v as usize;
                let mut sum = Vector3::zeros();
                for &fc in &incident[count[v] as usize..count[v + 1] as usize] {
                    let g = (fc >> 2) as usize;
                    if normals[g].dot(&n) >= cos_crease {
                        sum += normals[g] * corner_angle[3 * g + (fc & 3) as usize];
                    }
                }
                face.corner_normals[i] = sum.try_normalize(0.0).unwrap_or(n);
            }
            face
        };
        // The records in parallel chunks, the locating grid beside them.
        let mut faces = vec![Face::default(); tris.len()];
        let threads = worker_threads(tris.len());
        let chunk = tris.len().div_ceil(threads).max(1);
        let grid = std::thread::scope(|scope| {
            let grid = scope.spawn(|| Grid::new(&mesh));
            for (k, part) in faces.chunks_mut(chunk).enumerate() {
                let build = &build;
                scope.spawn(move || {
                    for (j, slot) in part.iter_mut().enumerate() {
                        *slot = build(k * chunk + j);
                    }
                });
            }
            grid.join()
        })
        .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        Ok(Tracer { mesh, faces, grid })
    }

    /// The mesh.
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    /// The smooth unit normal at barycentric coordinates `bary` of triangle `face`.
    pub fn normal_at(&self, face: usize, bary: [f64; 3]) -> Vector3<f64> {
        let c = &self.faces[face].corner_normals;
        (c[0] * bary[0] + c[1] * bary[1] + c[2] * bary[2])
            .try_normalize(0.0)
            .unwrap_or(self.faces[face].n)
    }

    /// The nearest surface point to `p`, its triangle and smooth normal. `None` only for a
    /// non-finite `p`.
    pub fn locate(&self, p: &Point3<f64>) -> Option<Located> {
        if !p.iter().all(|c| c.is_finite()) {
            return None;
        }
        let (face, point, bary, d2) = self.grid.nearest(&self.mesh, p)?;
        Some(Located {
            face,
            point,
            normal: self.normal_at(face, bary),
            distance_mm: d2.sqrt(),
        })
    }

    /// Traces from `start` (within `tolerance_mm` of the surface) at `heading_rad` from the
    /// reference direction: `options.axis` projected into the tangent plane, turned
    /// counter-clockwise about the outward normal by the heading.
    pub fn trace_heading(
        &self,
        start: &Point3<f64>,
        heading_rad: f64,
        tolerance_mm: f64,
        options: &TraceOptions,
    ) -> Result<MeshPath, Error> {
        options.validate()?;
        if !heading_rad.is_finite() {
            return Err(Error::OutOfRange {
                name: "heading_deg",
                value: heading_rad,
                expected: "must be finite",
            });
        }
        let at = self.locate_start(start, tolerance_mm)?;
        let n = at.normal;
        let axis = options.axis.normalize();
        let r = (axis - n * axis.dot(&n))
            .try_normalize(1e-9)
            .ok_or(Error::OutOfRange {
                name: "axis",
                value: axis.dot(&n),
                expected: "must not be normal to the surface at the start point",
            })?;
        let (s, c) = heading_rad.sin_cos();
        let t = r * c + n.cross(&r) * s;
        Ok(self.run(at, t, options))
    }

    /// Traces from `start` (within `tolerance_mm` of the surface) along `direction` (projected
    /// into the tangent plane). The start triangle is the one nearest to a point a micrometre
    /// ahead, so a start on an edge or a cap's rim picks the triangle the path runs into.
    pub fn trace_direction(
        &self,
        start: &Point3<f64>,
        direction: &Vector3<f64>,
        tolerance_mm: f64,
        options: &TraceOptions,
    ) -> Result<MeshPath, Error> {
        options.validate()?;
        let ahead = direction.try_normalize(0.0).unwrap_or_default() * 1e-3;
        let at = self.locate_start(&(start + ahead), tolerance_mm)?;
        let n = at.normal;
        let t = (direction - n * direction.dot(&n))
            .try_normalize(1e-12)
            .ok_or(Error::OutOfRange {
                name: "direction",
                value: direction.norm(),
                expected: "must be finite and not normal to the surface",
            })?;
        Ok(self.run(at, t, options))
    }

    fn locate_start(&self, start: &Point3<f64>, tolerance_mm: f64) -> Result<Located, Error> {
        let at = self.locate(start).ok_or(Error::OutOfRange {
            name: "start_mm",
            value: f64::NAN,
            expected: "must be finite",
        })?;
        if at.distance_mm > tolerance_mm {
            return Err(Error::OffSurface {
                nearest_mm: at.point.coords.into(),
                distance_mm: at.distance_mm,
                limit_mm: tolerance_mm,
            });
        }
        Ok(at)
    }

    /// The tangent `t` carried from unit normal `from` to unit normal `to`: the smallest rotation,
    /// plus the slip ratio's turn `λ |Δn · t|` about `to`; kept tangent and of unit length (one
    /// Newton step for `1/|t|`, no square root).
    #[inline(always)]
    fn turn(
        &self,
        t: &Vector3<f64>,
        from: &Vector3<f64>,
        to: &Vector3<f64>,
        lambda: f64,
    ) -> Vector3<f64> {
        let mut turned = rotate(t, from, to);
        if lambda != 0.0 {
            let theta = lambda * (to - from).dot(t).abs();
            let (sn, cs) = theta.sin_cos();
            turned = turned * cs + to.cross(&turned) * sn;
        }
        turned -= to * turned.dot(to);
        turned * (0.5 * (3.0 - turned.norm_squared()))
    }

    /// The crossing loop.
    fn run(&self, at: Located, t0: Vector3<f64>, o: &TraceOptions) -> MeshPath {
        let exact = o.mode == Mode::Exact;
        let axis = o.axis.normalize();
        let mut f = at.face;
        let mut p = at.point.coords;
        let mut nprev = if exact { self.faces[f].n } else { at.normal };
        let mut t = t0;
        let mut e_in = 3usize;
        let mut s = 0.0;
        let mut crossings = 0usize;
        let mut zero_steps = 0usize;
        let estimate = (o.max_length_mm / self.grid.cell_mm.max(1e-9) * 2.0).min(1e6) as usize;
        let mut points = Vec::with_capacity(estimate + 2);
        let mut faces = Vec::with_capacity(estimate + 2);
        points.push(Point3::from(p));
        faces.push(f as u32);
        let finish =
            |points: Vec<Point3<f64>>, faces: Vec<u32>, s: f64, crossings, stop| MeshPath {
                points,
                faces,
                length_mm: s,
                crossings,
                stop,
            };
        loop {
            let face = &self.faces[f];
            let nf = face.n;
            if exact && nprev != nf {
                // Exact mode turns at the crossing into this triangle, here, where its record is
                // read anyway (the previous record never reads this one's normal).
                t = self.turn(&t, &nprev, &nf, o.lambda);
                nprev = nf;
            }
            let mut d = t - nf * t.dot(&nf);
            let dn2 = d.norm_squared();
            if dn2.is_nan() || dn2 <= 1e-24 {
                return finish(points, faces, s, crossings, Stop::Stuck);
            }
            d /= dn2.sqrt();
            let (best, best_t) = exit(face, &p, &d, e_in);
            // Stops inside this triangle.
            let mut step = best_t;
            let mut stop = None;
            let remaining = o.max_length_mm - s;
            if step >= remaining {
                step = remaining.max(0.0);
                stop = Some(Stop::Length);
            }
            if let Some((lo, hi)) = o.height_range_mm {
                let h0 = p.dot(&axis);
                let rh = d.dot(&axis);
                let h1 = h0 + step * rh;
                if rh > 0.0 && h1 > hi {
                    step = ((hi - h0) / rh).max(0.0);
                    stop = Some(Stop::Height);
                } else if rh < 0.0 && h1 < lo {
                    step = ((lo - h0) / rh).max(0.0);
                    stop = Some(Stop::Height);
                }
            }
            let q = p + d * step;
            s += step;
            if let Some(stop) = stop {
                points.push(Point3::from(q));
                faces.push(f as u32);
                return finish(points, faces, s, crossings, stop);
            }
            let next = face.next[best];
            if next == NO_NEIGHBOUR {
                points.push(Point3::from(q));
                faces.push(f as u32);
                return finish(points, faces, s, crossings, Stop::Boundary);
            }
            let g = (next >> 2) as usize;
            if !exact {
                let nq = edge_normal(face, best, &q);
                t = self.turn(&t, &nprev, &nq, o.lambda);
                nprev = nq;
            }
            crossings += 1;
            if crossings >= MAX_CROSSINGS {
                points.push(Point3::from(q));
                faces.push(g as u32);
                return finish(points, faces, s, crossings, Stop::CrossingLimit);
            }
            if step > 0.0 {
                zero_steps = 0;
                points.push(Point3::from(q));
                faces.push(g as u32);
            } else {
                zero_steps += 1;
                if let Some(last) = faces.last_mut() {
                    *last = g as u32;
                }
                if zero_steps > 1024 {
                    return finish(points, faces, s, crossings, Stop::Stuck);
                }
            }
            p = q;
            f = g;
            e_in = (next & 3) as usize;
        }
    }
}

/// Threads for a preparation step over `items` items: the machine's parallelism (at most 8), one
/// below 20 000 items, where starting threads costs more than it saves.
pub(crate) fn worker_threads(items: usize) -> usize {
    if items < 20_000 {
        return 1;
    }
    std::thread::available_parallelism()
        .map_or(1, usize::from)
        .clamp(1, 8)
}

/// The exit edge of a straight run from `p` along `d` in `face` (never the entry edge `e_in`) and
/// the distance to it. When the direction leaves through the corner the path entered by, the edge
/// nearest to `p` at distance 0, so the path walks around that vertex.
///
/// For edge `i` from corner `a` along `e`, `m = n × e` points into the triangle with `|m| = |e|`;
/// the distance to the edge is `(p − a) · m / |m|` and the rate at which `d` approaches it
/// `−d · m / |m|`, so their ratio needs no square root.
#[inline(always)]
fn exit(face: &Face, p: &Vector3<f64>, d: &Vector3<f64>, e_in: usize) -> (usize, f64) {
    let mut best = 3usize;
    let mut best_t = f64::INFINITY;
    let mut dists = [0.0; 3];
    let mut ms = [Vector3::zeros(); 3];
    for i in 0..3 {
        if i == e_in {
            continue;
        }
        let a = face.corners[i];
        let m = face.n.cross(&(face.corners[(i + 1) % 3] - a));
        let rate = d.dot(&m);
        let dist = (p - a).dot(&m).max(0.0);
        if rate < 0.0 {
            let ti = dist / -rate;
            if ti < best_t {
                best_t = ti;
                best = i;
            }
        }
        dists[i] = dist;
        ms[i] = m;
    }
    if best == 3 {
        let mut near = 3usize;
        let mut near_dist = f64::INFINITY;
        for i in 0..3 {
            if i == e_in {
                continue;
            }
            let dist = dists[i] / ms[i].norm().max(f64::MIN_POSITIVE);
            if dist < near_dist {
                near_dist = dist;
                near = i;
            }
        }
        (near, 0.0)
    } else {
        (best, best_t)
    }
}

/// The smooth unit normal at `q` on edge `i` of `face` (interpolated between its corners).
#[inline(always)]
fn edge_normal(face: &Face, i: usize, q: &Vector3<f64>) -> Vector3<f64> {
    let a = face.corners[i];
    let e = face.corners[(i + 1) % 3] - a;
    let u = ((q - a).dot(&e) / e.norm_squared().max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
    let cn = &face.corner_normals;
    let n = cn[i] * (1.0 - u) + cn[(i + 1) % 3] * u;
    n / n.norm()
}

/// `v` turned by the smallest rotation taking unit `a` to unit `b` (Rodrigues, no trigonometry;
/// `v` unchanged when `a` and `b` are nearly opposite).
#[inline(always)]
fn rotate(v: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> Vector3<f64> {
    let c = a.dot(b);
    if c <= -0.9 {
        return *v;
    }
    let k = a.cross(b);
    v * c + k.cross(v) + k * (k.dot(v) / (1.0 + c))
}

/// The point of triangle `abc` nearest to `p`, with its barycentric coordinates (Ericson,
/// Real-Time Collision Detection §5.1.5).
fn closest_on_triangle(
    p: &Point3<f64>,
    a: &Point3<f64>,
    b: &Point3<f64>,
    c: &Point3<f64>,
) -> (Point3<f64>, [f64; 3]) {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (*a, [1.0, 0.0, 0.0]);
    }
    let bp = p - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (*b, [0.0, 1.0, 0.0]);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, [1.0 - v, v, 0.0]);
    }
    let cp = p - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (*c, [0.0, 0.0, 1.0]);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, [1.0 - w, 0.0, w]);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, [0.0, 1.0 - w, w]);
    }
    let denom = va + vb + vc;
    if denom.is_nan() || denom == 0.0 {
        return (*a, [1.0, 0.0, 0.0]);
    }
    let v = vb / denom;
    let w = vc / denom;
    (a + ab * v + ac * w, [1.0 - v - w, v, w])
}

impl Grid {
    fn new(mesh: &Mesh) -> Grid {
        let (lo, hi) = mesh.bounds();
        let size = hi - lo;
        let n = mesh.triangles().len() as f64;
        // About one triangle per occupied cell on a surface: cell ≈ mean edge length × 2.
        let mut edge_sum = 0.0;
        let step = (mesh.triangles().len() / 4096).max(1);
        let mut sampled = 0usize;
        for t in (0..mesh.triangles().len()).step_by(step) {
            let [a, b, _] = mesh.corners(t);
            edge_sum += (b - a).norm();
            sampled += 1;
        }
        let mean_edge = edge_sum / sampled.max(1) as f64;
        let extent = size.max().max(1e-9);
        let mut cell = (2.0 * mean_edge).max(extent / 1024.0).max(1e-9);
        // Never more than ~8 cells per triangle in all.
        let cells = |c: f64| size.iter().map(|s| (s / c).floor() + 1.0).product::<f64>();
        while cells(cell) > 8.0 * n + 64.0 {
            cell *= 1.25;
        }
        let dims = [0, 1, 2].map(|k| ((size[k] / cell).floor() as usize + 1).max(1));
        let index = |p: &Point3<f64>| -> [usize; 3] {
            [0, 1, 2].map(|k| (((p[k] - lo[k]) / cell).floor().max(0.0) as usize).min(dims[k] - 1))
        };
        let flat = |i: [usize; 3]| (i[2] * dims[1] + i[1]) * dims[0] + i[0];
        let total = dims[0] * dims[1] * dims[2];
        let mut start = vec![0u32; total + 1];
        let ranges: Vec<([usize; 3], [usize; 3])> = (0..mesh.triangles().len())
            .map(|t| {
                let [a, b, c] = mesh.corners(t);
                (index(&a.inf(&b).inf(&c)), index(&a.sup(&b).sup(&c)))
            })
            .collect();
        let each = |r: &([usize; 3], [usize; 3]), f: &mut dyn FnMut(usize)| {
            for z in r.0[2]..=r.1[2] {
                for y in r.0[1]..=r.1[1] {
                    for x in r.0[0]..=r.1[0] {
                        f(flat([x, y, z]));
                    }
                }
            }
        };
        for r in &ranges {
            each(r, &mut |c| start[c + 1] += 1);
        }
        for i in 0..total {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut items = vec![0u32; start[total] as usize];
        for (t, r) in ranges.iter().enumerate() {
            each(r, &mut |c| {
                items[fill[c] as usize] = t as u32;
                fill[c] += 1;
            });
        }
        Grid {
            origin: lo.coords,
            cell_mm: cell,
            dims,
            start,
            items,
        }
    }

    /// Nearest triangle to `p`: search shells of cells outward until no closer cell remains.
    fn nearest(&self, mesh: &Mesh, p: &Point3<f64>) -> Option<(usize, Point3<f64>, [f64; 3], f64)> {
        let rel = p.coords - self.origin;
        let mut home = [0i64; 3];
        let mut outside2 = 0.0;
        for k in 0..3 {
            let x = rel[k] / self.cell_mm;
            let top = self.dims[k] as f64;
            let clamped = x.clamp(0.0, top - 1e-9);
            outside2 += ((x - clamped) * self.cell_mm).powi(2);
            home[k] = clamped.floor() as i64;
        }
        let outside = outside2.sqrt();
        let dims = self.dims.map(|d| d as i64);
        let max_shell = *dims.iter().max()?;
        let mut best: Option<(usize, Point3<f64>, [f64; 3], f64)> = None;
        let tris = mesh.triangles();
        let verts = mesh.vertices();
        for shell in 0..=max_shell {
            let lo = home.map(|h| h - shell);
            let hi = home.map(|h| h + shell);
            for z in lo[2].max(0)..=hi[2].min(dims[2] - 1) {
                for y in lo[1].max(0)..=hi[1].min(dims[1] - 1) {
                    let on_yz = z == lo[2] || z == hi[2] || y == lo[1] || y == hi[1];
                    let (x0, x1) = (lo[0].max(0), hi[0].min(dims[0] - 1));
                    let mut x = x0;
                    while x <= x1 {
                        let cell = ((z * dims[1] + y) * dims[0] + x) as usize;
                        for &t in
                            &self.items[self.start[cell] as usize..self.start[cell + 1] as usize]
                        {
                            let [a, b, c] = tris[t as usize].map(|i| verts[i as usize]);
                            let (q, bary) = closest_on_triangle(p, &a, &b, &c);
                            let d2 = (q - p).norm_squared();
                            if best.as_ref().is_none_or(|b| d2 < b.3) {
                                best = Some((t as usize, q, bary, d2));
                            }
                        }
                        // Off the shell's y–z surface only its two x ends belong to the shell.
                        x = if on_yz || x >= hi[0] || x < lo[0] {
                            x + 1
                        } else {
                            hi[0]
                        };
                    }
                }
            }
            if let Some(b) = &best {
                let reach = shell as f64 * self.cell_mm + outside;
                if b.3 <= reach * reach {
                    break;
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{Closure, DEFAULT_WELD_MM, prepare, triasym};

    fn tracer(mesh: Mesh) -> Tracer {
        let (m, adj) = prepare(&mesh, DEFAULT_WELD_MM, Closure::Open).unwrap();
        Tracer::new(m, &adj, DEFAULT_CREASE_DEG).unwrap()
    }

    #[test]
    fn locate_finds_the_nearest_point_like_a_linear_scan() {
        let tr = tracer(triasym::icosphere(50.0, 3).unwrap());
        let m = tr.mesh();
        for q in [
            Point3::new(1.0, 2.0, 3.0),
            Point3::new(60.0, -5.0, 7.0),
            Point3::new(0.0, 0.0, 49.9),
            Point3::new(300.0, 200.0, -100.0),
            Point3::new(-30.0, 30.0, 30.0),
        ] {
            let got = tr.locate(&q).unwrap();
            let brute = (0..m.triangles().len())
                .map(|t| {
                    let [a, b, c] = m.corners(t);
                    (closest_on_triangle(&q, &a, &b, &c).0 - q).norm()
                })
                .fold(f64::INFINITY, f64::min);
            assert!(
                (got.distance_mm - brute).abs() < 1e-9,
                "{q}: {} vs {brute}",
                got.distance_mm
            );
        }
        assert!(tr.locate(&Point3::new(f64::NAN, 0.0, 0.0)).is_none());
    }

    #[test]
    fn flat_plane_path_is_straight_through_vertices_and_edges() {
        // A flat grid: any path is a straight line, also when it runs exactly through vertices.
        let m = triasym::revolution(&[(0.0, 1.0), (1.0, 1.0)], 4, false).unwrap();
        let _ = m;
        let n = 20;
        let mut v = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                v.push(Point3::new(i as f64, j as f64, 0.0));
            }
        }
        let mut t = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let a = (j * (n + 1) + i) as u32;
                let (b, c, d) = (a + 1, a + n as u32 + 1, a + n as u32 + 2);
                t.push([a, b, d]);
                t.push([a, d, c]);
            }
        }
        let tr = tracer(Mesh::new(v, t).unwrap());
        for mode in [Mode::Smooth, Mode::Exact] {
            for (start, heading_deg) in [
                (Point3::new(0.0, 0.0, 0.0), -45.0), // along diagonals, vertex to vertex
                (Point3::new(5.0, 0.0, 0.0), 0.0),   // along a grid line
                (Point3::new(3.3, 0.1, 0.0), -30.0),
                (Point3::new(10.0, 10.0, 0.0), 90.0), // from a vertex along an edge
            ] {
                let o = TraceOptions {
                    axis: Vector3::y(),
                    max_length_mm: 100.0,
                    mode,
                    ..TraceOptions::default()
                };
                let path = tr
                    .trace_heading(&start, f64::to_radians(heading_deg), 1e-9, &o)
                    .unwrap();
                assert_eq!(path.stop, Stop::Boundary);
                let dir = (path.points.last().unwrap() - start).normalize();
                for p in &path.points {
                    let off = (p - start) - dir * (p - start).dot(&dir);
                    assert!(
                        off.norm() < 1e-9,
                        "{mode:?} {heading_deg}: off {}",
                        off.norm()
                    );
                }
                assert_eq!(path.points.len(), path.faces.len());
            }
        }
    }

    #[test]
    fn slip_ratio_is_checked_against_friction() {
        let o = TraceOptions {
            lambda: 0.3,
            mu: Some(0.2),
            ..TraceOptions::default()
        };
        assert!(matches!(
            o.validate(),
            Err(Error::SlipExceedsFriction { .. })
        ));
        let o = TraceOptions {
            lambda: 0.1,
            ..TraceOptions::default()
        };
        assert!(o.validate().is_err());
        let o = TraceOptions {
            lambda: -0.1,
            mu: Some(0.2),
            ..TraceOptions::default()
        };
        assert!(o.validate().is_ok());
    }
}
