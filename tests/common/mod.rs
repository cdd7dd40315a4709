//! Helpers shared by the integration tests: scene pieces built in code, the usual
//! preparation and solve, the area-weighted RMS difference, the point-to-polygon form factor
//! and its rounding, scratch folders and the test-scene corpus.
//!
//! Every test file that uses them declares `mod common;` and so compiles its own copy of
//! this module, using only some of it. Each item therefore carries `#[allow(dead_code)]`:
//! an item is unused in some test binaries and used in others, and the lint, which looks at
//! one binary at a time, cannot tell.

use glam::{DMat4, DVec3, Vec3};
use radiosity::analytic::parallel_square;
use radiosity::mesh::{Mesh, MeshSettings, Reconstruction};
use radiosity::pipeline::{Prepared, probe_values};
use radiosity::scene::{Object, Scene};
use radiosity::solver::form_factor::point_to_polygon;
use radiosity::solver::{HierarchySettings, Method, Solver, SolverSettings, StepOutcome};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

/// Corner (i, j) of a unit sphere cut into `rings` bands of 2 `rings` facets: polar angle
/// π i / `rings` from the north pole (+y), azimuth 2π j / (2 `rings`).
#[allow(dead_code)]
pub fn sphere_corner(rings: u32, i: u32, j: u32) -> DVec3 {
    let segments = 2 * rings;
    let (theta, phi) = (
        std::f64::consts::PI * i as f64 / rings as f64,
        2.0 * std::f64::consts::PI * (j % segments) as f64 / segments as f64,
    );
    DVec3::new(
        theta.sin() * phi.cos(),
        theta.cos(),
        theta.sin() * phi.sin(),
    )
}

/// The facets of that sphere, band by band: (band i, quad j of the band, its corners), two
/// per quad, one in the bands at the poles, which are fans (one corner of each quad is the
/// pole twice). The winding is whichever the quad gives; callers orient them.
#[allow(dead_code)]
pub fn sphere_facets(rings: u32) -> Vec<(u32, u32, [DVec3; 3])> {
    let at = |i, j| sphere_corner(rings, i, j);
    let mut facets = Vec::new();
    for i in 0..rings {
        for j in 0..2 * rings {
            let quad = [at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j)];
            let triangles: &[[usize; 3]] = match i {
                0 => &[[0, 2, 3]],
                _ if i == rings - 1 => &[[0, 1, 2]],
                _ => &[[0, 1, 2], [0, 2, 3]],
            };
            for t in triangles {
                facets.push((i, j, t.map(|k| quad[k])));
            }
        }
    }
    facets
}

/// Appends the quad `v` (two triangles, the winding of `v`) with `material` to `o`.
#[allow(dead_code)]
pub fn quad(o: &mut Object, v: [[f32; 3]; 4], material: u32) {
    let base = o.positions.len() as u32;
    o.positions.extend(v.iter().map(|p| Vec3::from(*p)));
    o.triangles.push([base, base + 1, base + 2]);
    o.triangles.push([base, base + 2, base + 3]);
    o.triangle_material.extend([material, material]);
}

/// An object named `name`, placed by `world_from_local`, that is the one quad `v` (two
/// triangles, the winding of `v`: counter-clockwise seen from the side it faces) of
/// `material`.
#[allow(dead_code)]
pub fn quad_object(name: &str, world_from_local: DMat4, v: [[f32; 3]; 4], material: u32) -> Object {
    let mut o = Object {
        name: name.into(),
        world_from_local,
        ..Default::default()
    };
    quad(&mut o, v, material);
    o
}

/// A 2 m square floor at y = 0 facing +y (counter-clockwise seen from above), of material
/// 0, placed by `world_from_local`.
#[allow(dead_code)]
pub fn floor(world_from_local: DMat4) -> Object {
    quad_object(
        "floor",
        world_from_local,
        [
            [-1.0, 0.0, -1.0],
            [-1.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 0.0, -1.0],
        ],
        0,
    )
}

/// A 1 m square floor (one quad, material 0 of reflectance `rho`, facing +y) under a black
/// ceiling 1 m above it with a square opening of half-side `half` over its centre, under a
/// uniform sky of radiance L = 1. The ceiling runs 100 m out, so the sky past its edge is
/// 10⁻⁴ of the hemisphere: the floor sees the sky only through the opening, and nothing
/// else sends it light, so its irradiance is π L F(x → opening) (Howell's C-11 by
/// superposition, `analytic::parallel_square`).
#[allow(dead_code)]
pub fn opening(rho: f32, half: f32) -> Scene {
    let far = 100.0f32;
    let ceiling = |x0: f32, x1: f32, z0: f32, z1: f32| {
        quad_object(
            "ceiling",
            DMat4::IDENTITY,
            [[x0, 1.0, z0], [x1, 1.0, z0], [x1, 1.0, z1], [x0, 1.0, z1]],
            1,
        )
    };
    Scene {
        name: "opening".into(),
        objects: vec![
            quad_object(
                "floor",
                DMat4::IDENTITY,
                [
                    [-0.5, 0.0, -0.5],
                    [-0.5, 0.0, 0.5],
                    [0.5, 0.0, 0.5],
                    [0.5, 0.0, -0.5],
                ],
                0,
            ),
            ceiling(-far, far, half, far),
            ceiling(-far, far, -far, -half),
            ceiling(-far, -half, -half, half),
            ceiling(half, far, -half, half),
        ],
        materials: vec![
            radiosity::scene::Material::diffuse("floor", Vec3::splat(rho)),
            radiosity::scene::Material::diffuse("ceiling", Vec3::ZERO),
        ],
        lights: Vec::new(),
        environment: Some(radiosity::scene::Environment {
            sky: Vec3::ONE,
            sun: None,
        }),
        images: Vec::new(),
        warnings: Vec::new(),
    }
}

/// Points (x, z) of the floor of [`opening`] on a 10 × 10 grid over its middle 0.8 m, off
/// the grid's symmetry.
#[allow(dead_code)]
pub fn opening_points() -> Vec<(f64, f64)> {
    (0..100)
        .map(|k| {
            (
                -0.4 + 0.08 * (k % 10) as f64 + 0.013,
                -0.4 + 0.08 * (k / 10) as f64 + 0.007,
            )
        })
        .collect()
}

/// `scene` (a variant of [`opening`]) meshed from its input triangles and solved with the
/// hierarchical method down to 2 cm leaves, converged.
#[allow(dead_code)]
pub fn opening_solved(scene: &Scene) -> Solver {
    let p = prepared(scene, 10);
    let mut s = p
        .solver(SolverSettings {
            method: Method::Hierarchical,
            hierarchy: HierarchySettings {
                min_size: Some(0.02),
                ..Default::default()
            },
            ..Default::default()
        })
        .unwrap();
    converge(&mut s);
    s
}

/// The relative RMS error of the viewer's Gouraud light at [`opening_points`] against the
/// closed form ρ π L F(x → opening) (L = 1) of [`opening`] with floor reflectance `rho`
/// and opening half-side `half`.
#[allow(dead_code)]
pub fn opening_gouraud_rms(s: &Solver, rho: f64, half: f32) -> f64 {
    let xz = opening_points();
    let points: Vec<(DVec3, DVec3)> = xz
        .iter()
        .map(|&(x, z)| (DVec3::new(x, 0.0, z), DVec3::Y))
        .collect();
    let got = probe_values(s.mesh(), &s.radiosity(), &points, Reconstruction::Gouraud);
    let mut sum = 0.0;
    for ((x, z), b) in xz.iter().zip(&got) {
        let want = rho * std::f64::consts::PI * parallel_square(*x, *z, half as f64, 1.0);
        let e = (b.x as f64 - want) / want;
        sum += e * e;
    }
    (sum / xz.len() as f64).sqrt()
}

/// The leaves of the floor (material 0) of [`opening`].
#[allow(dead_code)]
pub fn floor_leaves(mesh: &Mesh) -> usize {
    mesh.elements
        .iter()
        .filter(|e| mesh.patches[e.patch as usize].material == 0)
        .count()
}

/// `scene` meshed with the default settings but at most `max_elements` elements.
#[allow(dead_code)]
pub fn prepared(scene: &Scene, max_elements: usize) -> Prepared {
    Prepared::new(
        scene,
        &MeshSettings {
            max_elements: Some(max_elements),
            ..Default::default()
        },
    )
}

/// The default solver settings with `method`, stopping at `tolerance`.
#[allow(dead_code)]
pub fn settings(method: Method, tolerance: f64) -> SolverSettings {
    SolverSettings {
        method,
        tolerance,
        ..Default::default()
    }
}

/// Runs `s` to the end and fails the test unless it converged (rather than being
/// cancelled or stopped).
#[allow(dead_code)]
pub fn converge(s: &mut Solver) {
    assert_eq!(
        s.run(None, &AtomicBool::new(false)).unwrap(),
        StepOutcome::Converged
    );
}

/// Area-weighted relative RMS difference of the per-element values `a` from the reference
/// `b` on `mesh`: √(Σ Aᵢ |aᵢ − bᵢ|² / Σ Aᵢ |bᵢ|²).
#[allow(dead_code)]
pub fn rms(a: &[Vec3], b: &[Vec3], mesh: &Mesh) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for ((x, y), e) in a.iter().zip(b).zip(&mesh.elements) {
        num += (*x - *y).as_dvec3().length_squared() * e.area as f64;
        den += y.as_dvec3().length_squared() * e.area as f64;
    }
    (num / den).sqrt()
}

/// Relative error of one f32 form factor plus f64 summation: a few ulps of f32 per value,
/// and sums of a few hundred such values in f64 stay within 1e-6 relative. On top of it,
/// each `point_to_polygon` carries the absolute error [`contour_slack`] of its f32 contour
/// terms.
#[allow(dead_code)]
pub const F32_REL: f64 = 1e-6;

/// The absolute error bound of one f32 `point_to_polygon` (see its doc): its contour terms
/// are each at most γ_k (the angle edge k subtends at `p`) with a few f32 ulps of relative
/// error, so the sum is off by at most 10⁻⁶ · Σ_k γ_k / 2π. Computed here in f64 with
/// libm's atan2.
#[allow(dead_code)]
pub fn contour_slack(p: Vec3, poly: &[Vec3]) -> f64 {
    let rel: Vec<glam::DVec3> = poly.iter().map(|v| (*v - p).as_dvec3()).collect();
    let angles: f64 = (0..rel.len())
        .map(|k| {
            let (a, b) = (rel[k], rel[(k + 1) % rel.len()]);
            a.cross(b).length().atan2(a.dot(b))
        })
        .sum();
    1e-6 * angles / std::f64::consts::TAU
}

/// The form factor from a point `p` with normal `n` to the polygon `poly`
/// (`point_to_polygon`, Lambert's contour integral), as f64.
#[allow(dead_code)]
pub fn ptp(p: Vec3, n: Vec3, poly: &[Vec3]) -> f64 {
    point_to_polygon(p, n, poly) as f64
}

/// An empty scratch folder for one test: `name` under the system's temporary folder,
/// qualified by this process's id (so concurrent runs do not meet), emptied if a
/// previous run left it.
#[allow(dead_code)]
pub fn scratch_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("radiosity-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The test-scene corpus `../shared/scenes` beside the repository (see its CATALOGUE.md
/// and VALIDATION.tsv). When it is missing: `None`, with a note on stderr, so that the test
/// can skip; but under CI (the `CI` environment variable set, to any value) the test fails
/// instead, so that a CI run without the corpus cannot pass by skipping.
#[allow(dead_code)]
pub fn shared_scenes() -> Option<PathBuf> {
    let ci = std::env::var_os("CI").is_some();
    scenes_at(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes"),
        ci,
    )
}

/// [`shared_scenes`] for the corpus folder `dir`: `Some(dir)` if it holds VALIDATION.tsv;
/// otherwise a panic if `ci`, else `None` with a note on stderr.
#[allow(dead_code)]
pub fn scenes_at(dir: &Path, ci: bool) -> Option<PathBuf> {
    if dir.join("VALIDATION.tsv").is_file() {
        Some(dir.to_path_buf())
    } else if ci {
        panic!(
            "the test scenes are not at {} and CI is set: under CI a test that needs them \
             fails instead of skipping (unset CI to skip)",
            dir.display()
        );
    } else {
        eprintln!("skipped: the test scenes are not at {}", dir.display());
        None
    }
}

/// The built-in path-traced reference at `points` (world position, normal), to `rel_error`
/// standard error relative to max(B, 2 % of the mean B), with the default seed: the
/// unbiased truth the solvers are held to.
#[allow(dead_code)]
pub fn path_traced(
    scene: &Scene,
    points: &[(DVec3, DVec3)],
    rel_error: f64,
) -> Vec<radiosity::reference::Estimate> {
    let settings = radiosity::reference::ReferenceSettings {
        rel_error,
        ..Default::default()
    };
    radiosity::reference::estimate(
        scene,
        points,
        &settings,
        &|_, _, _| {},
        radiosity::cancel::never(),
    )
    .unwrap()
}
