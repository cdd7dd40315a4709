//! Shadow lines of punctual lights (D0 discontinuity meshing of direct light; Heckbert,
//! "Discontinuity meshing for radiosity", 1992; Lischinski, Tampieri & Greenberg, 1992):
//! a point light's or the sun's shadow has a sharp edge, where the light's visibility
//! jumps. That edge is the shadow of a silhouette edge of an occluder (an edge between a
//! face turned to the light and one turned away, or a free edge of an open surface): the
//! quad swept by the edge away from the light cuts each receiver along a segment, and the
//! receiver is split along it before solving, like a contact line. The receivers are
//! those the shadow lands on: rays from points along the edge, away from the light, find
//! them (one every half element along the edge). Segments across which
//! the light does not actually change (they lie in another object's shadow, or the edge
//! is itself in shadow) are dropped by testing the light's visibility on either side of
//! the segment's midpoint.

use super::contact::edge_key;
use crate::accel::Bvh;
use crate::cancel::{Cancelled, check};
use crate::geometry::{dtriangle_cross, triangle_cross, triangle_normal};
use crate::light::Punctual;
use glam::{DVec3, Vec3};
use std::collections::HashMap;
use std::sync::atomic::AtomicBool;

/// Silhouette edges, or edge–receiver pairs, traced between two looks at the cancel flag.
const TASKS_PER_CHECK: usize = 64;

/// Lengths for [`shadow_cuts`]: the scene's diagonal, the contact tolerance, and the
/// shortest shadow segment split along (shorter ones are left to refinement).
#[derive(Clone, Copy)]
pub(super) struct Lengths {
    pub scale: f32,
    pub tol: f32,
    pub min_len: f32,
}

/// Shadow-line segments per triangle (for the `receivers`) cast by the opaque triangles
/// (transmittance below one half) from `lights`. Not deduplicated: the caller merges
/// them with the contact lines, dropping segments that coincide. Looks at `cancel` for
/// every light and every [`TASKS_PER_CHECK`] rays' worth of work, and stops when it is
/// raised.
pub(super) fn shadow_cuts(
    triangles: &[[Vec3; 3]],
    transmittance: &[f32],
    receivers: &[bool],
    lights: &[Punctual],
    lengths: &Lengths,
    bvh: &Bvh,
    cancel: &AtomicBool,
) -> Result<Vec<Vec<[Vec3; 2]>>, Cancelled> {
    use rayon::prelude::*;
    let Lengths {
        scale,
        tol,
        min_len,
    } = *lengths;
    let mut cuts: Vec<Vec<[Vec3; 2]>> = vec![Vec::new(); triangles.len()];
    let opaque = |i: usize| transmittance.get(i).is_none_or(|t| *t < 0.5);
    // Edges of opaque triangles, by bit-identical end points.
    let mut edges: HashMap<_, Vec<(u32, [Vec3; 2])>> = HashMap::new();
    for (i, t) in triangles.iter().enumerate() {
        if opaque(i) && t.iter().all(|p| p.is_finite()) {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                edges
                    .entry(edge_key(a, b))
                    .or_default()
                    .push((i as u32, [a, b]));
            }
        }
    }
    let eps = scale * 1e-5;
    for light in lights {
        check(cancel)?;
        let towards = |p: Vec3| light.towards(p);
        let facing = |i: u32| {
            let t = &triangles[i as usize];
            let nrm = triangle_cross(t);
            let c = (t[0] + t[1] + t[2]) / 3.0;
            nrm.dot(towards(c)) > 0.0
        };
        // Silhouette edges: free edges, and edges between faces turned to and away from
        // the light. Each sweeps a quad (two triangles) away from the light; rays from
        // points along the edge, away from the light, find the receivers it lands on.
        let mut silhouettes: Vec<([Vec3; 2], u32)> = Vec::new();
        for users in edges.values() {
            let silhouette =
                users.len() == 1 || users.iter().any(|u| facing(u.0) != facing(users[0].0));
            if silhouette && (users[0].1[0] - users[0].1[1]).length() >= min_len {
                silhouettes.push((users[0].1, users[0].0));
            }
        }
        // In a fixed order (the map's is random): the cuts' order decides the
        // triangulation, and meshes must not change from run to run.
        silhouettes.sort_by_key(|&([a, b], own)| {
            (
                own,
                a.to_array().map(f32::to_bits),
                b.to_array().map(f32::to_bits),
            )
        });
        let away = |p: Vec3| -towards(p).normalize_or_zero();
        let landings = |&([a, b], own): &([Vec3; 2], u32)| {
            let steps = (((b - a).length() / min_len).ceil() as usize).clamp(1, 256);
            let mut seen: Vec<u32> = Vec::new();
            for k in 0..steps {
                let p = a + (b - a) * ((k as f32 + 0.5) / steps as f32);
                let d = away(p);
                if let Some(h) = bvh.closest_hit(p, d, eps, f32::INFINITY, own)
                    && receivers.get(h.triangle as usize) == Some(&true)
                    && !seen.contains(&h.triangle)
                {
                    seen.push(h.triangle);
                }
            }
            seen.into_iter().map(move |r| ([a, b], r))
        };
        let tasks: Vec<([Vec3; 2], u32)> = silhouettes
            .par_chunks(TASKS_PER_CHECK)
            .map(|chunk| {
                check(cancel)?;
                Ok(chunk.iter().flat_map(landings).collect::<Vec<_>>())
            })
            .collect::<Result<Vec<_>, Cancelled>>()?
            .concat();
        let visible = |p: Vec3, own: u32| light.visible(bvh, p, [own, u32::MAX]);
        let jump = |&(edge, i): &([Vec3; 2], u32)| {
            let r = &triangles[i as usize];
            let nrm = triangle_normal(r);
            let [a, b] = project(r, edge, *light, tol, min_len)?;
            let m = (a + b) * 0.5;
            if nrm.dot(towards(m)) <= 0.0 {
                return None; // the receiver's back: no direct light to jump
            }
            // Either side of the midpoint, in the receiver's plane.
            let side = nrm.cross(b - a).normalize_or_zero() * (min_len * 0.05).max(eps);
            let lift = nrm * eps;
            (visible(m + side + lift, i) != visible(m - side + lift, i)).then_some((i, [a, b]))
        };
        let found: Vec<(u32, [Vec3; 2])> = tasks
            .par_chunks(TASKS_PER_CHECK)
            .map(|chunk| {
                check(cancel)?;
                Ok(chunk.iter().filter_map(jump).collect::<Vec<_>>())
            })
            .collect::<Result<Vec<_>, Cancelled>>()?
            .concat();
        for (i, s) in found {
            cuts[i as usize].push(s);
        }
    }
    Ok(cuts)
}

/// The shadow of `edge` from `light` on the plane of triangle `r`, clipped to `r`; `None`
/// when the edge is not wholly between the light and the plane, when the shadow is
/// shorter than `min_len` before clipping (left to refinement), when nothing of it lies
/// in `r`, or when it runs along one of `r`'s edges (nothing to split there).
fn project(
    r: &[Vec3; 3],
    edge: [Vec3; 2],
    light: Punctual,
    tol: f32,
    min_len: f32,
) -> Option<[Vec3; 2]> {
    let v = r.map(|p| p.as_dvec3());
    let n = dtriangle_cross(&v);
    let len = n.length();
    if len <= 0.0 || !len.is_finite() {
        return None;
    }
    let n = n / len;
    let tol = tol as f64;
    // Along the ray from the light through p (or along the light's direction), where it
    // meets the plane; only beyond p.
    let shadow = |p: DVec3| -> Option<DVec3> {
        let dir = match light {
            Punctual::Point(l) => p - l.as_dvec3(),
            Punctual::Direction(d) => -d.as_dvec3(),
        };
        let denom = dir.dot(n);
        if denom.abs() <= 1e-12 * dir.length() {
            return None;
        }
        let t = (v[0] - p).dot(n) / denom;
        (t > 0.0 && t.is_finite()).then(|| p + dir * t)
    };
    let a = shadow(edge[0].as_dvec3())?;
    let b = shadow(edge[1].as_dvec3())?;
    if (b - a).length() < min_len as f64 {
        return None;
    }
    // Clip a→b to the triangle (Cyrus–Beck against its three edges, inward normals in
    // its plane). Exactly to the edges: an end even slightly outside would grow the
    // triangulation's hull by a sliver, and the neighbour across the edge clips its part
    // of the same shadow line to the same point.
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    let slack = 1e-9 * (b - a).length();
    for k in 0..3 {
        let e = v[(k + 1) % 3] - v[k];
        let inward = n.cross(e).normalize_or_zero();
        let f0 = (a - v[k]).dot(inward);
        let f1 = (b - v[k]).dot(inward);
        if f0 < -slack && f1 < -slack {
            return None;
        }
        if f0 >= -slack && f1 >= -slack {
            continue;
        }
        if f0 < 0.0 {
            t0 = t0.max(f0 / (f0 - f1));
        } else if f1 < 0.0 {
            t1 = t1.min(f0 / (f0 - f1));
        }
    }
    if t1 - t0 <= 1e-9 {
        return None;
    }
    let (p, q) = (a + (b - a) * t0, a + (b - a) * t1);
    // Along one of the triangle's own edges: no split.
    for k in 0..3 {
        let (s, e) = (v[k], v[(k + 1) % 3]);
        let d = (e - s).normalize_or_zero();
        let off = |x: DVec3| ((x - s) - d * (x - s).dot(d)).length();
        if off(p) <= tol && off(q) <= tol {
            return None;
        }
    }
    Some([p.as_vec3(), q.as_vec3()])
}
