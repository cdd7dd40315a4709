//! Texture coordinates and texture means at the patches' vertices, for the display.
//!
//! A patch is a piece of one scene triangle, and a triangle's texture coordinates are an
//! affine function of position on it, so the coordinates at any point of a patch (an
//! element corner, a pixel's visible point) are the barycentric interpolation of the
//! coordinates at the patch's vertices, which are interpolated from the triangle's.

use super::Mesh;
use crate::scene::{Scene, Slot, TexturedTriangle};
use glam::{Vec2, Vec3};

/// A patch's texture coordinates at its vertices and its triangle's texture means, per
/// [`Slot`] (means of 1 and coordinates of 0 where the material has no such texture).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchTexture {
    pub uv: [[Vec2; 3]; 2],
    pub mean: [Vec3; 2],
}

impl PatchTexture {
    /// The coordinates in `slot` at barycentric point `bary` of the patch.
    pub fn uv_at(&self, slot: Slot, bary: [f32; 3]) -> Vec2 {
        interpolate(&self.uv[slot as usize], bary)
    }

    /// 1 / the base and emissive means (each channel at most 10⁶): the factors that turn
    /// the solved ρ_e and E_e into the textures' factors (ρ(uv) = ρ_e · T(uv) / T̄).
    pub fn inverse_means(&self) -> [Vec3; 2] {
        self.mean.map(|m| Vec3::ONE / m.max(Vec3::splat(1e-6)))
    }
}

/// The value at barycentric point `bary` of the corner values `corners`.
fn interpolate(corners: &[Vec2; 3], bary: [f32; 3]) -> Vec2 {
    corners[0] * bary[0] + corners[1] * bary[1] + corners[2] * bary[2]
}

impl Mesh {
    /// The texture coordinates in `slot` at point `p` (mesh frame) of element `e`, or
    /// `None` when the scene has no textures.
    pub fn texture_uv(&self, e: u32, p: Vec3, slot: Slot) -> Option<Vec2> {
        let patch = self.elements[e as usize].patch as usize;
        let t = self.textures.get(patch)?;
        Some(t.uv_at(slot, barycentric(&self.patches[patch].verts, p)))
    }
}

/// Barycentric coordinates of `p` in triangle `t` (p projected onto its plane; the
/// coordinates sum to 1, and are (1/3, 1/3, 1/3) for a degenerate triangle).
pub fn barycentric(t: &[Vec3; 3], p: Vec3) -> [f32; 3] {
    let (e1, e2, d) = (t[1] - t[0], t[2] - t[0], p - t[0]);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (d1, d2) = (d.dot(e1), d.dot(e2));
    let det = d11 * d22 - d12 * d12;
    if det.is_nan() || det.abs() <= f32::MIN_POSITIVE {
        return [1.0 / 3.0; 3];
    }
    let b1 = (d22 * d1 - d12 * d2) / det;
    let b2 = (d11 * d2 - d12 * d1) / det;
    [1.0 - b1 - b2, b1, b2]
}

/// Every patch's [`PatchTexture`], or none when no object of `scene` is textured.
pub(super) fn patch_textures(mesh: &Mesh, scene: &Scene) -> Vec<PatchTexture> {
    if scene.objects.iter().all(|o| o.textured.is_empty()) {
        return Vec::new();
    }
    mesh.patches
        .iter()
        .map(|p| {
            let t: TexturedTriangle =
                scene.objects[p.object as usize].textured(p.triangle as usize);
            let triangle = &mesh.triangles[p.scene_triangle as usize];
            let uv = std::array::from_fn(|slot| {
                p.verts
                    .map(|v| interpolate(&t.uv[slot], barycentric(triangle, v)))
            });
            PatchTexture { uv, mean: t.mean }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn barycentric_reproduces_the_point() {
        let t = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 1.0),
        ];
        let b = [0.2, 0.5, 0.3];
        let p = t[0] * b[0] + t[1] * b[1] + t[2] * b[2];
        let got = barycentric(&t, p);
        for k in 0..3 {
            assert!((got[k] - b[k]).abs() < 1e-6, "{got:?}");
        }
    }
}
