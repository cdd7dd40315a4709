//! Form factors on meshes against independent truth: the conservation laws of the discrete
//! system (reciprocity, closed-enclosure row sums), the hemicube as a second, independently
//! written estimator, a dense kernel-weighted reference row, and bounded values at contact.
//!
//! Tolerances: see `common::F32_REL`. `point_to_polygon` itself is checked against closed
//! forms from the radiation literature in `form_factor_closed_forms.rs`.

mod common;
use common::{F32_REL, contour_slack, prepared, ptp};
use glam::{DVec3, Vec3};
use radiosity::accel::Bvh;
use radiosity::geometry::subdivide;
use radiosity::mesh::Mesh;
use radiosity::scene::{Material, Object, Scene, builtin};
use radiosity::solver::form_factor::{FormFactorSettings, element_to_patch};
use radiosity::solver::hemicube::{Hemicube, hemicube_row};

// ---------------------------------------------------------------------------------------
// Conservation laws of the discrete system
// ---------------------------------------------------------------------------------------

/// Patch-to-patch form factor from the element-to-patch estimator: the area average of the
/// element rows, F_pq = Σ_{i∈p} A_i F_iq / A_p; `None` if any element–patch pair is partly
/// occluded (its shadow-ray fraction is not 1), so that only collocation error remains.
/// Also returns the same average over the elements' four midpoint children (unoccluded,
/// analytic), which converges four times faster: the pair estimates the collocation error.
/// The third value is the f32 rounding bound of the coarse average (`contour_slack` per
/// element, area-weighted), which the fine one shares within a factor of 2.
fn patch_form_factor(mesh: &Mesh, bvh: &Bvh, p: usize, q: usize) -> Option<(f64, f64, f64)> {
    let settings = FormFactorSettings::default();
    let target = &mesh.patches[q];
    let (mut coarse, mut fine, mut slack) = (0.0, 0.0, 0.0);
    for i in mesh.patches[p].elements.clone() {
        let e = &mesh.elements[i as usize];
        let (f, _) = element_to_patch(mesh, bvh, i as usize, q, &settings);
        let exact = ptp(e.centroid(), e.normal, &target.verts);
        // Any blocked shadow ray changes the value by ≥ 1/16 relative; 1e-6 is rounding.
        if (f as f64 - exact).abs() > 1e-6 * exact || f <= 0.0 {
            return None;
        }
        coarse += e.area as f64 * f as f64;
        slack += e.area as f64 * contour_slack(e.centroid(), &target.verts);
        for child in subdivide(&e.verts) {
            let c = (child[0] + child[1] + child[2]) / 3.0;
            fine += e.area as f64 / 4.0 * ptp(c, e.normal, &target.verts);
        }
    }
    let area = mesh.patches[p].area as f64;
    Some((coarse / area, fine / area, slack / area))
}

#[test]
fn element_to_patch_is_reciprocal_on_the_cornell_box() {
    // A_p F_pq = A_q F_qp holds for the exact area-to-area form factors. Our F_pq averages
    // exact point values at element centroids (one-point rule per element), so each side
    // carries a collocation error; by Richardson extrapolation from the children's average
    // (error ¼ as large for the O(h²) centroid rule) that error is ≈ (4/3)|coarse − fine|.
    // Reciprocity must hold to the sum of both sides' estimated errors, with a factor 2 for
    // the estimate's own error (higher-order terms near the shared edges of adjacent walls),
    // plus f32 rounding.
    let prepared = prepared(&builtin::cornell_box(), 1500);
    let (mesh, bvh) = (&*prepared.mesh, &*prepared.bvh);
    let (mut checked, mut separated) = (0, 0);
    let mut worst: f64 = 0.0;
    for p in 0..mesh.patches.len() {
        for q in p + 1..mesh.patches.len() {
            let (Some((fpq, fpq_fine, spq)), Some((fqp, fqp_fine, sqp))) = (
                patch_form_factor(mesh, bvh, p, q),
                patch_form_factor(mesh, bvh, q, p),
            ) else {
                continue;
            };
            let straddles = |a: usize, b: usize| {
                let (pa, pb) = (&mesh.patches[a], &mesh.patches[b]);
                let side = pb.verts.map(|v| pa.normal.dot(v - pa.verts[0]));
                side.iter().any(|s| *s < -1e-6) && side.iter().any(|s| *s > 1e-6)
            };
            if straddles(p, q) || straddles(q, p) {
                continue;
            }
            let (ap, aq) = (mesh.patches[p].area as f64, mesh.patches[q].area as f64);
            let (left, right) = (ap * fpq, aq * fqp);
            let collocation =
                4.0 / 3.0 * (ap * (fpq - fpq_fine).abs() + aq * (fqp - fqp_fine).abs());
            // f32 rounding of both sides, coarse and fine.
            let rounding = 3.0 * (ap * spq + aq * sqp);
            let bound = 2.0 * collocation + F32_REL * (left + right) + rounding;
            // Near a shared or close edge the kernel is singular and the one-point rule's
            // error is not O(h²), so the Richardson estimate is not a bound there: check
            // the bound only for separated pairs (closest vertices at least one patch
            // diameter apart), and for all pairs that refinement does not make it worse
            // (beyond 2e-3 relative: next to a shared edge, such as a wall corner or a
            // block's base on the floor split along its contact line, the children's
            // one-point values still err by O(h) there, observed up to ~1.2e-3 of A·F, and
            // the coarse gap can be zero by chance). Pairs of different objects touching
            // along a contact line (the floor's pieces beside a block's base) are not
            // held to it: there a small piece beside a large face makes the large face's
            // one-point rule err by several per cent, and halving it need not help.
            let diam = |k: usize| {
                let v = mesh.patches[k].verts;
                (v[0] - v[1])
                    .length()
                    .max((v[1] - v[2]).length())
                    .max((v[2] - v[0]).length()) as f64
            };
            let mut gap_min = f64::INFINITY;
            for a in mesh.patches[p].verts {
                for b in mesh.patches[q].verts {
                    gap_min = gap_min.min((a - b).length() as f64);
                }
            }
            let fine_gap = (ap * fpq_fine - aq * fqp_fine).abs();
            if gap_min >= diam(p).max(diam(q)) {
                assert!(
                    (left - right).abs() <= bound,
                    "patches {p}, {q}: A_p F_pq = {left:.6e}, A_q F_qp = {right:.6e}, collocation bound {bound:.2e}"
                );
                separated += 1;
            } else if mesh.patches[p].object == mesh.patches[q].object {
                assert!(
                    fine_gap <= (left - right).abs() * 1.05 + 2e-3 * (left + right) + rounding,
                    "patches {p}, {q}: refinement widened the gap: {} → {fine_gap} (areas {ap} {aq}, F {fpq} {fqp}, gap {gap_min}, objects {} {})",
                    (left - right).abs(),
                    mesh.patches[p].object,
                    mesh.patches[q].object
                );
            }
            worst = worst.max((left - right).abs() / left.max(right));
            checked += 1;
        }
    }
    eprintln!(
        "reciprocity: {checked} unoccluded pairs ({separated} separated), worst relative gap {worst:.3e}"
    );
    assert!(
        checked > 1000 && separated > 300,
        "too few unoccluded pairs checked: {checked}"
    );
}

#[test]
fn element_to_patch_rows_sum_to_one_in_the_furnace_box() {
    // Closed convex enclosure: every direction above an element meets exactly one patch, no
    // occlusion, so Σ_p F_ip = 1 with exact point values. What remains is f32 rounding of
    // each value (6e-8 relative, summed: ≤ 6e-8) and of the mesh vertices (patch edges meet
    // to an ulp, 1e-7 of the box), far inside 1e-5.
    let scene = builtin::furnace_box(
        DVec3::new(3.0, -2.0, 1.0),
        DVec3::new(1.0, 2.0, 0.5),
        0.5,
        1.0,
    );
    let prepared = prepared(&scene, 600);
    let (mesh, bvh) = (&*prepared.mesh, &*prepared.bvh);
    let settings = FormFactorSettings::default();
    for i in 0..mesh.elements.len() {
        let sum: f64 = (0..mesh.patches.len())
            .map(|p| element_to_patch(mesh, bvh, i, p, &settings).0 as f64)
            .sum();
        assert!((sum - 1.0).abs() <= 1e-5, "element {i}: Σ_p F_ip = {sum}");
    }
}

// ---------------------------------------------------------------------------------------
// The hemicube against the analytic estimator
// ---------------------------------------------------------------------------------------

fn row_sum(row: &[(u32, f32)]) -> f64 {
    row.iter().map(|(_, f)| *f as f64).sum()
}

#[test]
fn hemicube_rows_sum_to_one_in_the_furnace_box() {
    // In a closed box every hemicube pixel shows some patch, so a row sums to the sum of the
    // delta form factors, whose midpoint-rule error is ≈ 0.54/res² (+1.3e-4 at 64, +8.3e-6
    // at 256); pixels lost to edge rounding or the near plane would show as a deficit. Bound:
    // 1/res² for every element, and the worst error must shrink from 64 to 256.
    let scene = builtin::furnace_box(DVec3::ZERO, DVec3::new(1.0, 0.7, 1.3), 0.5, 1.0);
    let prepared = prepared(&scene, 200);
    let mesh = &*prepared.mesh;
    let mut worst = Vec::new();
    for res in [64u32, 256] {
        let mut cube = Hemicube::new(res);
        let mut w: f64 = 0.0;
        // Every element at 64, every third at 256 (the test's time budget).
        let stride = if res == 64 { 1 } else { 3 };
        for i in (0..mesh.elements.len()).step_by(stride) {
            let err = row_sum(&cube.row(mesh, i)) - 1.0;
            assert!(
                err.abs() <= 1.0 / (res as f64).powi(2),
                "res {res}, element {i}: row sum − 1 = {err:.3e}"
            );
            w = w.max(err.abs());
        }
        eprintln!("hemicube {res}: worst |Σ F − 1| over the furnace box = {w:.3e}");
        worst.push(w);
    }
    assert!(
        worst[1] < worst[0] / 4.0,
        "hemicube error did not shrink with resolution: {worst:?}"
    );
}

/// Index of the Cornell box's surface (a quad = two consecutive scene triangles) of a patch:
/// 0 floor, 1 ceiling, 2 back, 3 green, 4 red, 5 light, then the blocks' faces.
fn surface(mesh: &Mesh, patch: u32) -> usize {
    mesh.patches[patch as usize].scene_triangle as usize / 2
}

fn per_surface(mesh: &Mesh, row: impl Iterator<Item = (u32, f64)>) -> Vec<f64> {
    let mut out = vec![0.0; mesh.triangles.len().div_ceil(2)];
    for (p, f) in row {
        out[surface(mesh, p)] += f;
    }
    out
}

/// Reference row F_ip for element `element`'s centroid x: each patch cut into 4⁵ = 1024
/// midpoint sub-triangles, each contributing its exact point-to-polygon value times the
/// visibility of its centroid (one shadow ray). Exact where unoccluded; under partial
/// occlusion, visibility is weighted by the form-factor kernel (as the definition of F
/// requires), and only the sub-triangles cut by a shadow edge are misjudged: shadow edges
/// resolved to 1/32 of a patch, a few 1e-3 of a partly hidden surface's F (checked against
/// 4⁶ sub-triangles and a 1024² hemicube while writing this test: within 0.2 %).
fn reference_row(mesh: &Mesh, bvh: &Bvh, element: usize) -> Vec<f64> {
    let e = &mesh.elements[element];
    let x = e.centroid();
    let eps = mesh.epsilon();
    let from = x + e.normal * eps;
    let own = mesh.patches[e.patch as usize].scene_triangle;
    (0..mesh.patches.len())
        .map(|p| {
            let patch = &mesh.patches[p];
            if p == e.patch as usize || patch.normal.dot(x - patch.verts[0]) <= 0.0 {
                return 0.0;
            }
            let skip = [own, patch.scene_triangle];
            let mut pieces = vec![patch.verts];
            for _ in 0..5 {
                pieces = pieces.iter().flat_map(subdivide).collect();
            }
            pieces
                .iter()
                .map(|t| {
                    let c = (t[0] + t[1] + t[2]) / 3.0 + patch.normal * eps;
                    ptp(x, e.normal, t) * bvh.transmittance(from, c, skip) as f64
                })
                .sum()
        })
        .collect()
}

#[test]
fn hemicube_and_ray_cast_agree_with_a_reference_on_the_cornell_box() {
    let prepared = prepared(&builtin::cornell_box(), 400);
    let (mesh, bvh) = (&*prepared.mesh, &*prepared.bvh);
    let settings = FormFactorSettings::default();
    let mut worst = [0.0f64; 3];
    let mut compared = 0;
    for i in (0..mesh.elements.len()).step_by(9) {
        let reference = per_surface(
            mesh,
            reference_row(mesh, bvh, i)
                .into_iter()
                .enumerate()
                .map(|(p, f)| (p as u32, f)),
        );
        let h64 = per_surface(
            mesh,
            hemicube_row(mesh, i, 64)
                .into_iter()
                .map(|(p, f)| (p, f as f64)),
        );
        let h256 = per_surface(
            mesh,
            hemicube_row(mesh, i, 256)
                .into_iter()
                .map(|(p, f)| (p, f as f64)),
        );
        let ray = per_surface(
            mesh,
            (0..mesh.patches.len()).map(|p| {
                (
                    p as u32,
                    element_to_patch(mesh, bvh, i, p, &settings).0 as f64,
                )
            }),
        );
        for s in 0..reference.len() {
            let r = reference[s];
            if r < 0.02 {
                continue;
            }
            compared += 1;
            for (k, v) in [h64[s], h256[s], ray[s]].into_iter().enumerate() {
                let err = (v - r).abs() / r;
                worst[k] = worst[k].max(err);
            }
        }
    }
    eprintln!(
        "{compared} surface sums; worst relative error: hemicube 64 {:.3e}, 256 {:.3e}, ray-cast {:.3e}",
        worst[0], worst[1], worst[2]
    );
    assert!(compared > 100, "{compared}");
    // Per-surface sums (≥ 0.02) against the reference: the hemicube's error is pixel
    // aliasing of the surface outlines, ∝ 1/resolution (measured 5.4 % at 64, 2.0 % at
    // 256: bounds at twice that); the ray-cast estimate is exact where unoccluded and its
    // visibility error is that of the strata cut by a shadow edge (measured 5.3 %).
    assert!(worst[0] < 0.1, "hemicube 64: {}", worst[0]);
    assert!(worst[1] < 0.04, "hemicube 256: {}", worst[1]);
    assert!(worst[2] < 0.1, "ray-cast: {}", worst[2]);
    // Resolution must help: the finer hemicube is closer.
    assert!(worst[1] < worst[0]);
}

/// A floor (1 × 1 at y = 0, facing up), a small emitter (0.2 × 0.2 at y = 1, facing down)
/// and between them a single-sided blocker (0.4 × 0.4 at y = 0.5) facing *up*: the floor
/// sees only its back, which is no patch but must still block.
fn blocker_scene() -> Scene {
    let square = |centre: [f64; 3], half: f32, up: bool| {
        let c = Vec3::new(centre[0] as f32, centre[1] as f32, centre[2] as f32);
        let (a, b) = (Vec3::X * half, Vec3::Z * half);
        let positions = vec![c - a - b, c + a - b, c + a + b, c - a + b];
        // (−a−b, +a−b, +a+b) winds counter-clockwise seen from below (normal −y).
        let triangles = if up {
            vec![[0, 2, 1], [0, 3, 2]]
        } else {
            vec![[0, 1, 2], [0, 2, 3]]
        };
        (positions, triangles)
    };
    let mut objects = Vec::new();
    for (name, centre, half, up, material) in [
        ("floor", [0.0, 0.0, 0.0], 0.5, true, 0u32),
        ("lamp", [0.0, 1.0, 0.0], 0.1, false, 1),
        ("blocker", [0.0, 0.5, 0.0], 0.2, true, 0),
    ] {
        let (positions, triangles) = square(centre, half, up);
        objects.push(Object {
            name: name.into(),
            positions,
            triangle_material: vec![material; triangles.len()],
            triangles,
            ..Default::default()
        });
    }
    Scene {
        name: "blocker".into(),
        objects,
        materials: vec![
            Material::diffuse("white", Vec3::splat(0.5)),
            Material::emitter("lamp", Vec3::ZERO, Vec3::ONE),
        ],
        ..Default::default()
    }
}

#[test]
fn hemicube_blocks_with_back_faces_of_single_sided_surfaces() {
    let prepared = prepared(&blocker_scene(), 400);
    let (mesh, bvh) = (&*prepared.mesh, &*prepared.bvh);
    // Orientation sanity: floor and blocker face up, the lamp down.
    for p in &mesh.patches {
        let want = if p.object == 1 { -1.0 } else { 1.0 };
        assert!(
            (p.normal.y - want).abs() < 1e-6,
            "patch of object {} has normal {}",
            p.object,
            p.normal
        );
    }
    let settings = FormFactorSettings {
        max_rays: 64,
        min_rays: 16,
        penumbra_rays: 256,
    };
    let lamp = |row: &[(u32, f32)]| -> f64 {
        row.iter()
            .filter(|(p, _)| mesh.patches[*p as usize].object == 1)
            .map(|(_, f)| *f as f64)
            .sum()
    };
    let mut umbra = 0;
    let (mut hemi_err, mut ray_err) = (Vec::new(), Vec::new());
    for (i, e) in mesh.elements.iter().enumerate() {
        if mesh.patches[e.patch as usize].object != 0 {
            continue;
        }
        let row = hemicube_row(mesh, i, 256);
        // The blocker faces away from the floor: it shoots nothing there.
        assert!(
            row.iter()
                .all(|(p, _)| mesh.patches[*p as usize].object != 2),
            "element {i} sees the blocker's front"
        );
        let hemi = lamp(&row);
        let ray: f64 = (0..mesh.patches.len())
            .filter(|&p| mesh.patches[p].object == 1)
            .map(|p| element_to_patch(mesh, bvh, i, p, &settings).0 as f64)
            .sum();
        let c = e.centroid();
        // Umbra: every segment from the centroid to the lamp (|x|, |z| ≤ 0.1 at y = 1)
        // crosses y = 0.5 within the blocker (|x|, |z| ≤ 0.2) when |x_c|, |z_c| < 0.3.
        if c.x.abs() < 0.29 && c.z.abs() < 0.29 {
            assert_eq!(
                hemi, 0.0,
                "element {i} at {c} is in the umbra but the hemicube sees the lamp"
            );
            assert_eq!(
                ray, 0.0,
                "element {i} at {c} is in the umbra but shadow rays reach the lamp"
            );
            umbra += 1;
        } else {
            // Penumbra and lit: against the dense kernel-weighted reference.
            let reference: f64 = reference_row(mesh, bvh, i)
                .into_iter()
                .enumerate()
                .filter(|(p, _)| mesh.patches[*p].object == 1)
                .map(|(_, f)| f)
                .sum();
            let free = (0..mesh.patches.len())
                .filter(|&p| mesh.patches[p].object == 1)
                .map(|p| ptp(c, e.normal, &mesh.patches[p].verts))
                .sum::<f64>();
            hemi_err.push((hemi - reference) / free);
            ray_err.push((ray - reference) / free);
        }
    }
    let stats = |v: &[f64]| {
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let rms = (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
        let worst = v.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        (mean, rms, worst)
    };
    eprintln!("hemicube (mean, rms, worst) / free: {:?}", stats(&hemi_err));
    eprintln!("ray-cast (mean, rms, worst) / free: {:?}", stats(&ray_err));
    // Tolerances, as fractions of the unoccluded value: the ray-cast estimate misjudges
    // only the strata cut by the shadow edge (about 2k of k² = 256 here, each counted whole
    // or not at all: a few percent), the hemicube only the pixels on it (a 256² cube puts
    // the lamp on ~25² pixels: a few percent). Neither may be biased beyond 1 %.
    // Measured: hemicube (−0.4 %, 1.5 %, 3.2 %), ray-cast (+0.4 %, 1.0 %, 6.9 %).
    for (what, err) in [("hemicube", &hemi_err), ("ray-cast", &ray_err)] {
        let (mean, rms, worst) = stats(err);
        assert!(
            mean.abs() < 0.01 && rms < 0.025 && worst < 0.1,
            "{what}: mean {mean}, rms {rms}, worst {worst}"
        );
    }
    assert!(umbra > 10, "too few umbra elements: {umbra}");
}

// ---------------------------------------------------------------------------------------
// Bounded behaviour at contact
// ---------------------------------------------------------------------------------------

#[test]
fn form_factors_stay_bounded_at_contact() {
    // A point 1e-9 from a triangle (above its interior, facing it; beside an edge; at a
    // vertex): the exact value tends to 1, ½ or a wedge fraction, never beyond 1.
    let tri = [
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(2.0, -1.0, 0.0),
        Vec3::new(-1.0, 2.0, 0.0),
    ];
    let cases = [
        (Vec3::new(0.0, 0.0, -1e-9), Vec3::Z, 0.999, 1.0),
        (Vec3::new(0.0, -1.0 - 1e-9, 1e-9), Vec3::Y, 0.0, 0.5),
        (Vec3::new(-1.0, -1.0, -1e-9), Vec3::Z, 0.0, 1.0),
        (tri[0], Vec3::Z, 0.0, 1.0),
        ((tri[0] + tri[1]) * 0.5, Vec3::Y, 0.0, 1.0),
    ];
    for (p, n, lo, hi) in cases {
        let f = ptp(p, n, &tri);
        assert!(
            f.is_finite() && f >= lo && f <= hi,
            "point {p} normal {n}: F = {f}"
        );
    }
    // The Cornell box's blocks stand on the floor: their side elements touch floor patches
    // along an edge, and floor elements touch the block faces. Every pair, both estimators:
    // finite and in [0, 1], and a row never exceeds 1 (plus the hemicube's table excess).
    let prepared = prepared(&builtin::cornell_box(), 300);
    let (mesh, bvh) = (&*prepared.mesh, &*prepared.bvh);
    let settings = FormFactorSettings::default();
    // Elements with a corner on the floor line: the floor itself, the bottom rows of the
    // walls and of the blocks' sides.
    let floor_y = -mesh.origin.y as f32;
    let on_floor = |i: &usize| {
        mesh.elements[*i]
            .verts
            .iter()
            .any(|v| (v.y - floor_y).abs() < 1e-4)
    };
    let mut checked = 0;
    for i in (0..mesh.elements.len()).filter(on_floor) {
        let row: Vec<f64> = (0..mesh.patches.len())
            .map(|p| element_to_patch(mesh, bvh, i, p, &settings).0 as f64)
            .collect();
        assert!(
            row.iter().all(|f| f.is_finite() && (0.0..=1.0).contains(f)),
            "element {i}: {row:?}"
        );
        // The exact row sums to ≤ 1 (a closed box: = 1). Visibility is sampled per stratum,
        // and a stratum cut by a shadow edge counts whole or not at all, so the estimate
        // can exceed 1 by the form factor of the cut strata (one row of a 16-stratum first
        // pass at a contact, 64 in penumbra: about 1 %; measured up to 0.7 %).
        assert!(
            row.iter().sum::<f64>() <= 1.02,
            "element {i}: row sum {}",
            row.iter().sum::<f64>()
        );
        let hemi = hemicube_row(mesh, i, 64);
        assert!(
            hemi.iter()
                .all(|(_, f)| f.is_finite() && (0.0..=1.0).contains(f)),
            "element {i}: {hemi:?}"
        );
        assert!(
            row_sum(&hemi) <= 1.0 + 1.0 / 64f64.powi(2),
            "element {i}: hemicube row sum {}",
            row_sum(&hemi)
        );
        checked += 1;
    }
    assert!(checked > 20, "{checked}");
}
