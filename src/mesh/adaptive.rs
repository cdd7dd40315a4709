//! A-posteriori adaptive subdivision (the substructuring refinement of Cohen, Greenberg,
//! Immel & Brock 1986, §4): after a solve, elements whose radiosity differs from their
//! neighbours' by more than a perceptual contrast are split into four, down to a minimum
//! size, keeping vertex-sharing elements within one level of each other (2:1 balance).
//!
//! Two criteria, both in log luminance (so a 20 % step reads the same in a dark corner as
//! beside the light): the contrast between an element and a vertex-sharing neighbour
//! (`threshold`), and how far the element's value lies from the Gouraud reconstruction at
//! its centroid (`threshold / 20`: the curvature that linear interpolation misses, which
//! a contrast test cannot see in a smooth ramp and which concentrates at the kinks of
//! penumbrae and umbrae); values below a small fraction of the mean (`floor`) are treated as
//! that floor, so noise in near-black regions does not drive refinement.
//!
//! [`Mesh::refine`] rewrites the element array (each patch's leaves stay contiguous) and
//! returns where every old element went, so a solver can carry its per-element state over.

use super::{Element, Mesh, luminance};
use crate::geometry::{subdivide, triangle_cross};
use glam::Vec3;

/// Refinement parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct AdaptiveSettings {
    /// Split where the log-luminance contrast between an element and a neighbour exceeds
    /// this (natural log: 0.2 ≈ a 22 % step).
    pub threshold: f32,
    /// No element gets smaller than this (metres, as `sqrt(2·area)`); `None`: an eighth of
    /// the starting element size.
    pub min_size: Option<f64>,
    /// Most refinement passes per solve.
    pub max_passes: u32,
    /// Most elements the refinement may create in all (a memory and time bound).
    pub max_elements: usize,
}

impl Default for AdaptiveSettings {
    fn default() -> Self {
        AdaptiveSettings {
            threshold: 0.2,
            min_size: None,
            max_passes: 4,
            max_elements: 200_000,
        }
    }
}

/// Where an old element went in [`Mesh::refine`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Moved {
    /// Kept whole, at this new index.
    Kept(u32),
    /// Split into these four new elements.
    Split([u32; 4]),
}

/// Element size as the leg of a right isosceles triangle of the same area.
pub fn size(e: &Element) -> f64 {
    (2.0 * e.area as f64).sqrt()
}

impl Mesh {
    /// Elements to split for `values` (per-element radiosity): log-luminance contrast to a
    /// vertex-sharing neighbour above `threshold`, or a Gouraud reconstruction error at the
    /// centroid above `threshold / 20`; size above `min_size` (splitting halves it). Not yet balanced: add other criteria, then call [`Mesh::balance`].
    pub fn mark_for_refinement(&self, values: &[Vec3], threshold: f32, min_size: f64) -> Vec<bool> {
        let n = self.elements.len();
        let nv = self.display.positions.len();
        // Floor: 1 % of the area-weighted mean luminance of the lit (non-emitting) surfaces.
        let (mut sum, mut area) = (0.0f64, 0.0f64);
        for (e, v) in self.elements.iter().zip(values) {
            let l = luminance(*v);
            if l.is_finite() && self.patches[e.patch as usize].emission.max_element() <= 0.0 {
                sum += l.max(0.0) as f64 * e.area as f64;
                area += e.area as f64;
            }
        }
        let floor = ((sum / area.max(1e-30)) * 0.01).max(1e-30) as f32;
        let log = |v: Vec3| {
            let l = luminance(v);
            if l.is_finite() {
                l.max(floor).ln()
            } else {
                floor.ln()
            }
        };
        // Per display vertex, the range of log luminance of the elements using it.
        let mut lo = vec![f32::INFINITY; nv];
        let mut hi = vec![f32::NEG_INFINITY; nv];
        for (e, v) in self.elements.iter().zip(values) {
            let l = log(*v);
            for &c in &e.corners {
                lo[c as usize] = lo[c as usize].min(l);
                hi[c as usize] = hi[c as usize].max(l);
            }
        }
        // Reconstruction error: the element's own value against the Gouraud reconstruction
        // at its centroid (the mean of its vertex values, each a least-squares plane fit
        // of the elements around it). Zero for linear light whatever the step between
        // neighbours; large where the light bends within a few elements (the edges of
        // penumbrae and umbrae, hot spots), which is where linear reconstruction errs.
        // Its tolerance is a twentieth of the contrast threshold (1 % at the default 0.2):
        // the error it measures is what the viewer shows, while a contrast step is only a
        // sign of it.
        let vertex = self.display.vertex_values(&self.elements, values);
        let tolerance = threshold / 20.0;
        let mut marked = vec![false; n];
        for (i, (e, v)) in self.elements.iter().zip(values).enumerate() {
            if size(e) * 0.5 < min_size * 0.999 {
                continue;
            }
            let l = log(*v);
            let step = e.corners.iter().any(|&c| {
                let c = c as usize;
                (hi[c] - l).max(l - lo[c]) > threshold
            });
            let mean = e.corners.iter().map(|&c| vertex[c as usize]).sum::<Vec3>() / 3.0;
            let curved = (log(mean) - l).abs() > tolerance;
            marked[i] = step || curved;
        }
        marked
    }

    /// Closes `marked` under 2:1 balance, so that every hanging vertex subdivision makes
    /// lies at the midpoint of a coarser edge (a T-vertex the display takes from that
    /// edge, without a crack, and the coarse side's next split uses):
    ///
    /// - an element split beside a coarser edge it hangs from (one of its corners is that
    ///   edge's hanging midpoint and another that edge's end) would put a vertex at a
    ///   quarter of it: the coarse element splits too. This is the rule between elements
    ///   of different shapes: neighbouring input triangles, and the pieces of one triangle
    ///   cut along contact lines (a long thin triangle's elements meet a wide one's along
    ///   a few of their edges at many sizes). A sliver split so may go below the minimum
    ///   size measured by area (√(2A)), not along its long edge, which halves to the
    ///   length of its neighbour's edge beside it;
    /// - no two elements sharing a display vertex may differ in size by more than a factor
    ///   of 2 (up to rounding): the grading inside a patch's quadtree;
    /// - along a coarse edge with T-vertices off its midpoint (an input's T-junctions, see
    ///   `hanging`), whose vertices refinement cannot meet, an element split beside it
    ///   along the edge may not leave the edge more than twice as long as its own edge
    ///   there: the coarse element splits too. Otherwise the display, continuous across
    ///   the edge, takes the coarse edge's linear interpolation on the fine side as well,
    ///   a band along the edge as wrong as the coarse side.
    pub fn balance(&self, marked: &mut [bool]) {
        let nv = self.display.positions.len();
        let after =
            |i: usize, marked: &[bool]| size(&self.elements[i]) * if marked[i] { 0.5 } else { 1.0 };
        // Vertex → elements.
        let mut users: Vec<Vec<u32>> = vec![Vec::new(); nv];
        for (i, e) in self.elements.iter().enumerate() {
            for &c in &e.corners {
                users[c as usize].push(i as u32);
            }
        }
        // Hanging midpoint → the coarse edge it lies on; the same for the other T-vertices.
        let mut hangs_on: Vec<Option<(u32, u32)>> = vec![None; nv];
        let mut hangs_off: Vec<Option<(u32, u32)>> = vec![None; nv];
        for h in &self.display.hanging {
            let edge = (h.edge[0].min(h.edge[1]), h.edge[0].max(h.edge[1]));
            match h.is_midpoint() {
                true => hangs_on[h.vertex as usize] = Some(edge),
                false => hangs_off[h.vertex as usize] = Some(edge),
            }
        }
        let position = |v: u32| self.display.positions[v as usize];
        let length = |a: u32, b: u32| (position(a) - position(b)).length();
        let mut queue: Vec<u32> = (0..self.elements.len() as u32)
            .filter(|&i| marked[i as usize])
            .collect();
        let mark = |j: u32, marked: &mut [bool], queue: &mut Vec<u32>| {
            if !marked[j as usize] {
                marked[j as usize] = true;
                queue.push(j);
            }
        };
        while let Some(i) = queue.pop() {
            let corners = self.elements[i as usize].corners;
            let s = after(i as usize, marked);
            for &c in &corners {
                for &j in &users[c as usize] {
                    if after(j as usize, marked) > 2.0 * s * 1.01 {
                        mark(j, marked, &mut queue);
                    }
                }
                if let Some((a, b)) = hangs_on[c as usize]
                    && (corners.contains(&a) || corners.contains(&b))
                {
                    for &j in &users[a as usize] {
                        if users[b as usize].contains(&j) {
                            mark(j, marked, &mut queue);
                        }
                    }
                }
                if let Some((a, b)) = hangs_off[c as usize] {
                    // This element's shortest edge along the coarse edge from c, halved.
                    let on_line =
                        |w: u32| w == a || w == b || hangs_off[w as usize] == Some((a, b));
                    let fine = corners
                        .iter()
                        .filter(|&&w| w != c && on_line(w))
                        .map(|&w| 0.5 * length(c, w))
                        .fold(f32::INFINITY, f32::min);
                    for &j in &users[a as usize] {
                        let coarse = length(a, b) * if marked[j as usize] { 0.5 } else { 1.0 };
                        if users[b as usize].contains(&j) && coarse > 2.0 * fine * 1.01 {
                            mark(j, marked, &mut queue);
                        }
                    }
                }
            }
        }
    }

    /// Splits the `marked` elements into four (midpoint subdivision in their quadtrees),
    /// rebuilds the element array with each patch's leaves contiguous and the display mesh,
    /// and returns where each old element went.
    pub fn refine(&mut self, marked: &[bool]) -> Vec<Moved> {
        let old = std::mem::take(&mut self.elements);
        let mut moved = vec![Moved::Kept(0); old.len()];
        let mut elements: Vec<Element> = Vec::with_capacity(old.len() + 3 * marked.len());
        for p in 0..self.patches.len() {
            let first = elements.len() as u32;
            // Leaves of the patch's quadtree in depth-first order.
            let mut stack = vec![self.patches[p].root];
            let mut leaves = Vec::new();
            while let Some(node) = stack.pop() {
                match self.nodes[node as usize].children {
                    Some(kids) => stack.extend(kids.iter().rev()),
                    None => leaves.push(node),
                }
            }
            for node in leaves {
                let Some(e) = self.nodes[node as usize].element else {
                    continue;
                };
                let e = e as usize;
                if marked.get(e).copied().unwrap_or(false) {
                    let parent = &old[e];
                    let verts = self.nodes[node as usize].verts;
                    let mut kids = [0u32; 4];
                    let mut new = [0u32; 4];
                    for (k, v) in subdivide(&verts).into_iter().enumerate() {
                        let index = elements.len() as u32;
                        let nid = self.nodes.len() as u32;
                        self.nodes.push(super::QuadNode {
                            verts: v,
                            children: None,
                            element: Some(index),
                        });
                        let nrm = triangle_cross(&v);
                        elements.push(Element {
                            verts: v,
                            normal: parent.normal,
                            area: 0.5 * nrm.length(),
                            patch: parent.patch,
                            level: parent.level + 1,
                            corners: [0; 3],
                        });
                        kids[k] = nid;
                        new[k] = index;
                    }
                    let n = &mut self.nodes[node as usize];
                    n.children = Some(kids);
                    n.element = None;
                    moved[e] = Moved::Split(new);
                } else {
                    let index = elements.len() as u32;
                    self.nodes[node as usize].element = Some(index);
                    elements.push(old[e].clone());
                    moved[e] = Moved::Kept(index);
                }
            }
            self.patches[p].elements = first..elements.len() as u32;
        }
        self.elements = elements;
        self.display = super::DisplayMesh::build(
            &mut self.elements,
            &self.patches,
            &self.cut_edges,
            self.scale,
        );
        debug_assert_eq!(self.validate(), Ok(()), "invalid mesh after refinement");
        moved
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::MeshSettings;
    use crate::scene::builtin;

    fn cornell() -> Mesh {
        Mesh::build(
            &builtin::cornell_box(),
            &MeshSettings {
                max_elements: Some(400),
                ..Default::default()
            },
        )
    }

    #[test]
    fn refining_conserves_area_and_keeps_patches_contiguous() {
        let mut mesh = cornell();
        let before: Vec<f64> = mesh.patches.iter().map(|p| p.area as f64).collect();
        let total: f64 = mesh.elements.iter().map(|e| e.area as f64).sum();
        let marked: Vec<bool> = (0..mesh.elements.len()).map(|i| i % 3 == 0).collect();
        let n_marked = marked.iter().filter(|m| **m).count();
        let n = mesh.elements.len();
        let moved = mesh.refine(&marked);
        assert_eq!(mesh.elements.len(), n + 3 * n_marked);
        for (p, area) in mesh.patches.iter().zip(before) {
            let sum: f64 = mesh.elements[p.elements.start as usize..p.elements.end as usize]
                .iter()
                .map(|e| e.area as f64)
                .sum();
            // f32 areas: relative 1e-5.
            assert!((sum - area).abs() <= 1e-5 * area, "{sum} vs {area}");
        }
        let after: f64 = mesh.elements.iter().map(|e| e.area as f64).sum();
        assert!((after - total).abs() <= 1e-5 * total);
        // Every split element's children lie in its patch's range.
        for m in moved {
            if let Moved::Split(kids) = m {
                let p = mesh.elements[kids[0] as usize].patch as usize;
                for k in kids {
                    assert!(mesh.patches[p].elements.contains(&k));
                }
            }
        }
    }

    #[test]
    fn balance_keeps_neighbours_of_new_elements_within_one_level() {
        let mut mesh = cornell();
        // Split the element nearest the centre of the box's floor corner three times in a
        // row; balance must spread the refinement around it.
        let mut newest: Vec<u32> = Vec::new();
        for _ in 0..3 {
            let target = mesh
                .elements
                .iter()
                .enumerate()
                .min_by(|a, b| {
                    let ca = (a.1.centroid() - Vec3::splat(-0.2)).length();
                    let cb = (b.1.centroid() - Vec3::splat(-0.2)).length();
                    ca.total_cmp(&cb)
                })
                .map(|(i, _)| i)
                .unwrap();
            let mut marked = vec![false; mesh.elements.len()];
            marked[target] = true;
            mesh.balance(&mut marked);
            let moved = mesh.refine(&marked);
            newest = moved
                .iter()
                .flat_map(|m| match m {
                    Moved::Split(k) => k.to_vec(),
                    Moved::Kept(_) => Vec::new(),
                })
                .collect();
            assert!(newest.len() >= 4);
        }
        // Every element sharing a vertex with a new element is at most twice its size
        // (1 % slack: patches next to each other differ slightly in size).
        let nv = mesh.display.positions.len();
        let mut users: Vec<Vec<usize>> = vec![Vec::new(); nv];
        for (i, e) in mesh.elements.iter().enumerate() {
            for &c in &e.corners {
                users[c as usize].push(i);
            }
        }
        for &k in &newest {
            let e = &mesh.elements[k as usize];
            for &c in &e.corners {
                for &j in &users[c as usize] {
                    let ratio = size(&mesh.elements[j]) / size(e);
                    assert!(
                        ratio <= 2.0 * 1.01 + 1e-9,
                        "neighbour {ratio}× the new element"
                    );
                }
            }
        }
    }
}
