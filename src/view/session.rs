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
use crate::mesh::Mesh;
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
    /// Irradiance H per element and its Gouraud values per display-mesh vertex.
    pub(super) irradiance: Arc<[Vec3]>,
    pub(super) vertex: Arc<[Vec3]>,
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
