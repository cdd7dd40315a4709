//! Refinement for the external light (punctual lights, the sun, the sky; see
//! `light::direct`). Its first bounce enters each leaf as the irradiance h at the leaf's
//! centroid, held constant over the leaf (the source term E' = E + ρ h). No link carries
//! it, so link refinement never sees how it varies: a wall lit by the sky through an
//! opening stayed a few long input triangles, whose constant values Gouraud shading
//! fanned out between their corners (Sponza's walls).
//!
//! A leaf is split like the receiver of a link whose error is above the oracle's
//! threshold: the error of holding h constant over it is about ρ · (h_max − h_min) / 2,
//! the range taken over three points 90 % of the way from its centroid to its corners (at
//! a corner itself, a surface touching the leaf there would block the rays). The three
//! points cast the same sky directions (one seed; common random numbers), so what differs
//! between them is what they see, not sampling noise; [`SKY_RAYS`] each.

use crate::accel::Bvh;
use crate::light::{ExternalLight, direct};
use crate::mesh::Mesh;
use crate::solver::form_factor::element_seed;
use glam::Vec3;

/// Sky rays at each of a leaf's three points: a 4 × 4 stratified grid. A change of one
/// ray in 16 is 6 % of the open sky's irradiance; smaller changes go unseen until a
/// neighbour's split brings the points closer.
const SKY_RAYS: u32 = 16;

/// Where the three points lie, as a fraction of the way from the centroid to a corner.
const TOWARD_CORNER: f32 = 0.9;

/// The range of the external irradiance over leaf element `e`: per channel the largest
/// minus the smallest of its values at the three points, largest channel; and the rays
/// cast.
pub(super) fn range(mesh: &Mesh, bvh: &Bvh, external: &ExternalLight, e: usize) -> (f32, u32) {
    if external.is_empty() {
        return (0.0, 0);
    }
    let element = &mesh.elements[e];
    let own = mesh.patches[element.patch as usize].scene_triangle;
    let centroid = element.centroid();
    let seed = element_seed(element);
    let frame = mesh.frame();
    let (mut lo, mut hi, mut rays) = (Vec3::INFINITY, Vec3::NEG_INFINITY, 0);
    for corner in element.verts {
        let x = centroid + (corner - centroid) * TOWARD_CORNER;
        let (h, r) = direct::irradiance_with_sky_rays(
            &frame,
            bvh,
            external,
            (x, element.normal, own),
            seed,
            SKY_RAYS,
        );
        let h = if h.is_finite() { h } else { Vec3::ZERO };
        lo = lo.min(h);
        hi = hi.max(h);
        rays += r;
    }
    ((hi - lo).max_element().max(0.0), rays)
}
