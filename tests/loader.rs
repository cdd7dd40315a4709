//! Integration tests of the glTF loader (`radiosity::scene::gltf`) against the test-scene
//! corpus in `../shared/scenes` (see its CATALOGUE.md and VALIDATION.tsv) and against the
//! built-in Cornell box written by `write_gltf`.
//!
//! Tests that need the corpus print why and return when it is absent.

use glam::{DVec3, Vec3};
use radiosity::scene::gltf::{LoadError, load, write_gltf};
use radiosity::scene::{Light, Scene, builtin};
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The corpus folder, or `None` (with a note on stderr) when it is not there.
fn corpus() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes");
    if dir.join("VALIDATION.tsv").is_file() {
        Some(dir)
    } else {
        eprintln!("skipped: the test scenes are not at {}", dir.display());
        None
    }
}

/// Loads `rel` (relative to the corpus) and fails the test with the error if it fails.
fn must_load(rel: &str) -> Option<Scene> {
    let dir = corpus()?;
    match load(&dir.join(rel)) {
        Ok(s) => Some(s),
        Err(e) => panic!("{rel} should load: {e}"),
    }
}

/// Every `.gltf` / `.glb` under `dir`, sorted.
fn model_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else { continue };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if matches!(p.extension().and_then(|x| x.to_str()), Some("gltf" | "glb")) {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// One row of VALIDATION.tsv.
struct Validation {
    /// Khronos validator error count (`None`: the validator could not read the file).
    errors: Option<u32>,
    /// The validator's `totalTriangleCount`.
    triangles: Option<usize>,
}

fn validation(dir: &Path) -> std::collections::HashMap<String, Validation> {
    let text = std::fs::read_to_string(dir.join("VALIDATION.tsv")).expect("VALIDATION.tsv");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or("").split('\t').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    let (file, errors, triangles) = (col("file"), col("validator_errors"), col("triangles"));
    lines
        .map(|l| l.split('\t').collect::<Vec<_>>())
        .filter(|c| c.len() > triangles)
        .map(|c| {
            (
                c[file].to_string(),
                Validation {
                    errors: c[errors].parse().ok(),
                    triangles: c[triangles].parse().ok(),
                },
            )
        })
        .collect()
}

/// Signed volume enclosed by an object's world-space triangles (positive when they face
/// outward counter-clockwise).
fn signed_volume(scene: &Scene, object: usize) -> f64 {
    let o = &scene.objects[object];
    o.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| o.world_position(v));
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

/// World-space bounds of one object.
fn object_bounds(scene: &Scene, object: usize) -> (DVec3, DVec3) {
    let o = &scene.objects[object];
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for v in 0..o.positions.len() as u32 {
        lo = lo.min(o.world_position(v));
        hi = hi.max(o.world_position(v));
    }
    (lo, hi)
}

#[test]
fn cornell_box_round_trips_through_write_gltf() {
    let original = builtin::cornell_box();
    let text = write_gltf(&original);
    let dir = std::env::temp_dir().join(format!("radiosity-loader-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("cornell round trip.gltf");
    std::fs::write(&path, &text).unwrap();
    let loaded = load(&path).unwrap_or_else(|e| panic!("{e}"));
    std::fs::remove_file(&path).ok();

    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    assert_eq!(loaded.triangle_count(), original.triangle_count());
    assert_eq!(loaded.objects.len(), original.objects.len());
    assert_eq!(loaded.materials.len(), original.materials.len());
    // Materials: reflectance is written as the shortest decimal of the f32 and emission as
    // factor × strength recomputed in f64, so both come back to within f32 rounding
    // (1e-6 relative covers one f32 ulp of values up to 17).
    for (a, b) in original.materials.iter().zip(&loaded.materials) {
        assert_eq!(a.name, b.name);
        assert!((a.reflectance - b.reflectance).abs().max_element() <= 1e-6, "{a:?} vs {b:?}");
        assert!((a.emission - b.emission).abs().max_element() <= 1e-6 * a.emission.max_element().max(1.0), "{a:?} vs {b:?}");
        assert_eq!(a.double_sided, b.double_sided);
        assert_eq!(a.transmittance, b.transmittance);
    }
    // Geometry: world positions are written as f32 (the builtin stores f32 too), so each
    // triangle corner matches to 1e-6 m (f32 resolution at ~0.5 m is 6e-8 m).
    for (oa, ob) in original.objects.iter().zip(&loaded.objects) {
        assert_eq!(oa.name, ob.name);
        // Triangles are grouped by material on export; compare as sorted multisets.
        let corners = |o: &radiosity::scene::Object| {
            let mut v: Vec<(u32, [[i64; 3]; 3])> = o
                .triangles
                .iter()
                .zip(&o.triangle_material)
                .map(|(t, &m)| (m, t.map(|i| o.world_position(i).to_array().map(|c| (c * 1e6).round() as i64))))
                .collect();
            v.sort();
            v
        };
        let (ca, cb) = (corners(oa), corners(ob));
        assert_eq!(ca.len(), cb.len());
        for ((ma, ta), (mb, tb)) in ca.iter().zip(&cb) {
            assert_eq!(ma, mb);
            for (pa, pb) in ta.iter().zip(tb) {
                for (x, y) in pa.iter().zip(pb) {
                    assert!((x - y).abs() <= 1, "{ta:?} vs {tb:?}");
                }
            }
        }
    }
}

/// Loads every file of the corpus under `catch_unwind` and checks what must hold for each.
#[test]
fn every_corpus_file_loads_or_fails_cleanly() {
    let Some(dir) = corpus() else { return };
    let expected = validation(&dir);
    let mut panicked = Vec::new();
    let mut failures = Vec::new();
    let (mut loaded, mut rejected) = (0, 0);
    let started = Instant::now();
    for path in model_files(&dir) {
        let rel = path.strip_prefix(&dir).unwrap().to_string_lossy().replace('\\', "/");
        let t0 = Instant::now();
        let result = std::panic::catch_unwind(AssertUnwindSafe(|| load(&path)));
        let secs = t0.elapsed().as_secs_f64();
        if secs > 2.0 {
            eprintln!("slow: {rel} took {secs:.1} s");
        }
        let Ok(result) = result else {
            panicked.push(rel);
            continue;
        };
        let file_name = path.file_name().unwrap().to_string_lossy().to_string();
        let v = expected.get(&rel);
        let must_succeed = !rel.starts_with("invalid/") && v.is_some_and(|v| v.errors == Some(0));
        match result {
            Ok(scene) => {
                loaded += 1;
                for w in &scene.warnings {
                    if !w.starts_with(&scene.name) {
                        failures.push(format!("{rel}: warning does not start with the path: {w}"));
                    }
                }
                if rel.contains("Draco") || rel.contains("/draco/") {
                    failures.push(format!("{rel}: Draco file was accepted"));
                }
                // The validator's totalTriangleCount counts each mesh once and includes
                // degenerate triangles; the loader counts per node instance after dropping
                // zero-area ones. They must agree where neither applies (checked below and
                // in `triangle_counts_match_the_validator`).
                let _ = scene.triangle_count();
            }
            Err(e) => {
                rejected += 1;
                let msg = e.to_string();
                if !msg.contains(&file_name) {
                    failures.push(format!("{rel}: error does not name the file: {msg}"));
                }
                if msg.contains('\n') {
                    failures.push(format!("{rel}: error is not one line: {msg}"));
                }
                let draco = rel.contains("Draco") || rel.contains("/draco/");
                if draco && !msg.contains("Draco") {
                    failures.push(format!("{rel}: Draco rejection does not say Draco: {msg}"));
                }
                if must_succeed && !draco {
                    failures.push(format!("{rel}: valid file (0 validator errors) rejected: {msg}"));
                }
            }
        }
    }
    eprintln!(
        "{loaded} files loaded, {rejected} rejected in {:.1} s",
        started.elapsed().as_secs_f64()
    );
    assert!(panicked.is_empty(), "load panicked on: {panicked:#?}");
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn survey() {
    let Some(dir) = corpus() else { return };
    let expected = validation(&dir);
    for path in model_files(&dir) {
        let rel = path.strip_prefix(&dir).unwrap().to_string_lossy().to_string();
        let v = expected.get(&rel);
        let t0 = Instant::now();
        let r = load(&path);
        let secs = t0.elapsed().as_secs_f64();
        match r {
            Ok(s) => {
                println!(
                    "OK  {rel}: {} tris (validator {:?}, errors {:?}), {} objects, {} lights, {:.2}s",
                    s.triangle_count(),
                    v.and_then(|v| v.triangles),
                    v.and_then(|v| v.errors),
                    s.objects.len(),
                    s.lights.len(),
                    secs
                );
                for w in &s.warnings {
                    println!("      {w}");
                }
            }
            Err(e) => println!("ERR {rel} (errors {:?}): {e}", v.and_then(|v| v.errors)),
        }
    }
}
