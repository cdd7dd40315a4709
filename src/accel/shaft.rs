//! Shaft culling: what every segment from a point to a triangle meets, proved for all of
//! them at once (Haines & Wallace, "Shaft culling for efficient ray-traced radiosity",
//! 1991, here with the exact shaft of a point and a triangle: a tetrahedron).
//!
//! - **Clear**: no triangle can meet the tetrahedron, so every segment is clear.
//!   Separation is tested on the four face planes of the tetrahedron (for BVH nodes and
//!   triangles, with a margin, a length: touching counts as meeting) and on each
//!   triangle's own plane (strictly).
//! - **Blocked**: one opaque triangle crosses every segment. The apex and the base lie on
//!   opposite sides of its plane, and the base lies inside the three planes through the
//!   apex and the triangle's edges (the pyramid the triangle casts from the apex), each by
//!   the margin where the segments cross it. This is the shadow-volume test that proves an
//!   umbra without a ray (as in Teller & Hanrahan's and Drettakis & Fiume's visibility
//!   work, here for one occluder at a time).
//! - Otherwise nothing is proved, and shadow rays decide.

use super::bvh::{Bvh, END_MARGIN, STACK, Tri};
use glam::Vec3;

/// What a shaft test proves about every segment from a point to a triangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shaft {
    /// No triangle can meet any of the segments.
    Clear,
    /// One opaque triangle crosses every segment.
    Blocked,
    /// Neither could be shown.
    Unknown,
}

impl Bvh {
    /// Whether no triangle other than those in `skip` (and fully transparent ones) can
    /// meet the tetrahedron with apex `apex` and base `base`: the region every segment
    /// from `apex` to a point of `base` sweeps. `true` proves all such segments clear; `false` means only
    /// "maybe blocked". `margin` is a length: touching counts as meeting.
    pub fn shaft_clear(&self, apex: Vec3, base: &[Vec3; 3], skip: [u32; 2], margin: f32) -> bool {
        self.shaft_test((apex, base), skip, margin, false) == Shaft::Clear
    }

    /// [`Bvh::shaft_clear`], and where the shaft is not clear, whether one opaque triangle
    /// (not in `skip`) blocks every segment from `apex` to a point of `base` where
    /// `Bvh::transmittance` looks (past the first 2·10⁻⁴ of it and short of its last
    /// 10⁻⁴). A shaft that
    /// is not clear is searched on for such a triangle (among the first
    /// [`BLOCKER_SEARCH`] it meets), so this costs more than `shaft_clear` where the answer
    /// is [`Shaft::Unknown`].
    pub fn shaft(&self, apex: Vec3, base: &[Vec3; 3], skip: [u32; 2], margin: f32) -> Shaft {
        self.shaft_test((apex, base), skip, margin, true)
    }

    // `!(a > b)` on purpose: true when either side is NaN, so that NaN proves nothing.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    fn shaft_test(
        &self,
        (apex, base): (Vec3, &[Vec3; 3]),
        skip: [u32; 2],
        margin: f32,
        find_blocker: bool,
    ) -> Shaft {
        if self.tris.is_empty() {
            return Shaft::Clear;
        }
        // `transmittance` ignores the last `END_MARGIN` of each segment, so the shaft that
        // matters ends short of the base: pull the base towards the apex by that much. This
        // lets a shaft to a wall patch standing on the floor clear the floor, which it only
        // touches at the segments' ends.
        let verts = [
            apex,
            base[0] + (apex - base[0]) * END_MARGIN,
            base[1] + (apex - base[1]) * END_MARGIN,
            base[2] + (apex - base[2]) * END_MARGIN,
        ];
        // Face k is opposite vertex k; its outward normal points away from that vertex.
        let mut planes = [(Vec3::ZERO, 0.0f32); 4];
        for (k, plane) in planes.iter_mut().enumerate() {
            let [a, b, c] = [1, 2, 3].map(|j| verts[(k + j) % 4]);
            let n = (b - a).cross(c - a);
            let len = n.length();
            if len.is_nan() || len <= 0.0 || !len.is_finite() {
                return Shaft::Unknown; // degenerate shaft: prove nothing
            }
            let mut n = n / len;
            let mut d = n.dot(a);
            if n.dot(verts[k]) > d {
                n = -n;
                d = -d;
            }
            // The opposite vertex must lie strictly inside, else the tetrahedron is flat
            // (written so that NaN proves nothing).
            if !(d - n.dot(verts[k]) > margin) {
                return Shaft::Unknown;
            }
            *plane = (n, d + margin);
        }
        let mut lo = apex;
        let mut hi = apex;
        for v in &verts[1..] {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
        let (lo, hi) = (lo - margin, hi + margin);
        let mut stack = [0u32; STACK];
        let mut sp = 1;
        let mut met = 0;
        while sp > 0 {
            sp -= 1;
            let node = &self.nodes[stack[sp] as usize];
            if node.hi.cmplt(lo).any() || node.lo.cmpgt(hi).any() {
                continue;
            }
            let centre = (node.lo + node.hi) * 0.5;
            let half = (node.hi - node.lo) * 0.5;
            if planes
                .iter()
                .any(|(n, d)| n.dot(centre) - n.abs().dot(half) > *d)
            {
                continue;
            }
            if node.count == 0 {
                if sp + 2 > STACK {
                    return Shaft::Unknown;
                }
                stack[sp] = node.start;
                stack[sp + 1] = node.start + 1;
                sp += 2;
                continue;
            }
            for tri in &self.tris[node.start as usize..(node.start + node.count) as usize] {
                if tri.id == skip[0] || tri.id == skip[1] || tri.transmittance >= 1.0 {
                    continue;
                }
                let tv = [tri.v0, tri.v0 + tri.e1, tri.v0 + tri.e2];
                if planes
                    .iter()
                    .any(|(n, d)| tv.iter().all(|v| n.dot(*v) > *d))
                {
                    continue;
                }
                // The triangle's own plane.
                let n = tri.e1.cross(tri.e2);
                let len = n.length();
                if len > 0.0 && len.is_finite() {
                    let n = n / len;
                    let d = n.dot(tri.v0);
                    let side = verts.map(|v| n.dot(v) - d);
                    // Strictly one side: no margin here, so that a floor that a shaft
                    // starts just above (by the solver's ε) is cleared.
                    if side.iter().all(|s| *s > 0.0) || side.iter().all(|s| *s < 0.0) {
                        continue;
                    }
                } else {
                    continue; // zero area: blocks nothing (as in `transmittance`)
                }
                if !find_blocker {
                    return Shaft::Unknown;
                }
                if blocks(tri, &verts, margin) {
                    return Shaft::Blocked;
                }
                met += 1;
                if met == BLOCKER_SEARCH {
                    return Shaft::Unknown;
                }
            }
        }
        if met > 0 {
            Shaft::Unknown
        } else {
            Shaft::Clear
        }
    }
}

/// How many triangles meeting a shaft [`Bvh::shaft`] tests as blockers before it gives up:
/// in a scene of many small triangles a wide shaft meets thousands, and one of them
/// blocking it all is then unlikely.
const BLOCKER_SEARCH: u32 = 16;

/// The shadow rays of `Bvh::transmittance` ignore the first 1e-4 of each segment: a
/// blocker must be crossed past twice that.
const FIRST_CROSSING: f32 = 2e-4;

/// Whether the opaque triangle `tri` crosses every segment from `verts[0]` (the apex) to
/// a point of the triangle `verts[1..]`, at least `margin` inside its edges, its plane at
/// least `margin` from both ends of each segment and past [`FIRST_CROSSING`] of its
/// length. Every comparison is written so that NaN proves nothing.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // `!(a > b)`: NaN proves nothing
fn blocks(tri: &Tri, verts: &[Vec3; 4], margin: f32) -> bool {
    if !(tri.transmittance <= 0.0) {
        return false;
    }
    let apex = verts[0];
    let n = tri.e1.cross(tri.e2);
    let len = n.length();
    if !(len > 0.0 && len.is_finite()) {
        return false;
    }
    let n = n / len;
    let d = n.dot(tri.v0);
    let apex_side = n.dot(apex) - d;
    if !(apex_side.abs() > margin) {
        return false;
    }
    // Where each segment crosses the plane, as a multiple t ≥ 1 of the way to it: the
    // base vertex is t times as far from the apex as the crossing.
    let mut reach = [0.0f32; 3];
    for (t, v) in reach.iter_mut().zip(&verts[1..]) {
        let side = n.dot(*v) - d;
        if !(side * apex_side.signum() < -margin) {
            return false; // not strictly beyond the plane
        }
        *t = (apex_side - side) / apex_side;
        if !(*t * FIRST_CROSSING < 1.0) {
            return false; // crossed where the rays do not look
        }
    }
    let corners = [tri.v0, tri.v0 + tri.e1, tri.v0 + tri.e2];
    for k in 0..3 {
        let (a, b, opposite) = (corners[k], corners[(k + 1) % 3], corners[(k + 2) % 3]);
        let m = (a - apex).cross(b - apex);
        let len = m.length();
        if !(len > 0.0 && len.is_finite()) {
            return false;
        }
        let m = if m.dot(opposite - apex) < 0.0 {
            -m / len
        } else {
            m / len
        };
        // The crossing's distance inside this edge is the vertex's over t.
        if verts[1..]
            .iter()
            .zip(reach)
            .any(|(v, t)| !(m.dot(*v - apex) > margin * t))
        {
            return false;
        }
    }
    true
}
