//! The solver thread's protocol (ARCHITECTURE.md, "Threads and messages"), with no GUI: load → snapshots →
//! converged; the converged snapshot equals a direct `Solver::run` (the worker adds no
//! error of its own); cancel by opening another scene; stale job ids; errors and bad files
//! become `Failed` and the worker lives on; pause, resume and settings changes.

mod common;
use common::scratch_dir;
use radiosity::mesh::MeshSettings;
use radiosity::pipeline::Prepared;
use radiosity::scene::builtin;
use radiosity::solver::{Method, SolverSettings};
use radiosity::worker::{Command, Event, ExportError, JobError, Source, Stage, Worker};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

fn mesh() -> MeshSettings {
    MeshSettings {
        max_elements: Some(300),
        ..Default::default()
    }
}

fn load(job: u64, source: &str, solver: SolverSettings) -> Command {
    Command::Load {
        job,
        source: Source(source.into()),
        outside: Default::default(),
        mesh: mesh(),
        solver,
    }
}

/// Collects events until `stop` says so or 60 s pass (a hang fails the test).
fn until(worker: &Worker, mut stop: impl FnMut(&Event) -> bool) -> Vec<Event> {
    let start = Instant::now();
    let mut seen = Vec::new();
    while start.elapsed() < Duration::from_secs(60) {
        if let Some(e) = worker.recv_timeout(Duration::from_millis(100)) {
            let done = stop(&e);
            seen.push(e);
            if done {
                return seen;
            }
        }
    }
    panic!("no final event within 60 s; saw {} events", seen.len());
}

#[test]
fn a_load_streams_snapshots_and_converges_to_the_direct_answer() {
    let wakes = Arc::new(AtomicUsize::new(0));
    let w = Arc::clone(&wakes);
    let worker = Worker::spawn(move || {
        w.fetch_add(1, Ordering::Relaxed);
    });
    let settings = SolverSettings {
        tolerance: 1e-4,
        ..Default::default()
    };
    worker.send(load(1, "builtin:cornell", settings.clone()));
    let events = until(&worker, |e| {
        matches!(e, Event::Converged { .. } | Event::Failed { .. })
    });
    let stages: Vec<Stage> = events
        .iter()
        .filter_map(|e| match e {
            Event::Progress { stage, .. } => Some(*stage),
            _ => None,
        })
        .collect();
    assert_eq!(stages, [Stage::Loading, Stage::Meshing, Stage::Solving]);
    assert!(
        events
            .iter()
            .any(|e| matches!(e, Event::Loaded { job: 1, .. }))
    );
    let snaps: Vec<(u64, Arc<[glam::Vec3]>)> = events
        .iter()
        .filter_map(|e| match e {
            Event::Snapshot {
                version, radiosity, ..
            } => Some((*version, radiosity.clone())),
            _ => None,
        })
        .collect();
    assert!(!snaps.is_empty());
    // Versions increase strictly; the UI keeps the newest.
    assert!(
        snaps
            .windows(2)
            .all(|w| w[0].1.len() == w[1].1.len() && w[0].0 < w[1].0)
    );
    let Some(Event::Converged { job: 1, stats }) = events.last() else {
        panic!("ended with {:?}", events.last());
    };
    assert!(stats.converged);
    // The worker's final snapshot is exactly what the solver gives on this thread.
    let prepared = Prepared::new(&builtin::cornell_box(), &mesh());
    let mut solver = prepared.solver(settings).unwrap();
    solver
        .run(None, &std::sync::atomic::AtomicBool::new(false))
        .unwrap();
    let want = solver.display_radiosity(true);
    let got = &snaps.last().unwrap().1;
    assert_eq!(got.len(), want.len());
    assert!(
        got.iter().zip(&want).all(|(a, b)| a == b),
        "worker and direct run differ"
    );
    // Every event woke the UI.
    assert!(wakes.load(Ordering::Relaxed) >= events.len());
}

#[test]
fn opening_another_scene_cancels_the_first_and_its_events_are_stale() {
    let worker = Worker::spawn(|| {});
    // A slow solve (tiny tolerance, many elements) that the second load must cut short.
    let slow = SolverSettings {
        tolerance: 1e-12,
        method: Method::Progressive,
        ..Default::default()
    };
    worker.send(load(1, "builtin:cornell", slow));
    until(&worker, |e| matches!(e, Event::Snapshot { job: 1, .. }));
    let t = Instant::now();
    worker.send(load(2, "builtin:furnace-cube", SolverSettings::default()));
    let events = until(&worker, |e| {
        matches!(e, Event::Converged { job: 2, .. } | Event::Failed { .. })
    });
    assert!(
        matches!(events.last(), Some(Event::Converged { job: 2, .. })),
        "{:?}",
        events.last()
    );
    // Job 1 never converged, and after job 2's first event nothing of job 1 arrives: the
    // UI drops job-1 events by id anyway, but the worker must not keep solving it.
    assert!(
        !events
            .iter()
            .any(|e| matches!(e, Event::Converged { job: 1, .. }))
    );
    let first2 = events.iter().position(|e| e.job() == 2).unwrap();
    assert!(events[first2..].iter().all(|e| e.job() == 2));
    // Generous bound: switching must not wait for job 1 to finish (it never would).
    assert!(t.elapsed() < Duration::from_secs(30));
}

#[test]
fn a_bad_file_fails_with_its_name_and_the_worker_lives_on() {
    let worker = Worker::spawn(|| {});
    worker.send(load(
        1,
        "/nonexistent/scene.gltf",
        SolverSettings::default(),
    ));
    let events = until(&worker, |e| {
        matches!(e, Event::Failed { .. } | Event::Converged { .. })
    });
    match events.last() {
        Some(Event::Failed { job: 1, error }) => {
            assert!(matches!(error, JobError::Open(_)), "{error:?}");
            assert!(
                error.to_string().contains("/nonexistent/scene.gltf"),
                "{error}"
            )
        }
        other => panic!("{other:?}"),
    }
    // The same worker then opens a good scene.
    worker.send(load(2, "builtin:cornell", SolverSettings::default()));
    let events = until(&worker, |e| {
        matches!(e, Event::Converged { .. } | Event::Failed { .. })
    });
    assert!(matches!(
        events.last(),
        Some(Event::Converged { job: 2, .. })
    ));
}

#[test]
fn pause_stops_snapshots_and_new_settings_restart_the_solve() {
    let worker = Worker::spawn(|| {});
    let slow = SolverSettings {
        tolerance: 1e-12,
        ..Default::default()
    };
    worker.send(load(1, "builtin:cornell", slow));
    until(&worker, |e| matches!(e, Event::Snapshot { .. }));
    worker.send(Command::Pause);
    // The worker takes commands in order, so once the export that follows the pause has
    // answered, the pause has taken effect and every event sent before it has arrived.
    let dir = scratch_dir("worker-pause");
    worker.send(Command::Export {
        path: dir.join("fence.glb"),
        ev: None,
        tonemap: None,
    });
    until(&worker, |e| matches!(e, Event::Exported { .. }));
    // From here on, a snapshot comes only when asked for: turning the ambient term on
    // (it already is) sends one at once, with the solve's iteration count.
    let ask = || {
        worker.send(Command::SetAmbient(true));
        let events = until(&worker, |e| matches!(e, Event::Snapshot { .. }));
        let [Event::Snapshot { stats, .. }] = &events[..] else {
            panic!("{} events while paused, not one snapshot", events.len());
        };
        stats.iterations
    };
    let before = ask();
    // Over a window, nothing may arrive and the solve may not advance. No false failure: a
    // paused worker blocks waiting for a command, so it sends nothing and does not step
    // however long the window or however loaded the machine. No false pass for a worker
    // that ignored the pause: it steps without pause and sends a snapshot at least every
    // few tens of milliseconds, so in 500 ms both checks see it, unless the machine gives
    // its thread no time at all for the whole window; that would hide the fault in one
    // loaded run only, never pass it everywhere.
    let window = Duration::from_millis(500);
    if let Some(e) = worker.recv_timeout(window) {
        let shown: String = format!("{e:?}").chars().take(120).collect();
        panic!("event while paused: {shown}…");
    }
    assert_eq!(ask(), before, "the paused solve advanced");
    let _ = std::fs::remove_dir_all(&dir);
    // New settings restart the solve (iterations start over) and it converges.
    worker.send(Command::SetSettings(SolverSettings {
        tolerance: 1e-3,
        method: Method::GaussSeidel,
        ..Default::default()
    }));
    worker.send(Command::Resume);
    let events = until(&worker, |e| {
        matches!(e, Event::Converged { .. } | Event::Failed { .. })
    });
    match events.last() {
        Some(Event::Converged { stats, .. }) => {
            assert_eq!(stats.method, Some(Method::GaussSeidel));
            assert!(stats.converged);
        }
        other => panic!("{other:?}"),
    }
}

fn last_snapshot(events: &[Event]) -> Arc<[glam::Vec3]> {
    events
        .iter()
        .rev()
        .find_map(|e| match e {
            Event::Snapshot { radiosity, .. } => Some(radiosity.clone()),
            _ => None,
        })
        .expect("a snapshot")
}

#[test]
fn a_material_edit_reaches_the_running_solver_without_a_restart() {
    let worker = Worker::spawn(|| {});
    let settings = SolverSettings {
        tolerance: 1e-6,
        ..Default::default()
    };
    worker.send(load(1, "builtin:cornell", settings));
    let events = until(&worker, |e| {
        matches!(e, Event::Converged { .. } | Event::Failed { .. })
    });
    let before = last_snapshot(&events);
    // Doubling the only emitter doubles every radiosity (B is linear in E with ρ fixed):
    // material 3 is the built-in Cornell box's light.
    let light = builtin::cornell_box().materials[3].clone();
    worker.send(Command::SetMaterial {
        material: 3,
        reflectance: light.reflectance,
        emission: light.emission * 2.0,
    });
    let events = until(&worker, |e| {
        matches!(e, Event::Converged { .. } | Event::Failed { .. })
    });
    // The changed frame comes at once, and nothing was reloaded or restarted.
    assert!(
        matches!(events.first(), Some(Event::Snapshot { .. })),
        "{:?}",
        events.first()
    );
    assert!(!events.iter().any(|e| matches!(e, Event::Loaded { .. })));
    let after = last_snapshot(&events);
    // Tolerance: both solves stop at 1e-6 unshot; the ambient term is zero once converged.
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (a, b) in after.iter().zip(before.iter()) {
        num += (*a - *b * 2.0).as_dvec3().length_squared();
        den += (*b * 2.0).as_dvec3().length_squared();
    }
    let err = (num / den).sqrt();
    assert!(err < 1e-4, "RMS difference to 2 × before: {err:e}");
}

#[test]
fn moving_an_object_meshes_again_and_keeps_material_edits() {
    let worker = Worker::spawn(|| {});
    worker.send(load(1, "builtin:cornell", SolverSettings::default()));
    let events = until(&worker, |e| {
        matches!(e, Event::Converged { .. } | Event::Failed { .. })
    });
    let (objects, mesh) = events
        .iter()
        .find_map(|e| match e {
            Event::Loaded { objects, mesh, .. } => Some((objects.clone(), mesh.clone())),
            _ => None,
        })
        .expect("loaded");
    // Move the last object (a block) 5 cm along +x; edit a material first.
    let o = objects.len() as u32 - 1;
    worker.send(Command::SetMaterial {
        material: 0,
        reflectance: glam::Vec3::splat(0.5),
        emission: glam::Vec3::ZERO,
    });
    let shift = glam::DVec3::new(0.05, 0.0, 0.0);
    worker.send(Command::SetTransform {
        object: o,
        world_from_local: glam::DMat4::from_translation(shift)
            * objects[o as usize].world_from_local,
    });
    // The material edit alone may converge before the worker takes the move: wait for
    // the convergence that follows the new mesh.
    let mut loaded = false;
    let events = until(&worker, |e| {
        loaded |= matches!(e, Event::Loaded { .. });
        matches!(e, Event::Failed { .. }) || (loaded && matches!(e, Event::Converged { .. }))
    });
    let (moved, materials) = events
        .iter()
        .find_map(|e| match e {
            Event::Loaded {
                mesh, materials, ..
            } => Some((mesh.clone(), materials.clone())),
            _ => None,
        })
        .expect("a new mesh after the move");
    assert!(matches!(
        events.last(),
        Some(Event::Converged { job: 1, .. })
    ));
    assert_eq!(materials[0].reflectance, glam::Vec3::splat(0.5));
    // Every patch of the moved object is 5 cm further along +x (mesh frames may differ by
    // their origins, so compare world positions).
    let centroid = |m: &radiosity::mesh::Mesh| -> glam::DVec3 {
        let ps: Vec<_> = m.patches.iter().filter(|p| p.object == o).collect();
        ps.iter()
            .map(|p| p.centroid().as_dvec3())
            .sum::<glam::DVec3>()
            / ps.len() as f64
            + m.origin
    };
    let d = centroid(&moved) - centroid(&mesh);
    assert!((d - shift).length() < 1e-4, "moved by {d}");
}

#[test]
fn export_writes_a_valid_glb_and_never_overwrites_the_opened_file() {
    let dir = scratch_dir("worker-export");
    let opened = dir.join("cornell.gltf");
    std::fs::write(&opened, builtin::cornell_box_gltf()).unwrap();
    let original = std::fs::read(&opened).unwrap();
    let worker = Worker::spawn(|| {});
    worker.send(load(1, opened.to_str().unwrap(), SolverSettings::default()));
    until(&worker, |e| {
        matches!(e, Event::Converged { .. } | Event::Failed { .. })
    });
    let out = dir.join("baked.glb");
    worker.send(Command::Export {
        path: out.clone(),
        ev: None,
        tonemap: None,
    });
    let events = until(&worker, |e| matches!(e, Event::Exported { .. }));
    match events.last() {
        Some(Event::Exported { result: Ok(p), .. }) => assert_eq!(p, &out),
        other => panic!("{other:?}"),
    }
    // The gltf crate (an independent reader) accepts it, with linear radiance per vertex.
    let doc = gltf::Gltf::from_slice(&std::fs::read(&out).unwrap()).expect("a valid .glb");
    assert!(doc.meshes().count() > 0);
    assert!(
        doc.meshes()
            .flat_map(|m| m.primitives())
            .all(|p| p.attributes().any(|(s, _)| s == gltf::Semantic::Colors(0)))
    );
    // Exporting over the opened scene is refused and leaves it as it was.
    worker.send(Command::Export {
        path: opened.clone(),
        ev: None,
        tonemap: None,
    });
    let events = until(&worker, |e| matches!(e, Event::Exported { .. }));
    match events.last() {
        Some(Event::Exported { result: Err(e), .. }) => {
            assert!(matches!(e, ExportError::WouldOverwrite(_)), "{e}")
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(std::fs::read(&opened).unwrap(), original);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The newest mesh among `events` (loaded or refined), which later snapshots are for.
fn newest_mesh(events: &[Event]) -> Option<Arc<radiosity::mesh::Mesh>> {
    events.iter().rev().find_map(|e| match e {
        Event::Refined { mesh, .. } | Event::Loaded { mesh, .. } => Some(Arc::clone(mesh)),
        _ => None,
    })
}

#[test]
fn snapshots_carry_the_hermite_vertex_data_while_asked() {
    // Hermite display asks the worker for its vertex data (`Command::SetHermite`): the
    // snapshot sent at once carries the values and slopes `DisplayMesh::hermite` makes of
    // the snapshot's irradiance, and the Gouraud values of `vertex_values`; once the ask
    // is withdrawn, snapshots carry none.
    let worker = Worker::spawn(|| {});
    worker.send(load(1, "builtin:cornell", SolverSettings::default()));
    let events = until(&worker, |e| {
        matches!(e, Event::Converged { .. } | Event::Failed { .. })
    });
    let mesh = newest_mesh(&events).expect("a mesh");
    for e in &events {
        if let Event::Snapshot { hermite, .. } = e {
            assert!(hermite.is_none(), "Hermite data before they were asked for");
        }
    }
    worker.send(Command::SetHermite(true));
    let events = until(&worker, |e| matches!(e, Event::Snapshot { .. }));
    let Some(Event::Snapshot {
        irradiance,
        vertex,
        hermite: Some(hermite),
        ..
    }) = events.last()
    else {
        panic!("the snapshot after SetHermite(true) has no Hermite data");
    };
    let want = mesh.display.hermite(&mesh.elements, irradiance);
    assert_eq!(hermite.values, want.values);
    assert_eq!(hermite.gradients, want.gradients);
    assert_eq!(
        **vertex,
        *mesh.display.vertex_values(&mesh.elements, irradiance)
    );
    worker.send(Command::SetHermite(false));
    worker.send(Command::SetAmbient(true));
    let events = until(&worker, |e| matches!(e, Event::Snapshot { .. }));
    assert!(matches!(
        events.last(),
        Some(Event::Snapshot { hermite: None, .. })
    ));
}

#[test]
fn an_edits_first_snapshot_reuses_the_vertex_data_of_the_unchanged_light() {
    // A reflectance edit on a converged hierarchical solve shows first with each
    // element's irradiance H as it was (the edited elements change ρ, not H): that
    // snapshot reuses the last one's vertex data instead of fitting them again (on Sponza
    // the fit is most of a snapshot's cost), and they are what the fit of its own
    // irradiance gives, to the 10⁻⁶ the reuse allows.
    let worker = Worker::spawn(|| {});
    let hierarchical = SolverSettings {
        method: Method::Hierarchical,
        ..Default::default()
    };
    worker.send(load(1, "builtin:cornell", hierarchical));
    worker.send(Command::SetHermite(true));
    let events = until(&worker, |e| {
        matches!(e, Event::Converged { .. } | Event::Failed { .. })
    });
    let mesh = newest_mesh(&events).expect("a mesh");
    let last = |events: &[Event]| {
        events.iter().rev().find_map(|e| match e {
            Event::Snapshot {
                irradiance,
                vertex,
                hermite,
                ..
            } => Some((irradiance.clone(), vertex.clone(), hermite.clone())),
            _ => None,
        })
    };
    let (_, vertex, hermite) = last(&events).expect("a snapshot");
    assert!(hermite.is_some(), "no Hermite data after SetHermite(true)");
    worker.send(Command::SetMaterial {
        material: 0,
        reflectance: glam::Vec3::splat(0.3),
        emission: glam::Vec3::ZERO,
    });
    let events = until(&worker, |e| matches!(e, Event::Snapshot { .. }));
    let (irradiance, first, first_hermite) = last(&events).expect("a snapshot");
    assert!(
        Arc::ptr_eq(&vertex, &first),
        "the vertex values were fitted again"
    );
    assert!(Arc::ptr_eq(
        hermite.as_ref().unwrap(),
        first_hermite.as_ref().unwrap()
    ));
    let fitted = mesh.display.vertex_values(&mesh.elements, &irradiance);
    let worst = fitted
        .iter()
        .zip(first.iter())
        .map(|(a, b)| {
            ((*a - *b).abs() / a.abs().max(b.abs()).max(glam::Vec3::splat(1e-30))).max_element()
        })
        .fold(0.0f32, f32::max);
    assert!(
        worst <= 1e-5,
        "reused vertex values {worst} off their own fit"
    );
    // The sweeps that follow change the light, and the vertex data are fitted anew.
    let events = until(&worker, |e| {
        matches!(e, Event::Converged { .. } | Event::Failed { .. })
    });
    let (irradiance, after, _) = last(&events).expect("a snapshot after the sweeps");
    assert!(!Arc::ptr_eq(&first, &after));
    // On the mesh the sweeps left (the oracle may have split leaves the edit brightened).
    let mesh = newest_mesh(&events).unwrap_or(mesh);
    assert_eq!(
        *after,
        *mesh.display.vertex_values(&mesh.elements, &irradiance)
    );
}
