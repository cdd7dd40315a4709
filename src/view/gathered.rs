//! The final-gathered picture: the surface point seen through each pixel, its radiosity
//! computed there by the final gather (`solver::gather`), shown with the viewer's exposure
//! and tone mapping. Anti-aliased by `samples`² stratified positions per pixel, averaged
//! after tone mapping (as a multisampled framebuffer resolves); rows in parallel.
//!
//! With textures, a point shows B = ρ(uv)·H(x) + E(uv) as the rasteriser does
//! (`shader.wgsl`), with H(x) = (B(x) − E_e)/ρ_e the gathered irradiance, the texture read
//! at the mip level of the sample's footprint, and alpha cut-outs passed through.

use super::camera::Camera;
use super::render::{CLEAR_COLOUR, Display};
use crate::geometry::sampling::{hash, unit};
use crate::mesh::Mesh;
use crate::scene::{Image, Material, Slot, TextureRef};
use crate::solver::gather::Gatherer;
use glam::{Vec3, Vec4};
use rayon::prelude::*;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Back faces a pixel's ray passes through before it gives up.
const MAX_BACK_FACES: usize = 16;

/// The scene's materials (for their texture references) and the images they refer to.
#[derive(Clone, Debug, Default)]
pub struct SurfaceTextures {
    pub materials: Vec<Material>,
    pub images: Vec<Arc<Image>>,
}

/// What to gather: the solution (with the mesh it lies on and the scene's BVH) and the
/// view.
pub struct GatheredView<'a> {
    pub gatherer: &'a Gatherer,
    pub camera: &'a Camera,
    pub size: [u32; 2],
    /// Samples per pixel side.
    pub samples: u32,
    pub display: Display,
    /// The textures shown when `display.textures` is on.
    pub textures: &'a SurfaceTextures,
}

/// A surface point seen by a sample: its element, the point, and the sample's footprint
/// (metres across, on the surface).
struct Seen {
    element: u32,
    point: Vec3,
    footprint: f32,
}

impl GatheredView<'_> {
    /// The linear display colour of pixel (`x`, `y`) (row 0 at the top).
    pub fn pixel(&self, x: u32, y: u32) -> Vec3 {
        let k = self.samples.max(1);
        let [w, h] = self.size.map(|v| v as f32);
        let exposure = 2f32.powf(self.display.ev) / std::f32::consts::PI;
        let mut sum = Vec3::ZERO;
        for s in 0..k * k {
            let seed = hash(((y as u64) << 32 | x as u64) ^ (s as u64) << 56);
            let sx = x as f32 + ((s % k) as f32 + unit(seed)) / k as f32;
            let sy = y as f32 + ((s / k) as f32 + unit(hash(seed))) / k as f32;
            let (origin, dir) = self.camera.ray(sx, sy, w, h);
            // The sample's spacing at unit distance.
            let spread = 2.0 * (self.camera.fov_y * 0.5).tan() / (h * k as f32);
            sum += match self.visible(origin, dir, spread) {
                Some(seen) => {
                    let b = self.shown(&seen);
                    self.display.tonemap.apply(b.max(Vec3::ZERO) * exposure)
                }
                None => CLEAR_COLOUR,
            };
        }
        sum / (k * k) as f32
    }

    /// The displayed radiosity at a seen point: the gathered B, or with textures on
    /// ρ(uv)·H + E(uv).
    fn shown(&self, seen: &Seen) -> Vec3 {
        let b = self.gatherer.at(seen.element, seen.point);
        if !self.display.textures {
            return b;
        }
        let mesh = self.gatherer.mesh();
        let patch = mesh.elements[seen.element as usize].patch as usize;
        let (Some(t), Some(m)) = (
            mesh.textures.get(patch),
            self.textures
                .materials
                .get(mesh.patches[patch].material as usize),
        ) else {
            return b;
        };
        let (rho, e) = self.gatherer.surface(seen.element);
        let h = crate::solver::irradiance_at(b, rho, e);
        let base = self
            .texel(mesh, seen, m.base_texture, Slot::Base)
            .truncate();
        let glow = self
            .texel(mesh, seen, m.emissive_texture, Slot::Emissive)
            .truncate();
        let [inverse_base, inverse_glow] = t.inverse_means();
        rho * inverse_base * base * h + e * inverse_glow * glow
    }

    /// `texture` (white when `None`) at the seen point, at the mip level whose texels
    /// match the sample's footprint.
    fn texel(&self, mesh: &Mesh, seen: &Seen, texture: Option<TextureRef>, slot: Slot) -> Vec4 {
        let Some((t, image)) =
            texture.and_then(|t| Some((t, self.textures.images.get(t.image as usize)?)))
        else {
            return Vec4::ONE;
        };
        let Some(uv) = mesh.texture_uv(seen.element, seen.point, slot) else {
            return Vec4::ONE;
        };
        // Texels per metre: the patch's texture area over its area, in texels.
        let patch = mesh.elements[seen.element as usize].patch as usize;
        let tex = &mesh.textures[patch].uv[slot as usize];
        let uv_area = 0.5 * (tex[1] - tex[0]).perp_dot(tex[2] - tex[0]).abs();
        let top = &image.levels[0];
        let texels =
            uv_area * (top.width * top.height) as f32 / mesh.patches[patch].area.max(1e-30);
        let across = texels.sqrt() * seen.footprint;
        let level = if across > 1.0 {
            across.log2().round() as usize
        } else {
            0
        };
        image.sample(level, uv, t.wrap)
    }

    /// The element and point (mesh frame, on the element's plane) a ray from `origin` along
    /// `dir` first meets on a side that faces it: the back of a single-sided surface, a
    /// covered patch (a ceiling under a flush lamp) and, with textures on, an alpha
    /// cut-out are passed through, as the rasteriser culls, leaves out and discards them.
    /// `None` when it leaves the scene.
    pub fn visible_point(&self, origin: Vec3, dir: Vec3) -> Option<(u32, Vec3)> {
        self.visible(origin, dir, 0.0).map(|s| (s.element, s.point))
    }

    /// [`GatheredView::visible_point`] with the footprint of a sample `spread` wide at
    /// unit distance.
    fn visible(&self, origin: Vec3, dir: Vec3, spread: f32) -> Option<Seen> {
        let (mut t0, mut skip) = (0.0, u32::MAX);
        let mesh = self.gatherer.mesh();
        for _ in 0..MAX_BACK_FACES {
            let hit = (self.gatherer.bvh()).closest_hit(origin, dir, t0, f32::INFINITY, skip)?;
            let p = origin + dir * hit.t;
            let seen = mesh.element_at(hit.triangle, p, -dir).filter(|&e| {
                let patch = mesh.elements[e as usize].patch;
                !mesh.patches[patch as usize].covered
            });
            if let Some(e) = seen {
                let element = &mesh.elements[e as usize];
                let cos = element.normal.dot(-dir).abs().max(0.05);
                let seen = Seen {
                    element: e,
                    point: element.project(p),
                    // The geometric mean of the footprint's two axes.
                    footprint: spread * hit.t / cos.sqrt(),
                };
                if !self.cut_out(mesh, &seen) {
                    return Some(seen);
                }
            }
            (t0, skip) = (hit.t, hit.triangle);
        }
        None
    }

    /// Whether the seen point is cut out by its material's alpha mask (textures on).
    fn cut_out(&self, mesh: &Mesh, seen: &Seen) -> bool {
        if !self.display.textures {
            return false;
        }
        let patch = &mesh.patches[mesh.elements[seen.element as usize].patch as usize];
        let Some(m) = self.textures.materials.get(patch.material as usize) else {
            return false;
        };
        match m.alpha_cutoff {
            Some(cutoff) => self.texel(mesh, seen, m.base_texture, Slot::Base).w < cutoff,
            None => false,
        }
    }

    /// Every pixel, rows from the top, with `rows_done` called as rows finish.
    pub fn image(&self, rows_done: &(dyn Fn(usize) + Sync)) -> Vec<Vec3> {
        let [w, h] = self.size;
        let done = AtomicUsize::new(0);
        (0..h)
            .into_par_iter()
            .flat_map_iter(|y| {
                let row: Vec<Vec3> = (0..w).map(|x| self.pixel(x, y)).collect();
                rows_done(done.fetch_add(1, Ordering::Relaxed) + 1);
                row
            })
            .collect()
    }
}

/// A linear display colour as opaque sRGB-encoded RGBA bytes.
pub fn encode(c: Vec3) -> [u8; 4] {
    let e = |c: f32| (super::colour::linear_to_srgb(c.clamp(0.0, 1.0)) * 255.0).round() as u8;
    [e(c.x), e(c.y), e(c.z), 255]
}

/// Linear display colours (rows from the top) as an sRGB-encoded image.
pub fn to_image(size: [u32; 2], pixels: &[Vec3]) -> image::RgbaImage {
    image::RgbaImage::from_fn(size[0], size[1], |x, y| {
        image::Rgba(encode(pixels[(y * size[0] + x) as usize]))
    })
}
