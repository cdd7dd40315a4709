//! The baked export (`export::baked_glb`): the Khronos glTF validator accepts it, and our
//! loader reads it back as the scene it was baked from (materials, textures, geometry),
//! so that solving it again gives the same light.

mod common;

use glam::Vec3;
use radiosity::export::{Bake, baked_glb};
use radiosity::exposure::auto_exposure;
use radiosity::mesh::MeshSettings;
use radiosity::pipeline::Prepared;
use radiosity::scene::Scene;
use radiosity::solver::{Method, Solver, SolverSettings};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::Duration;

/// Solves `scene` with `method` on at most `elements` elements (for at most `limit`).
fn solve(scene: &Scene, method: Method, elements: usize, limit: Option<Duration>) -> Solver {
    let prepared = Prepared::new(
        scene,
        &MeshSettings {
            max_elements: Some(elements),
            ..Default::default()
        },
    );
    let mut solver = prepared
        .solver(SolverSettings {
            method,
            adaptive: None,
            ..Default::default()
        })
        .unwrap();
    solver.run(limit, &AtomicBool::new(false)).unwrap();
    solver
}

/// The .glb of `solver`'s solution of `scene`, at the auto exposure, written to `path`.
fn bake(scene: &Scene, solver: &Solver, path: &Path) {
    let radiosity = solver.radiosity();
    let ev = auto_exposure(solver.mesh(), &radiosity).map_or(0.0, |a| a.0);
    let bytes = baked_glb(
        scene,
        solver.mesh(),
        &Bake {
            radiosity: &radiosity,
            reflectance: &solver.reflectance(),
            emission: &solver.emission(),
            exposure: 2f32.powf(ev),
            tonemap: Default::default(),
        },
    );
    std::fs::write(path, bytes).unwrap();
}

/// `node_modules` holding the npm package `gltf-validator` (`.ci/run` installs it under
/// `target/gltf-validator`), or `None` with a note when it is missing; under CI (the `CI`
/// variable set) a missing validator fails the test instead.
fn validator() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/gltf-validator/node_modules");
    let found = dir.join("gltf-validator").is_dir()
        && std::process::Command::new("node")
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success());
    if found {
        return Some(dir);
    }
    let how = "npm install --prefix target/gltf-validator gltf-validator@2.0.0-dev.3.10";
    assert!(
        std::env::var_os("CI").is_none(),
        "the Khronos glTF validator is not at {} (install it: {how}) and CI is set",
        dir.display()
    );
    eprintln!("skipped: the Khronos glTF validator is not installed ({how})");
    None
}

#[test]
fn exported_files_pass_the_khronos_validator() {
    let Some(node_modules) = validator() else {
        return;
    };
    let Some(scenes) = common::shared_scenes() else {
        return;
    };
    let dir = common::scratch_dir("export-validate");
    let mut files = Vec::new();
    // The built-in Cornell box, a textured Khronos sample and Sponza (262k triangles, 24
    // textures; a short stochastic solve is enough: the file's structure is the question).
    let cases: [(&str, Method, usize, Option<Duration>); 3] = [
        ("builtin:cornell", Method::Progressive, 1500, None),
        (
            "khronos-sample-assets/BoxTextured/glTF/BoxTextured.gltf",
            Method::Progressive,
            1500,
            None,
        ),
        (
            "sponza-crytek-converted/sponza.gltf",
            Method::StochasticJacobi,
            0,
            Some(Duration::from_secs(1)),
        ),
    ];
    for (k, (name, method, elements, limit)) in cases.into_iter().enumerate() {
        let spec = if name.starts_with("builtin:") {
            name.to_string()
        } else {
            scenes.join(name).to_string_lossy().into_owned()
        };
        let scene = radiosity::scene::open(&spec, None, None).unwrap();
        let solver = solve(&scene, method, elements.max(scene.triangle_count()), limit);
        let path = dir.join(format!("baked-{k}.glb"));
        bake(&scene, &solver, &path);
        files.push(path);
    }
    let out = std::process::Command::new("node")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/validate_gltf.cjs"))
        .args(&files)
        .env("NODE_PATH", &node_modules)
        .output()
        .unwrap();
    let report = String::from_utf8_lossy(&out.stdout);
    eprintln!("{report}");
    let lines: Vec<serde_json::Value> = report
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), files.len(), "{report}");
    for l in &lines {
        assert_eq!(l["errors"], 0, "{l}");
        assert_eq!(l["warnings"], 0, "{l}");
    }
    assert!(out.status.success(), "{report}");
}

/// Per material, the total area and the area-weighted mean radiosity of a solution, over
/// the surfaces in view (the export leaves out covered ones: a block's bottom on the floor
/// and the floor under it, which receive no light and are not drawn).
fn by_material(solver: &Solver, materials: usize) -> Vec<(f64, Vec3)> {
    let mesh = solver.mesh();
    let b = solver.radiosity();
    let mut out = vec![(0.0f64, Vec3::ZERO); materials];
    for (e, element) in mesh.elements.iter().enumerate() {
        let patch = &mesh.patches[element.patch as usize];
        if patch.covered {
            continue;
        }
        let m = patch.material as usize;
        out[m].0 += element.area as f64;
        out[m].1 += b[e] * element.area;
    }
    out.iter()
        .map(|&(a, s)| (a, if a > 0.0 { s / a as f32 } else { Vec3::ZERO }))
        .collect()
}

#[test]
fn a_baked_file_reads_back_as_the_scene_it_was_baked_from() {
    let dir = common::scratch_dir("export-round-trip");
    let mut specs = vec!["builtin:cornell".to_string()];
    if let Some(scenes) = common::shared_scenes() {
        specs.push(
            scenes
                .join("khronos-sample-assets/BoxTextured/glTF/BoxTextured.gltf")
                .to_string_lossy()
                .into_owned(),
        );
    }
    for spec in specs {
        let scene = radiosity::scene::open(&spec, None, None).unwrap();
        let solver = solve(&scene, Method::Progressive, 600, None);
        let path = dir.join("baked.glb");
        bake(&scene, &solver, &path);
        let back = radiosity::scene::open(path.to_str().unwrap(), None, None).unwrap();
        // The physical materials come back exactly (f32 through JSON's f64).
        assert_eq!(back.materials.len(), scene.materials.len(), "{spec}");
        for (a, b) in scene.materials.iter().zip(&back.materials) {
            assert_eq!(
                (a.reflectance, a.emission, a.double_sided),
                (b.reflectance, b.emission, b.double_sided),
                "{spec}: material {}",
                a.name
            );
            assert_eq!(a.base_texture.is_some(), b.base_texture.is_some(), "{spec}");
        }
        // The images are the files' own bytes.
        assert_eq!(back.images.len(), scene.images.len(), "{spec}");
        for (a, b) in scene.images.iter().zip(&back.images) {
            assert!(a.encoded == b.encoded, "{spec}: image {} changed", a.name);
        }
        // Solving the baked file gives the same light: per material, the same area and
        // mean radiosity as the original solved at the same budget. The two meshes differ
        // (the baked file's triangles are the original's elements), so the tolerance is
        // the discretisation error, measured here as the change of the original's own
        // means between a 600- and a 2400-element mesh (with a floor of 0.5 %).
        let n = scene.materials.len();
        let coarse = by_material(&solver, n);
        let fine = by_material(&solve(&scene, Method::Progressive, 2400, None), n);
        let again = by_material(&solve(&back, Method::Progressive, 2400, None), n);
        let rel = |a: Vec3, b: Vec3| (a - b).abs().max_element() / b.max_element().max(1e-9);
        for m in 0..n {
            let ((a0, b0), (a1, b1)) = (fine[m], again[m]);
            assert!(
                (a0 - a1).abs() <= 1e-4 * a0.max(1e-9),
                "{spec}: material {m} area {a0} vs {a1}"
            );
            let meshing = rel(coarse[m].1, b0);
            let round_trip = rel(b1, b0);
            eprintln!(
                "{spec}: material {m}: mean B {b0} vs {b1} after the round trip ({:.2} %; remeshing the original: {:.2} %)",
                100.0 * round_trip,
                100.0 * meshing
            );
            assert!(
                round_trip <= meshing.max(0.005),
                "{spec}: material {m}: mean B {b0} vs {b1}"
            );
        }
    }
}
