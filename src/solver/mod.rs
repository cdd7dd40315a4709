//! The radiosity solvers and their common step contract.
//!
//! Discrete system (per RGB channel, substructured: elements receive, patches shoot):
//!
//! B_i = E'_i + ρ_i Σ_p F_ip B̄_p,   B̄_p = Σ_{i∈p} A_i B_i / A_p,
//!
//! where E'_i is the element's emitted radiosity plus the first bounce of punctual lights,
//! sun and sky ([`lighting`]), and F_ip the ray-cast form factor from element i to patch p
//! ([`form_factor`]). Every method solves this same system, so they converge to the same
//! answer and [`Method::Direct`] is its exact reference:
//!
//! - [`Method::Progressive`]: progressive refinement (Cohen, Chen, Wallace & Greenberg,
//!   "A progressive refinement approach to fast radiosity image generation", SIGGRAPH 1988):
//!   shoot the patch with the most unshot power; an ambient term for display; stop when the
//!   unshot fraction falls below the tolerance. Form-factor columns are cached.
//! - [`Method::Jacobi`] and [`Method::GaussSeidel`]: gathering sweeps over the stored rows of
//!   F (Cohen & Greenberg 1985); stop on the relative residual.
//! - [`Method::StochasticJacobi`]: all unshot power shot at once by rays
//!   ([`stochastic`]), for scenes too large for form factors; an unbiased, noisy estimate.
//! - [`Method::Direct`]: LU of the reduced M×M patch system (I − P ρ F) B̄ = P E', then
//!   B = E' + ρ F B̄ — exact for the discrete system at O(M³) instead of O(N³).
//!
//! The RenderPark method contract: `Solver::new` initialises, [`Solver::step`] is a short unit
//! of work after which a snapshot may be taken (it checks a cancel flag inside), and
//! [`Solver::stats`] reports. Results do not depend on the thread count: parallel work is
//! per element with per-pair deterministic sampling, and sums are reduced in a fixed order.

mod anderson;
pub mod direct;
mod edits;
pub mod form_factor;
pub mod gather;
mod gathering;
pub mod hemicube;
mod hierarchical;
mod irradiance;
mod progressive;
mod refine;
mod source_term;
pub mod stochastic;
mod types;

pub use hierarchical::{ElementLinks, LinkView};
pub use irradiance::{irradiance, irradiance_at, irradiance_at_f64};
pub use types::{
    HierarchySettings, MAX_DIRECT_PATCHES, MAX_MATRIX_PAIRS, Method, PatchEdit, SolverError,
    SolverSettings, Stats, StepOutcome,
};

use crate::accel::Bvh;
use crate::light::ExternalLight;
use crate::mesh::Mesh;
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use source_term::external_factor;
use std::borrow::Cow;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use stochastic::Pending;
use types::Stop;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    /// Computing E' for elements from this index on.
    Lighting(usize),
    /// Computing form-factor rows from this element on (gathering and direct).
    Rows(usize),
    Iterating,
    Done,
}

type Sparse = Arc<[(u32, f32)]>;

/// A radiosity solve of one mesh.
pub struct Solver {
    mesh: Arc<Mesh>,
    bvh: Arc<Bvh>,
    external: ExternalLight,
    settings: SolverSettings,
    phase: Phase,
    /// E'_i per element.
    source: Vec<Vec3>,
    /// B_i per element. Accumulated in f64: a progressive solve adds thousands of small
    /// increments per element, whose f32 rounding would otherwise cost ~1e-5 relative.
    radiosity: Vec<DVec3>,
    /// Unshot radiosity ΔB_i per element (progressive).
    unshot: Vec<DVec3>,
    /// Form-factor columns per patch: (element, F_ip), cached for progressive shooting.
    columns: Vec<Option<Sparse>>,
    cache_used: usize,
    /// Form-factor rows per element: (patch, F_ip), for gathering and direct.
    rows: Vec<Sparse>,
    /// Reflectance per element (its patch's, or an edit's), times its opacity: what the
    /// solve transports (see `Mesh::opacity`).
    reflectance: Vec<Vec3>,
    /// Emitted radiosity E per element (its patch's, or an edit's), times its opacity.
    emission: Vec<Vec3>,
    /// Opacity per element (`Mesh::opacity`); empty where every element is opaque. The
    /// solve's B, ρ and E are per unit of an element's area; what `radiosity`,
    /// `reflectance` and `emission` report is its covered part's, over its opacity.
    opacity: Vec<f32>,
    /// First-bounce irradiance factor h_i of external light, so E'_i = E_i + ρ_i h_i.
    external_in: Vec<Vec3>,
    /// Progressive: radiosity gathered so far before reflection, H_i = Σ F_ip ΔB̄_p, so that
    /// B_i = E'_i + ρ_i H_i at every moment; hierarchical: each leaf's H of the last sweep.
    /// Chen's incremental edits need it.
    gathered: Vec<DVec3>,
    /// Largest source power seen (the scale for the unshot fraction when an edit turns the
    /// lights off and the source power drops to zero).
    power_scale: f64,
    /// Progressive: everything each patch has shot so far, Σ ΔB̄_p. New elements from a
    /// refinement gather from it, so refining loses no light already shot.
    shot_total: Vec<DVec3>,
    /// Refinement passes done, and a counter that changes whenever the mesh does.
    refine_passes: u32,
    mesh_version: u64,
    /// The stochastic iteration under way.
    pending: Option<Pending>,
    /// The hierarchical method's links and node values (built on its first step).
    hierarchy: Option<hierarchical::Hierarchy>,
    stats: Stats,
    shot_power: f64,
    captured_power: f64,
}

fn sum3(v: Vec3) -> f64 {
    v.x as f64 + v.y as f64 + v.z as f64
}

fn sum3d(v: DVec3) -> f64 {
    v.x + v.y + v.z
}

/// Elements per piece of a parallel pass over the elements, and per chunk of
/// [`ordered_sum`].
const ELEMENT_CHUNK: usize = 4096;

/// Σ f(e) over e in 0..n: each chunk of [`ELEMENT_CHUNK`] elements summed in order, in
/// parallel, then the chunk sums in order, so the result does not depend on the thread
/// count.
fn ordered_sum<T>(n: usize, f: impl Fn(usize) -> T + Sync) -> T
where
    T: Copy + Default + Send + std::ops::Add<Output = T>,
{
    (0..n.div_ceil(ELEMENT_CHUNK))
        .into_par_iter()
        .map(|c| {
            (c * ELEMENT_CHUNK..((c + 1) * ELEMENT_CHUNK).min(n))
                .fold(T::default(), |s, e| s + f(e))
        })
        .collect::<Vec<T>>()
        .into_iter()
        .fold(T::default(), |s, x| s + x)
}

impl Solver {
    /// A solver for `mesh` with visibility from `bvh` and the scene's external `lights`.
    pub fn new(
        mesh: Arc<Mesh>,
        bvh: Arc<Bvh>,
        external: ExternalLight,
        settings: SolverSettings,
    ) -> Result<Solver, SolverError> {
        let (n, m) = (mesh.elements.len(), mesh.patches.len());
        let needs_matrix = matches!(
            settings.method,
            Method::Jacobi | Method::GaussSeidel | Method::Direct
        );
        if needs_matrix && n.saturating_mul(m) > MAX_MATRIX_PAIRS {
            return Err(SolverError::TooLarge {
                method: settings.method,
                elements: n,
                patches: m,
                limit: MAX_MATRIX_PAIRS,
            });
        }
        if settings.method == Method::Direct && m > MAX_DIRECT_PATCHES {
            return Err(SolverError::TooLarge {
                method: settings.method,
                elements: n,
                patches: m,
                limit: MAX_DIRECT_PATCHES * n,
            });
        }
        // What the elements transport: the covered share of a cut-out's area reflects
        // and emits (`Mesh::opacity`).
        let opacity: Vec<f32> = mesh
            .elements
            .iter()
            .map(|e| mesh.opacity(&mesh.patches[e.patch as usize]))
            .collect();
        let (reflectance, emission) = mesh
            .elements
            .iter()
            .zip(&opacity)
            .map(|(e, o)| {
                let patch = &mesh.patches[e.patch as usize];
                (patch.reflectance * *o, patch.emission * *o)
            })
            .unzip();
        let opacity = if opacity.iter().any(|&o| o < 1.0) {
            opacity
        } else {
            Vec::new()
        };
        Ok(Solver {
            emission,
            external_in: vec![Vec3::ZERO; n],
            gathered: vec![DVec3::ZERO; n],
            power_scale: 0.0,
            shot_total: vec![DVec3::ZERO; m],
            refine_passes: 0,
            mesh_version: 0,
            source: vec![Vec3::ZERO; n],
            radiosity: vec![DVec3::ZERO; n],
            unshot: vec![DVec3::ZERO; n],
            columns: vec![None; m],
            cache_used: 0,
            rows: Vec::new(),
            reflectance,
            opacity,
            pending: None,
            hierarchy: None,
            stats: Stats {
                method: Some(settings.method),
                elements: n,
                patches: m,
                ..Default::default()
            },
            phase: Phase::Lighting(0),
            mesh,
            bvh,
            external,
            settings,
            shot_power: 0.0,
            captured_power: 0.0,
        })
    }

    /// The mesh being solved (replaced by each adaptive refinement).
    pub fn mesh(&self) -> &Arc<Mesh> {
        &self.mesh
    }

    /// Changes whenever adaptive refinement replaces the mesh.
    pub fn mesh_version(&self) -> u64 {
        self.mesh_version
    }

    /// Current radiosity B per element (W/m² per channel).
    pub fn radiosity(&self) -> Vec<Vec3> {
        self.covered(self.radiosity.iter().map(|b| b.as_vec3()))
    }

    /// `values` per element over each element's opacity: its covered part's.
    fn covered(&self, values: impl Iterator<Item = Vec3>) -> Vec<Vec3> {
        if self.opacity.is_empty() {
            return values.collect();
        }
        values.zip(&self.opacity).map(|(v, o)| v / *o).collect()
    }

    /// Current radiosity B per element in the f64 it is accumulated in.
    pub fn radiosity_f64(&self) -> &[DVec3] {
        &self.radiosity
    }

    /// Source term E'_i per element (emission plus first bounce of external light).
    pub fn source(&self) -> &[Vec3] {
        &self.source
    }

    /// The current solution prepared for the final gather at points (see [`gather`]).
    pub fn gatherer(&self, settings: gather::GatherSettings) -> gather::Gatherer {
        gather::Gatherer::new(
            self.mesh.clone(),
            self.bvh.clone(),
            self.external.clone(),
            gather::Solution {
                // As transported: the gather reports a point's covered part itself.
                radiosity: self.radiosity.iter().map(|b| b.as_vec3()).collect(),
                reflectance: self.reflectance.clone(),
                emission: self.emission.clone(),
            },
            settings,
        )
    }

    /// Progress so far.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// The settings in use.
    pub fn settings(&self) -> &SolverSettings {
        &self.settings
    }

    /// Whether the solve has converged.
    pub fn is_converged(&self) -> bool {
        self.phase == Phase::Done
    }

    /// Reflectance ρ per element, as solved with (after edits), of its covered part.
    pub fn reflectance(&self) -> Cow<'_, [Vec3]> {
        self.covered_slice(&self.reflectance)
    }

    /// Emitted radiosity E per element, as solved with (after edits), of its covered part.
    pub fn emission(&self) -> Cow<'_, [Vec3]> {
        self.covered_slice(&self.emission)
    }

    /// [`Solver::covered`] without a copy where every element is opaque.
    fn covered_slice<'a>(&self, values: &'a [Vec3]) -> Cow<'a, [Vec3]> {
        if self.opacity.is_empty() {
            Cow::Borrowed(values)
        } else {
            Cow::Owned(self.covered(values.iter().copied()))
        }
    }

    /// Radiosity for display: B plus, when `with_ambient`, ρ times the ambient term.
    pub fn display_radiosity(&self, with_ambient: bool) -> Vec<Vec3> {
        let ambient = if with_ambient {
            self.ambient()
        } else {
            Vec3::ZERO
        };
        self.covered(
            self.radiosity
                .iter()
                .zip(&self.reflectance)
                .map(|(b, rho)| b.as_vec3() + *rho * ambient),
        )
    }

    /// The irradiance behind [`Solver::display_radiosity`], H = (B − E)/ρ per element,
    /// taken from B in f64 ([`irradiance_at_f64`]): from the f32 display values an
    /// emitter's H would lose digits, and an edit's first solution, which changes ρ and E
    /// but not H, would show another irradiance.
    pub fn display_irradiance(&self, with_ambient: bool) -> Vec<Vec3> {
        let ambient = if with_ambient {
            self.ambient()
        } else {
            Vec3::ZERO
        };
        (0..self.radiosity.len())
            .into_par_iter()
            .with_min_len(ELEMENT_CHUNK)
            .map(|i| {
                let rho = self.reflectance[i];
                let b = self.radiosity[i] + rho.as_dvec3() * ambient.as_dvec3();
                irradiance_at_f64(b, rho, self.emission[i])
            })
            .collect()
    }

    /// Does one short unit of work (about `step_budget` of wall time, less if it converges)
    /// and reports whether the solve is done. Checks `cancel` between pieces of work.
    pub fn step(&mut self, cancel: &AtomicBool) -> Result<StepOutcome, SolverError> {
        let start = Instant::now();
        let deadline = start + self.settings.step_budget;
        let outcome = loop {
            if cancel.load(Ordering::Relaxed) {
                break StepOutcome::Cancelled;
            }
            match self.work(cancel) {
                Ok(Some(outcome)) => break outcome,
                Ok(None) => {}
                Err(Stop::Cancelled) => break StepOutcome::Cancelled,
                Err(Stop::Failed(e)) => return Err(e),
            }
            if Instant::now() >= deadline {
                break StepOutcome::Working;
            }
        };
        self.stats.seconds += start.elapsed().as_secs_f64();
        self.stats.converged = self.phase == Phase::Done;
        Ok(outcome)
    }

    /// One piece of work of the current phase; `Some(Converged)` when the solve is done and
    /// no refinement pass changed the mesh.
    fn work(&mut self, cancel: &AtomicBool) -> Result<Option<StepOutcome>, Stop> {
        match self.phase {
            Phase::Lighting(next) => self.lighting_chunk(next),
            Phase::Rows(next) => self.rows_chunk(next),
            Phase::Iterating => match self.settings.method {
                Method::Progressive => self.shoot(cancel)?,
                Method::Jacobi => self.jacobi_sweep(),
                Method::GaussSeidel => self.gauss_seidel_sweep(),
                Method::StochasticJacobi => self.stochastic_chunk(),
                Method::Direct => self.direct_solve(cancel)?,
                Method::Hierarchical => self.hierarchical_work(cancel)?,
            },
            Phase::Done => {}
        }
        if self.phase == Phase::Done && !self.refine(cancel)? {
            return Ok(Some(StepOutcome::Converged));
        }
        Ok(None)
    }

    /// Steps until converged, cancelled or `time_limit` has passed; returns the last outcome.
    pub fn run(
        &mut self,
        time_limit: Option<Duration>,
        cancel: &AtomicBool,
    ) -> Result<StepOutcome, SolverError> {
        let start = Instant::now();
        loop {
            let outcome = self.step(cancel)?;
            if outcome != StepOutcome::Working || time_limit.is_some_and(|t| start.elapsed() >= t) {
                return Ok(outcome);
            }
        }
    }

    /// Sets the source power Σ A_i E'_i (summed over RGB) from the current sources, and
    /// raises the unshot-fraction scale to it.
    fn update_source_power(&mut self) {
        self.stats.source_power = self
            .source
            .iter()
            .zip(&self.mesh.elements)
            .map(|(s, e)| sum3(*s) * e.area as f64)
            .sum();
        self.power_scale = self.power_scale.max(self.stats.source_power);
    }

    /// Area-weighted patch means B̄_p of per-element values.
    fn patch_means<T: Copy + Into<DVec3> + Sync>(&self, values: &[T]) -> Vec<DVec3> {
        let mesh = &self.mesh;
        mesh.patches
            .par_iter()
            .map(|p| {
                let mut s = DVec3::ZERO;
                for i in p.elements.clone() {
                    s += values[i as usize].into() * mesh.elements[i as usize].area as f64;
                }
                s / p.area as f64
            })
            .collect()
    }
}
