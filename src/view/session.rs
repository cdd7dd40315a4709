//! One opened scene: everything the viewer holds about it (the worker job, the mesh and
//! its BVH, materials and objects, the newest snapshot, statistics and convergence
//! history, the selection, the edits, what of it is on the GPU). [`App::open`] replaces
//! the whole [`Session`], so nothing of one scene outlives it into the next.

use super::app::App;
use super::camera::Camera;
use super::edits::Edits;
use super::final_gather::Pass;
use super::gpu::Uploads;
use crate::accel::Bvh;
use crate::mesh::{Hermite, Mesh};
use crate::scene::{Image, Material};
use crate::solver::gather::Gatherer;
use crate::solver::{ElementLinks, Stats};
use crate::worker::{Command, ObjectInfo, Source, Stage};
use glam::Vec3;
use std::sync::Arc;
use std::time::Instant;

/// A solution snapshot from the worker.
pub(super) struct Snap {
    pub(super) version: u64,
    /// Radiosity B per element.
    pub(super) radiosity: Arc<[Vec3]>,
    /// Irradiance H per element, its Gouraud values per display-mesh vertex and, while
    /// Hermite display asks for them, its Hermite values and slopes there.
    pub(super) irradiance: Arc<[Vec3]>,
    pub(super) vertex: Arc<[Vec3]>,
    pub(super) hermite: Option<Arc<Hermite>>,
    /// Reflectance ρ and emitted radiosity E per element, as solved with.
    pub(super) reflectance: Arc<[Vec3]>,
    pub(super) emission: Arc<[Vec3]>,
}

/// The state of one opened scene. The default is "no scene" (job 0, nothing loaded).
#[derive(Default)]
pub(super) struct Session {
    /// The worker job that loads and solves this scene; events of other jobs are stale.
    pub(super) job: u64,
    /// A path or `builtin:NAME`.
    pub(super) source: String,
    /// What the worker is doing for this scene; `None` once it converged or failed.
    pub(super) stage: Option<Stage>,
    /// The error shown in the side panel until dismissed.
    pub(super) error: Option<String>,
    pub(super) warnings: Vec<String>,
    pub(super) mesh: Option<Arc<Mesh>>,
    pub(super) bvh: Option<Arc<Bvh>>,
    /// The scene's materials, with the edits made to them, and the images their textures
    /// refer to.
    pub(super) materials: Vec<Material>,
    pub(super) images: Vec<Arc<Image>>,
    pub(super) objects: Vec<ObjectInfo>,
    /// The newest snapshot received.
    pub(super) snapshot: Option<Snap>,
    pub(super) stats: Stats,
    pub(super) converged: bool,
    /// What the status bar's progress bar shows.
    pub(super) progress: Progress,
    pub(super) paused: bool,
    /// The convergence plot: (solver seconds, unshot fraction, residual), by time.
    pub(super) history: Vec<[f64; 3]>,
    /// The selected object and its material.
    pub(super) selected: Option<u32>,
    pub(super) material: Option<u32>,
    /// The element under the last click and the links that light it (hierarchical only).
    pub(super) inspected: Option<ElementLinks>,
    /// The camera has been placed for this scene (once, when its first mesh arrives).
    pub(super) camera_set: bool,
    /// When the current mesh arrived (the timed screenshot counts from it).
    pub(super) solve_started: Option<Instant>,
    pub(super) edits: Edits,
    pub(super) uploads: Uploads,
    /// The camera the auto exposure was last metered from.
    pub(super) metered: Option<Camera>,
    /// The final gather of this scene: the newest prepared solution with the snapshot
    /// version it was made from, the version asked for, when and where the camera came to
    /// rest, the pass under way and its texture.
    pub(super) gatherer: Option<(u64, Arc<Gatherer>)>,
    pub(super) gatherer_asked: Option<u64>,
    pub(super) camera_rest: Option<(Camera, Instant)>,
    pub(super) pass: Option<Pass>,
    pub(super) pass_texture: Option<eframe::egui::TextureHandle>,
}

/// The status bar's progress towards a converged solve: the residual's way from 1 to the
/// tolerance on a log scale, and for the hierarchical method the refinement rounds too
/// (round k of n with the residual's share r shows (k + r) / n), since every round's
/// sweeps reach the tolerance again. Below 1 until the solve has converged (the flat
/// methods' adaptive passes, too, start after the residual met the tolerance). It never
/// goes back within one solve (a round's first sweep raises the residual); it starts again
/// when a solve does (its solver time goes back) and when a converged solve is asked for
/// more (an edit, a new setting).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Progress {
    shown: f32,
    seconds: f64,
    converged: bool,
}

impl Progress {
    /// The fraction to show now, given the solver's stats and whether it has converged.
    pub(super) fn update(&mut self, stats: &Stats, converged: bool, tolerance: f64) -> f32 {
        if stats.seconds < self.seconds || (self.converged && !converged) {
            self.shown = 0.0;
        }
        (self.seconds, self.converged) = (stats.seconds, converged);
        let residual = match stats.residual {
            Some(r) if r > 0.0 => (r.ln() / tolerance.max(1e-12).ln()).clamp(0.0, 1.0),
            Some(_) => 1.0,
            None => 0.0,
        };
        let estimate = match stats.refinement_round {
            Some((round, rounds)) => (round as f64 + residual) / rounds.max(1) as f64,
            None => residual,
        }
        .min(0.99);
        self.shown = if converged {
            1.0
        } else {
            self.shown.max(estimate as f32)
        };
        self.shown
    }
}

impl Session {
    /// Scene `source` about to be loaded as worker job `job`.
    pub(super) fn new(job: u64, source: String) -> Session {
        Session {
            job,
            source,
            stage: Some(Stage::Loading),
            ..Default::default()
        }
    }

    /// Adds a point to the convergence history (only later solver times than the last).
    pub(super) fn record(&mut self, stats: &Stats) {
        let t = stats.seconds;
        let u = stats.unshot_fraction.unwrap_or(f64::NAN);
        let r = stats.residual.unwrap_or(f64::NAN);
        if self.history.last().is_none_or(|h| t > h[0]) {
            self.history.push([t, u, r]);
        }
    }
}

impl App {
    /// Opens a scene (a path or `builtin:NAME`) as a new job; the old job is cancelled and
    /// everything of its scene dropped. Settings, display choices, the camera (until the
    /// new scene's mesh places it) and the recent-files list carry over.
    pub fn open(&mut self, source: String) {
        self.session = Session::new(self.session.job + 1, source.clone());
        // The highlight is a display setting that names an object of the old scene.
        self.display.selected = None;
        self.mesh_settings.element_size = (self.element_size > 0.0).then_some(self.element_size);
        self.worker.send(Command::Load {
            job: self.session.job,
            source: Source(source.clone()),
            outside: self.outside,
            mesh: self.mesh_settings.clone(),
            solver: self.solver_settings.clone(),
        });
        if !self.ambient {
            self.worker.send(Command::SetAmbient(false));
        }
        if !source.starts_with("builtin:") {
            self.remember_recent(source);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stats(seconds: f64, residual: f64, round: Option<(u32, u32)>) -> Stats {
        Stats {
            seconds,
            residual: Some(residual),
            refinement_round: round,
            ..Default::default()
        }
    }

    #[test]
    fn progress_counts_the_rounds_and_never_goes_back_within_a_solve() {
        let tol = 1e-4;
        let mut p = Progress::default();
        // Round 0 of 5, its sweeps halfway to the tolerance (1e-2 of 1e-4 on a log scale).
        let a = p.update(&stats(0.5, 1e-2, Some((0, 5))), false, tol);
        assert!((a - 0.1).abs() < 1e-6, "{a}");
        // Its sweeps at the tolerance: a fifth, not all of it.
        let b = p.update(&stats(0.8, 1e-4, Some((0, 5))), false, tol);
        assert!((b - 0.2).abs() < 1e-6, "{b}");
        // The next round refines with the last sweep's residual still at the tolerance,
        // then its first sweep raises the residual: the bar stays where it got.
        let c = p.update(&stats(0.9, 1e-4, Some((1, 5))), false, tol);
        assert!((c - 0.4).abs() < 1e-6, "{c}");
        assert_eq!(p.update(&stats(1.0, 0.5, Some((1, 5))), false, tol), c);
        // The last round at the tolerance: just short of full until the solve converges.
        let last = p.update(&stats(5.0, 1e-5, Some((4, 5))), false, tol);
        assert!((0.98..1.0).contains(&last), "{last}");
        assert_eq!(p.update(&stats(6.0, 1e-5, Some((4, 5))), true, tol), 1.0);
        // An edit asks the converged solve for more: the bar starts again.
        let d = p.update(&stats(6.1, 1e-1, Some((4, 5))), false, tol);
        assert!((0.8..1.0).contains(&d), "{d}");
        // A new solve (its time starts again): from the start.
        let e = p.update(&stats(0.1, 1.0, Some((0, 5))), false, tol);
        assert_eq!(e, 0.0);
    }

    #[test]
    fn progress_of_the_other_methods_is_the_residual_s_way_to_the_tolerance() {
        let mut p = Progress::default();
        let a = p.update(&stats(1.0, 1e-2, None), false, 1e-4);
        assert!((a - 0.5).abs() < 1e-6, "{a}");
        // At the tolerance but refining adaptively: not yet full.
        let b = p.update(&stats(2.0, 1e-5, None), false, 1e-4);
        assert!((0.98..1.0).contains(&b), "{b}");
        assert_eq!(p.update(&stats(3.0, 1e-5, None), true, 1e-4), 1.0);
    }
}
