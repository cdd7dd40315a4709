//! Progressive refinement (Cohen, Chen, Wallace & Greenberg, "A progressive refinement
//! approach to fast radiosity image generation", SIGGRAPH 1988): shoot the patch with the
//! most unshot power through its cached form-factor column; the ambient term for display.

use super::{Method, Phase, Solver, Sparse, sum3d};
use crate::cancel::{Cancelled, check};
use crate::solver::form_factor::element_to_patch;
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

impl Solver {
    /// Cohen et al. 1988's ambient term: the unshot radiosity spread uniformly and reflected
    /// by the average reflectance, R · Σ ΔB_i A_i / Σ A_i with R = 1 / (1 − ρ_avg). Add
    /// ρ_i × this to B_i for display; it fades to zero as the solve converges.
    pub fn ambient(&self) -> Vec3 {
        if self.settings.method != Method::Progressive || self.phase == Phase::Done {
            return Vec3::ZERO;
        }
        let mut area = 0.0f64;
        let mut rho = DVec3::ZERO;
        let mut unshot = DVec3::ZERO;
        for (i, e) in self.mesh.elements.iter().enumerate() {
            let a = e.area as f64;
            area += a;
            rho += self.reflectance[i].as_dvec3() * a;
            unshot += self.unshot[i] * a;
        }
        if area <= 0.0 {
            return Vec3::ZERO;
        }
        let r = (DVec3::ONE - rho / area).max(DVec3::splat(1e-3)).recip();
        (r * unshot / area).as_vec3()
    }

    /// The form-factor column of patch `p`: (element, F_ip) for every element that sees it,
    /// sorted by element; from the cache when it is there. Computed in blocks of elements,
    /// checking `cancel` between them.
    pub(super) fn column(&mut self, p: usize, cancel: &AtomicBool) -> Result<Sparse, Cancelled> {
        if let Some(c) = &self.columns[p] {
            return Ok(c.clone());
        }
        let mut col = Vec::new();
        let mut rays = 0;
        let n = self.mesh.elements.len();
        for start in (0..n).step_by(Self::COLUMN_BLOCK) {
            check(cancel)?;
            let end = (start + Self::COLUMN_BLOCK).min(n);
            rays += self.column_block(p, start..end, &mut col);
        }
        self.stats.rays += rays;
        let col: Sparse = Arc::from(col);
        let bytes = col.len() * std::mem::size_of::<(u32, f32)>();
        if self.cache_used + bytes <= self.settings.cache_bytes {
            self.cache_used += bytes;
            self.columns[p] = Some(col.clone());
        }
        Ok(col)
    }

    /// Receivers per block of a column between cancel checks: about a tenth of a second of
    /// shadow rays on one core at worst.
    const COLUMN_BLOCK: usize = 1 << 15;

    /// Appends F_ip of the elements in `range` to `col` (in element order) and returns the
    /// rays cast.
    fn column_block(
        &self,
        p: usize,
        range: std::ops::Range<usize>,
        col: &mut Vec<(u32, f32)>,
    ) -> u64 {
        let mesh = &self.mesh;
        let bvh = &self.bvh;
        let ff = self.settings.form_factors;
        let shooter = &mesh.patches[p];
        let parts: Vec<(Vec<(u32, f32)>, u64)> = range
            .into_par_iter()
            .with_min_len(Self::CHUNK)
            .fold(
                || (Vec::new(), 0u64),
                |(mut v, mut rays), i| {
                    // Cheap rejection before the exact form factor: receivers behind the
                    // shooter's plane see nothing of it.
                    let e = &mesh.elements[i];
                    if shooter.normal.dot(e.centroid() - shooter.verts[0]) > 0.0 {
                        let (f, r) = element_to_patch(mesh, bvh, i, p, &ff);
                        rays += r as u64;
                        if f > 0.0 {
                            v.push((i as u32, f));
                        }
                    }
                    (v, rays)
                },
            )
            .collect();
        // rayon's fold/collect keeps the index order of the pieces, so `col` stays sorted.
        let mut rays = 0;
        for (v, r) in parts {
            col.extend(v);
            rays += r;
        }
        rays
    }

    /// One progressive-refinement shot: from the patch with the most unshot power while
    /// the unshot fraction is above the tolerance; then from the patch with the most
    /// unshot radiosity ΔB̄_p (W/m²) until none is above the tolerance times the mean
    /// radiosity. The first criterion bounds the error in power, which is what the scene
    /// as a whole is short of; the second bounds it at every receiver, since patch p's
    /// unshot part would add at most ρ_i F_ip ΔB̄_p ≤ ΔB̄_p to element i: a sliver or a
    /// tiny patch has little power but can fill half the hemisphere of the elements beside
    /// it, and without the second criterion it would never shoot.
    /// `Err(Cancelled)` leaves the solve as it was (the column is computed first).
    pub(super) fn shoot(&mut self, cancel: &AtomicBool) -> Result<(), Cancelled> {
        let mesh = Arc::clone(&self.mesh);
        let (mut best, mut best_power, mut total) = (usize::MAX, 0.0f64, 0.0f64);
        let (mut densest, mut densest_unshot) = (usize::MAX, 0.0f64);
        let (mut radiosity, mut area) = (0.0f64, 0.0f64);
        for (pi, p) in mesh.patches.iter().enumerate() {
            // Signed unshot radiosity (after an edit) is shot like positive: by magnitude.
            let mut power = 0.0;
            for i in p.elements.clone() {
                let a = mesh.elements[i as usize].area as f64;
                power += sum3d(self.unshot[i as usize].abs()) * a;
                radiosity += sum3d(self.radiosity[i as usize].abs()) * a;
                area += a;
            }
            total += power;
            if power > best_power {
                best_power = power;
                best = pi;
            }
            let unshot = power / p.area as f64;
            if unshot > densest_unshot {
                densest_unshot = unshot;
                densest = pi;
            }
        }
        let fraction = total / self.power_scale;
        self.stats.unshot_fraction = Some(fraction);
        self.stats.residual = Some(fraction);
        if fraction <= self.settings.tolerance || best == usize::MAX {
            let mean = if area > 0.0 { radiosity / area } else { 0.0 };
            if densest == usize::MAX || densest_unshot <= self.settings.tolerance * mean {
                self.phase = Phase::Done;
                return Ok(());
            }
            best = densest;
        }
        let column = self.column(best, cancel)?;
        let p = &mesh.patches[best];
        let mut shot = DVec3::ZERO;
        for i in p.elements.clone() {
            shot += self.unshot[i as usize] * mesh.elements[i as usize].area as f64;
            self.unshot[i as usize] = DVec3::ZERO;
        }
        let shot = shot / p.area as f64;
        self.shot_total[best] += shot;
        let mut captured = 0.0f64;
        for &(i, f) in column.iter() {
            let i = i as usize;
            let g = shot * f as f64;
            self.gathered[i] += g;
            let d = self.reflectance[i].as_dvec3() * g;
            self.radiosity[i] += d;
            self.unshot[i] += d;
            captured += f as f64 * mesh.elements[i].area as f64;
        }
        let shot_power = sum3d(shot.abs()) * p.area as f64;
        self.shot_power += shot_power;
        self.captured_power += captured / p.area as f64 * shot_power;
        self.stats.energy_balance = Some(self.captured_power / self.shot_power);
        self.stats.iterations += 1;
        Ok(())
    }
}
