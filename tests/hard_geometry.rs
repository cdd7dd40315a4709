//! Hard geometry at the command line's default settings, against a closed form: the white
//! furnace (every surface emits E and reflects ρ = 0.9, so B = E / (1 − ρ) everywhere,
//! exactly). Probed 0.1 mm from the edge where two coplanar triangles meet and from the
//! 90° edges and corners between faces, a kilometre from the origin and at millimetre
//! scale; and at the centroids of sliver triangles of aspect 10⁴ lining every edge of
//! every face, with tiny triangles in the corners. And a floor cut into long slivers
//! under a shadow, against the penumbra scene's closed form.
//!
//! Both the default hierarchical solve and the flat progressive one are checked, each
//! against its own bound (see `methods`). The progressive tolerance: it stops when at most
//! `tolerance` (1e-3) of the source power is unshot and no patch's unshot radiosity
//! exceeds `tolerance` × the mean radiosity. In a furnace what is still unshot would raise
//! each B by about that fraction again after its later bounces, so the error is below
//! 2 × `tolerance`. Before the second criterion, slivers never shot (they have almost no
//! power) and the elements beside them, which see them over half their hemisphere, came out
//! up to 73 % low.

use glam::DVec3;
use glam::{DMat4, Vec3};
use radiosity::analytic::{penumbra_floor, penumbra_grid};
use radiosity::cli::SolveOptions;
use radiosity::mesh::Reconstruction;
use radiosity::pipeline::{Prepared, probe_values};
use radiosity::scene::{Material, Object, Scene, builtin};
use radiosity::solver::Method;

/// The methods checked: the command line's default (hierarchical) and the flat
/// progressive solve, each with the tolerance its own stopping rule and error bound give.
///
/// - progressive: 2 × `tolerance` (see the module doc);
/// - hierarchical: the oracle holds every link's estimated error, and the summed misfit of
///   each receiver's links near its corners, to ε · Ē' (Ē' the mean light the surfaces
///   emit or first reflect), and the sweeps stop when what is left is about
///   `tolerance` · B̄; an error δ per transfer grows over the bounces by the scene's gain
///   B̄ / Ē', so the result is within about ε · B̄ (+ `tolerance`) of the truth.
fn methods() -> [(Method, f64); 2] {
    let o = SolveOptions::default();
    [
        (Method::Hierarchical, o.link_error as f64 + o.tolerance),
        (Method::Progressive, 2.0 * o.tolerance),
    ]
}

/// Radiosity at `points` (world, normal) after a default solve with `method`: as `probe`
/// reports it (the final gather at each point) and as the viewer shows it (Gouraud). The
/// gather's own error adds nothing here: seen from a point inside a closed box the exact
/// form factors of all surfaces sum to 1, so the gather returns E + ρ · (a mean of the
/// solution's B), within ρ times the solution's error of the truth.
fn probe(
    scene: &Scene,
    points: &[(DVec3, DVec3)],
    method: Method,
) -> [(&'static str, Vec<f64>); 2] {
    let options = SolveOptions {
        method: Some(method),
        ..SolveOptions::default()
    };
    let prepared = Prepared::new(scene, &options.mesh_settings());
    let mut solver = prepared.solver(options.solver_settings()).unwrap();
    solver.run(None, radiosity::cancel::never()).unwrap();
    let red = |v: Vec<Vec3>| v.iter().map(|v| v.x as f64).collect();
    [
        (
            "gather",
            red(solver.gatherer(options.gather_settings()).at_points(points)),
        ),
        (
            "gouraud",
            red(probe_values(
                solver.mesh(),
                &solver.radiosity(),
                points,
                Reconstruction::Gouraud,
            )),
        ),
    ]
}

/// Points inside the box `origin + [0, size]³` a distance `d` from its edges, corners and
/// the face diagonal (where each face's two triangles meet), with inward normals.
fn furnace_points(origin: DVec3, size: f64, d: f64) -> Vec<(DVec3, DVec3)> {
    let at = |x: f64, y: f64, z: f64| origin + DVec3::new(x, y, z) * size;
    let f = d / size;
    vec![
        // Floor (normal +y): near the corner, near an edge, on the diagonal x = z (offset).
        (at(f, 0.0, f), DVec3::Y),
        (at(0.5, 0.0, f), DVec3::Y),
        (at(0.5 + f, 0.0, 0.5), DVec3::Y),
        // The wall x = 0 (normal +x) next to the floor, and the ceiling near a corner.
        (at(0.0, f, 0.5), DVec3::X),
        (at(1.0 - f, 1.0, 1.0 - f), -DVec3::Y),
    ]
}

fn worst_relative(values: &[f64], truth: f64) -> f64 {
    values
        .iter()
        .map(|v| (v - truth).abs() / truth)
        .fold(0.0, f64::max)
}

#[test]
fn furnace_is_exact_near_edges_and_corners_at_every_scale() {
    let (rho, e) = (0.9f32, 1.0f32);
    let truth = e as f64 / (1.0 - rho as f64);
    for (origin, size, d) in [
        (DVec3::ZERO, 1.0, 1e-4),
        (DVec3::new(1000.0, -500.0, 1000.0), 1.0, 1e-4),
        (DVec3::ZERO, 1e-3, 1e-7),
    ] {
        let scene = builtin::furnace_box(origin, DVec3::splat(size), rho, e);
        let pts = furnace_points(origin, size, d);
        for (method, tolerance) in methods() {
            for (how, v) in probe(&scene, &pts, method) {
                let worst = worst_relative(&v, truth);
                eprintln!("{method} {how}: furnace at {origin} size {size}: worst {worst:.3e}");
                assert!(
                    worst <= tolerance,
                    "{method} {how}: furnace at {origin} size {size}: {v:?}"
                );
            }
        }
    }
}

#[test]
fn sliver_furnace_is_exact_at_the_slivers() {
    let (rho, e) = (0.9f32, 1.0f32);
    let truth = e as f64 / (1.0 - rho as f64);
    let s = 1e-4;
    let scene = builtin::furnace_box_slivers(DVec3::ZERO, DVec3::ONE, rho, e, s);
    // Sliver centroids: (p, p + u, p + u + s·v) per face, from the scene itself.
    let o = &scene.objects[0];
    let mut pts = Vec::new();
    for (k, t) in o.triangles.iter().enumerate() {
        if k % 3 != 0 {
            continue;
        }
        let p = t.map(|i| o.world_position(i));
        let c = (p[0] + p[1] + p[2]) / 3.0;
        let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
        pts.push((c, n));
    }
    for (method, tolerance) in methods() {
        for (how, v) in probe(&scene, &pts, method) {
            let worst = worst_relative(&v, truth);
            eprintln!("{method} {how}: sliver furnace: worst {worst:.3e}");
            assert!(worst <= tolerance, "{method} {how}: {v:?}");
        }
    }
}

/// A unit furnace box whose every face is lined with slivers: a border strip of width `s`
/// along each edge cut into two triangles of aspect about 1/s, and two tiny triangles in
/// each s × s corner square, around the face's two ordinary triangles. Returns the scene
/// and the centroids (with inward normals) of every sliver and tiny triangle.
fn lined_furnace(rho: f32, e: f32, s: f64) -> (Scene, Vec<(DVec3, DVec3)>) {
    let mut o = Object {
        name: "lined box".into(),
        world_from_local: DMat4::IDENTITY,
        ..Default::default()
    };
    let mut probes = Vec::new();
    // Each face: corner p and edges u, v with u × v pointing inward.
    let faces = [
        (DVec3::ZERO, DVec3::Z, DVec3::X),
        (DVec3::Y, DVec3::X, DVec3::Z),
        (DVec3::ZERO, DVec3::X, DVec3::Y),
        (DVec3::Z, DVec3::Y, DVec3::X),
        (DVec3::ZERO, DVec3::Y, DVec3::Z),
        (DVec3::X, DVec3::Z, DVec3::Y),
    ];
    let cuts = [0.0, s, 1.0 - s, 1.0];
    for (p, u, v) in faces {
        let n = u.cross(v).normalize();
        let at = |i: usize, j: usize| p + u * cuts[i] + v * cuts[j];
        for i in 0..3 {
            for j in 0..3 {
                let q = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
                let base = o.positions.len() as u32;
                o.positions.extend(q.iter().map(|x| x.as_vec3()));
                o.triangles.push([base, base + 1, base + 2]);
                o.triangles.push([base, base + 2, base + 3]);
                if i != 1 || j != 1 {
                    for t in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
                        probes.push(((t[0] + t[1] + t[2]) / 3.0, n));
                    }
                }
            }
        }
    }
    o.triangle_material = vec![0; o.triangles.len()];
    let scene = Scene {
        name: "lined furnace".into(),
        objects: vec![o],
        materials: vec![Material::emitter(
            "furnace",
            Vec3::splat(rho),
            Vec3::splat(e / std::f32::consts::PI),
        )],
        ..Default::default()
    };
    (scene, probes)
}

#[test]
fn furnace_lined_with_slivers_is_exact_at_their_centroids() {
    let (rho, e) = (0.9f32, 1.0f32);
    let truth = e as f64 / (1.0 - rho as f64);
    let (scene, pts) = lined_furnace(rho, e, 1e-4);
    for (method, tolerance) in methods() {
        for (how, v) in probe(&scene, &pts, method) {
            let worst = worst_relative(&v, truth);
            eprintln!(
                "{method} {how}: lined furnace: worst {worst:.3e} over {} slivers",
                v.len()
            );
            assert!(worst <= tolerance, "{method} {how}: {v:?}");
        }
    }
}

/// `builtin:penumbra` with its floor cut into strips `width` wide along x, each in pieces
/// 0.25 m long (two triangles each): long slivers wherever `width` is well under the
/// hierarchy's minimum size.
fn penumbra_on_strips(width: f64) -> Scene {
    let mut scene = builtin::penumbra();
    let floor = &mut scene.objects[0];
    let half = builtin::PENUMBRA_FLOOR;
    let strips = (2.0 * half / width).round() as usize;
    floor.positions.clear();
    floor.triangles.clear();
    for i in 0..strips {
        let (z0, z1) = (-half + i as f64 * width, -half + (i + 1) as f64 * width);
        for j in 0..8 {
            let (x0, x1) = (-half + j as f64 * 0.25, -half + (j + 1) as f64 * 0.25);
            let base = floor.positions.len() as u32;
            for (x, z) in [(x0, z0), (x0, z1), (x1, z1), (x1, z0)] {
                floor.positions.push(DVec3::new(x, 0.0, z).as_vec3());
            }
            // Counter-clockwise seen from +y.
            floor.triangles.push([base, base + 1, base + 2]);
            floor.triangles.push([base, base + 2, base + 3]);
        }
    }
    floor.triangle_material = vec![0; floor.triangles.len()];
    scene
}

#[test]
fn a_floor_of_long_slivers_takes_the_shadow_the_closed_form_gives() {
    // The penumbra scene's floor (closed form: `analytic::penumbra_floor`) meshed at 0.25 m
    // elements, so the hierarchy's minimum size is 3.1 cm: once as the scene's two
    // triangles, once cut into strips 5 mm wide and 25 cm long, slivers whose children
    // would be under the minimum size by their area (as sqrt(2 · area)). Gouraud RMS over
    // the 41 × 41 grid, relative to the exact values' RMS, measured 2026-12-08: 0.0137 on
    // the two triangles, 0.0236 on the strips. While a leaf could split only by its area,
    // the strips never split and each held one value across the occluder's shadow and
    // penumbra: 0.150 (the two triangles 0.034). A strip's children are strips again,
    // never as compact as the plain floor's, so the bound is twice its error, not equality.
    let options = SolveOptions::default();
    let rms = |scene: &Scene| {
        let prepared = Prepared::new(
            scene,
            &radiosity::mesh::MeshSettings {
                element_size: Some(0.25),
                ..options.mesh_settings()
            },
        );
        let mut solver = prepared.solver(options.solver_settings()).unwrap();
        solver.run(None, radiosity::cancel::never()).unwrap();
        let pts = penumbra_grid();
        let got = probe_values(
            solver.mesh(),
            &solver.radiosity(),
            &pts,
            Reconstruction::Gouraud,
        );
        let (mut num, mut den) = (0.0, 0.0);
        for ((p, _), g) in pts.iter().zip(&got) {
            let exact = penumbra_floor(p.x, p.z);
            num += (g.x as f64 - exact).powi(2);
            den += exact * exact;
        }
        ((num / den).sqrt(), solver.mesh().elements.len())
    };
    let (plain, plain_elements) = rms(&builtin::penumbra());
    let (strips, strip_elements) = rms(&penumbra_on_strips(0.005));
    eprintln!(
        "penumbra floor, Gouraud RMS: two triangles {plain:.4} ({plain_elements} elements), \
         5 mm strips {strips:.4} ({strip_elements} elements)"
    );
    assert!(
        strips <= 2.0 * plain,
        "strips {strips:.4}, plain {plain:.4}"
    );
}
