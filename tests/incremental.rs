//! Chen's incremental radiosity (live material edits): an edit shot as signed unshot energy
//! must land on the answer of solving the edited scene from scratch, whatever state the
//! solve is in when the edit arrives.
//!
//! Truth: the dense direct solve of the edited scene on the identical mesh (meshing, form
//! factors and their deterministic ray seeds do not depend on materials, so both sides
//! solve the same discrete system).

mod common;
use common::{converge, prepared, rms, settings};
use glam::Vec3;
use radiosity::mesh::surface_values;
use radiosity::pipeline::Prepared;
use radiosity::scene::{Scene, builtin};
use radiosity::solver::{Method, PatchEdit};
use std::sync::atomic::AtomicBool;

const WHITE: u32 = 0;
const RED: u32 = 1;
const LIGHT: u32 = 3;

/// The mesh size of every solve here (edits must not change the mesh).
const ELEMENTS: usize = 600;

/// The patch edits that give every patch of `material` the scene's (edited) values, as the
/// viewer's worker computes them.
fn edits(scene: &Scene, p: &Prepared, material: u32) -> Vec<PatchEdit> {
    p.mesh
        .patches
        .iter()
        .enumerate()
        .filter(|(_, patch)| patch.material == material)
        .map(|(i, patch)| {
            let (rho, e, _) = surface_values(
                &scene.materials[material as usize],
                &scene.objects[patch.object as usize],
                patch.triangle as usize,
            );
            PatchEdit {
                patch: i as u32,
                reflectance: rho,
                emission: e,
            }
        })
        .collect()
}

fn exact(scene: &Scene, elements: usize) -> Vec<Vec3> {
    let p = prepared(scene, ELEMENTS);
    assert_eq!(
        p.mesh.elements.len(),
        elements,
        "edits must not change the mesh"
    );
    let mut s = p.solver(settings(Method::Direct, 0.0)).unwrap();
    s.run(None, &AtomicBool::new(false)).unwrap();
    s.radiosity()
}

/// Tolerance for "equal to the direct solve": the methods stop at 1e-6 of the source power
/// left unshot (or as residual), which leaves ≲ 1e-6/(1 − ρ_max) ≈ 4e-6 of the answer; 1e-4
/// also absorbs f32 storage of B and E' (same bound as tests/solvers.rs).
const AGREE: f64 = 1e-4;

#[test]
fn an_edit_after_convergence_reaches_the_edited_scenes_answer() {
    for method in [
        Method::Progressive,
        Method::Jacobi,
        Method::GaussSeidel,
        Method::Direct,
    ] {
        let mut scene = builtin::cornell_box();
        let p = prepared(&scene, ELEMENTS);
        let mut s = p.solver(settings(method, 1e-6)).unwrap();
        converge(&mut s);
        let before = s.radiosity();
        // The red wall turns blue and the light gets 1.5× brighter.
        scene.materials[RED as usize].reflectance = Vec3::new(0.05, 0.1, 0.6);
        scene.materials[LIGHT as usize].emission *= 1.5;
        let mut all = edits(&scene, &p, RED);
        all.extend(edits(&scene, &p, LIGHT));
        s.edit_patches(&all);
        assert!(!s.is_converged(), "{method}: an edit must reopen the solve");
        converge(&mut s);
        let truth = exact(&scene, p.mesh.elements.len());
        let err = rms(&s.radiosity(), &truth, &p.mesh);
        assert!(
            err < AGREE,
            "{method}: RMS difference to the edited direct solve {err:e}"
        );
        assert!(
            rms(&before, &truth, &p.mesh) > 0.1,
            "{method}: the edit changed too little to test"
        );
    }
}

#[test]
fn an_edit_in_mid_solve_from_black_is_exact() {
    // White starts black (ρ = 0): no light has been reflected by it, so an edit cannot be
    // a rescaling of its reflected light; it needs the gathered radiosity H the solver
    // tracks. The edit arrives after a few shots, with most energy still unshot.
    let mut scene = builtin::cornell_box();
    scene.materials[WHITE as usize].reflectance = Vec3::ZERO;
    let p = prepared(&scene, ELEMENTS);
    let mut s = p.solver(settings(Method::Progressive, 1e-6)).unwrap();
    let cancel = AtomicBool::new(false);
    while s.stats().iterations < 5 {
        s.step(&cancel).unwrap();
    }
    scene.materials[WHITE as usize].reflectance = Vec3::splat(0.73);
    s.edit_patches(&edits(&scene, &p, WHITE));
    converge(&mut s);
    let truth = exact(&scene, p.mesh.elements.len());
    let err = rms(&s.radiosity(), &truth, &p.mesh);
    assert!(
        err < AGREE,
        "RMS difference to the edited direct solve {err:e}"
    );
}

#[test]
fn turning_the_light_off_shoots_the_light_back_out() {
    // Negative unshot energy: every element must return to zero (no other source).
    let mut scene = builtin::cornell_box();
    let p = prepared(&scene, ELEMENTS);
    let mut s = p.solver(settings(Method::Progressive, 1e-6)).unwrap();
    converge(&mut s);
    let peak = s
        .radiosity()
        .iter()
        .map(|b| b.max_element())
        .fold(0.0f32, f32::max);
    scene.materials[LIGHT as usize].emission = Vec3::ZERO;
    s.edit_patches(&edits(&scene, &p, LIGHT));
    converge(&mut s);
    let left = s
        .radiosity()
        .iter()
        .map(|b| b.abs().max_element())
        .fold(0.0f32, f32::max);
    // 1e-6 of the old source power left unshot bounds what remains; 1e-4 of the old peak
    // is a loose ceiling on it per element (the light's own elements held the peak).
    assert!(left < 1e-4 * peak, "left {left} of peak {peak}");
}

#[test]
fn an_emission_only_edit_scales_the_answer_linearly() {
    // With reflectances fixed, B is linear in E: doubling the only emitter doubles every B.
    // An independent check that needs no reference solve.
    let mut scene = builtin::cornell_box();
    let p = prepared(&scene, ELEMENTS);
    let mut s = p.solver(settings(Method::Progressive, 1e-7)).unwrap();
    converge(&mut s);
    let before = s.radiosity();
    scene.materials[LIGHT as usize].emission *= 2.0;
    s.edit_patches(&edits(&scene, &p, LIGHT));
    converge(&mut s);
    let doubled: Vec<Vec3> = before.iter().map(|b| *b * 2.0).collect();
    let err = rms(&s.radiosity(), &doubled, &p.mesh);
    assert!(err < AGREE, "RMS difference to 2 × before: {err:e}");
}
