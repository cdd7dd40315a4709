//! Live material edits (Chen, "Incremental radiosity", Graphics Gems II, 1991): a
//! reflectance or emission change becomes signed unshot radiosity that the solve carries.

use super::{Method, PatchEdit, Phase, Solver, sum3d};
use crate::mesh::sanitize;
use glam::{DVec3, Vec3};
use std::sync::Arc;

impl Solver {
    /// Changes the reflectance and emitted radiosity of some patches without restarting:
    /// Chen's incremental radiosity ("Incremental radiosity", Graphics Gems II, 1991). With
    /// H_i the radiosity gathered by element i so far, B_i = E'_i + ρ_i H_i, so the edit
    /// changes B_i by ΔE'_i + Δρ_i H_i; that difference is added to B_i and to its *signed*
    /// unshot radiosity, and progressive shooting carries it (positive or negative) to the
    /// rest of the scene. The gathering methods keep their current B as the starting guess
    /// and sweep again; the direct method solves again from its stored rows; stochastic
    /// Jacobi, whose sources must be positive, starts over.
    ///
    /// The hierarchical method takes the same step on the edited elements at once (B_i =
    /// E'_i + ρ_i H_i with the new values, a Gauss–Seidel update of just those elements);
    /// the sweeps carry the change on. H_i is what the current B_i says was gathered
    /// ([`Solver::gathered_now`]), so the edit's first solution has every element's
    /// irradiance as it was and the display can keep its vertex data.
    ///
    /// Returns whether the solution already shows the edit (on the edited elements, before
    /// any further step): true for the progressive and hierarchical methods.
    pub fn edit_patches(&mut self, edits: &[PatchEdit]) -> bool {
        let mesh = Arc::clone(&self.mesh);
        let lit = match self.phase {
            Phase::Lighting(next) => next,
            _ => mesh.elements.len(),
        };
        let incremental = self.settings.method == Method::Progressive;
        let local = incremental || self.settings.method == Method::Hierarchical;
        // The change of Σ A E' over the edited elements (a whole sum would cost a pass over
        // every element of the scene for each edit).
        let mut power_change = 0.0f64;
        let mut edited = Vec::with_capacity(edits.len());
        for edit in edits {
            let Some(patch) = mesh.patches.get(edit.patch as usize) else {
                continue;
            };
            edited.push(edit.patch);
            // Transported as at the start (`Mesh::opacity`).
            let opacity = mesh.opacity(patch);
            let rho = sanitize(edit.reflectance).min(Vec3::splat(0.999)) * opacity;
            let emission = sanitize(edit.emission) * opacity;
            for i in patch.elements.clone() {
                let i = i as usize;
                let old_rho = self.reflectance[i];
                self.reflectance[i] = rho;
                self.emission[i] = emission;
                if i >= lit {
                    continue; // its source is computed later, with the new values
                }
                let s = emission + rho * self.external_in[i];
                let h = self.gathered_now(i, old_rho);
                let ds = (s - self.source[i]).as_dvec3();
                power_change += sum3d(ds) * mesh.elements[i].area as f64;
                self.source[i] = s;
                if local {
                    let delta = ds + (rho - old_rho).as_dvec3() * h;
                    self.radiosity[i] += delta;
                    if incremental {
                        self.unshot[i] += delta;
                    }
                } else if matches!(self.phase, Phase::Lighting(_)) {
                    self.radiosity[i] = s.as_dvec3();
                    self.unshot[i] = s.as_dvec3();
                }
            }
        }
        if matches!(self.phase, Phase::Lighting(_)) {
            return false; // the source power is summed when lighting finishes
        }
        let power = self.stats.source_power + power_change;
        // What rounding leaves of a sum that should be zero (every light turned off).
        let rounding = 1e-9 * self.power_scale.max(self.stats.source_power);
        self.stats.source_power = if power <= rounding { 0.0 } else { power };
        self.power_scale = self.power_scale.max(self.stats.source_power);
        self.stats.converged = false;
        match self.settings.method {
            Method::StochasticJacobi => {
                // Restart: its sources cannot be negative.
                self.pending = None;
                for i in 0..mesh.elements.len() {
                    self.radiosity[i] = self.source[i].as_dvec3();
                    self.unshot[i] = self.source[i].as_dvec3();
                }
                self.shot_power = 0.0;
                self.captured_power = 0.0;
                self.phase = Phase::Iterating;
            }
            _ => {
                if self.phase == Phase::Done {
                    self.phase = Phase::Iterating;
                }
                self.hierarchy_edited(&edited);
            }
        }
        if self.power_scale <= 0.0 {
            self.phase = Phase::Done;
            self.stats.converged = true;
        }
        local
    }

    /// What element `i` gathered according to its current solution, H = (B − S)/ρ with
    /// `rho` the reflectance B was made with (S = E + ρ H_external); the last sweep's H
    /// where a channel reflects nothing. The two differ on the hierarchical method, whose
    /// B is Anderson's step from the sweeps rather than the last sweep itself: by less
    /// than the tolerance once converged, yet an edit that used the sweep's H moved the
    /// irradiance of its elements by that much (4.7·10⁻⁶ on the Cornell box) and the
    /// display fitted its vertex data again.
    fn gathered_now(&self, i: usize, rho: Vec3) -> DVec3 {
        let (b, s, swept) = (
            self.radiosity[i],
            self.source[i].as_dvec3(),
            self.gathered[i],
        );
        let implied = (b - s) / rho.as_dvec3();
        DVec3::select(rho.as_dvec3().cmpgt(DVec3::ZERO), implied, swept)
    }
}
