//! The element triangles to draw or export, conforming at T-vertices: an element with
//! vertices of its neighbours inside its edges (a finer neighbour's midpoint, or an input
//! triangle's corner anywhere along the edge) is cut into triangles through them, so that
//! a rasteriser sees no T-junction (which leaves pixel cracks showing the background).
//! Values are unchanged: a T-vertex carries the coarse edge's value at its parameter
//! (`DisplayMesh::hanging`), and every corner carries its barycentric coordinates within
//! the element (for the wireframe and Hermite shading).

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

/// The hanging vertices by the coarse edge they lie on: (parameter from the edge's lower
/// vertex id, vertex), in order along the edge.
pub struct TVertices(HashMap<(u32, u32), Vec<(f32, u32)>>);

impl Mesh {
    /// The hanging vertices of the display mesh, for [`Mesh::conforming_triangles`].
    pub fn t_vertices(&self) -> TVertices {
        let mut map: HashMap<(u32, u32), Vec<(f32, u32)>> = HashMap::new();
        for h in &self.display.hanging {
            let [a, b] = h.edge;
            let t = if a < b { h.t } else { 1.0 - h.t };
            map.entry((a.min(b), a.max(b)))
                .or_default()
                .push((t, h.vertex));
        }
        for list in map.values_mut() {
            list.sort_by(|x, y| x.0.total_cmp(&y.0));
        }
        TVertices(map)
    }

    /// Calls `out` with each conforming triangle of element `e` (same winding as the
    /// element), none for an element of a covered patch (hidden under a face pressed
    /// against it: drawing it would only z-fight).
    pub fn conforming_triangles(
        &self,
        e: u32,
        t_vertices: &TVertices,
        out: impl FnMut([Corner; 3]),
    ) {
        let element = &self.elements[e as usize];
        if self.patches[element.patch as usize].covered {
            return;
        }
        let c = element.corners;
        // The element's boundary: each corner, then the T-vertices inside the edge from
        // it to the next, each with the lines it lies on (bit k: the line of edge k).
        let mut polygon: Vec<(Corner, u8)> = Vec::with_capacity(3);
        for k in 0..3 {
            let k1 = (k + 1) % 3;
            let mut bary = [0.0f32; 3];
            bary[k] = 1.0;
            let lines = 1 << k | 1 << ((k + 2) % 3);
            polygon.push((
                Corner {
                    vertex: c[k],
                    position: element.verts[k],
                    bary,
                },
                lines,
            ));
            let Some(list) = t_vertices.0.get(&(c[k].min(c[k1]), c[k].max(c[k1]))) else {
                continue;
            };
            let mut inside = |(t, vertex): (f32, u32)| {
                let t = if c[k] < c[k1] { t } else { 1.0 - t };
                let mut bary = [0.0f32; 3];
                bary[k] = 1.0 - t;
                bary[k1] = t;
                let position = element.verts[k] * (1.0 - t) + element.verts[k1] * t;
                polygon.push((
                    Corner {
                        vertex,
                        position,
                        bary,
                    },
                    1 << k,
                ));
            };
            if c[k] < c[k1] {
                list.iter().copied().for_each(&mut inside);
            } else {
                list.iter().rev().copied().for_each(&mut inside);
            }
        }
        triangulate(polygon, out);
    }
}

/// Triangulates a convex polygon whose vertices lie on the three lines of a triangle
/// (`lines`: which of them each lies on) by clipping ears: each time the ear of the
/// shortest diagonal that is a true triangle (its three vertices not on one line) and
/// leaves a polygon that is not all on one line. Each vertex is one of the triangle's
/// corners or lies inside one of its edges, so such an ear always exists.
fn triangulate(mut polygon: Vec<(Corner, u8)>, mut out: impl FnMut([Corner; 3])) {
    while polygon.len() > 3 {
        let n = polygon.len();
        let straight = |p: &[(Corner, u8)], i: usize| {
            let m = p.len();
            p[(i + m - 1) % m].1 & p[i].1 & p[(i + 1) % m].1 != 0
        };
        let mut best: Option<(f32, usize)> = None;
        for i in 0..n {
            let (prev, next) = (&polygon[(i + n - 1) % n], &polygon[(i + 1) % n]);
            if straight(&polygon, i) {
                continue;
            }
            // What is left must keep three vertices that are not straight.
            let mut rest = polygon.clone();
            rest.remove(i);
            if (0..rest.len()).filter(|&j| !straight(&rest, j)).count() < 3 {
                continue;
            }
            let diagonal = (prev.0.position - next.0.position).length_squared();
            if best.is_none_or(|(d, _)| diagonal < d) {
                best = Some((diagonal, i));
            }
        }
        let Some((_, i)) = best else {
            break; // degenerate (cannot happen for the polygons above); draw nothing more
        };
        let (prev, next) = ((i + n - 1) % n, (i + 1) % n);
        out([polygon[prev].0, polygon[i].0, polygon[next].0]);
        polygon.remove(i);
    }
    if polygon.len() == 3 {
        out([polygon[0].0, polygon[1].0, polygon[2].0]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::sampling::{hash, unit};

    /// Triangles with up to 6 vertices inside each edge at random places (stratified): the triangulation
    /// has n − 2 triangles for n vertices, each turned as the element and none degenerate,
    /// covering the element's area exactly (a convex polygon's triangulation), and uses
    /// every vertex.
    #[test]
    fn an_element_with_t_vertices_is_cut_into_proper_triangles() {
        let verts = [
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.1),
            Vec3::new(0.3, 0.0, 1.5),
        ];
        let normal = (verts[1] - verts[0]).cross(verts[2] - verts[0]);
        let area = 0.5 * normal.length();
        for k in 0..2000u64 {
            let h = hash(k);
            let mut polygon = Vec::new();
            let mut id = 3;
            for e in 0..3 {
                let mut bary = [0.0; 3];
                bary[e] = 1.0;
                let corner = Corner {
                    vertex: e as u32,
                    position: verts[e],
                    bary,
                };
                polygon.push((corner, 1 << e | 1 << ((e + 2) % 3)));
                let count = hash(h ^ e as u64) % 7;
                // Stratified, so that no two lie closer than 0.2 / count (a sliver of a
                // triangle is still proper, but below the area bound's f32 precision).
                let ts: Vec<f32> = (0..count)
                    .map(|i| {
                        let u = unit(hash(h ^ (10 + 10 * e as u64 + i)));
                        (i as f32 + 0.1 + 0.8 * u) / count as f32
                    })
                    .collect();
                for t in ts {
                    let e1 = (e + 1) % 3;
                    let mut bary = [0.0; 3];
                    bary[e] = 1.0 - t;
                    bary[e1] = t;
                    let position = verts[e] * (1.0 - t) + verts[e1] * t;
                    polygon.push((
                        Corner {
                            vertex: id,
                            position,
                            bary,
                        },
                        1 << e,
                    ));
                    id += 1;
                }
            }
            let n = polygon.len();
            let mut triangles = Vec::new();
            triangulate(polygon, |t| triangles.push(t));
            assert_eq!(triangles.len(), n - 2, "case {k}");
            let mut used = std::collections::HashSet::new();
            let mut sum = 0.0;
            for t in &triangles {
                let [a, b, c] = t.map(|c| c.position);
                let cross = (b - a).cross(c - a);
                let signed = 0.5 * cross.dot(normal.normalize());
                assert!(
                    signed > 1e-6 * area,
                    "case {k}: a degenerate or turned triangle ({signed} of {area}: {t:?})"
                );
                sum += signed;
                used.extend(t.iter().map(|c| c.vertex));
            }
            assert!(
                (sum - area).abs() < 1e-4 * area,
                "case {k}: {sum} of {area}"
            );
            assert_eq!(used.len(), n, "case {k}");
        }
    }
}
