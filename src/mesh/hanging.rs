//! T-vertices: display vertices of a smooth surface that lie inside an element's edge
//! without being one of its corners.
//!
//! Two kinds exist. Adaptive subdivision leaves them at the midpoints of coarse edges
//! (a finer neighbour's corner), and the 2:1 balance keeps them there. Input meshes leave
//! them anywhere: a triangle whose edge runs past a neighbour's corner (Sponza's walls are
//! modelled so, fans of long triangles against rows of short ones), or a contact line
//! ending on an edge its neighbour does not share. A vertex there that took its own value
//! would show the light jump along the edge (a line, dark or bright, where the coarse side
//! interpolates across it); hung at its parameter on the edge it takes the edge's value,
//! and the light is continuous (see `DisplayMesh::vertex_values`).
//!
//! Finding them: an edge with a T-vertex inside is used by one element only (its
//! neighbours across use shorter edges), and the T-vertex is an end of such an edge. So
//! only the unmatched edges are searched, for the ends of unmatched edges within a
//! tolerance of them, through a uniform grid over those ends.

use super::Element;
use crate::geometry::sampling::FastMap;
use glam::Vec3;
use rayon::prelude::*;

/// A T-vertex: `vertex` lies on the edge from display vertex `edge[0]` to `edge[1]` of a
/// coarser element that does not use it, at `edge[0] + t·(edge[1] − edge[0])`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hanging {
    pub vertex: u32,
    pub edge: [u32; 2],
    pub t: f32,
}

impl Hanging {
    /// Whether the vertex is its edge's midpoint (up to f32 rounding): the T-vertices of
    /// subdivision, which the 2:1 balance acts on.
    pub fn is_midpoint(&self) -> bool {
        (self.t - 0.5).abs() <= 1e-4
    }
}

/// The T-vertices of `elements` over display vertices at `positions`: each vertex that
/// lies on an element's edge, is not one of its corners and is of the same smooth surface
/// (`same_surface(vertex, element)`). On the edge means: further than `tol` / 10 from
/// its ends (welding merges points closer), and off the line by no more than `tol` and
/// either a few f32 roundings of the coordinates or 10⁻³ of the distance to the nearer
/// end. The second bound keeps a vertex of a neighbouring sliver out: near the apex of a
/// fan of long thin triangles, a triangle's corner lies within any fixed distance of the
/// next one's edge, but at an angle to it as seen from the apex. A vertex inside several
/// edges hangs on the longest. Ordered longest edge first, so that an edge whose ends hang
/// themselves is resolved before the vertices on it.
pub(super) fn find(
    elements: &[Element],
    positions: &[Vec3],
    tol: f32,
    same_surface: impl Fn(u32, &Element) -> bool + Sync,
) -> Vec<Hanging> {
    let unmatched = unmatched_edges(elements);
    if unmatched.is_empty() {
        return Vec::new();
    }
    let ends = |&(e, k): &(u32, u8)| {
        let c = elements[e as usize].corners;
        [c[k as usize], c[(k as usize + 1) % 3]]
    };
    // The grid's cell: the median unmatched edge, so that a typical edge crosses a few
    // cells and a cell holds a few ends.
    let mut lengths: Vec<f32> = unmatched
        .iter()
        .map(|edge| {
            let [a, b] = ends(edge);
            (positions[b as usize] - positions[a as usize]).length()
        })
        .collect();
    let middle = lengths.len() / 2;
    let cell = lengths
        .select_nth_unstable_by(middle, f32::total_cmp)
        .1
        .max(4.0 * tol)
        .max(f32::MIN_POSITIVE);
    let cell_of = |p: Vec3| (p / cell).floor().as_ivec3().to_array();
    let mut grid: Grid = Grid::default();
    let mut candidate = vec![false; positions.len()];
    for edge in &unmatched {
        for v in ends(edge) {
            if !std::mem::replace(&mut candidate[v as usize], true) {
                // Within twice the tolerance: the walk along an edge may round past a
                // cell the edge only grazes.
                let p = positions[v as usize];
                for_cells(cell_of(p - 2.0 * tol), cell_of(p + 2.0 * tol), |c| {
                    grid.entry(c).or_default().push(v)
                });
            }
        }
    }
    // Every (edge length, T-vertex) found, edges in parallel.
    let found: Vec<(f32, Hanging)> = unmatched
        .par_chunks(4096)
        .flat_map_iter(|chunk| {
            let mut near = Vec::new();
            let mut found = Vec::new();
            for &(e, k) in chunk {
                let element = &elements[e as usize];
                let [ca, cb] = ends(&(e, k));
                let (a, b) = (positions[ca as usize], positions[cb as usize]);
                let d = b - a;
                let len = d.length();
                if len <= 0.2 * tol {
                    continue;
                }
                near.clear();
                for_cells_along(a / cell, b / cell, |c| {
                    if let Some(list) = grid.get(&c) {
                        near.extend_from_slice(list);
                    }
                });
                near.sort_unstable();
                near.dedup();
                for &v in &near {
                    if element.corners.contains(&v) {
                        continue;
                    }
                    let p = positions[v as usize];
                    let along = (p - a).dot(d) / len;
                    let nearer = along.min(len - along);
                    if nearer <= 0.1 * tol {
                        continue; // at an end (welding merges points closer than this)
                    }
                    let t = along / len;
                    let rounding = 1e-6 * a.abs().max(b.abs()).max(p.abs()).max_element();
                    let off = (a + d * t - p).length();
                    if off <= tol.min(rounding.max(1e-3 * nearer)) && same_surface(v, element) {
                        let edge = [ca, cb];
                        found.push((len, Hanging { vertex: v, edge, t }));
                    }
                }
            }
            found
        })
        .collect();
    // Per vertex the longest edge (then the lowest ends: the same for any thread count).
    let mut best: Vec<Option<(f32, Hanging)>> = vec![None; positions.len()];
    for (len, h) in found {
        let slot = &mut best[h.vertex as usize];
        let better = slot.is_none_or(|(l, o)| len > l || (len == l && h.edge < o.edge));
        if better {
            *slot = Some((len, h));
        }
    }
    let mut found: Vec<(f32, Hanging)> = best.into_iter().flatten().collect();
    found.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.vertex.cmp(&y.1.vertex)));
    found.into_iter().map(|(_, h)| h).collect()
}

/// The grid over the ends of unmatched edges: cell → the vertices within `tol` of it.
type Grid = FastMap<[i32; 3], Vec<u32>>;

/// The edges (element, edge k from corner k to k + 1) that no other element shares, by
/// their display vertices.
fn unmatched_edges(elements: &[Element]) -> Vec<(u32, u8)> {
    let mut keys: Vec<(u64, u32, u8)> = Vec::with_capacity(3 * elements.len());
    for (e, element) in elements.iter().enumerate() {
        let c = element.corners;
        for k in 0..3 {
            let (a, b) = (c[k], c[(k + 1) % 3]);
            if a != b {
                let key = (a.min(b) as u64) << 32 | a.max(b) as u64;
                keys.push((key, e as u32, k as u8));
            }
        }
    }
    keys.par_sort_unstable();
    let mut unmatched = Vec::new();
    let mut i = 0;
    while i < keys.len() {
        let mut j = i + 1;
        while j < keys.len() && keys[j].0 == keys[i].0 {
            j += 1;
        }
        if j == i + 1 {
            unmatched.push((keys[i].1, keys[i].2));
        }
        i = j;
    }
    unmatched
}

/// Calls `f` with every unit cell the segment from `a` to `b` passes through, in order
/// (Amanatides & Woo, "A fast voxel traversal algorithm for ray tracing", Eurographics
/// 1987).
fn for_cells_along(a: Vec3, b: Vec3, mut f: impl FnMut([i32; 3])) {
    let mut cell = a.floor().as_ivec3();
    let last = b.floor().as_ivec3();
    let d = b - a;
    let mut step = [0i32; 3];
    let mut next = [f32::INFINITY; 3]; // segment parameter of the next boundary per axis
    let mut delta = [f32::INFINITY; 3]; // parameter between boundaries per axis
    for i in 0..3 {
        if d[i] > 0.0 {
            step[i] = 1;
            next[i] = (cell[i] as f32 + 1.0 - a[i]) / d[i];
            delta[i] = 1.0 / d[i];
        } else if d[i] < 0.0 {
            step[i] = -1;
            next[i] = (cell[i] as f32 - a[i]) / d[i];
            delta[i] = -1.0 / d[i];
        }
    }
    let most = (last - cell).abs().element_sum() + 3;
    for _ in 0..=most {
        f(cell.to_array());
        if cell == last {
            return;
        }
        let i = if next[0] <= next[1] && next[0] <= next[2] {
            0
        } else if next[1] <= next[2] {
            1
        } else {
            2
        };
        if next[i] > 1.0 {
            return;
        }
        cell[i] += step[i];
        next[i] += delta[i];
    }
}

/// Calls `f` with every cell from `lo` to `hi` inclusive.
fn for_cells(lo: [i32; 3], hi: [i32; 3], mut f: impl FnMut([i32; 3])) {
    for x in lo[0]..=hi[0] {
        for y in lo[1]..=hi[1] {
            for z in lo[2]..=hi[2] {
                f([x, y, z]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::sampling::{hash, unit};

    /// The unit square in the plane y = 0, cut along its diagonal from (0, 0) to (1, 1):
    /// one triangle on one side, two on the other meeting the diagonal at `(t, t)`.
    fn square(t: f32) -> (Vec<Vec3>, Vec<Element>) {
        let positions = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(t, 0.0, t),
        ];
        let elements = [[0, 2, 1], [0, 3, 4], [4, 3, 2]]
            .map(|c| Element::over(&positions, c))
            .to_vec();
        (positions, elements)
    }

    /// A corner at 0.3 of its neighbour's edge hangs there (the parameter from the edge's
    /// first end); the same corner 100 tolerances off the edge, or of another surface,
    /// does not; nor does any vertex where all edges are shared.
    #[test]
    fn a_corner_inside_an_edge_hangs_at_its_parameter() {
        let tol = 1e-5;
        let (positions, elements) = square(0.3);
        let found = find(&elements, &positions, tol, |_, _| true);
        assert_eq!(found.len(), 1, "{found:?}");
        let h = found[0];
        assert_eq!(h.vertex, 4);
        let t = if h.edge == [2, 0] { 1.0 - h.t } else { h.t };
        assert!(h.edge == [0, 2] || h.edge == [2, 0], "{h:?}");
        assert!((t - 0.3).abs() < 1e-6, "{h:?}");
        assert!(!h.is_midpoint());
        assert!(find(&elements, &positions, tol, |_, _| false).is_empty());
        let (mut positions, elements) = square(0.3);
        positions[4] += Vec3::new(1.0, 0.0, -1.0) * (100.0 * tol / 2f32.sqrt());
        assert!(find(&elements, &positions, tol, |_, _| true).is_empty());
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Z, Vec3::X + Vec3::Z];
        let elements = vec![
            Element::over(&positions, [0, 2, 1]),
            Element::over(&positions, [1, 2, 3]),
        ];
        assert!(find(&elements, &positions, tol, |_, _| true).is_empty());
    }

    /// The walk visits every cell that 2,000 points spread along a segment fall in
    /// (brute force; points within 10⁻⁴ of a cell's side, which f32 rounding may put in
    /// either cell, left out), over segments of all directions and lengths up to 20 cells.
    #[test]
    fn the_walk_visits_every_cell_a_segment_crosses() {
        for k in 0..500u64 {
            let h = hash(k);
            let r = |i: u64| (unit(hash(h ^ i)) - 0.5) * 20.0;
            let a = Vec3::new(r(1), r(2), r(3));
            let b = if k % 5 == 0 {
                Vec3::new(a.x, r(4), a.z) // parallel to an axis
            } else {
                Vec3::new(r(4), r(5), r(6))
            };
            let mut visited = std::collections::HashSet::new();
            for_cells_along(a, b, |c| {
                visited.insert(c);
            });
            for i in 0..=2000 {
                let p = a + (b - a) * (i as f32 / 2000.0);
                let fraction = p - p.floor();
                if fraction.min_element() < 1e-4 || fraction.max_element() > 1.0 - 1e-4 {
                    continue; // on a cell's side, where rounding may take either cell
                }
                let c = p.floor().as_ivec3().to_array();
                assert!(visited.contains(&c), "segment {a} → {b}: cell {c:?} of {p}");
            }
        }
    }
}
