//! Parallel plates against a closed form (issue 4, item 6): a black square emitter of
//! radiance L facing a square receiver of reflectance ρ, nothing else. The receiver's
//! radiosity is exactly ρ·π·L·F(x), with F the form factor from a point to a parallel
//! rectangle, Howell's catalogue C-11 (a point under one corner of an a×b rectangle at
//! height c: F = 1/2π [X/√(1+X²)·atan(Y/√(1+X²)) + Y/√(1+Y²)·atan(X/√(1+Y²))], X = a/c,
//! Y = b/c), summed over four corner rectangles with signs. Independent of our own
//! Lambert contour integral.

use glam::{DMat4, DVec3, Vec3};
use radiosity::cli::probe_values;
use radiosity::mesh::{MeshSettings, Reconstruction};
use radiosity::pipeline::Prepared;
use radiosity::scene::{Material, Object, Scene};
use radiosity::solver::{Method, SolverSettings};
use std::f64::consts::PI;
use std::sync::atomic::AtomicBool;

const HALF: f64 = 0.5; // both plates 1 m × 1 m
const GAP: f64 = 0.5; // 0.5 m apart
const RHO: f64 = 0.5;

fn corner(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a.abs() / c, b.abs() / c);
    let f = (x / (1.0 + x * x).sqrt() * (y / (1.0 + x * x).sqrt()).atan()
        + y / (1.0 + y * y).sqrt() * (x / (1.0 + y * y).sqrt()).atan())
        / (2.0 * PI);
    f * a.signum() * b.signum()
}

fn exact(px: f64, pz: f64) -> f64 {
    let f = corner(HALF - px, HALF - pz, GAP)
        - corner(-HALF - px, HALF - pz, GAP)
        - corner(HALF - px, -HALF - pz, GAP)
        + corner(-HALF - px, -HALF - pz, GAP);
    RHO * PI * f
}

fn scene() -> Scene {
    let h = HALF as f32;
    let y = GAP as f32;
    let mut receiver = Object {
        name: "receiver".into(),
        world_from_local: DMat4::IDENTITY,
        ..Default::default()
    };
    receiver.positions = vec![
        Vec3::new(-h, 0.0, -h),
        Vec3::new(-h, 0.0, h),
        Vec3::new(h, 0.0, h),
        Vec3::new(h, 0.0, -h),
    ];
    receiver.triangles = vec![[0, 1, 2], [0, 2, 3]]; // facing +y
    receiver.triangle_material = vec![0, 0];
    let mut emitter = Object {
        name: "emitter".into(),
        world_from_local: DMat4::IDENTITY,
        ..Default::default()
    };
    emitter.positions = vec![
        Vec3::new(-h, y, -h),
        Vec3::new(-h, y, h),
        Vec3::new(h, y, h),
        Vec3::new(h, y, -h),
    ];
    emitter.triangles = vec![[0, 2, 1], [0, 3, 2]]; // facing −y
    emitter.triangle_material = vec![1, 1];
    Scene {
        name: "parallel plates".into(),
        objects: vec![receiver, emitter],
        materials: vec![
            Material::diffuse("receiver", Vec3::splat(RHO as f32)),
            Material::emitter("emitter", Vec3::ZERO, Vec3::ONE),
        ],
        lights: Vec::new(),
        environment: None,
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
    let p = Prepared::new(
        &scene(),
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
    let mut pts = Vec::new();
    for i in 0..11 {
        for k in 0..11 {
            let x = -0.45 + 0.09 * i as f64;
            let z = -0.45 + 0.09 * k as f64;
            pts.push((DVec3::new(x, 0.0, z), DVec3::Y));
        }
    }
    for mode in [
        Reconstruction::Flat,
        Reconstruction::Gouraud,
        Reconstruction::Hermite,
    ] {
        let got = probe_values(s.mesh(), &s.radiosity(), &pts, mode);
        let worst = pts
            .iter()
            .zip(&got)
            .map(|((p, _), g)| ((g.x as f64 - exact(p.x, p.z)) / exact(p.x, p.z)).abs())
            .fold(0.0, f64::max);
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
