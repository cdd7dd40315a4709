//! White-furnace scenes: closed enclosures where every surface emits E and reflects ρ.
//! Since Σ_j F_ij = 1 for every receiver in a closed enclosure, B = E + ρB, so B = E/(1 − ρ)
//! exactly, for the continuous problem and for any discretisation whose form factors are
//! exact point-to-polygon values (ours, unoccluded in a convex enclosure).

mod common;
use common::{converge, prepared, settings};
use glam::DVec3;
use radiosity::scene::{Scene, builtin};
use radiosity::solver::Method;

fn solve(
    scene: &Scene,
    method: Method,
    tolerance: f64,
    max_elements: usize,
) -> (Vec<f32>, Vec<f64>, radiosity::solver::Stats) {
    let prepared = prepared(scene, max_elements);
    let mut solver = prepared.solver(settings(method, tolerance)).unwrap();
    converge(&mut solver);
    let b = solver.radiosity().iter().map(|b| b.x).collect();
    let areas = prepared
        .mesh
        .elements
        .iter()
        .map(|e| e.area as f64)
        .collect();
    (b, areas, solver.stats().clone())
}

/// Checks the solution against B = E/(1−ρ) (E = 1 here).
///
/// Area-weighted mean error: from the progressive invariant B = E + ρK(B − ΔB) and the fact
/// that K = F·P preserves area-weighted sums in a closed enclosure (Σ_i A_i F_ip = A_p), the
/// power still missing is exactly ρ/(1−ρ) × the unshot power, so the area-weighted mean
/// error relative to E/(1−ρ) is ρ × (unshot fraction) ≤ ρ·tol. Gathering methods stop on a
/// residual of the same size. On top we allow f32 rounding: form factors carry ~1e-7
/// relative error each and B accumulates ~1/(1−ρ) bounces of them, so 2e-6/(1−ρ).
///
/// Per element: the direct solve is exact up to that rounding, so every element is held to
/// it. Iterative methods may leave their last unshot power concentrated in one corner, so
/// per element we only hold them to 1e-3 relative (a loose sanity bound, 1000× the tolerance).
fn check_furnace(scene: &Scene, rho: f32, method: Method, max_elements: usize) {
    let tol = 1e-6;
    let (b, areas, stats) = solve(scene, method, tol, max_elements);
    let rho = rho as f64;
    let want = 1.0 / (1.0 - rho);
    let rounding = 2e-6 / (1.0 - rho);
    let total: f64 = areas.iter().sum();
    let mean: f64 = b
        .iter()
        .zip(&areas)
        .map(|(v, a)| (*v as f64 - want).abs() * a)
        .sum::<f64>()
        / total
        / want;
    assert!(
        mean <= rho * tol + rounding,
        "{} ρ={rho} {method}: mean relative error {mean:e} > {:e}",
        scene.name,
        rho * tol + rounding
    );
    let per_element = if method == Method::Direct {
        rounding
    } else {
        1e-3
    };
    for (i, v) in b.iter().enumerate() {
        assert!(v.is_finite(), "element {i}: {v}");
        let err = (*v as f64 - want).abs() / want;
        assert!(
            err <= per_element,
            "{} ρ={rho} {method}: element {i} has B={v}, want {want} (relative error {err:e})",
            scene.name
        );
    }
    let balance = stats.energy_balance.unwrap();
    // Closed scene: every bit of light leaving a surface arrives at one; the only loss is the
    // f32 rounding of the form factors, so the balance is 1 to ~1e-5.
    assert!(
        (balance - 1.0).abs() < 1e-4,
        "closed scene must capture all light: {balance}"
    );
}

#[test]
fn cube() {
    for rho in [0.5, 0.9, 0.99] {
        let scene = builtin::furnace_box(DVec3::ZERO, DVec3::ONE, rho, 1.0);
        check_furnace(&scene, rho, Method::Progressive, 600);
    }
}

#[test]
fn cube_gathering_methods() {
    for method in [Method::Jacobi, Method::GaussSeidel, Method::Direct] {
        let scene = builtin::furnace_box(DVec3::ZERO, DVec3::ONE, 0.9, 1.0);
        check_furnace(&scene, 0.9, method, 400);
    }
}

#[test]
fn long_box_100_1_1() {
    for rho in [0.5, 0.9, 0.99] {
        let scene = builtin::furnace_box(DVec3::ZERO, DVec3::new(100.0, 1.0, 1.0), rho, 1.0);
        check_furnace(&scene, rho, Method::Progressive, 2000);
    }
}

#[test]
fn sphere() {
    for rho in [0.5, 0.9, 0.99] {
        let scene = builtin::furnace_sphere(DVec3::ZERO, 1.0, 2, rho, 1.0);
        check_furnace(&scene, rho, Method::Progressive, 1000);
    }
}

#[test]
fn slivers() {
    let scene = builtin::furnace_box_slivers(DVec3::ZERO, DVec3::ONE, 0.9, 1.0, 1e-4);
    check_furnace(&scene, 0.9, Method::Progressive, 600);
}

#[test]
fn kilometre_box_far_from_origin() {
    let origin = DVec3::new(3.0e6, -2.0e6, 5.0e5);
    let scene = builtin::furnace_box(origin, DVec3::splat(1000.0), 0.9, 1.0);
    check_furnace(&scene, 0.9, Method::Progressive, 600);
}

#[test]
fn millimetre_box() {
    let scene = builtin::furnace_box(DVec3::splat(1e-3), DVec3::splat(1e-3), 0.9, 1.0);
    check_furnace(&scene, 0.9, Method::Progressive, 600);
}

/// A cut-out across a furnace: a double-sided plate through the middle of the unit box,
/// from wall to wall, emitting E and reflecting ρ like the walls but letting half the
/// light through (an alpha mask's uncovered half, τ = 0.5). Light passes it with τ and its
/// covered half reflects and emits, so every surface still sees B = E/(1 − ρ) from every
/// direction and the closed form holds at every element: the plate's read as its covered
/// part's radiosity (what `Solver::radiosity` reports: the solved B per unit of its area
/// over its opacity 1 − τ).
///
/// Before the solvers weighed a cut-out's own light by its opacity, the walls saw the
/// plate's whole B and the light through it besides. With its ρ and E weighed but the
/// conservation caps still counting its links whole (so that a leaf below it seemed to
/// see more than a hemisphere), the hierarchical solve came out 56 % low. Tolerances: the progressive solve's per element as in `check_furnace`
/// (1e-3; measured 6·10⁻⁵). The hierarchical solve's links are refined to its oracle's
/// ε = 2 % of error each, and at ρ = 0.9 an error δ in a leaf's sum of form factors moves
/// its B by about 9 δ: measured 0.74 % at worst, every leaf a little low (the conservation
/// caps scale back the leaves whose coarse links add to more than a hemisphere; without
/// them 0.8 % either way), 0.08 % with an opaque plate. The bound is 1 %.
#[test]
fn a_cut_out_plate_across_the_box_keeps_the_closed_form() {
    let rho = 0.9f32;
    let mut scene = builtin::furnace_box(DVec3::ZERO, DVec3::ONE, rho, 1.0);
    let mut plate = scene.materials[0].clone();
    plate.name = "cut-out".into();
    plate.double_sided = true;
    plate.transmittance = 0.5;
    scene.materials.push(plate);
    scene.objects.push(common::quad_object(
        "plate",
        glam::DMat4::IDENTITY,
        [
            [0.0, 0.5, 0.0],
            [0.0, 0.5, 1.0],
            [1.0, 0.5, 1.0],
            [1.0, 0.5, 0.0],
        ],
        1,
    ));
    let want = 1.0 / (1.0 - rho as f64);
    for (method, bound) in [(Method::Progressive, 1e-3), (Method::Hierarchical, 1e-2)] {
        let prepared = prepared(&scene, 600);
        let mut solver = prepared.solver(settings(method, 1e-6)).unwrap();
        converge(&mut solver);
        let mut worst = 0.0f64;
        // `radiosity` reports each element's covered part's.
        for b in solver.radiosity() {
            worst = worst.max((b.x as f64 - want).abs() / want);
        }
        assert!(worst <= bound, "{method}: worst relative error {worst:e}");
    }
}
