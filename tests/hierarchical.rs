//! Hierarchical radiosity with clustering against independent truth: the white furnace's
//! closed form with clustering on, clustering on and off against each other within the
//! oracle's bound, an edited solve against a from-scratch solve of the edited scene (and
//! no new form factor for an edit that dims the light), and identical results for one and
//! two threads.

mod common;

use common::prepared;
use glam::{DVec3, Vec3};
use radiosity::mesh::Mesh;
use radiosity::scene::{Scene, builtin};
use radiosity::solver::{HierarchySettings, Method, PatchEdit, Solver, SolverSettings};

fn settings(hierarchy: HierarchySettings) -> SolverSettings {
    SolverSettings {
        method: Method::Hierarchical,
        hierarchy,
        ..Default::default()
    }
}

fn solve(scene: &Scene, hierarchy: HierarchySettings) -> Solver {
    solve_to(scene, hierarchy, SolverSettings::default().tolerance)
}

fn solve_to(scene: &Scene, hierarchy: HierarchySettings, tolerance: f64) -> Solver {
    // 1000 starting elements: the hierarchy refines below them where the light asks.
    let mut s = prepared(scene, 1000)
        .solver(SolverSettings {
            tolerance,
            ..settings(hierarchy)
        })
        .unwrap();
    common::converge(&mut s);
    s
}

/// Area-weighted mean radiosity of each patch (patches are the same whatever the
/// hierarchy refined below them).
fn patch_means(mesh: &Mesh, b: &[Vec3]) -> Vec<DVec3> {
    mesh.patches
        .iter()
        .map(|p| {
            let mut s = DVec3::ZERO;
            for i in p.elements.clone() {
                s += b[i as usize].as_dvec3() * mesh.elements[i as usize].area as f64;
            }
            s / p.area as f64
        })
        .collect()
}

/// Area-weighted relative RMS difference of per-patch means, over the patches that are
/// not emitters (whose B is their emission in both).
fn patch_rms(mesh: &Mesh, a: &[DVec3], b: &[DVec3]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for ((p, x), y) in mesh.patches.iter().zip(a).zip(b) {
        if p.emission.max_element() > 0.0 || p.covered {
            continue;
        }
        num += (*x - *y).length_squared() * p.area as f64;
        den += y.length_squared() * p.area as f64;
    }
    (num / den).sqrt()
}

#[test]
fn furnace_at_rho_099_is_exact_with_clustering_on() {
    // B = E / (1 − ρ) = 100 everywhere. The oracle holds each link's estimated error to
    // ε · B̄ · (1 − ρ̄) and the sweeps' stopping is scaled by 1 − ρ̄ too (the error
    // amplification of a closed scene), so after all bounces the error is bounded by about
    // ε · B̄: 1 % at ε = 0.01. The box must do ten times better (0.1 %, the issue's
    // figure): its faces are flat and its links mostly end on whole faces. The 320-facet
    // sphere, whose every facet sees every other at a different angle, is held to the
    // bound. Swept to 1e-4, so what the sweeps leave (about the tolerance, 1e-4 of B, as
    // their stopping is scaled by 1 − ρ̄) is far below either.
    let hierarchy = HierarchySettings {
        link_error: 0.01,
        ..Default::default()
    };
    for (scene, tolerance) in [
        (
            builtin::furnace_box(DVec3::ZERO, DVec3::ONE, 0.99, 1.0),
            1e-3,
        ),
        (
            builtin::furnace_sphere(DVec3::new(3.0, -2.0, 1.0), 0.5, 2, 0.99, 1.0),
            1e-2,
        ),
    ] {
        let s = solve_to(&scene, hierarchy.clone(), 1e-4);
        assert!(s.stats().links.unwrap() > 0);
        let b = s.radiosity();
        let worst = b
            .iter()
            .map(|v| (v.x as f64 - 100.0).abs() / 100.0)
            .fold(0.0, f64::max);
        assert!(worst <= tolerance, "{}: worst {worst}", scene.name);
    }
}

#[test]
fn clustering_on_and_off_agree_within_the_oracle_bound() {
    // Both solves refine until no link's estimated error exceeds ε · B̄ · (1 − ρ̄); they
    // differ by what each approximation leaves, a few ε of the mean. Tolerance: 3 ε.
    let scene = builtin::cornell_box();
    let eps = 0.02;
    let h = |clustering| HierarchySettings {
        link_error: eps,
        clustering,
        ..Default::default()
    };
    let on = solve(&scene, h(true));
    let off = solve(&scene, h(false));
    let a = patch_means(on.mesh(), &on.radiosity());
    let b = patch_means(off.mesh(), &off.radiosity());
    let d = patch_rms(on.mesh(), &a, &b);
    assert!(d <= 3.0 * eps as f64, "clustering on vs off: {d}");
}

#[test]
fn an_edited_solve_matches_a_fresh_solve_of_the_edited_scene() {
    let scene = builtin::cornell_box();
    let red = scene
        .materials
        .iter()
        .position(|m| m.reflectance.x > 2.0 * m.reflectance.y)
        .expect("the Cornell box has a red wall") as u32;
    let new_rho = Vec3::new(0.2, 0.2, 0.6);
    let mut edited_scene = scene.clone();
    edited_scene.materials[red as usize].reflectance = new_rho;

    let mut s = solve(&scene, HierarchySettings::default());
    let rays_before = s.stats().rays;
    let edits: Vec<PatchEdit> = s
        .mesh()
        .patches
        .iter()
        .enumerate()
        .filter(|(_, p)| p.material == red)
        .map(|(i, p)| PatchEdit {
            patch: i as u32,
            reflectance: new_rho,
            emission: p.emission,
        })
        .collect();
    assert!(!edits.is_empty());
    s.edit_patches(&edits);
    common::converge(&mut s);
    // The oracle looks again after the edit and may add links where the wall's blue rose.
    let fresh = solve(&edited_scene, HierarchySettings::default());
    let a = patch_means(s.mesh(), &s.radiosity());
    let b = patch_means(fresh.mesh(), &fresh.radiosity());
    let d = patch_rms(s.mesh(), &a, &b);
    // Both are solves of the same scene to the oracle's bound (ε = 0.05 of the mean,
    // scaled by 1 − ρ̄) by different refinement histories: tolerance 2 ε.
    assert!(d <= 0.1, "edited vs fresh: {d}");
    assert!(s.stats().rays >= rays_before);
}

#[test]
fn dimming_the_light_computes_no_form_factor() {
    // Halving every emission halves every B (the system is linear), so every link's error
    // estimate halves while the oracle's threshold is held at the largest it has been: the
    // edit costs sweeps through the cached links and not a single new form factor or ray,
    // and the result is exactly half of the first.
    let scene = builtin::cornell_box();
    let mut s = solve(&scene, HierarchySettings::default());
    let before = s.radiosity();
    let (rays, links) = (s.stats().rays, s.stats().links);
    let edits: Vec<PatchEdit> = s
        .mesh()
        .patches
        .iter()
        .enumerate()
        .filter(|(_, p)| p.emission.max_element() > 0.0)
        .map(|(i, p)| PatchEdit {
            patch: i as u32,
            reflectance: p.reflectance,
            emission: p.emission * 0.5,
        })
        .collect();
    assert!(!edits.is_empty());
    s.edit_patches(&edits);
    common::converge(&mut s);
    assert_eq!((s.stats().rays, s.stats().links), (rays, links));
    let half: Vec<Vec3> = before.iter().map(|b| *b * 0.5).collect();
    // Both solves stop at a change per sweep of 1e-3 · (1 − ρ̄): they agree to about that.
    let d = common::rms(&s.radiosity(), &half, s.mesh());
    assert!(d <= 2e-3, "{d}");
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let scene = builtin::cornell_box();
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let s = solve(&scene, HierarchySettings::default());
                (s.radiosity(), s.stats().links, s.stats().rays)
            })
    };
    let (b1, l1, r1) = run(1);
    let (b2, l2, r2) = run(2);
    assert_eq!((l1, r1), (l2, r2));
    assert!(b1 == b2, "radiosity differs between 1 and 2 threads");
}
