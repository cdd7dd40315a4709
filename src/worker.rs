//! The solver thread (ARCHITECTURE.md, "Threads and messages"): the viewer sends commands, the worker loads, meshes,
//! builds the BVH and steps the solver, and sends events back. Nothing here depends on a
//! GUI: the UI passes a wake-up callback (`ctx.request_repaint()` in the app, a counter in
//! tests) and drains the event channel without ever blocking on the solver.
//!
//! Every job (one opened scene) has an id; every event carries it, and snapshots carry a
//! version, so the UI drops what belongs to a job it has moved past. Opening another scene
//! raises the current job's cancel flag at once (before the command is even read), so a
//! long load, mesh or solver step ends early. A panic or error inside a job becomes
//! [`Event::Failed`]; the worker lives on and takes the next command.

use crate::accel::Bvh;
use crate::files::WriteError;
use crate::mesh::{Hermite, Mesh, MeshSettings, surface_values};
use crate::pipeline::Prepared;
use crate::scene::{Image, Material, OpenError, Outside, Scene};
use crate::solver::gather::{GatherSettings, Gatherer};
use crate::solver::{
    ElementLinks, PatchEdit, Solver, SolverError, SolverSettings, Stats, StepOutcome,
};
use glam::{DMat4, Vec3};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, TryRecvError, channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// What a scene is opened from: a path or `builtin:NAME`, as on the command line.
#[derive(Clone, Debug, PartialEq)]
pub struct Source(pub String);

/// UI → worker.
#[derive(Clone, Debug)]
pub enum Command {
    /// Open a scene as job `job` (the UI picks increasing ids); cancels the current job.
    Load {
        job: u64,
        source: Source,
        /// `--sky` and `--sun`, when given.
        outside: Outside,
        mesh: MeshSettings,
        solver: SolverSettings,
    },
    /// New solver settings for the current job: the solve restarts on the same mesh.
    SetSettings(SolverSettings),
    Pause,
    Resume,
    /// Restart the current job's solve from nothing.
    Reset,
    /// Change a material of the current job live (Chen's incremental radiosity: the
    /// difference is shot as signed unshot energy; nothing restarts). `emission` is the
    /// emitted radiance L_e, W/(m²·sr).
    SetMaterial {
        material: u32,
        reflectance: Vec3,
        emission: Vec3,
    },
    /// Place an object anew: the scene is meshed again and the solve restarts on the new
    /// geometry (a new `Loaded` with the same job id, then snapshots).
    SetTransform {
        object: u32,
        world_from_local: DMat4,
    },
    /// Whether snapshots include Cohen et al.'s ambient term (progressive only).
    SetAmbient(bool),
    /// Whether snapshots carry the Hermite values and slopes at the display vertices
    /// (what Hermite display draws; on Sponza they take the worker 111 ms a snapshot
    /// against the Gouraud values' 78 ms, so only while the display asks). Turning it on
    /// sends a snapshot.
    SetHermite(bool),
    /// Write the current solution as a baked .glb (the light per vertex under the edited
    /// materials and their textures; `export`).
    Export {
        path: PathBuf,
        /// The exposure to bake the colours at, in stops, and the tone map (the viewer's);
        /// `None`: the auto exposure of the solution and the default tone map.
        ev: Option<f32>,
        tonemap: Option<crate::exposure::ToneMap>,
    },
    /// Prepare the current solution for the final gather at points (answered by
    /// `Event::Gatherer`).
    Gather(GatherSettings),
    /// The links of the element at `point` (the mesh's frame) on the side `normal` faces,
    /// for the link inspector (answered by `Event::Inspected`).
    Inspect {
        point: Vec3,
        normal: Vec3,
    },
    Shutdown,
}

/// Where a job's preparation stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    Loading,
    Meshing,
    Solving,
}

/// Worker → UI. Every event names its job.
#[derive(Clone, Debug)]
pub enum Event {
    Progress {
        job: u64,
        stage: Stage,
    },
    /// The scene is meshed (or meshed again after a move): the UI builds its display from
    /// `mesh`, picks with `bvh` and lists `materials` and `objects`.
    Loaded {
        job: u64,
        mesh: Arc<Mesh>,
        bvh: Arc<Bvh>,
        materials: Vec<Material>,
        /// The images the materials' textures refer to.
        images: Vec<Arc<Image>>,
        objects: Vec<ObjectInfo>,
        warnings: Vec<String>,
    },
    /// The newest radiosity B per element (with the ambient term for progressive display
    /// unless turned off); the irradiance H = (B − E)/ρ it came from, per element, as
    /// Gouraud values at the display mesh's vertices and, after `SetHermite(true)`, as
    /// their Hermite values and slopes (what the display reconstructs); and
    /// the reflectance ρ and emitted radiosity E per element it was solved with (the same
    /// `Arc`s until an edit changes them).
    Snapshot {
        job: u64,
        version: u64,
        radiosity: Arc<[Vec3]>,
        irradiance: Arc<[Vec3]>,
        vertex: Arc<[Vec3]>,
        hermite: Option<Arc<Hermite>>,
        reflectance: Arc<[Vec3]>,
        emission: Arc<[Vec3]>,
        stats: Stats,
    },
    /// Adaptive refinement replaced the mesh (same scene, finer elements); the next
    /// snapshots are for it.
    Refined {
        job: u64,
        mesh: Arc<Mesh>,
    },
    /// An export finished: the path written, or why not.
    Exported {
        job: u64,
        result: Result<PathBuf, ExportError>,
    },
    Converged {
        job: u64,
        stats: Stats,
    },
    /// The solution of snapshot `version`, prepared for the final gather.
    Gatherer {
        job: u64,
        version: u64,
        gatherer: Arc<Gatherer>,
    },
    /// The links of the element asked about (`None`: the method is not hierarchical, or
    /// no element faces that way there).
    Inspected {
        job: u64,
        links: Option<ElementLinks>,
    },
    Failed {
        job: u64,
        error: JobError,
    },
}

/// Why a job (or one command of it) failed. Cheap to clone, so events stay `Clone`; its
/// `Display` is the one line the viewer shows.
#[derive(Clone, Debug, thiserror::Error)]
pub enum JobError {
    /// The scene could not be opened (names the file and the problem).
    #[error("{0}")]
    Open(Arc<OpenError>),
    /// The solver refused the settings (a method too large for the mesh) or failed.
    #[error("{0}")]
    Solver(Arc<SolverError>),
    /// An edit named a material or object the scene does not have, or a degenerate
    /// transform; the job goes on unchanged.
    #[error("{0}")]
    Edit(String),
    /// A bug: a panic inside the job, caught so the worker lives on.
    #[error("internal error in the solver: {0}")]
    Internal(String),
}

/// Why an export did not happen.
#[derive(Clone, Debug, thiserror::Error)]
pub enum ExportError {
    /// The path is the scene file that is open.
    #[error("{0}: will not overwrite the opened scene; choose another file")]
    WouldOverwrite(String),
    #[error("{0}")]
    Write(Arc<WriteError>),
}

impl Event {
    pub fn job(&self) -> u64 {
        match self {
            Event::Progress { job, .. }
            | Event::Loaded { job, .. }
            | Event::Snapshot { job, .. }
            | Event::Converged { job, .. }
            | Event::Gatherer { job, .. }
            | Event::Exported { job, .. }
            | Event::Refined { job, .. }
            | Event::Inspected { job, .. }
            | Event::Failed { job, .. } => *job,
        }
    }
}

/// The reflectance ρ and emitted radiosity E per element a snapshot was solved with.
pub type Surfaces = (Arc<[Vec3]>, Arc<[Vec3]>);

/// An object as the UI lists it.
#[derive(Clone, Debug)]
pub struct ObjectInfo {
    pub name: String,
    pub world_from_local: DMat4,
}

/// The UI's end of the worker.
pub struct Worker {
    commands: Sender<Command>,
    events: Receiver<Event>,
    /// Cancel flag of the job the worker is on (replaced for each load).
    cancel: Arc<Mutex<Arc<AtomicBool>>>,
    thread: Option<JoinHandle<()>>,
}

/// How often snapshots are sent at most (a 60 Hz frame); on big meshes also at most every
/// 4× the time a snapshot takes to build, so snapshots cost the solver at most 20 %.
const SNAPSHOT_INTERVAL: Duration = Duration::from_millis(16);

impl Worker {
    /// Starts the worker thread; `wake` is called after every event is sent.
    pub fn spawn(wake: impl Fn() + Send + 'static) -> Worker {
        let (commands, command_rx) = channel();
        let (event_tx, events) = channel();
        let cancel = Arc::new(Mutex::new(Arc::new(AtomicBool::new(false))));
        let shared = Arc::clone(&cancel);
        let thread = std::thread::Builder::new()
            .name("radiosity-solver".into())
            .spawn(move || {
                // The solver's parallel work runs in its own pool, one thread short of the
                // machine, so the UI thread always has a core: frames stay smooth while a
                // big scene solves (the results do not depend on the thread count).
                let threads = std::thread::available_parallelism()
                    .map_or(1, |n| n.get().saturating_sub(1).max(1));
                match rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .thread_name(|i| format!("radiosity-solver-{i}"))
                    .build()
                {
                    Ok(pool) => pool.install(|| run(command_rx, event_tx, shared, wake)),
                    Err(_) => run(command_rx, event_tx, shared, wake),
                }
            })
            .expect("spawning the solver thread");
        Worker {
            commands,
            events,
            cancel,
            thread: Some(thread),
        }
    }

    /// Sends a command. A `Load` or `Shutdown` first cancels whatever is running.
    pub fn send(&self, command: Command) {
        if matches!(command, Command::Load { .. } | Command::Shutdown) {
            let flag = Arc::new(AtomicBool::new(false));
            let old = std::mem::replace(
                &mut *self.cancel.lock().unwrap_or_else(|e| e.into_inner()),
                flag,
            );
            old.store(true, Ordering::Relaxed);
        }
        let _ = self.commands.send(command);
    }

    /// Events received so far, without waiting.
    pub fn drain(&self) -> Vec<Event> {
        self.events.try_iter().collect()
    }

    /// Waits up to `timeout` for the next event (for tests and the headless screenshot).
    pub fn recv_timeout(&self, timeout: Duration) -> Option<Event> {
        self.events.recv_timeout(timeout).ok()
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        self.send(Command::Shutdown);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The current job on the worker.
struct Job {
    id: u64,
    source: Source,
    scene: Scene,
    mesh_settings: MeshSettings,
    ambient: bool,
    /// Whether snapshots carry the Hermite data (`Command::SetHermite`).
    hermite: bool,
    snapshot_cost: Duration,
    /// The solver's mesh version last sent to the UI.
    mesh_version: u64,
    prepared: Prepared,
    solver: Solver,
    version: u64,
    paused: bool,
    done: bool,
    last_snapshot: Option<Instant>,
    /// The reflectance and emission last sent, reused while they do not change.
    surfaces: Option<Surfaces>,
    /// The last snapshot's vertex data, reused while the light does not change.
    vertex_data: Option<VertexData>,
}

fn run(
    commands: Receiver<Command>,
    events: Sender<Event>,
    cancel: Arc<Mutex<Arc<AtomicBool>>>,
    wake: impl Fn(),
) {
    let send = |e: Event| {
        let _ = events.send(e);
        wake();
    };
    let mut job: Option<Job> = None;
    // `Command::SetHermite`, for this job and the next ones.
    let mut hermite = false;
    loop {
        // Idle (no job, paused or converged): block for the next command. Working: take
        // what has arrived and step.
        let busy = job.as_ref().is_some_and(|j| !j.paused && !j.done);
        let command = if busy {
            match commands.try_recv() {
                Ok(c) => Some(c),
                Err(TryRecvError::Empty) => None,
                Err(TryRecvError::Disconnected) => return,
            }
        } else {
            match commands.recv_timeout(Duration::from_secs(3600)) {
                Ok(c) => Some(c),
                Err(RecvTimeoutError::Timeout) => continue,
                Err(RecvTimeoutError::Disconnected) => return,
            }
        };
        if let Some(command) = command {
            match command {
                Command::Shutdown => return,
                Command::Load {
                    job: id,
                    source,
                    outside,
                    mesh,
                    solver,
                } => {
                    job = None; // free the old scene before loading the next
                    let flag = cancel.lock().unwrap_or_else(|e| e.into_inner()).clone();
                    let result = catch_unwind(AssertUnwindSafe(|| {
                        load(id, &source, outside, &mesh, solver, &flag, &send)
                    }));
                    match result {
                        Ok(Ok(Some(j))) => {
                            job = Some(Job { hermite, ..j });
                        }
                        Ok(Ok(None)) => {} // cancelled by a newer load
                        Ok(Err(error)) => send(Event::Failed { job: id, error }),
                        Err(panic) => send(Event::Failed {
                            job: id,
                            error: JobError::Internal(panic_message(&panic)),
                        }),
                    }
                }
                Command::SetSettings(settings) => {
                    if let Some(j) = &mut job {
                        restart(j, settings, &send);
                    }
                }
                Command::Reset => {
                    if let Some(j) = &mut job {
                        let settings = j.solver.settings().clone();
                        restart(j, settings, &send);
                    }
                }
                Command::Pause => {
                    if let Some(j) = &mut job {
                        j.paused = true;
                    }
                }
                Command::Resume => {
                    if let Some(j) = &mut job {
                        j.paused = false;
                    }
                }
                Command::SetAmbient(on) => {
                    if let Some(j) = &mut job {
                        j.ambient = on;
                        snapshot(j, &send);
                    }
                }
                Command::SetHermite(on) => {
                    hermite = on;
                    if let Some(j) = &mut job {
                        j.hermite = on;
                        if on && j.version > 0 {
                            snapshot(j, &send);
                        }
                    }
                }
                Command::SetMaterial {
                    material,
                    reflectance,
                    emission,
                } => {
                    if let Some(j) = &mut job {
                        edit_material(j, material, reflectance, emission, &send);
                    }
                }
                Command::SetTransform {
                    object,
                    world_from_local,
                } => {
                    if let Some(j) = &mut job {
                        let flag = cancel.lock().unwrap_or_else(|e| e.into_inner()).clone();
                        let result = catch_unwind(AssertUnwindSafe(|| {
                            move_object(j, object, world_from_local, &flag, &send)
                        }));
                        if let Err(panic) = result {
                            let id = j.id;
                            job = None;
                            send(Event::Failed {
                                job: id,
                                error: JobError::Internal(panic_message(&panic)),
                            });
                        }
                    }
                }
                Command::Gather(settings) => {
                    if let Some(j) = &mut job {
                        send(Event::Gatherer {
                            job: j.id,
                            version: j.version,
                            gatherer: Arc::new(j.solver.gatherer(settings)),
                        });
                    }
                }
                Command::Inspect { point, normal } => {
                    if let Some(j) = &mut job {
                        let links = j
                            .solver
                            .mesh()
                            .locate(point, normal)
                            .and_then(|(e, _)| j.solver.element_links(e));
                        send(Event::Inspected { job: j.id, links });
                    }
                }
                Command::Export { path, ev, tonemap } => {
                    if let Some(j) = &mut job {
                        let result = export(j, &path, ev, tonemap);
                        send(Event::Exported { job: j.id, result });
                    }
                }
            }
            continue;
        }
        let Some(j) = &mut job else { continue };
        let flag = cancel.lock().unwrap_or_else(|e| e.into_inner()).clone();
        let outcome = catch_unwind(AssertUnwindSafe(|| j.solver.step(&flag)));
        if j.solver.mesh_version() != j.mesh_version {
            j.mesh_version = j.solver.mesh_version();
            j.last_snapshot = None;
            send(Event::Refined {
                job: j.id,
                mesh: Arc::clone(j.solver.mesh()),
            });
        }
        match outcome {
            Ok(Ok(StepOutcome::Working)) => {
                let interval = SNAPSHOT_INTERVAL.max(j.snapshot_cost * 4);
                if j.last_snapshot.is_none_or(|t| t.elapsed() >= interval) {
                    snapshot(j, &send);
                }
            }
            Ok(Ok(StepOutcome::Converged)) => {
                snapshot(j, &send);
                j.done = true;
                send(Event::Converged {
                    job: j.id,
                    stats: j.solver.stats().clone(),
                });
            }
            Ok(Ok(StepOutcome::Cancelled)) => {}
            Ok(Err(e)) => {
                j.done = true;
                send(Event::Failed {
                    job: j.id,
                    error: JobError::Solver(Arc::new(e)),
                });
            }
            Err(panic) => {
                let id = j.id;
                job = None;
                send(Event::Failed {
                    job: id,
                    error: JobError::Internal(panic_message(&panic)),
                });
            }
        }
    }
}

/// A fresh solve of `settings` on the job's mesh; a settings error is reported, and the
/// old solve is kept.
fn restart(j: &mut Job, settings: SolverSettings, send: &impl Fn(Event)) {
    match j.prepared.solver(settings) {
        Ok(solver) => {
            // A fresh solve starts on the unrefined mesh: show it.
            if j.mesh_version != 0 {
                send(Event::Refined {
                    job: j.id,
                    mesh: Arc::clone(solver.mesh()),
                });
            }
            j.solver = solver;
            j.mesh_version = 0;
            j.done = false;
            j.last_snapshot = None;
        }
        Err(e) => send(Event::Failed {
            job: j.id,
            error: JobError::Solver(Arc::new(e)),
        }),
    }
}

/// A snapshot's vertex data (`Event::Snapshot`'s `vertex` and `hermite`), with the
/// irradiance and the mesh version they were made for.
struct VertexData {
    mesh_version: u64,
    irradiance: Arc<[Vec3]>,
    vertex: Arc<[Vec3]>,
    hermite: Option<Arc<Hermite>>,
}

/// Whether two irradiances are the same light: every channel of every element within
/// 10⁻⁶ of the larger. An edit's first snapshot keeps each element's H (it changes ρ and
/// E; `Solver::edit_patches`), up to the rounding of H to f32.
fn same_light(a: &[Vec3], b: &[Vec3]) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(a, b)| {
            (*a - *b).abs().max_element() <= 1e-6 * a.abs().max(b.abs()).max_element()
        })
}

fn snapshot(j: &mut Job, send: &impl Fn(Event)) {
    let start = Instant::now();
    j.version += 1;
    let radiosity = j.solver.display_radiosity(j.ambient);
    let (rho, e) = (j.solver.reflectance(), j.solver.emission());
    let irradiance: Arc<[Vec3]> = j.solver.display_irradiance(j.ambient).into();
    let mesh = j.solver.mesh();
    let mesh_version = j.solver.mesh_version();
    // The vertex data are most of a snapshot's cost (on Sponza 78 ms, 111 with Hermite):
    // an edit's first snapshot, which only ρ and E tell from the last, reuses them.
    let reused = j.vertex_data.as_ref().filter(|d| {
        d.mesh_version == mesh_version
            && (d.hermite.is_some() || !j.hermite)
            && same_light(&d.irradiance, &irradiance)
    });
    let (vertex, hermite) = match reused {
        Some(d) => (
            Arc::clone(&d.vertex),
            d.hermite.as_ref().filter(|_| j.hermite).map(Arc::clone),
        ),
        None if j.hermite => {
            let (vertex, hermite) = mesh.display.smooth_values(&mesh.elements, &irradiance);
            (vertex.into(), Some(Arc::new(hermite)))
        }
        None => (
            mesh.display
                .vertex_values(&mesh.elements, &irradiance)
                .into(),
            None,
        ),
    };
    // Kept with the irradiance they were made of, so that reuse never drifts.
    let reused = reused.is_some();
    if !reused {
        j.vertex_data = Some(VertexData {
            mesh_version,
            irradiance: Arc::clone(&irradiance),
            vertex: Arc::clone(&vertex),
            hermite: hermite.clone(),
        });
    }
    let (reflectance, emission) = match j.surfaces.take() {
        Some((r, m)) if *r == *rho && *m == *e => (r, m),
        _ => (Arc::from(&*rho), Arc::from(&*e)),
    };
    j.surfaces = Some((Arc::clone(&reflectance), Arc::clone(&emission)));
    // A reused snapshot's cost says nothing of the next one's.
    if !reused {
        j.snapshot_cost = start.elapsed();
    }
    j.last_snapshot = Some(Instant::now());
    send(Event::Snapshot {
        job: j.id,
        version: j.version,
        radiosity: radiosity.into(),
        irradiance,
        vertex,
        hermite,
        reflectance,
        emission,
        stats: j.solver.stats().clone(),
    });
}

/// Chen's incremental edit: new ρ and E for every patch of `material`, shot as a signed
/// difference by the running solver.
fn edit_material(
    j: &mut Job,
    material: u32,
    reflectance: Vec3,
    emission: Vec3,
    send: &impl Fn(Event),
) {
    let Some(m) = j.scene.materials.get_mut(material as usize) else {
        send(Event::Failed {
            job: j.id,
            error: JobError::Edit(format!("no material {material} in the scene")),
        });
        return;
    };
    m.reflectance = reflectance.clamp(Vec3::ZERO, Vec3::splat(0.999));
    m.emission = emission.max(Vec3::ZERO);
    let m = m.clone();
    let mesh = Arc::clone(j.solver.mesh());
    let edits: Vec<PatchEdit> = mesh
        .patches
        .iter()
        .enumerate()
        .filter(|(_, p)| p.material == material)
        .filter_map(|(i, p)| {
            let o = j.scene.objects.get(p.object as usize)?;
            let (rho, e, _) = surface_values(&m, o, p.triangle as usize);
            Some(PatchEdit {
                patch: i as u32,
                reflectance: rho,
                emission: e,
            })
        })
        .collect();
    j.solver.edit_patches(&edits);
    j.done = j.solver.is_converged();
    // The first changed frame goes out at once.
    snapshot(j, send);
}

/// Moves an object: mesh again, rebuild the BVH, restart the solve with the same settings.
fn move_object(
    j: &mut Job,
    object: u32,
    world_from_local: DMat4,
    cancel: &AtomicBool,
    send: &impl Fn(Event),
) {
    let Some(o) = j.scene.objects.get_mut(object as usize) else {
        send(Event::Failed {
            job: j.id,
            error: JobError::Edit(format!("no object {object} in the scene")),
        });
        return;
    };
    if !world_from_local.is_finite() || world_from_local.determinant().abs() < 1e-12 {
        send(Event::Failed {
            job: j.id,
            error: JobError::Edit("that transform is degenerate (zero scale or not finite)".into()),
        });
        return;
    }
    let old = std::mem::replace(&mut o.world_from_local, world_from_local);
    // Keep the triangles counter-clockwise in world space when the new transform mirrors
    // and the old did not (or the reverse), as the loader does.
    if (old.determinant() < 0.0) != (world_from_local.determinant() < 0.0) {
        for t in &mut o.triangles {
            t.swap(1, 2);
        }
    }
    send(Event::Progress {
        job: j.id,
        stage: Stage::Meshing,
    });
    // Cancelled only by opening another scene, which replaces this job.
    let Ok(prepared) = Prepared::new_cancellable(&j.scene, &j.mesh_settings, cancel) else {
        return;
    };
    match prepared.solver(j.solver.settings().clone()) {
        Ok(solver) => {
            // The new mesh is read from the scene, which already holds the material edits.
            send(loaded_event(j.id, &j.scene, &prepared));
            j.prepared = prepared;
            j.solver = solver;
            j.mesh_version = 0;
            j.done = false;
            j.last_snapshot = None;
            send(Event::Progress {
                job: j.id,
                stage: Stage::Solving,
            });
        }
        Err(e) => send(Event::Failed {
            job: j.id,
            error: JobError::Solver(Arc::new(e)),
        }),
    }
}

fn export(
    j: &Job,
    path: &std::path::Path,
    ev: Option<f32>,
    tonemap: Option<crate::exposure::ToneMap>,
) -> Result<PathBuf, ExportError> {
    if !j.source.0.starts_with("builtin:") {
        let opened = std::path::Path::new(&j.source.0);
        let same = match (opened.canonicalize(), path.canonicalize()) {
            (Ok(a), Ok(b)) => a == b,
            _ => opened == path,
        };
        if same {
            return Err(ExportError::WouldOverwrite(path.display().to_string()));
        }
    }
    let radiosity = j.solver.radiosity();
    let mesh = j.solver.mesh();
    let ev = ev.or_else(|| crate::exposure::auto_exposure(mesh, &radiosity).map(|a| a.0));
    let (reflectance, emission) = (j.solver.reflectance(), j.solver.emission());
    let bake = crate::export::Bake {
        radiosity: &radiosity,
        reflectance: &reflectance,
        emission: &emission,
        exposure: 2f32.powf(ev.unwrap_or(0.0)),
        tonemap: tonemap.unwrap_or_default(),
    };
    let bytes = crate::export::baked_glb(&j.scene, mesh, &bake);
    crate::files::write_atomic(path, &bytes).map_err(|e| ExportError::Write(Arc::new(e)))?;
    Ok(path.to_path_buf())
}

fn loaded_event(id: u64, scene: &Scene, prepared: &Prepared) -> Event {
    let mut warnings = scene.warnings.clone();
    warnings.extend(prepared.mesh.warnings.iter().cloned());
    Event::Loaded {
        job: id,
        mesh: Arc::clone(&prepared.mesh),
        bvh: Arc::clone(&prepared.bvh),
        materials: scene.materials.clone(),
        images: scene.images.clone(),
        objects: scene
            .objects
            .iter()
            .map(|o| ObjectInfo {
                name: o.name.clone(),
                world_from_local: o.world_from_local,
            })
            .collect(),
        warnings,
    }
}

/// Loads, meshes and prepares the scene of a `Command::Load` (its fields, then the cancel
/// flag and the event sink).
fn load(
    id: u64,
    source: &Source,
    outside: Outside,
    mesh: &MeshSettings,
    solver: SolverSettings,
    cancel: &AtomicBool,
    send: &impl Fn(Event),
) -> Result<Option<Job>, JobError> {
    send(Event::Progress {
        job: id,
        stage: Stage::Loading,
    });
    let scene = match crate::scene::open_cancellable(&source.0, outside.sky, outside.sun, cancel) {
        Ok(scene) => scene,
        Err(_) if cancel.load(Ordering::Relaxed) => return Ok(None),
        Err(e) => return Err(JobError::Open(Arc::new(e))),
    };
    send(Event::Progress {
        job: id,
        stage: Stage::Meshing,
    });
    let Ok(prepared) = Prepared::new_cancellable(&scene, mesh, cancel) else {
        return Ok(None);
    };
    let solver = prepared
        .solver(solver)
        .map_err(|e| JobError::Solver(Arc::new(e)))?;
    send(loaded_event(id, &scene, &prepared));
    send(Event::Progress {
        job: id,
        stage: Stage::Solving,
    });
    Ok(Some(Job {
        id,
        source: source.clone(),
        scene,
        mesh_settings: mesh.clone(),
        ambient: true,
        hermite: false,
        snapshot_cost: Duration::ZERO,
        mesh_version: 0,
        prepared,
        solver,
        version: 0,
        paused: false,
        done: false,
        last_snapshot: None,
        surfaces: None,
        vertex_data: None,
    }))
}

fn panic_message(panic: &Box<dyn std::any::Any + Send>) -> String {
    panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}
