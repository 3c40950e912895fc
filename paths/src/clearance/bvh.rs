//! A bounding-volume hierarchy of axis-aligned boxes over a mesh's triangles: the collision
//! check's index ([`super::MeshSolid`]).
//!
//! Built top-down by median split: each node's items are split at the median of their boxes'
//! centres along the axis where those centres spread widest (`select_nth_unstable`, linear per
//! level), down to leaves of at most [`LEAF_ITEMS`] items. So the tree is balanced whatever the
//! mesh (depth `⌈log₂(n / LEAF_ITEMS)⌉ + 1`, 22 for 5 million triangles), its build is
//! `O(n log n)` with no allocation beyond its two arrays, and the nodes lie in depth-first order
//! (a node's left child follows it), the leaves' items in the same order, so a walk down one
//! branch reads memory that lies together. Boxes are exact (`f64`, the triangles' own bounds):
//! a box test never drops a triangle a query needs.
//!
//! Two walks: [`Bvh::leaves`] (every item whose leaf box passes a test: the triangles a ray or a
//! segment may cross) and [`Bvh::find_best`] (branch and bound for the item of least cost: the
//! nearest triangle to a point or a segment, nearer boxes first, boxes no better than the best
//! so far skipped).

/// Most items in a leaf.
pub const LEAF_ITEMS: usize = 2;

/// Deepest tree [`Bvh::new`] builds (a median split halves the items at each level, so this is
/// reached only beyond 2⁶⁰ items); it sizes the walks' stacks.
const MAX_DEPTH: usize = 64;

/// An axis-aligned box, mm: its least and greatest corner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Box3 {
    /// Least corner.
    pub lo: [f64; 3],
    /// Greatest corner.
    pub hi: [f64; 3],
}

impl Box3 {
    /// The empty box (its union with any box is that box).
    pub const EMPTY: Box3 = Box3 {
        lo: [f64::INFINITY; 3],
        hi: [f64::NEG_INFINITY; 3],
    };

    /// The smallest box holding both.
    pub fn union(&self, other: &Box3) -> Box3 {
        Box3 {
            lo: std::array::from_fn(|i| self.lo[i].min(other.lo[i])),
            hi: std::array::from_fn(|i| self.hi[i].max(other.hi[i])),
        }
    }

    fn centre(&self, axis: usize) -> f64 {
        0.5 * (self.lo[axis] + self.hi[axis])
    }
}

/// A node: inner (`count == 0`; left child at the next index, right child at `first`) or a leaf
/// (`count` items from `first` in [`Bvh::items`] order).
#[derive(Debug, Clone, Copy)]
struct Node {
    bounds: Box3,
    first: u32,
    count: u32,
}

/// The hierarchy over items `0..n` given by their boxes.
#[derive(Debug, Clone)]
pub struct Bvh {
    nodes: Vec<Node>,
    items: Vec<u32>,
}

impl Bvh {
    /// The hierarchy of `boxes` (item `i` is `boxes[i]`). Items beyond `u32::MAX` are not
    /// supported (the mesh limit is far below).
    pub fn new(boxes: &[Box3]) -> Bvh {
        let mut order: Vec<Centred> = boxes
            .iter()
            .enumerate()
            .map(|(i, b)| Centred {
                centre: std::array::from_fn(|axis| b.centre(axis)),
                item: i as u32,
            })
            .collect();
        let mut nodes = Vec::with_capacity(2 * boxes.len().div_ceil(LEAF_ITEMS).max(1));
        if !boxes.is_empty() {
            build_split(&mut nodes, &mut order, boxes);
        }
        Bvh {
            nodes,
            items: order.into_iter().map(|c| c.item).collect(),
        }
    }

    /// The root's box (`None` when there are no items).
    pub fn bounds(&self) -> Option<Box3> {
        self.nodes.first().map(|n| n.bounds)
    }

    /// Every item in a leaf whose box, and every box above it, passes `test`; in depth-first
    /// order, left before right.
    pub fn leaves<F: FnMut(&Box3) -> bool>(&self, test: F) -> Leaves<'_, F> {
        let mut stack = [0u32; MAX_DEPTH];
        let len = usize::from(!self.nodes.is_empty());
        stack[0] = 0;
        Leaves {
            bvh: self,
            test,
            stack,
            len,
            next: 0,
            end: 0,
        }
    }

    /// The item of least cost below `max_cost`, its cost and what `leaf_cost` said of it; `None`
    /// when none costs less than `max_cost`.
    ///
    /// `box_cost(b)` must be a lower bound of the cost of every item in box `b`; `leaf_cost(i,
    /// best)` is item `i`'s cost and a value (or `None` to skip it), where `best` is the least
    /// cost so far (an item at or above it changes nothing). Nearer boxes are walked first, and
    /// a box whose bound is not below the best so far is skipped with everything under it.
    pub fn find_best<T>(
        &self,
        max_cost: f64,
        box_cost: impl Fn(&Box3) -> f64,
        mut leaf_cost: impl FnMut(u32, f64) -> Option<(f64, T)>,
    ) -> Option<(u32, f64, T)> {
        let root = self.nodes.first()?;
        let mut best = max_cost;
        let mut found: Option<(u32, f64, T)> = None;
        let mut stack = [(0u32, 0.0f64); MAX_DEPTH];
        let mut len = 0;
        let root_cost = box_cost(&root.bounds);
        if root_cost < best {
            stack[0] = (0, root_cost);
            len = 1;
        }
        while len > 0 {
            len -= 1;
            let (index, cost) = stack[len];
            if cost >= best {
                continue;
            }
            let node = &self.nodes[index as usize];
            if node.count > 0 {
                let first = node.first as usize;
                for &item in &self.items[first..first + node.count as usize] {
                    if let Some((c, value)) = leaf_cost(item, best)
                        && c < best
                    {
                        best = c;
                        found = Some((item, c, value));
                    }
                }
                continue;
            }
            let (left, right) = (index + 1, node.first);
            let cl = box_cost(&self.nodes[left as usize].bounds);
            let cr = box_cost(&self.nodes[right as usize].bounds);
            // The nearer child on top, so it is walked first.
            let (near, far) = if cl <= cr {
                ((left, cl), (right, cr))
            } else {
                ((right, cr), (left, cl))
            };
            if far.1 < best {
                stack[len] = far;
                len += 1;
            }
            if near.1 < best {
                stack[len] = near;
                len += 1;
            }
        }
        found
    }
}

/// An item with its box's centre, as the build sorts them (the centres side by side, so each
/// level's split reads memory in order).
#[derive(Clone, Copy)]
struct Centred {
    centre: [f64; 3],
    item: u32,
}

/// Items from which the two halves under the root are built on two threads.
const PARALLEL_ITEMS: usize = 1 << 16;

/// [`build`] of the whole tree; on a large one, the root's two subtrees on two threads (each into
/// its own nodes, then joined behind the root with their node indices moved).
fn build_split(nodes: &mut Vec<Node>, items: &mut [Centred], boxes: &[Box3]) {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    if items.len() < PARALLEL_ITEMS || threads < 2 {
        build(nodes, items, 0, boxes);
        return;
    }
    let mid = split(items);
    let (left, right) = items.split_at_mut(mid);
    let ((left_nodes, left_bounds), (right_nodes, right_bounds)) = std::thread::scope(|scope| {
        let right_half = scope.spawn(|| {
            let mut n = Vec::with_capacity(right.len());
            let b = build(&mut n, right, mid, boxes);
            (n, b)
        });
        let mut n = Vec::with_capacity(left.len());
        let b = build(&mut n, left, 0, boxes);
        let r = right_half
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        ((n, b), r)
    });
    let right_root = 1 + left_nodes.len() as u32;
    nodes.push(Node {
        bounds: left_bounds.union(&right_bounds),
        first: right_root,
        count: 0,
    });
    let moved = |base: u32| {
        move |n: Node| {
            if n.count == 0 {
                Node {
                    first: n.first + base,
                    ..n
                }
            } else {
                n
            }
        }
    };
    nodes.extend(left_nodes.into_iter().map(moved(1)));
    nodes.extend(right_nodes.into_iter().map(moved(right_root)));
}

/// Splits `items` at the median of their centres along the axis where the centres spread
/// widest (ties and a zero spread take the lowest axis: the split still halves the items);
/// returns the index of the first item of the upper half.
fn split(items: &mut [Centred]) -> usize {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for c in items.iter() {
        for axis in 0..3 {
            lo[axis] = lo[axis].min(c.centre[axis]);
            hi[axis] = hi[axis].max(c.centre[axis]);
        }
    }
    let axis = (0..3)
        .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])).then(b.cmp(&a)))
        .unwrap_or(0);
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |a, b| a.centre[axis].total_cmp(&b.centre[axis]));
    mid
}

/// Builds the subtree of `items`, whose first is item `offset` of the whole order; returns its
/// root's box. Its root is the node at the index `nodes` has on entry.
fn build(nodes: &mut Vec<Node>, items: &mut [Centred], offset: usize, boxes: &[Box3]) -> Box3 {
    let me = nodes.len();
    if items.len() <= LEAF_ITEMS {
        let bounds = items
            .iter()
            .fold(Box3::EMPTY, |b, c| b.union(&boxes[c.item as usize]));
        nodes.push(Node {
            bounds,
            first: offset as u32,
            count: items.len() as u32,
        });
        return bounds;
    }
    let mid = split(items);
    nodes.push(Node {
        bounds: Box3::EMPTY,
        first: 0,
        count: 0,
    });
    let (left, right) = items.split_at_mut(mid);
    let left_bounds = build(nodes, left, offset, boxes);
    let right_index = nodes.len() as u32;
    let right_bounds = build(nodes, right, offset + mid, boxes);
    let bounds = left_bounds.union(&right_bounds);
    nodes[me] = Node {
        bounds,
        first: right_index,
        count: 0,
    };
    bounds
}

/// The walk of [`Bvh::leaves`].
#[allow(missing_debug_implementations)]
pub struct Leaves<'a, F> {
    bvh: &'a Bvh,
    test: F,
    stack: [u32; MAX_DEPTH],
    len: usize,
    /// The current leaf's items still to give, `next..end` of [`Bvh::items`].
    next: usize,
    end: usize,
}

impl<F: FnMut(&Box3) -> bool> Iterator for Leaves<'_, F> {
    type Item = u32;

    fn next(&mut self) -> Option<u32> {
        loop {
            if self.next < self.end {
                self.next += 1;
                return Some(self.bvh.items[self.next - 1]);
            }
            if self.len == 0 {
                return None;
            }
            self.len -= 1;
            let index = self.stack[self.len];
            let node = &self.bvh.nodes[index as usize];
            if !(self.test)(&node.bounds) {
                continue;
            }
            if node.count > 0 {
                self.next = node.first as usize;
                self.end = self.next + node.count as usize;
            } else {
                // Right below left, so the left is walked first.
                self.stack[self.len] = node.first;
                self.stack[self.len + 1] = index + 1;
                self.len += 2;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn random_boxes(n: usize, seed: u64) -> Vec<Box3> {
        let mut next = crate::clearance::test_support::uniform(seed);
        (0..n)
            .map(|_| {
                let c = [next() * 100.0, next() * 100.0, next() * 10.0];
                let h = [next() * 2.0, next() * 2.0, next() * 2.0];
                Box3 {
                    lo: std::array::from_fn(|i| c[i] - h[i]),
                    hi: std::array::from_fn(|i| c[i] + h[i]),
                }
            })
            .collect()
    }

    fn overlaps(a: &Box3, b: &Box3) -> bool {
        (0..3).all(|i| a.lo[i] <= b.hi[i] && b.lo[i] <= a.hi[i])
    }

    fn point_box(p: [f64; 3], b: &Box3) -> f64 {
        (0..3)
            .map(|i| (b.lo[i] - p[i]).max(p[i] - b.hi[i]).max(0.0).powi(2))
            .sum::<f64>()
            .sqrt()
    }

    #[test]
    fn every_item_sits_once_in_a_leaf_whose_boxes_hold_it() {
        for n in [1, 2, 4, 5, 17, 1000] {
            let boxes = random_boxes(n, 7 + n as u64);
            let bvh = Bvh::new(&boxes);
            let mut seen: Vec<u32> = bvh.leaves(|_| true).collect();
            seen.sort_unstable();
            assert_eq!(seen, (0..n as u32).collect::<Vec<_>>(), "n = {n}");
            // Walking only the boxes that hold item i's box reaches item i.
            for (i, b) in boxes.iter().enumerate() {
                let holds =
                    |node: &Box3| (0..3).all(|k| node.lo[k] <= b.lo[k] && node.hi[k] >= b.hi[k]);
                assert!(
                    bvh.leaves(holds).any(|j| j as usize == i),
                    "item {i} of {n}"
                );
            }
            let depth_bound = (n.div_ceil(LEAF_ITEMS) as f64).log2().ceil() as usize + 2;
            assert!(bvh.nodes.len() < 2 * n.div_ceil(LEAF_ITEMS) * 2 + 1);
            assert!(depth(&bvh, 0) <= depth_bound, "n = {n}");
        }
    }

    fn depth(bvh: &Bvh, index: u32) -> usize {
        let node = &bvh.nodes[index as usize];
        if node.count > 0 {
            1
        } else {
            1 + depth(bvh, index + 1).max(depth(bvh, node.first))
        }
    }

    #[test]
    fn leaves_are_exactly_the_items_whose_boxes_pass_an_overlap_test() {
        let boxes = random_boxes(3000, 99);
        let bvh = Bvh::new(&boxes);
        for q in random_boxes(50, 5) {
            let query = Box3 {
                lo: q.lo,
                hi: std::array::from_fn(|i| q.hi[i] + 5.0),
            };
            let mut got: Vec<u32> = bvh
                .leaves(|b| overlaps(b, &query))
                .filter(|&i| overlaps(&boxes[i as usize], &query))
                .collect();
            got.sort_unstable();
            let want: Vec<u32> = (0..boxes.len() as u32)
                .filter(|&i| overlaps(&boxes[i as usize], &query))
                .collect();
            assert_eq!(got, want);
        }
    }

    #[test]
    fn find_best_is_the_brute_force_nearest_box_and_honours_its_cap() {
        let boxes = random_boxes(2000, 3);
        let bvh = Bvh::new(&boxes);
        for (k, q) in random_boxes(200, 11).iter().enumerate() {
            let p = [
                q.lo[0] * 1.2 - 10.0,
                q.lo[1] * 1.2 - 10.0,
                q.lo[2] * 3.0 - 5.0,
            ];
            let (want_i, want) = boxes
                .iter()
                .enumerate()
                .map(|(i, b)| (i, point_box(p, b)))
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap();
            let mut calls = 0;
            let got = bvh.find_best(
                f64::INFINITY,
                |b| point_box(p, b),
                |i, _| {
                    calls += 1;
                    Some((point_box(p, &boxes[i as usize]), i))
                },
            );
            let (i, cost, value) = got.unwrap();
            assert_eq!(cost, want, "query {k}");
            assert_eq!(i, value);
            if want > 0.0 {
                assert_eq!(i as usize, want_i, "query {k}");
                // Branch and bound visits a small part of the items.
                assert!(calls < boxes.len() / 4, "{calls} leaf calls");
            }
            // Below a cap at the nearest cost, nothing is found; just above it, the nearest.
            assert!(
                bvh.find_best(
                    want,
                    |b| point_box(p, b),
                    |i, _| Some((point_box(p, &boxes[i as usize]), ()))
                )
                .is_none()
            );
            let capped = bvh.find_best(
                want + 1e-9,
                |b| point_box(p, b),
                |i, _| Some((point_box(p, &boxes[i as usize]), ())),
            );
            assert_eq!(capped.map(|c| c.1), Some(want));
        }
    }

    /// A tree large enough to be built on two threads: each inner node's box holds its
    /// children's, every item sits once in a leaf, and the nearest box is brute force's.
    #[test]
    fn a_tree_built_on_two_threads_is_whole() {
        let n = PARALLEL_ITEMS + 4321;
        let boxes = random_boxes(n, 42);
        let bvh = Bvh::new(&boxes);
        let holds = |a: &Box3, b: &Box3| (0..3).all(|k| a.lo[k] <= b.lo[k] && a.hi[k] >= b.hi[k]);
        for (i, node) in bvh.nodes.iter().enumerate() {
            if node.count == 0 {
                let (l, r) = (&bvh.nodes[i + 1], &bvh.nodes[node.first as usize]);
                assert!(node.first as usize > i + 1, "node {i}");
                assert!(holds(&node.bounds, &l.bounds) && holds(&node.bounds, &r.bounds));
            } else {
                let first = node.first as usize;
                for &item in &bvh.items[first..first + node.count as usize] {
                    assert!(holds(&node.bounds, &boxes[item as usize]), "leaf {i}");
                }
            }
        }
        let mut seen: Vec<u32> = bvh.leaves(|_| true).collect();
        seen.sort_unstable();
        assert_eq!(seen, (0..n as u32).collect::<Vec<_>>());
        assert!(depth(&bvh, 0) <= (n.div_ceil(LEAF_ITEMS) as f64).log2().ceil() as usize + 2);
        for q in random_boxes(20, 8) {
            let p = [q.lo[0] * 1.5 - 20.0, q.lo[1], q.lo[2] * 4.0];
            let want = boxes
                .iter()
                .map(|b| point_box(p, b))
                .fold(f64::INFINITY, f64::min);
            let got = bvh.find_best(
                f64::INFINITY,
                |b| point_box(p, b),
                |i, _| Some((point_box(p, &boxes[i as usize]), ())),
            );
            assert_eq!(got.map(|g| g.1), Some(want));
        }
    }

    /// Boxes in a row across the origin (not centred on it): every split is at the median centre, so at every inner
    /// node the two children's boxes lie apart along the row (a split by anything but the
    /// centres, or a centre computed wrongly, interleaves them), and each half holds half.
    #[test]
    fn a_row_of_boxes_splits_into_apart_halves() {
        let boxes: Vec<Box3> = (-300..700)
            .map(|i| Box3 {
                lo: [i as f64, 0.0, 0.0],
                hi: [i as f64 + 0.5, 1.0, 1.0],
            })
            .collect();
        let bvh = Bvh::new(&boxes);
        fn leaves_under(bvh: &Bvh, index: u32) -> usize {
            let node = &bvh.nodes[index as usize];
            if node.count > 0 {
                node.count as usize
            } else {
                leaves_under(bvh, index + 1) + leaves_under(bvh, node.first)
            }
        }
        for (i, node) in bvh.nodes.iter().enumerate() {
            if node.count > 0 {
                continue;
            }
            let (l, r) = (
                &bvh.nodes[i + 1].bounds,
                &bvh.nodes[node.first as usize].bounds,
            );
            assert!(
                l.hi[0] < r.lo[0] || r.hi[0] < l.lo[0],
                "node {i}: {l:?} {r:?}"
            );
            let (nl, nr) = (
                leaves_under(&bvh, i as u32 + 1),
                leaves_under(&bvh, node.first),
            );
            assert!(nl.abs_diff(nr) <= 1, "node {i}: {nl} and {nr}");
        }
    }

    #[test]
    fn an_empty_hierarchy_finds_nothing() {
        let bvh = Bvh::new(&[]);
        assert!(bvh.bounds().is_none());
        assert_eq!(bvh.leaves(|_| true).count(), 0);
        assert!(
            bvh.find_best(f64::INFINITY, |_| 0.0, |i, _| Some((0.0, i)))
                .is_none()
        );
    }

    #[test]
    fn identical_boxes_still_split_into_small_leaves() {
        let b = Box3 {
            lo: [1.0; 3],
            hi: [2.0; 3],
        };
        let bvh = Bvh::new(&vec![b; 1000]);
        assert!(bvh.nodes.iter().all(|n| n.count as usize <= LEAF_ITEMS));
        assert_eq!(bvh.leaves(|_| true).count(), 1000);
        assert!(depth(&bvh, 0) <= 10);
    }
}
