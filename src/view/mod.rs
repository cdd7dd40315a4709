//! The viewer: an eframe/egui window over the solver worker, and the wgpu renderer it
//! shares with `radiosity render` and the screenshot path.
//!
//! - [`app`]: the window: [`app::Options`], [`app::run`], the [`app::App`], the worker's
//!   events, keyboard shortcuts, each frame's order of work.
//! - `session`: everything of one opened scene, replaced whole when a scene opens.
//! - `panels`: the menu bar, status bar and side panel (statistics, display, selection,
//!   solver, convergence plot).
//! - `viewport`: the 3D view: camera controls, picking, painting the GPU's picture.
//! - `gpu`: the GPU's copy of the scene (uploads throttled by their cost) and when the 3D
//!   picture is drawn again.
//! - `edits`: moving objects with undo and redo, live material edits.
//! - `files`: dialogs, dropped files, recent files, screenshots, the frame statistics.
//! - `colour`: the false-colour map and sRGB conversions.
//! - [`render`]: the offscreen wgpu renderer (colour + depth target, value textures).
//! - [`camera`]: the orbit camera and picking rays.

pub mod app;
pub mod camera;
mod colour;
mod edits;
mod files;
mod final_gather;
pub mod gathered;
mod gpu;
mod panels;
pub mod render;
mod session;
pub mod textures;
mod viewport;

use crate::accel::Bvh;
use crate::geometry::triangle_cross;
use crate::mesh::Mesh;
use anyhow::{Context, Result};
use camera::Camera;
use glam::Vec3;
use std::path::Path;

pub use crate::exposure::auto_exposure;

/// Auto exposure metered on what `camera` sees in a view of `aspect` (width / height):
/// `exposure::metered_exposure` over a 48 × 32 grid of the view's rays, the scene-wide
/// rule's EV when the view shows no lit surface; the false-colour range is the scene's
/// (`auto_exposure`).
pub fn view_exposure(
    mesh: &Mesh,
    bvh: &Bvh,
    radiosity: &[Vec3],
    camera: &Camera,
    aspect: f32,
) -> Option<(f32, (f32, f32))> {
    let (scene_ev, range) = auto_exposure(mesh, radiosity)?;
    let (w, h) = (48.0 * aspect.clamp(0.25, 4.0), 32.0);
    let rays: Vec<(Vec3, Vec3)> = (0..32)
        .flat_map(|y| (0..w as u32).map(move |x| (x, y)))
        .map(|(x, y)| camera.ray(x as f32 + 0.5, y as f32 + 0.5, w.floor(), h))
        .collect();
    let ev = crate::exposure::metered_exposure(mesh, bvh, radiosity, &rays).unwrap_or(scene_ev);
    Some((ev, range))
}
pub(crate) use crate::exposure::percentile;

/// Encodes `image` as PNG and writes it atomically (temporary file, then rename).
pub fn write_png(path: &Path, image: &image::RgbaImage) -> Result<()> {
    let mut bytes = Vec::new();
    image
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .with_context(|| format!("{}: cannot encode the PNG", path.display()))?;
    Ok(crate::files::write_atomic(path, &bytes)?)
}

/// Bounding sphere (centre, radius) of the mesh's triangles in the mesh frame.
pub fn bounds(mesh: &Mesh) -> Option<(Vec3, f32)> {
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for t in &mesh.triangles {
        for v in t {
            if v.is_finite() {
                lo = lo.min(*v);
                hi = hi.max(*v);
            }
        }
    }
    (lo.x <= hi.x).then(|| ((lo + hi) * 0.5, ((hi - lo) * 0.5).length()))
}

/// The starting view. From the centre of the scene's bounds, rays go out along +z, −z,
/// +x and −x, taking what lies beyond a tenth of the bounds' radius and passing through
/// the backs of one-sided surfaces: an object at the centre is not the scene's shape
/// (cornell-box-vinc3r has its logo there, through the very centre; the view stood
/// inside it, and the picture was black):
/// - when one escapes and at least two meet surfaces, the first that escapes is the open
///   side (a Cornell box's missing front wall): look in through it at the whole scene;
/// - when all four meet surfaces facing the centre, the centre is inside a room or a
///   courtyard (Sponza's atrium): stand there and look along the longer horizontal axis;
/// - otherwise the scene is an object, or objects, to look at from outside (the centre
///   may be inside one, or in the open beside a single surface): the whole scene from
///   above at an angle.
pub fn default_camera(mesh: &Mesh, bvh: &Bvh) -> Camera {
    let Some((c, r)) = bounds(mesh) else {
        return Camera::default();
    };
    let dirs = [
        (Vec3::Z, 0.0f32),
        (-Vec3::Z, std::f32::consts::PI),
        (Vec3::X, std::f32::consts::FRAC_PI_2),
        (-Vec3::X, -std::f32::consts::FRAC_PI_2),
    ];
    let met: Vec<bool> = dirs
        .iter()
        .map(|(d, _)| meets_a_face(mesh, bvh, c, *d, 0.1 * r))
        .collect();
    let faces = met.iter().filter(|m| **m).count();
    if let Some(k) = met.iter().position(|m| !m) {
        if faces >= 2 {
            return Camera::framing(c, r, dirs[k].1, 0.0);
        }
    } else {
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for v in mesh.triangles.iter().flatten().filter(|v| v.is_finite()) {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
        let e = hi - lo;
        // Looking along +x is yaw −90° (the eye sits on the −x side of the target).
        let yaw = if e.x >= e.z {
            -std::f32::consts::FRAC_PI_2
        } else {
            std::f32::consts::PI
        };
        let mut cam = Camera::framing(c, r, yaw, 0.1);
        cam.distance = r * 0.02;
        return cam;
    }
    Camera::framing(c, r, 0.6, 0.6)
}

/// Whether a ray from the scene's centre meets, beyond `near`, a surface facing back at it
/// (or double-sided), passing through the backs of one-sided surfaces on the way.
fn meets_a_face(mesh: &Mesh, bvh: &Bvh, from: Vec3, d: Vec3, near: f32) -> bool {
    let (mut t_min, mut skip) = (near, u32::MAX);
    // A bounded walk: a ray through a tangle of overlapping backs gives up as "escaped".
    for _ in 0..64 {
        let Some(hit) = bvh.closest_hit(from, d, t_min, f32::INFINITY, skip) else {
            break;
        };
        let facing = triangle_cross(&mesh.triangles[hit.triangle as usize]).dot(d) < 0.0;
        if facing || mesh.double_sided(hit.triangle) {
            return true;
        }
        (t_min, skip) = (hit.t, hit.triangle);
    }
    false
}
