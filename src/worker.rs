//! The solver thread (DESIGN.md §2): the viewer sends commands, the worker loads, meshes,
//! builds the BVH and steps the solver, and sends events back. Nothing here depends on a
//! GUI: the UI passes a wake-up callback (`ctx.request_repaint()` in the app, a counter in
//! tests) and drains the event channel without ever blocking on the solver.
//!
//! Every job (one opened scene) has an id; every event carries it, and snapshots carry a
//! version, so the UI drops what belongs to a job it has moved past. Opening another scene
//! raises the current job's cancel flag at once (before the command is even read), so a
//! long load, mesh or solver step ends early. A panic or error inside a job becomes
//! [`Event::Failed`]; the worker lives on and takes the next command.

use crate::cli::open_scene;
use crate::mesh::{Mesh, MeshSettings};
use crate::pipeline::Prepared;
use crate::solver::{Solver, SolverSettings, Stats, StepOutcome};
use glam::Vec3;
use std::panic::{AssertUnwindSafe, catch_unwind};
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
        mesh: MeshSettings,
        solver: SolverSettings,
    },
    /// New solver settings for the current job: the solve restarts on the same mesh.
    SetSettings(SolverSettings),
    Pause,
    Resume,
    /// Restart the current job's solve from nothing.
    Reset,
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
    /// The scene is meshed: the UI builds its display from `mesh`.
    Loaded {
        job: u64,
        mesh: Arc<Mesh>,
        warnings: Vec<String>,
    },
    /// The newest radiosity per element (with the ambient term for progressive display).
    Snapshot {
        job: u64,
        version: u64,
        radiosity: Arc<[Vec3]>,
        stats: Stats,
    },
    Converged {
        job: u64,
        stats: Stats,
    },
    Failed {
        job: u64,
        error: String,
    },
}

impl Event {
    pub fn job(&self) -> u64 {
        match self {
            Event::Progress { job, .. }
            | Event::Loaded { job, .. }
            | Event::Snapshot { job, .. }
            | Event::Converged { job, .. }
            | Event::Failed { job, .. } => *job,
        }
    }
}

/// The UI's end of the worker.
pub struct Worker {
    commands: Sender<Command>,
    events: Receiver<Event>,
    /// Cancel flag of the job the worker is on (replaced for each load).
    cancel: Arc<Mutex<Arc<AtomicBool>>>,
    thread: Option<JoinHandle<()>>,
}

/// How often snapshots are sent at most (a 60 Hz frame).
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
            .spawn(move || run(command_rx, event_tx, shared, wake))
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
    prepared: Prepared,
    solver: Solver,
    version: u64,
    paused: bool,
    done: bool,
    last_snapshot: Option<Instant>,
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
                    mesh,
                    solver,
                } => {
                    job = None; // free the old scene before loading the next
                    let flag = cancel.lock().unwrap_or_else(|e| e.into_inner()).clone();
                    let result = catch_unwind(AssertUnwindSafe(|| {
                        load(id, &source, &mesh, solver, &flag, &send)
                    }));
                    match result {
                        Ok(Ok(Some(j))) => job = Some(j),
                        Ok(Ok(None)) => {} // cancelled by a newer load
                        Ok(Err(error)) => send(Event::Failed { job: id, error }),
                        Err(panic) => send(Event::Failed {
                            job: id,
                            error: panic_message(&panic),
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
            }
            continue;
        }
        let Some(j) = &mut job else { continue };
        let flag = cancel.lock().unwrap_or_else(|e| e.into_inner()).clone();
        let outcome = catch_unwind(AssertUnwindSafe(|| j.solver.step(&flag)));
        match outcome {
            Ok(Ok(StepOutcome::Working)) => {
                if j.last_snapshot
                    .is_none_or(|t| t.elapsed() >= SNAPSHOT_INTERVAL)
                {
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
                    error: e.to_string(),
                });
            }
            Err(panic) => {
                let id = j.id;
                job = None;
                send(Event::Failed {
                    job: id,
                    error: panic_message(&panic),
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
            j.solver = solver;
            j.done = false;
            j.last_snapshot = None;
        }
        Err(e) => send(Event::Failed {
            job: j.id,
            error: e.to_string(),
        }),
    }
}

fn snapshot(j: &mut Job, send: &impl Fn(Event)) {
    j.version += 1;
    j.last_snapshot = Some(Instant::now());
    send(Event::Snapshot {
        job: j.id,
        version: j.version,
        radiosity: j.solver.display_radiosity(true).into(),
        stats: j.solver.stats().clone(),
    });
}

fn load(
    id: u64,
    source: &Source,
    mesh: &MeshSettings,
    solver: SolverSettings,
    cancel: &AtomicBool,
    send: &impl Fn(Event),
) -> Result<Option<Job>, String> {
    send(Event::Progress {
        job: id,
        stage: Stage::Loading,
    });
    let scene = open_scene(&source.0, None, None).map_err(|e| format!("{e:#}"))?;
    if cancel.load(Ordering::Relaxed) {
        return Ok(None);
    }
    send(Event::Progress {
        job: id,
        stage: Stage::Meshing,
    });
    let prepared = Prepared::new(&scene, mesh);
    if cancel.load(Ordering::Relaxed) {
        return Ok(None);
    }
    let solver = prepared.solver(solver).map_err(|e| e.to_string())?;
    send(Event::Loaded {
        job: id,
        mesh: Arc::clone(&prepared.mesh),
        warnings: scene.warnings.clone(),
    });
    send(Event::Progress {
        job: id,
        stage: Stage::Solving,
    });
    Ok(Some(Job {
        id,
        prepared,
        solver,
        version: 0,
        paused: false,
        done: false,
        last_snapshot: None,
    }))
}

fn panic_message(panic: &Box<dyn std::any::Any + Send>) -> String {
    let what = panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into());
    format!("internal error in the solver: {what}")
}
