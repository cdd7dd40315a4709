//! Opening another scene while the first still loads or meshes: the first job stops (its
//! cancel flag is checked inside loading, the texture pass, contact and shadow-line search,
//! splitting and emitting), the second scene is shown, and nothing of the first arrives
//! after it. On Sponza (262k triangles, textures), from `../shared/scenes`.
//!
//! The time from sending the second `Load` to the worker taking it (its `Progress {
//! Loading }`) is how long the old job took to notice the flag; it is printed
//! (`cargo test --test cancel -- --nocapture`), not asserted: timings belong in benchmarks.
//! The test asserts what the user sees: the second scene loads and converges, and the
//! first never reports `Loaded` once cancelled.

use radiosity::mesh::MeshSettings;
use radiosity::solver::SolverSettings;
use radiosity::worker::{Command, Event, Source, Stage, Worker};
use std::path::PathBuf;
use std::time::{Duration, Instant};

mod common;

/// Sponza from the shared scenes (`None`, skipped, when they are absent outside CI).
fn sponza() -> Option<PathBuf> {
    Some(common::shared_scenes()?.join("sponza-crytek-converted/sponza.gltf"))
}

fn load(job: u64, source: &str) -> Command {
    Command::Load {
        job,
        source: Source(source.into()),
        outside: Default::default(),
        mesh: MeshSettings {
            max_elements: Some(300),
            ..Default::default()
        },
        solver: SolverSettings::default(),
    }
}

/// Waits up to `limit` for an event `want` accepts; returns it and everything before it.
fn wait(worker: &Worker, limit: Duration, mut want: impl FnMut(&Event) -> bool) -> Vec<Event> {
    let start = Instant::now();
    let mut seen = Vec::new();
    while start.elapsed() < limit {
        if let Some(e) = worker.recv_timeout(Duration::from_millis(5)) {
            let done = want(&e);
            seen.push(e);
            if done {
                return seen;
            }
        }
    }
    panic!("no such event within {limit:?}; saw {seen:?}");
}

/// Opens Sponza, waits for it to reach `stage` (plus `delay` into it), opens the Cornell
/// box, and returns how long the worker took to start the second load.
fn cancel_at(sponza: &str, stage: Stage, delay: Duration) -> Duration {
    let worker = Worker::spawn(|| {});
    worker.send(load(1, sponza));
    wait(
        &worker,
        Duration::from_secs(120),
        |e| matches!(e, Event::Progress { job: 1, stage: s } if *s == stage),
    );
    std::thread::sleep(delay);
    let sent = Instant::now();
    worker.send(load(2, "builtin:cornell"));
    let before = wait(&worker, Duration::from_secs(120), |e| {
        matches!(
            e,
            Event::Progress {
                job: 2,
                stage: Stage::Loading
            }
        )
    });
    let latency = sent.elapsed();
    // If job 1 finished meshing before it saw the flag, its Loaded may come before job 2
    // starts; none may come after.
    let after = wait(&worker, Duration::from_secs(120), |e| {
        matches!(e, Event::Converged { job: 2, .. } | Event::Failed { .. })
    });
    assert!(
        matches!(after.last(), Some(Event::Converged { job: 2, .. })),
        "{:?}",
        after.last()
    );
    assert!(
        after
            .iter()
            .any(|e| matches!(e, Event::Loaded { job: 2, .. })),
        "the second scene was not shown"
    );
    assert!(
        !after.iter().any(|e| e.job() == 1),
        "job 1 sent events after job 2 started"
    );
    let finished = before
        .iter()
        .any(|e| matches!(e, Event::Loaded { job: 1, .. }));
    eprintln!(
        "cancelled while {stage:?} (+{delay:?}): job 2 started {:.0} ms after it was sent{}",
        latency.as_secs_f64() * 1e3,
        if finished {
            " (job 1 had finished meshing)"
        } else {
            ""
        }
    );
    latency
}

#[test]
fn opening_a_second_scene_while_the_first_loads_or_meshes_shows_the_second() {
    let Some(path) = sponza() else { return };
    let path = path.to_string_lossy().into_owned();
    let mut worst = Duration::ZERO;
    // Moments spread over Sponza's load (about 1 s here) and meshing (about 3 s).
    let ms = Duration::from_millis;
    for (stage, delay) in [
        (Stage::Loading, ms(0)),
        (Stage::Loading, ms(250)),
        (Stage::Loading, ms(600)),
        (Stage::Meshing, ms(0)),
        (Stage::Meshing, ms(400)),
        (Stage::Meshing, ms(1200)),
        (Stage::Meshing, ms(2400)),
    ] {
        worst = worst.max(cancel_at(&path, stage, delay));
    }
    eprintln!("worst: {:.0} ms", worst.as_secs_f64() * 1e3);
}
