//! Stochastic Jacobi radiosity: rays instead of form factors, for large scenes.
//!
//! Each iteration shoots *all* unshot power at once with a fixed number of rays (Neumann,
//! Feda, Kopp & Tobler, "A new stochastic radiosity method for highly complex scenes", 1994;
//! Bekaert, Neumann, Willems et al., "Hierarchical Monte Carlo radiosity", 1998): a ray
//! starts on element i with probability ∝ A_i |ΔB_i|, at a uniform point, in a
//! cosine-distributed direction, and carries an equal share of the total unshot power; the
//! element it hits first receives ρ_j × (that power) / A_j of new unshot radiosity. The
//! expected transfer equals the deterministic Jacobi shooting step, so the iteration is an
//! unbiased estimate of it, at a cost set by the ray count instead of elements × patches.
//!
//! Good at: huge scenes (Sponza) where one deterministic shot costs O(N) form factors; each
//! iteration removes a factor ≈ ρ_avg of the unshot power. Poor at: per-element accuracy,
//! which is noisy (standard error ∝ 1/√(rays hitting the element)).
//!
//! Partly transmissive surfaces (alpha cut-outs, glass) keep a share τ of the ray's power
//! going and absorb-or-reflect the rest, so shadows of foliage are partial, as with the
//! deterministic form factors.

use super::{Phase, Solver};
use crate::accel::Bvh;
use crate::geometry::orthonormal_basis;
use crate::geometry::sampling::{cosine_direction, hash, point_in_triangle, unit};
use crate::mesh::Mesh;
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use std::sync::Arc;

/// Rays per parallel chunk; chunks are reduced in order, so results do not depend on the
/// thread count.
pub const CHUNK_RAYS: usize = 16_384;
/// Most surfaces a ray may pass through (transmissive ones) before it is dropped.
const MAX_HITS: usize = 8;

/// The deposits of one chunk of rays: (element, unshot radiosity added) and the power that
/// reached any element, summed over RGB.
pub struct Deposits {
    pub added: Vec<(u32, DVec3)>,
    pub arrived: f64,
}

/// Sampling table for ray origins: cumulative A_i |ΔB_i| over elements.
pub struct Sources {
    cdf: Vec<f64>,
    pub total: f64,
}

impl Sources {
    /// Builds the table from the current unshot radiosity.
    pub fn new(mesh: &Mesh, unshot: &[DVec3]) -> Sources {
        let mut cdf = Vec::with_capacity(unshot.len());
        let mut total = 0.0;
        for (e, u) in mesh.elements.iter().zip(unshot) {
            total += (u.x + u.y + u.z).max(0.0) * e.area as f64;
            cdf.push(total);
        }
        Sources { cdf, total }
    }
}

/// Traces rays `first..first + count` of iteration `iteration` (seeded by both).
// The arguments are the read-only inputs of one independent chunk of work; bundling them
// into a struct would only move the list.
#[allow(clippy::too_many_arguments)]
pub fn trace_chunk(
    mesh: &Mesh,
    bvh: &Bvh,
    reflectance: &[Vec3],
    unshot: &[DVec3],
    sources: &Sources,
    rays_total: usize,
    first: usize,
    count: usize,
    iteration: u64,
) -> Deposits {
    let mut out = Deposits {
        added: Vec::with_capacity(count),
        arrived: 0.0,
    };
    if sources.total <= 0.0 || rays_total == 0 {
        return out;
    }
    let share = sources.total / rays_total as f64;
    let eps = mesh.epsilon();
    for r in first..first + count {
        let h = hash((iteration << 40) ^ r as u64);
        let x = unit(h) as f64 * sources.total;
        let i = sources
            .cdf
            .partition_point(|c| *c < x)
            .min(sources.cdf.len() - 1);
        let u = unshot[i];
        let s = u.x + u.y + u.z;
        if s <= 0.0 {
            continue;
        }
        let e = &mesh.elements[i];
        let patch = &mesh.patches[e.patch as usize];
        // Uniform point on the element, cosine-weighted direction (Malley's method).
        let origin = point_in_triangle(&e.verts, unit(hash(h ^ 0x51)), unit(hash(h ^ 0xA3)));
        let (r1, r2) = (unit(hash(h ^ 0x1F3)), unit(hash(h ^ 0x2E7)));
        let dir = cosine_direction(e.normal, orthonormal_basis(e.normal), r1, r2);
        let mut power = u * (share / s);
        let mut from = origin + e.normal * eps;
        let mut skip = patch.scene_triangle;
        for _ in 0..MAX_HITS {
            let Some(hit) = bvh.closest_hit(from, dir, 0.0, f32::INFINITY, skip) else {
                break;
            };
            let p = from + dir * hit.t;
            let tau = mesh
                .transmittance
                .get(hit.triangle as usize)
                .copied()
                .unwrap_or(0.0) as f64;
            if let Some(j) = mesh.element_at(hit.triangle, p, -dir) {
                let j = j as usize;
                let absorbed = power * (1.0 - tau);
                out.arrived += absorbed.x + absorbed.y + absorbed.z;
                // Its covered share takes `absorbed` and reflects ρ (1 − τ) · power per unit
                // of the element's area: `reflectance` holds ρ (1 − τ) (`Mesh::opacity`).
                let add = reflectance[j].as_dvec3() * power / mesh.elements[j].area as f64;
                if add.max_element() > 0.0 {
                    out.added.push((j as u32, add));
                }
            }
            if tau <= 0.0 {
                break;
            }
            power *= tau;
            from = p;
            skip = hit.triangle;
        }
    }
    out
}

/// A stochastic Jacobi iteration split over several steps.
pub(super) struct Pending {
    sources: Sources,
    rays: usize,
    next_chunk: usize,
    added: Vec<DVec3>,
    arrived: f64,
}

impl Solver {
    /// Traces a few chunks of the current stochastic iteration; finishes it when all its
    /// rays are done.
    pub(super) fn stochastic_chunk(&mut self) {
        let mesh = Arc::clone(&self.mesh);
        let n = mesh.elements.len();
        let pending = match self.pending.take() {
            Some(p) => p,
            None => {
                let sources = Sources::new(&mesh, &self.unshot);
                let fraction = sources.total / self.power_scale;
                self.stats.unshot_fraction = Some(fraction);
                self.stats.residual = Some(fraction);
                if fraction <= self.settings.tolerance {
                    self.phase = Phase::Done;
                    return;
                }
                Pending {
                    sources,
                    rays: self
                        .settings
                        .stochastic_rays
                        .unwrap_or((16 * n).max(1 << 18)),
                    next_chunk: 0,
                    added: vec![DVec3::ZERO; n],
                    arrived: 0.0,
                }
            }
        };
        let mut p = pending;
        let chunks = p.rays.div_ceil(CHUNK_RAYS);
        let end = (p.next_chunk + 2 * rayon::current_num_threads().max(1)).min(chunks);
        let iteration = self.stats.iterations;
        let (bvh, refl, unshot, src, rays) = (
            &self.bvh,
            &self.reflectance,
            &self.unshot,
            &p.sources,
            p.rays,
        );
        let parts: Vec<Deposits> = (p.next_chunk..end)
            .into_par_iter()
            .map(|c| {
                let first = c * CHUNK_RAYS;
                let count = CHUNK_RAYS.min(rays - first);
                trace_chunk(&mesh, bvh, refl, unshot, src, rays, first, count, iteration)
            })
            .collect();
        for part in parts {
            p.arrived += part.arrived;
            for (j, add) in part.added {
                p.added[j as usize] += add;
            }
        }
        let traced = (end * CHUNK_RAYS).min(p.rays) - p.next_chunk * CHUNK_RAYS;
        self.stats.rays += traced as u64;
        p.next_chunk = end;
        if end < chunks {
            self.pending = Some(p);
            return;
        }
        for (i, add) in p.added.iter().enumerate() {
            self.radiosity[i] += *add;
        }
        self.unshot = p.added;
        self.shot_power += p.sources.total;
        self.captured_power += p.arrived;
        self.stats.energy_balance = Some(self.captured_power / self.shot_power);
        self.stats.iterations += 1;
    }
}
