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

pub mod direct;
pub mod form_factor;
pub mod hemicube;
pub mod lighting;
pub mod stochastic;

use crate::accel::Bvh;
use crate::mesh::{AdaptiveSettings, Mesh, Moved, Punctual, sanitize};
use form_factor::{FormFactorSettings, element_to_patch};
use glam::{DVec3, Vec3};
use lighting::ExternalLight;
use rayon::prelude::*;
use serde::Serialize;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// A solution method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    Progressive,
    Jacobi,
    GaussSeidel,
    StochasticJacobi,
    Direct,
}

impl Method {
    /// Every method, in the order `bench` compares them.
    pub const ALL: [Method; 5] = [
        Method::Progressive,
        Method::Jacobi,
        Method::GaussSeidel,
        Method::StochasticJacobi,
        Method::Direct,
    ];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Progressive => "progressive",
            Method::Jacobi => "jacobi",
            Method::GaussSeidel => "gauss-seidel",
            Method::StochasticJacobi => "stochastic-jacobi",
            Method::Direct => "direct",
        }
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == s || (s == "gs" && *m == Method::GaussSeidel))
            .ok_or_else(|| format!("unknown method '{s}' (expected progressive, jacobi, gauss-seidel, stochastic-jacobi or direct)"))
    }
}

/// Solver settings.
#[derive(Clone, Debug, PartialEq)]
pub struct SolverSettings {
    pub method: Method,
    /// Convergence threshold: unshot fraction (progressive) or relative residual (Jacobi,
    /// Gauss–Seidel), both relative to the source power Σ A_i E'_i.
    pub tolerance: f64,
    pub form_factors: FormFactorSettings,
    /// Wall-clock work per [`Solver::step`] before it returns (a frame's worth).
    pub step_budget: Duration,
    /// Most bytes the form-factor cache may hold.
    pub cache_bytes: usize,
    /// Rays per stochastic Jacobi iteration; `None` is 16 per element, at least 2¹⁸.
    pub stochastic_rays: Option<usize>,
    /// A-posteriori adaptive subdivision after each converged solve (`None`: the mesh
    /// stays as built). The command line and the viewer turn it on by default.
    pub adaptive: Option<AdaptiveSettings>,
}

impl Default for SolverSettings {
    fn default() -> Self {
        SolverSettings {
            method: Method::Progressive,
            // 1e-3 of the source power left unshot: on the Cornell box the converged
            // display then differs from the direct solve by ~0.1 % RMS.
            tolerance: 1e-3,
            form_factors: FormFactorSettings::default(),
            step_budget: Duration::from_millis(30),
            cache_bytes: 1 << 30,
            stochastic_rays: None,
            adaptive: None,
        }
    }
}

/// Where a solve stands. Serialised as the `--stats` JSON.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Stats {
    pub method: Option<Method>,
    pub elements: usize,
    pub patches: usize,
    /// Progressive: patches shot. Gathering: sweeps. Direct: 1 once solved.
    pub iterations: u64,
    /// Shadow and sky rays cast so far.
    pub rays: u64,
    /// Solver time so far (excluding meshing and BVH build).
    pub seconds: f64,
    /// Progressive: unshot power / source power. `None` for the other methods.
    pub unshot_fraction: Option<f64>,
    /// Relative residual Σ A_i |r_i| / Σ A_i |E'_i| (progressive: the unshot radiosity,
    /// Southwell's residual of the shooting formulation).
    pub residual: Option<f64>,
    /// Light arriving at surfaces / light leaving them (1 in a closed scene; less when light
    /// escapes, as through the Cornell box's open front).
    pub energy_balance: Option<f64>,
    /// Source power Σ A_i E'_i summed over RGB, W.
    pub source_power: f64,
    pub converged: bool,
}

/// A live material change of one patch (see [`Solver::edit_patches`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchEdit {
    pub patch: u32,
    /// New reflectance ρ (clamped to [0, 0.999]).
    pub reflectance: Vec3,
    /// New emitted radiosity E = π L_e, W/m².
    pub emission: Vec3,
}

/// What a step did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepOutcome {
    /// More work remains.
    Working,
    /// The tolerance is met (or the direct solve is done).
    Converged,
    /// The cancel flag was raised.
    Cancelled,
}

/// Errors the solver reports instead of panicking.
#[derive(Debug, thiserror::Error)]
pub enum SolverError {
    #[error(
        "{method} needs the full form-factor matrix: {elements} elements × {patches} patches is too large (limit {limit} pairs); use --method progressive or a coarser mesh"
    )]
    TooLarge {
        method: Method,
        elements: usize,
        patches: usize,
        limit: usize,
    },
    #[error("the direct solve found the system singular")]
    Singular,
}

/// Largest element × patch product the gathering methods will store (≈ 1.6 GB as (u32, f32)).
pub const MAX_MATRIX_PAIRS: usize = 200_000_000;
/// Largest patch count for the dense direct solve (M² doubles, O(M³) time).
pub const MAX_DIRECT_PATCHES: usize = 6000;

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

/// A stochastic Jacobi iteration split over several steps.
struct Pending {
    sources: stochastic::Sources,
    rays: usize,
    next_chunk: usize,
    added: Vec<DVec3>,
    arrived: f64,
}

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
    /// Reflectance per element (its patch's, or an edit's).
    reflectance: Vec<Vec3>,
    /// Emitted radiosity E per element (its patch's, or an edit's).
    emission: Vec<Vec3>,
    /// First-bounce irradiance factor h_i of external light, so E'_i = E_i + ρ_i h_i.
    external_in: Vec<Vec3>,
    /// Progressive: radiosity gathered so far before reflection, H_i = Σ F_ip ΔB̄_p, so that
    /// B_i = E'_i + ρ_i H_i at every moment. Chen's incremental edits need it.
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
    stats: Stats,
    shot_power: f64,
    captured_power: f64,
}

/// The first-bounce irradiance factor h_i of the external lights (punctual, sun, sky) at
/// element `i`, so that E'_i = E_i + ρ_i h_i, and the rays cast; zero without external
/// light. Seeded by the element's geometry.
fn external_factor(mesh: &Mesh, bvh: &Bvh, external: &ExternalLight, i: usize) -> (Vec3, u32) {
    if external.lights.is_empty() && external.environment.is_none() {
        return (Vec3::ZERO, 0);
    }
    let e = &mesh.elements[i];
    let p = &mesh.patches[e.patch as usize];
    let (h, rays) = lighting::irradiance(
        mesh,
        bvh,
        external,
        e.centroid(),
        e.normal,
        p.scene_triangle,
        form_factor::element_seed(e),
    );
    (if h.is_finite() { h } else { Vec3::ZERO }, rays)
}

/// Per-element values carried through a refinement: children start from their parent's.
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

fn sum3(v: Vec3) -> f64 {
    v.x as f64 + v.y as f64 + v.z as f64
}

fn sum3d(v: DVec3) -> f64 {
    v.x + v.y + v.z
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
        let reflectance = mesh
            .elements
            .iter()
            .map(|e| mesh.patches[e.patch as usize].reflectance)
            .collect();
        let emission = mesh
            .elements
            .iter()
            .map(|e| mesh.patches[e.patch as usize].emission)
            .collect();
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
            pending: None,
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
        self.radiosity.iter().map(|b| b.as_vec3()).collect()
    }

    /// Current radiosity B per element in the f64 it is accumulated in.
    pub fn radiosity_f64(&self) -> &[DVec3] {
        &self.radiosity
    }

    /// Source term E'_i per element (emission plus first bounce of external light).
    pub fn source(&self) -> &[Vec3] {
        &self.source
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

    /// Radiosity for display: B plus, when `with_ambient`, ρ times the ambient term.
    pub fn display_radiosity(&self, with_ambient: bool) -> Vec<Vec3> {
        let ambient = if with_ambient {
            self.ambient()
        } else {
            Vec3::ZERO
        };
        self.radiosity
            .iter()
            .zip(&self.reflectance)
            .map(|(b, rho)| b.as_vec3() + *rho * ambient)
            .collect()
    }

    /// One pass of a-posteriori adaptive subdivision on a converged solve (see
    /// [`crate::mesh::AdaptiveSettings`]); returns whether the mesh changed, in which case
    /// the solve goes on from where it was.
    ///
    /// New elements are re-evaluated, not interpolated: progressive refinement gathers
    /// each child's radiosity from everything already shot (H_c = Σ_p F_cp · Σ ΔB̄_p, the
    /// patches' shot totals), and the child's unshot radiosity keeps the parent's plus the
    /// difference, so for every patch Σ A_i (B_i − ΔB_i) still equals what it has shot:
    /// refinement neither creates nor loses energy. The gathering methods compute the
    /// children's rows and sweep again from the parent's values; the direct method solves
    /// again; stochastic Jacobi carries the parent's values.
    fn refine(&mut self) -> bool {
        let Some(a) = self.settings.adaptive.clone() else {
            return false;
        };
        if self.refine_passes >= a.max_passes || self.stats.source_power <= 0.0 {
            return false;
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
            return false;
        }
        self.refine_passes += 1;
        let mut mesh = (*self.mesh).clone();
        let moved = mesh.refine(&marked);
        mark_hard_shadows(&mut mesh, &self.bvh, &self.external, min_size);
        let mesh = Arc::new(mesh);
        let n = mesh.elements.len();
        self.radiosity = remap(&self.radiosity, &moved, n);
        self.unshot = remap(&self.unshot, &moved, n);
        self.gathered = remap(&self.gathered, &moved, n);
        self.source = remap(&self.source, &moved, n);
        self.reflectance = remap(&self.reflectance, &moved, n);
        self.emission = remap(&self.emission, &moved, n);
        self.external_in = remap(&self.external_in, &moved, n);
        let children: Vec<u32> = moved
            .iter()
            .flat_map(|m| match m {
                Moved::Split(kids) => kids.to_vec(),
                Moved::Kept(_) => Vec::new(),
            })
            .collect();
        let had_rows = !self.rows.is_empty();
        let mut old_rows = std::mem::take(&mut self.rows);
        self.mesh = mesh;
        self.pending = None;
        let old_columns = std::mem::replace(&mut self.columns, vec![None; self.mesh.patches.len()]);
        self.cache_used = 0;
        // Re-evaluate the children: external light, and (progressive) what has been shot.
        let mesh = Arc::clone(&self.mesh);
        let (bvh, external, ff) = (&self.bvh, &self.external, self.settings.form_factors);
        let progressive = self.settings.method == Method::Progressive;
        let shot_total = &self.shot_total;
        let needed = |q: usize| had_rows || (progressive && shot_total[q] != DVec3::ZERO);
        // Per child: external irradiance factor h, gathered H, its F to the patches needed,
        // rays cast.
        type Evaluated = (Vec3, DVec3, Vec<(u32, f32)>, u64);
        let evaluated: Vec<Evaluated> = children
            .par_iter()
            .map(|&c| {
                let c = c as usize;
                let (h, mut rays) = external_factor(&mesh, bvh, external, c);
                let mut gathered = DVec3::ZERO;
                let mut row = Vec::new();
                for (q, total) in shot_total.iter().enumerate() {
                    if !needed(q) {
                        continue;
                    }
                    let (f, r) = element_to_patch(&mesh, bvh, c, q, &ff);
                    rays += r;
                    if f > 0.0 {
                        gathered += *total * f as f64;
                        row.push((q as u32, f));
                    }
                }
                (h, gathered, row, rays as u64)
            })
            .collect();
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
            if !needed(q) {
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
        true
    }

    /// Marks elements across which the visibility of a main light source changes: shadow
    /// rays from the element's three corners to the source disagree (a shadow or penumbra
    /// boundary, or a contact line where another surface touches it). Sources: punctual and
    /// directional lights, the sun, and the patches that carry most of the light (up to
    /// 8, each at least 1 % of the total: shot power for progressive refinement, emitted
    /// power otherwise), seen at their centroids. Such elements are split down to the
    /// minimum size, so hard shadows come out as sharp as it allows.
    fn mark_visibility_changes(&self, marked: &mut [bool], min_size: f64) {
        let mesh = &self.mesh;
        let eps = mesh.epsilon();
        let mut targets = Targets::punctual(mesh, &self.external);
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

    /// Changes the reflectance and emitted radiosity of some patches without restarting:
    /// Chen's incremental radiosity ("Incremental radiosity", Graphics Gems II, 1991). With
    /// H_i the radiosity gathered by element i so far, B_i = E'_i + ρ_i H_i, so the edit
    /// changes B_i by ΔE'_i + Δρ_i H_i; that difference is added to B_i and to its *signed*
    /// unshot radiosity, and progressive shooting carries it (positive or negative) to the
    /// rest of the scene. The gathering methods keep their current B as the starting guess
    /// and sweep again; the direct method solves again from its stored rows; stochastic
    /// Jacobi, whose sources must be positive, starts over.
    pub fn edit_patches(&mut self, edits: &[PatchEdit]) {
        let mesh = Arc::clone(&self.mesh);
        let lit = match self.phase {
            Phase::Lighting(next) => next,
            _ => mesh.elements.len(),
        };
        let incremental = self.settings.method == Method::Progressive;
        for edit in edits {
            let Some(patch) = mesh.patches.get(edit.patch as usize) else {
                continue;
            };
            let rho = sanitize(edit.reflectance).min(Vec3::splat(0.999));
            let emission = sanitize(edit.emission);
            for i in patch.elements.clone() {
                let i = i as usize;
                let old_rho = self.reflectance[i];
                self.reflectance[i] = rho;
                self.emission[i] = emission;
                if i >= lit {
                    continue; // its source is computed later, with the new values
                }
                let s = emission + rho * self.external_in[i];
                let ds = (s - self.source[i]).as_dvec3();
                self.source[i] = s;
                if incremental {
                    let delta = ds + (rho - old_rho).as_dvec3() * self.gathered[i];
                    self.radiosity[i] += delta;
                    self.unshot[i] += delta;
                } else if matches!(self.phase, Phase::Lighting(_)) {
                    self.radiosity[i] = s.as_dvec3();
                    self.unshot[i] = s.as_dvec3();
                }
            }
        }
        if matches!(self.phase, Phase::Lighting(_)) {
            return; // the source power is summed when lighting finishes
        }
        self.update_source_power();
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
            }
        }
        if self.power_scale <= 0.0 {
            self.phase = Phase::Done;
            self.stats.converged = true;
        }
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
            match self.phase {
                Phase::Lighting(next) => self.lighting_chunk(next),
                Phase::Rows(next) => self.rows_chunk(next),
                Phase::Iterating => match self.settings.method {
                    Method::Progressive => self.shoot(),
                    Method::Jacobi => self.jacobi_sweep(),
                    Method::GaussSeidel => self.gauss_seidel_sweep(),
                    Method::StochasticJacobi => self.stochastic_chunk(),
                    Method::Direct => self.direct_solve()?,
                },
                Phase::Done => {
                    if self.refine() {
                        continue;
                    }
                    break StepOutcome::Converged;
                }
            }
            if self.phase == Phase::Done && !self.refine() {
                break StepOutcome::Converged;
            }
            if Instant::now() >= deadline {
                break StepOutcome::Working;
            }
        };
        self.stats.seconds += start.elapsed().as_secs_f64();
        self.stats.converged = self.phase == Phase::Done;
        Ok(outcome)
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

    /// Elements per parallel chunk: large enough to amortise scheduling, small enough to
    /// return within a step budget.
    const CHUNK: usize = 256;

    fn lighting_chunk(&mut self, next: usize) {
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
            Method::Progressive | Method::StochasticJacobi => Phase::Iterating,
            _ => Phase::Rows(0),
        };
        if self.power_scale <= 0.0 {
            // No light at all: the solution is zero and already exact.
            self.stats.unshot_fraction = Some(0.0);
            self.stats.residual = Some(0.0);
            self.phase = Phase::Done;
        }
    }

    fn rows_chunk(&mut self, next: usize) {
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

    fn column(&mut self, p: usize) -> Sparse {
        if let Some(c) = &self.columns[p] {
            return c.clone();
        }
        let mesh = &self.mesh;
        let bvh = &self.bvh;
        let ff = self.settings.form_factors;
        let n = mesh.elements.len();
        let shooter = &mesh.patches[p];
        let parts: Vec<(Vec<(u32, f32)>, u64)> = (0..n)
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
        let mut col = Vec::new();
        for (v, rays) in parts {
            col.extend(v);
            self.stats.rays += rays;
        }
        // rayon's fold/collect keeps the index order of the pieces, so `col` is sorted.
        let col: Sparse = Arc::from(col);
        let bytes = col.len() * std::mem::size_of::<(u32, f32)>();
        if self.cache_used + bytes <= self.settings.cache_bytes {
            self.cache_used += bytes;
            self.columns[p] = Some(col.clone());
        }
        col
    }

    /// One progressive-refinement shot from the patch with the most unshot power.
    fn shoot(&mut self) {
        let mesh = Arc::clone(&self.mesh);
        let (mut best, mut best_power, mut total) = (usize::MAX, 0.0f64, 0.0f64);
        for (pi, p) in mesh.patches.iter().enumerate() {
            // Signed unshot radiosity (after an edit) is shot like positive: by magnitude.
            let mut power = 0.0;
            for i in p.elements.clone() {
                power +=
                    sum3d(self.unshot[i as usize].abs()) * mesh.elements[i as usize].area as f64;
            }
            total += power;
            if power > best_power {
                best_power = power;
                best = pi;
            }
        }
        let fraction = total / self.power_scale;
        self.stats.unshot_fraction = Some(fraction);
        self.stats.residual = Some(fraction);
        if fraction <= self.settings.tolerance || best == usize::MAX {
            self.phase = Phase::Done;
            return;
        }
        let p = &mesh.patches[best];
        let mut shot = DVec3::ZERO;
        for i in p.elements.clone() {
            shot += self.unshot[i as usize] * mesh.elements[i as usize].area as f64;
            self.unshot[i as usize] = DVec3::ZERO;
        }
        let shot = shot / p.area as f64;
        self.shot_total[best] += shot;
        let column = self.column(best);
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
    }

    /// Traces a few chunks of the current stochastic iteration; finishes it when all its
    /// rays are done.
    fn stochastic_chunk(&mut self) {
        let mesh = Arc::clone(&self.mesh);
        let n = mesh.elements.len();
        let pending = match self.pending.take() {
            Some(p) => p,
            None => {
                let sources = stochastic::Sources::new(&mesh, &self.unshot);
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
        let chunks = p.rays.div_ceil(stochastic::CHUNK_RAYS);
        let end = (p.next_chunk + 2 * rayon::current_num_threads().max(1)).min(chunks);
        let iteration = self.stats.iterations;
        let (bvh, refl, unshot, src, rays) = (
            &self.bvh,
            &self.reflectance,
            &self.unshot,
            &p.sources,
            p.rays,
        );
        let parts: Vec<stochastic::Deposits> = (p.next_chunk..end)
            .into_par_iter()
            .map(|c| {
                let first = c * stochastic::CHUNK_RAYS;
                let count = stochastic::CHUNK_RAYS.min(rays - first);
                stochastic::trace_chunk(
                    &mesh, bvh, refl, unshot, src, rays, first, count, iteration,
                )
            })
            .collect();
        for part in parts {
            p.arrived += part.arrived;
            for (j, add) in part.added {
                p.added[j as usize] += add;
            }
        }
        let traced =
            (end * stochastic::CHUNK_RAYS).min(p.rays) - p.next_chunk * stochastic::CHUNK_RAYS;
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

    /// Gathered radiosity E'_i + ρ_i Σ_p F_ip B̄_p for element i.
    fn gather(&self, i: usize, means: &[DVec3]) -> DVec3 {
        let mut h = DVec3::ZERO;
        for &(p, f) in self.rows[i].iter() {
            h += means[p as usize] * f as f64;
        }
        self.source[i].as_dvec3() + self.reflectance[i].as_dvec3() * h
    }

    fn finish_sweep(&mut self, residual: f64) {
        let r = residual / self.power_scale;
        self.stats.residual = Some(r);
        self.stats.iterations += 1;
        if r <= self.settings.tolerance {
            self.phase = Phase::Done;
            self.stats.energy_balance = Some(self.gathered_balance());
        }
    }

    fn jacobi_sweep(&mut self) {
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

    fn gauss_seidel_sweep(&mut self) {
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

    fn direct_solve(&mut self) -> Result<(), SolverError> {
        let m = self.mesh.patches.len();
        let mesh = Arc::clone(&self.mesh);
        let source_means = self.patch_means(&self.source);
        let mut means = vec![DVec3::ZERO; m];
        for c in 0..3 {
            // Reduced system: (I − P ρ F) B̄ = P E'.
            let mut a = vec![0.0f64; m * m];
            for q in 0..m {
                a[q * m + q] = 1.0;
            }
            for (q, patch) in mesh.patches.iter().enumerate() {
                for i in patch.elements.clone() {
                    let i = i as usize;
                    let w =
                        (mesh.elements[i].area / patch.area) as f64 * self.reflectance[i][c] as f64;
                    if w == 0.0 {
                        continue;
                    }
                    for &(p, f) in self.rows[i].iter() {
                        a[q * m + p as usize] -= w * f as f64;
                    }
                }
            }
            let b: Vec<f64> = source_means.iter().map(|s| s[c]).collect();
            let x = direct::solve_dense(a, b, m).ok_or(SolverError::Singular)?;
            for (mean, v) in means.iter_mut().zip(x) {
                mean[c] = v;
            }
        }
        self.radiosity = (0..self.radiosity.len())
            .into_par_iter()
            .map(|i| self.gather(i, &means))
            .collect();
        self.stats.iterations = 1;
        self.stats.residual = Some(0.0);
        self.stats.energy_balance = Some(self.gathered_balance());
        self.phase = Phase::Done;
        Ok(())
    }

    /// Light arriving at surfaces over light leaving them, from the stored rows:
    /// Σ_i A_i Σ_p F_ip B̄_p / Σ_p A_p B̄_p.
    fn gathered_balance(&self) -> f64 {
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

/// Light sources for corner-visibility tests, in the mesh frame, each with the scene
/// triangle a ray to it skips (`u32::MAX` for none).
struct Targets {
    sources: Vec<(Punctual, u32)>,
}

impl Targets {
    /// Point, spot and directional lights and the sun: the sources whose shadows are hard.
    fn punctual(mesh: &Mesh, external: &ExternalLight) -> Targets {
        let lights = crate::mesh::punctual_lights(
            &external.lights,
            external.environment.as_ref(),
            mesh.origin,
        );
        Targets {
            sources: lights.into_iter().map(|l| (l, u32::MAX)).collect(),
        }
    }

    /// Which of the sources point `p` (normal `n`, on scene triangle `own`) sees: a bit
    /// per source (the first 64).
    fn seen(&self, mesh: &Mesh, bvh: &Bvh, p: Vec3, n: Vec3, own: u32) -> u64 {
        let x = p + n * mesh.epsilon();
        let far = mesh.scale * 4.0;
        self.sources
            .iter()
            .map(|&(l, tri)| n.dot(l.towards(p)) > 0.0 && l.visible(bvh, x, [own, tri], far))
            .take(64)
            .enumerate()
            .fold(0, |m, (b, seen)| m | (u64::from(seen) << b))
    }

    /// The elements (other than those `skip` names) whose three corners disagree about
    /// seeing one of the sources: a shadow boundary crosses them. Corners are pulled 1 %
    /// towards the centroid (a corner exactly on a contact line is ambiguous) and lifted
    /// off the surface.
    fn changes(&self, mesh: &Mesh, bvh: &Bvh, skip: impl Fn(usize) -> bool + Sync) -> Vec<u32> {
        if self.sources.is_empty() {
            return Vec::new();
        }
        let eps = mesh.epsilon();
        let far = mesh.scale * 4.0;
        (0..mesh.elements.len())
            .into_par_iter()
            .with_min_len(64)
            .filter(|&i| {
                if skip(i) {
                    return false;
                }
                let e = &mesh.elements[i];
                let own = mesh.patches[e.patch as usize].scene_triangle;
                let c = e.centroid();
                let corners = e.verts.map(|v| v + (c - v) * 0.01 + e.normal * eps);
                self.sources.iter().any(|&(l, tri)| {
                    if e.normal.dot(l.towards(c)) <= 0.0 {
                        return false;
                    }
                    let vis = corners.map(|x| l.visible(bvh, x, [own, tri], far));
                    vis[0] != vis[1] || vis[1] != vis[2]
                })
            })
            .map(|i| i as u32)
            .collect()
    }
}

/// Records the sides of hard shadow edges in `mesh.display.shadow_sides` (see
/// [`crate::mesh::ShadowSides`]): the elements across which the visibility of a point,
/// spot or directional light or the sun changes, and for their corners and the elements
/// around those, which of these sources each sees. Only where adaptive subdivision has
/// resolved the edge, in elements it may not split further (below twice `min_size`):
/// where the mesh is coarser than the shadows (the refinement stopped at its element
/// budget), the element values are scattered samples of them, and choosing sides at each
/// vertex would show that scatter as speckle, where averaging smooths it. Area lights'
/// shadows have penumbrae and are left to the smooth reconstruction.
pub fn mark_hard_shadows(mesh: &mut Mesh, bvh: &Bvh, external: &ExternalLight, min_size: f64) {
    mesh.display.shadow_sides = None;
    let targets = Targets::punctual(mesh, external);
    let crossed = targets.changes(mesh, bvh, |i| {
        crate::mesh::element_size(&mesh.elements[i]) * 0.5 >= min_size * 0.999
    });
    if crossed.is_empty() {
        return;
    }
    let nv = mesh.display.positions.len();
    // Corners of crossed elements, each with an element using it (for the triangle its
    // shadow rays skip).
    let mut owner = vec![u32::MAX; nv];
    for &i in &crossed {
        for &c in &mesh.elements[i as usize].corners {
            owner[c as usize] = i;
        }
    }
    let elements = &mesh.elements;
    let own = |i: u32| mesh.patches[elements[i as usize].patch as usize].scene_triangle;
    let element: Vec<u64> = elements
        .par_iter()
        .with_min_len(256)
        .map(|e| {
            if e.corners.iter().all(|&c| owner[c as usize] == u32::MAX) {
                return 0;
            }
            let tri = mesh.patches[e.patch as usize].scene_triangle;
            targets.seen(mesh, bvh, e.centroid(), e.normal, tri)
        })
        .collect();
    let display = &mesh.display;
    let mut vertex: Vec<Option<u64>> = (0..nv)
        .into_par_iter()
        .with_min_len(256)
        .map(|k| {
            let i = owner[k];
            (i != u32::MAX).then(|| {
                let e = &elements[i as usize];
                targets.seen(mesh, bvh, display.positions[k], e.normal, own(i))
            })
        })
        .collect();
    // A vertex with no element on its side (a sliver of light) keeps all of them.
    let mut matched = vec![false; nv];
    for (e, side) in elements.iter().zip(&element) {
        for &c in &e.corners {
            matched[c as usize] |= vertex[c as usize] == Some(*side);
        }
    }
    for (v, m) in vertex.iter_mut().zip(matched) {
        if !m {
            *v = None;
        }
    }
    mesh.display.shadow_sides = Some(crate::mesh::ShadowSides { vertex, element });
}
