//! Splitting a triangle along its discontinuity lines (contact lines from `contact`,
//! shadow lines from `shadow`): a constrained Delaunay triangulation of the triangle with
//! the segments as constraints (`spade`, which also splits constraints where they cross),
//! refined so no angle is below 25° and no piece is much larger than a patch, and the
//! pieces grouped into *regions*: pieces connected without crossing a segment. The display
//! mesh does not weld vertices on a segment across regions, so Gouraud and Hermite shading
//! jump there instead of smearing the dark underside into the lit floor.

use crate::geometry::{dtriangle_cross, triangle_cross};
use glam::{DVec2, DVec3, Vec3};
use spade::{
    AngleLimit, ConstrainedDelaunayTriangulation, Point2, RefinementParameters, Triangulation,
};

/// One piece of a split triangle: its vertices (same orientation as the triangle) and its
/// region, numbered from 0 per triangle (pieces of the same region meet without crossing
/// a contact segment).
pub(super) struct Piece {
    pub verts: [Vec3; 3],
    pub region: u32,
}

/// Panics raised inside `spade` (caught in [`split`]) are not reported on stderr: they
/// are handled, and a user would read them as a crash. Every other panic is reported by
/// the hook that was in place.
fn quiet_spade_panics() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let in_spade = info
                .location()
                .is_some_and(|l| l.file().contains("spade-") || l.file().contains("/spade/"));
            if !in_spade {
                previous(info);
            }
        }));
    });
}

/// Splits triangle `verts` along `cuts` (segments in its plane, inside it) into pieces
/// with edges no longer than about `max_len` (0: no limit). `None` when the
/// triangulation fails (then the triangle stays whole).
pub(super) fn split(verts: [Vec3; 3], cuts: &[[Vec3; 2]], max_len: f64) -> Option<Vec<Piece>> {
    let max_len = if max_len > 0.0 {
        max_len
    } else {
        f64::INFINITY
    };
    let v = verts.map(|p| p.as_dvec3());
    // A 2D frame in the triangle's plane: origin v0, axes u (along v0→v1) and w.
    let n = dtriangle_cross(&v).normalize_or_zero();
    let u = (v[1] - v[0]).normalize_or_zero();
    let w = n.cross(u);
    let to2 = |p: DVec3| {
        let q = p - v[0];
        Point2::new(q.dot(u), q.dot(w))
    };
    let to3 = |p: Point2<f64>| (v[0] + u * p.x + w * p.y).as_vec3();
    let run = |refine: bool| -> Option<Vec<Piece>> {
        let mut cdt: ConstrainedDelaunayTriangulation<Point2<f64>> =
            ConstrainedDelaunayTriangulation::new();
        for p in v {
            cdt.insert(to2(p)).ok()?;
        }
        // Cut ends are snapped onto the triangle (a point a rounding error outside would
        // grow the triangulation's hull by a sliver) and onto each other (ends of two
        // segments meeting at a corner of a footprint), within 1e-6 of the triangle's size.
        let c = v.map(to2).map(|p| DVec2::new(p.x, p.y));
        let size = (c[1] - c[0]).length().max((c[2] - c[0]).length());
        let snap = 1e-6 * size;
        let twice_area = (c[1] - c[0]).perp_dot(c[2] - c[0]);
        let mut ends: Vec<(DVec2, _)> = Vec::new();
        let mut place = |cdt: &mut ConstrainedDelaunayTriangulation<Point2<f64>>, p: Vec3| {
            let q = to2(p.as_dvec3());
            let q = DVec2::new(q.x, q.y);
            // Barycentric coordinates; those within `snap` of an edge go to zero.
            let mut b = [
                (c[2] - c[1]).perp_dot(q - c[1]) / twice_area,
                (c[0] - c[2]).perp_dot(q - c[2]) / twice_area,
                0.0,
            ];
            b[2] = 1.0 - b[0] - b[1];
            let tol = snap / size.max(1e-300);
            let b = b.map(|x| if x < tol { 0.0 } else { x });
            let sum: f64 = b.iter().sum();
            let q = (c[0] * b[0] + c[1] * b[1] + c[2] * b[2]) / sum.max(1e-300);
            if let Some(&(_, h)) = ends.iter().find(|(e, _)| (*e - q).length() <= snap) {
                return Some(h);
            }
            let h = cdt.insert(Point2::new(q.x, q.y)).ok()?;
            ends.push((q, h));
            Some(h)
        };
        let mut segments: Vec<_> = Vec::new();
        for [a, b] in cuts {
            let ha = place(&mut cdt, *a)?;
            let hb = place(&mut cdt, *b)?;
            segments.push((ha, hb));
        }
        segments.sort_unstable_by_key(|&(a, b)| if a < b { (a, b) } else { (b, a) });
        segments.dedup_by_key(|&mut (a, b)| if a < b { (a, b) } else { (b, a) });
        // Constraints are put in in pieces no longer than `max_len` (the patch length),
        // so the refinement below never needs to split them. The triangle's own edges are
        // cut at the same dyadic points the longest-edge bisection of a neighbouring,
        // unsplit triangle puts on the shared edge (halving until at most `max_len`), so
        // the neighbours' vertices match (no T-junctions beyond the contact lines' own
        // ends).
        let chain = |cdt: &mut ConstrainedDelaunayTriangulation<Point2<f64>>,
                     a: Point2<f64>,
                     b: Point2<f64>,
                     parts: u32|
         -> Option<()> {
            let mut prev = cdt.insert(a).ok()?;
            for i in 1..=parts {
                let t = i as f64 / parts as f64;
                let p = Point2::new(a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t);
                let next = if i == parts {
                    cdt.insert(b).ok()?
                } else {
                    cdt.insert(p).ok()?
                };
                if next != prev {
                    cdt.add_constraint_and_split(prev, next, |p| p);
                }
                prev = next;
            }
            Some(())
        };
        for (ha, hb) in segments {
            if ha != hb {
                let (a, b) = (cdt.vertex(ha).position(), cdt.vertex(hb).position());
                let len = ((b.x - a.x).powi(2) + (b.y - a.y).powi(2)).sqrt();
                let parts = (len / max_len).ceil().clamp(1.0, 1024.0) as u32;
                chain(&mut cdt, a, b, parts)?;
            }
        }
        for k in 0..3 {
            let (a, b) = (c[k], c[(k + 1) % 3]);
            let mut parts = 1u32;
            while (b - a).length() / parts as f64 > max_len && parts < 1 << 12 {
                parts *= 2;
            }
            chain(
                &mut cdt,
                Point2::new(a.x, a.y),
                Point2::new(b.x, b.y),
                parts,
            )?;
        }
        // Then interior points until no angle is below 25° and no piece is much larger
        // than a patch (Ruppert's refinement, constraints kept whole): contact lines that
        // end inside the triangle would otherwise leave long slivers fanning out to its
        // corners, and slivers shade in streaks.
        if refine {
            cdt.refine(
                RefinementParameters::<f64>::new()
                    .with_angle_limit(AngleLimit::from_deg(25.0))
                    .with_max_allowed_area(0.5 * max_len * max_len)
                    .keep_constraint_edges()
                    .with_max_additional_vertices(4096),
            );
        }
        // Constraint edges: the contact lines and the triangle's edges. Only the former
        // separate regions.
        let on_boundary = |p: Point2<f64>| {
            let q = DVec2::new(p.x, p.y);
            (0..3).any(|k| {
                let (a, b) = (c[k], c[(k + 1) % 3]);
                let len = (b - a).length().max(1e-300);
                ((b - a).perp_dot(q - a) / len).abs() <= 1e-9 * len
            })
        };
        let is_cut = |e: spade::handles::DirectedEdgeHandle<_, _, _, _>| {
            if !cdt.is_constraint_edge(e.as_undirected().fix()) {
                return false;
            }
            let [a, b] = e.positions();
            !(on_boundary(a)
                && on_boundary(b)
                && on_boundary(Point2::new((a.x + b.x) * 0.5, (a.y + b.y) * 0.5)))
        };
        // Faces, their regions by flood fill across non-constraint edges.
        let faces: Vec<_> = cdt.inner_faces().collect();
        let index: std::collections::HashMap<_, usize> = faces
            .iter()
            .enumerate()
            .map(|(k, f)| (f.fix(), k))
            .collect();
        let mut region = vec![u32::MAX; faces.len()];
        let mut next = 0;
        for start in 0..faces.len() {
            if region[start] != u32::MAX {
                continue;
            }
            region[start] = next;
            let mut stack = vec![start];
            while let Some(k) = stack.pop() {
                for e in faces[k].adjacent_edges() {
                    if is_cut(e) {
                        continue;
                    }
                    if let Some(other) = e.rev().face().as_inner()
                        && let Some(&j) = index.get(&other.fix())
                        && region[j] == u32::MAX
                    {
                        region[j] = next;
                        stack.push(j);
                    }
                }
            }
            next += 1;
        }
        let mut pieces = Vec::with_capacity(faces.len());
        for (k, f) in faces.iter().enumerate() {
            let p = f.positions();
            let mut t = p.map(to3);
            // spade's faces are counter-clockwise in (u, w), which is the triangle's own
            // orientation (n = u × w); keep it.
            let nn = triangle_cross(&t);
            if nn.dot(n.as_vec3()) < 0.0 {
                t.swap(1, 2);
            }
            pieces.push(Piece {
                verts: t,
                region: region[k],
            });
        }
        Some(pieces)
    };
    // The triangulation asserts on inputs it cannot handle (its refinement, with the
    // triangle's edges kept whole, can fail to place a point): then the triangle is split
    // without refinement, and failing that it stays whole rather than ending the load.
    quiet_spade_panics();
    let attempt = |refine: bool| {
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run(refine)))
            .ok()
            .flatten()
            .filter(|p| !p.is_empty())
    };
    attempt(true).or_else(|| attempt(false))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::triangle_area;

    #[test]
    fn splitting_keeps_area_orientation_and_separates_regions() {
        let t = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, -2.0),
        ];
        // A closed square footprint inside the triangle.
        let q = [
            Vec3::new(0.2, 0.0, -0.2),
            Vec3::new(0.6, 0.0, -0.2),
            Vec3::new(0.6, 0.0, -0.6),
            Vec3::new(0.2, 0.0, -0.6),
        ];
        let cuts: Vec<[Vec3; 2]> = (0..4).map(|k| [q[k], q[(k + 1) % 4]]).collect();
        let pieces = split(t, &cuts, 0.5).expect("split");
        let n = triangle_cross(&t);
        let area = |v: &[Vec3; 3]| triangle_area(v) as f64;
        let total: f64 = pieces.iter().map(|p| area(&p.verts)).sum();
        assert!((total - area(&t)).abs() < 1e-6, "{total}");
        for p in &pieces {
            let m = triangle_cross(&p.verts);
            assert!(m.dot(n) > 0.0, "orientation kept");
        }
        // Two regions: inside the square (area 0.16) and outside.
        let mut regions: Vec<u32> = pieces.iter().map(|p| p.region).collect();
        regions.sort();
        regions.dedup();
        assert_eq!(regions, vec![0, 1]);
        let inside: f64 = pieces
            .iter()
            .filter(|p| {
                let c = (p.verts[0] + p.verts[1] + p.verts[2]) / 3.0;
                c.x > 0.2 && c.x < 0.6 && c.z < -0.2 && c.z > -0.6
            })
            .map(|p| area(&p.verts))
            .sum();
        assert!((inside - 0.16).abs() < 1e-6, "{inside}");
        let inside_region = pieces
            .iter()
            .find(|p| {
                let c = (p.verts[0] + p.verts[1] + p.verts[2]) / 3.0;
                c.x > 0.2 && c.x < 0.6 && c.z < -0.2 && c.z > -0.6
            })
            .unwrap()
            .region;
        for p in &pieces {
            let c = (p.verts[0] + p.verts[1] + p.verts[2]) / 3.0;
            let is_inside = c.x > 0.2 && c.x < 0.6 && c.z < -0.2 && c.z > -0.6;
            assert_eq!(p.region == inside_region, is_inside);
        }
    }
}
