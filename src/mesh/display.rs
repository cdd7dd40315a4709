//! The display mesh: element corners welded into shared vertices on smooth surfaces, and
//! reconstruction of a continuous radiosity from per-element values.
//!
//! Vertices are shared between elements of the same patch side and material whose normals
//! differ by less than [`SMOOTH_ANGLE_DEG`], so Gouraud shading (area-weighted vertex
//! averages, Cohen & Wallace, "Radiosity and Realistic Image Synthesis" §9.2) blends across
//! a smooth surface but never across a crease or a material boundary.

use super::{Element, Patch};
use glam::Vec3;
use std::collections::HashMap;

/// Normals within this angle are one smooth surface (the usual 30° crease angle of
/// modelling tools).
pub const SMOOTH_ANGLE_DEG: f32 = 30.0;

/// How a continuous radiosity is reconstructed from element values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Reconstruction {
    /// Each element's value, constant over it.
    Flat,
    /// Linear interpolation of area-weighted vertex averages.
    #[default]
    Gouraud,
}

impl std::str::FromStr for Reconstruction {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "flat" => Ok(Reconstruction::Flat),
            "gouraud" => Ok(Reconstruction::Gouraud),
            _ => Err(format!(
                "unknown reconstruction '{s}' (expected flat or gouraud)"
            )),
        }
    }
}

/// Shared vertices of the elements, in the mesh frame.
#[derive(Clone, Debug, Default)]
pub struct DisplayMesh {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    /// T-vertices left by adaptive subdivision: vertex `v` lies at the midpoint of the edge
    /// (`a`, `b`) of a coarser element that does not use it. Its Gouraud value is taken
    /// from that edge (the mean of `a` and `b`), so the shading has no crack there.
    /// Ordered coarse edges first, so chains of T-vertices resolve in one pass.
    pub hanging: Vec<[u32; 3]>,
}

impl DisplayMesh {
    /// Welds the corners of `elements` into shared vertices and records them in
    /// `Element::corners`. Positions closer than `scale × 1e-6` are the same point.
    pub fn build(elements: &mut [Element], patches: &[Patch], scale: f32) -> DisplayMesh {
        let cos_smooth = SMOOTH_ANGLE_DEG.to_radians().cos();
        let quantum = (scale * 1e-6).max(f32::MIN_POSITIVE);
        let mut mesh = DisplayMesh::default();
        // Key: quantised position, material, side → candidate vertices.
        let mut welded: HashMap<([i64; 3], u32, bool), Vec<u32>> = HashMap::new();
        for e in elements.iter_mut() {
            let patch = &patches[e.patch as usize];
            for k in 0..3 {
                let p = e.verts[k];
                let q = (p / quantum).round();
                let key = (
                    [q.x as i64, q.y as i64, q.z as i64],
                    patch.material,
                    patch.back,
                );
                let slots = welded.entry(key).or_default();
                let found = slots
                    .iter()
                    .copied()
                    .find(|&v| mesh.normals[v as usize].dot(e.normal) >= cos_smooth);
                e.corners[k] = match found {
                    Some(v) => v,
                    None => {
                        let v = mesh.positions.len() as u32;
                        mesh.positions.push(p);
                        mesh.normals.push(e.normal);
                        slots.push(v);
                        v
                    }
                };
            }
        }
        // T-vertices: a vertex of the same smooth surface at the midpoint of an element's
        // edge is not one of its corners, so it hangs on that edge.
        let mut hanging: Vec<(f32, [u32; 3])> = Vec::new();
        let mut seen = std::collections::HashSet::new();
        for e in elements.iter() {
            let patch = &patches[e.patch as usize];
            for k in 0..3 {
                let (a, b) = (e.corners[k], e.corners[(k + 1) % 3]);
                let m = (e.verts[k] + e.verts[(k + 1) % 3]) * 0.5;
                let q = (m / quantum).round();
                let key = (
                    [q.x as i64, q.y as i64, q.z as i64],
                    patch.material,
                    patch.back,
                );
                if let Some(slots) = welded.get(&key)
                    && let Some(&v) = slots
                        .iter()
                        .find(|&&v| mesh.normals[v as usize].dot(e.normal) >= cos_smooth)
                    && seen.insert(v)
                {
                    let len = (e.verts[k] - e.verts[(k + 1) % 3]).length();
                    hanging.push((len, [v, a, b]));
                }
            }
        }
        hanging.sort_by(|x, y| y.0.total_cmp(&x.0));
        mesh.hanging = hanging.into_iter().map(|h| h.1).collect();
        mesh
    }

    /// Gouraud vertex values: for each vertex the area-weighted mean of the values of the
    /// elements that use it.
    pub fn vertex_values(&self, elements: &[Element], values: &[Vec3]) -> Vec<Vec3> {
        let mut sum = vec![Vec3::ZERO; self.positions.len()];
        let mut weight = vec![0.0f32; self.positions.len()];
        for (e, v) in elements.iter().zip(values) {
            for &c in &e.corners {
                sum[c as usize] += *v * e.area;
                weight[c as usize] += e.area;
            }
        }
        let mut values: Vec<Vec3> = sum
            .iter()
            .zip(&weight)
            .map(|(s, w)| if *w > 0.0 { *s / *w } else { Vec3::ZERO })
            .collect();
        for &[v, a, b] in &self.hanging {
            values[v as usize] = (values[a as usize] + values[b as usize]) * 0.5;
        }
        values
    }

    /// The reconstructed value at barycentric point `bary` of element `e`, given element
    /// values and (for Gouraud) the vertex values from [`DisplayMesh::vertex_values`].
    pub fn value_at(
        mode: Reconstruction,
        elements: &[Element],
        element_values: &[Vec3],
        vertex_values: &[Vec3],
        e: u32,
        bary: [f32; 3],
    ) -> Vec3 {
        match mode {
            Reconstruction::Flat => element_values[e as usize],
            Reconstruction::Gouraud => {
                let c = elements[e as usize].corners;
                vertex_values[c[0] as usize] * bary[0]
                    + vertex_values[c[1] as usize] * bary[1]
                    + vertex_values[c[2] as usize] * bary[2]
            }
        }
    }
}
