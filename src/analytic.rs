//! Closed-form answers for the analytic test scenes, used by tests and the mesh study.

use crate::scene::builtin::{
    PENUMBRA_LIGHT, PENUMBRA_LIGHT_Y, PENUMBRA_OCCLUDER, PENUMBRA_OCCLUDER_X, PENUMBRA_OCCLUDER_Y,
    PENUMBRA_OCCLUDER_Z, PENUMBRA_RHO,
};
use crate::solver::form_factor::point_to_polygon;
use glam::{DVec3, Vec3};

/// The exact floor radiosity B (W/m², every channel) of `builtin:penumbra` at floor point
/// (`x`, 0, `z`): ρ · π L · F to the visible part of the emitter. Seen from the point, the
/// occluder's shadow on the emitter's plane is the occluder scaled about the point by
/// H_light / H_occluder (central projection between parallel planes), an axis-aligned
/// square; the emitter minus it is at most four rectangles, whose exact point-to-polygon
/// form factors (Lambert) add up.
pub fn penumbra_floor(x: f64, z: f64) -> f64 {
    let k = PENUMBRA_LIGHT_Y / PENUMBRA_OCCLUDER_Y;
    let shadow = |c: f64, p: f64| {
        (
            p + (c - PENUMBRA_OCCLUDER - p) * k,
            p + (c + PENUMBRA_OCCLUDER - p) * k,
        )
    };
    let (sx0, sx1) = shadow(PENUMBRA_OCCLUDER_X, x);
    let (sz0, sz1) = shadow(PENUMBRA_OCCLUDER_Z, z);
    let (a0, a1) = (-PENUMBRA_LIGHT, PENUMBRA_LIGHT);
    // The shadow clipped to the emitter.
    let (ix0, ix1) = (sx0.max(a0), sx1.min(a1));
    let (iz0, iz1) = (sz0.max(a0), sz1.min(a1));
    let mut rects: Vec<[f64; 4]> = Vec::new();
    if ix0 >= ix1 || iz0 >= iz1 {
        rects.push([a0, a1, a0, a1]);
    } else {
        rects.push([a0, ix0, a0, a1]);
        rects.push([ix1, a1, a0, a1]);
        rects.push([ix0, ix1, a0, iz0]);
        rects.push([ix0, ix1, iz1, a1]);
    }
    let p = DVec3::new(x, 0.0, z).as_vec3();
    let f: f64 = rects
        .iter()
        .filter(|r| r[1] > r[0] && r[3] > r[2])
        .map(|r| {
            let y = PENUMBRA_LIGHT_Y;
            let poly = [
                DVec3::new(r[0], y, r[2]).as_vec3(),
                DVec3::new(r[1], y, r[2]).as_vec3(),
                DVec3::new(r[1], y, r[3]).as_vec3(),
                DVec3::new(r[0], y, r[3]).as_vec3(),
            ];
            point_to_polygon(p, Vec3::Y, &poly) as f64
        })
        .sum();
    PENUMBRA_RHO as f64 * std::f64::consts::PI * f
}

/// The penumbra study's receiver points: a 41 × 41 grid over the floor of
/// `builtin:penumbra` (x and z in ±0.95 m), normal +y.
pub fn penumbra_grid() -> Vec<(DVec3, DVec3)> {
    (0..41 * 41)
        .map(|i| {
            let (a, b) = ((i / 41) as f64, (i % 41) as f64);
            (
                DVec3::new(-0.95 + 1.9 * a / 40.0, 0.0, -0.95 + 1.9 * b / 40.0),
                DVec3::Y,
            )
        })
        .collect()
}

/// `builtin:penumbra` meshed with `element_size` and solved to 1e-6 (Gauss–Seidel: the
/// floor's light only reaches black surfaces, so two sweeps finish; progressive above
/// 50,000 elements, beyond the matrix limit), with `adaptive` refinement if given.
pub fn solve_penumbra(
    element_size: f64,
    adaptive: Option<crate::mesh::AdaptiveSettings>,
) -> crate::solver::Solver {
    use crate::solver::{Method, SolverSettings};
    let p = crate::pipeline::Prepared::new(
        &crate::scene::builtin::penumbra(),
        &crate::mesh::MeshSettings {
            element_size: Some(element_size),
            ..Default::default()
        },
    );
    let method = if p.mesh.elements.len() > 50_000 {
        Method::Progressive
    } else {
        Method::GaussSeidel
    };
    let mut s = p
        .solver(SolverSettings {
            method,
            tolerance: 1e-6,
            adaptive,
            ..Default::default()
        })
        .expect("the penumbra scene fits the solver");
    s.run(None, &std::sync::atomic::AtomicBool::new(false))
        .expect("the penumbra scene solves");
    s
}

/// Error of a solved `builtin:penumbra` against [`penumbra_floor`] over [`penumbra_grid`]
/// in reconstruction `mode`: (RMS error relative to the RMS of the exact values, worst
/// error relative to the peak), and the number of floor elements.
pub fn penumbra_errors(
    solver: &crate::solver::Solver,
    mode: crate::mesh::Reconstruction,
) -> (f64, f64, usize) {
    let pts = penumbra_grid();
    let got = crate::pipeline::probe_values(solver.mesh(), &solver.radiosity(), &pts, mode);
    let peak = pts
        .iter()
        .map(|(p, _)| penumbra_floor(p.x, p.z))
        .fold(0.0, f64::max);
    let (mut num, mut den, mut max) = (0.0, 0.0, 0.0f64);
    for ((p, _), g) in pts.iter().zip(&got) {
        let exact = penumbra_floor(p.x, p.z);
        let e = g.x as f64 - exact;
        num += e * e;
        den += exact * exact;
        max = max.max(e.abs() / peak);
    }
    let mesh = solver.mesh();
    let floor = mesh
        .elements
        .iter()
        .filter(|e| mesh.patches[e.patch as usize].object == 0)
        .count();
    ((num / den).sqrt(), max, floor)
}

/// Howell's catalogue C-11: the form factor from a differential area to a parallel
/// rectangle a × b at height c, the area on the normal through one corner:
/// F = 1/2π [X/√(1+X²)·atan(Y/√(1+X²)) + Y/√(1+Y²)·atan(X/√(1+Y²))], X = a/c, Y = b/c.
/// Signed by a and b, so rectangles not over the point add up by superposition.
pub fn parallel_rectangle_corner(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a.abs() / c, b.abs() / c);
    let f = (x / (1.0 + x * x).sqrt() * (y / (1.0 + x * x).sqrt()).atan()
        + y / (1.0 + y * y).sqrt() * (x / (1.0 + y * y).sqrt()).atan())
        / (2.0 * std::f64::consts::PI);
    f * a.signum() * b.signum()
}

/// The form factor from a point to the axis-aligned square of half-width `half` centred
/// above it at height `gap`, offset by (`px`, `pz`) from its centre: four
/// [`parallel_rectangle_corner`] terms.
pub fn parallel_square(px: f64, pz: f64, half: f64, gap: f64) -> f64 {
    parallel_rectangle_corner(half - px, half - pz, gap)
        - parallel_rectangle_corner(-half - px, half - pz, gap)
        - parallel_rectangle_corner(half - px, -half - pz, gap)
        + parallel_rectangle_corner(-half - px, -half - pz, gap)
}

/// Howell's catalogue: the form factor from a plane element to a perpendicular rectangle
/// `b` wide and `a` high whose bottom edge lies in the element's plane, the element at
/// distance `c` from the rectangle's plane in front of one bottom corner:
/// F = 1/2π [atan(1/Y) − Y/√(X²+Y²)·atan(1/√(X²+Y²))], X = a/b, Y = c/b.
pub fn perpendicular_rectangle_corner(a: f64, b: f64, c: f64) -> f64 {
    if b <= 0.0 {
        return 0.0;
    }
    let (x, y) = (a / b, c / b);
    let r = (x * x + y * y).sqrt();
    ((1.0 / y).atan() - y / r * (1.0 / r).atan()) / (2.0 * std::f64::consts::PI)
}
