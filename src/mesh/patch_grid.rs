//! Which patches of a scene triangle may hold a point: a grid over the triangle's
//! barycentric coordinates, for the triangles cut into many patches.
//!
//! [`Mesh::element_at`](super::Mesh::element_at) finds the patch that holds a ray's hit
//! among the hit triangle's patches, and a wall's triangle is cut into hundreds of them:
//! going through them one by one took about as long as tracing the ray (Sponza's leaves'
//! rays, `perf record`). Each such triangle gets a G × G grid over its barycentric
//! coordinates (u, v) of its first two edges, G ≈ √(patches); a cell lists, in index
//! order, the patches whose (u, v) bounding box, widened by the distance the lookup
//! accepts, meets it. Every patch within that distance of a point is then in the point's
//! cell, in the same order as in the triangle's range, so the lookup's answer is the full
//! scan's.

use crate::geometry::shortest_altitude;
use glam::Vec3;
use std::ops::Range;

/// Triangles with at most this many patches are scanned whole.
const MIN_PATCHES: usize = 16;

/// The grid's side is at most this many cells.
const MAX_SIDE: usize = 64;

/// One triangle's grid: where its cells start in `PatchGrid::cells` and its side.
#[derive(Clone, Copy, Debug)]
struct Grid {
    first: u32,
    side: u32,
    /// The widening of the patches' boxes, in barycentric units.
    margin: f64,
}

/// The grids of the triangles with more than [`MIN_PATCHES`] patches.
#[derive(Clone, Debug, Default)]
pub struct PatchGrid {
    /// Per scene triangle, its grid's index in `grids`, or `u32::MAX` for none.
    index: Vec<u32>,
    grids: Vec<Grid>,
    /// Per cell, its range in `patches`.
    cells: Vec<Range<u32>>,
    /// Patch indices, cell after cell, each cell's in increasing order.
    patches: Vec<u32>,
}

/// Barycentric (u, v) of `x` projected on the plane of triangle `t`, along its edges
/// t[1] − t[0] and t[2] − t[0]; `None` for a degenerate triangle. In f64, unlike
/// `texture::barycentric`: the boxes are widened by a fraction of a ray offset over the
/// triangle's altitude, and f32's rounding of a sliver's coordinates could exceed that.
fn barycentric(t: &[Vec3; 3], x: Vec3) -> Option<(f64, f64)> {
    let [a, b, c] = t.map(|p| p.as_dvec3());
    let (e1, e2, d) = (b - a, c - a, x.as_dvec3() - a);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let det = d11 * d22 - d12 * d12;
    if !(det > 0.0 && det.is_finite()) {
        return None;
    }
    let (d1, d2) = (d.dot(e1), d.dot(e2));
    Some(((d22 * d1 - d12 * d2) / det, (d11 * d2 - d12 * d1) / det))
}

/// The cell along one coordinate of a grid `side` cells wide that holds coordinate `x`
/// (the first or last for what lies beyond).
fn cell_of(x: f64, side: usize) -> usize {
    (x * side as f64).floor().clamp(0.0, side as f64 - 1.0) as usize
}

impl PatchGrid {
    /// The grids of `triangles` whose `ranges` of `patch_verts` hold more than
    /// [`MIN_PATCHES`] patches, for lookups that accept a patch within `reach` of the
    /// point (mesh frame).
    pub fn build(
        triangles: &[[Vec3; 3]],
        ranges: &[Range<u32>],
        patch_verts: impl Fn(u32) -> [Vec3; 3],
        reach: f32,
    ) -> PatchGrid {
        let mut grid = PatchGrid {
            index: vec![u32::MAX; triangles.len()],
            ..Default::default()
        };
        for (t, range) in ranges.iter().enumerate() {
            let count = range.len();
            if count <= MIN_PATCHES {
                continue;
            }
            let tri = &triangles[t];
            let altitude = shortest_altitude(tri) as f64;
            if !(altitude > 0.0 && altitude.is_finite()) {
                continue;
            }
            // Twice the reach, for the rounding of the coordinates.
            let margin = 2.0 * reach as f64 / altitude;
            let side = ((count as f64).sqrt().ceil() as usize).clamp(1, MAX_SIDE);
            let mut lists: Vec<Vec<u32>> = vec![Vec::new(); side * side];
            let cell = |x: f64| cell_of(x, side);
            for p in range.clone() {
                let (mut lo, mut hi) = (
                    (f64::INFINITY, f64::INFINITY),
                    (f64::NEG_INFINITY, f64::NEG_INFINITY),
                );
                for v in patch_verts(p) {
                    let Some((u, v)) = barycentric(tri, v) else {
                        continue;
                    };
                    lo = (lo.0.min(u), lo.1.min(v));
                    hi = (hi.0.max(u), hi.1.max(v));
                }
                if !(lo.0 <= hi.0 && lo.1 <= hi.1) {
                    continue;
                }
                for i in cell(lo.0 - margin)..=cell(hi.0 + margin) {
                    for j in cell(lo.1 - margin)..=cell(hi.1 + margin) {
                        lists[i * side + j].push(p);
                    }
                }
            }
            grid.index[t] = grid.grids.len() as u32;
            grid.grids.push(Grid {
                first: grid.cells.len() as u32,
                side: side as u32,
                margin,
            });
            for list in lists {
                let start = grid.patches.len() as u32;
                grid.patches.extend(list);
                grid.cells.push(start..grid.patches.len() as u32);
            }
        }
        grid
    }

    /// The patches of triangle `t` (`tri`) that may lie within the reach of `x`, in
    /// increasing order; `None` where the triangle has no grid or `x` lies off it by more
    /// than the widening (the caller then scans the triangle's patches).
    pub fn near(&self, t: u32, tri: &[Vec3; 3], x: Vec3) -> Option<&[u32]> {
        let grid = *self.grids.get(*self.index.get(t as usize)? as usize)?;
        let (u, v) = barycentric(tri, x)?;
        let inside = |c: f64| (-grid.margin..=1.0 + grid.margin).contains(&c);
        if !(inside(u) && inside(v)) {
            return None;
        }
        let side = grid.side as usize;
        let range =
            self.cells[grid.first as usize + cell_of(u, side) * side + cell_of(v, side)].clone();
        Some(&self.patches[range.start as usize..range.end as usize])
    }

    /// Whether triangle `t` has a grid.
    #[cfg(test)]
    pub fn covers(&self, t: usize) -> bool {
        self.index.get(t).is_some_and(|&i| i != u32::MAX)
    }
}
