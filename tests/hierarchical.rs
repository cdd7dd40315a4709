//! Hierarchical radiosity with clustering against independent truth: the white furnace's
//! closed form with clustering on, the irradiance the links deliver against a brute-force
//! gather of the same solution, clustering on and off against each other within the
//! oracle's bound, an edited solve against a from-scratch solve of the edited scene (and
//! no new form factor for an edit that dims the light), and identical results for one and
//! two threads.

mod common;

use common::prepared;
use glam::{DVec3, Vec3};
use radiosity::mesh::Mesh;
use radiosity::scene::{Material, Scene, builtin};
use radiosity::solver::{
    HierarchySettings, Method, PatchEdit, Solver, SolverSettings, StepOutcome,
};

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
    // B = E / (1 − ρ) = 100 everywhere, to 0.1 % (the figure) for the box and the
    // 320-facet sphere alike. The oracle's bound alone would allow more: it holds each
    // link's estimated error to ε · Ē' (the mean of E'), and after all bounces that is
    // about ε · Ē' / (1 − ρ) = ε · B̄, 1 % at ε = 0.01. But in a closed scene every leaf's
    // links and its share along its rays (`sight`: one hemisphere less what its surface links hand it) sum to
    // exactly one hemisphere, so a uniform B is reproduced whatever the links are; what
    // is left is f32 rounding and the sweeps' stopping. Swept to 1e-4 (their stopping is
    // scaled by 1 − ρ̄, so what they leave is about 1e-4 of B). Measured (2026-12-07):
    // the sphere's worst element 1·10⁻⁵ off, with clustering on and off.
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
            1e-3,
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
fn a_closed_box_at_rho_0999_converges_in_few_sweeps_and_keeps_the_power_balance() {
    // A closed box whose every face reflects ρ = 0.999 (what a glTF material without a
    // base colour gets), lit by one emitting face of B = 1. All the light emitted is
    // absorbed somewhere, Σ A E = (1 − ρ) Σ A H, and B = E + ρ H, so Σ A B = Σ A E / (1 − ρ):
    // a thousand times the emitted power. Plain Jacobi sweeps shrink the error by ρ each,
    // ln(10⁻⁶) / ln(0.999) ≈ 13,800 sweeps to the sweeps' stopping point; the accelerated
    // ones must stop within 100 (they take 11).
    // - Refined to ε: the balance within 1 % (the face-to-face factors miss about 10⁻⁶
    //   of a hemisphere, amplified a thousandfold: 0.04 %).
    // - Cut to 3,000 links by the link budget: the links left coarse hand the leaves
    //   from 0.39 to 1.26 hemispheres (the sampled near transfer, linear transfers
    //   extrapolated into corners), and without the conservation caps the sweeps grew by
    //   0.3 % each, for ever (checked by switching either fix off: without the caps the
    //   sweeps do not converge, without Anderson's step they take thousands). With the
    //   caps every leaf's links sum to at most one hemisphere, so no leaf should exceed
    //   E / (1 − ρ), the radiosity of a surface surrounded by the brightest possible
    //   scene; 1 % is allowed for what the caps do not bound (a linear transfer's
    //   negative part near a corner, a source's linear fit above its brightest leaf) and
    //   the f32 sums at a thousandfold amplification.
    // - The balance holds there too, within 2 %: the light the coarse links leave to the
    //   clusters comes along each leaf's rays (`sight`), whose share, one hemisphere less
    //   what the surface links hand it, makes every leaf's form factors sum to one in a
    //   closed box. Measured (2026-12-05): 1.005. It was 0.017 while the links from
    //   clusters carried their light by the cluster model, and 0.68 while a leaf whose own
    //   16 rays all met surface links took nothing from the clusters: at a thousandfold
    //   amplification, a form-factor sum short by 5·10⁻⁴ on average.
    let rho = 0.999f32;
    let mut scene = builtin::furnace_box(DVec3::ZERO, DVec3::ONE, rho, 0.0);
    scene.materials.push(Material::emitter(
        "lamp",
        Vec3::splat(rho),
        Vec3::splat(1.0 / std::f32::consts::PI),
    ));
    scene.objects[0].triangle_material[0] = 1;
    scene.objects[0].triangle_material[1] = 1;
    let bound = 1.0 / (1.0 - rho as f64);
    for (max_links, refined) in [
        (HierarchySettings::default().max_links, true),
        (3000, false),
    ] {
        let hierarchy = HierarchySettings {
            max_links,
            ..Default::default()
        };
        let mut s = prepared(&scene, 1000)
            .solver(SolverSettings {
                tolerance: 1e-4,
                ..settings(hierarchy)
            })
            .unwrap();
        let cancel = std::sync::atomic::AtomicBool::new(false);
        while s.step(&cancel).unwrap() != StepOutcome::Converged {
            let sweeps = s.stats().iterations;
            assert!(
                sweeps <= 100,
                "{max_links} links: not converged after {sweeps} sweeps"
            );
        }
        assert_eq!(s.stats().link_budget_reached, Some(!refined));
        let mesh = s.mesh();
        let b = s.radiosity();
        let (mut power, mut emitted) = (0.0f64, 0.0f64);
        for (i, e) in mesh.elements.iter().enumerate() {
            power += b[i].x as f64 * e.area as f64;
            emitted += mesh.patches[e.patch as usize].emission.x as f64 * e.area as f64;
        }
        let top = b.iter().map(|v| v.x as f64).fold(0.0, f64::max);
        assert!(top <= bound * 1.01, "{max_links} links: B up to {top}");
        let want = emitted * bound;
        let tolerance = if refined { 0.01 } else { 0.02 };
        assert!(
            (power / want - 1.0).abs() < tolerance,
            "{max_links} links: Σ A B = {power}, the balance says {want}"
        );
    }
}

#[test]
fn the_links_deliver_what_a_brute_force_gather_of_the_solution_finds() {
    // What the links hand each element, H = (B − E')/ρ, against an independent estimate
    // from the same B: cosine-distributed rays from stratified points of the element, each
    // returning the B of the element it hits, whose mean is the element's mean of
    // ∫ B cos θ / π dω = Σ_j F_j V_j B_j, what the links approximate. The small, bright
    // light would make those rays noisy (it holds 3 % of a wall's view and most of its
    // light), so its part is taken by next-event estimation instead: each point adds, for
    // each emitting patch, its mean B times A cos θ cos θ' / (π r²) times the transmittance
    // towards one uniform point of it (unbiased), and rays that hit an emitter add nothing. Summed over each surface (area-weighted), the two must agree
    // to 1 %: the oracle holds each link to ε of the mean E' (what the surfaces emit or
    // first reflect), about ε / 2 of the mean radiosity here (the box's gain is 2), 1 %
    // at ε = 0.02, and the receiver's links err both ways. Taking a source's mean radiosity
    // instead of its linear fit where the receiver sees it best made the ceiling's links
    // 1.4 % short (all of them erred the same way); area-weighted visibility made the
    // blocks' faces 4 % short. The rays' noise is about 0.1 % per surface (256 per element
    // over hundreds of elements).
    use radiosity::geometry::orthonormal_basis;
    use radiosity::geometry::sampling::{
        cosine_direction, hash, point_in_triangle, stratified_point, unit,
    };
    let scene = builtin::cornell_box();
    let p = prepared(&scene, 1000);
    let mut s = p.solver(settings(HierarchySettings::default())).unwrap();
    common::converge(&mut s);
    let (mesh, b) = (s.mesh().clone(), s.radiosity());
    let eps = mesh.epsilon();
    let k = 16u32;
    let emitters: Vec<(usize, Vec3)> = (0..mesh.patches.len())
        .filter(|&p| mesh.patches[p].emission.max_element() > 0.0)
        .map(|p| {
            let patch = &mesh.patches[p];
            let mut sum = Vec3::ZERO;
            for e in patch.elements.clone() {
                sum += b[e as usize] * mesh.elements[e as usize].area;
            }
            (p, sum / patch.area)
        })
        .collect();
    assert!(!emitters.is_empty());
    let mut surfaces: std::collections::BTreeMap<(u32, [i8; 3]), (f64, f64)> = Default::default();
    for (i, e) in mesh.elements.iter().enumerate() {
        let patch = &mesh.patches[e.patch as usize];
        let rho = s.reflectance()[i];
        if patch.emission.max_element() > 0.0 || rho.min_element() <= 0.0 {
            continue;
        }
        let links = (b[i] - s.source()[i]) / rho;
        let basis = orthonormal_basis(e.normal);
        let mut rays = Vec3::ZERO;
        for j in 0..k * k {
            let h = hash((i as u64) << 20 ^ j as u64);
            let x = stratified_point(&e.verts, k, j, h) + e.normal * eps;
            // Direction strata in another order than the points' (7 is prime to k²).
            let d = j * 7 % (k * k);
            let u = ((d % k) as f32 + unit(h)) / k as f32;
            let v = ((d / k) as f32 + unit(hash(h))) / k as f32;
            let d = cosine_direction(e.normal, basis, u, v);
            if let Some(hit) = p.bvh.closest_hit(x, d, 0.0, f32::INFINITY, u32::MAX)
                && let Some(seen) = mesh.element_at(hit.triangle, x + d * hit.t, -d)
                && mesh.patches[mesh.elements[seen as usize].patch as usize]
                    .emission
                    .max_element()
                    <= 0.0
            {
                rays += b[seen as usize];
            }
            for &(q, light) in &emitters {
                let q = &mesh.patches[q];
                if q.normal.dot(x - q.verts[0]) <= 0.0 {
                    continue;
                }
                let y = point_in_triangle(&q.verts, unit(hash(h ^ 1)), unit(hash(h ^ 2)));
                let r = y - x;
                let (r2, w) = (r.length_squared(), r.normalize());
                let (cos, cos_light) = (e.normal.dot(w), -q.normal.dot(w));
                if cos <= 0.0 || cos_light <= 0.0 {
                    continue;
                }
                let t = p.bvh.transmittance(
                    x,
                    y + q.normal * eps,
                    [patch.scene_triangle, q.scene_triangle],
                );
                rays += light * (q.area * cos * cos_light / (std::f32::consts::PI * r2) * t);
            }
        }
        rays /= (k * k) as f32;
        let key = (
            patch.material,
            patch.normal.to_array().map(|c| c.round() as i8),
        );
        let sum = surfaces.entry(key).or_default();
        sum.0 += links.element_sum() as f64 * e.area as f64;
        sum.1 += rays.element_sum() as f64 * e.area as f64;
    }
    assert!(surfaces.len() >= 6, "{surfaces:?}");
    for (surface, (links, rays)) in &surfaces {
        eprintln!(
            "material {} facing {:?}: {:.4}",
            surface.0,
            surface.1,
            links / rays
        );
    }
    for (surface, (links, rays)) in surfaces {
        let ratio = links / rays;
        assert!(
            (ratio - 1.0).abs() <= 0.015,
            "material {} facing {:?}: links deliver {ratio} of the rays' irradiance",
            surface.0,
            surface.1
        );
    }
}

#[test]
fn clustering_on_and_off_agree_within_the_oracle_bound() {
    // Both solves refine until no link's estimated error exceeds ε · Ē'; they
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
    let edits = material_edits(&s, red, new_rho);
    assert!(!edits.is_empty());
    let before = patch_means(s.mesh(), &s.radiosity());
    // The edit shows on the wall at once, before any sweep: B = E' + ρ_new H with the H
    // each leaf gathered in the last sweep.
    assert!(
        s.edit_patches(&edits),
        "the edit is in the solution at once"
    );
    let at_once = patch_means(s.mesh(), &s.radiosity());
    common::converge(&mut s);
    // The oracle looks again after the edit and may add links where the wall's blue rose.
    let fresh = solve(&edited_scene, HierarchySettings::default());
    let a = patch_means(s.mesh(), &s.radiosity());
    let b = patch_means(fresh.mesh(), &fresh.radiosity());
    let d = patch_rms(s.mesh(), &a, &b);
    // Both are solves of the same scene to the oracle's bound (ε = 0.05 of the mean E',
    // about ε of the mean radiosity after the bounces) by different refinement
    // histories: tolerance 2 ε.
    assert!(d <= 0.1, "edited vs fresh: {d}");
    assert!(s.stats().rays >= rays_before);
    // On the edited wall, the immediate update leaves only the change in the light that
    // comes back to the wall from the rest of the box: the wall's light reflected by
    // walls of ρ ≈ 0.5–0.75 and returning with a form factor well under one half, so less
    // than a third of the whole change. Measured: 0.10 at once against 1.81 before, which
    // includes the two solves' own difference (2 ε at most).
    let wall = |m: &[DVec3]| {
        let (mut num, mut den) = (0.0, 0.0);
        for (i, p) in s.mesh().patches.iter().enumerate() {
            if p.material == red {
                num += (m[i] - b[i]).length_squared() * p.area as f64;
                den += b[i].length_squared() * p.area as f64;
            }
        }
        (num / den).sqrt()
    };
    let (stale, updated) = (wall(&before), wall(&at_once));
    assert!(
        updated <= stale / 3.0,
        "the wall at once {updated} vs before the edit {stale}"
    );
}

/// The edits that give every patch of `material` the reflectance `rho`, keeping its
/// emission.
fn material_edits(s: &Solver, material: u32, rho: Vec3) -> Vec<PatchEdit> {
    s.mesh()
        .patches
        .iter()
        .enumerate()
        .filter(|(_, p)| p.material == material)
        .map(|(i, p)| PatchEdit {
            patch: i as u32,
            reflectance: rho,
            emission: p.emission,
        })
        .collect()
}

/// The largest relative difference, over elements and channels, between two irradiances.
fn worst_relative(a: &[Vec3], b: &[Vec3]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(a, b)| (*a - *b).abs().max_element() / a.abs().max(*b).max_element().max(1e-30))
        .fold(0.0, f32::max)
}

#[test]
fn an_edit_changes_reflectance_and_not_the_irradiance_at_once() {
    // B = E + ρ H: an edit of ρ (or E) changes B at once and leaves each element's
    // irradiance H, the light arriving, as it was until the sweeps carry the change on.
    // That holds whatever the solve's state (mid-solve, where the sweeps' last H and the
    // H of the accelerated B differ most, and converged), for every material, the lamp's
    // too (an emitter's H is small beside its E). The viewer relies on it: an edit's
    // first snapshot keeps the vertex data fitted to H (`worker::same_light`, 10⁻⁶).
    // Tolerance 10⁻⁶: H in f64 rounded to f32 is good to 6·10⁻⁸. It fails with the edit
    // taking H from the last sweep rather than from B (Anderson's step): 5·10⁻⁵ here
    // mid-solve (on converged Sponza, 16,707 elements of one material, up to 100 %), and
    // with H taken from B rounded to f32: 1.6·10⁻⁵ on the lamp.
    let scene = builtin::cornell_box();
    let mut s = prepared(&scene, 1000)
        .solver(settings(HierarchySettings::default()))
        .unwrap();
    let cancel = std::sync::atomic::AtomicBool::new(false);
    while s.stats().iterations < 4 {
        assert_eq!(
            s.step(&cancel).unwrap(),
            StepOutcome::Working,
            "converged too soon"
        );
    }
    for (when, materials) in [
        ("mid-solve", vec![0]),
        ("converged", (0..scene.materials.len() as u32).collect()),
    ] {
        if when == "converged" {
            common::converge(&mut s);
        }
        for m in materials {
            let before = s.display_irradiance(false);
            let rho = scene.materials[m as usize].reflectance * 0.7;
            s.edit_patches(&material_edits(&s, m, rho));
            let worst = worst_relative(&before, &s.display_irradiance(false));
            assert!(worst <= 1e-6, "{when}, material {m}: H moved by {worst:e}");
        }
    }
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

/// The bottom edge of the Cornell box's short block's front face, from its left corner to
/// its right, and the face's outward normal (towards −z, the open front: all the face's
/// light is interreflected).
fn short_block_front() -> (DVec3, DVec3, DVec3) {
    let (a, b) = (DVec3::new(0.130, 0.0, 0.065), DVec3::new(0.290, 0.0, 0.114));
    let out = DVec3::Y.cross(b - a).normalize();
    assert!(out.z < 0.0);
    (a, b, out)
}

/// The RMS relative error (of the RGB vector) of the viewer's Gouraud reconstruction of
/// the Cornell box, solved with the command line's defaults, at `points` (position,
/// normal), against the built-in path tracer at `reference_error`.
fn cornell_gouraud_error(points: &[(DVec3, DVec3)], reference_error: f64) -> f64 {
    use radiosity::mesh::{MeshSettings, Reconstruction};
    use radiosity::pipeline::{Prepared, probe_values};
    let scene = builtin::cornell_box();
    let prepared = Prepared::new(&scene, &MeshSettings::default());
    let mut solver = prepared
        .solver(settings(HierarchySettings::default()))
        .unwrap();
    common::converge(&mut solver);
    let truth = common::path_traced(&scene, points, reference_error);
    let got = probe_values(
        solver.mesh(),
        &solver.radiosity(),
        points,
        Reconstruction::Gouraud,
    );
    let mut squares = 0.0;
    for ((g, t), (p, n)) in got.iter().zip(&truth).zip(points) {
        let err = (g.as_dvec3() - t.value).length() / t.value.length();
        eprintln!(
            "{p} ({n}): {g} against {} ± {}: {err:.4}",
            t.value, t.std_error
        );
        squares += err * err;
    }
    (squares / got.len() as f64).sqrt()
}

#[test]
fn the_foot_of_a_block_matches_the_path_traced_reference() {
    // Points at the foot of the short block's front face (its light goes from 0.031 at
    // 0.1 mm above the floor to 0.056 at 4 mm) and on the floor just in front of it, 0.3
    // to 2 mm from the contact, at three places along it.
    let (a, b, out) = short_block_front();
    let mut points = Vec::new();
    for t in [0.25, 0.6, 0.9] {
        let foot = a + (b - a) * t;
        for d in [3e-4, 1e-3, 2e-3] {
            points.push((foot + DVec3::Y * d + out * 1e-6, out));
            points.push((foot + out * d + DVec3::Y * 1e-6, DVec3::Y));
        }
    }
    let rms = cornell_gouraud_error(&points, 0.01);
    eprintln!("the foot of the short block: Gouraud against the reference, RMS {rms:.3}");
    // Measured: 12.8 % RMS, the worst point 29 %, with leaves held at the minimum size
    // there (an element beside the contact averages light that doubles within it, and the
    // vertex fit extrapolates that average); 5.8 %, the worst 12 %, with leaves in contact
    // graded to a quarter of it; 1.6 % with receivers darker than the mean held to their
    // own light (this face is at 4–13 % of the mean) and ε = 0.03. This 1 % reference
    // adds about 1 % in quadrature. Bound 4 %.
    assert!(rms < 0.04, "RMS {rms}");
}

#[test]
fn a_dark_face_matches_the_path_traced_reference() {
    // Twelve points over the short block's front face, 2 to 14.5 cm above the floor, at
    // 4–13 % of the scene's mean radiosity.
    let (a, b, out) = short_block_front();
    let mut points = Vec::new();
    for t in [0.2, 0.5, 0.8] {
        for y in [0.02, 0.06, 0.10, 0.145] {
            points.push((a + (b - a) * t + DVec3::Y * y + out * 1e-6, out));
        }
    }
    let rms = cornell_gouraud_error(&points, 0.005);
    eprintln!("the short block's front face: Gouraud against the reference, RMS {rms:.4}");
    // Measured: 2.2 % RMS, nearly all too bright, with the oracle's absolute threshold
    // ε · B̄ · (1 − ρ̄) (0.0051 here, 7–17 % of this face's light); 0.63 % with receivers
    // darker than the mean held to ε · B_r · (1 − ρ̄), and 0.49 % with that at the
    // default ε = 0.03. This 0.5 % reference adds about 0.5 % in quadrature. Bound 1.2 %.
    assert!(rms < 0.012, "RMS {rms}");
}

/// A hollow box (walls 2 cm thick: outer faces facing out, inner faces facing in) on a
/// floor lit from straight above. No light gets inside: the inner faces' exact radiosity
/// is 0, against ρ E = 0.5 on the floor.
/// - Refined to ε (the default link budget): the links reach the surfaces, whose shadow
///   rays the walls stop; the inside must be black to 10⁻⁴ of the floor.
/// - Cut to 1,000 links by the link budget, links stay at clusters that hold outer and
///   inner faces alike. A cluster's light went to every leaf below it that faced its way,
///   and the inside took 6.4 % of the floor's radiosity on average. Each leaf now takes
///   the clusters' light along its own rays (`sight`), which inside hit only the inner
///   walls: 4.4 %. What is left enters through the surface links the budget leaves
///   coarse, and the rays pass on only what the inner walls took from them. The bound,
///   5 %, is between the two.
#[test]
fn the_inside_of_a_closed_box_stays_dark() {
    use common::{floor, quad};
    use radiosity::scene::{Light, Object};
    let (h, t, w) = (0.3f32, 0.6f32, 0.02f32);
    let mut hollow = Object {
        name: "hollow box".into(),
        ..Default::default()
    };
    // Six faces of the box [−a, a] × [y0, y1] × [−a, a], counter-clockwise seen from
    // outside; `inward` reverses each winding, so the faces look into the box.
    let faces = |a: f32, y0: f32, y1: f32| {
        [
            [[-a, y1, -a], [-a, y1, a], [a, y1, a], [a, y1, -a]],
            [[-a, y0, -a], [a, y0, -a], [a, y0, a], [-a, y0, a]],
            [[a, y0, -a], [a, y1, -a], [a, y1, a], [a, y0, a]],
            [[-a, y0, -a], [-a, y0, a], [-a, y1, a], [-a, y1, -a]],
            [[-a, y0, a], [a, y0, a], [a, y1, a], [-a, y1, a]],
            [[-a, y0, -a], [-a, y1, -a], [a, y1, -a], [a, y0, -a]],
        ]
    };
    for f in faces(h, 0.0, t) {
        quad(&mut hollow, f, 0);
    }
    let inner_first = hollow.triangles.len();
    for mut f in faces(h - w, w, t - w) {
        f.reverse();
        quad(&mut hollow, f, 0);
    }
    let scene = Scene {
        name: "hollow box".into(),
        objects: vec![floor(glam::DMat4::IDENTITY), hollow],
        materials: vec![Material::diffuse("white", Vec3::splat(0.5))],
        lights: vec![Light::Directional {
            direction: DVec3::new(0.0, -1.0, 0.0),
            irradiance: Vec3::ONE,
        }],
        environment: None,
        images: Vec::new(),
        warnings: Vec::new(),
    };
    for max_links in [1000, HierarchySettings::default().max_links] {
        let s = solve(
            &scene,
            HierarchySettings {
                max_links,
                ..Default::default()
            },
        );
        let mesh = s.mesh();
        let b = s.radiosity();
        let (mut inside, mut area, mut top) = (0.0f64, 0.0f64, 0.0f64);
        for (i, e) in mesh.elements.iter().enumerate() {
            let patch = &mesh.patches[e.patch as usize];
            let object = patch.object as usize;
            if object == 1 && patch.triangle as usize >= inner_first {
                inside += b[i].x as f64 * e.area as f64;
                area += e.area as f64;
                top = top.max(b[i].x as f64);
            }
        }
        let mean = inside / area / 0.5;
        let bound = if max_links == 1000 { 0.05 } else { 1e-4 };
        assert!(
            mean <= bound,
            "{max_links} links: the inside has {mean} of the floor's B on average (up to {top})"
        );
    }
}

#[test]
fn every_element_of_a_converged_solve_satisfies_its_own_equation() {
    // The sweeps stop when their area-weighted change falls below the tolerance, in which
    // small elements count for little. What must hold at every element is its own
    // equation, B = E' + ρ H(B): the converged solve's last sweep must leave each within
    // 1 % of its own light (`Stats::worst_element_residual`; 1 % is ten times the
    // tolerance, 10⁻³ of the scene's light). The scene: cornell-box-nvpro as `solve` runs
    // it, whose white sphere (ρ = 0.999) meets its floor in an 18° wedge of elements down
    // to 3·10⁻⁹ m². While Anderson's γ was fitted to residuals weighted by area, the
    // sphere's foot swung between 0 and 2.3 W/m², about ten sweeps a period, until the
    // solve stopped (at 0, where the path tracer finds 0.118 in green): the worst element
    // was 3–50 % off its equation at each sweep, 3–5 % at the last (two runs). Measured with the
    // relative norm (2026-12-06): 7·10⁻⁵.
    let Some(scenes) = common::shared_scenes() else {
        return;
    };
    let path = scenes.join("cornell-box-nvpro/cornellBox.gltf");
    let scene = radiosity::scene::open(path.to_str().unwrap(), None, None).unwrap();
    let options = radiosity::cli::SolveOptions::default();
    let prepared = radiosity::pipeline::Prepared::new(&scene, &options.mesh_settings());
    let mut s = prepared.solver(options.solver_settings()).unwrap();
    common::converge(&mut s);
    let worst = s.stats().worst_element_residual.unwrap();
    assert!(
        worst < 1e-2,
        "an element is {worst} of its light off its equation"
    );
}
