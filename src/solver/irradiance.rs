//! The irradiance behind a solution: B = E + ρ H per element, so H = (B − E) / ρ.
//!
//! The display puts textures under the light (displayed radiance = albedo(uv) · H / π +
//! L_e(uv)), so it reconstructs H, which is smooth across triangles of different texture
//! means, rather than B, which jumps with them.

use glam::{DVec3, Vec3};

/// H per element and channel from radiosity, reflectance and emitted radiosity (W/m²)
/// ([`irradiance_at`] of each element).
pub fn irradiance(radiosity: &[Vec3], reflectance: &[Vec3], emission: &[Vec3]) -> Vec<Vec3> {
    radiosity
        .iter()
        .zip(reflectance)
        .zip(emission)
        .map(|((b, rho), e)| irradiance_at(*b, *rho, *e))
        .collect()
}

/// H from one radiosity `b`, reflectance `rho` and emitted radiosity `e`
/// ([`irradiance_at_f64`]).
pub fn irradiance_at(b: Vec3, rho: Vec3, e: Vec3) -> Vec3 {
    irradiance_at_f64(b.as_dvec3(), rho, e)
}

/// H from a radiosity `b` kept in f64 (as the solvers keep it), reflectance `rho` and
/// emitted radiosity `e`, rounded to f32 once at the end: an emitter's H is small beside
/// its E, and B rounded to f32 first would lose its digits. A channel with ρ = 0 reflects
/// nothing, so its H is unknown and does not matter: 0.
pub fn irradiance_at_f64(b: DVec3, rho: Vec3, e: Vec3) -> Vec3 {
    let rho = rho.as_dvec3();
    let h = (b - e.as_dvec3()) / rho;
    DVec3::select(rho.cmpgt(DVec3::ZERO), h.max(DVec3::ZERO), DVec3::ZERO).as_vec3()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reflecting_h_gives_back_b() {
        let (rho, e, h) = (
            Vec3::new(0.5, 0.0, 0.9),
            Vec3::new(1.0, 2.0, 0.0),
            Vec3::splat(3.0),
        );
        let b = e + rho * h;
        let got = irradiance(&[b], &[rho], &[e])[0];
        assert!(
            (got - Vec3::new(3.0, 0.0, 3.0)).abs().max_element() < 1e-6,
            "{got}"
        );
    }
}
