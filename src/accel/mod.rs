//! Visibility: a bounding volume hierarchy over the scene triangles and the two queries
//! the solver needs, `transmittance(a, b)` (any-hit with early exit on opaque surfaces) and
//! `closest_hit(origin, direction)`.
//!
//! Shadow rays (`transmittance`, `occluded`) and closest hits (`closest_hit`,
//! `stopping_hit`) go through a 4-wide BVH with four triangles per leaf, traced four boxes
//! or four triangles at a time (`wide.rs`, Embree's BVH4 and Triangle4 layout over obvhs's
//! PLOC build). On Sponza it traces occlusion rays at 92 % of Embree 4's rate, twice
//! obvhs's own compressed 8-wide traversal and four times our binary tree, and closest
//! hits at twice the binary tree's rate (`cargo run --release --example bvh_compare --
//! SCENE`). The binary tree (binned SAH, Wald 2007; Möller–Trumbore 1997) serves what the
//! wide one does not: shaft tests against the exact point-to-patch tetrahedron
//! (`shaft.rs`: clear, or blocked whole by one opaque triangle), and the baseline of those
//! comparisons. Both know per-triangle transmittance (alpha-masked cut-outs and glass
//! attenuate shadow rays instead of blocking them) and skip the
//! shooter's and receiver's own triangles.

mod bvh;
mod shaft;
mod wide;

use crate::geometry::sampling::{hash, point_in_triangle, unit};
use crate::geometry::triangle_area;

pub use bvh::Bvh;
pub use shaft::Shaft;

/// A ray hit: distance along the (unit or not) direction, the caller's triangle index and
/// barycentric coordinates (u, v) of the hit on it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub triangle: u32,
    pub u: f32,
    pub v: f32,
    /// The hit triangle's transmittance (0 = opaque).
    pub transmittance: f32,
}

/// `n` segments between pairs of points drawn uniformly by area over `triangles` (a fixed
/// hash sequence, so every run and every ray engine sees the same segments), each with the
/// indices of its two end triangles. `None` when the triangles have no area.
///
/// This is the distribution of `radiosity bench --occlusion`.
pub fn sample_segments(triangles: &[[glam::Vec3; 3]], n: usize) -> Option<Vec<Segment>> {
    let mut cdf = Vec::with_capacity(triangles.len());
    let mut total = 0.0f64;
    for t in triangles {
        let a = triangle_area(t) as f64;
        total += if a.is_finite() { a } else { 0.0 };
        cdf.push(total);
    }
    if total.is_nan() || total <= 0.0 {
        return None;
    }
    let sample = |k: u64| {
        let h = hash(k);
        let x = unit(h) as f64 * total;
        let i = cdf.partition_point(|c| *c < x).min(cdf.len() - 1);
        let t = &triangles[i];
        let p = point_in_triangle(t, unit(hash(h ^ 1)), unit(hash(h ^ 2)));
        (p, i as u32)
    };
    Some(
        (0..n as u64)
            .map(|k| {
                let (a, ta) = sample(2 * k);
                let (b, tb) = sample(2 * k + 1);
                (a, b, [ta, tb])
            })
            .collect(),
    )
}

/// A segment's two end points and the triangles they lie on.
pub type Segment = (glam::Vec3, glam::Vec3, [u32; 2]);
