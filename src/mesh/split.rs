//! Splitting a triangle along its discontinuity lines (contact lines from `contact`,
//! shadow lines from `shadow`): a constrained Delaunay triangulation of the triangle with
//! the segments as constraints (`spade`, which also splits constraints where they cross),
//! refined so no angle is below 25° and no piece is much larger than a patch (or, where
//! that refinement fails and the lines alone fan out, given a lattice of points a patch
//! apart), and the pieces grouped into *regions*: pieces connected without crossing a
//! segment. The display mesh does not weld vertices on a segment across regions, so
//! Gouraud and Hermite shading jump there instead of smearing the dark underside into the
//! lit floor.

use crate::geometry::{dtriangle_cross, triangle_cross};
use glam::{DVec2, DVec3, Vec3};
use spade::handles::FixedVertexHandle;
use spade::{
    AngleLimit, ConstrainedDelaunayTriangulation, Point2, RefinementParameters, Triangulation,
};

/// A point on a constrained path: a vertex already in the triangulation, or a position to
/// insert.
#[derive(Clone, Copy)]
enum Stop {
    Vertex(FixedVertexHandle),
    At(f64, f64),
}

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
///
/// The triangulation asserts on inputs it cannot handle: its refinement, with the
/// triangle's edges kept whole, can fail to place a point ("Failed to locate position").
/// It did on 254 of NegativeScaleTest's triangles, among them the two halves of its
/// background, cut by 176 and 492 contact segments, whose pieces then fanned from the
/// labels' outlines across the whole plane and shaded in streaks, and on 2,748 of
/// Sponza's (without `keep_constraint_edges` the refinement ran to its 4,096-vertex cap
/// on small triangles instead: 644,224 patches for NegativeScaleTest's 26,751). Then the
/// triangle is split along its lines alone, and where that leaves a piece longer than
/// [`FAN_LENGTH`] patches, with a lattice of points about a patch apart ([`lattice`]),
/// which keeps its pieces within that; failing both it stays whole rather than ending the
/// load. (The lattice only where the lines fan out: on the built-in Cornell box, whose
/// floor's refinement fails too, the lattice everywhere moved its Hermite picture from
/// 1.53 to 1.58 % RMS against the path tracer, penumbrae 1.17 to 1.31 %.)
pub(super) fn split(verts: [Vec3; 3], cuts: &[[Vec3; 2]], max_len: f64) -> Option<Vec<Piece>> {
    if let Some(pieces) = split_as(verts, cuts, max_len, Quality::Refined) {
        return Some(pieces);
    }
    let plain = split_as(verts, cuts, max_len, Quality::Plain);
    let fans = |pieces: &Vec<Piece>| longest_edge(pieces) as f64 > FAN_LENGTH * max_len;
    if max_len > 0.0
        && plain.as_ref().is_none_or(fans)
        && let Some(pieces) = split_as(verts, cuts, max_len, Quality::Lattice)
    {
        return Some(pieces);
    }
    plain
}

/// The longest piece, in patch lengths, that the lines alone may leave (see [`split`]):
/// the lattice keeps its pieces within it (see [`lattice`]).
const FAN_LENGTH: f64 = 3.0;

/// The longest edge of any piece.
fn longest_edge(pieces: &[Piece]) -> f32 {
    pieces
        .iter()
        .flat_map(|p| (0..3).map(|k| (p.verts[k] - p.verts[(k + 1) % 3]).length()))
        .fold(0.0, f32::max)
}

/// [`split`] with the given way of avoiding slivers; `None` where the triangulation
/// fails.
fn split_as(
    verts: [Vec3; 3],
    cuts: &[[Vec3; 2]],
    max_len: f64,
    quality: Quality,
) -> Option<Vec<Piece>> {
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
    let run = || -> Option<Vec<Piece>> {
        let mut cdt: ConstrainedDelaunayTriangulation<Point2<f64>> =
            ConstrainedDelaunayTriangulation::new();
        for p in v {
            cdt.insert(to2(p)).ok()?;
        }
        // Cut ends are snapped onto the triangle (a point a rounding error outside would
        // grow the triangulation's hull by a sliver) and onto each other (ends of two
        // segments meeting at a corner of a footprint), within 1e-6 of the triangle's size
        // or eight roundings of its f32 coordinates, whichever is larger: the ends are
        // found in f32, so a small triangle far from the origin has ends a few of its
        // coordinates' roundings off its edges (NegativeScaleTest's spheres: 8 cm
        // triangles 3.4 m out, ends 1.1–1.4·10⁻⁷ m off, beyond 1e-6 of the size), and an
        // end left a hair inside an edge leaves a sliver between it and the edge through
        // which the regions on either side of its segment join.
        let c = v.map(to2).map(|p| DVec2::new(p.x, p.y));
        let size = (c[1] - c[0]).length().max((c[2] - c[0]).length());
        let magnitude = verts
            .iter()
            .map(|p| p.abs().max_element() as f64)
            .fold(0.0, f64::max);
        let snap = (1e-6 * size).max(8.0 * f32::EPSILON as f64 * magnitude);
        let twice_area = (c[1] - c[0]).perp_dot(c[2] - c[0]);
        // Each end placed: its position, vertex and whether it lies on each of the
        // triangle's edges (edge k runs from corner k to corner k + 1).
        let mut ends: Vec<(DVec2, FixedVertexHandle, [bool; 3])> = Vec::new();
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
            if let Some(&(_, h, _)) = ends.iter().find(|(e, _, _)| (*e - q).length() <= snap) {
                return Some(h);
            }
            let h = cdt.insert(Point2::new(q.x, q.y)).ok()?;
            // Edge k lies opposite corner k + 2.
            ends.push((q, h, [0, 1, 2].map(|k| b[(k + 2) % 3] == 0.0)));
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
        // Constrains the path through `points` (vertices already in, or positions to
        // insert), one edge between each two in a row.
        let path = |cdt: &mut ConstrainedDelaunayTriangulation<Point2<f64>>,
                    points: &[Stop]|
         -> Option<()> {
            let mut prev: Option<FixedVertexHandle> = None;
            for p in points {
                let next = match *p {
                    Stop::Vertex(h) => h,
                    Stop::At(x, y) => cdt.insert(Point2::new(x, y)).ok()?,
                };
                if let Some(prev) = prev
                    && prev != next
                {
                    cdt.add_constraint_and_split(prev, next, |p| p);
                }
                prev = Some(next);
            }
            Some(())
        };
        // Constraints are put in in pieces no longer than `max_len` (the patch length),
        // so the refinement below never needs to split them.
        for &(ha, hb) in &segments {
            if ha != hb {
                let (a, b) = (cdt.vertex(ha).position(), cdt.vertex(hb).position());
                let len = ((b.x - a.x).powi(2) + (b.y - a.y).powi(2)).sqrt();
                let parts = (len / max_len).ceil().clamp(1.0, 1024.0) as u32;
                let mut stops = vec![Stop::Vertex(ha)];
                for i in 1..parts {
                    let t = i as f64 / parts as f64;
                    stops.push(Stop::At(a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t));
                }
                stops.push(Stop::Vertex(hb));
                path(&mut cdt, &stops)?;
            }
        }
        // The triangle's own edges are cut at the same dyadic points the longest-edge
        // bisection of a neighbouring, unsplit triangle puts on the shared edge (halving
        // until at most `max_len`), so the neighbours' vertices match (no T-junctions
        // beyond the contact lines' own ends); and at the ends of segments that were
        // snapped onto them, so that the edge runs through those ends. A segment ending
        // a rounding error beside the edge would otherwise leave a sliver of a piece
        // around its end, through which the regions on either side of the segment join.
        for k in 0..3 {
            let (a, b) = (c[k], c[(k + 1) % 3]);
            let mut parts = 1u32;
            while (b - a).length() / parts as f64 > max_len && parts < 1 << 12 {
                parts *= 2;
            }
            let along = |p: DVec2| (p - a).dot(b - a) / (b - a).length_squared().max(1e-300);
            let mut stops: Vec<(f64, Stop)> = (0..=parts)
                .map(|i| {
                    let t = i as f64 / parts as f64;
                    let p = if i == parts { b } else { a + (b - a) * t };
                    (t, Stop::At(p.x, p.y))
                })
                .collect();
            stops.extend(
                ends.iter()
                    .filter(|e| e.2[k])
                    .map(|&(q, h, _)| (along(q), Stop::Vertex(h))),
            );
            stops.sort_by(|x, y| x.0.total_cmp(&y.0));
            let stops: Vec<Stop> = stops.into_iter().map(|s| s.1).collect();
            path(&mut cdt, &stops)?;
        }
        // Then interior points until no angle is below 25° and no piece is much larger
        // than a patch (Ruppert's refinement, constraints kept whole): contact lines that
        // end inside the triangle would otherwise leave long slivers fanning out to its
        // corners, and slivers shade in streaks.
        if quality == Quality::Refined {
            cdt.refine(
                RefinementParameters::<f64>::new()
                    .with_angle_limit(AngleLimit::from_deg(25.0))
                    .with_max_allowed_area(0.5 * max_len * max_len)
                    .keep_constraint_edges()
                    .with_max_additional_vertices(4096),
            );
        }
        if quality == Quality::Lattice {
            for q in lattice(c, max_len, &segment_positions(&cdt, &segments)) {
                cdt.insert(Point2::new(q.x, q.y)).ok()?;
            }
        }
        // Constraint edges (the contact lines and the triangle's edges) bound regions. The
        // triangle's edges must too: where rounding leaves the points on an edge a hair
        // off one line, the triangulation's hull grows a zero-area face beyond the edge,
        // and a flood across it would join the regions on either side of a segment that
        // ends on the edge.
        let is_cut = |e: spade::handles::DirectedEdgeHandle<_, _, _, _>| {
            cdt.is_constraint_edge(e.as_undirected().fix())
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
        // A face whose corners all lie within `snap` of one of the triangle's edges is a
        // sliver of the hull along that edge (its points a rounding apart from one
        // line), not a part of the triangle: dropped.
        let off_edge = |p: Point2<f64>, k: usize| {
            let (a, b) = (c[k], c[(k + 1) % 3]);
            (b - a).perp_dot(DVec2::new(p.x, p.y) - a).abs() / (b - a).length().max(1e-300)
        };
        let along_an_edge =
            |p: [Point2<f64>; 3]| (0..3).any(|k| p.iter().all(|&q| off_edge(q, k) <= snap));
        let mut pieces = Vec::with_capacity(faces.len());
        for (k, f) in faces.iter().enumerate() {
            let p = f.positions();
            if along_an_edge(p) {
                continue;
            }
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
    quiet_spade_panics();
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(run))
        .ok()
        .flatten()
        .filter(|p| !p.is_empty())
}

/// How the pieces of a split triangle are kept from long slivers.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Quality {
    /// Ruppert's refinement.
    Refined,
    /// A lattice of interior points (see [`lattice`]).
    Lattice,
    /// Neither: the constrained Delaunay triangulation of the lines alone.
    Plain,
}

/// The constrained segments' end positions.
fn segment_positions(
    cdt: &ConstrainedDelaunayTriangulation<Point2<f64>>,
    segments: &[(FixedVertexHandle, FixedVertexHandle)],
) -> Vec<[DVec2; 2]> {
    segments
        .iter()
        .map(|&(a, b)| {
            [a, b].map(|h| {
                let p = cdt.vertex(h).position();
                DVec2::new(p.x, p.y)
            })
        })
        .collect()
}

/// Points of a square lattice of spacing `step` inside the triangle `c` (its own 2D
/// frame), leaving out those within a quarter step of its edges or of a `segment`: a
/// piece then spans at most about a step, wherever the lines run, and none is made
/// thinner than a quarter step by a lattice point.
fn lattice(c: [DVec2; 3], step: f64, segments: &[[DVec2; 2]]) -> Vec<DVec2> {
    let lo = c[0].min(c[1]).min(c[2]);
    let hi = c[0].max(c[1]).max(c[2]);
    if step.is_nan() || step <= 0.0 || ((hi - lo) / step).max_element() > 1024.0 {
        return Vec::new();
    }
    let margin = 0.25 * step;
    let near = |p: DVec2, [a, b]: [DVec2; 2]| {
        let ab = b - a;
        let t = ((p - a).dot(ab) / ab.length_squared().max(1e-300)).clamp(0.0, 1.0);
        (a + ab * t - p).length() < margin
    };
    let edges = [[c[0], c[1]], [c[1], c[2]], [c[2], c[0]]];
    let twice_area = (c[1] - c[0]).perp_dot(c[2] - c[0]);
    let inside = |p: DVec2| {
        edges
            .iter()
            .all(|[a, b]| (*b - *a).perp_dot(p - *a) * twice_area.signum() > 0.0)
    };
    let mut points = Vec::new();
    let mut y = lo.y + 0.5 * step;
    while y < hi.y {
        let mut x = lo.x + 0.5 * step;
        while x < hi.x {
            let p = DVec2::new(x, y);
            if inside(p)
                && !edges.iter().any(|e| near(p, *e))
                && !segments.iter().any(|s| near(p, *s))
            {
                points.push(p);
            }
            x += step;
        }
        y += step;
    }
    points
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

    /// The built-in Cornell box's lamp, 0.1 mm under the ceiling, outlines its footprint
    /// on the ceiling's triangle; the triangle's diagonal crosses the footprint, so two of
    /// the outline's segments end on the diagonal, where f32 rounding leaves them a hair
    /// off the line. The pieces under the lamp must still form a region of their own
    /// (before the fix they shared one region with the rest of the ceiling through a
    /// zero-area face of the triangulation's hull, and Gouraud shading averaged the dark
    /// footprint into the lit ceiling around it). The footprint's area is the polygon's,
    /// by the shoelace formula; 1e-9 m² allows for f32 vertices.
    #[test]
    fn segments_ending_a_hair_off_an_edge_still_separate_regions() {
        let y = 0.2744;
        let t = [
            Vec3::new(0.278, y, -0.2796),
            Vec3::new(0.278, y, 0.2796),
            Vec3::new(-0.278, y, 0.2796),
        ];
        let (x0, x1, z0, z1) = (-0.052100137, 0.065, -0.052599996, 0.052399993);
        let on_diagonal = 0.052298997;
        let cuts = [
            [Vec3::new(x1, y, z0), Vec3::new(x1, y, z1)],
            [Vec3::new(x1, y, z1), Vec3::new(x0, y, z1)],
            [Vec3::new(on_diagonal, y, z0), Vec3::new(x1, y, z0)],
        ];
        // The footprint's part in this triangle: (x1, z0), (x1, z1), (x0, z1) and the
        // diagonal between (x0, z1) and (on_diagonal, z0).
        let polygon = [(x1, z0), (x1, z1), (x0, z1), (on_diagonal, z0)];
        let footprint: f64 = (0..4)
            .map(|k| {
                let (a, b) = (polygon[k], polygon[(k + 1) % 4]);
                (a.0 as f64 * b.1 as f64 - b.0 as f64 * a.1 as f64) / 2.0
            })
            .sum::<f64>()
            .abs();
        let inside = |p: &Piece| {
            let c = (p.verts[0] + p.verts[1] + p.verts[2]) / 3.0;
            // On the triangle's side of its diagonal from (0.278, −0.2796) to (−0.278, 0.2796).
            c.x < x1 && c.z > z0 && c.z < z1 && c.z * 0.278 > -c.x * 0.2796
        };
        for max_len in [0.0, 0.05, 0.2] {
            let pieces = split(t, &cuts, max_len).expect("split");
            let region = pieces
                .iter()
                .find(|p| inside(p) && triangle_area(&p.verts) > 1e-6)
                .expect("a piece under the lamp")
                .region;
            let (mut under, mut outside) = (0.0f64, 0.0f64);
            for p in &pieces {
                let a = triangle_area(&p.verts) as f64;
                match (inside(p), p.region == region) {
                    (true, true) => under += a,
                    (false, true) => outside += a,
                    // Slivers along the diagonal form regions of their own; they are
                    // dropped when the patches are made (under 1e-7 of the triangle).
                    (true, false) => assert!(
                        a <= 1e-7 * triangle_area(&t) as f64,
                        "max_len {max_len}: a piece under the lamp in another region: {:?} {a} {} {region}",
                        p.verts,
                        p.region
                    ),
                    (false, false) => {}
                }
            }
            assert!(
                outside < 1e-9,
                "max_len {max_len}: {outside} m² outside in the lamp's region"
            );
            assert!(
                (under - footprint).abs() < 1e-9,
                "max_len {max_len}: {under} against {footprint}"
            );
        }
    }

    #[test]
    fn the_lattice_fallback_keeps_pieces_within_a_few_patch_lengths() {
        // A 10 m triangle with a 30 cm footprint near one corner and a short line in the
        // middle, cut into patches of 1 m: the triangulation of the lines alone fans from
        // them to the far corners. With the lattice (what a triangle gets when spade's
        // refinement fails) no piece is longer than 3 m: a constrained Delaunay edge is a
        // chord of a circle empty of vertices, and no circle wider than about 1.46 steps
        // (a lattice cell's half diagonal, 0.71, plus the quarter-step margin kept free
        // around the lines and edges, plus half a step between the points put on the
        // lines) is empty of the lattice, the lines' and the edges' points.
        let t = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, -10.0),
        ];
        let q = [
            Vec3::new(0.5, 0.0, -0.5),
            Vec3::new(0.8, 0.0, -0.5),
            Vec3::new(0.8, 0.0, -0.8),
            Vec3::new(0.5, 0.0, -0.8),
        ];
        let mut cuts: Vec<[Vec3; 2]> = (0..4).map(|k| [q[k], q[(k + 1) % 4]]).collect();
        cuts.push([Vec3::new(3.0, 0.0, -3.0), Vec3::new(3.4, 0.0, -3.2)]);
        let step = 1.0;
        let plain = split_as(t, &cuts, step, Quality::Plain).expect("plain");
        assert!(
            longest_edge(&plain) > (FAN_LENGTH * step) as f32,
            "the lines alone fan out"
        );
        let pieces = split_as(t, &cuts, step, Quality::Lattice).expect("lattice");
        let longest = longest_edge(&pieces);
        assert!(
            longest <= (FAN_LENGTH * step) as f32,
            "longest edge {longest}"
        );
        let n = triangle_cross(&t);
        let total: f64 = pieces.iter().map(|p| triangle_area(&p.verts) as f64).sum();
        assert!((total - triangle_area(&t) as f64).abs() < 1e-4, "{total}");
        assert!(pieces.iter().all(|p| triangle_cross(&p.verts).dot(n) > 0.0));
        // The footprint is a region of its own, of its own area.
        let inside = |p: &Piece| {
            let c = (p.verts[0] + p.verts[1] + p.verts[2]) / 3.0;
            (0.5..0.8).contains(&c.x) && (-0.8..-0.5).contains(&c.z)
        };
        let region = pieces.iter().find(|p| inside(p)).expect("under").region;
        let under: f64 = pieces
            .iter()
            .filter(|p| p.region == region)
            .map(|p| triangle_area(&p.verts) as f64)
            .sum();
        assert!((under - 0.09).abs() < 1e-6, "{under}");
    }

    #[test]
    fn lattice_points_keep_clear_of_the_lines_and_the_edges() {
        let c = [
            DVec2::new(0.0, 0.0),
            DVec2::new(6.0, 0.0),
            DVec2::new(0.0, 6.0),
        ];
        let segment = [DVec2::new(1.0, 1.0), DVec2::new(3.0, 1.5)];
        let points = lattice(c, 0.5, &[segment]);
        assert!(!points.is_empty());
        let distance = |p: DVec2, [a, b]: [DVec2; 2]| {
            let t = ((p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
            (a + (b - a) * t - p).length()
        };
        for p in &points {
            assert!(p.x > 0.0 && p.y > 0.0 && p.x + p.y < 6.0, "{p} outside");
            for line in [segment, [c[0], c[1]], [c[1], c[2]], [c[2], c[0]]] {
                assert!(
                    distance(*p, line) >= 0.125 - 1e-9,
                    "{p} within a quarter step"
                );
            }
        }
        // Every point of the triangle away from the lines has a lattice point within a
        // step (none of the lattice is missing).
        let probe = DVec2::new(4.0, 0.9);
        assert!(points.iter().any(|p| (*p - probe).length() <= 0.5));
    }

    /// NegativeScaleTest's sphere triangle 2517 (8 cm across, 3.4 m from the origin),
    /// cut where it passes through the background (z = −0.15) and a plate (z = −0.10):
    /// each cut runs from one edge to another, so the triangle falls into three parts.
    /// The cuts' ends were found in f32 and lie 1.1–1.4·10⁻⁷ m off the edges, beyond
    /// 1e-6 of the triangle's size; before the ends were snapped within the coordinates'
    /// rounding, the corner behind the background shared a region with the middle part
    /// through a sliver between an end and its edge (the display then welded the vertices
    /// on the cut, and the corner's light, 1.67 W/m², spread to the dark side).
    #[test]
    fn cuts_ending_a_rounding_off_the_edges_of_a_far_triangle_separate_three_regions() {
        let t = [
            Vec3::new(3.3766818, -1.3071713, -0.11728822),
            Vec3::new(3.3354087, -1.361805, -0.081228875),
            Vec3::new(3.3228703, -1.3482795, -0.15638438),
        ];
        let behind_background = [
            Vec3::new(3.331658, -1.3415664, -0.14999992),
            Vec3::new(3.3239355, -1.3494284, -0.1499999),
        ];
        let behind_plate = [
            Vec3::new(3.3568935, -1.3333653, -0.09999966),
            Vec3::new(3.332277, -1.3584268, -0.09999965),
        ];
        let pieces = split(t, &[behind_background, behind_plate], 0.8).expect("split");
        let mut regions: Vec<u32> = pieces.iter().map(|p| p.region).collect();
        regions.sort();
        regions.dedup();
        assert_eq!(regions.len(), 3);
        // Each corner's region has the area of the triangle the cut takes off it
        // (closed form from the inputs), to f32 rounding of the pieces' areas; all
        // regions together the triangle's.
        let area = |v: &[Vec3; 3]| triangle_area(v) as f64;
        let region_area = |corner: Vec3| {
            let r = pieces
                .iter()
                .find(|p| p.verts.contains(&corner))
                .expect("corner")
                .region;
            pieces
                .iter()
                .filter(|p| p.region == r)
                .map(|p| area(&p.verts))
                .sum::<f64>()
        };
        let cut_off = |corner: Vec3, cut: [Vec3; 2]| area(&[corner, cut[0], cut[1]]);
        for (corner, cut) in [(t[2], behind_background), (t[1], behind_plate)] {
            let (got, want) = (region_area(corner), cut_off(corner, cut));
            assert!((got - want).abs() < 1e-4 * want, "{got} vs {want}");
        }
        let total: f64 = pieces.iter().map(|p| area(&p.verts)).sum();
        assert!((total - area(&t)).abs() < 1e-5 * area(&t), "{total}");
    }
}
