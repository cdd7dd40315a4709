//! Gathering (Cohen & Greenberg 1985): Jacobi and Gauss–Seidel sweeps over the stored
//! rows of F, B_i ← E'_i + ρ_i Σ_p F_ip B̄_p; stop on the relative residual.

use super::{Phase, Solver, Sparse, sum3d};
use crate::solver::form_factor::element_to_patch;
use glam::DVec3;
use rayon::prelude::*;
use std::sync::Arc;

impl Solver {
    pub(super) fn rows_chunk(&mut self, next: usize) {
        let n = self.mesh.elements.len();
        let m = self.mesh.patches.len();
        // About 64k element–patch pairs per thread per chunk.
        let per_thread = (65_536 / m.max(1)).max(1);
        let end = (next + per_thread * rayon::current_num_threads().max(1)).min(n);
        let mesh = &self.mesh;
        let bvh = &self.bvh;
        let ff = self.settings.form_factors;
        let rows: Vec<(Sparse, u64)> = (next..end)
            .into_par_iter()
            .map(|i| {
                let mut row = Vec::new();
                let mut rays = 0u64;
                for p in 0..m {
                    let (f, r) = element_to_patch(mesh, bvh, i, p, &ff);
                    rays += r as u64;
                    if f > 0.0 {
                        row.push((p as u32, f));
                    }
                }
                (Arc::from(row), rays)
            })
            .collect();
        for (row, rays) in rows {
            self.rows.push(row);
            self.stats.rays += rays;
        }
        self.phase = if end < n {
            Phase::Rows(end)
        } else {
            Phase::Iterating
        };
    }

    /// Gathered radiosity E'_i + ρ_i Σ_p F_ip B̄_p for element i.
    pub(super) fn gather(&self, i: usize, means: &[DVec3]) -> DVec3 {
        let mut h = DVec3::ZERO;
        for &(p, f) in self.rows[i].iter() {
            h += means[p as usize] * f as f64;
        }
        self.source[i].as_dvec3() + self.reflectance[i].as_dvec3() * h
    }

    pub(super) fn finish_sweep(&mut self, residual: f64) {
        let r = residual / self.power_scale;
        self.stats.residual = Some(r);
        self.stats.iterations += 1;
        if r <= self.settings.tolerance {
            self.phase = Phase::Done;
            self.stats.energy_balance = Some(self.gathered_balance());
        }
    }

    pub(super) fn jacobi_sweep(&mut self) {
        let means = self.patch_means(&self.radiosity);
        let next: Vec<DVec3> = (0..self.radiosity.len())
            .into_par_iter()
            .map(|i| self.gather(i, &means))
            .collect();
        let residual: f64 = next
            .iter()
            .zip(&self.radiosity)
            .zip(&self.mesh.elements)
            .map(|((a, b), e)| sum3d((*a - *b).abs()) * e.area as f64)
            .sum();
        self.radiosity = next;
        self.finish_sweep(residual);
    }

    pub(super) fn gauss_seidel_sweep(&mut self) {
        let mut means = self.patch_means(&self.radiosity);
        let mut residual = 0.0;
        for i in 0..self.radiosity.len() {
            let new = self.gather(i, &means);
            let e = &self.mesh.elements[i];
            let delta = new - self.radiosity[i];
            residual += sum3d(delta.abs()) * e.area as f64;
            let p = e.patch as usize;
            means[p] += delta * (e.area / self.mesh.patches[p].area) as f64;
            self.radiosity[i] = new;
        }
        self.finish_sweep(residual);
    }

    /// Light arriving at surfaces over light leaving them, from the stored rows:
    /// Σ_i A_i Σ_p F_ip B̄_p / Σ_p A_p B̄_p.
    pub(super) fn gathered_balance(&self) -> f64 {
        let means = self.patch_means(&self.radiosity);
        let leaving: f64 = means
            .iter()
            .zip(&self.mesh.patches)
            .map(|(b, p)| sum3d(*b) * p.area as f64)
            .sum();
        let arriving: f64 = self
            .rows
            .iter()
            .zip(&self.mesh.elements)
            .map(|(row, e)| {
                row.iter()
                    .map(|&(p, f)| sum3d(means[p as usize]) * f as f64)
                    .sum::<f64>()
                    * e.area as f64
            })
            .sum();
        if leaving > 0.0 {
            arriving / leaving
        } else {
            1.0
        }
    }
}
