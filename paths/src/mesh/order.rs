//! Face and vertex order for memory locality.
//!
//! Files list triangles in whatever order their writer chose; some put the two triangles of a grid
//! quad half the file apart, so a path crossing the mandrel jumps across memory at every edge. At
//! load ([`super::prepare`]) the triangles are sorted along a Morton (Z-order) curve through their
//! centroids, and the vertices renumbered in the order the sorted triangles first use them, so
//! neighbours on the surface are neighbours in memory.
//!
//! Each triangle keeps its corner order (so its normal and its edge numbering are unchanged), and
//! the mesh remembers where each triangle stood in the file ([`Mesh::file_triangle`]): reports
//! name triangles by their file index.

use super::{Adjacency, Mesh, NO_NEIGHBOUR};

/// Bits per axis of the Morton key (three axes in a `u64`).
const BITS: u32 = 21;

/// Spreads the low 21 bits of `x` so that two zero bits follow each one.
fn spread(x: u64) -> u64 {
    let mut x = x & 0x1f_ffff;
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// The Morton key of integer cell coordinates (each below 2²¹).
fn morton(cell: [u64; 3]) -> u64 {
    spread(cell[0]) | spread(cell[1]) << 1 | spread(cell[2]) << 2
}

/// The mesh with its triangles in Morton order of their centroids and its vertices in order of
/// first use, and `adjacency` renumbered to match. The geometry is unchanged: the same triangles,
/// each with its corners in the same order.
pub fn by_locality(mesh: &Mesh, adjacency: &Adjacency) -> (Mesh, Adjacency) {
    let (lo, hi) = mesh.bounds();
    let size = (hi - lo).max().max(f64::MIN_POSITIVE);
    let scale = ((1u64 << BITS) - 1) as f64 / size;
    let mut keyed: Vec<(u64, u32)> = (0..mesh.triangles.len())
        .map(|t| {
            let [a, b, c] = mesh.corners(t);
            let centroid = (a.coords + b.coords + c.coords) / 3.0 - lo.coords;
            let cell = [0, 1, 2].map(|k| (centroid[k] * scale).clamp(0.0, scale * size) as u64);
            (morton(cell), t as u32)
        })
        .collect();
    keyed.sort_unstable();
    let mut new_of_old = vec![0u32; keyed.len()];
    for (new, &(_, old)) in keyed.iter().enumerate() {
        new_of_old[old as usize] = new as u32;
    }
    let mut vertex_of_old = vec![u32::MAX; mesh.vertices.len()];
    let mut vertices = Vec::with_capacity(mesh.vertices.len());
    let mut triangles = Vec::with_capacity(keyed.len());
    let mut file_triangles = Vec::with_capacity(keyed.len());
    let mut across = Vec::with_capacity(keyed.len());
    for &(_, old) in &keyed {
        let tri = mesh.triangles[old as usize].map(|v| {
            let slot = &mut vertex_of_old[v as usize];
            if *slot == u32::MAX {
                *slot = vertices.len() as u32;
                vertices.push(mesh.vertices[v as usize]);
            }
            *slot
        });
        triangles.push(tri);
        file_triangles.push(mesh.file_triangles[old as usize]);
        across.push(adjacency.across[old as usize].map(|h| {
            if h == NO_NEIGHBOUR {
                h
            } else {
                new_of_old[(h >> 2) as usize] << 2 | (h & 3)
            }
        }));
    }
    (
        Mesh {
            vertices,
            triangles,
            file_triangles,
        },
        Adjacency {
            across,
            boundary_edges: adjacency.boundary_edges,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::trace::{DEFAULT_CREASE_DEG, TraceOptions, Tracer};
    use crate::mesh::{Closure, DEFAULT_WELD_MM, prepare, triasym};
    use nalgebra::Point3;

    /// A geodesic traced on the sorted mesh is the one traced in file order: the same points
    /// (to rounding) through the same file triangles.
    #[test]
    fn sorting_leaves_traces_unchanged() {
        let profile: Vec<(f64, f64)> = (0..41).map(|i| (5.0 * i as f64, 28.5)).collect();
        let grid = triasym::revolution(&profile, 64, true).unwrap();
        // Split order: the two triangles of each quad half the file apart.
        let quads = 2 * 64 * 40;
        let t = grid.triangles();
        let mut split: Vec<[u32; 3]> = (0..quads).step_by(2).map(|i| t[i]).collect();
        split.extend((1..quads).step_by(2).map(|i| t[i]));
        split.extend_from_slice(&t[quads..]);
        let file = Mesh::new(grid.vertices().to_vec(), split).unwrap();
        let adjacency = file.validate(Closure::Closed).unwrap();
        let unsorted = Tracer::new(file.clone(), &adjacency, DEFAULT_CREASE_DEG).unwrap();
        let (sorted_mesh, sorted_adjacency) =
            prepare(&file, DEFAULT_WELD_MM, Closure::Closed).unwrap();
        assert_ne!(sorted_mesh.triangles(), file.triangles());
        let sorted = Tracer::new(sorted_mesh, &sorted_adjacency, DEFAULT_CREASE_DEG).unwrap();
        let o = TraceOptions {
            max_length_mm: 600.0,
            ..TraceOptions::default()
        };
        // Inside a triangle: a start on an edge may begin in either neighbour.
        let start = Point3::new(28.5 * 0.05f64.cos(), 28.5 * 0.05f64.sin(), 12.3);
        for heading in [0.3, 1.0, 1.4] {
            let a = unsorted.trace_heading(&start, heading, 1.0, &o).unwrap();
            let b = sorted.trace_heading(&start, heading, 1.0, &o).unwrap();
            assert_eq!(a.crossings, b.crossings);
            assert!((a.length_mm - b.length_mm).abs() < 1e-9);
            for (p, q) in a.points.iter().zip(&b.points) {
                assert!((p - q).norm() < 1e-9, "{p} vs {q}");
            }
            let mapped: Vec<u32> = b
                .faces
                .iter()
                .map(|&f| sorted.mesh().file_triangle(f as usize) as u32)
                .collect();
            assert_eq!(a.faces, mapped);
        }
    }

    #[test]
    fn spread_interleaves_bits() {
        assert_eq!(spread(0b1), 0b1);
        assert_eq!(spread(0b11), 0b1001);
        assert_eq!(spread(0x1f_ffff).count_ones(), 21);
        assert_eq!(morton([1, 0, 0]), 1);
        assert_eq!(morton([0, 1, 0]), 2);
        assert_eq!(morton([0, 0, 1]), 4);
        assert_eq!(morton([3, 3, 3]), 0b111_111);
    }

    /// A fine flat grid far from the origin, its triangles in scrambled file order: the key must
    /// quantise the centroids relative to the mesh's own bounds and at full resolution, or
    /// neighbouring triangles share a key and keep the scrambled order. Morton order on a grid of
    /// 1/8 mm squares steps on average about one square side; scrambled order steps about a third of
    /// the grid's width.
    #[test]
    fn orders_a_fine_grid_far_from_the_origin() {
        // 56 squares of 1/8 mm: 7 mm across, exact in binary.
        let n = 56u32;
        let side = 0.125;
        let origin = 1.0e6;
        let vertices: Vec<Point3<f64>> = (0..=n)
            .flat_map(|j| {
                (0..=n).map(move |i| {
                    Point3::new(origin + i as f64 * side, origin + j as f64 * side, 0.0)
                })
            })
            .collect();
        let v = |i: u32, j: u32| j * (n + 1) + i;
        let mut triangles = Vec::new();
        for j in 0..n {
            for i in 0..n {
                triangles.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
                triangles.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
            }
        }
        // Scramble: sorted by a splitmix64 hash of the index (no spatial pattern left).
        let count = triangles.len();
        let hash = |k: u64| {
            let mut z = k.wrapping_add(0x9e37_79b9_7f4a_7c15);
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^ (z >> 31)
        };
        let mut keyed: Vec<(u64, [u32; 3])> = triangles
            .iter()
            .enumerate()
            .map(|(k, &t)| (hash(k as u64), t))
            .collect();
        keyed.sort_unstable();
        let scrambled: Vec<[u32; 3]> = keyed.into_iter().map(|(_, t)| t).collect();
        let mesh = Mesh::new(vertices, scrambled).unwrap();
        let adjacency = mesh.validate(Closure::Open).unwrap();
        let (sorted, _) = by_locality(&mesh, &adjacency);
        let centroid = |t: usize| {
            let [a, b, c] = sorted.corners(t);
            (a.coords + b.coords + c.coords) / 3.0
        };
        let mean_step: f64 = (1..count)
            .map(|t| (centroid(t) - centroid(t - 1)).norm())
            .sum::<f64>()
            / (count - 1) as f64;
        assert!(mean_step < 2.0 * side, "mean step {mean_step} mm");
    }

    /// Reversed file order: the sort must undo it, keep every triangle's geometry and corner
    /// order, and give the adjacency a fresh validation would give.
    #[test]
    fn keeps_geometry_and_adjacency_and_remembers_file_order() {
        let ring = triasym::icosphere(10.0, 3).unwrap();
        let reversed: Vec<[u32; 3]> = ring.triangles().iter().rev().copied().collect();
        let mesh = Mesh::new(ring.vertices().to_vec(), reversed).unwrap();
        let adjacency = mesh.validate(Closure::Closed).unwrap();
        let (sorted, sorted_adjacency) = by_locality(&mesh, &adjacency);
        assert_eq!(sorted.triangles().len(), mesh.triangles().len());
        assert_eq!(sorted.vertices().len(), mesh.vertices().len());
        let mut seen = vec![false; mesh.triangles().len()];
        for t in 0..sorted.triangles().len() {
            let file = sorted.file_triangle(t);
            assert!(!seen[file]);
            seen[file] = true;
            assert_eq!(sorted.corners(t), mesh.corners(file));
        }
        assert_eq!(
            sorted_adjacency,
            sorted.validate(Closure::Closed).unwrap(),
            "renumbered adjacency differs from a fresh one"
        );
        // Vertices in order of first use.
        let mut next = 0;
        for tri in sorted.triangles() {
            for &v in tri {
                assert!(v <= next);
                if v == next {
                    next += 1;
                }
            }
        }
        // Locality: consecutive triangles are close (mean centroid step well below the radius).
        let centroid = |t: usize| {
            let [a, b, c] = sorted.corners(t);
            (a.coords + b.coords + c.coords) / 3.0
        };
        let mean_step: f64 = (1..sorted.triangles().len())
            .map(|t| (centroid(t) - centroid(t - 1)).norm())
            .sum::<f64>()
            / (sorted.triangles().len() - 1) as f64;
        assert!(mean_step < 2.0, "mean step {mean_step} mm");
    }
}
