//! The mesh's index invariants, checked by [`Mesh::validate`] after building and after
//! every refinement in debug builds: the ranges and indices that tie patches, elements,
//! quadtree nodes, the display mesh and the scene triangles together, and finite geometry.

use super::Mesh;
use crate::geometry::triangle_cross;
use glam::Vec3;
use std::ops::Range;

fn finite(verts: &[Vec3]) -> bool {
    verts.iter().all(|v| v.is_finite())
}

/// An area: finite and not negative.
fn area_ok(a: f32) -> bool {
    a.is_finite() && a >= 0.0
}

/// A length the mesh divides by: finite and positive.
fn length_ok(x: f64) -> bool {
    x.is_finite() && x > 0.0
}

fn within(range: &Range<u32>, len: usize) -> bool {
    range.start <= range.end && range.end as usize <= len
}

impl Mesh {
    /// Checks the invariants the rest of the code indexes by, and returns the first one
    /// broken:
    ///
    /// - one transmittance and one patch range per scene triangle; as many display normals
    ///   as positions;
    /// - the patches' element ranges are non-empty and tile `elements` in order, and every
    ///   element's `patch` is the patch whose range holds it;
    /// - each patch's scene triangle exists and its `triangle_patches` range holds the
    ///   patch; every patch in a triangle's range lies on that triangle; `cuts` ranges lie
    ///   in `cut_edges`;
    /// - every quadtree node is a leaf holding an element or has four children (never
    ///   both), children come after their parent, each node belongs to exactly one
    ///   patch's tree, and each element is the leaf of exactly one node, in its patch's
    ///   tree, with the node's vertices;
    /// - element corners, T-vertices and the hard-shadow sides index the display mesh
    ///   (and the elements) in range;
    /// - all positions and normals are finite; areas are finite and not negative; the
    ///   element size and scale are finite and positive.
    pub fn validate(&self) -> Result<(), String> {
        let (np, ne, nv, nt) = (
            self.patches.len(),
            self.elements.len(),
            self.display.positions.len(),
            self.triangles.len(),
        );
        if !self.origin.is_finite() || !length_ok(self.scale as f64) {
            return Err(format!(
                "origin {} or scale {} not finite",
                self.origin, self.scale
            ));
        }
        if !length_ok(self.element_size) {
            return Err(format!("element size {}", self.element_size));
        }
        if self.transmittance.len() != nt || self.triangle_patches.len() != nt {
            return Err(format!(
                "{nt} triangles, {} transmittances, {} patch ranges",
                self.transmittance.len(),
                self.triangle_patches.len()
            ));
        }
        if self.display.normals.len() != nv {
            return Err(format!(
                "{nv} display positions, {} normals",
                self.display.normals.len()
            ));
        }
        self.validate_patches()?;
        self.validate_elements()?;
        self.validate_nodes()?;
        for (t, range) in self.triangle_patches.iter().enumerate() {
            if !within(range, np) {
                return Err(format!("triangle {t}: patches {range:?} of {np}"));
            }
            if let Some(p) = range
                .clone()
                .find(|&p| self.patches[p as usize].scene_triangle != t as u32)
            {
                return Err(format!("triangle {t}: patch {p} lies on another triangle"));
            }
        }
        if !finite(&self.display.positions) || !finite(&self.display.normals) {
            return Err("display position or normal not finite".into());
        }
        if let Some(h) = self.display.hanging.iter().find(|h| {
            h.vertex as usize >= nv
                || h.edge.iter().any(|&v| v as usize >= nv)
                || !(h.t > 0.0 && h.t < 1.0)
        }) {
            return Err(format!("T-vertex {h:?} of {nv} display vertices"));
        }
        if let Some(sides) = &self.display.shadow_sides
            && (sides.vertex.len() != nv || sides.element.len() != ne)
        {
            return Err(format!(
                "shadow sides for {} vertices and {} elements, of {nv} and {ne}",
                sides.vertex.len(),
                sides.element.len()
            ));
        }
        if !self.cut_edges.iter().all(|c| finite(c)) {
            return Err("contact segment not finite".into());
        }
        Ok(())
    }

    fn validate_patches(&self) -> Result<(), String> {
        let (ne, nn, nt) = (self.elements.len(), self.nodes.len(), self.triangles.len());
        let mut next = 0u32;
        for (i, p) in self.patches.iter().enumerate() {
            if p.elements.start != next || p.elements.is_empty() || !within(&p.elements, ne) {
                return Err(format!(
                    "patch {i}: elements {:?}, expected a non-empty range from {next} within {ne}",
                    p.elements
                ));
            }
            next = p.elements.end;
            if p.root as usize >= nn {
                return Err(format!("patch {i}: root {} of {nn} nodes", p.root));
            }
            if p.scene_triangle as usize >= nt
                || !self.triangle_patches[p.scene_triangle as usize].contains(&(i as u32))
            {
                return Err(format!(
                    "patch {i}: scene triangle {} (of {nt}) does not list it",
                    p.scene_triangle
                ));
            }
            if !within(&p.cuts, self.cut_edges.len()) {
                return Err(format!(
                    "patch {i}: cuts {:?} of {}",
                    p.cuts,
                    self.cut_edges.len()
                ));
            }
            if !finite(&p.verts) || !p.normal.is_finite() || !area_ok(p.area) {
                return Err(format!(
                    "patch {i}: vertices, normal or area {} not finite",
                    p.area
                ));
            }
            // A patch is a piece of its scene triangle, in its plane: it faces the way the
            // triangle does (its back side the other way), however thin the piece.
            let whole =
                triangle_cross(&self.triangles[p.scene_triangle as usize]).normalize_or_zero();
            let side = if p.back { -whole } else { whole };
            if whole != Vec3::ZERO && p.normal.dot(side) < 1.0 - 1e-5 {
                return Err(format!(
                    "patch {i}: normal {} where its scene triangle {} faces {side}",
                    p.normal, p.scene_triangle
                ));
            }
        }
        if next as usize != ne {
            return Err(format!("patches hold elements up to {next} of {ne}"));
        }
        Ok(())
    }

    fn validate_elements(&self) -> Result<(), String> {
        let nv = self.display.positions.len();
        for (i, p) in self.patches.iter().enumerate() {
            for k in p.elements.clone() {
                let e = &self.elements[k as usize];
                if e.patch != i as u32 {
                    return Err(format!(
                        "element {k}: patch {} but in patch {i}'s range",
                        e.patch
                    ));
                }
                if let Some(c) = e.corners.iter().find(|&&c| c as usize >= nv) {
                    return Err(format!("element {k}: corner {c} of {nv} display vertices"));
                }
                if !finite(&e.verts) || !e.normal.is_finite() || !area_ok(e.area) {
                    return Err(format!(
                        "element {k}: vertices, normal or area {} not finite",
                        e.area
                    ));
                }
                if e.normal != p.normal {
                    return Err(format!(
                        "element {k}: normal {} in patch {i} of normal {}",
                        e.normal, p.normal
                    ));
                }
            }
        }
        Ok(())
    }

    fn validate_nodes(&self) -> Result<(), String> {
        let (ne, nn) = (self.elements.len(), self.nodes.len());
        for (i, node) in self.nodes.iter().enumerate() {
            match (node.children, node.element) {
                (Some(kids), None) => {
                    if let Some(c) = kids.iter().find(|&&c| c as usize >= nn || c as usize <= i) {
                        return Err(format!("node {i}: child {c} not after it within {nn}"));
                    }
                }
                (None, Some(e)) => {
                    if e as usize >= ne {
                        return Err(format!("node {i}: element {e} of {ne}"));
                    }
                }
                _ => return Err(format!("node {i}: not exactly one of children and element")),
            }
            if !finite(&node.verts) {
                return Err(format!("node {i}: vertices not finite"));
            }
        }
        // Each tree: its nodes are nobody else's, its leaves hold its patch's elements.
        let mut owner = vec![u32::MAX; nn];
        let mut leaf = vec![u32::MAX; ne];
        for (p, patch) in self.patches.iter().enumerate() {
            let mut stack = vec![patch.root];
            while let Some(n) = stack.pop() {
                if owner[n as usize] != u32::MAX {
                    return Err(format!(
                        "node {n}: in the trees of patches {} and {p}",
                        owner[n as usize]
                    ));
                }
                owner[n as usize] = p as u32;
                let node = &self.nodes[n as usize];
                if let Some(kids) = node.children {
                    stack.extend(kids);
                } else if let Some(e) = node.element {
                    if !patch.elements.contains(&e) || leaf[e as usize] != u32::MAX {
                        return Err(format!(
                            "node {n}: element {e} outside patch {p}'s {:?} or held twice",
                            patch.elements
                        ));
                    }
                    leaf[e as usize] = n;
                    if self.elements[e as usize].verts != node.verts {
                        return Err(format!("node {n}: vertices differ from element {e}'s"));
                    }
                }
            }
        }
        if let Some(n) = owner.iter().position(|&o| o == u32::MAX) {
            return Err(format!("node {n}: in no patch's tree"));
        }
        if let Some(e) = leaf.iter().position(|&l| l == u32::MAX) {
            return Err(format!("element {e}: no quadtree leaf holds it"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use crate::mesh::{Mesh, MeshSettings};
    use crate::scene::builtin;

    fn cornell() -> Mesh {
        let scene = builtin::by_name("cornell").expect("built-in Cornell box");
        Mesh::build(&scene, &MeshSettings::default())
    }

    #[test]
    fn built_and_refined_meshes_are_valid() {
        let mut mesh = cornell();
        assert_eq!(mesh.validate(), Ok(()));
        let mut marked: Vec<bool> = (0..mesh.elements.len()).map(|i| i % 5 == 0).collect();
        mesh.balance(&mut marked);
        mesh.refine(&marked);
        assert_eq!(mesh.validate(), Ok(()));
        // Twice: the second pass splits leaves of trees the first one grew.
        let marked: Vec<bool> = (0..mesh.elements.len()).map(|i| i % 7 == 0).collect();
        mesh.refine(&marked);
        assert_eq!(mesh.validate(), Ok(()));
    }

    #[test]
    fn corrupted_meshes_are_invalid() {
        let mesh = cornell();
        type Corruption = Box<dyn Fn(&mut Mesh)>;
        let corruptions: Vec<(&str, Corruption)> = vec![
            (
                "element's patch out of range",
                Box::new(|m| m.elements[0].patch = m.patches.len() as u32),
            ),
            (
                "element's patch another one",
                Box::new(|m| m.elements[0].patch = 1),
            ),
            (
                "patch range past the end",
                Box::new(|m| {
                    let n = m.elements.len() as u32;
                    m.patches.last_mut().unwrap().elements.end = n + 1;
                }),
            ),
            (
                "node child out of range",
                Box::new(|m| {
                    let n = m.nodes.len() as u32;
                    let k = m.nodes.iter().position(|x| x.children.is_some()).unwrap();
                    m.nodes[k].children.as_mut().unwrap()[2] = n;
                }),
            ),
            (
                "leaf's element out of range",
                Box::new(|m| {
                    let n = m.elements.len() as u32;
                    let k = m.nodes.iter().position(|x| x.element.is_some()).unwrap();
                    m.nodes[k].element = Some(n);
                }),
            ),
            (
                "corner out of range",
                Box::new(|m| {
                    m.elements[3].corners[1] = m.display.positions.len() as u32;
                }),
            ),
            (
                "triangle range too long",
                Box::new(|m| {
                    let r = m
                        .triangle_patches
                        .iter_mut()
                        .find(|r| r.start < r.end)
                        .unwrap();
                    r.end += 1;
                }),
            ),
            (
                "position not finite",
                Box::new(|m| m.display.positions[0].x = f32::NAN),
            ),
            ("negative area", Box::new(|m| m.elements[0].area = -1.0)),
        ];
        for (what, corrupt) in corruptions {
            let mut bad = mesh.clone();
            corrupt(&mut bad);
            assert!(bad.validate().is_err(), "{what}: not caught");
        }
    }
}
