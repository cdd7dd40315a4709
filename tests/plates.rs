//! Parallel and perpendicular plates against closed forms.
//!
//! Parallel: a black square emitter of
//! radiance L facing a square receiver of reflectance ρ, nothing else. The receiver's
//! radiosity is exactly ρ·π·L·F(x), with F the form factor from a point to a parallel
//! rectangle, Howell's catalogue C-11 (a point under one corner of an a×b rectangle at
//! height c: F = 1/2π [X/√(1+X²)·atan(Y/√(1+X²)) + Y/√(1+Y²)·atan(X/√(1+Y²))], X = a/c,
//! Y = b/c), summed over four corner rectangles with signs. Independent of our own
//! Lambert contour integral.
//!
//! Perpendicular: a black square emitter standing on the receiver's edge (a wall on a
//! floor, touching along the shared edge): F from a floor point to a perpendicular
//! rectangle whose bottom edge lies in the floor's plane, Howell's catalogue (plane element
//! to a perpendicular rectangle, the element on the normal through one corner: F = 1/2π
//! [atan(1/Y) − Y/√(X²+Y²)·atan(1/√(X²+Y²))], X = height/width, Y = distance/width),
//! summed over the two rectangles left and right of the point; checked here against
//! brute-force quadrature as well.

mod common;
use common::quad_object;
use glam::{DMat4, DVec3, Vec3};
use radiosity::analytic::{parallel_square, perpendicular_rectangle_corner};
use radiosity::mesh::{MeshSettings, Reconstruction};
use radiosity::pipeline::Prepared;
use radiosity::pipeline::probe_values;
use radiosity::scene::{Material, Scene};
use radiosity::solver::{Method, SolverSettings};
use std::f64::consts::PI;
use std::sync::atomic::AtomicBool;

const HALF: f64 = 0.5; // both plates 1 m × 1 m
const GAP: f64 = 0.5; // 0.5 m apart
const RHO: f64 = 0.5;

fn exact(px: f64, pz: f64) -> f64 {
    RHO * PI * parallel_square(px, pz, HALF, GAP)
}

/// Solves `scene` with 0.05 m elements and returns the worst relative error against
/// `exact` over `pts` (receiver points, normal +y) for flat, Gouraud and Hermite.
fn worst_errors(
    scene: &Scene,
    pts: &[(DVec3, DVec3)],
    exact: impl Fn(f64, f64) -> f64,
) -> Vec<(Reconstruction, f64)> {
    let p = Prepared::new(
        scene,
        &MeshSettings {
            element_size: Some(0.05),
            ..Default::default()
        },
    );
    let mut s = p
        .solver(SolverSettings {
            method: Method::GaussSeidel,
            tolerance: 1e-6,
            ..Default::default()
        })
        .unwrap();
    s.run(None, &AtomicBool::new(false)).unwrap();
    [
        Reconstruction::Flat,
        Reconstruction::Gouraud,
        Reconstruction::Hermite,
    ]
    .into_iter()
    .map(|mode| {
        let got = probe_values(s.mesh(), &s.radiosity(), pts, mode);
        let worst = pts
            .iter()
            .zip(&got)
            .map(|((p, _), g)| {
                let e = exact(p.x, p.z);
                ((g.x as f64 - e) / e).abs()
            })
            .fold(0.0, f64::max);
        (mode, worst)
    })
    .collect()
}

fn scene() -> Scene {
    let h = HALF as f32;
    let y = GAP as f32;
    // The receiver faces +y, the emitter −y.
    let receiver = quad_object(
        "receiver",
        DMat4::IDENTITY,
        [[-h, 0.0, -h], [-h, 0.0, h], [h, 0.0, h], [h, 0.0, -h]],
        0,
    );
    let emitter = quad_object(
        "emitter",
        DMat4::IDENTITY,
        [[-h, y, -h], [h, y, -h], [h, y, h], [-h, y, h]],
        1,
    );
    Scene {
        name: "parallel plates".into(),
        objects: vec![receiver, emitter],
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

#[test]
fn catalogue_and_contour_integral_agree() {
    // Two independent exact forms: Howell C-11 by superposition here, Lambert's contour
    // integral in the solver (`point_to_polygon`). They must agree to f32 rounding.
    let h = HALF as f32;
    let y = GAP as f32;
    let poly = [
        Vec3::new(-h, y, -h),
        Vec3::new(h, y, -h),
        Vec3::new(h, y, h),
        Vec3::new(-h, y, h),
    ];
    for (x, z) in [
        (0.0, 0.0),
        (0.3, -0.2),
        (-0.45, 0.45),
        (0.7, 0.1),
        (1.5, -1.0),
    ] {
        let contour = radiosity::solver::form_factor::point_to_polygon(
            Vec3::new(x as f32, 0.0, z as f32),
            Vec3::Y,
            &poly,
        ) as f64;
        let catalogue = exact(x, z) / (RHO * PI);
        assert!(
            (contour - catalogue).abs() < 1e-6,
            "({x}, {z}): contour {contour} vs catalogue {catalogue}"
        );
    }
}

#[test]
fn receiver_radiosity_matches_the_closed_form() {
    let mut pts = Vec::new();
    for i in 0..11 {
        for k in 0..11 {
            let x = -0.45 + 0.09 * i as f64;
            let z = -0.45 + 0.09 * k as f64;
            pts.push((DVec3::new(x, 0.0, z), DVec3::Y));
        }
    }
    for (mode, worst) in worst_errors(&scene(), &pts, exact) {
        println!("{mode:?}: worst relative error {worst:.4}");
        // 0.05 m elements on a field whose relative slope is at most ~1.5 /m: a flat
        // element is off by up to ~half its width × slope ≈ 4 %; the interpolating
        // reconstructions do much better. Form-factor rays: none (nothing occludes).
        let bound = if mode == Reconstruction::Flat {
            0.05
        } else {
            0.01
        };
        assert!(worst < bound, "{mode:?}: worst relative error {worst}");
    }
}

// Perpendicular plates: a 1 m × 1 m floor (x in ±0.5, z in 0..1) facing +y, and a 1 m × 1 m
// emitter wall at z = 0 (x in ±0.5, y in 0..1) facing +z, touching the floor along z = 0.
const WALL: f64 = 1.0;

fn exact_perpendicular(px: f64, pz: f64) -> f64 {
    let f = perpendicular_rectangle_corner(WALL, HALF - px, pz)
        + perpendicular_rectangle_corner(WALL, px + HALF, pz);
    RHO * PI * f
}

fn perpendicular_scene() -> Scene {
    let h = HALF as f32;
    let w = WALL as f32;
    // The floor faces +y, the wall +z.
    let floor = quad_object(
        "floor",
        DMat4::IDENTITY,
        [[-h, 0.0, 0.0], [-h, 0.0, w], [h, 0.0, w], [h, 0.0, 0.0]],
        0,
    );
    let wall = quad_object(
        "wall",
        DMat4::IDENTITY,
        [[-h, 0.0, 0.0], [h, 0.0, 0.0], [h, w, 0.0], [-h, w, 0.0]],
        1,
    );
    Scene {
        name: "perpendicular plates".into(),
        objects: vec![floor, wall],
        materials: vec![
            Material::diffuse("floor", Vec3::splat(RHO as f32)),
            Material::emitter("wall", Vec3::ZERO, Vec3::ONE),
        ],
        lights: Vec::new(),
        environment: None,
        images: Vec::new(),
        warnings: Vec::new(),
    }
}

#[test]
fn perpendicular_catalogue_agrees_with_quadrature() {
    // Midpoint quadrature of cos θ1 cos θ2 / (π r²) over the wall, 400 × 400 cells, at
    // points away from the shared edge (where the kernel is smooth): agreement to 1e-4.
    for (px, pz) in [(0.0, 0.5), (0.3, 0.2), (-0.4, 0.8), (0.45, 0.35)] {
        let n = 400;
        let mut f = 0.0;
        for i in 0..n {
            let x = -HALF + (i as f64 + 0.5) / n as f64 * 2.0 * HALF;
            for j in 0..n {
                let y = (j as f64 + 0.5) / n as f64 * WALL;
                let d = DVec3::new(x - px, y, -pz);
                let r2 = d.length_squared();
                let cos1 = y / r2.sqrt();
                let cos2 = pz / r2.sqrt();
                f += cos1 * cos2 / (PI * r2);
            }
        }
        f *= 2.0 * HALF * WALL / (n * n) as f64;
        let catalogue = exact_perpendicular(px, pz) / (RHO * PI);
        assert!(
            (f - catalogue).abs() < 1e-4,
            "({px}, {pz}): quadrature {f} vs catalogue {catalogue}"
        );
    }
}

#[test]
fn perpendicular_receiver_matches_the_closed_form() {
    let mut pts = Vec::new();
    for i in 0..11 {
        for k in 0..10 {
            let x = -0.45 + 0.09 * i as f64;
            let z = 0.1 + 0.09 * k as f64;
            pts.push((DVec3::new(x, 0.0, z), DVec3::Y));
        }
    }
    for (mode, worst) in worst_errors(&perpendicular_scene(), &pts, exact_perpendicular) {
        println!("perpendicular, {mode:?}: worst relative error {worst:.4}");
        // Worst at (0.45, 0.1), beside the wall's end: relative slope 3.2 /m, relative
        // curvature 35 /m² (finite differences of the closed form). A flat 0.05 m element
        // is off by up to the slope × the ~0.025 m from its centroid, 8 %; linear
        // reconstruction by about h²/8 × curvature, 1.1 %; the cubic one no more.
        let bound = match mode {
            Reconstruction::Flat => 0.08,
            Reconstruction::Gouraud => 0.011,
            Reconstruction::Hermite => 0.011,
        };
        assert!(worst < bound, "{mode:?}: worst relative error {worst}");
    }
}
