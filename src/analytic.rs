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
