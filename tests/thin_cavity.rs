//! A thin cavity of reflectance near 1: a square lamp under a ceiling 27 cm above it, both
//! of ρ = 0.999, the shape of `cornell-box-nvpro`'s lamp under its ceiling. Light leaves
//! only past the lamp's edges, so its centre comes to about seven times what it emits;
//! every per cent of transfer lost or gained between the plates moves that by about eight
//! per cent (B ≈ E / (1 − ρ² F²) with F ≈ 0.9 between the plates there), and the kernel
//! varies over a few centimetres, so both the links and the gather must follow the near
//! field.
//!
//! The truth is an independent random walk: from a point x on the lamp, B(x) = E +
//! E Σ_k ρ^k P(the walk is on the lamp after k bounces), with each bounce a cosine-
//! distributed direction from a plane to the other, and a walk that misses the other plate
//! leaving for good (nothing else is there). The same cavity a kilometre from the origin
//! and a thousand times smaller must come out the same.

mod common;
use glam::{DMat4, DVec3, Vec3};
use radiosity::cli::SolveOptions;
use radiosity::mesh::Reconstruction;
use radiosity::pipeline::{Prepared, probe_values};
use radiosity::scene::{Material, Object, Scene};

const RHO: f64 = 0.999;
const GAP: f64 = 0.274;
const LAMP_HALF: f64 = 1.5;
const CEILING_HALF: f64 = 5.0;
/// The lamp's emitted radiance, W/(m²·sr); E = π L.
const RADIANCE: f64 = 1.0;

/// The cavity placed in the world by `world_from_local`.
fn scene(world_from_local: DMat4) -> Scene {
    let mut lamp = Material::emitter(
        "lamp",
        Vec3::splat(RHO as f32),
        Vec3::splat(RADIANCE as f32),
    );
    lamp.double_sided = false;
    let white = Material::diffuse("ceiling", Vec3::splat(RHO as f32));
    let mut o = Object {
        name: "plates".into(),
        world_from_local,
        ..Default::default()
    };
    let (l, c, g) = (LAMP_HALF as f32, CEILING_HALF as f32, GAP as f32);
    // The lamp facing +y, the ceiling facing −y (counter-clockwise seen from the front).
    common::quad(
        &mut o,
        [[-l, 0.0, -l], [-l, 0.0, l], [l, 0.0, l], [l, 0.0, -l]],
        0,
    );
    common::quad(&mut o, [[-c, g, -c], [c, g, -c], [c, g, c], [-c, g, c]], 1);
    Scene {
        name: "thin cavity".into(),
        objects: vec![o],
        materials: vec![lamp, white],
        ..Default::default()
    }
}

/// A small deterministic generator (SplitMix64) for the walk.
struct Walk(u64);

impl Walk {
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The random walk's B at the lamp point (x, z), and its standard error.
fn walked(x: f64, z: f64, walks: u32, seed: u64) -> (f64, f64) {
    let e = std::f64::consts::PI * RADIANCE;
    let mut rng = Walk(seed);
    let (mut sum, mut sum2) = (0.0, 0.0);
    for _ in 0..walks {
        let (mut px, mut pz) = (x, z);
        let mut on_lamp = true;
        let mut weight = 1.0;
        let mut got = 0.0;
        loop {
            // A cosine-distributed direction: its horizontal part has length √u.
            let (u, v) = (rng.unit(), rng.unit());
            let r = u.sqrt();
            let phi = 2.0 * std::f64::consts::PI * v;
            let t = GAP / (1.0 - u).sqrt();
            px += r * phi.cos() * t;
            pz += r * phi.sin() * t;
            let half = if on_lamp { CEILING_HALF } else { LAMP_HALF };
            if px.abs() >= half || pz.abs() >= half {
                break;
            }
            on_lamp = !on_lamp;
            weight *= RHO;
            if on_lamp {
                got += weight * e;
            }
        }
        sum += got;
        sum2 += got * got;
    }
    let n = walks as f64;
    let mean = sum / n;
    let var = (sum2 / n - mean * mean).max(0.0);
    (e + mean, (var / n).sqrt())
}

/// The cavity placed by `world_from_local` (a similarity): the gather and the Hermite
/// picture at four lamp points against the walk, which is the same at any place and scale
/// (the radiosity of a scaled scene is the same at matching points).
fn check(world_from_local: DMat4) {
    let up = world_from_local.transform_vector3(DVec3::Y);
    let scale = up.length();
    let scene = scene(world_from_local);
    let options = SolveOptions::default();
    let prepared = Prepared::new(&scene, &options.mesh_settings());
    let mut solver = prepared.solver(options.solver_settings()).unwrap();
    solver.run(None, radiosity::cancel::never()).unwrap();
    // The centre, two points between it and the edge, and one 10 cm from a corner.
    let at = [(0.0, 0.0), (-0.15, 0.69), (0.8, 1.04), (1.4, 1.4)];
    let points: Vec<(DVec3, DVec3)> = at
        .iter()
        .map(|(x, z)| {
            let p = world_from_local.transform_point3(DVec3::new(*x, 0.0, *z));
            (p, up / scale)
        })
        .collect();
    let gathered = solver
        .gatherer(options.gather_settings())
        .at_points(&points);
    let radiosity: Vec<Vec3> = solver.radiosity();
    let hermite = probe_values(solver.mesh(), &radiosity, &points, Reconstruction::Hermite);
    // 3 %: the walk's standard error is under 0.3 %, and the cavity multiplies a transfer
    // error by about 8 (above), so this holds the transfer between the plates to about
    // 0.35 %. Measured at the origin: the gather 1.6, 1.2, 0.8 and 0.2 % under the walk,
    // the Hermite picture 1.4, 0.8, 0.8 and 0.2 % (the default settings, 2026-12-07);
    // 1 km away and at millimetre scale the same to the digits printed.
    for (i, (x, z)) in at.iter().enumerate() {
        let (truth, error) = walked(*x, *z, 200_000, 17 + i as u64);
        assert!(
            error < 0.004 * truth,
            "the walk's error {error} at ({x}, {z})"
        );
        for (what, got) in [("gather", gathered[i]), ("Hermite", hermite[i])] {
            let got = got.x as f64;
            println!("scale {scale}, ({x}, {z}): walk {truth:.3} ± {error:.3}, {what} {got:.3}");
            assert!(
                (got / truth - 1.0).abs() < 0.03,
                "{what} at ({x}, {z}), scale {scale}: {got} against the walk's {truth} ± {error}"
            );
        }
    }
}

#[test]
fn a_thin_cavity_of_reflectance_0999_matches_a_random_walk() {
    check(DMat4::IDENTITY);
}

#[test]
fn the_thin_cavity_a_kilometre_from_the_origin_and_at_millimetre_scale() {
    check(DMat4::from_translation(DVec3::new(1000.0, -2000.0, 500.0)));
    check(
        DMat4::from_translation(DVec3::new(0.003, 0.001, -0.002))
            * DMat4::from_scale(DVec3::splat(0.001)),
    );
}
