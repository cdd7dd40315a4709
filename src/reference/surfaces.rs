//! The scene's surfaces as the path tracer sees them: every scene triangle in the mesh
//! frame with its reflectance, emission, sidedness and transmittance — the same values the
//! mesher gives its patches ([`crate::mesh::surface_values`]), with no discretisation —
//! and the emitters, sampled by power for next-event estimation.

use crate::geometry::sampling::point_in_triangle;
use crate::geometry::{Frame, closest_point_on_triangle, triangle_area, triangle_cross};
use crate::mesh::{scene_triangle, surface_values};
use crate::scene::Scene;
use glam::Vec3;

/// Every scene triangle with what light transport needs of it.
pub struct Surfaces {
    /// The frame positions are stored in (centred on the scene's bounds, as the mesh's).
    pub frame: Frame,
    /// Scene triangles in the frame (the BVH's input and numbering).
    pub triangles: Vec<[Vec3; 3]>,
    /// Fraction of light a shadow ray passes through each triangle (alpha cut-outs, glass).
    pub transmittance: Vec<f32>,
    /// Unit front normal (counter-clockwise side); zero for a degenerate triangle.
    pub normal: Vec<Vec3>,
    /// Reflectance ρ per triangle (material × texture mean, clamped to [0, 0.999]).
    pub reflectance: Vec<Vec3>,
    /// Emitted radiosity E = π L_e per triangle, W/m².
    pub emission: Vec<Vec3>,
    /// Whether both sides reflect and emit (otherwise the back side is black).
    pub double_sided: Vec<bool>,
    /// Area per triangle, m² (zero for degenerate triangles and those without material).
    pub area: Vec<f32>,
    /// The scene object each triangle belongs to.
    pub object: Vec<u32>,
    /// Emissive triangles and the cumulative distribution of their power Σ_c E_c · A.
    emitters: Vec<u32>,
    emitter_cdf: Vec<f64>,
}

/// An emitter point drawn for next-event estimation.
pub struct EmitterSample {
    pub triangle: u32,
    pub point: Vec3,
    /// Probability density of having drawn this point, per m².
    pub pdf_area: f64,
}

impl Surfaces {
    /// The surfaces of `scene`, triangle by triangle as the mesher reads them
    /// ([`crate::mesh::scene_triangle`]): triangles without a material are left out (they
    /// block nothing in the solvers either); degenerate ones stay, blocking rays, with zero
    /// area and no light.
    pub fn new(scene: &Scene) -> Surfaces {
        let frame = scene.frame();
        let n = scene.triangle_count();
        let mut s = Surfaces {
            frame,
            triangles: Vec::with_capacity(n),
            transmittance: Vec::with_capacity(n),
            normal: Vec::with_capacity(n),
            reflectance: Vec::with_capacity(n),
            emission: Vec::with_capacity(n),
            double_sided: Vec::with_capacity(n),
            area: Vec::with_capacity(n),
            object: Vec::with_capacity(n),
            emitters: Vec::new(),
            emitter_cdf: Vec::new(),
        };
        let mut total = 0.0;
        for (oi, o) in scene.objects.iter().enumerate() {
            for ti in 0..o.triangles.len() {
                let Some(t) = scene_triangle(scene, o, ti, &frame) else {
                    continue;
                };
                let usable = !t.degenerate;
                let (rho, emission, _) = surface_values(t.mat, o, ti);
                let (rho, emission) = if usable {
                    (rho, emission)
                } else {
                    (Vec3::ZERO, Vec3::ZERO)
                };
                let a = if usable { triangle_area(&t.verts) } else { 0.0 };
                let index = s.triangles.len() as u32;
                s.triangles.push(t.verts);
                s.transmittance.push(t.transmittance);
                s.object.push(oi as u32);
                s.normal.push(if usable {
                    triangle_cross(&t.verts).normalize_or_zero()
                } else {
                    Vec3::ZERO
                });
                s.area.push(a);
                s.reflectance.push(rho);
                s.emission.push(emission);
                s.double_sided.push(usable && t.mat.double_sided);
                let power = (emission.x + emission.y + emission.z) as f64 * a as f64;
                if power > 0.0 {
                    total += power;
                    s.emitters.push(index);
                    s.emitter_cdf.push(total);
                }
            }
        }
        s
    }

    /// Whether any surface emits.
    pub fn has_emitters(&self) -> bool {
        !self.emitters.is_empty()
    }

    /// An emitter point for (u, v, w) ∈ [0, 1)³: a triangle by power, a point uniform on it.
    pub fn sample_emitter(&self, u: f32, v: f32, w: f32) -> Option<EmitterSample> {
        let total = *self.emitter_cdf.last()?;
        let x = u as f64 * total;
        let k = self
            .emitter_cdf
            .partition_point(|c| *c <= x)
            .min(self.emitters.len() - 1);
        let t = self.emitters[k];
        let before = if k == 0 { 0.0 } else { self.emitter_cdf[k - 1] };
        let p_triangle = (self.emitter_cdf[k] - before) / total;
        let area = self.area[t as usize] as f64;
        Some(EmitterSample {
            triangle: t,
            point: point_in_triangle(&self.triangles[t as usize], v, w),
            pdf_area: p_triangle / area,
        })
    }

    /// The density per m² with which [`Surfaces::sample_emitter`] draws a point of
    /// triangle `t` (zero when it does not emit).
    pub fn emitter_pdf_area(&self, t: u32) -> f64 {
        let Some(total) = self.emitter_cdf.last() else {
            return 0.0;
        };
        let e = self.emission[t as usize];
        let area = self.area[t as usize] as f64;
        if area <= 0.0 {
            return 0.0;
        }
        // Power over total power, spread uniformly over the triangle's area.
        (e.x + e.y + e.z) as f64 / total
    }

    /// The triangle a query point lies on: among triangles with area whose side facing
    /// `normal` (world) is reflective or emissive — the front, or either side of a
    /// double-sided one — and whose plane faces it (normal · side normal > 0.5), the one
    /// nearest to `p` (frame). Returns the triangle, the nearest point on it, and the side's
    /// unit normal.
    pub fn locate(&self, p: Vec3, normal: Vec3) -> Option<(u32, Vec3, Vec3)> {
        let n = normal.normalize_or_zero();
        let mut best: Option<(f32, u32, Vec3, Vec3)> = None;
        for (i, t) in self.triangles.iter().enumerate() {
            if self.area[i] <= 0.0 {
                continue;
            }
            let front = self.normal[i];
            let side = if front.dot(n) > 0.5 {
                front
            } else if self.double_sided[i] && -front.dot(n) > 0.5 {
                -front
            } else {
                continue;
            };
            let (q, _) = closest_point_on_triangle(p, t);
            let d = (q - p).length_squared();
            if best.is_none_or(|(bd, ..)| d < bd) {
                best = Some((d, i as u32, q, side));
            }
        }
        best.map(|(_, i, q, side)| (i, q, side))
    }
}
