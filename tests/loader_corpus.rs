//! The glTF loader (`radiosity::scene::gltf`) against the test-scene corpus in
//! `../shared/scenes` (see its CATALOGUE.md and VALIDATION.tsv): every file loads or fails
//! cleanly, and chosen sample files give what they are documented or validated to hold.
//!
//! Tests that need the corpus print why and return when it is absent, except under CI,
//! where they fail (`common::shared_scenes`).

mod common;
use common::{scenes_at, shared_scenes};
use glam::{DVec3, Vec3};
use radiosity::scene::gltf::{LoadError, load};
use radiosity::scene::{Light, Scene};
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Loads `rel` (relative to the corpus) and fails the test with the error if it fails.
fn must_load(rel: &str) -> Option<Scene> {
    let dir = shared_scenes()?;
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
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
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
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .unwrap_or_else(|| panic!("no column {name}"))
    };
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

/// The JSON of a `.gltf` or `.glb` file, read independently of the loader (for the
/// expectations of the tests).
fn file_json(path: &Path) -> Option<serde_json::Value> {
    let bytes = std::fs::read(path).ok()?;
    let json = if bytes.starts_with(b"glTF") {
        let len = u32::from_le_bytes(bytes.get(12..16)?.try_into().ok()?) as usize;
        bytes.get(20..20 + len)?.to_vec()
    } else {
        bytes
    };
    serde_json::from_slice(&json).ok()
}

/// Whether the file's scene draws every mesh exactly once (then the validator's
/// per-mesh `totalTriangleCount` is also the per-instance count the loader gives).
fn meshes_drawn_once(doc: &serde_json::Value) -> bool {
    let empty = Vec::new();
    let nodes = doc["nodes"].as_array().unwrap_or(&empty);
    let meshes = doc["meshes"].as_array().map_or(0, Vec::len);
    let scene = doc["scene"].as_u64().unwrap_or(0) as usize;
    let mut stack: Vec<usize> = doc["scenes"][scene]["nodes"]
        .as_array()
        .unwrap_or(&empty)
        .iter()
        .filter_map(|v| v.as_u64().map(|v| v as usize))
        .collect();
    let mut uses = vec![0usize; meshes];
    let mut seen = vec![false; nodes.len()];
    while let Some(n) = stack.pop() {
        if n >= nodes.len() || std::mem::replace(&mut seen[n], true) {
            continue;
        }
        if let Some(u) = nodes[n]["mesh"]
            .as_u64()
            .and_then(|m| uses.get_mut(m as usize))
        {
            *u += 1;
        }
        for c in nodes[n]["children"].as_array().unwrap_or(&empty) {
            stack.extend(c.as_u64().map(|c| c as usize));
        }
    }
    uses.iter().all(|&u| u == 1)
}

/// The number in a warning line "… N <what> …" (0 when there is no such line).
fn counted(scene: &Scene, what: &str) -> usize {
    scene
        .warnings
        .iter()
        .find(|w| w.contains(what))
        .and_then(|w| {
            w[scene.name.len()..]
                .trim_start_matches(':')
                .split_whitespace()
                .next()?
                .parse()
                .ok()
        })
        .unwrap_or(0)
}

/// Loads every file of the corpus under `catch_unwind`: none may panic; errors are one line
/// naming the file; files outside `invalid/` with 0 validator errors must load (except the
/// Draco ones, which must be refused saying so), and there the triangle count must equal the
/// validator's `totalTriangleCount` once dropped zero-area triangles are added back —
/// except where the scene instances a mesh several times or leaves one out (the validator
/// counts each mesh once), which is printed as an exception.
#[test]
fn every_corpus_file_loads_or_fails_cleanly() {
    let Some(dir) = shared_scenes() else { return };
    let expected = validation(&dir);
    let mut panicked = Vec::new();
    let mut failures = Vec::new();
    let (mut loaded, mut rejected, mut compared) = (0, 0, 0);
    let started = Instant::now();
    for path in model_files(&dir) {
        let rel = path
            .strip_prefix(&dir)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let t0 = Instant::now();
        let result = std::panic::catch_unwind(AssertUnwindSafe(|| load(&path)));
        let secs = t0.elapsed().as_secs_f64();
        if secs > 1.0 {
            eprintln!("slow: {rel} took {secs:.1} s");
        }
        let Ok(result) = result else {
            panicked.push(rel);
            continue;
        };
        let file_name = path.file_name().unwrap().to_string_lossy().to_string();
        let v = expected.get(&rel);
        let valid = !rel.starts_with("invalid/") && v.is_some_and(|v| v.errors == Some(0));
        let draco = rel.contains("Draco") || rel.contains("/draco/");
        match result {
            Ok(scene) => {
                loaded += 1;
                for w in &scene.warnings {
                    if !w.starts_with(&scene.name) || w.contains('\n') {
                        failures.push(format!(
                            "{rel}: warning is not one line starting with the path: {w}"
                        ));
                    }
                }
                if draco {
                    failures.push(format!("{rel}: Draco file was accepted"));
                }
                let Some(expect) = v.and_then(|v| v.triangles).filter(|_| valid) else {
                    continue;
                };
                let dropped = counted(&scene, "zero-area triangle");
                let got = scene.triangle_count();
                if file_json(&path).is_some_and(|d| meshes_drawn_once(&d)) {
                    compared += 1;
                    if got + dropped != expect {
                        failures.push(format!("{rel}: {got} triangles + {dropped} zero-area dropped, validator says {expect}"));
                    }
                } else {
                    eprintln!(
                        "count not compared (meshes instanced or unused): {rel}: {got} + {dropped} dropped vs validator {expect} per mesh"
                    );
                }
            }
            Err(e) => {
                rejected += 1;
                let msg = e.to_string();
                if !msg.contains(&file_name) || msg.contains('\n') {
                    failures.push(format!(
                        "{rel}: error is not one line naming the file: {msg}"
                    ));
                }
                if draco && !msg.contains("Draco") {
                    failures.push(format!("{rel}: Draco rejection does not say Draco: {msg}"));
                }
                if valid && !draco {
                    failures.push(format!(
                        "{rel}: valid file (0 validator errors) rejected: {msg}"
                    ));
                }
            }
        }
    }
    eprintln!(
        "{loaded} files loaded, {rejected} rejected, {compared} triangle counts compared, in {:.1} s",
        started.elapsed().as_secs_f64()
    );
    assert!(panicked.is_empty(), "load panicked on: {panicked:#?}");
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn box_has_twelve_red_triangles() {
    for rel in [
        "khronos-sample-assets/Box/glTF/Box.gltf",
        "khronos-sample-assets/Box/glTF-Binary/Box.glb",
        "khronos-sample-assets/Box/glTF-Embedded/Box.gltf",
        "khronos-sample-assets/Box With Spaces/glTF/Box With Spaces.gltf",
    ] {
        let Some(s) = must_load(rel) else { return };
        assert_eq!(s.triangle_count(), 12, "{rel}");
        if rel.contains("/Box/") {
            // Box.gltf: one material "Red", baseColorFactor [0.8, 0, 0, 1] (f32 in the file).
            assert_eq!(s.materials.len(), 1);
            assert!(
                (s.materials[0].reflectance - Vec3::new(0.8, 0.0, 0.0))
                    .abs()
                    .max_element()
                    < 1e-6
            );
        }
        // A closed box seen from outside: its signed volume is positive and equals its
        // bounding box's (an axis-aligned cube; 1e-5 relative covers f32 positions).
        let v: f64 = (0..s.objects.len()).map(|o| signed_volume(&s, o)).sum();
        let (lo, hi) = s.bounds().unwrap();
        let cube = (hi - lo).element_product();
        assert!(
            v > 0.0 && (v - cube).abs() < 1e-5 * cube,
            "{rel}: volume {v}, bounds {cube}"
        );
    }
}

#[test]
fn primitive_modes_give_the_validator_counts_and_one_warning() {
    let Some(s) =
        must_load("khronos-sample-assets/MeshPrimitiveModes/glTF/MeshPrimitiveModes.gltf")
    else {
        return;
    };
    assert_eq!(s.triangle_count(), 16);
    let point_line: Vec<_> = s
        .warnings
        .iter()
        .filter(|w| w.contains("point/line"))
        .collect();
    assert_eq!(point_line.len(), 1, "{:?}", s.warnings);
    // The asset-generator quads (triangles, strip, fan; non-indexed and u8/u16/u32 indexed)
    // all face the viewer on +z: strips and fans must be unrolled with the spec's winding.
    for n in [4, 5, 6, 11, 12, 13, 14, 15] {
        let rel = format!("asset-generator-mesh-primitive-mode/Mesh_PrimitiveMode_{n:02}.gltf");
        let Some(s) = must_load(&rel) else { return };
        assert_eq!(s.triangle_count(), 2, "{rel}");
        for o in &s.objects {
            for t in &o.triangles {
                let [a, b, c] = t.map(|v| o.world_position(v));
                assert!(
                    (b - a).cross(c - a).z > 0.0,
                    "{rel}: triangle faces away from +z"
                );
            }
        }
    }
}

#[test]
fn sparse_accessor_positions_are_substituted() {
    for rel in [
        "khronos-sample-assets/SimpleSparseAccessor/glTF/SimpleSparseAccessor.gltf",
        "khronos-sample-assets/SimpleSparseAccessor/glTF-Embedded/SimpleSparseAccessor.gltf",
    ] {
        let Some(s) = must_load(rel) else { return };
        // The base grid spans y ∈ [0, 1]; the sparse values move vertices 8, 10, 12 to
        // y = 2, 3, 4 (read from the .bin), so the bounds are (0,0,0)–(6,4,0) exactly.
        let (lo, hi) = s.bounds().unwrap();
        assert_eq!((lo, hi), (DVec3::ZERO, DVec3::new(6.0, 4.0, 0.0)), "{rel}");
        assert_eq!(s.triangle_count(), 12);
    }
}

#[test]
fn mirrored_objects_keep_their_triangles_facing_outward() {
    for rel in [
        "khronos-sample-assets/NegativeScaleTest/glTF/NegativeScaleTest.gltf",
        "khronos-sample-assets/NegativeScaleTest/glTF-Binary/NegativeScaleTest.glb",
    ] {
        let Some(s) = must_load(rel) else { return };
        let find = |name: &str| {
            s.objects
                .iter()
                .position(|o| o.name == name)
                .unwrap_or_else(|| panic!("{name}"))
        };
        let mut mirrored = 0;
        // Three icosphere pairs: an un-mirrored sphere and its twin under a negative scale
        // (each pair in a parent that may itself be mirrored). All are closed, so outward
        // counter-clockwise triangles give a positive signed volume, the same for both twins
        // (1e-9 relative: the same f32 vertices through f64 transforms).
        for (a, b) in [
            ("NotShiny1", "NotShinyMinus1"),
            ("Shiny1", "ShinyMinus1"),
            ("Dark1", "DarkMinus1"),
        ] {
            let (ia, ib) = (find(a), find(b));
            let (va, vb) = (signed_volume(&s, ia), signed_volume(&s, ib));
            assert!(va > 0.0 && vb > 0.0, "{rel}: {a} {va}, {b} {vb}");
            assert!(
                (va - vb).abs() <= 1e-9 * va.abs(),
                "{rel}: {a} {va}, {b} {vb}"
            );
            mirrored += s.objects[ia].mirrors() as usize + s.objects[ib].mirrors() as usize;
        }
        assert!(
            mirrored >= 2,
            "{rel}: the test file should contain mirrored spheres"
        );
    }
}

#[test]
fn emissive_strength_multiplies_the_emissive_factor() {
    for rel in [
        "khronos-sample-assets/EmissiveStrengthTest/glTF/EmissiveStrengthTest.gltf",
        "khronos-sample-assets/EmissiveStrengthTest/glTF-Binary/EmissiveStrengthTest.glb",
    ] {
        let Some(s) = must_load(rel) else { return };
        // Cube k uses emissiveFactor [0.1, 0.5, 0.9] with emissiveStrength k (1 = absent).
        for k in [1, 2, 4, 8, 16] {
            let o = s
                .objects
                .iter()
                .find(|o| o.name == format!("Cube{k}"))
                .expect("cube");
            let m = &s.materials[o.triangle_material[0] as usize];
            let want = Vec3::new(0.1, 0.5, 0.9) * k as f32;
            // Tolerance: f32 rounding of factor × strength (relative 1e-6).
            assert!(
                (m.emission - want).abs().max_element() <= 1e-6 * want.max_element(),
                "{rel} Cube{k}: {:?}",
                m.emission
            );
            assert_eq!(m.reflectance, Vec3::ZERO);
        }
        assert!(s.has_light());
    }
}

#[test]
fn lights_punctual_lamp_has_its_five_point_lights() {
    let rel = "khronos-sample-assets/LightsPunctualLamp/glTF/LightsPunctualLamp.gltf";
    let Some(s) = must_load(rel) else { return };
    let doc = file_json(&shared_scenes().unwrap().join(rel)).unwrap();
    let mut want: Vec<[f32; 3]> = doc["extensions"]["KHR_lights_punctual"]["lights"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| {
            let i = l["intensity"].as_f64().unwrap_or(1.0);
            let c = |k: usize| l["color"][k].as_f64().unwrap_or(1.0);
            [(c(0) * i) as f32, (c(1) * i) as f32, (c(2) * i) as f32]
        })
        .collect();
    let mut got: Vec<[f32; 3]> = s
        .lights
        .iter()
        .map(|l| match l {
            Light::Point {
                intensity,
                position,
                range,
            } => {
                assert!(position.is_finite() && range.is_none());
                intensity.to_array()
            }
            other => panic!("not a point light: {other:?}"),
        })
        .collect();
    assert_eq!(got.len(), 5);
    want.sort_by(|a, b| a.partial_cmp(b).unwrap());
    got.sort_by(|a, b| a.partial_cmp(b).unwrap());
    // color × intensity in W/sr, computed the same way (f64 product, then f32).
    assert_eq!(got, want);
    // The light nodes are root nodes with a `matrix`: positions are its translation column.
    let mut want_pos: Vec<[f64; 3]> = doc["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|n| n.get("extensions").is_some())
        .map(|n| [12, 13, 14].map(|k| n["matrix"][k].as_f64().unwrap()))
        .collect();
    let mut got_pos: Vec<[f64; 3]> = s
        .lights
        .iter()
        .map(|l| match l {
            Light::Point { position, .. } => position.to_array(),
            _ => unreachable!(),
        })
        .collect();
    want_pos.sort_by(|a, b| a.partial_cmp(b).unwrap());
    got_pos.sort_by(|a, b| a.partial_cmp(b).unwrap());
    assert_eq!(got_pos, want_pos);
    assert!(
        s.materials.iter().any(|m| m.transmittance > 0.0),
        "KHR_materials_transmission glass"
    );
}

#[test]
fn point_and_spot_lights_from_the_validator_suite() {
    let Some(s) =
        must_load("invalid/khronos-gltf-validator/ext/KHR_lights_punctual/node/valid.gltf")
    else {
        return;
    };
    assert_eq!(
        s.lights,
        vec![Light::Point {
            position: DVec3::ZERO,
            intensity: Vec3::ONE,
            range: None
        }]
    );
    // Broken light definitions are skipped with a warning, never an error.
    for name in [
        "unresolved_light_empty_root_array",
        "unresolved_light_no_root_ext",
        "empty_object",
    ] {
        let rel =
            format!("invalid/khronos-gltf-validator/ext/KHR_lights_punctual/node/{name}.gltf");
        let Some(s) = must_load(&rel) else { return };
        assert!(s.lights.is_empty() && !s.warnings.is_empty(), "{rel}");
    }
}

#[test]
fn cornell_box_nvpro_loads_leniently_with_its_emitter() {
    let Some(s) = must_load("cornell-box-nvpro/cornellBox.gltf") else {
        return;
    };
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("textures[0]") && w.contains("image")),
        "{:?}",
        s.warnings
    );
    assert!(s.has_light());
    assert!(s.materials.iter().any(|m| m.emission == Vec3::splat(3.0)));
    // 16,720 per the validator (each mesh once) + 12 for the cube mesh drawn by two nodes;
    // the sphere poles are zero-area and dropped.
    let dropped = counted(&s, "zero-area triangle");
    assert_eq!(s.triangle_count() + dropped, 16_720 + 12);
    eprintln!(
        "cornell-box-nvpro: {} triangles, {dropped} zero-area dropped",
        s.triangle_count()
    );
}

#[test]
fn sponza_loads_with_alpha_masked_triangles() {
    let t0 = Instant::now();
    let Some(s) = must_load("sponza-crytek-converted/sponza.gltf") else {
        return;
    };
    let secs = t0.elapsed().as_secs_f64();
    let dropped = counted(&s, "zero-area triangle");
    eprintln!(
        "sponza: {} triangles ({dropped} zero-area dropped of 262,249), {} objects, loaded in {secs:.2} s",
        s.triangle_count(),
        s.objects.len()
    );
    assert_eq!(s.triangle_count() + dropped, 262_249);
    let masked: usize = s
        .objects
        .iter()
        .map(|o| o.transmittance.iter().filter(|&&t| t > 0.0).count())
        .sum();
    let tinted: usize = s.objects.iter().map(|o| o.reflectance_tint.len()).sum();
    eprintln!("sponza: {masked} triangles with transmittance > 0, {tinted} with a texture tint");
    assert!(masked > 0);
    assert_eq!(
        tinted,
        s.triangle_count(),
        "every Sponza material has a base colour texture"
    );
    // Tints are means of sRGB-decoded 8-bit texels: in [0, 1].
    for o in &s.objects {
        assert!(
            o.reflectance_tint
                .iter()
                .all(|t| t.cmpge(Vec3::ZERO).all() && t.cmple(Vec3::ONE).all())
        );
    }
}

#[test]
fn node_cycles_terminate() {
    let Some(dir) = shared_scenes() else { return };
    let path = dir.join("invalid/assimp/RecursiveNodes/RecursiveNodes.gltf");
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(load(&path).map(|s| s.warnings));
    });
    // A hang would be a failure, not a stuck test run.
    let warnings = rx
        .recv_timeout(std::time::Duration::from_secs(20))
        .expect("loading a node cycle did not finish")
        .expect("the cycle is skipped, not an error");
    assert!(
        warnings.iter().any(|w| w.contains("more than once")),
        "{warnings:?}"
    );
}

#[test]
fn out_of_range_indices_and_infinities_drop_triangles() {
    let Some(s) = must_load("invalid/assimp/IndexOutOfRange/IndexOutOfRange.gltf") else {
        return;
    };
    assert_eq!(s.triangle_count(), 11);
    assert_eq!(counted(&s, "out of range"), 1);
    let Some(s) = must_load("invalid/assimp/BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb")
    else {
        return;
    };
    assert_eq!(counted(&s, "NaN or infinite"), 12 - s.triangle_count());
}

#[test]
fn a_missing_bin_is_an_error_naming_the_scene_and_the_file() {
    let Some(c) = shared_scenes() else { return };
    let err = load(&c.join("invalid/assimp/MissingBin/BoxTextured.gltf")).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("BoxTextured.gltf") && msg.contains("BoxTextured0.bin"),
        "{msg}"
    );
}

#[test]
fn draco_files_are_refused_clearly() {
    let Some(dir) = shared_scenes() else { return };
    for rel in [
        "khronos-sample-assets/Box/glTF-Draco/Box.gltf",
        "khronos-sample-assets/Duck/glTF-Draco/Duck.gltf",
        "assimp-gltf2-tests/draco/2CylinderEngine.gltf",
    ] {
        let err = load(&dir.join(rel)).unwrap_err();
        assert!(matches!(err, LoadError::Unsupported { .. }), "{rel}: {err}");
        let msg = err.to_string();
        assert!(
            msg.contains("Draco-compressed meshes (KHR_draco_mesh_compression) are not supported"),
            "{msg}"
        );
        assert!(msg.contains(Path::new(rel).file_name().unwrap().to_str().unwrap()));
    }
}

#[test]
fn quantized_duck_loads_with_its_texture() {
    let Some(s) = must_load("khronos-sample-assets/Duck/glTF-Quantized/Duck.gltf") else {
        return;
    };
    assert_eq!(s.triangle_count(), 4_212);
    // Dequantized positions (unsigned shorts through the node's scale and translation) must
    // give the duck's float bounds, which the Draco variant keeps in its POSITION accessor:
    // min (−69.379, 9.849, −61.409), max (96.261, 164.090, 54.030) under a 0.01 scale.
    // Tolerance 2 mm: the quantization step is 0.1 mm, and the two files' extremes come from
    // different encoders.
    let (lo, hi) = s.bounds().unwrap();
    let want_lo = DVec3::new(-69.37933953401223, 9.848530453475558, -61.40903695222513) * 0.01;
    let want_hi = DVec3::new(96.26074059602396, 164.09024489374352, 54.029730459044615) * 0.01;
    assert!(
        (lo - want_lo).abs().max_element() < 2e-3 && (hi - want_hi).abs().max_element() < 2e-3,
        "{lo} {hi}"
    );
    // The base colour texture is reached through quantized UVs + KHR_texture_transform.
    let o = &s.objects[0];
    assert_eq!(o.reflectance_tint.len(), o.triangles.len());
    let mean = o.reflectance_tint.iter().copied().sum::<Vec3>() / o.triangles.len() as f32;
    // The duck is yellow: red and green well above blue.
    assert!(mean.x > 2.0 * mean.z && mean.y > 1.5 * mean.z, "{mean}");
}

#[test]
fn textures_from_file_data_uri_and_glb_agree() {
    let mut tints = Vec::new();
    for rel in [
        "khronos-sample-assets/BoxTextured/glTF/BoxTextured.gltf",
        "khronos-sample-assets/BoxTextured/glTF-Embedded/BoxTextured.gltf",
        "khronos-sample-assets/BoxTextured/glTF-Binary/BoxTextured.glb",
    ] {
        let Some(s) = must_load(rel) else { return };
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        tints.push(s.objects[0].reflectance_tint.clone());
    }
    assert_eq!(tints[0].len(), 12);
    // The same PNG through three containers: identical factors.
    assert_eq!(tints[0], tints[1]);
    assert_eq!(tints[0], tints[2]);
    assert!(
        tints[0]
            .iter()
            .all(|t| t.max_element() < 1.0 && t.min_element() > 0.0)
    );
}

#[test]
fn alpha_modes_give_transmittance() {
    let Some(s) =
        must_load("khronos-sample-assets/AlphaBlendModeTest/glTF/AlphaBlendModeTest.gltf")
    else {
        return;
    };
    let all: Vec<f32> = s
        .objects
        .iter()
        .flat_map(|o| o.transmittance.iter().copied())
        .collect();
    assert!(all.iter().all(|t| (0.0..=1.0).contains(t)));
    assert!(
        all.iter().any(|&t| t > 0.0 && t < 1.0),
        "partial (BLEND or partly masked) triangles"
    );
    let opaque = s
        .objects
        .iter()
        .find(|o| o.name.contains("Opaque"))
        .expect("the opaque sample");
    assert!(
        opaque.transmittance.is_empty()
            && s.materials[opaque.triangle_material[0] as usize].transmittance == 0.0
    );
    // The emissive texture of MultiUVTest is read through TEXCOORD_1.
    let Some(s) = must_load("khronos-sample-assets/MultiUVTest/glTF/MultiUVTest.gltf") else {
        return;
    };
    assert!(s.objects.iter().any(|o| !o.emission_tint.is_empty()));
}

#[test]
fn a_missing_corpus_skips_outside_ci_and_fails_under_it() {
    let nowhere = Path::new("/nonexistent/radiosity/shared/scenes");
    assert_eq!(scenes_at(nowhere, false), None);
    let under_ci = std::panic::catch_unwind(|| scenes_at(nowhere, true));
    let message = under_ci.expect_err("a missing corpus must fail under CI");
    let message = message
        .downcast_ref::<String>()
        .expect("a formatted panic message");
    assert!(
        message.contains("/nonexistent/radiosity/shared/scenes") && message.contains("CI"),
        "{message}"
    );
}
