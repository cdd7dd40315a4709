//! The final gather (`probe`'s default) against closed forms and the path-traced
//! reference: parallel and perpendicular plates down to 0.1 mm from their edges (near the
//! origin, a kilometre from it and at millimetre scale), the penumbra scene in its umbra
//! and penumbra, and a sample of Cornell-box points.

mod common;
use common::quad_object;
use glam::{DMat4, DVec3, Vec3};
use radiosity::analytic::{
    parallel_square, penumbra_floor, penumbra_grid, perpendicular_rectangle_corner,
};
use radiosity::cli::SolveOptions;
use radiosity::pipeline::Prepared;
use radiosity::scene::{Material, Scene, builtin};
use std::f64::consts::PI;

const RHO: f64 = 0.5;

/// `scene` solved with the command line's defaults, then gathered at `points`.
fn gathered(scene: &Scene, points: &[(DVec3, DVec3)]) -> Vec<Vec3> {
    let options = SolveOptions::default();
    let prepared = Prepared::new(scene, &options.mesh_settings());
    let mut solver = prepared.solver(options.solver_settings()).unwrap();
    solver.run(None, radiosity::cancel::never()).unwrap();
    solver.gatherer(options.gather_settings()).at_points(points)
}

/// Two 1 m squares, an emitter of radiance 1 with ρ = 0 and a receiver of ρ = 0.5, the
/// emitter `emitter` (corners), the receiver on y = 0 facing +y with x in ±0.5 and z in
/// `z0..z0 + 1`; both placed in the world by `frame`.
fn plates(name: &str, emitter: [[f32; 3]; 4], z0: f32, frame: DMat4) -> Scene {
    let receiver = quad_object(
        "receiver",
        frame,
        [
            [-0.5, 0.0, z0],
            [-0.5, 0.0, z0 + 1.0],
            [0.5, 0.0, z0 + 1.0],
            [0.5, 0.0, z0],
        ],
        0,
    );
    Scene {
        name: name.into(),
        objects: vec![receiver, quad_object("emitter", frame, emitter, 1)],
        materials: vec![
            Material::diffuse("receiver", Vec3::splat(RHO as f32)),
            Material::emitter("emitter", Vec3::ZERO, Vec3::ONE),
        ],
        lights: Vec::new(),
        environment: None,
        images: Vec::new(),
        warnings: Vec::new(),
    }
}

/// Receiver points (x, 0, z) facing +y, placed in the world by `frame`.
fn on_receiver(xz: Vec<(f64, f64)>, frame: DMat4) -> Vec<(DVec3, DVec3)> {
    xz.into_iter()
        .map(|(x, z)| (frame.transform_point3(DVec3::new(x, 0.0, z)), DVec3::Y))
        .collect()
}

/// Where the plates are put: at the origin, a kilometre away from it (the mesh keeps f32
/// coordinates relative to its own origin), and a thousand times smaller (form factors
/// depend on ratios of lengths only, so the closed forms are the same).
fn frames() -> [(&'static str, DMat4); 3] {
    [
        ("at the origin", DMat4::IDENTITY),
        (
            "1 km from the origin",
            DMat4::from_translation(DVec3::new(1000.0, 250.0, -1000.0)),
        ),
        ("at millimetre scale", DMat4::from_scale(DVec3::splat(1e-3))),
    ]
}

/// Largest relative error of the red channel of `got` against `exact` at the points'
/// positions in the plates' own frame.
fn worst(
    points: &[(DVec3, DVec3)],
    got: &[Vec3],
    frame: DMat4,
    exact: impl Fn(DVec3) -> f64,
) -> f64 {
    let local = frame.inverse();
    points
        .iter()
        .zip(got)
        .map(|((p, _), g)| {
            let e = exact(local.transform_point3(*p));
            let err = (g.x as f64 - e).abs() / e;
            if err > 1e-3 {
                eprintln!("  {p}: {} vs {e} ({err:.2e})", g.x);
            }
            err
        })
        .fold(0.0, f64::max)
}

#[test]
fn parallel_plates_are_exact_to_a_tenth_of_a_millimetre_from_the_edges() {
    // Receiver z in ±0.5; the emitter 0.5 m or 5 cm above it (the near field),
    // facing down; in each of the frames.
    for gap in [0.5f32, 0.05] {
        for (place, frame) in frames() {
            let scene = plates(
                "parallel plates",
                [
                    [-0.5, gap, -0.5],
                    [0.5, gap, -0.5],
                    [0.5, gap, 0.5],
                    [-0.5, gap, 0.5],
                ],
                -0.5,
                frame,
            );
            let mut pts = Vec::new();
            for d in [1e-4, 1e-3, 0.01, 0.1, 0.5] {
                let c = 0.5 - d;
                pts.extend([(c, 0.0), (0.0, c), (c, c), (-c, 0.3), (0.2, -c)]);
            }
            let pts = on_receiver(pts, frame);
            let got = gathered(&scene, &pts);
            // B = ρ π L F(x) exactly (the emitter is black, nothing else is there). The
            // gather sums exact point-to-polygon form factors of a uniform emitter with no
            // occluder: only f32 rounding is left, so 0.1 %, within the goal of
            // 0.5 %.
            let w = worst(&pts, &got, frame, |p| {
                RHO * PI * parallel_square(p.x, p.z, 0.5, gap as f64)
            });
            assert!(
                w < 1e-3,
                "gap {gap} m, {place}: worst relative error {w:.2e}"
            );
        }
    }
}

#[test]
fn perpendicular_plates_are_exact_to_a_tenth_of_a_millimetre_from_the_contact() {
    // Receiver z in 0..1; the emitter wall stands on its edge z = 0, facing +z.
    for (place, frame) in frames() {
        let scene = plates(
            "perpendicular plates",
            [
                [-0.5, 0.0, 0.0],
                [0.5, 0.0, 0.0],
                [0.5, 1.0, 0.0],
                [-0.5, 1.0, 0.0],
            ],
            0.0,
            frame,
        );
        let mut pts = Vec::new();
        for d in [1e-4, 1e-3, 0.01, 0.1, 0.5] {
            pts.extend([(0.0, d), (0.5 - 1e-3, d), (-0.3, d)]);
        }
        let pts = on_receiver(pts, frame);
        let got = gathered(&scene, &pts);
        // Howell's catalogue, the two rectangles left and right of the point; as above,
        // only rounding is left (0.1 %).
        let w = worst(&pts, &got, frame, |p| {
            RHO * PI
                * (perpendicular_rectangle_corner(1.0, 0.5 - p.x, p.z)
                    + perpendicular_rectangle_corner(1.0, p.x + 0.5, p.z))
        });
        assert!(w < 1e-3, "{place}: worst relative error {w:.2e}");
    }
}

#[test]
fn penumbra_scene_matches_the_closed_form_in_umbra_and_penumbra() {
    let scene = builtin::penumbra();
    let pts = penumbra_grid();
    let got = gathered(&scene, &pts);
    let exact: Vec<f64> = pts.iter().map(|(p, _)| penumbra_floor(p.x, p.z)).collect();
    let peak = exact.iter().copied().fold(0.0, f64::max);
    let (mut num, mut den, mut max) = (0.0, 0.0, 0.0f64);
    for ((g, e), (p, _)) in got.iter().zip(&exact).zip(&pts) {
        let d = g.x as f64 - e;
        num += d * d;
        den += e * e;
        max = max.max(d.abs() / peak);
        if d.abs() > 1e-2 * peak {
            eprintln!("  {p}: {} vs {e}", g.x);
        }
    }
    let rms = (num / den).sqrt();
    eprintln!("penumbra: RMS {rms:.2e}, worst {max:.2e} of the peak");
    // The floor's light comes straight from the emitter past the occluder (everything
    // else is black), so the gather's error is its visibility estimate alone: nodes split
    // while their shadow rays disagree and they carry more than δ = 0.05 % of the point's
    // light, and a node at the last level takes 16 strata; along a shadow boundary some 20
    // to 30 nodes stop splitting at that allowance. Measured: 0.13 % RMS, 0.99 % of the
    // peak at the worst point (1.7 % of its own value, in the penumbra). Bound: 0.5 % RMS
    // (the goal), 1.5 % of the peak at any point.
    assert!(rms < 5e-3 && max < 1.5e-2, "RMS {rms:.2e}, worst {max:.2e}");
}

#[test]
fn cornell_box_matches_the_path_traced_reference_at_every_class_of_point() {
    use radiosity::reference::Surfaces;
    use radiosity::reference::probes::{ProbeCounts, pick};
    let scene = builtin::cornell_box();
    let surfaces = Surfaces::new(&scene);
    let bvh = radiosity::accel::Bvh::build(&surfaces.triangles, &surfaces.transmittance);
    // A seed the bench does not use: points nobody tuned on.
    let counts = ProbeCounts {
        uniform: 20,
        near_edges: 20,
        penumbra: 10,
        umbra: 10,
    };
    let probes = pick(&surfaces, &bvh, &counts, 7);
    let points: Vec<(DVec3, DVec3)> = probes.iter().map(|p| (p.point, p.normal)).collect();
    let truth = common::path_traced(&scene, &points, 0.01);
    let got = gathered(&scene, &points);
    let mean = truth.iter().map(|t| t.value).sum::<DVec3>() / truth.len() as f64;
    let floor = mean * 0.02;
    let mut squares = 0.0;
    for ((g, t), p) in got.iter().zip(&truth).zip(&probes) {
        let scale = t.value.max(floor).length();
        let err = (g.as_dvec3() - t.value).length() / scale;
        let sigma = t.std_error.length() / scale;
        squares += err * err;
        // Measured on the bench's 299 points against a 1 % reference: 1.2 % RMS, 4.0 % at
        // the worst point (a block's side 0.1 mm above the floor); against a 0.4 %
        // reference at 300 other points, 0.9 % RMS and 2.7 % at worst. Bound per point: 3σ
        // of this reference plus 5 %.
        assert!(
            err <= 3.0 * sigma + 0.05,
            "{:?} at {} (normal {}): {g} vs {} ± {}",
            p.class,
            p.point,
            p.normal,
            t.value,
            t.std_error
        );
    }
    let rms = (squares / got.len() as f64).sqrt();
    eprintln!(
        "Cornell box: gather vs reference RMS {rms:.3e} over {} points",
        got.len()
    );
    // 0.9 % measured against a 0.4 % reference; this 1 % reference adds about 0.8 % in
    // quadrature (1.2 % measured against the bench's). Bound 2 %.
    assert!(rms <= 0.02, "RMS {rms}");
}

#[test]
fn the_sky_through_a_small_opening_is_gathered_at_the_point() {
    // A floor (ρ = 0.5) under a black ceiling 1 m above it with a 0.4 m square opening over
    // its centre, under a uniform sky of radiance L = 1. The floor sees the sky only
    // through the opening (the ceiling runs 100 m out: the sky past its edge is 10⁻⁴ of
    // the hemisphere), and nothing else sends light (the ceiling is black, the floor
    // flat), so B(x) = ρ π L F(x → opening), Howell's C-11 by superposition
    // (`parallel_square`). The opening is 4.7 % of the cosine-weighted hemisphere from the
    // centre: the 64 stratified rays an element takes hit it about 3 times, ±1 hit being
    // ±30 % (Sponza's galleries see their sky so; with 64 rays at the point, its interior
    // probe points were 33 % RMS off the path-traced truth, 6.3 % with 1024). The point
    // takes 1024 rays (about 48 hits; only the ~30 strata the opening's edges cross are
    // uncertain, each by under half a hit: about 5 % at one standard deviation, 6.1 % RMS
    // measured): each of 9 points within 15 %, their RMS within 10 % (with 64 rays at the
    // point: 27 % RMS, the worst point 35 % off).
    let h = 0.2f32;
    let scene = common::opening(RHO as f32, h);
    let xz: Vec<(f64, f64)> = (0..9)
        .map(|k| {
            (
                0.15 * (k % 3) as f64 - 0.15 + 0.013,
                0.15 * (k / 3) as f64 - 0.15 + 0.007,
            )
        })
        .collect();
    let points = on_receiver(xz.clone(), DMat4::IDENTITY);
    let got = gathered(&scene, &points);
    let mut sum = 0.0;
    for ((x, z), b) in xz.iter().zip(&got) {
        let want = RHO * PI * parallel_square(*x, *z, h as f64, 1.0);
        let e = (b.x as f64 - want).abs() / want;
        sum += e * e;
        assert!(e < 0.15, "({x}, {z}): B = {}, the closed form {want}", b.x);
    }
    let rms = (sum / xz.len() as f64).sqrt();
    assert!(rms < 0.1, "RMS {rms}");
}
