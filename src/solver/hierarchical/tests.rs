//! The hierarchy's machinery against independent truth: with the links fixed at the leaves
//! the sweeps must reach the solution of the same linear system solved densely, and
//! push–pull must hand the leaves exactly the power the nodes gathered.

use super::*;
use crate::accel::Bvh;
use crate::light::ExternalLight;
use crate::mesh::MeshSettings;
use crate::scene::builtin;
use crate::solver::{HierarchySettings, Method, SolverSettings};
use std::sync::Arc;

fn solver(mesh: MeshSettings, hierarchy: HierarchySettings, tolerance: f64) -> Solver {
    let scene = builtin::cornell_box();
    let mesh = Mesh::build(&scene, &mesh);
    let bvh = Bvh::build(&mesh.triangles, &mesh.transmittance);
    let external = ExternalLight {
        lights: scene.lights.clone(),
        environment: scene.environment.clone(),
    };
    Solver::new(
        Arc::new(mesh),
        Arc::new(bvh),
        external,
        SolverSettings {
            method: Method::Hierarchical,
            tolerance,
            hierarchy,
            ..Default::default()
        },
    )
    .unwrap()
}

/// Σ A B over the elements (all channels), W.
fn power(s: &Solver) -> f64 {
    s.radiosity
        .iter()
        .zip(&s.mesh.elements)
        .map(|(b, e)| sum3d(*b) * e.area as f64)
        .sum()
}

/// Dense Gaussian elimination with partial pivoting (the test's own, independent of the
/// solver's LU).
fn solve_dense(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let n = b.len();
    for k in 0..n {
        let p = (k..n)
            .max_by(|&i, &j| a[i][k].abs().total_cmp(&a[j][k].abs()))
            .unwrap();
        a.swap(k, p);
        b.swap(k, p);
        let pivot = a[k].clone();
        for i in k + 1..n {
            let m = a[i][k] / pivot[k];
            for (x, p) in a[i][k..].iter_mut().zip(&pivot[k..]) {
                *x -= m * p;
            }
            b[i] -= m * b[k];
        }
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let s: f64 = (i + 1..n).map(|j| a[i][j] * x[j]).sum();
        x[i] = (b[i] - s) / a[i][i];
    }
    x
}

#[test]
fn with_links_fixed_at_the_leaves_the_sweeps_reach_the_dense_solution() {
    // One element per patch, every pair of patches linked, no refinement: the hierarchy is
    // then the flat system B = E' + ρ F B with F_ij the links' factors (the linear transfer
    // at the receiver's centroid, which is the mean of its quadrature values). The
    // tolerance of 1e-12 is below what f32 sweeps can reach: they must stop at their
    // rounding floor rather than cycle there (this test hung before `SWEEP_FLOOR`).
    let mut s = solver(
        MeshSettings {
            element_size: Some(10.0),
            ..Default::default()
        },
        HierarchySettings {
            link_error: f32::INFINITY,
            clustering: false,
            ..Default::default()
        },
        1e-12,
    );
    s.run(None, crate::cancel::never()).unwrap();
    let h = s.hierarchy.as_ref().unwrap();
    let n = s.mesh.elements.len();
    assert_eq!(n, s.mesh.patches.len(), "one element per patch");
    let element_of = |id: NodeId| s.mesh.nodes[id.0 as usize].element.unwrap() as usize;
    for channel in 0..3 {
        let mut a = vec![vec![0.0f64; n]; n];
        for (i, row) in a.iter_mut().enumerate() {
            row[i] = 1.0;
        }
        for (r, l) in h.links.iter() {
            let (i, j) = (element_of(r), element_of(l.source));
            a[i][j] -= s.reflectance[i][channel] as f64 * l.transfer.factor() as f64;
        }
        let b: Vec<f64> = s.source.iter().map(|e| e[channel] as f64).collect();
        let exact = solve_dense(a, b);
        let scale = exact.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for (i, x) in exact.iter().enumerate() {
            // Jacobi to a change of 1e-12 per sweep, f32 factors and node values: the
            // solutions agree to f32 resolution of the largest value.
            let got = s.radiosity[i][channel];
            assert!(
                (got - x).abs() <= 1e-5 * scale,
                "element {i} channel {channel}: {got} vs {x}"
            );
        }
    }
}

#[test]
fn push_pull_hands_the_leaves_the_power_the_nodes_gathered() {
    // Clustering off: what a cluster receives is shared out by orientation, which is not
    // meant to conserve power exactly; the quadtrees' push–pull is.
    let mut s = solver(
        MeshSettings::default(),
        HierarchySettings {
            clustering: false,
            ..Default::default()
        },
        1e-3,
    );
    s.run(None, crate::cancel::never()).unwrap();
    let mut h = s.hierarchy.take().unwrap();
    h.pull(&s.mesh, &s.radiosity);
    h.gather(&s.mesh);
    let mesh = &s.mesh;
    let down = h.cluster_down(&s.radiosity, &s.opacity);
    // Gathered: every surface node's mean H (its linear function's mean over it) times
    // its area.
    let mut gathered = 0.0f64;
    for (n, corners) in h.node_h.iter().enumerate() {
        let mean = (corners[0] + corners[1] + corners[2]) / 3.0;
        gathered += (mean.x + mean.y + mean.z) as f64 * h.node_area[n] as f64;
    }
    assert!(h.links.iter().all(|(r, _)| r.cluster().is_none()));
    let pushed: f64 = (0..mesh.elements.len())
        .map(|e| {
            let v = h.leaf_irradiance_linear(mesh, e, &down);
            (v.x + v.y + v.z) as f64 * mesh.elements[e].area as f64
        })
        .sum();
    assert!(
        gathered > 0.0 && h.links.len() > 100,
        "{} links",
        h.links.len()
    );
    // f32 node values and areas summed over ~10⁴ terms: 1e-4 relative.
    assert!(
        (pushed - gathered).abs() <= 1e-4 * gathered,
        "pushed {pushed} vs gathered {gathered}"
    );
}

/// Streaming: before the first refinement round ends, previews over the links it holds
/// so far light the whole scene, approaching the converged solution from below.
#[test]
fn previews_light_the_whole_scene_before_the_first_round_ends() {
    let mut s = solver(MeshSettings::default(), HierarchySettings::default(), 1e-3);
    s.settings.step_budget = std::time::Duration::ZERO;
    // Area of the elements without light.
    let dark = |s: &Solver| {
        s.radiosity
            .iter()
            .zip(&s.mesh.elements)
            .filter(|(b, _)| b.max_element() <= 0.0)
            .map(|(_, e)| e.area as f64)
            .sum::<f64>()
    };
    let mut previews = Vec::new();
    let mut last_dark = f64::INFINITY;
    while !s.is_converged() {
        s.step(crate::cancel::never()).unwrap();
        if let Some(h) = &s.hierarchy
            && h.sweeps == 0
            && s.stats.first_solution_seconds.is_some()
        {
            previews.push(power(&s));
            last_dark = dark(&s);
        }
    }
    let converged = power(&s);
    assert!(previews.len() > 10, "{} previews", previews.len());
    // Every surface the converged solution lights is lit: the area left dark is the floor
    // under the blocks, dark in both (up to 1 % of it: the meshes differ by later splits).
    let converged_dark = dark(&s);
    assert!(
        last_dark <= converged_dark * 1.01,
        "dark area {last_dark} m² against {converged_dark} m² converged"
    );
    // Links whose ends overlap carry nothing (the oracle splits them all; their
    // centre-to-centre kernel is meaningless), so the coarser links of a preview carry
    // less than the finer ones, not more: no preview may hold more light than the
    // converged solution, up to the oracle's ε = 2 % on what the coarser links carry.
    // With the overlapping links carrying their centre-to-centre kernel, the seventh
    // preview held 2 % more light than the converged solution (and single points of the
    // bench 150 times their true value).
    for (k, p) in previews.iter().enumerate() {
        assert!(
            *p <= converged * 1.02,
            "preview {k}: {p} against {converged}"
        );
    }
    // Each preview converges the light over its links, so the last, whose links are
    // nearly the first round's, holds nearly all of it: within the same 2 %, and 1 % for
    // the links the later rounds add. Measured: 0.53 of the converged power (the lamp
    // alone) rising to 0.989; with one sweep per preview, one bounce more each, the last
    // held 0.95.
    let last = previews.last().unwrap();
    assert!(
        *last >= converged * 0.97,
        "last preview {last} against {converged}"
    );
}

/// Streaming after the first solution: a refinement round previews its links as they
/// refine (`LATER_PREVIEW_GROWTH`), so before its own sweeps the picture comes closer to
/// the converged solution than the last round's. Measured by the light on each patch
/// (patches are never split, so the sums compare across the leaves' splits). Measured on
/// the Cornell box, off the converged light at each round's start and at its last
/// preview: 0.37 → 0.22 %, 0.19 → 0.10 %, 0.12 → 0.056 %, 0.064 → 0.030 %, then two
/// rounds at ε that barely change. Without previews after the first solution, the light
/// changes only by the leaves' splits, which keep it.
#[test]
fn later_rounds_preview_their_links_as_they_refine() {
    let mut s = solver(MeshSettings::default(), HierarchySettings::default(), 1e-3);
    s.settings.step_budget = std::time::Duration::ZERO;
    let per_patch = |s: &Solver| {
        let mut light = vec![0.0f64; s.mesh.patches.len()];
        for (b, e) in s.radiosity.iter().zip(&s.mesh.elements) {
            light[e.patch as usize] += sum3d(*b) * e.area as f64;
        }
        light
    };
    // Per round after the first solution: the light at its start, and at its last preview.
    let mut rounds: Vec<(Vec<f64>, Option<Vec<f64>>)> = Vec::new();
    let mut last = per_patch(&s);
    let mut in_round = false;
    while !s.is_converged() {
        s.step(crate::cancel::never()).unwrap();
        let now = per_patch(&s);
        let refining = s
            .hierarchy
            .as_ref()
            .is_some_and(|h| h.sweeps > 0 && h.round.is_some());
        if refining && !in_round {
            rounds.push((last.clone(), None));
        }
        if refining && now != last {
            rounds.last_mut().unwrap().1 = Some(now.clone());
        }
        in_round = refining;
        last = now;
    }
    let converged = per_patch(&s);
    let total: f64 = converged.iter().sum();
    let distance = |light: &[f64]| {
        light
            .iter()
            .zip(&converged)
            .map(|(a, b)| (a - b).abs())
            .sum::<f64>()
            / total
    };
    let previewed: Vec<(f64, f64)> = rounds
        .iter()
        .filter_map(|(start, preview)| Some((distance(start), distance(preview.as_ref()?))))
        .collect();
    println!("later rounds (start, last preview) off the converged light: {previewed:?}");
    // No round's preview is further off than its start (0.1 % for f32 sums of rounds that
    // barely change), and the rounds that refine much come much closer.
    for &(start, preview) in &previewed {
        assert!(
            preview <= start * 1.001,
            "a preview {preview} off the converged light, its round's start {start}"
        );
    }
    let closer = previewed.iter().filter(|(s, p)| *p <= 0.75 * s).count();
    assert!(
        closer >= 2,
        "{closer} rounds' previews came closer by a quarter"
    );
}

/// The link budget: a solve whose oracle would make sixty times more links stops
/// refining near the budget and still converges, says so in its stats, and its light is
/// the full solve's within what its coarser links may miss. The links with a cluster at
/// either end leave their light to each leaf's 16 rays (`sight`), an estimate without
/// bias whose seeds move the budgeted power: measured (2026-12-05) with five seeds of
/// the rays, 0.6 % under the full solve's to 0.2 % over (78 k links against 5.13 M; the
/// mean 0.35 % under, the spread 0.35 %). The bound, 1.2 %, is the mean's offset and
/// two and a half spreads. While the links from clusters carried their light by the
/// cluster model, the power here was 1.4 % under, and 5.7 % at a budget of 20 k.
#[test]
fn the_link_budget_stops_refinement_and_the_solve_still_converges() {
    let budget = 80_000;
    let mut budgeted = solver(
        MeshSettings::default(),
        HierarchySettings {
            max_links: budget,
            ..Default::default()
        },
        1e-3,
    );
    budgeted.run(None, crate::cancel::never()).unwrap();
    assert_eq!(budgeted.stats.link_budget_reached, Some(true));
    let links = budgeted.stats.links.unwrap();
    // The generation under way when the budget passes is the last: each of its links
    // splits into at most four (a cluster and itself) times four.
    assert!(
        links <= 16 * budget,
        "{links} links for a budget of {budget}"
    );
    // Past the budget no round runs again, so the table drops what only rounds read: 16
    // bytes a link (`table::StoredLink`) and 8 per receiver (its id and where its run
    // starts), and the run's end.
    let h = budgeted.hierarchy.as_ref().unwrap();
    let receivers = h.links.groups().count();
    assert_eq!(h.links.bytes(), 16 * links + 8 * receivers + 4);
    assert_eq!(budgeted.stats.link_bytes, Some(h.links.bytes()));
    let mut full = solver(MeshSettings::default(), HierarchySettings::default(), 1e-3);
    full.run(None, crate::cancel::never()).unwrap();
    assert_eq!(full.stats.link_budget_reached, Some(false));
    let (b, f) = (power(&budgeted), power(&full));
    let share = |s: &Solver| s.stats.cluster_light_share.expect("the share of the light");
    eprintln!(
        "budgeted: {links} links, power {b}, {} of the light from clusters; full: {} links, power {f}, {}",
        share(&budgeted),
        full.stats.links.unwrap(),
        share(&full)
    );
    // Refined to the surfaces, the box's links from clusters carry a thousandth of its
    // light (measured 0.10 %); stopped at the budget, the links left at the clusters'
    // levels carry twenty times more (measured 2.1 %), which the stats must say. The
    // bounds: five times the one, half the other.
    assert!(share(&full) < 0.005, "full: {}", share(&full));
    assert!(share(&budgeted) > 0.01, "budgeted: {}", share(&budgeted));
    assert!(
        (b - f).abs() <= 0.012 * f,
        "budgeted power {b} against {f} ({links} links against {})",
        full.stats.links.unwrap()
    );
}

/// After an edit, only the clusters above the edited patches are recomputed: every
/// cluster's largest reflectance must still be the largest over all the patches below it,
/// found by brute force (each patch's ancestors walked from its leaf cluster), both where
/// the edit raised a reflectance and where it lowered one.
#[test]
fn an_edit_leaves_every_cluster_with_the_largest_reflectance_below_it() {
    let mut s = solver(MeshSettings::default(), HierarchySettings::default(), 1e-2);
    s.run(None, crate::cancel::never()).unwrap();
    let patches = s.mesh.patches.clone();
    let edits: Vec<crate::solver::PatchEdit> = patches
        .iter()
        .enumerate()
        .filter(|(i, _)| i % 3 == 0)
        .map(|(i, p)| crate::solver::PatchEdit {
            patch: i as u32,
            // Raise some, lower others (the lowered ones test that a maximum can fall).
            reflectance: if i % 2 == 0 {
                Vec3::splat(0.95)
            } else {
                Vec3::splat(0.01)
            },
            emission: p.emission,
        })
        .collect();
    assert!(s.edit_patches(&edits));
    let h = s.hierarchy.as_ref().unwrap();
    let mut expected = vec![0.0f32; h.clusters.nodes.len()];
    for (p, patch) in patches.iter().enumerate() {
        let rho = s.reflectance[patch.elements.start as usize].max_element();
        let mut c = h.clusters.patch_parent[p];
        while c != NONE {
            expected[c as usize] = expected[c as usize].max(rho);
            c = h.clusters.nodes[c as usize].parent;
        }
    }
    let got: Vec<f32> = h.clusters.nodes.iter().map(|c| c.reflectance).collect();
    assert_eq!(got, expected);
    assert!(expected.contains(&0.95));
}

/// A wall's two faces in one cluster: the lit outer face (normal +z, B = 1) and the dark
/// inner one (−z, B = 0). Towards +z the cluster sends what the outer face sends, towards
/// −z nothing: its mean, 0.5, had sent the outside's light into the room (Sponza's
/// shell). Sideways, where nothing faces, it sends the mean. With one B on every face,
/// every direction gets that B, so a furnace stays exact: the sender record's areas are
/// rounded to 1/65535 of the largest, which only weighs faces of one B against each other.
#[test]
fn a_cluster_sends_what_its_surfaces_facing_the_receiver_send() {
    let mut wall = Facing::default();
    wall.add_surface(Vec3::Z, 2.0, Vec3::ONE);
    wall.add_surface(-Vec3::Z, 2.0, Vec3::ZERO);
    let wall = Sender::new(&wall, Vec3::ZERO);
    assert_eq!(wall.toward(Vec3::Z), Vec3::ONE);
    assert_eq!(wall.toward(-Vec3::Z), Vec3::ZERO);
    assert_eq!(
        wall.toward(Vec3::X),
        Vec3::splat(0.5),
        "nothing faces sideways"
    );
    let slanted = wall.toward(Vec3::new(1.0, 0.0, 1.0).normalize());
    assert!((slanted - Vec3::ONE).abs().max_element() < 1e-6);
    let mut uniform = Facing::default();
    for n in [
        Vec3::X,
        -Vec3::Y,
        Vec3::new(0.6, 0.8, 0.0),
        Vec3::new(-0.36, 0.48, 0.8),
    ] {
        let mut child = Facing::default();
        child.add_surface(n, 0.7, Vec3::splat(0.3));
        uniform.merge(&child);
    }
    let uniform = Sender::new(&uniform, Vec3::ZERO);
    for k in 0..200u64 {
        use crate::geometry::sampling::{hash, unit};
        let z = 1.0 - 2.0 * unit(hash(k));
        let phi = std::f32::consts::TAU * unit(hash(k ^ 9));
        let r = (1.0 - z * z).max(0.0).sqrt();
        let w = Vec3::new(r * phi.cos(), r * phi.sin(), z);
        let b = uniform.toward(w);
        assert!((b - Vec3::splat(0.3)).abs().max_element() < 1e-6, "{w} {b}");
    }
}

/// The record the gather reads of a cluster is two cache lines, whatever its index.
#[test]
fn a_sender_is_two_cache_lines() {
    assert_eq!(std::mem::size_of::<Sender>(), 96);
    assert_eq!(std::mem::align_of::<Sender>(), 32);
}

/// After an edit of one patch of a converged solve, the sweep through the links out of the
/// edited elements hands every leaf the H a full sweep (pull, gather over every link, push)
/// from the same iterate hands it. They differ only in how the f32 sums are grouped: a
/// receiver's H is its old sum plus the change instead of one sum, each of its n terms
/// rounding by 2⁻²⁴ of the running sum, so the tolerance is n · 2⁻²⁴ of the largest H with
/// n the most links into one receiver, doubled for the push through the ancestors.
///
/// Both with the box refined to its oracle (links between surfaces) and cut short by a
/// link budget, where cluster links to clusters and surfaces carry much of the light.
#[test]
fn an_incremental_sweep_after_an_edit_equals_the_full_sweep() {
    incremental_against_full(HierarchySettings::default());
    incremental_against_full(HierarchySettings {
        max_links: 20_000,
        ..Default::default()
    });
}

fn incremental_against_full(settings: HierarchySettings) {
    let budgeted = settings.max_links < 1_000_000;
    let mut s = solver(MeshSettings::default(), settings, 1e-3);
    s.run(None, crate::cancel::never()).unwrap();
    // The largest patch facing up above the floor (a block's top), lit and seen by much
    // of the box.
    let up = |p: &crate::mesh::Patch| p.normal.y > 0.9 && p.emission == Vec3::ZERO;
    let height = |p: &crate::mesh::Patch| s.mesh.elements[p.elements.start as usize].centroid().y;
    let floor = s
        .mesh
        .patches
        .iter()
        .filter(|p| up(p))
        .map(height)
        .fold(f32::INFINITY, f32::min);
    let (patch, _) = s
        .mesh
        .patches
        .iter()
        .enumerate()
        .filter(|(_, p)| up(p) && height(p) > floor + 0.05)
        .max_by(|a, b| a.1.area.total_cmp(&b.1.area))
        .expect("a block's top");
    let edit = crate::solver::PatchEdit {
        patch: patch as u32,
        reflectance: Vec3::new(0.9, 0.1, 0.1),
        emission: Vec3::ZERO,
    };
    assert!(s.edit_patches(&[edit]));
    let mut h = s.hierarchy.take().unwrap();
    s.rebase_on_sweep_basis(&mut h);
    let x = s.radiosity.clone();
    let mesh = Arc::clone(&s.mesh);
    let before = s.gathered.clone();
    let mut incremental = before.clone();
    assert!(
        h.sweep_incrementally(&mesh, (&x, &s.opacity), &mut incremental)
            .is_some(),
        "an edit of one patch sweeps incrementally"
    );
    h.pull(&mesh, &x);
    h.gather(&mesh);
    let down = h.cluster_down(&x, &s.opacity);
    let full: Vec<DVec3> = (0..mesh.elements.len())
        .map(|e| {
            h.capped(e, h.leaf_irradiance_linear(&mesh, e, &down))
                .as_dvec3()
        })
        .collect();
    let from = h
        .links
        .iter()
        .filter(|(_, l)| l.source.cluster().is_some())
        .count();
    let to = h
        .links
        .iter()
        .filter(|(r, _)| r.cluster().is_some())
        .count();
    let most_links = h.links.groups().map(|(_, g)| g.len()).max().unwrap();
    let largest = full.iter().map(|h| h.max_element()).fold(0.0, f64::max);
    let tolerance = 2.0 * most_links as f64 * 2f64.powi(-24) * largest;
    let worst = full
        .iter()
        .zip(&incremental)
        .map(|(f, i)| (*f - *i).abs().max_element())
        .fold(0.0, f64::max);
    let moved = full
        .iter()
        .zip(&before)
        .filter(|(f, b)| (**f - **b).abs().max_element() > 10.0 * tolerance)
        .count();
    eprintln!(
        "worst difference {worst:e} (tolerance {tolerance:e}, {most_links} links into one receiver); {moved} of {} leaves' H moved; {} links, {from} from clusters, {to} to clusters",
        full.len(),
        h.links.len()
    );
    if budgeted {
        assert!(from > 0 && to > 0, "the budget leaves cluster links");
    }
    assert!(worst <= tolerance, "{worst} > {tolerance}");
    // The edit moved light well beyond the patch itself.
    assert!(moved > mesh.elements.len() / 10, "{moved} leaves' H moved");
}

/// Only a converged solve is put back on its last sweep's input before the sweep after an
/// edit. While edits keep coming before it has converged again (a slider dragged), the
/// sweeps start from the solution as it stands: putting it back each time would hold every
/// unedited element at the solution before the first edit for as long as the edits come.
#[test]
fn edits_before_the_solve_converges_again_do_not_hold_it_back() {
    let mut s = solver(MeshSettings::default(), HierarchySettings::default(), 1e-3);
    s.run(None, crate::cancel::never()).unwrap();
    // The light, dimmed: a few elements, so the sweep after it is incremental, and every
    // B changes, so that sweep does not meet the tolerance.
    let lights: Vec<(u32, Vec3, Vec3)> = (s.mesh.patches.iter().enumerate())
        .filter(|(_, p)| p.emission.max_element() > 0.0)
        .map(|(i, p)| (i as u32, p.reflectance, p.emission))
        .collect();
    assert!(!lights.is_empty());
    let dim = |s: &mut Solver, factor: f32| {
        let edits: Vec<_> = lights
            .iter()
            .map(|&(patch, reflectance, emission)| crate::solver::PatchEdit {
                patch,
                reflectance,
                emission: emission * factor,
            })
            .collect();
        assert!(s.edit_patches(&edits));
    };
    let lit: Vec<u32> = lights
        .iter()
        .flat_map(|&(p, _, _)| s.mesh.patches[p as usize].elements.clone())
        .collect();
    // Whether the sweep about to run starts anywhere but on the lights from elsewhere
    // than the solution as it stands.
    let rebased = |s: &mut Solver| {
        let before = s.radiosity.clone();
        let mut h = s.hierarchy.take().unwrap();
        s.rebase_on_sweep_basis(&mut h);
        s.hierarchy = Some(h);
        (0..before.len() as u32)
            .filter(|e| !lit.contains(e))
            .any(|e| s.radiosity[e as usize] != before[e as usize])
    };
    // Converged: the sweep after the edit starts from the last sweep's input, which
    // differs from the solution shown (Anderson's step from it) on unedited elements.
    dim(&mut s, 0.5);
    assert!(
        rebased(&mut s),
        "a converged solve is put back on its basis"
    );
    s.hierarchical_work(crate::cancel::never()).unwrap();
    let h = s.hierarchy.as_ref().unwrap();
    assert_eq!(h.incremental_sweeps, 1, "one sweep, incremental");
    assert!(!h.converged, "half the light is not one sweep's change");
    dim(&mut s, 0.25);
    assert!(
        !rebased(&mut s),
        "an unconverged solve is left as it stands"
    );
}

/// The rounds go from coarse to fine (`COARSE_START`), so the solve must end where rounds
/// at the full threshold from the start end: both refine until no link's estimated error
/// exceeds ε · Ē' (their meshes then differ only where a link sits near its
/// threshold), so at points spread over every patch their radiosities must agree within
/// ε of the mean (RMS over the points); and the later rounds must have moved it: the
/// first round alone, at 16 ε, is at least twice as far from the full-threshold solve.
/// Measured at ε = 0.05: 0.8 % between the two; the first round 2.9 %.
#[test]
fn coarse_to_fine_rounds_end_where_full_threshold_rounds_end() {
    let eps = 0.05;
    let settings = HierarchySettings {
        link_error: eps,
        ..Default::default()
    };
    // Sixteen points inside each patch (the same in both meshes: patches never split).
    let points: Vec<(u32, Vec3)> = {
        let s = solver(MeshSettings::default(), settings.clone(), 1e-3);
        let mut k = 0u64;
        let mut points = Vec::new();
        for (p, patch) in s.mesh.patches.iter().enumerate() {
            for _ in 0..16 {
                k += 1;
                use crate::geometry::sampling::{hash, point_in_triangle, unit};
                let x = point_in_triangle(&patch.verts, unit(hash(k)), unit(hash(k ^ 0x5eed)));
                points.push((p as u32, x));
            }
        }
        points
    };
    let at_points = |s: &Solver| -> Vec<f64> {
        points
            .iter()
            .map(|&(p, x)| {
                let (e, _) = s.mesh.locate_in_patch(x, p);
                s.radiosity[e as usize].max_element()
            })
            .collect()
    };
    let rms = |a: &[f64], b: &[f64]| {
        let mean = b.iter().sum::<f64>() / b.len() as f64;
        let ms = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / b.len() as f64;
        ms.sqrt() / mean
    };
    let mut coarse = solver(MeshSettings::default(), settings.clone(), 1e-3);
    // The smallest steps, so that the end of the first round is seen whatever the speed
    // (with the 30 ms budget, one step of a fast build ran from the first round to the end).
    coarse.settings.step_budget = std::time::Duration::ZERO;
    let mut first_round = None;
    while !coarse.is_converged() {
        coarse.step(crate::cancel::never()).unwrap();
        // The hierarchy is made by the first step that reaches the hierarchical work; a
        // short step may end before (the direct light comes first).
        let coarseness = coarse
            .hierarchy
            .as_ref()
            .map_or(COARSE_START, |h| h.coarseness);
        if first_round.is_none() && coarseness < COARSE_START {
            first_round = Some(at_points(&coarse));
        }
    }
    assert_eq!(coarse.hierarchy.as_ref().unwrap().coarseness, 1.0);
    let mut full = solver(MeshSettings::default(), settings, 1e-3);
    let mut h = Hierarchy::new(&full.mesh, &full.reflectance);
    h.pull(&full.mesh, &full.radiosity);
    h.coarseness = 1.0;
    full.hierarchy = Some(h);
    full.run(None, crate::cancel::never()).unwrap();
    let (c, f) = (at_points(&coarse), at_points(&full));
    let d = rms(&c, &f);
    let early = rms(first_round.as_ref().unwrap(), &f);
    eprintln!("coarse to fine against full: {d}; after the first round: {early}");
    assert!(
        d <= eps as f64,
        "coarse to fine against full threshold: {d}"
    );
    assert!(
        early >= 2.0 * d,
        "the first round alone: {early}, converged {d}"
    );
}

/// The first round decides the links from lit sources first (`oracle::Round::unlit_pairs`)
/// so that its previews show the emitters' light early; the order must not change what
/// the solve converges to. Under the link budget the round ends with the links of the
/// breadth-first order; over it (a budget of 80 k links), where the cut depends on the
/// order, it starts again in breadth-first order and ends where that does.
#[test]
fn deciding_lit_links_first_changes_no_solution() {
    let run = |max_links: usize, lit_first: bool| {
        let mut s = solver(
            MeshSettings::default(),
            HierarchySettings {
                link_error: 0.05,
                max_links,
                ..Default::default()
            },
            1e-3,
        );
        let mut h = Hierarchy::new(&s.mesh, &s.reflectance);
        h.pull(&s.mesh, &s.radiosity);
        h.lit_first = lit_first;
        s.hierarchy = Some(h);
        s.run(None, crate::cancel::never()).unwrap();
        let h = s.hierarchy.as_ref().unwrap();
        (
            s.stats.links.unwrap(),
            h.first_round_restarted,
            power(&s),
            s.mesh.elements.len(),
        )
    };
    // Under the budget. The links differ a little: a receiver whose links together miss
    // too much of its light near its corners splits all its links of one generation
    // (`View::receiver_overloaded`), and the order regroups them; and the leaves split in
    // the round take their first values from brighter previews. Measured: 1,986,051
    // links against 1,991,262 (0.26 %), the light 5·10⁻⁵ apart, within the sweeps'
    // tolerance of 10⁻³. Since leaves split by their length (stop 61) the refusal of such
    // splits for balance is decided for the leaves a round splits together, which the
    // order groups differently: 1,457,142 links against 1,471,986 (1.0 %), the light
    // 3·10⁻⁵ apart; the links are held to 2 %.
    let (links, restarted, light, _) = run(HierarchySettings::default().max_links, true);
    let (links_b, _, light_b, _) = run(HierarchySettings::default().max_links, false);
    eprintln!("lit first: {links} links, light {light}; breadth first: {links_b}, {light_b}");
    assert!(!restarted);
    assert!(
        (links as f64 - links_b as f64).abs() <= 0.02 * links_b as f64,
        "{links} links against {links_b}"
    );
    assert!(
        (light - light_b).abs() <= 1e-3 * light_b,
        "{light} against {light_b}"
    );
    // Over the budget: started again, the very links of the breadth-first order (the
    // light 1.7·10⁻⁴ apart: the sweeps start from another picture).
    let (links, restarted, light, elements) = run(80_000, true);
    let (links_b, _, light_b, elements_b) = run(80_000, false);
    eprintln!(
        "budgeted, lit first: {links} links, light {light}; breadth first: {links_b}, {light_b}"
    );
    assert!(restarted);
    assert_eq!((links, elements), (links_b, elements_b));
    assert!(
        (light - light_b).abs() <= 1e-3 * light_b,
        "{light} against {light_b}"
    );
}

/// A round at ε that makes at most a thousandth of the links new is the oracle's last
/// (`ROUND_TOLERANCE`): its links are refined a little less than the rounds would go on
/// to, so each patch may differ from the solve whose rounds go on until one changes
/// nothing by about what a link kept at the threshold misses. The bound is that
/// threshold, ε times the mean E' (`Solver::link_threshold`), on every patch's mean B.
/// Measured on the built-in Cornell box at ε = 0.05: 14 sweeps against 17, 32 links fewer
/// of 1.42 M, the worst patch 1.0·10⁻⁵ W/m² off against a threshold of 1.9·10⁻².
#[test]
fn a_round_that_makes_few_links_ends_the_solve_within_the_oracles_threshold() {
    let run = |round_tolerance| {
        let mut s = solver(
            MeshSettings::default(),
            HierarchySettings {
                link_error: 0.05,
                round_tolerance,
                ..Default::default()
            },
            1e-4,
        );
        s.run(None, crate::cancel::never()).unwrap();
        assert!(s.stats.converged);
        s
    };
    let (early, full) = (run(ROUND_TOLERANCE), run(0.0));
    let threshold = full.link_threshold() as f64;
    // Patches are the same in any two solves of one scene, whatever their leaves.
    let (a, b) = (
        early.patch_means(&early.radiosity),
        full.patch_means(&full.radiosity),
    );
    let worst = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (*x - *y).abs().max_element())
        .fold(0.0, f64::max);
    eprintln!(
        "sweeps {} / {}, links {:?} / {:?}, worst patch {worst:.3e} (threshold {threshold:.3e})",
        early.stats.iterations, full.stats.iterations, early.stats.links, full.stats.links
    );
    // The early end did come: otherwise this test compares a solve with itself.
    assert!(early.stats.iterations < full.stats.iterations);
    assert!(worst <= threshold, "worst patch {worst} over {threshold}");
}
