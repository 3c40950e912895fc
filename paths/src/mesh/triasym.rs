//! Mesh generation from a spine and sections, the TRIASYM approach of seed 001 §3.1: circular
//! sections of the mandrel radius, normal to the spine, every `spacing_mm` along it; each section
//! divided into `facets` equal arcs; consecutive sections joined by two triangles per facet; the
//! ends closed by flat caps (a fan around the section centre) so the mesh is watertight.
//!
//! The section vertices lie exactly on the analytic tube ([`Tube::point`]), so a mesh geodesic and
//! the analytic one ([`crate::geodesic`]) can be compared directly. Surfaces of revolution (cones,
//! for Clairaut's relation) and icospheres (for the tracer's tests and benches) are generated too.

use std::collections::HashMap;
use std::f64::consts::TAU;

use nalgebra::{Point3, Vector3};

use super::Mesh;
use crate::{Error, Tube};

fn check_facets(facets: usize) -> Result<(), Error> {
    if (3..=1 << 20).contains(&facets) {
        Ok(())
    } else {
        Err(Error::OutOfRange {
            name: "facets",
            value: facets as f64,
            expected: "must lie in 3..=1048576",
        })
    }
}

/// Joins rings of equally many points (ordered counter-clockwise about the axis, seen from the
/// last ring) into a tube, closing the ends with fans around `caps` centres when given.
fn rings_to_mesh(
    rings: Vec<Vec<Point3<f64>>>,
    caps: Option<[Point3<f64>; 2]>,
) -> Result<Mesh, Error> {
    let n = rings[0].len();
    let m = rings.len();
    let mut vertices: Vec<Point3<f64>> = rings.into_iter().flatten().collect();
    let id = |i: usize, j: usize| (i * n + j % n) as u32;
    let mut triangles = Vec::with_capacity(2 * n * m + 2 * n);
    for i in 0..m - 1 {
        for j in 0..n {
            let (a, b, c, d) = (id(i, j), id(i, j + 1), id(i + 1, j), id(i + 1, j + 1));
            triangles.push([a, b, c]);
            triangles.push([b, d, c]);
        }
    }
    if let Some([bottom, top]) = caps {
        let cb = vertices.len() as u32;
        vertices.push(bottom);
        let ct = vertices.len() as u32;
        vertices.push(top);
        for j in 0..n {
            triangles.push([cb, id(0, j + 1), id(0, j)]);
            triangles.push([ct, id(m - 1, j), id(m - 1, j + 1)]);
        }
    }
    Mesh::new(vertices, triangles)
}

/// The TRIASYM mesh of `tube`: sections every `spacing_mm` or less along the spine height (equal
/// spacing, the first and last at the spine's ends), `facets` triangles pairs per circumference,
/// with end caps when `caps` is true. Section `j` starts at `v = 0` (the spine normal side).
pub fn tube(tube: &Tube, facets: usize, spacing_mm: f64, caps: bool) -> Result<Mesh, Error> {
    check_facets(facets)?;
    let (u0, u1) = (tube.u_min(), tube.u_max());
    if !(spacing_mm > 0.0 && spacing_mm.is_finite()) {
        return Err(Error::OutOfRange {
            name: "section_spacing_mm",
            value: spacing_mm,
            expected: "must be > 0",
        });
    }
    let sections = ((u1 - u0) / spacing_mm).ceil().max(1.0);
    if sections > 1e6 {
        return Err(Error::OutOfRange {
            name: "section_spacing_mm",
            value: spacing_mm,
            expected: "must leave at most a million sections",
        });
    }
    crate::limits::at_most(
        "triangle count",
        2.0 * (sections + 1.0) * facets as f64,
        crate::limits::MAX_TRIANGLES as f64,
    )?;
    let sections = sections as usize;
    let rings: Vec<Vec<Point3<f64>>> = (0..=sections)
        .map(|i| {
            let u = u0 + (u1 - u0) * i as f64 / sections as f64;
            (0..facets)
                .map(|j| tube.point(u, TAU * j as f64 / facets as f64))
                .collect()
        })
        .collect();
    let centre = |u: f64| Point3::new(tube.spine().offset_mm(u), 0.0, u);
    rings_to_mesh(rings, caps.then(|| [centre(u0), centre(u1)]))
}

/// A surface of revolution about `z` through `profile` points `(z_mm, radius_mm)` (heights strictly
/// increasing, radii > 0), `facets` around, capped when `caps` is true. A cone is two points.
pub fn revolution(profile: &[(f64, f64)], facets: usize, caps: bool) -> Result<Mesh, Error> {
    check_facets(facets)?;
    if profile.len() < 2 {
        return Err(Error::TooFewPoints {
            what: "surface of revolution",
            count: profile.len(),
            needed: 2,
        });
    }
    for (i, &(z, r)) in profile.iter().enumerate() {
        if !(z.is_finite() && r.is_finite() && r > 0.0) || (i > 0 && z <= profile[i - 1].0) {
            return Err(Error::SpineNotIncreasing {
                index: i,
                height_mm: z,
            });
        }
    }
    let rings = profile
        .iter()
        .map(|&(z, r)| {
            (0..facets)
                .map(|j| {
                    let (s, c) = (TAU * j as f64 / facets as f64).sin_cos();
                    Point3::new(r * c, r * s, z)
                })
                .collect()
        })
        .collect();
    let (z0, z1) = (profile[0].0, profile[profile.len() - 1].0);
    rings_to_mesh(
        rings,
        caps.then(|| [Point3::new(0.0, 0.0, z0), Point3::new(0.0, 0.0, z1)]),
    )
}

/// An icosphere of `radius_mm` centred at the origin: an icosahedron with each triangle split in
/// four `subdivisions` times, new vertices pushed onto the sphere (`20 · 4^subdivisions` faces;
/// 6 subdivisions give 81 920).
pub fn icosphere(radius_mm: f64, subdivisions: u32) -> Result<Mesh, Error> {
    if !(radius_mm > 0.0 && radius_mm.is_finite()) || subdivisions > 9 {
        return Err(Error::OutOfRange {
            name: "radius_mm / subdivisions",
            value: radius_mm,
            expected: "radius > 0 and at most 9 subdivisions",
        });
    }
    let phi = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<Vector3<f64>> = [
        (-1.0, phi, 0.0),
        (1.0, phi, 0.0),
        (-1.0, -phi, 0.0),
        (1.0, -phi, 0.0),
        (0.0, -1.0, phi),
        (0.0, 1.0, phi),
        (0.0, -1.0, -phi),
        (0.0, 1.0, -phi),
        (phi, 0.0, -1.0),
        (phi, 0.0, 1.0),
        (-phi, 0.0, -1.0),
        (-phi, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vector3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[u32; 3]> = vec![
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
    for _ in 0..subdivisions {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::with_capacity(f.len() * 4);
        let mut midpoint = |a: u32, b: u32, v: &mut Vec<Vector3<f64>>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                v.push((v[a as usize] + v[b as usize]).normalize());
                (v.len() - 1) as u32
            })
        };
        for &[a, b, c] in &f {
            let ab = midpoint(a, b, &mut v);
            let bc = midpoint(b, c, &mut v);
            let ca = midpoint(c, a, &mut v);
            next.extend_from_slice(&[[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    Mesh::new(
        v.into_iter().map(|p| Point3::from(p * radius_mm)).collect(),
        f,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Spine;
    use crate::mesh::{Closure, DEFAULT_WELD_MM, prepare};
    use crate::spine::{SBEND_SMOOTHING_MM, SBEND_TABLE_6_1_MM};

    #[test]
    fn sbend_mesh_is_closed_outward_and_on_the_tube() {
        let t = Tube::new(
            Spine::smoothing(&SBEND_TABLE_6_1_MM, SBEND_SMOOTHING_MM).unwrap(),
            28.5,
        )
        .unwrap();
        let m = tube(&t, 48, 5.0, true).unwrap();
        assert_eq!(m.triangles().len(), 2 * 48 * 70 + 2 * 48);
        let adj = m.validate(Closure::Closed).unwrap();
        assert_eq!(adj.boundary_edges, 0);
        assert!(m.signed_volume_mm3() > 0.0);
        // Volume close to π r² × spine length (the spine is nearly straight).
        let v = m.signed_volume_mm3();
        let expect = std::f64::consts::PI * 28.5f64.powi(2) * 350.0;
        assert!((v / expect - 1.0).abs() < 0.02, "{v} vs {expect}");
        for p in &m.vertices()[..48 * 71] {
            assert!(t.distance_to_surface_mm(p).abs() < 1e-6);
        }
    }

    #[test]
    fn icosphere_and_cone_are_valid() {
        let s = icosphere(50.0, 3).unwrap();
        assert_eq!(s.triangles().len(), 1280);
        let (s, _) = prepare(&s, DEFAULT_WELD_MM, Closure::Closed).unwrap();
        assert!(s.signed_volume_mm3() > 0.0);
        let c = revolution(&[(0.0, 40.0), (100.0, 20.0)], 64, false).unwrap();
        assert_eq!(c.validate(Closure::Open).unwrap().boundary_edges, 128);
        assert!(revolution(&[(0.0, 1.0)], 8, true).is_err());
        assert!(revolution(&[(0.0, 1.0), (0.0, 2.0)], 8, true).is_err());
        assert!(revolution(&[(0.0, 1.0), (1.0, 2.0)], 2, true).is_err());
    }
}
