//! The viewer window (eframe + wgpu): menu, side panel (scene, selection, display, solver,
//! convergence plot), the 3D view, and the glue to the solver worker.
//!
//! The UI thread never solves: it sends [`Command`]s and drains [`Event`]s each frame, drops
//! events of jobs it has moved past, and uploads only the newest snapshot. Uploads are
//! throttled by their own measured cost (at most a quarter of the time), so a big scene's
//! snapshots cannot stall frames.

use super::camera::Camera;
use super::percentile;
use super::render::{Display, GpuMesh, Renderer, Target, ToneMap};
use crate::accel::Bvh;
use crate::mesh::{Mesh, MeshSettings, Reconstruction};
use crate::scene::Material;
use crate::solver::{Method, SolverSettings, Stats};
use crate::worker::{Command, Event, ObjectInfo, Source, Stage, Worker};
use eframe::egui;
use eframe::egui_wgpu;
use glam::{DMat4, DQuat, DVec3, Vec3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::{Duration, Instant};

/// What the viewer starts with.
#[derive(Clone, Debug)]
pub struct Options {
    /// A path or `builtin:NAME`.
    pub scene: String,
    pub mesh: MeshSettings,
    pub solver: SolverSettings,
    /// Save a screenshot of the window to this file after `screenshot_after` seconds of
    /// solving, then exit.
    pub screenshot: Option<PathBuf>,
    pub screenshot_after: f64,
    /// Write frame-time statistics (JSON) here on exit.
    pub frame_stats: Option<PathBuf>,
    /// Start with the wireframe on.
    pub wireframe: bool,
    /// Turn the camera a little every frame (to measure frame times while orbiting).
    pub orbit: bool,
    /// Let the worker pick stochastic Jacobi for very large scenes (the method was not
    /// chosen on the command line).
    pub auto_method: bool,
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
            screenshot: None,
            screenshot_after: 3.0,
            frame_stats: None,
            wireframe: false,
            orbit: false,
            auto_method: true,
        }
    }
}

/// Opens the window and runs until it is closed.
pub fn run(options: Options) -> anyhow::Result<()> {
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("radiosity")
            .with_inner_size([1280.0, 800.0])
            .with_drag_and_drop(true),
        renderer: eframe::Renderer::Wgpu,
        ..Default::default()
    };
    eframe::run_native(
        "radiosity",
        native,
        Box::new(move |cc| Ok(Box::new(App::new(cc, options)))),
    )
    .map_err(|e| anyhow::anyhow!("the viewer window could not start: {e}"))
}

/// An object's placement edit, relative to how it was loaded: about the centre of its
/// loaded bounding box, scale, then rotate (yaw, pitch, roll in degrees), then translate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    pub translate: [f64; 3],
    pub rotate_deg: [f64; 3],
    pub scale: [f64; 3],
}

impl Default for Placement {
    fn default() -> Self {
        Placement {
            translate: [0.0; 3],
            rotate_deg: [0.0; 3],
            scale: [1.0; 3],
        }
    }
}

impl Placement {
    /// World-from-local after this edit of an object loaded with `base`, centred at `c`.
    pub fn apply(&self, base: DMat4, c: DVec3) -> DMat4 {
        let [y, p, r] = self.rotate_deg.map(f64::to_radians);
        let rot = DQuat::from_euler(glam::EulerRot::YXZ, y, p, r);
        DMat4::from_translation(c + DVec3::from_array(self.translate))
            * DMat4::from_quat(rot)
            * DMat4::from_scale(DVec3::from_array(self.scale))
            * DMat4::from_translation(-c)
            * base
    }
}

struct Gpu {
    state: egui_wgpu::RenderState,
    renderer: Renderer,
    mesh: Option<GpuMesh>,
    target: Option<Target>,
    texture: Option<egui::TextureId>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PathAction {
    Open,
    Export,
    Screenshot,
}

/// Everything the 3D picture depends on.
#[derive(Clone, Copy, PartialEq)]
struct DrawKey {
    camera: Camera,
    display: Display,
    uploaded: u64,
    bezier: u64,
    size: [u32; 2],
}

struct Snap {
    version: u64,
    radiosity: Arc<[Vec3]>,
    vertex: Arc<[Vec3]>,
}

/// The viewer's state.
pub struct App {
    worker: Worker,
    job: u64,
    source: String,
    mesh_settings: MeshSettings,
    solver_settings: SolverSettings,
    element_size: f64,
    stage: Option<Stage>,
    error: Option<String>,
    warnings: Vec<String>,
    status: String,
    mesh: Option<Arc<Mesh>>,
    bvh: Option<Arc<Bvh>>,
    materials: Vec<Material>,
    objects: Vec<ObjectInfo>,
    base: Vec<DMat4>,
    placements: HashMap<u32, (Placement, DVec3)>,
    undo: Vec<(u32, Placement, Placement)>,
    redo: Vec<(u32, Placement, Placement)>,
    snapshot: Option<Snap>,
    uploaded: u64,
    upload_cost: Duration,
    last_upload: Option<Instant>,
    stats: Stats,
    converged: bool,
    paused: bool,
    history: Vec<[f64; 3]>,
    camera: Camera,
    camera_set: bool,
    display: Display,
    auto_exposure: bool,
    ambient: bool,
    selected: Option<u32>,
    material: Option<u32>,
    /// When the last material edit was sent, and the version of the first snapshot that
    /// carries it once it has arrived.
    edit_sent: Option<(Instant, Option<u64>)>,
    edit_latency: Option<Duration>,
    recent: Vec<String>,
    prompt: Option<(PathAction, String)>,
    gpu: Option<Gpu>,
    frame_times: Vec<f32>,
    last_frame: Option<Instant>,
    screenshot: Option<(PathBuf, f64)>,
    shot_rx: Option<(PathBuf, Receiver<Arc<egui::ColorImage>>)>,
    pending_shot: Option<Sender<Arc<egui::ColorImage>>>,
    /// The placement fields being edited (object, values) before they are committed.
    draft: Option<(u32, Placement)>,
    viewport_rect: Option<egui::Rect>,
    orbit: bool,
    auto_method: bool,
    /// What the 3D target shows now: it is drawn again only when this changes.
    drawn: Option<DrawKey>,
    /// When the last 3D draw started and what it cost (the interval to the next frame).
    last_draw: Option<(Instant, Duration)>,
    draw_started: Option<Instant>,
    /// The snapshot version whose Hermite control points are on the GPU.
    bezier_uploaded: u64,
    frame_stats: Option<PathBuf>,
    solve_started: Option<Instant>,
    close_after_shot: bool,
}

fn recent_path() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CONFIG_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".config")))?;
    Some(base.join("radiosity").join("recent.txt"))
}

fn load_recent() -> Vec<String> {
    recent_path()
        .and_then(|p| std::fs::read_to_string(p).ok())
        .map(|s| {
            s.lines()
                .map(str::to_owned)
                .filter(|l| !l.is_empty())
                .collect()
        })
        .unwrap_or_default()
}

/// The turbo colour map (Mikhailov 2019), the same polynomial as the shader's; sRGB.
fn turbo(t: f32) -> [f32; 3] {
    let x = t.clamp(0.0, 1.0);
    let r = 0.135_721_38
        + x * (4.615_392_6
            + x * (-42.660_32 + x * (132.131_08 + x * (-152.942_4 + x * 59.286_38))));
    let g = 0.091_402_61
        + x * (2.194_188_4
            + x * (4.842_966_6 + x * (-14.185_033 + x * (4.277_298_6 + x * 2.829_566))));
    let b = 0.106_673_3
        + x * (12.641_946 + x * (-60.582_05 + x * (110.362_77 + x * (-89.903_11 + x * 27.348_25))));
    [r.clamp(0.0, 1.0), g.clamp(0.0, 1.0), b.clamp(0.0, 1.0)]
}

fn linear_to_srgb(x: f32) -> f32 {
    if x <= 0.0031308 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

fn srgb_to_linear(x: f32) -> f32 {
    if x <= 0.04045 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

impl App {
    pub fn new(cc: &eframe::CreationContext<'_>, options: Options) -> App {
        let ctx = cc.egui_ctx.clone();
        let worker = Worker::spawn(move || ctx.request_repaint());
        let gpu = cc.wgpu_render_state.clone().map(|state| Gpu {
            renderer: Renderer::new(&state.device),
            state,
            mesh: None,
            target: None,
            texture: None,
        });
        let mut app = App {
            worker,
            job: 0,
            source: String::new(),
            element_size: options.mesh.element_size.unwrap_or(0.0),
            mesh_settings: options.mesh.clone(),
            solver_settings: options.solver.clone(),
            stage: None,
            error: None,
            warnings: Vec::new(),
            status: String::new(),
            mesh: None,
            bvh: None,
            materials: Vec::new(),
            objects: Vec::new(),
            base: Vec::new(),
            placements: HashMap::new(),
            undo: Vec::new(),
            redo: Vec::new(),
            snapshot: None,
            uploaded: 0,
            upload_cost: Duration::ZERO,
            last_upload: None,
            stats: Stats::default(),
            converged: false,
            paused: false,
            history: Vec::new(),
            camera: Camera::default(),
            camera_set: false,
            display: Display {
                wireframe: options.wireframe,
                ..Default::default()
            },
            auto_exposure: true,
            ambient: true,
            selected: None,
            material: None,
            edit_sent: None,
            edit_latency: None,
            recent: load_recent(),
            prompt: None,
            gpu,
            frame_times: Vec::new(),
            last_frame: None,
            screenshot: options
                .screenshot
                .clone()
                .map(|p| (p, options.screenshot_after)),
            shot_rx: None,
            pending_shot: None,
            draft: None,
            viewport_rect: None,
            orbit: options.orbit,
            auto_method: options.auto_method,
            drawn: None,
            last_draw: None,
            draw_started: None,
            bezier_uploaded: 0,
            frame_stats: options.frame_stats.clone(),
            solve_started: None,
            close_after_shot: options.screenshot.is_some(),
        };
        if app.gpu.is_none() {
            app.error = Some("no wgpu renderer: the 3D view is unavailable".into());
        }
        app.open(options.scene);
        app
    }

    // Read-only views for tests and the headless screenshot.

    /// The scene being shown (a path or `builtin:NAME`).
    pub fn source(&self) -> &str {
        &self.source
    }
    pub fn stats(&self) -> &Stats {
        &self.stats
    }
    pub fn converged(&self) -> bool {
        self.converged
    }
    pub fn error(&self) -> Option<&str> {
        self.error.as_deref()
    }
    pub fn wireframe(&self) -> bool {
        self.display.wireframe
    }
    pub fn display(&self) -> &Display {
        &self.display
    }
    pub fn paused(&self) -> bool {
        self.paused
    }
    pub fn selected_object(&self) -> Option<u32> {
        self.selected
    }
    pub fn selected_material(&self) -> Option<u32> {
        self.material
    }
    pub fn materials(&self) -> &[Material] {
        &self.materials
    }
    pub fn mesh(&self) -> Option<&Arc<Mesh>> {
        self.mesh.as_ref()
    }
    pub fn camera(&self) -> &Camera {
        &self.camera
    }
    /// The newest snapshot received: version and per-element radiosity.
    pub fn snapshot(&self) -> Option<(u64, Arc<[Vec3]>)> {
        self.snapshot
            .as_ref()
            .map(|s| (s.version, Arc::clone(&s.radiosity)))
    }
    /// Time from the last material edit to the frame that first showed it (its snapshot
    /// uploaded and drawn).
    pub fn edit_latency(&self) -> Option<Duration> {
        self.edit_latency
    }
    /// Where the 3D view was drawn last frame (points).
    pub fn viewport_rect(&self) -> Option<egui::Rect> {
        self.viewport_rect
    }
    /// Frame intervals recorded while solving, seconds.
    pub fn frame_times(&self) -> &[f32] {
        &self.frame_times
    }

    /// Opens a scene (a path or `builtin:NAME`) as a new job; the old job is cancelled.
    pub fn open(&mut self, source: String) {
        self.job += 1;
        self.source = source.clone();
        self.stage = Some(Stage::Loading);
        self.error = None;
        self.warnings.clear();
        self.mesh = None;
        self.bvh = None;
        self.snapshot = None;
        self.uploaded = 0;
        self.bezier_uploaded = 0;
        self.materials.clear();
        self.objects.clear();
        self.base.clear();
        self.placements.clear();
        self.undo.clear();
        self.redo.clear();
        self.selected = None;
        self.material = None;
        self.converged = false;
        self.paused = false;
        self.history.clear();
        self.camera_set = false;
        self.stats = Stats::default();
        if let Some(g) = &mut self.gpu {
            g.mesh = None;
        }
        self.mesh_settings.element_size = (self.element_size > 0.0).then_some(self.element_size);
        self.worker.send(Command::Load {
            job: self.job,
            source: Source(source.clone()),
            mesh: self.mesh_settings.clone(),
            solver: self.solver_settings.clone(),
            auto_method: self.auto_method,
        });
        if !self.ambient {
            self.worker.send(Command::SetAmbient(false));
        }
        if !source.starts_with("builtin:") {
            self.recent.retain(|r| *r != source);
            self.recent.insert(0, source);
            self.recent.truncate(10);
            if let Some(p) = recent_path() {
                let _ = std::fs::create_dir_all(p.parent().unwrap_or(Path::new(".")));
                let _ = crate::files::write_atomic(&p, self.recent.join("\n").as_bytes());
            }
        }
    }

    /// Sends a material edit (reflectance ρ linear, emitted radiance L_e) to the worker.
    pub fn edit_material(&mut self, material: u32, reflectance: Vec3, emission: Vec3) {
        if let Some(m) = self.materials.get_mut(material as usize) {
            m.reflectance = reflectance;
            m.emission = emission;
            self.worker.send(Command::SetMaterial {
                material,
                reflectance,
                emission,
            });
            self.edit_sent = Some((Instant::now(), None));
            self.converged = false;
        }
    }

    /// Places object `object` by `placement` (relative to how it was loaded), with undo.
    pub fn place(&mut self, object: u32, placement: Placement) {
        let Some(mesh) = &self.mesh else { return };
        let entry = self.placements.entry(object).or_insert_with(|| {
            // Centre of the object's loaded bounding box, world frame.
            let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            for p in mesh.patches.iter().filter(|p| p.object == object) {
                for v in p.verts {
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
            let c = if lo.x <= hi.x {
                ((lo + hi) * 0.5).as_dvec3() + mesh.origin
            } else {
                DVec3::ZERO
            };
            (Placement::default(), c)
        });
        let before = entry.0;
        if before == placement {
            return;
        }
        self.undo.push((object, before, placement));
        self.redo.clear();
        self.send_placement(object, placement);
    }

    fn send_placement(&mut self, object: u32, placement: Placement) {
        let Some(base) = self.base.get(object as usize).copied() else {
            return;
        };
        let Some(entry) = self.placements.get_mut(&object) else {
            return;
        };
        entry.0 = placement;
        self.draft = None;
        let m = placement.apply(base, entry.1);
        self.worker.send(Command::SetTransform {
            object,
            world_from_local: m,
        });
        self.converged = false;
        self.status = format!("moving object {object}: meshing again");
    }

    pub fn undo(&mut self) {
        if let Some((o, before, after)) = self.undo.pop() {
            self.redo.push((o, before, after));
            self.send_placement(o, before);
        }
    }

    pub fn redo(&mut self) {
        if let Some((o, before, after)) = self.redo.pop() {
            self.undo.push((o, before, after));
            self.send_placement(o, after);
        }
    }

    /// Selects the object under pixel (`x`, `y`) of a `w`×`h` view, or clears the selection.
    pub fn pick(&mut self, x: f32, y: f32, w: f32, h: f32) {
        let (Some(mesh), Some(bvh)) = (&self.mesh, &self.bvh) else {
            return;
        };
        let (o, d) = self.camera.ray(x, y, w, h);
        let hit = bvh.closest_hit(o, d, 0.0, f32::INFINITY, u32::MAX);
        let patch = hit.and_then(|h| {
            let r = mesh.triangle_patches.get(h.triangle as usize)?;
            (!r.is_empty()).then(|| &mesh.patches[r.start as usize])
        });
        self.selected = patch.map(|p| p.object);
        self.material = patch.map(|p| p.material);
        self.display.selected = self.selected;
    }

    fn handle_events(&mut self) {
        for event in self.worker.drain() {
            if event.job() != self.job {
                continue; // a job we have moved past
            }
            match event {
                Event::Progress { stage, .. } => self.stage = Some(stage),
                Event::Loaded {
                    mesh,
                    bvh,
                    materials,
                    objects,
                    warnings,
                    ..
                } => {
                    if self.base.is_empty() {
                        self.base = objects.iter().map(|o| o.world_from_local).collect();
                    }
                    if let Some(g) = &mut self.gpu {
                        g.mesh = Some(g.renderer.upload(&g.state.device, &mesh));
                    }
                    self.uploaded = 0;
                    self.bezier_uploaded = 0;
                    self.snapshot = None;
                    self.mesh = Some(mesh);
                    self.bvh = Some(bvh);
                    self.materials = materials;
                    self.objects = objects;
                    self.warnings = warnings;
                    self.history.clear();
                    self.solve_started = Some(Instant::now());
                    if !self.camera_set {
                        self.default_camera();
                    }
                }
                Event::Snapshot {
                    version,
                    radiosity,
                    vertex,
                    stats,
                    ..
                } => {
                    if let Some((_, v @ None)) = &mut self.edit_sent {
                        *v = Some(version);
                    }
                    self.record(&stats);
                    if let Some(m) = stats.method
                        && m != self.solver_settings.method
                        && self.auto_method
                    {
                        // The worker chose the method by size: show it.
                        self.solver_settings.method = m;
                        self.status = format!("large scene: solving with {m}");
                    }
                    self.stats = stats;
                    self.converged = self.stats.converged;
                    if self.snapshot.as_ref().is_none_or(|s| version > s.version) {
                        self.snapshot = Some(Snap {
                            version,
                            radiosity,
                            vertex,
                        });
                    }
                }
                Event::Converged { stats, .. } => {
                    self.record(&stats);
                    self.stats = stats;
                    self.converged = true;
                    self.stage = None;
                }
                Event::Failed { error, .. } => {
                    self.error = Some(error.to_string());
                    self.stage = None;
                }
                Event::Refined { mesh, .. } => {
                    if let Some(g) = &mut self.gpu {
                        g.mesh = Some(g.renderer.upload(&g.state.device, &mesh));
                    }
                    self.uploaded = 0;
                    self.bezier_uploaded = 0;
                    self.snapshot = None;
                    self.status = format!("refined: {} elements", mesh.elements.len());
                    self.mesh = Some(mesh);
                }
                Event::Exported { result, .. } => match result {
                    Ok(p) => self.status = format!("exported {}", p.display()),
                    Err(e) => self.error = Some(e.to_string()),
                },
            }
        }
    }

    fn record(&mut self, stats: &Stats) {
        let t = stats.seconds;
        let u = stats.unshot_fraction.unwrap_or(f64::NAN);
        let r = stats.residual.unwrap_or(f64::NAN);
        if self.history.last().is_none_or(|h| t > h[0]) {
            self.history.push([t, u, r]);
        }
    }

    fn default_camera(&mut self) {
        if let (Some(mesh), Some(bvh)) = (&self.mesh, &self.bvh) {
            self.camera = super::default_camera(mesh, bvh);
            self.camera_set = true;
        }
    }

    fn frame_all(&mut self) {
        if let Some((c, r)) = self.mesh.as_deref().and_then(super::bounds) {
            self.camera.frame(c, r);
        }
    }

    /// Hermite display needs the control points of the uploaded snapshot: computed here
    /// when the mode is on and they are missing (the other modes never pay for them).
    fn upload_bezier(&mut self) {
        if self.display.reconstruction != Reconstruction::Hermite
            || self.uploaded == 0
            || self.bezier_uploaded == self.uploaded
        {
            return;
        }
        let (Some(g), Some(s), Some(mesh)) = (&self.gpu, &self.snapshot, &self.mesh) else {
            return;
        };
        let Some(gm) = &g.mesh else { return };
        if !gm.supports_hermite() {
            self.display.reconstruction = Reconstruction::Gouraud;
            self.status = "too many elements for Hermite display on this device".into();
            return;
        }
        if s.version != self.uploaded || s.radiosity.len() != mesh.elements.len() {
            return;
        }
        let points = super::render::bezier_points(mesh, &s.radiosity);
        if gm.set_bezier(&g.state.queue, &points) {
            self.bezier_uploaded = self.uploaded;
        }
    }

    /// Uploads the newest snapshot unless the last upload was too recent for its cost.
    fn upload(&mut self) {
        let Some(s) = &self.snapshot else { return };
        if s.version == self.uploaded {
            return;
        }
        // A fresh GPU mesh has nothing to show: upload at once. Otherwise at most a quarter
        // of the time goes to uploads.
        if self.uploaded != 0
            && let Some(t) = self.last_upload
            && t.elapsed() < self.upload_cost * 3
        {
            return;
        }
        let Some(g) = &self.gpu else { return };
        let Some(gm) = &g.mesh else { return };
        let start = Instant::now();
        if gm.set_values(&g.state.queue, &s.radiosity, &s.vertex) {
            self.uploaded = s.version;
            // The edit's first snapshot is on the GPU and is drawn this frame.
            if let Some((t, Some(v))) = self.edit_sent
                && self.uploaded >= v
            {
                self.edit_latency = Some(t.elapsed());
                self.edit_sent = None;
            }
        }
        self.upload_cost = start.elapsed();
        self.last_upload = Some(Instant::now());
        if self.auto_exposure {
            self.expose();
        }
    }

    fn expose(&mut self) {
        if let (Some(s), Some(mesh)) = (&self.snapshot, &self.mesh)
            && let Some((ev, range)) = super::auto_exposure(mesh, &s.radiosity)
        {
            self.display.ev = ev;
            self.display.log_range = range;
        }
    }

    fn save_screenshot(&mut self, path: &Path, image: &egui::ColorImage) {
        let [w, h] = image.size;
        let bytes: Vec<u8> = image.pixels.iter().flat_map(|c| c.to_array()).collect();
        let result = image::RgbaImage::from_raw(w as u32, h as u32, bytes)
            .ok_or_else(|| anyhow::anyhow!("screenshot has the wrong size"))
            .and_then(|img| super::write_png(path, &img));
        match result {
            Ok(()) => self.status = format!("screenshot saved to {}", path.display()),
            Err(e) => self.error = Some(format!("{e:#}")),
        }
    }

    fn write_frame_stats(&self) {
        let Some(path) = &self.frame_stats else {
            return;
        };
        let mut t: Vec<f32> = self.frame_times.clone();
        let n = t.len();
        let p50 = percentile(&mut t, 0.5);
        let p99 = percentile(&mut t, 0.99);
        let max = percentile(&mut t, 1.0);
        let adapter = self
            .gpu
            .as_ref()
            .map(|g| {
                let i = g.state.adapter.get_info();
                format!("{} ({:?})", i.name, i.backend)
            })
            .unwrap_or_default();
        let json = serde_json::json!({
            "scene": self.source,
            "frames": n,
            "p50_ms": p50 * 1e3,
            "p99_ms": p99 * 1e3,
            "max_ms": max * 1e3,
            "elements": self.stats.elements,
            "adapter": adapter,
            "solver_seconds": self.stats.seconds,
            "iterations": self.stats.iterations,
        });
        let _ = crate::files::write_atomic(path, json.to_string().as_bytes());
    }

    /// A file dialog, or the path field when no dialog service answers. rfd's portal
    /// backend returns `None` within milliseconds when no portal runs; a person cannot
    /// cancel that fast, so a quick `None` means "no dialog available".
    fn ask_path(&mut self, action: PathAction) {
        let start = Instant::now();
        let dialog = rfd::FileDialog::new();
        let picked = match action {
            PathAction::Open => dialog.add_filter("glTF", &["gltf", "glb"]).pick_file(),
            PathAction::Export => dialog
                .add_filter("binary glTF", &["glb"])
                .set_file_name("baked.glb")
                .save_file(),
            PathAction::Screenshot => dialog
                .add_filter("PNG", &["png"])
                .set_file_name("screenshot.png")
                .save_file(),
        };
        match picked {
            Some(p) => self.path_chosen(action, p),
            None if start.elapsed() < Duration::from_millis(250) => {
                self.prompt = Some((action, String::new()));
            }
            None => {}
        }
    }

    fn path_chosen(&mut self, action: PathAction, path: PathBuf) {
        match action {
            PathAction::Open => self.open(path.to_string_lossy().into_owned()),
            PathAction::Export => self.worker.send(Command::Export { path }),
            PathAction::Screenshot => self.request_screenshot(path),
        }
    }

    fn request_screenshot(&mut self, path: PathBuf) {
        let (tx, rx) = channel();
        self.shot_rx = Some((path, rx));
        self.pending_shot = Some(tx);
    }
}

impl eframe::App for App {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        let now = Instant::now();
        let solving = self.stage.is_some() && !self.paused && !self.converged;
        if let Some(last) = self.last_frame
            && solving
            && self.mesh.is_some()
        {
            self.frame_times.push((now - last).as_secs_f32());
        }
        self.last_frame = Some(now);

        self.handle_events();
        self.upload();
        self.upload_bezier();
        self.keys(&ctx);
        self.files_dropped(&ctx);
        self.screenshots(&ctx);

        egui::Panel::top("menu").show(ui, |ui| self.menu(ui));
        egui::Panel::bottom("status").show(ui, |ui| self.status_bar(ui));
        egui::Panel::left("side")
            .default_size(320.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.side_panel(ui));
            });
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE)
            .show(ui, |ui| self.viewport(ui));
        if let Some((action, mut text)) = self.prompt.take() {
            let mut keep = true;
            let mut chosen = None;
            egui::Window::new("Path")
                .collapsible(false)
                .show(&ctx, |ui| {
                    ui.label(match action {
                        PathAction::Open => {
                            "No file dialog is available. Scene to open (.gltf / .glb):"
                        }
                        PathAction::Export => "No file dialog is available. Export to (.glb):",
                        PathAction::Screenshot => {
                            "No file dialog is available. Save screenshot to (.png):"
                        }
                    });
                    let r = ui.text_edit_singleline(&mut text);
                    ui.horizontal(|ui| {
                        if ui.button("OK").clicked()
                            || (r.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter)))
                        {
                            chosen = Some(PathBuf::from(text.trim()));
                        }
                        if ui.button("Cancel").clicked() {
                            keep = false;
                        }
                    });
                });
            match chosen {
                Some(p) if !p.as_os_str().is_empty() => self.path_chosen(action, p),
                _ if keep => self.prompt = Some((action, text)),
                _ => {}
            }
        }
        // Keep frames coming while the solution changes, so the view streams.
        if solving || self.orbit || self.screenshot.is_some() || self.shot_rx.is_some() {
            ctx.request_repaint();
        }
    }

    fn on_exit(&mut self) {
        self.write_frame_stats();
    }
}

impl App {
    fn keys(&mut self, ctx: &egui::Context) {
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        let (w, f, undo, redo, space) = ctx.input(|i| {
            (
                i.key_pressed(egui::Key::W) && i.modifiers.is_none(),
                i.key_pressed(egui::Key::F) && i.modifiers.is_none(),
                i.key_pressed(egui::Key::Z) && i.modifiers.command && !i.modifiers.shift,
                i.key_pressed(egui::Key::Z) && i.modifiers.command && i.modifiers.shift,
                i.key_pressed(egui::Key::Space),
            )
        });
        if w {
            self.display.wireframe = !self.display.wireframe;
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

    fn toggle_pause(&mut self) {
        self.paused = !self.paused;
        self.worker.send(if self.paused {
            Command::Pause
        } else {
            Command::Resume
        });
    }

    fn files_dropped(&mut self, ctx: &egui::Context) {
        let dropped: Vec<PathBuf> = ctx.input(|i| {
            i.raw
                .dropped_files
                .iter()
                .map(|f| f.path().to_path_buf())
                .filter(|p| !p.as_os_str().is_empty())
                .collect()
        });
        if let Some(p) = dropped.into_iter().next() {
            let ext = p
                .extension()
                .map(|e| e.to_string_lossy().to_lowercase())
                .unwrap_or_default();
            if ext == "gltf" || ext == "glb" {
                self.open(p.to_string_lossy().into_owned());
            } else {
                self.error = Some(format!("{}: not a .gltf or .glb file", p.display()));
            }
        }
    }

    fn screenshots(&mut self, ctx: &egui::Context) {
        // The timed screenshot of `view --screenshot`: after the delay, once a snapshot is
        // on screen.
        if let Some((path, after)) = &self.screenshot
            && self.uploaded > 0
            && self
                .solve_started
                .is_some_and(|t| t.elapsed().as_secs_f64() >= *after)
        {
            let path = path.clone();
            self.screenshot = None;
            self.request_screenshot(path);
        } else if let Some((_, after)) = &self.screenshot
            && self.error.is_some()
            && self
                .solve_started
                .is_none_or(|t| t.elapsed().as_secs_f64() >= *after)
        {
            // Failed before any snapshot: still take the shot (it shows the error).
            let path = self.screenshot.take().map(|s| s.0).unwrap_or_default();
            self.request_screenshot(path);
        }
        if let Some(tx) = self.pending_shot.take() {
            ctx.request_screenshot(move |image| {
                let _ = tx.send(image);
            });
        }
        if let Some((path, rx)) = self.shot_rx.take() {
            match rx.try_recv() {
                Ok(image) => {
                    self.save_screenshot(&path, &image);
                    if self.close_after_shot {
                        self.write_frame_stats();
                        if let Some(e) = &self.error {
                            eprintln!("radiosity view: {e}");
                        }
                        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                    }
                }
                Err(std::sync::mpsc::TryRecvError::Empty) => self.shot_rx = Some((path, rx)),
                Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                    self.error = Some("the screenshot was not delivered".into());
                }
            }
        }
    }

    fn menu(&mut self, ui: &mut egui::Ui) {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                if ui.button("Open…").clicked() {
                    ui.close();
                    self.ask_path(PathAction::Open);
                }
                ui.menu_button("Open Recent", |ui| {
                    if self.recent.is_empty() {
                        ui.label("(none)");
                    }
                    let mut chosen = None;
                    for r in &self.recent {
                        if ui.button(r).clicked() {
                            chosen = Some(r.clone());
                        }
                    }
                    ui.separator();
                    for name in crate::scene::builtin::NAMES {
                        let spec = format!("builtin:{name}");
                        if ui.button(&spec).clicked() {
                            chosen = Some(spec);
                        }
                    }
                    if let Some(c) = chosen {
                        ui.close();
                        self.open(c);
                    }
                });
                if ui.button("Export baked glTF…").clicked() {
                    ui.close();
                    self.ask_path(PathAction::Export);
                }
                if ui.button("Save Screenshot…").clicked() {
                    ui.close();
                    self.ask_path(PathAction::Screenshot);
                }
                ui.separator();
                if ui.button("Quit").clicked() {
                    ui.ctx().send_viewport_cmd(egui::ViewportCommand::Close);
                }
            });
            ui.menu_button("Edit", |ui| {
                if ui
                    .add_enabled(
                        !self.undo.is_empty(),
                        egui::Button::new("Undo move (Ctrl+Z)"),
                    )
                    .clicked()
                {
                    self.undo();
                }
                if ui
                    .add_enabled(
                        !self.redo.is_empty(),
                        egui::Button::new("Redo move (Ctrl+Shift+Z)"),
                    )
                    .clicked()
                {
                    self.redo();
                }
            });
            ui.menu_button("View", |ui| {
                ui.checkbox(&mut self.display.wireframe, "Wireframe (W)");
                if ui.button("Frame all (F)").clicked() {
                    self.frame_all();
                }
            });
        });
    }

    fn status_bar(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            let stage = match (self.stage, self.converged, self.paused) {
                (_, true, _) => "converged".to_string(),
                (_, _, true) => "paused".to_string(),
                (Some(Stage::Loading), ..) => "loading…".to_string(),
                (Some(Stage::Meshing), ..) => "meshing and building the BVH…".to_string(),
                (Some(Stage::Solving), ..) => "solving".to_string(),
                (None, ..) => "idle".to_string(),
            };
            ui.label(format!("{}: {stage}", self.source));
            let progress = match self.stats.residual {
                Some(r) if r > 0.0 => {
                    let tol = self.solver_settings.tolerance.max(1e-12);
                    (r.ln() / tol.ln()).clamp(0.0, 1.0) as f32
                }
                Some(_) => 1.0,
                None => 0.0,
            };
            let progress = if self.converged { 1.0 } else { progress };
            ui.add(
                egui::ProgressBar::new(progress)
                    .desired_width(200.0)
                    .show_percentage(),
            );
            if !self.status.is_empty() {
                ui.label(&self.status);
            }
        });
    }

    fn side_panel(&mut self, ui: &mut egui::Ui) {
        if let Some(e) = self.error.clone() {
            ui.horizontal_wrapped(|ui| {
                ui.colored_label(egui::Color32::from_rgb(230, 80, 60), format!("Error: {e}"));
                if ui.small_button("dismiss").clicked() {
                    self.error = None;
                }
            });
            ui.separator();
        }
        if !self.warnings.is_empty() {
            egui::CollapsingHeader::new(format!("Warnings ({})", self.warnings.len())).show(
                ui,
                |ui| {
                    for w in &self.warnings {
                        ui.label(w);
                    }
                },
            );
        }
        egui::CollapsingHeader::new("Statistics")
            .default_open(true)
            .show(ui, |ui| self.stats_ui(ui));
        egui::CollapsingHeader::new("Display")
            .default_open(true)
            .show(ui, |ui| self.display_ui(ui));
        egui::CollapsingHeader::new("Selection")
            .default_open(true)
            .show(ui, |ui| self.selection_ui(ui));
        egui::CollapsingHeader::new("Solver")
            .default_open(true)
            .show(ui, |ui| self.solver_ui(ui));
        egui::CollapsingHeader::new("Convergence")
            .default_open(true)
            .show(ui, |ui| self.plot_ui(ui));
    }

    fn stats_ui(&mut self, ui: &mut egui::Ui) {
        let s = &self.stats;
        let secs = s.seconds.max(1e-9);
        egui::Grid::new("stats").num_columns(2).show(ui, |ui| {
            let mut row = |k: &str, v: String| {
                ui.label(k);
                ui.label(v);
                ui.end_row();
            };
            row("elements", s.elements.to_string());
            row("patches", s.patches.to_string());
            row("shots / sweeps", s.iterations.to_string());
            row("rays/s", format!("{:.2} M", s.rays as f64 / secs / 1e6));
            row(
                "unshot fraction",
                s.unshot_fraction.map_or("–".into(), |u| format!("{u:.2e}")),
            );
            row(
                "residual",
                s.residual.map_or("–".into(), |u| format!("{u:.2e}")),
            );
            row("elapsed", format!("{:.2} s", s.seconds));
            if let Some(l) = self.edit_latency {
                row(
                    "last edit to frame",
                    format!("{:.0} ms", l.as_secs_f64() * 1e3),
                );
            }
            if !self.frame_times.is_empty() {
                let mut t: Vec<f32> = self.frame_times.iter().rev().take(600).copied().collect();
                let p50 = percentile(&mut t, 0.5);
                let p99 = percentile(&mut t, 0.99);
                row(
                    "frame p50 / p99",
                    format!("{:.1} / {:.1} ms", p50 * 1e3, p99 * 1e3),
                );
            }
        });
        ui.horizontal(|ui| {
            let label = if self.paused { "Resume" } else { "Pause" };
            if ui.button(label).clicked() {
                self.toggle_pause();
            }
            if ui.button("Reset").clicked() {
                self.worker.send(Command::Reset);
                self.history.clear();
                self.converged = false;
                self.stage = Some(Stage::Solving);
            }
        });
    }

    fn display_ui(&mut self, ui: &mut egui::Ui) {
        let d = &mut self.display;
        ui.checkbox(&mut d.wireframe, "Wireframe (W)");
        ui.horizontal(|ui| {
            ui.label("Shading");
            ui.selectable_value(&mut d.reconstruction, Reconstruction::Flat, "flat");
            ui.selectable_value(&mut d.reconstruction, Reconstruction::Gouraud, "Gouraud");
            ui.selectable_value(&mut d.reconstruction, Reconstruction::Hermite, "Hermite");
        });
        ui.checkbox(&mut d.false_colour, "False colour (log radiosity)");
        let r = ui.add(egui::Slider::new(&mut d.ev, -20.0..=20.0).text("Exposure (EV)"));
        // Only a person's change turns auto exposure off (not the slider's own clamping).
        if r.changed() && (r.dragged() || r.clicked() || r.has_focus()) {
            self.auto_exposure = false;
        }
        ui.checkbox(&mut self.auto_exposure, "Auto exposure");
        egui::ComboBox::from_label("Tone mapping")
            .selected_text(d.tonemap.name())
            .show_ui(ui, |ui| {
                for t in ToneMap::ALL {
                    ui.selectable_value(&mut d.tonemap, t, t.name());
                }
            });
        if d.false_colour {
            // The legend: the shader's colour map from the low to the high end.
            let (rect, _) = ui.allocate_exact_size(egui::vec2(220.0, 12.0), egui::Sense::hover());
            let n = 64;
            for k in 0..n {
                let t0 = k as f32 / n as f32;
                let x0 = rect.left() + rect.width() * t0;
                let x1 = rect.left() + rect.width() * (k + 1) as f32 / n as f32;
                let [r, g, b] = turbo(t0 + 0.5 / n as f32);
                ui.painter().rect_filled(
                    egui::Rect::from_min_max(
                        egui::pos2(x0, rect.top()),
                        egui::pos2(x1, rect.bottom()),
                    ),
                    0.0,
                    egui::Color32::from_rgb(
                        (r * 255.0) as u8,
                        (g * 255.0) as u8,
                        (b * 255.0) as u8,
                    ),
                );
            }
            ui.label(format!(
                "radiosity 10^{:.1} to 10^{:.1} W/m² (log scale)",
                d.log_range.0, d.log_range.1
            ));
        }
        if ui
            .checkbox(&mut self.ambient, "Ambient term preview")
            .changed()
        {
            self.worker.send(Command::SetAmbient(self.ambient));
        }
    }

    fn selection_ui(&mut self, ui: &mut egui::Ui) {
        let Some(object) = self.selected else {
            ui.label("Click an object in the view to select it.");
            return;
        };
        let name = self
            .objects
            .get(object as usize)
            .map(|o| o.name.clone())
            .unwrap_or_default();
        ui.label(format!("Object {object}: {name}"));
        if let Some(mi) = self.material
            && let Some(m) = self.materials.get(mi as usize).cloned()
        {
            ui.label(format!("Material {mi}: {}", m.name));
            let mut rho = m.reflectance;
            let mut srgb = rho.to_array().map(linear_to_srgb);
            let mut changed = false;
            ui.horizontal(|ui| {
                let label = ui.label("Reflectance");
                if ui
                    .color_edit_button_rgb(&mut srgb)
                    .labelled_by(label.id)
                    .changed()
                {
                    rho = Vec3::from_array(srgb.map(srgb_to_linear));
                    changed = true;
                }
            });
            ui.horizontal(|ui| {
                let label = ui.label("ρ (linear)");
                for c in 0..3 {
                    changed |= ui
                        .add(
                            egui::DragValue::new(&mut rho[c])
                                .range(0.0..=0.999)
                                .speed(0.002)
                                .max_decimals(3),
                        )
                        .labelled_by(label.id)
                        .changed();
                }
            });
            let mut strength = m.emission.max_element();
            let mut colour = if strength > 0.0 {
                (m.emission / strength).to_array().map(linear_to_srgb)
            } else {
                [1.0; 3]
            };
            ui.horizontal(|ui| {
                let label = ui.label("Emission");
                changed |= ui
                    .color_edit_button_rgb(&mut colour)
                    .labelled_by(label.id)
                    .changed();
                let label = ui.label("strength");
                changed |= ui
                    .add(
                        egui::DragValue::new(&mut strength)
                            .range(0.0..=1e9)
                            .speed(0.05)
                            .suffix(" W/(m²·sr)"),
                    )
                    .labelled_by(label.id)
                    .changed();
            });
            if changed {
                let emission = Vec3::from_array(colour.map(srgb_to_linear)) * strength;
                self.edit_material(mi, rho.clamp(Vec3::ZERO, Vec3::splat(0.999)), emission);
            }
        }
        ui.separator();
        ui.label("Move (about the object's centre; Ctrl+Z undoes)");
        let committed = self
            .placements
            .get(&object)
            .map(|e| e.0)
            .unwrap_or_default();
        let mut p = match self.draft {
            Some((o, d)) if o == object => d,
            _ => committed,
        };
        let mut commit = false;
        let mut field = |ui: &mut egui::Ui, label: &str, v: &mut [f64; 3], speed: f64| {
            ui.horizontal(|ui| {
                let label = ui.label(label);
                for x in v.iter_mut() {
                    let r = ui
                        .add(egui::DragValue::new(x).speed(speed).max_decimals(3))
                        .labelled_by(label.id);
                    // Mesh again when a drag ends or a typed value is entered, not on
                    // every pixel of a drag.
                    if r.drag_stopped() || (r.changed() && !r.dragged()) {
                        commit = true;
                    }
                }
            });
        };
        let speed = (self.camera.scene_radius as f64 * 0.005).max(1e-6);
        field(ui, "translate", &mut p.translate, speed);
        field(ui, "rotate °", &mut p.rotate_deg, 0.5);
        field(ui, "scale", &mut p.scale, 0.005);
        p.scale = p.scale.map(|s| if s.abs() < 1e-6 { 1e-6 } else { s });
        self.draft = Some((object, p));
        if commit && p != committed {
            self.place(object, p);
        }
        ui.horizontal(|ui| {
            if ui.button("Reset placement").clicked() {
                self.place(object, Placement::default());
            }
        });
    }

    fn solver_ui(&mut self, ui: &mut egui::Ui) {
        let mut s = self.solver_settings.clone();
        egui::ComboBox::from_label("Method")
            .selected_text(s.method.name())
            .show_ui(ui, |ui| {
                for m in Method::ALL {
                    ui.selectable_value(&mut s.method, m, m.name());
                }
            });
        ui.horizontal(|ui| {
            let label = ui.label("Tolerance");
            let speed = s.tolerance * 0.05;
            ui.add(
                egui::DragValue::new(&mut s.tolerance)
                    .range(1e-8..=0.5)
                    .speed(speed)
                    .custom_formatter(|v, _| format!("{v:.1e}")),
            )
            .labelled_by(label.id);
        });
        let mut adaptive = s.adaptive.is_some();
        ui.checkbox(&mut adaptive, "Adaptive subdivision");
        if adaptive != s.adaptive.is_some() {
            s.adaptive = adaptive.then(crate::mesh::AdaptiveSettings::default);
        }
        if let Some(a) = &mut s.adaptive {
            ui.horizontal(|ui| {
                let label = ui.label("contrast threshold (ln)");
                ui.add(
                    egui::DragValue::new(&mut a.threshold)
                        .range(0.01..=5.0)
                        .speed(0.01),
                )
                .labelled_by(label.id);
            });
            ui.horizontal(|ui| {
                let label = ui.label("min element size (m, 0 = auto)");
                let mut m = a.min_size.unwrap_or(0.0);
                ui.add(
                    egui::DragValue::new(&mut m)
                        .range(0.0..=1e6)
                        .speed(0.001)
                        .max_decimals(4),
                )
                .labelled_by(label.id);
                a.min_size = (m > 0.0).then_some(m);
            });
        }
        if s.method != self.solver_settings.method {
            self.auto_method = false;
        }
        if s != self.solver_settings {
            self.solver_settings = s.clone();
            self.worker.send(Command::SetSettings(s));
            self.history.clear();
            self.converged = false;
            self.stage = Some(Stage::Solving);
        }
        ui.horizontal(|ui| {
            let label = ui.label("Element size (m, 0 = auto)");
            ui.add(
                egui::DragValue::new(&mut self.element_size)
                    .range(0.0..=1e6)
                    .speed(0.002)
                    .max_decimals(4),
            )
            .labelled_by(label.id);
        });
        let current = self.mesh.as_ref().map(|m| m.element_size).unwrap_or(0.0);
        ui.label(format!("in use: {current:.4} m"));
        let toggled = ui
            .checkbox(
                &mut self.mesh_settings.contact_lines,
                "Split at contact lines",
            )
            .on_hover_text(
                "Cut surfaces where others touch or pierce them (a box's base on a floor), \
                 so light and shadow do not leak across; meshes again",
            )
            .changed();
        if ui.button("Mesh again with this size").clicked() || toggled {
            let source = self.source.clone();
            self.open(source);
        }
    }

    fn plot_ui(&mut self, ui: &mut egui::Ui) {
        use egui_plot::{Line, Plot, PlotPoints};
        let log = |i: usize| -> PlotPoints<'static> {
            self.history
                .iter()
                .filter(|h| h[i].is_finite() && h[i] > 0.0)
                .map(|h| [h[0], h[i].log10()])
                .collect()
        };
        Plot::new("convergence")
            .height(160.0)
            .x_axis_label("solver time (s)")
            // Values are log10; label whole decades only.
            .y_axis_formatter(|m, _| {
                if (m.value - m.value.round()).abs() < 1e-6 {
                    format!("1e{:.0}", m.value)
                } else {
                    String::new()
                }
            })
            .legend(egui_plot::Legend::default())
            .show(ui, |p| {
                p.line(Line::new("unshot fraction", log(1)));
                p.line(Line::new("residual", log(2)));
            });
    }

    fn viewport(&mut self, ui: &mut egui::Ui) {
        let rect = ui.available_rect_before_wrap();
        self.viewport_rect = Some(rect);
        let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
        // Camera: left drag orbits, middle drag or shift+left drag pans, wheel zooms.
        let shift = ui.input(|i| i.modifiers.shift);
        let delta = response.drag_delta();
        if response.dragged_by(egui::PointerButton::Middle)
            || (response.dragged_by(egui::PointerButton::Primary) && shift)
        {
            self.camera.pan(delta.x, delta.y, rect.height());
        } else if response.dragged_by(egui::PointerButton::Primary) {
            self.camera.orbit(delta.x, delta.y);
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.camera.zoom(scroll);
            }
        }
        if response.clicked()
            && let Some(pos) = response.interact_pointer_pos()
        {
            let p = pos - rect.min;
            self.pick(p.x, p.y, rect.width(), rect.height());
        }
        let ppp = ui.ctx().pixels_per_point();
        let size = [
            (rect.width() * ppp).round().max(1.0) as u32,
            (rect.height() * ppp).round().max(1.0) as u32,
        ];
        let Some(g) = &mut self.gpu else {
            ui.painter()
                .rect_filled(rect, 0.0, egui::Color32::from_gray(20));
            return;
        };
        if g.target.as_ref().is_none_or(|t| t.size != size) {
            let target = Target::new(&g.state.device, size);
            let mut r = g.state.renderer.write();
            match g.texture {
                Some(id) => r.update_egui_texture_from_wgpu_texture(
                    &g.state.device,
                    &target.view,
                    eframe::wgpu::FilterMode::Linear,
                    id,
                ),
                None => {
                    g.texture = Some(r.register_native_texture(
                        &g.state.device,
                        &target.view,
                        eframe::wgpu::FilterMode::Linear,
                    ))
                }
            }
            g.target = Some(target);
        }
        if self.orbit && self.mesh.is_some() {
            self.camera.yaw += 0.5f32.to_radians();
        }
        let key = DrawKey {
            camera: self.camera,
            display: self.display,
            uploaded: self.uploaded,
            bezier: self.bezier_uploaded,
            size,
        };
        // What a person did (camera, size, display choices) is drawn at once, and so are a
        // first snapshot and the Hermite data a display choice asked for. What the solver
        // did (a new snapshot, and the auto exposure that follows it) waits until the last
        // draw has had 4× its cost to itself, so on a slow (software) renderer most frames
        // stay cheap while a big scene streams.
        let urgent = self.drawn.is_none_or(|k| {
            let mut d = k.display;
            d.ev = self.display.ev;
            d.log_range = self.display.log_range;
            k.camera != self.camera
                || k.size != size
                || d != self.display
                || (k.uploaded == 0) != (self.uploaded == 0)
                || k.bezier != self.bezier_uploaded
        });
        // The frame after a draw: the interval since it started is the draw's cost.
        if let Some(t) = self.draw_started.take() {
            self.last_draw = Some((t, t.elapsed()));
        }
        let due = self
            .last_draw
            .is_none_or(|(t, cost)| t.elapsed() >= cost * 4);
        if let Some(target) = &g.target
            && self.drawn != Some(key)
            && (urgent || due)
        {
            self.drawn = Some(key);
            self.draw_started = Some(Instant::now());
            g.renderer.render(
                &g.state.device,
                &g.state.queue,
                target,
                if self.uploaded > 0 {
                    g.mesh.as_ref()
                } else {
                    None
                },
                &self.camera,
                &self.display,
            );
        }
        if let Some(id) = g.texture {
            ui.painter().image(
                id,
                rect,
                egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
                egui::Color32::WHITE,
            );
        }
        if self.mesh.is_none() {
            ui.painter().text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                match self.stage {
                    Some(Stage::Loading) => "loading…",
                    Some(Stage::Meshing) => "meshing…",
                    _ => "",
                },
                egui::FontId::proportional(18.0),
                egui::Color32::LIGHT_GRAY,
            );
        }
    }
}
