//! Hard shadow edges in the mesh: which elements the shadow of a point, spot or
//! directional light or the sun crosses (corner visibility), and the sides of those edges
//! the display keeps apart ([`ShadowSides`]).

use super::{Mesh, ShadowSides, element_size};
use crate::accel::Bvh;
use crate::light::{ExternalLight, Punctual};
use glam::Vec3;
use rayon::prelude::*;

/// Light sources for corner-visibility tests, in the mesh frame, each with the scene
/// triangle a ray to it skips (`u32::MAX` for none).
pub struct LightTargets {
    pub sources: Vec<(Punctual, u32)>,
}

impl LightTargets {
    /// Point, spot and directional lights and the sun: the sources whose shadows are hard.
    pub fn punctual(mesh: &Mesh, external: &ExternalLight) -> LightTargets {
        let lights = external.punctual(mesh.origin);
        LightTargets {
            sources: lights.into_iter().map(|l| (l, u32::MAX)).collect(),
        }
    }

    /// Which of the sources point `p` (normal `n`, on scene triangle `own`) sees: a bit
    /// per source (the first 64).
    pub fn seen(&self, mesh: &Mesh, bvh: &Bvh, p: Vec3, n: Vec3, own: u32) -> u64 {
        let x = p + n * mesh.epsilon();
        self.sources
            .iter()
            .map(|&(l, tri)| n.dot(l.towards(p)) > 0.0 && l.visible(bvh, x, [own, tri]))
            .take(64)
            .enumerate()
            .fold(0, |m, (b, seen)| m | (u64::from(seen) << b))
    }

    /// The elements (other than those `skip` names) whose three corners disagree about
    /// seeing one of the sources: a shadow boundary crosses them. Corners are pulled 1 %
    /// towards the centroid (a corner exactly on a contact line is ambiguous) and lifted
    /// off the surface.
    pub fn changes(&self, mesh: &Mesh, bvh: &Bvh, skip: impl Fn(usize) -> bool + Sync) -> Vec<u32> {
        if self.sources.is_empty() {
            return Vec::new();
        }
        let eps = mesh.epsilon();
        (0..mesh.elements.len())
            .into_par_iter()
            .with_min_len(64)
            .filter(|&i| {
                if skip(i) {
                    return false;
                }
                let e = &mesh.elements[i];
                let own = mesh.patches[e.patch as usize].scene_triangle;
                let c = e.centroid();
                let corners = e.verts.map(|v| v + (c - v) * 0.01 + e.normal * eps);
                self.sources.iter().any(|&(l, tri)| {
                    if e.normal.dot(l.towards(c)) <= 0.0 {
                        return false;
                    }
                    let vis = corners.map(|x| l.visible(bvh, x, [own, tri]));
                    vis[0] != vis[1] || vis[1] != vis[2]
                })
            })
            .map(|i| i as u32)
            .collect()
    }
}

impl Mesh {
    /// Records the sides of hard shadow edges in `mesh.display.shadow_sides` (see
    /// [`ShadowSides`]): the elements across which the visibility of a point,
    /// spot or directional light or the sun changes, and for their corners and the elements
    /// around those, which of these sources each sees. Only where adaptive subdivision has
    /// resolved the edge, in elements it may not split further (below twice `min_size`):
    /// where the mesh is coarser than the shadows (the refinement stopped at its element
    /// budget), the element values are scattered samples of them, and choosing sides at each
    /// vertex would show that scatter as speckle, where averaging smooths it. Area lights'
    /// shadows have penumbrae and are left to the smooth reconstruction.
    pub fn mark_hard_shadows(&mut self, bvh: &Bvh, external: &ExternalLight, min_size: f64) {
        record_shadow_sides(self, bvh, external, min_size);
    }
}

fn record_shadow_sides(mesh: &mut Mesh, bvh: &Bvh, external: &ExternalLight, min_size: f64) {
    mesh.display.shadow_sides = None;
    let targets = LightTargets::punctual(mesh, external);
    let crossed = targets.changes(mesh, bvh, |i| {
        element_size(&mesh.elements[i]) * 0.5 >= min_size * 0.999
    });
    if crossed.is_empty() {
        return;
    }
    let nv = mesh.display.positions.len();
    // Corners of crossed elements, each with an element using it (for the triangle its
    // shadow rays skip).
    let mut owner = vec![u32::MAX; nv];
    for &i in &crossed {
        for &c in &mesh.elements[i as usize].corners {
            owner[c as usize] = i;
        }
    }
    let elements = &mesh.elements;
    let own = |i: u32| mesh.patches[elements[i as usize].patch as usize].scene_triangle;
    let element: Vec<u64> = elements
        .par_iter()
        .with_min_len(256)
        .map(|e| {
            if e.corners.iter().all(|&c| owner[c as usize] == u32::MAX) {
                return 0;
            }
            let tri = mesh.patches[e.patch as usize].scene_triangle;
            targets.seen(mesh, bvh, e.centroid(), e.normal, tri)
        })
        .collect();
    let display = &mesh.display;
    let mut vertex: Vec<Option<u64>> = (0..nv)
        .into_par_iter()
        .with_min_len(256)
        .map(|k| {
            let i = owner[k];
            (i != u32::MAX).then(|| {
                let e = &elements[i as usize];
                targets.seen(mesh, bvh, display.positions[k], e.normal, own(i))
            })
        })
        .collect();
    // A vertex with no element on its side (a sliver of light) keeps all of them.
    let mut matched = vec![false; nv];
    for (e, side) in elements.iter().zip(&element) {
        for &c in &e.corners {
            matched[c as usize] |= vertex[c as usize] == Some(*side);
        }
    }
    for (v, m) in vertex.iter_mut().zip(matched) {
        if !m {
            *v = None;
        }
    }
    mesh.display.shadow_sides = Some(ShadowSides { vertex, element });
}
