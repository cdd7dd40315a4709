//! A-posteriori adaptive subdivision of a converged solve: mark elements by contrast, by
//! reconstruction error and by changing visibility of the main lights, split them, and
//! carry the solve over to the new mesh without losing or creating light.

use super::{Method, Phase, Solver, Sparse, external_factor, sum3, sum3d};
use crate::cancel::{Cancelled, check};
use crate::light::Punctual;
use crate::mesh::{LightTargets, Mesh, Moved};
use crate::solver::form_factor::element_to_patch;
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

/// Per-element values carried through a refinement: children start from their parent's.
/// A refined element's re-evaluation: external irradiance factor h, gathered H, its
/// form factors to the patches needed, rays cast.
type Evaluated = (Vec3, DVec3, Vec<(u32, f32)>, u64);

fn remap<T: Copy + Default>(v: &[T], moved: &[Moved], n: usize) -> Vec<T> {
    let mut out = vec![T::default(); n];
    for (old, m) in moved.iter().enumerate() {
        match m {
            Moved::Kept(k) => out[*k as usize] = v[old],
            Moved::Split(kids) => kids.iter().for_each(|k| out[*k as usize] = v[old]),
        }
    }
    out
}

/// The new elements of a refinement, in order.
pub(super) fn split_children(moved: &[Moved]) -> Vec<u32> {
    moved
        .iter()
        .flat_map(|m| match m {
            Moved::Split(kids) => kids.to_vec(),
            Moved::Kept(_) => Vec::new(),
        })
        .collect()
}

impl Solver {
    /// Carries every per-element array over a refinement of the mesh to `n` elements
    /// (children start from their parent's values).
    pub(super) fn carry_elements(&mut self, moved: &[Moved], n: usize) {
        self.radiosity = remap(&self.radiosity, moved, n);
        self.unshot = remap(&self.unshot, moved, n);
        self.gathered = remap(&self.gathered, moved, n);
        self.source = remap(&self.source, moved, n);
        self.reflectance = remap(&self.reflectance, moved, n);
        self.emission = remap(&self.emission, moved, n);
        if !self.opacity.is_empty() {
            self.opacity = remap(&self.opacity, moved, n);
        }
        self.external_in = remap(&self.external_in, moved, n);
    }

    /// One pass of a-posteriori adaptive subdivision on a converged solve (see
    /// [`crate::mesh::AdaptiveSettings`]); returns whether the mesh changed (`Err(Cancelled)`: it did not), in which case
    /// the solve goes on from where it was.
    ///
    /// New elements are re-evaluated, not interpolated: progressive refinement gathers
    /// each child's radiosity from everything already shot (H_c = Σ_p F_cp · Σ ΔB̄_p, the
    /// patches' shot totals), and the child's unshot radiosity keeps the parent's plus the
    /// difference, so for every patch Σ A_i (B_i − ΔB_i) still equals what it has shot:
    /// refinement neither creates nor loses energy. The gathering methods compute the
    /// children's rows and sweep again from the parent's values; the direct method solves
    /// again; stochastic Jacobi carries the parent's values.
    pub(super) fn refine(&mut self, cancel: &AtomicBool) -> Result<bool, Cancelled> {
        let Some(a) = self.settings.adaptive.clone() else {
            return Ok(false);
        };
        if self.settings.method == Method::Hierarchical {
            return Ok(false); // it refines its own hierarchy (see `hierarchical`)
        }
        if self.refine_passes >= a.max_passes || self.stats.source_power <= 0.0 {
            return Ok(false);
        }
        let min_size = a.min_size.unwrap_or(self.mesh.element_size / 8.0);
        let values = self.radiosity();
        let mut marked = self
            .mesh
            .mark_for_refinement(&values, a.threshold, min_size);
        self.mark_visibility_changes(&mut marked, min_size);
        self.mesh.balance(&mut marked);
        let count = marked.iter().filter(|m| **m).count();
        if count == 0 || self.mesh.elements.len() + 3 * count > a.max_elements {
            return Ok(false);
        }
        check(cancel)?;
        let mut mesh = (*self.mesh).clone();
        let moved = mesh.refine(&marked);
        mesh.mark_hard_shadows(&self.bvh, &self.external, min_size);
        let mesh = Arc::new(mesh);
        let n = mesh.elements.len();
        let children = split_children(&moved);
        let had_rows = !self.rows.is_empty();
        // The children are evaluated before anything changes, so a cancelled pass leaves
        // the solve as it was.
        let evaluated = self.evaluate_children(&mesh, &children, had_rows, cancel)?;
        self.refine_passes += 1;
        self.carry_elements(&moved, n);
        let mut old_rows = std::mem::take(&mut self.rows);
        self.mesh = mesh;
        self.pending = None;
        let old_columns = std::mem::replace(&mut self.columns, vec![None; self.mesh.patches.len()]);
        self.cache_used = 0;
        let progressive = self.settings.method == Method::Progressive;
        if had_rows {
            let mut rows: Vec<Sparse> = vec![Arc::from(Vec::new()); n];
            for (old, m) in moved.iter().enumerate() {
                if let Moved::Kept(k) = m {
                    rows[*k as usize] =
                        std::mem::replace(&mut old_rows[old], Arc::from(Vec::new()));
                }
            }
            self.rows = rows;
        }
        // Cached form-factor columns survive: kept elements keep their F (their rays are
        // seeded by geometry, not index), and the children's F to every patch that has shot
        // were just computed. Columns of patches not yet shot are dropped (computed again
        // when they shoot).
        let mut child_entries: Vec<Vec<(u32, f32)>> = vec![Vec::new(); self.mesh.patches.len()];
        for (&c, (_, _, row, _)) in children.iter().zip(&evaluated) {
            for &(q, f) in row {
                child_entries[q as usize].push((c, f));
            }
        }
        for (q, col) in old_columns.into_iter().enumerate() {
            let Some(col) = col else { continue };
            if !self.needs_form_factors(q, had_rows) {
                continue;
            }
            let mut new: Vec<(u32, f32)> = col
                .iter()
                .filter_map(|&(i, f)| match moved[i as usize] {
                    Moved::Kept(k) => Some((k, f)),
                    Moved::Split(_) => None,
                })
                .collect();
            new.extend_from_slice(&child_entries[q]);
            new.sort_unstable_by_key(|e| e.0);
            let bytes = new.len() * std::mem::size_of::<(u32, f32)>();
            if self.cache_used + bytes <= self.settings.cache_bytes {
                self.cache_used += bytes;
                self.columns[q] = Some(Arc::from(new));
            }
        }
        for (&c, (h, gathered, row, rays)) in children.iter().zip(evaluated) {
            let c = c as usize;
            self.stats.rays += rays;
            let s = self.emission[c] + self.reflectance[c] * h;
            self.external_in[c] = h;
            self.source[c] = s;
            if had_rows {
                self.rows[c] = Arc::from(row);
            }
            if progressive {
                let b = s.as_dvec3() + self.reflectance[c].as_dvec3() * gathered;
                self.unshot[c] += b - self.radiosity[c];
                self.radiosity[c] = b;
                self.gathered[c] = gathered;
            }
        }
        self.stats.elements = n;
        self.update_source_power();
        self.stats.converged = false;
        self.mesh_version += 1;
        self.phase = Phase::Iterating;
        Ok(true)
    }

    /// Marks elements across which the visibility of a main light source changes: shadow
    /// rays from the element's three corners to the source disagree (a shadow or penumbra
    /// boundary, or a contact line where another surface touches it). Sources: punctual and
    /// directional lights, the sun, and the patches that carry most of the light (up to
    /// 8, each at least 1 % of the total: shot power for progressive refinement, emitted
    /// power otherwise), seen at their centroids. Such elements are split down to the
    /// minimum size, so hard shadows come out as sharp as it allows.
    pub(super) fn mark_visibility_changes(&self, marked: &mut [bool], min_size: f64) {
        let mesh = &self.mesh;
        let eps = mesh.epsilon();
        let mut targets = LightTargets::punctual(mesh, &self.external);
        let power: Vec<f64> = mesh
            .patches
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let b = if self.settings.method == Method::Progressive {
                    sum3d(self.shot_total[i])
                } else {
                    sum3(p.emission)
                };
                b.abs() * p.area as f64
            })
            .collect();
        let total: f64 = power.iter().sum();
        let mut order: Vec<usize> = (0..power.len())
            .filter(|&i| power[i] > 0.01 * total)
            .collect();
        order.sort_by(|&a, &b| power[b].total_cmp(&power[a]));
        for &p in order.iter().take(8) {
            let patch = &mesh.patches[p];
            targets.sources.push((
                Punctual::Point(patch.centroid() + patch.normal * eps),
                patch.scene_triangle,
            ));
        }
        let extra = targets.changes(mesh, &self.bvh, |i| {
            marked[i] || crate::mesh::element_size(&mesh.elements[i]) * 0.5 < min_size * 0.999
        });
        for i in extra {
            marked[i as usize] = true;
        }
    }

    /// Whether refined elements need their form factors to patch `q`: every patch for the
    /// gathering and direct methods (they store rows), the patches that have shot for
    /// progressive refinement.
    fn needs_form_factors(&self, q: usize, had_rows: bool) -> bool {
        had_rows
            || (self.settings.method == Method::Progressive && self.shot_total[q] != DVec3::ZERO)
    }

    /// Re-evaluates the new `children` of `mesh`: per child its external irradiance factor
    /// h, the radiosity H it gathers from everything shot so far, its form factors to the
    /// patches needed, and the rays cast. In blocks, checking `cancel` between them.
    fn evaluate_children(
        &self,
        mesh: &Mesh,
        children: &[u32],
        had_rows: bool,
        cancel: &AtomicBool,
    ) -> Result<Vec<Evaluated>, Cancelled> {
        let (bvh, external, ff) = (&self.bvh, &self.external, self.settings.form_factors);
        let shot_total = &self.shot_total;
        let mut evaluated = Vec::with_capacity(children.len());
        for block in children.chunks(Self::CHILD_BLOCK) {
            check(cancel)?;
            evaluated.par_extend(block.par_iter().map(|&c| {
                let c = c as usize;
                let (h, mut rays) = external_factor(mesh, bvh, external, c);
                let mut gathered = DVec3::ZERO;
                let mut row = Vec::new();
                for (q, total) in shot_total.iter().enumerate() {
                    if !self.needs_form_factors(q, had_rows) {
                        continue;
                    }
                    let (f, r) = element_to_patch(mesh, bvh, c, q, &ff);
                    rays += r;
                    if f > 0.0 {
                        gathered += *total * f as f64;
                        row.push((q as u32, f));
                    }
                }
                (h, gathered, row, rays as u64)
            }));
        }
        Ok(evaluated)
    }

    /// Children per block between cancel checks.
    const CHILD_BLOCK: usize = 4096;
}
