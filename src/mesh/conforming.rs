//! The element triangles to draw or export, conforming at T-vertices: an element with a
//! finer neighbour's vertex at the midpoint of one of its edges is cut into two to four
//! triangles through that vertex, so that a rasteriser sees no T-junction (which leaves
//! pixel cracks showing the background). Values are unchanged: a T-vertex carries the
//! coarse edge's value (`DisplayMesh::hanging`), and every corner carries its barycentric
//! coordinates within the element (for the wireframe and Hermite shading).

use super::Mesh;
use glam::Vec3;
use std::collections::HashMap;

/// A corner of a conforming triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Corner {
    /// Display-mesh vertex.
    pub vertex: u32,
    /// Position (mesh frame).
    pub position: Vec3,
    /// Barycentric coordinates within the element.
    pub bary: [f32; 3],
}

/// The hanging vertices by the coarse edge they lie on.
pub struct Midpoints(HashMap<(u32, u32), u32>);

/// An undirected edge between two display vertices.
fn edge(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

impl Mesh {
    /// The hanging vertices of the display mesh, for [`Mesh::conforming_triangles`].
    pub fn midpoints(&self) -> Midpoints {
        Midpoints(
            self.display
                .hanging
                .iter()
                .map(|&[v, a, b]| (edge(a, b), v))
                .collect(),
        )
    }

    /// Calls `out` with each conforming triangle of element `e` (same winding as the
    /// element), none for an element of a covered patch (hidden under a face pressed
    /// against it: drawing it would only z-fight).
    pub fn conforming_triangles(
        &self,
        e: u32,
        midpoints: &Midpoints,
        mut out: impl FnMut([Corner; 3]),
    ) {
        let element = &self.elements[e as usize];
        if self.patches[element.patch as usize].covered {
            return;
        }
        let c = element.corners;
        let corner = |k: usize| {
            let mut bary = [0.0f32; 3];
            bary[k] = 1.0;
            Corner {
                vertex: c[k],
                position: element.verts[k],
                bary,
            }
        };
        // The hanging vertex on edge k (corners k, k+1), if any.
        let mid: [Option<Corner>; 3] = std::array::from_fn(|k| {
            let k1 = (k + 1) % 3;
            midpoints.0.get(&edge(c[k], c[k1])).map(|&vertex| {
                let mut bary = [0.0f32; 3];
                bary[k] = 0.5;
                bary[k1] = 0.5;
                Corner {
                    vertex,
                    position: (element.verts[k] + element.verts[k1]) * 0.5,
                    bary,
                }
            })
        });
        match mid {
            [None, None, None] => out([corner(0), corner(1), corner(2)]),
            [Some(m01), Some(m12), Some(m20)] => {
                out([corner(0), m01, m20]);
                out([m01, corner(1), m12]);
                out([m20, m12, corner(2)]);
                out([m01, m12, m20]);
            }
            _ => {
                // One or two midpoints: rotate so that edge k = 0 has one, then split.
                let k = (0..3).find(|&k| mid[k].is_some()).unwrap_or(0);
                let (k1, k2) = ((k + 1) % 3, (k + 2) % 3);
                let m = mid[k].unwrap_or(corner(k));
                match (mid[k1], mid[k2]) {
                    (None, None) => {
                        out([corner(k), m, corner(k2)]);
                        out([m, corner(k1), corner(k2)]);
                    }
                    (Some(n), None) => {
                        // Midpoints on edges (k, k1) and (k1, k2).
                        out([m, corner(k1), n]);
                        out([corner(k), m, n]);
                        out([corner(k), n, corner(k2)]);
                    }
                    (None, Some(n)) => {
                        // Midpoints on edges (k, k1) and (k2, k).
                        out([corner(k), m, n]);
                        out([m, corner(k1), corner(k2)]);
                        out([n, m, corner(k2)]);
                    }
                    (Some(_), Some(_)) => unreachable!("all three are handled above"),
                }
            }
        }
    }
}
