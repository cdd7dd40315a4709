//! The source term of every method: E'_i = E_i + ρ_i h_i, the element's emitted radiosity
//! plus the first bounce of the external lights (punctual lights, sun, sky; see
//! [`crate::light::direct`]), computed in parallel chunks before the iterations start.

use super::{Method, Phase, Solver};
use crate::accel::Bvh;
use crate::light::{ExternalLight, direct};
use crate::mesh::Mesh;
use crate::solver::form_factor;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// The first-bounce irradiance factor h_i of the external lights (punctual, sun, sky) at
/// element `i`, so that E'_i = E_i + ρ_i h_i, and the rays cast; zero without external
/// light. Seeded by the element's geometry.
pub(super) fn external_factor(
    mesh: &Mesh,
    bvh: &Bvh,
    external: &ExternalLight,
    i: usize,
) -> (Vec3, u32) {
    if external.is_empty() {
        return (Vec3::ZERO, 0);
    }
    let e = &mesh.elements[i];
    let p = &mesh.patches[e.patch as usize];
    let (h, rays) = direct::element_irradiance(
        &mesh.frame(),
        bvh,
        external,
        (e.centroid(), e.normal, p.scene_triangle),
        form_factor::element_seed(e),
    );
    (if h.is_finite() { h } else { Vec3::ZERO }, rays)
}

impl Solver {
    /// Elements per parallel chunk: large enough to amortise scheduling, small enough to
    /// return within a step budget.
    pub(super) const CHUNK: usize = 256;

    pub(super) fn lighting_chunk(&mut self, next: usize) {
        let n = self.mesh.elements.len();
        let end = (next + Self::CHUNK * rayon::current_num_threads().max(1) * 4).min(n);
        let mesh = &self.mesh;
        let bvh = &self.bvh;
        let external = &self.external;
        let (reflectance, emission) = (&self.reflectance, &self.emission);
        let results: Vec<(Vec3, u32)> = (next..end)
            .into_par_iter()
            .with_min_len(16)
            .map(|i| external_factor(mesh, bvh, external, i))
            .collect();
        for (k, (h, rays)) in results.into_iter().enumerate() {
            let i = next + k;
            let s = emission[i] + reflectance[i] * h;
            let s = if s.is_finite() { s } else { Vec3::ZERO };
            self.external_in[i] = h;
            self.gathered[i] = DVec3::ZERO;
            self.source[i] = s;
            self.radiosity[i] = s.as_dvec3();
            self.unshot[i] = s.as_dvec3();
            self.stats.rays += rays as u64;
        }
        if end < n {
            self.phase = Phase::Lighting(end);
            return;
        }
        self.update_source_power();
        self.phase = match self.settings.method {
            Method::Progressive | Method::StochasticJacobi | Method::Hierarchical => {
                Phase::Iterating
            }
            _ => Phase::Rows(0),
        };
        if self.power_scale <= 0.0 {
            // No light at all: the solution is zero and already exact.
            self.stats.unshot_fraction = Some(0.0);
            self.stats.residual = Some(0.0);
            self.phase = Phase::Done;
        }
    }
}
