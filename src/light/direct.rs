//! Direct light from outside the element system: punctual lights (`KHR_lights_punctual`), the
//! sun and a uniform sky. Their first bounce becomes part of each element's source term:
//! E'_i = E_i + ρ_i H_i, with H_i the irradiance they deliver at the element's centroid
//! (W/m²), so the radiosity system B = E' + ρ F B then carries every later bounce.
//!
//! - Point light of intensity I (W/sr): H = I cosθ / r² · falloff(r) · V, with the glTF
//!   range window falloff = clamp(1 − (r/range)⁴, 0, 1) (glTF `KHR_lights_punctual`,
//!   "Range Property").
//! - Spot light: the point-light term times the spec's smooth cone attenuation
//!   (clamp((cos α − cos θ_outer) / (cos θ_inner − cos θ_outer), 0, 1))².
//! - Directional light / sun of irradiance E⊥: H = E⊥ cosθ · V.
//! - Uniform sky of radiance L: H = π L · (fraction of cosine-weighted directions that
//!   leave the scene), estimated with stratified cosine-weighted rays (Malley's method).

use super::ExternalLight;
use crate::accel::Bvh;
use crate::geometry::sampling::{cosine_direction, hash, unit};
use crate::geometry::{Frame, orthonormal_basis};
use crate::scene::Light;
use glam::{DVec3, Vec3};

/// Sky rays per element: one per cell of an 8×8 stratified grid over the cosine-weighted
/// hemisphere. Stratification keeps the error of the open fraction to the cells that a
/// silhouette crosses, about 8 of 64, so a few percent of π L at worst per element.
pub const SKY_RAYS: u32 = 64;

/// Irradiance (W/m² per channel) at point `x` with normal `n` on scene triangle `own`, and
/// the number of rays cast. `x` and `n` are in `frame`; light positions are world space.
/// The sky takes [`SKY_RAYS`] rays.
pub fn irradiance(
    frame: &Frame,
    bvh: &Bvh,
    external: &ExternalLight,
    x: Vec3,
    n: Vec3,
    own: u32,
    seed: u64,
) -> (Vec3, u32) {
    irradiance_with_sky_rays(frame, bvh, external, (x, n, own), seed, SKY_RAYS)
}

/// The irradiance an element's source term takes: [`irradiance`] with
/// [`ELEMENT_SKY_RAYS`] sky rays.
pub fn element_irradiance(
    frame: &Frame,
    bvh: &Bvh,
    external: &ExternalLight,
    at: (Vec3, Vec3, u32),
    seed: u64,
) -> (Vec3, u32) {
    irradiance_with_sky_rays(frame, bvh, external, at, seed, ELEMENT_SKY_RAYS)
}

/// Sky rays for an element's source term: a 16 × 16 stratified grid. Seen through an
/// opening (Sponza's galleries and the wall under its balconies, a few percent of the
/// hemisphere), one ray more or less of [`SKY_RAYS`] moved an element's light by a third,
/// and Gouraud shading fanned those steps out over long thin triangles. Casting more only
/// where the first 64 are partly open is cheaper but biased: an opening all 64 miss stays
/// dark.
pub const ELEMENT_SKY_RAYS: u32 = 256;

/// [`irradiance`] with `sky_rays` rays for the sky (rounded down to a square grid).
pub fn irradiance_with_sky_rays(
    frame: &Frame,
    bvh: &Bvh,
    external: &ExternalLight,
    (x, n, own): (Vec3, Vec3, u32),
    seed: u64,
    sky_rays: u32,
) -> (Vec3, u32) {
    let from = x + n * frame.epsilon();
    let mut h = Vec3::ZERO;
    let mut rays = 0;
    for light in &external.lights {
        match light {
            Light::Point {
                position,
                intensity,
                range,
            } => {
                let (g, r) = point_geometry(frame, *position, x, n);
                if g > 0.0 {
                    rays += 1;
                    let v = bvh.transmittance(from, frame.to_local(*position), [own, u32::MAX]);
                    h += *intensity * (g * v * range_falloff(r, *range));
                }
            }
            Light::Spot {
                position,
                direction,
                intensity,
                range,
                inner_cone,
                outer_cone,
            } => {
                let (g, r) = point_geometry(frame, *position, x, n);
                if g > 0.0 {
                    let to_x = (frame.origin + x.as_dvec3() - *position).normalize_or_zero();
                    let cone = spot_attenuation(to_x.dot(*direction), *inner_cone, *outer_cone);
                    if cone > 0.0 {
                        rays += 1;
                        let v = bvh.transmittance(from, frame.to_local(*position), [own, u32::MAX]);
                        h += *intensity * (g * v * cone * range_falloff(r, *range));
                    }
                }
            }
            Light::Directional {
                direction,
                irradiance,
            } => {
                let to_light = -direction.as_vec3();
                let c = n.dot(to_light);
                if c > 0.0 {
                    rays += 1;
                    h += *irradiance
                        * (c * bvh.transmittance_toward(from, to_light, [own, u32::MAX]));
                }
            }
        }
    }
    if let Some(env) = &external.environment {
        if let Some((to_sun, e_sun)) = env.sun {
            let to_sun = to_sun.as_vec3().normalize_or_zero();
            let c = n.dot(to_sun);
            if c > 0.0 {
                rays += 1;
                h += e_sun * (c * bvh.transmittance_toward(from, to_sun, [own, u32::MAX]));
            }
        }
        if env.sky.max_element() > 0.0 {
            let k = (sky_rays.max(1) as f32).sqrt() as u32;
            let open = sky_fraction(bvh, (from, n, own), seed, k);
            rays += k * k;
            h += env.sky * (std::f32::consts::PI * open);
        }
    }
    (h, rays)
}

/// cosθ / r² for a point light at world `position` seen from `x` (in `frame`), and r.
fn point_geometry(frame: &Frame, position: DVec3, x: Vec3, n: Vec3) -> (f32, f64) {
    let d = position - (frame.origin + x.as_dvec3());
    let r2 = d.length_squared();
    if r2 <= 0.0 {
        return (0.0, 0.0);
    }
    let r = r2.sqrt();
    let c = n.as_dvec3().dot(d) / r;
    if c <= 0.0 {
        return (0.0, r);
    }
    ((c / r2) as f32, r)
}

/// glTF range window: 1 inside, smoothly 0 at `range` (KHR_lights_punctual, "Range").
fn range_falloff(r: f64, range: Option<f64>) -> f32 {
    match range {
        Some(range) if range > 0.0 => (1.0 - (r / range).powi(4)).clamp(0.0, 1.0) as f32,
        _ => 1.0,
    }
}

/// The spec's spot cone attenuation for `cos_angle` between the spot axis and the direction
/// to the lit point.
pub fn spot_attenuation(cos_angle: f64, inner: f64, outer: f64) -> f32 {
    let (ci, co) = (inner.cos(), outer.cos());
    let scale = 1.0 / (ci - co).max(0.001);
    let t = ((cos_angle - co) * scale).clamp(0.0, 1.0);
    (t * t) as f32
}

/// Fraction of cosine-weighted directions above (`from`, `n`) that escape the scene.
/// One ray per cell of a k × k stratified grid.
fn sky_fraction(bvh: &Bvh, (from, n, own): (Vec3, Vec3, u32), seed: u64, k: u32) -> f32 {
    let (t, b) = orthonormal_basis(n);
    let mut open = 0.0;
    for i in 0..k {
        for j in 0..k {
            let h = hash(seed ^ ((i * k + j) as u64).wrapping_mul(0x9E37_79B9));
            let u = (i as f32 + unit(h)) / k as f32;
            let v = (j as f32 + unit(hash(h))) / k as f32;
            let d = cosine_direction(n, (t, b), u, v);
            open += bvh.transmittance_toward(from, d, [own, u32::MAX]);
        }
    }
    open / (k * k) as f32
}
