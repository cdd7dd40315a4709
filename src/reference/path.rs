//! One path-traced sample of the radiosity at a surface point.
//!
//! The estimator (Kajiya 1986, with next-event estimation; Veach 1997, §9.2) for diffuse
//! surfaces, in radiosity terms: at a point x with reflectance ρ(x) and emitted radiosity
//! E(x),
//!
//! B(x) = E(x) + ρ(x) · H(x),   H(x) = H_lights(x) + H_emitters(x) + ∫ (B_r(y)/π) cosθ dω,
//!
//! where H is the irradiance arriving at x: from the punctual lights and the sun
//! ([`crate::light::direct`], one shadow ray each), from emitting surfaces, and reflected by
//! the surfaces it sees, B_r(y) = ρ(y) H(y). One cosine-weighted direction (pdf cosθ/π)
//! estimates the light from surfaces: the surface y it hits contributes π L(y), that is
//! its emission E(y) and, recursively, ρ(y) H(y): a path. A ray that leaves the scene
//! brings the sky, π L_sky. Emitters are also sampled directly (next-event estimation: a
//! point drawn by power, with the point-to-point form factor and its visibility), and the
//! two estimates of emitted light are combined by multiple importance sampling with the
//! power heuristic (Veach & Guibas 1995): the emitter sample wins far from an emitter, the
//! cosine sample beside one (a point a hair from a glowing wall, where 1/r² makes the
//! emitter sample's variance unbounded). Paths end by Russian roulette
//! on ρ (continue with probability q = max ρ, weight ρ/q): no depth cut, so the estimate
//! is unbiased at any reflectance.
//!
//! The same scene semantics as the radiosity solvers: single-sided surfaces reflect and
//! emit on their front only and their back is black; every surface blocks light from both
//! sides; a triangle of transmittance τ (alpha cut-outs, glass, as the solvers model them)
//! lets a ray through with probability τ.

use super::surfaces::Surfaces;
use crate::accel::Bvh;
use crate::geometry::orthonormal_basis;
use crate::geometry::sampling::{cosine_direction, hash, unit};
use crate::light::{ExternalLight, direct};
use glam::{DVec3, Vec3};

/// Deterministic random numbers for one sample: a counter through the hash.
pub struct Rng(u64);

impl Rng {
    /// The stream of sample `sample` of point `point` for `seed`.
    pub fn new(seed: u64, point: u64, sample: u64) -> Rng {
        Rng(hash(
            seed ^ hash(point ^ hash(sample.wrapping_add(0x5851_F42D_4C95_7F2D))),
        ))
    }

    /// Uniform in [0, 1).
    pub fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        unit(hash(self.0))
    }
}

/// What a sample needs: the surfaces, their BVH, the lights outside them (punctual lights
/// and the sun; the sky comes from escaping rays), and the sky's radiance.
pub struct Tracer<'a> {
    pub surfaces: &'a Surfaces,
    pub bvh: &'a Bvh,
    /// Punctual lights and the sun (no sky).
    pub lights: ExternalLight,
    pub sky: Vec3,
}

impl Tracer<'_> {
    /// One sample of B at point `x` with side normal `n` on triangle `own`.
    pub fn radiosity(&self, x: Vec3, n: Vec3, own: u32, rng: &mut Rng) -> DVec3 {
        let s = self.surfaces;
        let e = s.emission[own as usize].as_dvec3();
        let rho = s.reflectance[own as usize].as_dvec3();
        e + rho * self.irradiance(x, n, own, rng)
    }

    /// One sample of the irradiance H arriving at `x` (normal `n`, on triangle `own`).
    fn irradiance(&self, mut x: Vec3, mut n: Vec3, mut own: u32, rng: &mut Rng) -> DVec3 {
        let s = self.surfaces;
        let eps = s.frame.epsilon();
        let mut total = DVec3::ZERO;
        let mut weight = DVec3::ONE;
        loop {
            total += weight * (self.lights_at(x, n, own, rng) + self.emitters_at(x, n, own, rng));
            let d = cosine_direction(n, orthonormal_basis(n), rng.next(), rng.next());
            let Some((y, t)) = self.trace(x + n * eps, d, own, rng) else {
                // Left the scene: the sky.
                total += weight * self.sky.as_dvec3() * std::f64::consts::PI;
                break;
            };
            let front = s.normal[t as usize];
            let facing = front.dot(d) < 0.0;
            if !facing && !s.double_sided[t as usize] {
                break; // the black back of a single-sided surface
            }
            let e = s.emission[t as usize];
            if e.max_element() > 0.0 {
                // π L_e = E, weighted against the emitter sample of the same direction.
                let r2 = (y - x).length_squared() as f64;
                let cos_y = front.dot(d).abs() as f64;
                let pdf_light = s.emitter_pdf_area(t) * r2 / cos_y.max(1e-12);
                let pdf_cosine = n.dot(d).max(0.0) as f64 / std::f64::consts::PI;
                total += weight * e.as_dvec3() * power_heuristic(pdf_cosine, pdf_light);
            }
            let rho = s.reflectance[t as usize];
            let q = rho.max_element();
            if q <= 0.0 || rng.next() >= q {
                break;
            }
            weight *= rho.as_dvec3() / q as f64;
            x = y;
            n = if facing { front } else { -front };
            own = t;
        }
        total
    }

    /// The first surface along `from + t·d` (t > 0) that stops the ray, skipping `own`:
    /// transmissive triangles let it through with probability τ.
    fn trace(&self, from: Vec3, d: Vec3, own: u32, rng: &mut Rng) -> Option<(Vec3, u32)> {
        self.bvh
            .stopping_hit(from, d, own, |tau| rng.next() < tau)
            .map(|(y, hit)| (y, hit.triangle))
    }

    /// Irradiance from the punctual lights and the sun, one shadow ray each.
    fn lights_at(&self, x: Vec3, n: Vec3, own: u32, rng: &mut Rng) -> DVec3 {
        if self.lights.is_empty() {
            return DVec3::ZERO;
        }
        let seed = (rng.next().to_bits() as u64) << 32 | rng.next().to_bits() as u64;
        let (h, _) = direct::irradiance(
            &self.surfaces.frame,
            self.bvh,
            &self.lights,
            x,
            n,
            own,
            seed,
        );
        if h.is_finite() {
            h.as_dvec3()
        } else {
            DVec3::ZERO
        }
    }

    /// One next-event sample of the irradiance from emitting surfaces:
    /// (E_y/π) cosθ_x cosθ_y / r² · V(x, y) / pdf(y).
    fn emitters_at(&self, x: Vec3, n: Vec3, own: u32, rng: &mut Rng) -> DVec3 {
        let s = self.surfaces;
        let Some(sample) = s.sample_emitter(rng.next(), rng.next(), rng.next()) else {
            return DVec3::ZERO;
        };
        let t = sample.triangle as usize;
        if t == own as usize {
            return DVec3::ZERO;
        }
        let to_y = sample.point - x;
        let r2 = to_y.length_squared();
        if r2 <= 0.0 || !r2.is_finite() {
            return DVec3::ZERO;
        }
        let r = r2.sqrt();
        let w = to_y / r;
        let cos_x = n.dot(w);
        // The emitter's side facing x: its front, or its back when double-sided.
        let mut ny = s.normal[t];
        let mut cos_y = -ny.dot(w);
        if cos_y < 0.0 && s.double_sided[t] {
            ny = -ny;
            cos_y = -cos_y;
        }
        if cos_x <= 0.0 || cos_y <= 0.0 {
            return DVec3::ZERO;
        }
        let eps = s.frame.epsilon();
        let v =
            self.bvh
                .transmittance(x + n * eps, sample.point + ny * eps, [own, sample.triangle]);
        if v <= 0.0 {
            return DVec3::ZERO;
        }
        let g = cos_x as f64 * cos_y as f64 / (std::f64::consts::PI * r2 as f64);
        let pdf_light = sample.pdf_area * r2 as f64 / cos_y as f64;
        let pdf_cosine = cos_x as f64 / std::f64::consts::PI;
        let w = power_heuristic(pdf_light, pdf_cosine);
        s.emission[t].as_dvec3() * (g * v as f64 / sample.pdf_area * w)
    }
}

/// The power heuristic's weight of a sample drawn with density `a` (per solid angle)
/// against another strategy of density `b`: a² / (a² + b²) (Veach & Guibas 1995).
fn power_heuristic(a: f64, b: f64) -> f64 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 && (a2 + b2).is_finite() {
        a2 / (a2 + b2)
    } else if a.is_infinite() {
        1.0
    } else {
        0.0
    }
}
