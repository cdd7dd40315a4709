//! The viewer window (eframe + wgpu) and the glue to the solver worker: [`Options`],
//! [`run`], the [`App`] with its window-wide state and one session (the opened scene's
//! state, `session.rs`), the worker's events, the keyboard shortcuts, and each frame's
//! order of work. The panels, the 3D view, the GPU, edits and files each have their own
//! file beside this one.
//!
//! The UI thread never solves: it sends [`Command`]s and drains [`Event`]s each frame, drops
//! events of jobs it has moved past, and uploads only the newest snapshot. Uploads are
//! throttled by their own measured cost (at most a quarter of the time), so a big scene's
//! snapshots cannot stall frames.

pub use super::edits::Placement;

use super::camera::Camera;
use super::files::{PathAction, Shots, load_recent};
use super::gpu::Gpu;
use super::render::{self, Display};
use super::session::{Session, Snap};
use crate::files::WriteError;
use crate::mesh::{Mesh, MeshSettings};
use crate::scene::{Material, Outside};
use crate::solver::{SolverSettings, Stats};
use crate::worker::{Command, Event, Worker};
use eframe::egui;
use glam::Vec3;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::{Sender, channel};
use std::time::{Duration, Instant};

/// What the viewer starts with.
#[derive(Clone, Debug)]
pub struct Options {
    /// A path or `builtin:NAME`.
    pub scene: String,
    pub mesh: MeshSettings,
    pub solver: SolverSettings,
    /// `--sky` and `--sun` for every scene opened.
    pub outside: Outside,
    /// Save a screenshot of the window to this file after `screenshot_after` seconds of
    /// solving, then exit.
    pub screenshot: Option<PathBuf>,
    pub screenshot_after: f64,
    /// Write frame-time statistics (JSON) here on exit; [`run`] fails when it cannot.
    pub frame_stats: Option<PathBuf>,
    /// Start with the wireframe on.
    pub wireframe: bool,
    /// Start with the textures off (each surface in the mean colour the solver used).
    pub no_textures: bool,
    /// Turn the camera a little every frame (to measure frame times while orbiting).
    pub orbit: bool,
    /// Start with the final gather on.
    pub final_gather: bool,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            scene: "builtin:cornell".into(),
            mesh: MeshSettings::default(),
            solver: SolverSettings {
                adaptive: Some(crate::mesh::AdaptiveSettings::default()),
                ..Default::default()
            },
            outside: Outside::default(),
            screenshot: None,
            screenshot_after: 3.0,
            frame_stats: None,
            wireframe: false,
            no_textures: false,
            orbit: false,
            final_gather: false,
        }
    }
}

/// Opens the window and runs until it is closed. Fails when the window cannot start, or
/// when the last write of the [`Options::frame_stats`] file failed (its error names the
/// file).
pub fn run(options: Options) -> anyhow::Result<()> {
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("radiosity")
            .with_inner_size([1280.0, 800.0])
            .with_drag_and_drop(true),
        renderer: eframe::Renderer::Wgpu,
        ..Default::default()
    };
    let (frame_stats_written, outcomes) = channel();
    eframe::run_native(
        "radiosity",
        native,
        Box::new(move |cc| {
            let mut app = App::new(cc, options);
            app.frame_stats_written = Some(frame_stats_written);
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| anyhow::anyhow!("the viewer window could not start: {e}"))?;
    match outcomes.try_iter().last() {
        Some(Err(e)) => Err(e.into()),
        _ => Ok(()),
    }
}

/// The viewer's state.
pub struct App {
    pub(super) worker: Worker,
    /// The opened scene.
    pub(super) session: Session,
    /// The settings the next scene (or mesh again) is loaded with.
    pub(super) mesh_settings: MeshSettings,
    pub(super) solver_settings: SolverSettings,
    /// `--sky` and `--sun`, applied to every scene opened.
    pub(super) outside: Outside,
    /// The element size field (0: automatic), applied when a scene is meshed.
    pub(super) element_size: f64,
    pub(super) camera: Camera,
    pub(super) display: Display,
    pub(super) auto_exposure: bool,
    /// The ambient term in the progressive display.
    pub(super) ambient: bool,
    /// Whether the worker was asked for the Hermite data (`Command::SetHermite`).
    pub(super) hermite_asked: bool,
    /// The status bar's last message.
    pub(super) status: String,
    /// Recently opened scene files, newest first.
    pub(super) recent: Vec<String>,
    /// The path field shown instead of a file dialog: its purpose and text.
    pub(super) prompt: Option<(PathAction, String)>,
    /// `None` without a wgpu renderer (no 3D view).
    pub(super) gpu: Option<Gpu>,
    /// Frame intervals recorded while solving, seconds.
    pub(super) frame_times: Vec<f32>,
    pub(super) last_frame: Option<Instant>,
    pub(super) shots: Shots,
    /// Where the 3D view was drawn last frame (points).
    pub(super) viewport_rect: Option<egui::Rect>,
    /// Turn the camera a little every frame.
    pub(super) orbit: bool,
    /// Fill the resting view with final-gathered pixels (see `final_gather`).
    pub(super) final_gather: bool,
    /// The `--frame-stats` file.
    pub(super) frame_stats: Option<PathBuf>,
    /// Where the outcome of each frame-statistics write goes (to [`run`]).
    pub(super) frame_stats_written: Option<Sender<Result<(), WriteError>>>,
}

impl App {
    /// The viewer for `options`: the worker started and `options.scene` opening.
    pub fn new(cc: &eframe::CreationContext<'_>, options: Options) -> App {
        let ctx = cc.egui_ctx.clone();
        let worker = Worker::spawn(move || ctx.request_repaint());
        let mut app = App {
            worker,
            session: Session::default(),
            element_size: options.mesh.element_size.unwrap_or(0.0),
            mesh_settings: options.mesh.clone(),
            solver_settings: options.solver.clone(),
            outside: options.outside,
            camera: Camera::default(),
            display: Display {
                wireframe: options.wireframe,
                textures: !options.no_textures,
                ..Default::default()
            },
            auto_exposure: true,
            ambient: true,
            hermite_asked: false,
            status: String::new(),
            recent: load_recent(),
            prompt: None,
            gpu: None,
            frame_times: Vec::new(),
            last_frame: None,
            shots: Shots::new(
                options
                    .screenshot
                    .clone()
                    .map(|p| (p, options.screenshot_after)),
            ),
            viewport_rect: None,
            orbit: options.orbit,
            final_gather: options.final_gather,
            frame_stats: options.frame_stats.clone(),
            frame_stats_written: None,
        };
        app.open(options.scene);
        match cc.wgpu_render_state.clone() {
            Some(state) => match render::unsupported(&state.adapter) {
                None => app.gpu = Some(Gpu::new(state)),
                Some(why) => app.session.error = Some(format!("{why}: the 3D view is unavailable")),
            },
            None => {
                app.session.error = Some("no wgpu renderer: the 3D view is unavailable".into());
            }
        }
        app
    }

    // Read-only views for tests and the headless screenshot.

    /// The scene being shown (a path or `builtin:NAME`).
    pub fn source(&self) -> &str {
        &self.session.source
    }
    pub fn stats(&self) -> &Stats {
        &self.session.stats
    }
    pub fn converged(&self) -> bool {
        self.session.converged
    }
    pub fn error(&self) -> Option<&str> {
        self.session.error.as_deref()
    }
    pub fn wireframe(&self) -> bool {
        self.display.wireframe
    }
    /// Whether the 3D view draws Hermite shading: chosen, and its data on the GPU (until
    /// then it draws Gouraud).
    pub fn hermite_shown(&self) -> bool {
        self.display.reconstruction == crate::mesh::Reconstruction::Hermite
            && self.session.uploads.hermite != 0
    }
    pub fn display(&self) -> &Display {
        &self.display
    }
    pub fn paused(&self) -> bool {
        self.session.paused
    }
    pub fn selected_object(&self) -> Option<u32> {
        self.session.selected
    }
    /// The clicked element and the links that light it (the link inspector).
    pub fn inspected(&self) -> Option<&crate::solver::ElementLinks> {
        self.session.inspected.as_ref()
    }

    pub fn selected_material(&self) -> Option<u32> {
        self.session.material
    }
    pub fn materials(&self) -> &[Material] {
        &self.session.materials
    }
    pub fn mesh(&self) -> Option<&Arc<Mesh>> {
        self.session.mesh.as_ref()
    }
    pub fn camera(&self) -> &Camera {
        &self.camera
    }
    /// The newest snapshot received: version and per-element radiosity.
    pub fn snapshot(&self) -> Option<(u64, Arc<[Vec3]>)> {
        self.session
            .snapshot
            .as_ref()
            .map(|s| (s.version, Arc::clone(&s.radiosity)))
    }
    /// Time from the last material edit to the frame that first showed it (its snapshot
    /// uploaded and drawn).
    pub fn edit_latency(&self) -> Option<Duration> {
        self.session.edits.edit_latency
    }
    /// Where the 3D view was drawn last frame (points).
    pub fn viewport_rect(&self) -> Option<egui::Rect> {
        self.viewport_rect
    }
    /// Frame intervals recorded while solving, seconds.
    pub fn frame_times(&self) -> &[f32] {
        &self.frame_times
    }

    /// The final gather's pass over the view: the fraction done and whether it finished
    /// (`None` while none runs).
    pub fn final_gather_progress(&self) -> Option<(f32, bool)> {
        let pass = self.session.pass.as_ref()?;
        let p = pass.picture.lock().unwrap_or_else(|e| e.into_inner());
        Some((p.done, p.finished))
    }

    /// Applies the worker's events of the current job; the others are stale.
    fn handle_events(&mut self) {
        for event in self.worker.drain() {
            if event.job() != self.session.job {
                continue; // a job we have moved past
            }
            match event {
                Event::Progress { stage, .. } => self.session.stage = Some(stage),
                Event::Loaded {
                    mesh,
                    bvh,
                    materials,
                    images,
                    objects,
                    warnings,
                    ..
                } => {
                    let edits = &mut self.session.edits;
                    if edits.base.is_empty() {
                        edits.base = objects.iter().map(|o| o.world_from_local).collect();
                    }
                    self.session.materials = materials;
                    self.session.images = images;
                    self.upload_mesh(&mesh);
                    let s = &mut self.session;
                    s.mesh = Some(mesh);
                    s.bvh = Some(bvh);
                    s.objects = objects;
                    s.warnings = warnings;
                    s.history.clear();
                    s.solve_started = Some(Instant::now());
                    if !s.camera_set {
                        self.default_camera();
                    }
                }
                Event::Snapshot {
                    version,
                    radiosity,
                    irradiance,
                    vertex,
                    hermite,
                    reflectance,
                    emission,
                    stats,
                    ..
                } => {
                    let s = &mut self.session;
                    if let Some((_, v @ None)) = &mut s.edits.edit_sent {
                        *v = Some(version);
                    }
                    s.record(&stats);
                    s.stats = stats;
                    s.converged = s.stats.converged;
                    if s.snapshot
                        .as_ref()
                        .is_none_or(|snap| version > snap.version)
                    {
                        s.snapshot = Some(Snap {
                            version,
                            radiosity,
                            irradiance,
                            vertex,
                            hermite,
                            reflectance,
                            emission,
                        });
                    }
                }
                Event::Converged { stats, .. } => {
                    let s = &mut self.session;
                    s.record(&stats);
                    s.stats = stats;
                    s.converged = true;
                    s.stage = None;
                }
                Event::Failed { error, .. } => {
                    self.session.error = Some(error.to_string());
                    self.session.stage = None;
                }
                Event::Refined { mesh, .. } => {
                    self.upload_mesh(&mesh);
                    self.status = format!("refined: {} elements", mesh.elements.len());
                    self.session.mesh = Some(mesh);
                }
                Event::Gatherer {
                    version, gatherer, ..
                } => self.session.gatherer = Some((version, gatherer)),
                Event::Inspected { links, .. } => self.session.inspected = links,
                Event::Exported { result, .. } => match result {
                    Ok(p) => self.status = format!("exported {}", p.display()),
                    Err(e) => self.session.error = Some(e.to_string()),
                },
            }
        }
    }

    /// The keyboard shortcuts (unless a text field has the keyboard): W wireframe, T
    /// textures, F frame all, Ctrl+Z undo, Ctrl+Shift+Z redo, Space pause or resume.
    fn keys(&mut self, ctx: &egui::Context) {
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        let (w, t, f, undo, redo, space) = ctx.input(|i| {
            (
                i.key_pressed(egui::Key::W) && i.modifiers.is_none(),
                i.key_pressed(egui::Key::T) && i.modifiers.is_none(),
                i.key_pressed(egui::Key::F) && i.modifiers.is_none(),
                i.key_pressed(egui::Key::Z) && i.modifiers.command && !i.modifiers.shift,
                i.key_pressed(egui::Key::Z) && i.modifiers.command && i.modifiers.shift,
                i.key_pressed(egui::Key::Space),
            )
        });
        if w {
            self.display.wireframe = !self.display.wireframe;
        }
        if t {
            self.display.textures = !self.display.textures;
        }
        if f {
            self.frame_all();
        }
        if undo {
            self.undo();
        }
        if redo {
            self.redo();
        }
        if space {
            self.toggle_pause();
        }
    }

    /// Pauses or resumes the solve.
    pub(super) fn toggle_pause(&mut self) {
        let s = &mut self.session;
        s.paused = !s.paused;
        self.worker.send(if s.paused {
            Command::Pause
        } else {
            Command::Resume
        });
    }
}

impl eframe::App for App {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        let now = Instant::now();
        let s = &self.session;
        let solving = s.stage.is_some() && !s.paused && !s.converged;
        if let Some(last) = self.last_frame
            && solving
            && s.mesh.is_some()
        {
            self.frame_times.push((now - last).as_secs_f32());
        }
        self.last_frame = Some(now);

        self.handle_events();
        self.upload();
        self.meter_view();
        self.upload_hermite();
        self.keys(&ctx);
        self.files_dropped(&ctx);
        self.screenshots(&ctx);

        egui::Panel::top("menu").show(ui, |ui| self.menu_ui(ui));
        egui::Panel::bottom("status").show(ui, |ui| self.status_bar_ui(ui));
        egui::Panel::left("side")
            .default_size(320.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.side_panel_ui(ui));
            });
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE)
            .show(ui, |ui| self.viewport_ui(ui));
        self.prompt_ui(&ctx);
        // Keep frames coming while the solution changes, so the view streams.
        if solving || self.orbit || self.shots.timed.is_some() || self.shots.awaited.is_some() {
            ctx.request_repaint();
        }
    }

    fn on_exit(&mut self) {
        self.write_frame_stats();
    }
}
