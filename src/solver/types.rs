//! The solver's shared types: the methods, their settings, progress statistics, edits, the
//! outcome of a step, and errors.

use super::form_factor::FormFactorSettings;
use crate::cancel::Cancelled;
use crate::mesh::AdaptiveSettings;
use glam::Vec3;
use serde::Serialize;
use std::time::Duration;

/// A solution method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    Progressive,
    Jacobi,
    GaussSeidel,
    StochasticJacobi,
    Direct,
    Hierarchical,
}

impl Method {
    /// Every method, in the order `bench` compares them.
    pub const ALL: [Method; 6] = [
        Method::Hierarchical,
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
            Method::Hierarchical => "hierarchical",
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
            .ok_or_else(|| format!("unknown method '{s}' (expected hierarchical, progressive, jacobi, gauss-seidel, stochastic-jacobi or direct)"))
    }
}

/// Solver settings.
#[derive(Clone, Debug, PartialEq)]
pub struct SolverSettings {
    pub method: Method,
    /// Convergence threshold: unshot fraction (progressive; and no patch's unshot radiosity
    /// above this times the mean radiosity) or relative residual (Jacobi, Gauss–Seidel),
    /// both relative to the source power Σ A_i E'_i.
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
    /// The hierarchical method's oracle and limits.
    pub hierarchy: HierarchySettings,
}

/// Settings of [`Method::Hierarchical`].
#[derive(Clone, Debug, PartialEq)]
pub struct HierarchySettings {
    /// The oracle's relative threshold ε: a link is refined when its estimated error
    /// exceeds ε times the scene's mean E' (what its surfaces emit or first reflect of
    /// the sky, sun and lamps), scaled down where the receiver is darker than the mean
    /// radiosity (down to a tenth). Smaller: more links and elements.
    pub link_error: f32,
    /// Start from one link of the root cluster to itself (on) or from every pair of
    /// patches (off, for small scenes and comparisons).
    pub clustering: bool,
    /// The smallest element the hierarchy makes (metres, as `sqrt(2·area)`); `None`: an
    /// eighth of the starting element size.
    pub min_size: Option<f64>,
    /// Most leaf elements (a memory bound).
    pub max_elements: usize,
    /// About the most links the hierarchy may hold (a memory bound): when a refinement
    /// round passes it, refinement stops there for the rest of the solve (the generation
    /// under way is the last), and the stats say so (`link_budget_reached`). Taken as at
    /// most [`MAX_LINK_BUDGET`].
    pub max_links: usize,
    /// A round at ε that makes at most this share of the links new is the oracle's last
    /// (see `hierarchical::ROUND_TOLERANCE`, the default); 0: the rounds go on until one
    /// changes nothing.
    pub round_tolerance: f64,
}

/// The largest link budget there is: a generation turns each link into at most 16 (a
/// node linked to itself, split on both sides), so the links stay below 2³¹, within the
/// u32 offsets of the solution's link table (and 3.7 GB at 28 bytes a link).
pub const MAX_LINK_BUDGET: usize = 1 << 27;

impl Default for HierarchySettings {
    fn default() -> Self {
        HierarchySettings {
            // 0.02 of the mean E' gives the built-in Cornell box (gain B̄ / Ē' = 2) about
            // the threshold it had at 0.03 of B̄ (1 − ρ̄), when 0.03 gave 1.57 % Gouraud
            // RMS against the path-traced reference at 41 M rays, 0.02 1.71 % at 50 M and
            // 0.04 1.94 % at 36 M (see `Solver::link_threshold`).
            link_error: 0.02,
            clustering: true,
            min_size: None,
            max_elements: 2_000_000,
            max_links: 1 << 24,
            round_tolerance: crate::solver::hierarchical::ROUND_TOLERANCE,
        }
    }
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
            hierarchy: HierarchySettings::default(),
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
    /// Hierarchical: the largest residual of any element in the last sweep, |E' + ρ H(B)
    /// − B| over max(B, a twentieth of the area-weighted mean B), channels summed (the
    /// residual above is the scene's, weighted by area).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub worst_element_residual: Option<f64>,
    /// Light arriving at surfaces / light leaving them (1 in a closed scene; less when light
    /// escapes, as through the Cornell box's open front).
    pub energy_balance: Option<f64>,
    /// Source power Σ A_i E'_i summed over RGB, W.
    pub source_power: f64,
    pub converged: bool,
    /// Hierarchical: links, and the bytes they take.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub links: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub link_bytes: Option<usize>,
    /// Hierarchical: seconds from the start of solving until the first solution covering
    /// the whole scene.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_solution_seconds: Option<f64>,
    /// Hierarchical: the share of the light arriving at the leaves (area-weighted,
    /// channels summed, in the last full sweep) that the links to clusters bring. The
    /// rest comes through surface links, whose transfer is computed per link; this part
    /// is estimated along each leaf's 16 rays (see `solver::hierarchical::sight`), so where
    /// it is large and what those rays hit differs much in brightness (a lamp reached
    /// through clusters), the picture shows their noise. Small where refinement
    /// reached the surfaces (the built-in Cornell box), large where the link budget
    /// stopped it early. Weighted by light, so a bright sealed space (the inside of
    /// nvpro's double-sided emissive lamp) counts with all of its light.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cluster_light_share: Option<f64>,
    /// Hierarchical: refinement stopped at the link budget (`max_links`) before the
    /// oracle was satisfied everywhere.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub link_budget_reached: Option<bool>,
    /// Hierarchical: bytes of the links' index by source, which sweeps after an edit go
    /// through (made when the solve converges; 4 bytes a link and a node).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub link_index_bytes: Option<usize>,
    /// Hierarchical: sweeps that went only through the links out of what an edit changed
    /// (see `solver::hierarchical::incremental`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub incremental_sweeps: Option<u64>,
    /// Hierarchical: the refinement round under way among the rounds from coarse to fine
    /// (counted from 0), and their number; the last, at the oracle's ε, repeats until it
    /// changes nothing or little (`hierarchical::ROUND_TOLERANCE`). What the viewer's
    /// progress bar counts besides the residual.
    #[serde(skip)]
    pub refinement_round: Option<(u32, u32)>,
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

/// Why a piece of work inside [`Solver::step`](super::Solver::step) stopped early: the
/// cancel flag (the step reports [`StepOutcome::Cancelled`]) or an error (the step returns
/// it).
#[derive(Debug)]
pub(super) enum Stop {
    Cancelled,
    Failed(SolverError),
}

impl From<Cancelled> for Stop {
    fn from(_: Cancelled) -> Stop {
        Stop::Cancelled
    }
}

impl From<SolverError> for Stop {
    fn from(e: SolverError) -> Stop {
        Stop::Failed(e)
    }
}

/// Largest element × patch product the gathering methods will store (≈ 1.6 GB as (u32, f32)).
pub const MAX_MATRIX_PAIRS: usize = 200_000_000;
/// Largest patch count for the dense direct solve (M² doubles, O(M³) time).
pub const MAX_DIRECT_PATCHES: usize = 6000;
