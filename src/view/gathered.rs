//! The final-gathered picture: the surface point seen through each pixel, its radiosity
//! computed there by the final gather (`solver::gather`), shown with the viewer's exposure
//! and tone mapping. Anti-aliased by `samples`² stratified positions per pixel, averaged
//! after tone mapping (as a multisampled framebuffer resolves); rows in parallel.

use super::camera::Camera;
use super::render::{CLEAR_COLOUR, Display};
use crate::geometry::sampling::{hash, unit};
use crate::solver::gather::Gatherer;
use glam::Vec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Back faces a pixel's ray passes through before it gives up.
const MAX_BACK_FACES: usize = 16;

/// What to gather: the solution (with the mesh it lies on and the scene's BVH) and the
/// view.
pub struct GatheredView<'a> {
    pub gatherer: &'a Gatherer,
    pub camera: &'a Camera,
    pub size: [u32; 2],
    /// Samples per pixel side.
    pub samples: u32,
    pub display: Display,
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
            sum += match self.radiosity_along(origin, dir) {
                Some(b) => self.display.tonemap.apply(b.max(Vec3::ZERO) * exposure),
                None => CLEAR_COLOUR,
            };
        }
        sum / (k * k) as f32
    }

    /// B at the first surface along the ray that faces it, `None` when the ray leaves
    /// the scene.
    fn radiosity_along(&self, origin: Vec3, dir: Vec3) -> Option<Vec3> {
        self.visible_point(origin, dir)
            .map(|(e, x)| self.gatherer.at(e, x))
    }

    /// The element and point (mesh frame, on the element's plane) a ray from `origin` along
    /// `dir` first meets on a side that faces it: the back of a single-sided surface and a
    /// covered patch (a ceiling under a flush lamp) are passed through, as the rasteriser
    /// culls the one and does not draw the other. `None` when it leaves the scene.
    pub fn visible_point(&self, origin: Vec3, dir: Vec3) -> Option<(u32, Vec3)> {
        let (mut t0, mut skip) = (0.0, u32::MAX);
        for _ in 0..MAX_BACK_FACES {
            let hit = (self.gatherer.bvh()).closest_hit(origin, dir, t0, f32::INFINITY, skip)?;
            let p = origin + dir * hit.t;
            let mesh = self.gatherer.mesh();
            let seen = mesh.element_at(hit.triangle, p, -dir).filter(|&e| {
                let patch = mesh.elements[e as usize].patch;
                !mesh.patches[patch as usize].covered
            });
            if let Some(e) = seen {
                return Some((e, mesh.elements[e as usize].project(p)));
            }
            (t0, skip) = (hit.t, hit.triangle);
        }
        None
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
