//! Visibility: a bounding volume hierarchy over the scene triangles and the two queries
//! the solver needs, `transmittance(a, b)` (any-hit with early exit on opaque surfaces) and
//! `closest_hit(origin, direction)`.
//!
//! The BVH is a binary tree built with the surface area heuristic over 16 bins per axis
//! (Wald, "On fast construction of SAH-based bounding volume hierarchies", 2007), with
//! Möller–Trumbore ray/triangle tests (1997). It is written here rather than taken from a
//! crate so that it works in the mesh's f32 frame, knows per-triangle transmittance
//! (alpha-masked cut-outs and glass attenuate shadow rays instead of blocking them) and
//! can skip the shooter's and receiver's own triangles without a callback per hit.

mod bvh;

pub use bvh::{Bvh, Hit};
