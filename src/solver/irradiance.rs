//! The irradiance behind a solution: B = E + ρ H per element, so H = (B − E) / ρ.
//!
//! The display puts textures under the light (displayed radiance = albedo(uv) · H / π +
//! L_e(uv)), so it reconstructs H, which is smooth across triangles of different texture
//! means, rather than B, which jumps with them.

use glam::Vec3;

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

/// H from one radiosity `b`, reflectance `rho` and emitted radiosity `e`. A channel with
/// ρ = 0 reflects nothing, so its H is unknown and does not matter: 0.
pub fn irradiance_at(b: Vec3, rho: Vec3, e: Vec3) -> Vec3 {
    let h = (b - e) / rho;
    Vec3::select(rho.cmpgt(Vec3::ZERO), h.max(Vec3::ZERO), Vec3::ZERO)
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
