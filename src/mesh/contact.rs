//! D0 discontinuity meshing: where another surface touches or pierces a triangle (a box
//! standing on a floor, a lamp set flush under a ceiling, a wall through a slab), the
//! radiosity on the triangle jumps along the line of contact: light on one side, the
//! hidden, dark underside on the other. Refining elements down to a minimum size only
//! narrows the band where the two are averaged; splitting the triangle *along the line*
//! removes it (Lischinski, Tampieri & Greenberg, "Discontinuity meshing for accurate
//! radiosity", IEEE CG&A 1992, §3: D0 discontinuities are found from the geometry alone,
//! before any light is computed).
//!
//! For each receiving triangle R this module finds the contact segments: every other
//! triangle T that crosses R's plane, or has an edge or its whole face within a small
//! tolerance of it, meets the plane in a segment (the crossing line, the touching edge,
//! or the coplanar face's edges), clipped to R. Segments along R's own edges (its
//! neighbours in a closed mesh) cut nothing and are dropped. The triangle is then split
//! along them (`split`). Faces lying against a triangle's front (a box's bottom on the
//! floor) are recorded too: they hide the part of it they cover.

use crate::cancel::{Cancelled, check};
use crate::geometry::dtriangle_cross;
use glam::{DVec3, Vec3};
use std::sync::atomic::AtomicBool;

/// Receiver–occluder pairs tested between two looks at the cancel flag.
const PAIRS_PER_CHECK: usize = 1024;

/// Axis-aligned box of a triangle, grown by `pad`.
fn bounds(t: &[Vec3; 3], pad: f32) -> (Vec3, Vec3) {
    let lo = t[0].min(t[1]).min(t[2]) - Vec3::splat(pad);
    let hi = t[0].max(t[1]).max(t[2]) + Vec3::splat(pad);
    (lo, hi)
}

/// Pairs (i, j), i ≠ j, of `triangles` whose boxes (grown by `pad`) overlap, for the `i`
/// in `receivers`; sweep and prune along the longest axis of the scene. Stops early when
/// `cancel` is raised.
fn overlapping_pairs(
    triangles: &[[Vec3; 3]],
    receivers: &[bool],
    pad: f32,
    cancel: &AtomicBool,
) -> Result<Vec<(u32, u32)>, Cancelled> {
    let boxes: Vec<(Vec3, Vec3)> = triangles.iter().map(|t| bounds(t, pad)).collect();
    let (lo, hi) = boxes.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(a, b), (l, h)| (a.min(*l), b.max(*h)),
    );
    let ext = hi - lo;
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    let mut order: Vec<u32> = (0..triangles.len() as u32)
        .filter(|&i| boxes[i as usize].0.is_finite() && boxes[i as usize].1.is_finite())
        .collect();
    order.sort_by(|&a, &b| boxes[a as usize].0[axis].total_cmp(&boxes[b as usize].0[axis]));
    let mut pairs = Vec::new();
    for (k, &i) in order.iter().enumerate() {
        if k % PAIRS_PER_CHECK == 0 {
            check(cancel)?;
        }
        let (li, hi_) = boxes[i as usize];
        for &j in &order[k + 1..] {
            let (lj, hj) = boxes[j as usize];
            if lj[axis] > hi_[axis] {
                break;
            }
            if li.cmple(hj).all() && lj.cmple(hi_).all() {
                if receivers[i as usize] {
                    pairs.push((i, j));
                }
                if receivers[j as usize] {
                    pairs.push((j, i));
                }
            }
        }
    }
    Ok(pairs)
}

/// How triangle `t` meets the plane of `r` (points within `tol` of the plane count as on
/// it).
pub(super) struct Contact {
    /// The segment where they meet, clipped to `r`; none when it runs along an edge of
    /// `r`. A face lying in the plane yields its edges (up to three segments).
    pub segments: Vec<[DVec3; 2]>,
    /// Bit k: segment k is shorter than `min_len` before clipping. Such a piece is kept
    /// only when asked (`t` is double-sided), and cut along only when it belongs to a
    /// longer outline ([`outlines_long_enough`]). A bit mask (at most three segments)
    /// rather than a `Vec`: `find_cuts` holds a `Contact` for each of millions of pairs at
    /// once on Sponza, and a second `Vec` in each took its meshing from 0.62 to 1.00 GB.
    pub short: u8,
    /// `t` lies in the plane.
    pub coplanar: bool,
    /// `t` lies against the front of `r`: in the plane and either in front of it, or (when
    /// in the same plane to 1/1000 of `tol`) facing it (a box's bottom on a floor, a lamp
    /// flush under a ceiling).
    covers: bool,
}

pub(super) fn contact(
    r: &[Vec3; 3],
    t: &[Vec3; 3],
    tol: f64,
    (min_len, keep_short): (f64, bool),
) -> Contact {
    let none = Contact {
        segments: Vec::new(),
        short: 0,
        coplanar: false,
        covers: false,
    };
    let r = r.map(|v| v.as_dvec3());
    let t = t.map(|v| v.as_dvec3());
    let n = dtriangle_cross(&r);
    let len = n.length();
    let m = dtriangle_cross(&t).normalize_or_zero();
    if len <= 0.0 || !len.is_finite() || m == DVec3::ZERO {
        return none;
    }
    let n = n / len;
    let d = t.map(|v| (v - r[0]).dot(n));
    let on = d.map(|x| x.abs() <= tol);
    let mut raw: Vec<[DVec3; 2]> = Vec::new();
    let coplanar = on.iter().all(|&o| o);
    let mean = (d[0] + d[1] + d[2]) / 3.0;
    let covers = coplanar && (mean > tol * 1e-3 || (mean.abs() <= tol * 1e-3 && m.dot(n) < 0.0));
    if coplanar {
        for k in 0..3 {
            raw.push([t[k], t[(k + 1) % 3]]);
        }
    } else {
        let mut pts: Vec<DVec3> = Vec::new();
        for k in 0..3 {
            if on[k] {
                pts.push(t[k]);
            }
            let (a, b) = (k, (k + 1) % 3);
            if !on[a] && !on[b] && (d[a] > 0.0) != (d[b] > 0.0) {
                let s = d[a] / (d[a] - d[b]);
                pts.push(t[a] + (t[b] - t[a]) * s);
            }
        }
        if pts.len() >= 2 {
            // The two farthest apart (three points only when a vertex lies on the plane
            // and the opposite edge crosses it: then they are collinear).
            let mut best = (0, 1, -1.0);
            for i in 0..pts.len() {
                for j in i + 1..pts.len() {
                    let l = (pts[i] - pts[j]).length_squared();
                    if l > best.2 {
                        best = (i, j, l);
                    }
                }
            }
            raw.push([pts[best.0], pts[best.1]]);
        }
    }
    // Into r's plane, clipped to r (Cyrus–Beck against its three edges), dropped when
    // along one of r's edges.
    let mut out = Vec::new();
    let mut short = 0u8;
    for [a, b] in raw {
        // Shortness is judged before clipping: a long contact line that only clips to a
        // short piece of this triangle (near its corner) must stay, or the outline it
        // belongs to would have a gap.
        let is_short = (b - a).length() < min_len;
        if is_short && !keep_short {
            continue;
        }
        let a = a - n * (a - r[0]).dot(n);
        let b = b - n * (b - r[0]).dot(n);
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        let mut inside = true;
        for k in 0..3 {
            let (p, q) = (r[k], r[(k + 1) % 3]);
            // Inward normal of edge k in the plane.
            let m = n.cross(q - p);
            let fa = (a - p).dot(m);
            let fb = (b - p).dot(m);
            if fa < 0.0 && fb < 0.0 {
                inside = false;
                break;
            }
            if fa < 0.0 {
                t0 = t0.max(fa / (fa - fb));
            } else if fb < 0.0 {
                t1 = t1.min(fa / (fa - fb));
            }
        }
        if !inside || t1 <= t0 {
            continue;
        }
        let (ca, cb) = (a + (b - a) * t0, a + (b - a) * t1);
        if (cb - ca).length() <= tol {
            continue;
        }
        let along_edge = (0..3).any(|k| {
            let (p, q) = (r[k], r[(k + 1) % 3]);
            let e = (q - p).normalize_or_zero();
            let off = |x: DVec3| {
                let v = x - p;
                (v - e * v.dot(e)).length()
            };
            off(ca) <= tol && off(cb) <= tol
        });
        if !along_edge {
            short |= u8::from(is_short) << out.len();
            out.push([ca, cb]);
        }
    }
    Contact {
        segments: out,
        short,
        coplanar,
        covers,
    }
}

/// What touches each triangle: the contact segments to split it along, and the faces lying
/// against its front (within the tolerance), which hide the part of it they overlap.
pub(super) struct Contacts {
    pub cuts: Vec<Vec<[Vec3; 2]>>,
    pub covers: Vec<Vec<u32>>,
    /// Per triangle: some of its cuts are short pieces kept for the outline they belong to
    /// ([`outlines_long_enough`]).
    pub outlined: Vec<bool>,
}

/// Whether point `p` (on a receiving triangle) lies under one of the faces `covers` (of
/// `triangles`): inside it, seen along its normal.
pub(super) fn is_covered(p: Vec3, covers: &[u32], triangles: &[[Vec3; 3]]) -> bool {
    covers.iter().any(|&j| {
        let t = triangles[j as usize].map(|v| v.as_dvec3());
        let p = p.as_dvec3();
        let n = dtriangle_cross(&t);
        let nn = n.length_squared();
        if nn <= 0.0 {
            return false;
        }
        // Barycentric coordinates of p projected onto t's plane.
        let b0 = (t[2] - t[1]).cross(p - t[1]).dot(n) / nn;
        let b1 = (t[0] - t[2]).cross(p - t[2]).dot(n) / nn;
        let b2 = 1.0 - b0 - b1;
        b0 >= -1e-9 && b1 >= -1e-9 && b2 >= -1e-9
    })
}

/// Contact segments for every receiving triangle: `receivers[i]` says whether triangle
/// `i` is meshed. `tol`: how close a surface must come to count as touching; `min_len`:
/// shorter contacts are ignored (they are finer than the elements) unless they come from a
/// `two_sided` triangle and chain into a longer outline ([`outlines_long_enough`]). Mesh
/// frame, f32.
/// Looks at `cancel` every [`PAIRS_PER_CHECK`] pairs and stops when it is raised.
pub(super) fn find_cuts(
    triangles: &[[Vec3; 3]],
    receivers: &[bool],
    two_sided: &[bool],
    tol: f32,
    min_len: f32,
    cancel: &AtomicBool,
) -> Result<Contacts, Cancelled> {
    use rayon::prelude::*;
    let pairs = overlapping_pairs(triangles, receivers, tol, cancel)?;
    let contacts: Vec<Vec<Contact>> = pairs
        .par_chunks(PAIRS_PER_CHECK)
        .map(|chunk| {
            check(cancel)?;
            Ok(chunk
                .iter()
                .map(|&(i, j)| {
                    let (r, t) = (&triangles[i as usize], &triangles[j as usize]);
                    contact(r, t, tol as f64, (min_len as f64, two_sided[j as usize]))
                })
                .collect())
        })
        .collect::<Result<_, Cancelled>>()?;
    // Per receiver: the faces covering it, and the segments with whether each came from a
    // face lying in its plane.
    let mut covers_of: Vec<Vec<u32>> = vec![Vec::new(); triangles.len()];
    let mut found: Vec<Vec<([DVec3; 2], bool, bool)>> = vec![Vec::new(); triangles.len()];
    for (&(i, j), c) in pairs.iter().zip(contacts.into_iter().flatten()) {
        if c.covers {
            covers_of[i as usize].push(j);
        }
        for (k, s) in c.segments.into_iter().enumerate() {
            found[i as usize].push((s, c.coplanar, c.short >> k & 1 == 1));
        }
    }
    let tol = tol as f64;
    let same = |a: &[DVec3; 2], b: &[DVec3; 2]| same_segment(*a, *b, tol);
    let cut: Vec<(Vec<[Vec3; 2]>, bool)> = found
        .into_iter()
        .enumerate()
        .map(|(i, segments)| {
            check(cancel)?;
            // An edge shared by two faces lying in the plane (the diagonal of a quad lamp
            // flush with a ceiling, of a box's bottom) is inside the contact area, not
            // its outline: drop it. Then drop duplicates (a box's bottom edge comes from
            // its bottom face and from a side face).
            let mut keep: Vec<[DVec3; 2]> = Vec::new();
            let mut short: Vec<bool> = Vec::new();
            for (k, (s, coplanar, is_short)) in segments.iter().enumerate() {
                let interior = *coplanar
                    && segments
                        .iter()
                        .enumerate()
                        .any(|(m, (o, c, _))| m != k && *c && same(s, o));
                if interior {
                    continue;
                }
                match keep.iter().position(|o| same(s, o)) {
                    Some(m) => short[m] &= *is_short,
                    None => {
                        keep.push(*s);
                        short.push(*is_short);
                    }
                }
            }
            let r = triangles[i].map(|v| v.as_dvec3());
            let long = outlines_long_enough(&keep, &short, &r, min_len as f64, tol);
            let outlined = short.iter().zip(&long).any(|(s, l)| *s && *l);
            let kept = keep
                .into_iter()
                .zip(long)
                .filter(|(_, long)| *long)
                .map(|([a, b], _)| [a.as_vec3(), b.as_vec3()])
                .collect();
            Ok((kept, outlined))
        })
        .collect::<Result<_, Cancelled>>()?;
    let (cuts, outlined) = cut.into_iter().unzip();
    Ok(Contacts {
        cuts,
        covers: covers_of,
        outlined,
    })
}

/// Which segments to cut along: every segment that is not `short`, and every short one
/// whose outline (the segments chained to it end to end, within `tol`) is at least
/// `min_len` long in all and divides the triangle `r`: it is closed, or its open ends lie
/// on `r`'s edges (where it goes on into the neighbour). An outline with a loose end
/// inside `r` separates nothing: light reaches both of its sides around that end. A tessellated sphere standing in a floor meets it in a circle of
/// pieces each far shorter than an element: one by one they are finer than the mesh, but
/// the circle they make is the border between the lit floor and the sealed floor under the
/// sphere, and an element straddling it would carry light into the sealed side. When the
/// sphere is double-sided its inside reflects what the floor's straddling elements bring
/// it, and at ρ = 0.999 keeps it for a thousand bounces (`cornell-box-nvpro`'s white
/// sphere held half of the light outside); so `find_cuts` chains only short pieces of
/// double-sided surfaces. A single-sided surface's inside reflects nothing, and the
/// straddle only blurs the outline over an element, as every contact finer than the mesh
/// does (chaining those too gave Sponza 11 % more patches and a 35 % longer solve). An
/// isolated short piece (a small pebble's contact) is still finer than the elements and
/// is dropped. Union–find over end points that meet, found in a grid of cells `tol` wide.
pub(super) fn outlines_long_enough(
    segments: &[[DVec3; 2]],
    short: &[bool],
    r: &[DVec3; 3],
    min_len: f64,
    tol: f64,
) -> Vec<bool> {
    let n = segments.len();
    if short.iter().all(|s| !s) {
        return vec![true; n];
    }
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    // End points in a grid of cells `tol` wide: only ends in neighbouring cells can touch.
    let cell = |p: DVec3| {
        (p / tol.max(f64::MIN_POSITIVE))
            .floor()
            .as_i64vec3()
            .to_array()
    };
    let mut grid: std::collections::HashMap<[i64; 3], Vec<(usize, DVec3)>> = Default::default();
    for (i, s) in segments.iter().enumerate() {
        for &p in s {
            grid.entry(cell(p)).or_default().push((i, p));
        }
    }
    // An end on one of r's edges goes on into the neighbouring triangle.
    let on_edge = |x: DVec3| {
        (0..3).any(|k| {
            let (a, b) = (r[k], r[(k + 1) % 3]);
            let t = ((x - a).dot(b - a) / (b - a).length_squared().max(f64::MIN_POSITIVE))
                .clamp(0.0, 1.0);
            (a + (b - a) * t - x).length() <= tol
        })
    };
    let mut loose = vec![false; n];
    for (i, s) in segments.iter().enumerate() {
        for &p in s {
            let c = cell(p);
            let mut joined = on_edge(p);
            for d in 0..27 {
                let key = [c[0] + d % 3 - 1, c[1] + d / 3 % 3 - 1, c[2] + d / 9 - 1];
                for &(j, q) in grid.get(&key).into_iter().flatten() {
                    if j != i && (p - q).length() <= tol {
                        joined = true;
                        let (ri, rj) = (root(&mut parent, i), root(&mut parent, j));
                        if ri != rj {
                            parent[ri] = rj;
                        }
                    }
                }
            }
            loose[i] |= !joined;
        }
    }
    let mut total = vec![0.0f64; n];
    let mut open = vec![false; n];
    for (i, [a, b]) in segments.iter().enumerate() {
        let k = root(&mut parent, i);
        total[k] += (*b - *a).length();
        open[k] |= loose[i];
    }
    (0..n)
        .map(|i| {
            let k = root(&mut parent, i);
            !short[i] || (total[k] >= min_len && !open[k])
        })
        .collect()
}

/// Whether two segments coincide (either way round) within `tol`.
pub(super) fn same_segment(a: [DVec3; 2], b: [DVec3; 2], tol: f64) -> bool {
    ((a[0] - b[0]).length() <= tol && (a[1] - b[1]).length() <= tol)
        || ((a[0] - b[1]).length() <= tol && (a[1] - b[0]).length() <= tol)
}

/// Key of the edge (`a`, `b`) either way round: its end points' bits, so edges of an
/// indexed mesh shared by two triangles get the same key.
pub(super) fn edge_key(a: Vec3, b: Vec3) -> ([u32; 3], [u32; 3]) {
    let (a, b) = (
        a.to_array().map(f32::to_bits),
        b.to_array().map(f32::to_bits),
    );
    if a <= b { (a, b) } else { (b, a) }
}

/// A cut that ends inside a triangle's edge puts a vertex there; the triangles sharing
/// that edge get it too, as a zero-length cut (a point to split at), unless they have a
/// cut end there already (the contact line goes on into them), so the mesh stays
/// conforming where a contact line ends on an edge (a short contact dropped on one side,
/// or one ending exactly there) instead of leaving a T-junction. Edges are shared when
/// their end points are bit for bit the same (indexed meshes).
pub(super) fn carry_cut_ends(
    triangles: &[[Vec3; 3]],
    receivers: &[bool],
    cuts: &mut [Vec<[Vec3; 2]>],
    tol: f64,
) {
    use std::collections::HashMap;
    let key = edge_key;
    let mut edges: HashMap<_, Vec<u32>> = HashMap::new();
    for (i, t) in triangles.iter().enumerate() {
        if receivers[i] {
            for k in 0..3 {
                edges
                    .entry(key(t[k], t[(k + 1) % 3]))
                    .or_default()
                    .push(i as u32);
            }
        }
    }
    let mut carried: Vec<(u32, Vec3)> = Vec::new();
    for (i, segments) in cuts.iter().enumerate() {
        let t = &triangles[i];
        for q in segments.iter().flatten() {
            for k in 0..3 {
                let (a, b) = (t[k].as_dvec3(), t[(k + 1) % 3].as_dvec3());
                let d = b - a;
                let len = d.length();
                if len <= 2.0 * tol {
                    continue;
                }
                let x = (q.as_dvec3() - a).dot(d) / len; // along the edge
                let off = (a + d * (x / len) - q.as_dvec3()).length();
                if off > tol || x <= tol || x >= len - tol {
                    continue; // not inside this edge
                }
                let sharing = edges.get(&key(t[k], t[(k + 1) % 3]));
                for &j in sharing.into_iter().flatten() {
                    if j as usize != i {
                        carried.push((j, *q));
                    }
                }
            }
        }
    }
    for (j, q) in carried {
        let near = |p: &Vec3| (p.as_dvec3() - q.as_dvec3()).length() <= tol;
        let list = &mut cuts[j as usize];
        if !list.iter().flatten().any(near) {
            list.push([q, q]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cancel::never;

    #[test]
    fn a_ring_of_short_pieces_cuts_but_a_lone_short_piece_does_not() {
        // A floor triangle, a 64-sided prism (radius 0.3 m, sides of 2.9 cm) standing
        // through it, and one small tetrahedron-like facet (a pebble, 1 cm) elsewhere.
        // With min_len = 10 cm every piece is short on its own; the prism's pieces chain
        // into a circle of 1.9 m and must all stay (the border of the sealed floor under
        // it), the pebble's piece is finer than the elements and must go.
        let floor = [
            Vec3::new(-2.0, 0.0, -2.0),
            Vec3::new(2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, -2.0),
        ];
        let mut triangles = vec![floor];
        let n = 64;
        let centre = Vec3::new(1.0, 0.0, -0.8);
        let at = |k: usize, y: f32| {
            let a = std::f32::consts::TAU * k as f32 / n as f32;
            centre + Vec3::new(0.3 * a.cos(), y, 0.3 * a.sin())
        };
        for k in 0..n {
            triangles.push([at(k, -0.05), at(k + 1, -0.05), at(k + 1, 0.5)]);
            triangles.push([at(k, -0.05), at(k + 1, 0.5), at(k, 0.5)]);
        }
        triangles.push([
            Vec3::new(1.5, -0.01, -1.2),
            Vec3::new(1.51, -0.01, -1.2),
            Vec3::new(1.505, 0.01, -1.2),
        ]);
        let mut receivers = vec![false; triangles.len()];
        receivers[0] = true;
        let two_sided = vec![true; triangles.len()];
        let c = find_cuts(&triangles, &receivers, &two_sided, 1e-4, 0.1, never()).unwrap();
        let cuts = &c.cuts[0];
        let on_circle = |p: Vec3| ((p - centre) * Vec3::new(1.0, 0.0, 1.0)).length();
        // Every cut lies on the circle (a chord's points are within 0.3·(1 − cos π/64) =
        // 0.36 mm of it), and together they make its whole polygon, 2·64·0.3·sin(π/64).
        let mut total = 0.0;
        for [a, b] in cuts {
            for p in [*a, *b, (*a + *b) * 0.5] {
                assert!((on_circle(p) - 0.3).abs() < 4e-4, "{p} is off the circle");
            }
            total += (*b - *a).length();
        }
        let perimeter = 2.0 * n as f32 * 0.3 * (std::f32::consts::PI / n as f32).sin();
        assert!(
            (total - perimeter).abs() < 1e-4,
            "{total} against {perimeter}"
        );
        // Judged one by one, the same pieces are all dropped (the old rule).
        let mut alone = vec![false; triangles.len()];
        alone[0] = true;
        let one = [floor, triangles[1], triangles[2]];
        let c = find_cuts(&one, &alone[..3], &two_sided[..3], 1e-4, 0.1, never()).unwrap();
        assert!(c.cuts[0].is_empty(), "{:?}", c.cuts[0]);
        // A single-sided prism's inside reflects nothing: its short pieces are dropped.
        let single = vec![false; triangles.len()];
        let c = find_cuts(&triangles, &receivers, &single, 1e-4, 0.1, never()).unwrap();
        assert!(c.cuts[0].is_empty(), "{:?}", c.cuts[0]);
    }

    #[test]
    fn a_box_on_a_floor_cuts_its_footprint() {
        let floor = [
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, -1.0),
        ];
        // One side face of a box standing on the floor: its bottom edge lies in the floor
        // from (0.2, 0, -0.5) to (0.6, 0, -0.5).
        let side = [
            Vec3::new(0.2, 0.0, -0.5),
            Vec3::new(0.6, 0.0, -0.5),
            Vec3::new(0.6, 0.3, -0.5),
        ];
        let s = contact(&floor, &side, 1e-6, (1e-4, false)).segments;
        assert_eq!(s.len(), 1);
        let [a, b] = s[0];
        assert!(
            (a - DVec3::new(0.2, 0.0, -0.5)).length() < 1e-6
                || (b - DVec3::new(0.2, 0.0, -0.5)).length() < 1e-6
        );
        assert!(((b - a).length() - 0.4).abs() < 1e-6);
        // A wall crossing the floor: the crossing line, clipped to the floor triangle.
        let wall = [
            Vec3::new(0.5, -1.0, -3.0),
            Vec3::new(0.5, -1.0, 3.0),
            Vec3::new(0.5, 1.0, 0.0),
        ];
        let s = contact(&floor, &wall, 1e-6, (1e-4, false)).segments;
        assert_eq!(s.len(), 1);
        for p in s[0] {
            assert!((p.x - 0.5).abs() < 1e-6 && p.y.abs() < 1e-6);
        }
        // Its length inside the floor triangle (x = 0.5, z from -1 to 0.5).
        assert!(((s[0][1] - s[0][0]).length() - 1.5).abs() < 1e-5);
        // A neighbour sharing an edge cuts nothing.
        let neighbour = [floor[0], Vec3::new(-1.0, 0.0, 1.0), floor[1]];
        assert!(
            contact(&floor, &neighbour, 1e-6, (1e-4, false))
                .segments
                .is_empty()
        );
        // Something above the floor cuts nothing.
        let above = side.map(|p| p + Vec3::Y * 0.01);
        assert!(
            contact(&floor, &above, 1e-6, (1e-4, false))
                .segments
                .is_empty()
        );
    }

    #[test]
    fn a_flush_quad_lamp_cuts_only_its_outline() {
        // A ceiling triangle and, 0.1 mm under it, a quad lamp of two triangles facing
        // down: four outline segments, not the quad's diagonal.
        let ceiling = [
            Vec3::new(-1.0, 1.0, -1.0),
            Vec3::new(1.0, 1.0, -1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ];
        let y = 1.0 - 1e-4;
        let q = [
            Vec3::new(-0.2, y, -0.2),
            Vec3::new(0.2, y, -0.2),
            Vec3::new(0.2, y, 0.2),
            Vec3::new(-0.2, y, 0.2),
        ];
        let triangles = vec![ceiling, [q[0], q[1], q[2]], [q[0], q[2], q[3]]];
        let cuts = find_cuts(
            &triangles,
            &[true, false, false],
            &[false; 3],
            2e-4,
            1e-3,
            never(),
        )
        .unwrap()
        .cuts;
        assert_eq!(cuts[0].len(), 4, "{:?}", cuts[0]);
        for [a, b] in &cuts[0] {
            // Each runs along the outline: one coordinate stays at ±0.2.
            let on_outline = ((a.x.abs() - 0.2).abs() < 1e-5 && (a.x - b.x).abs() < 1e-5)
                || ((a.z.abs() - 0.2).abs() < 1e-5 && (a.z - b.z).abs() < 1e-5);
            assert!(on_outline, "{a} {b}");
        }
        let pieces = crate::mesh::split::split(ceiling, &cuts[0], 0.5).expect("split");
        let regions: std::collections::HashSet<u32> = pieces.iter().map(|p| p.region).collect();
        assert_eq!(regions.len(), 2);
        // The lamp covers the ceiling's pieces inside the outline (they are hidden and not
        // drawn), not those outside; the ceiling does not cover the lamp (it is behind it).
        let covers = find_cuts(
            &triangles,
            &[true, true, true],
            &[false; 3],
            2e-4,
            1e-3,
            never(),
        )
        .unwrap()
        .covers;
        assert_eq!(covers[0].len(), 2);
        assert!(covers[1].is_empty() && covers[2].is_empty());
        for p in &pieces {
            let c = (p.verts[0] + p.verts[1] + p.verts[2]) / 3.0;
            let inside = c.x.abs() < 0.2 && c.z.abs() < 0.2;
            assert_eq!(is_covered(c, &covers[0], &triangles), inside, "{c}");
        }
    }

    #[test]
    fn a_block_moved_into_another_still_splits() {
        // The Cornell box's short block moved 12 cm towards the tall one: its faces cross,
        // and one of them once made the refining triangulation fail.
        let mut scene = crate::scene::builtin::cornell_box();
        let short = scene
            .objects
            .iter()
            .position(|o| o.name.contains("short"))
            .expect("short block");
        let o = &mut scene.objects[short];
        o.world_from_local =
            glam::DMat4::from_translation(glam::DVec3::new(-0.12, 0.0, 0.0)) * o.world_from_local;
        let mesh = crate::mesh::Mesh::build(
            &scene,
            &crate::mesh::MeshSettings {
                max_elements: Some(1500),
                ..Default::default()
            },
        );
        assert!(mesh.warnings.is_empty(), "{:?}", mesh.warnings);
    }

    #[test]
    fn the_cornell_box_splits_cleanly() {
        let mesh = crate::mesh::Mesh::build(
            &crate::scene::builtin::cornell_box(),
            &crate::mesh::MeshSettings::default(),
        );
        assert!(mesh.warnings.is_empty(), "{:?}", mesh.warnings);
        // The two blocks' footprints on the floor and the lamp's outline on the ceiling.
        assert!(mesh.cut_edges.len() >= 12, "{}", mesh.cut_edges.len());
        // No ceiling patch straddles the lamp's outline (the lamp's short edges clip to
        // short pieces near the ceiling's diagonal: they must be cut all the same), and
        // exactly those inside it are covered.
        let lamp: Vec<&Vec3> = mesh
            .patches
            .iter()
            .filter(|p| p.emission.max_element() > 0.0)
            .flat_map(|p| p.verts.iter())
            .collect();
        let lo = lamp.iter().fold(Vec3::INFINITY, |a, v| a.min(**v));
        let hi = lamp.iter().fold(Vec3::NEG_INFINITY, |a, v| a.max(**v));
        let eps = 1e-5;
        let mut inside_patches = 0;
        for p in mesh
            .patches
            .iter()
            .filter(|p| p.emission.max_element() <= 0.0 && p.normal.y < -0.9 && p.verts[0].y > hi.y)
        {
            let strictly_in = |v: &Vec3| {
                v.x > lo.x + eps && v.x < hi.x - eps && v.z > lo.z + eps && v.z < hi.z - eps
            };
            let strictly_out = |v: &Vec3| {
                v.x < lo.x - eps || v.x > hi.x + eps || v.z < lo.z - eps || v.z > hi.z + eps
            };
            assert!(
                !(p.verts.iter().any(strictly_in) && p.verts.iter().any(strictly_out)),
                "ceiling patch {:?} straddles the lamp's outline",
                p.verts
            );
            let c = p.centroid();
            let inside = c.x > lo.x && c.x < hi.x && c.z > lo.z && c.z < hi.z;
            assert_eq!(p.covered, inside, "{:?}", p.verts);
            inside_patches += inside as usize;
        }
        assert!(inside_patches > 0);
    }

    #[test]
    fn a_contact_line_ending_on_an_edge_puts_a_vertex_on_both_sides() {
        use crate::scene::{Material, Object, Scene};
        use glam::DMat4;
        // A floor of two triangles sharing the diagonal x = z, and a wall standing on the
        // first whose foot ends on the diagonal at q. The second triangle touches the wall
        // only at q (no contact segment of its own): it must still get a vertex there, or
        // the first triangle's vertex at q would hang inside its edge (a T-junction).
        let object = |name: &str, positions: Vec<Vec3>, triangles: Vec<[u32; 3]>| Object {
            name: name.into(),
            world_from_local: DMat4::IDENTITY,
            triangle_material: vec![0; triangles.len()],
            positions,
            triangles,
            ..Default::default()
        };
        let floor = object(
            "floor",
            vec![
                Vec3::new(-1.0, 0.0, -1.0),
                Vec3::new(-1.0, 0.0, 1.0),
                Vec3::new(1.0, 0.0, 1.0),
                Vec3::new(1.0, 0.0, -1.0),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let (p, q) = (Vec3::new(-0.6, 0.0, 0.2), Vec3::new(0.1, 0.0, 0.1));
        let up = Vec3::Y * 0.5;
        let wall = object(
            "wall",
            vec![p, q, q + up, p + up],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let scene = Scene {
            name: "wall on a floor".into(),
            objects: vec![floor, wall],
            materials: vec![Material::diffuse("white", Vec3::splat(0.5))],
            ..Default::default()
        };
        let mesh = crate::mesh::Mesh::build(
            &scene,
            &crate::mesh::MeshSettings {
                element_size: Some(0.25),
                ..Default::default()
            },
        );
        let q = mesh.to_local(q.as_dvec3());
        for triangle in [0, 1] {
            let patches: Vec<_> = mesh
                .patches
                .iter()
                .filter(|p| p.scene_triangle == triangle)
                .collect();
            assert!(
                patches
                    .iter()
                    .any(|p| p.verts.iter().any(|v| (*v - q).length() < 1e-5)),
                "floor triangle {triangle} has no vertex at the wall's foot"
            );
            for p in &patches {
                for k in 0..3 {
                    let (a, b) = (p.verts[k], p.verts[(k + 1) % 3]);
                    let t = (q - a).dot(b - a) / (b - a).length_squared();
                    let off = (a + (b - a) * t - q).length();
                    assert!(
                        !(off < 1e-5 && t > 1e-4 && t < 1.0 - 1e-4),
                        "q hangs inside an edge of floor triangle {triangle}"
                    );
                }
            }
        }
    }
}
