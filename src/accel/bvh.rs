//! Binned-SAH BVH over triangles, with any-hit transmittance and closest-hit queries.

use glam::Vec3;

use super::Hit;
use super::wide::WideBvh;

/// Bins per axis for the SAH sweep; 16 is the usual quality/speed balance (Wald 2007).
const BINS: usize = 16;
/// Leaves hold at most this many triangles.
const MAX_LEAF: usize = 4;
/// Traversal stack depth; a binned SAH tree over 2³² triangles stays far below this
/// unless degenerate, and the builder caps depth at `MAX_DEPTH` to keep it so.
pub(super) const STACK: usize = 96;
const MAX_DEPTH: usize = 80;

#[derive(Clone, Copy, Debug)]
pub(super) struct Node {
    pub(super) lo: Vec3,
    pub(super) hi: Vec3,
    /// Interior: index of the left child (right = left + 1). Leaf: first triangle.
    pub(super) start: u32,
    /// 0 for interior nodes, else the number of triangles in the leaf.
    pub(super) count: u32,
}

/// A triangle prepared for Möller–Trumbore: a vertex and two edges.
#[derive(Clone, Copy, Debug)]
pub(super) struct Tri {
    pub(super) v0: Vec3,
    pub(super) e1: Vec3,
    pub(super) e2: Vec3,
    /// Index in the caller's triangle list.
    pub(super) id: u32,
    /// Fraction of light passing through, 0 = opaque.
    pub(super) transmittance: f32,
}

/// The share of a segment at its start ([`Bvh::transmittance`]'s `a`, the receiving end)
/// within which hits are ignored: 40 µm on a 40 m segment, a tenth of the lift that keeps
/// the start off its own surface in a scene that size. It was 1e-4, as at the end: 4 mm
/// there, and a surface touching a receiver did not shade it from a source that far.
pub const START_MARGIN: f32 = 1e-6;

/// The share of a segment at its end (the source) within which hits are ignored: what
/// touches the source's sample point only grazes the segment there. The shaft test
/// (`accel::shaft`) proves visibility for segments shortened by the same share.
pub const END_MARGIN: f32 = 1e-4;

/// Most cut-outs [`Bvh::stopping_hit`] lets a ray pass before it takes the ray to stop.
pub const MAX_PASSES: usize = 64;

/// Bounding volume hierarchy over a fixed set of triangles.
#[derive(Clone, Default)]
pub struct Bvh {
    pub(super) nodes: Vec<Node>,
    pub(super) tris: Vec<Tri>,
    /// The shadow-ray engine (`accel/wide.rs`): 4-wide, four triangles per leaf, about
    /// four times our binary tree's rate on the occlusion benchmark
    /// (examples/bvh_compare.rs).
    wide: Option<WideBvh>,
}

impl std::fmt::Debug for Bvh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bvh")
            .field("nodes", &self.nodes.len())
            .field("triangles", &self.tris.len())
            .finish()
    }
}

#[derive(Clone, Copy)]
struct Aabb {
    lo: Vec3,
    hi: Vec3,
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        lo: Vec3::splat(f32::INFINITY),
        hi: Vec3::splat(f32::NEG_INFINITY),
    };
    fn grow(&mut self, p: Vec3) {
        self.lo = self.lo.min(p);
        self.hi = self.hi.max(p);
    }
    fn merge(&mut self, o: &Aabb) {
        self.lo = self.lo.min(o.lo);
        self.hi = self.hi.max(o.hi);
    }
    fn area(&self) -> f32 {
        let d = (self.hi - self.lo).max(Vec3::ZERO);
        d.x * d.y + d.y * d.z + d.z * d.x
    }
}

impl Bvh {
    /// Builds the hierarchy over `triangles` (vertex positions) with per-triangle
    /// `transmittance` (same length, or empty for all opaque). Triangles with non-finite
    /// coordinates are left out.
    pub fn build(triangles: &[[Vec3; 3]], transmittance: &[f32]) -> Bvh {
        let mut tris: Vec<Tri> = triangles
            .iter()
            .enumerate()
            .filter(|(_, t)| t.iter().all(|p| p.is_finite()))
            .map(|(i, t)| Tri {
                v0: t[0],
                e1: t[1] - t[0],
                e2: t[2] - t[0],
                id: i as u32,
                transmittance: transmittance.get(i).copied().unwrap_or(0.0).clamp(0.0, 1.0),
            })
            .collect();
        let mut nodes = Vec::with_capacity(tris.len() * 2 / MAX_LEAF + 1);
        let centroids: Vec<Vec3> = tris.iter().map(|t| t.v0 + (t.e1 + t.e2) / 3.0).collect();
        let mut order: Vec<u32> = (0..tris.len() as u32).collect();
        nodes.push(Node {
            lo: Vec3::ZERO,
            hi: Vec3::ZERO,
            start: 0,
            count: 0,
        });
        if !tris.is_empty() {
            build_node(
                &mut nodes,
                0,
                &tris,
                &centroids,
                &mut order,
                0,
                tris.len(),
                0,
            );
        }
        tris = order.iter().map(|&i| tris[i as usize]).collect();
        let positions: Vec<[Vec3; 3]> = tris.iter().map(|t| triangles[t.id as usize]).collect();
        let ids: Vec<u32> = tris.iter().map(|t| t.id).collect();
        let through: Vec<f32> = tris.iter().map(|t| t.transmittance).collect();
        let wide = WideBvh::build(&positions, &ids, &through);
        Bvh { nodes, tris, wide }
    }

    /// Number of triangles in the hierarchy.
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// Whether the hierarchy holds no triangle.
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// Fraction of light passing along the open segment from `a` to `b`: the product of the
    /// transmittances of the triangles it crosses, 0 as soon as an opaque one is crossed
    /// (any-hit early exit). Hits on the triangles in `skip` (the segment's own source and
    /// target surfaces), within the first [`START_MARGIN`] and within the last
    /// [`END_MARGIN`] of the segment are ignored; the caller offsets the endpoints off their
    /// surfaces by a scene-relative epsilon. `a` is the end where the light is received
    /// (a receiver's sample point, a probe point), whose surroundings matter most: what
    /// touches the receiver shades it.
    pub fn transmittance(&self, a: Vec3, b: Vec3, skip: [u32; 2]) -> f32 {
        self.through(a, b - a, (START_MARGIN, 1.0 - END_MARGIN), skip)
    }

    /// Fraction of light reaching `origin` from infinitely far along `direction` (the sun,
    /// a directional light, the sky): the product of the transmittances of the triangles
    /// the ray `origin + t·direction` crosses for every t > 0, as the path-traced
    /// reference's rays count them ([`Bvh::stopping_hit`]); only the triangles in `skip`
    /// are ignored, and the caller offsets `origin` off its surface. [`Bvh::transmittance`]
    /// towards a point beyond the scene would not do: its margin of 1e-4 of the segment
    /// is centimetres there, and an occluder that close to the origin went unseen (a leaf
    /// 4 mm over a vase's rim, the wall that a surface runs into).
    pub fn transmittance_toward(&self, origin: Vec3, direction: Vec3, skip: [u32; 2]) -> f32 {
        if direction == Vec3::ZERO {
            return 1.0;
        }
        self.through(origin, direction, (0.0, f32::INFINITY), skip)
    }

    /// The transmittance along `origin + t·dir` for t in (`t_min`, `t_max`), by the wide
    /// tree; 1 where there is nothing to cross or the ray is not finite.
    fn through(&self, origin: Vec3, dir: Vec3, (t_min, t_max): (f32, f32), skip: [u32; 2]) -> f32 {
        let Some(wide) = &self.wide else {
            return 1.0;
        };
        if !origin.is_finite() || !dir.is_finite() {
            return 1.0;
        }
        wide.transmittance(origin, dir, t_min, t_max, skip)
    }

    /// [`Bvh::transmittance`] by our own binary tree: kept as the baseline of
    /// examples/bvh_compare.rs and checked by the same property tests.
    pub fn transmittance_binary(&self, a: Vec3, b: Vec3, skip: [u32; 2]) -> f32 {
        if self.tris.is_empty() {
            return 1.0;
        }
        let dir = b - a;
        let inv = dir.recip();
        let (t_min, t_max) = (START_MARGIN, 1.0 - END_MARGIN);
        let mut stack = [0u32; STACK];
        let mut sp = 1;
        let mut through = 1.0f32;
        while sp > 0 {
            sp -= 1;
            let node = &self.nodes[stack[sp] as usize];
            if !slab(node, a, inv, t_max) {
                continue;
            }
            if node.count == 0 {
                if sp + 2 > STACK {
                    continue;
                }
                // Nearer child first: occluders near the segment's start are found sooner.
                let (near, far) = self.order_children(node, a, dir);
                stack[sp] = far;
                stack[sp + 1] = near;
                sp += 2;
                continue;
            }
            for tri in &self.tris[node.start as usize..(node.start + node.count) as usize] {
                if tri.id == skip[0] || tri.id == skip[1] {
                    continue;
                }
                if let Some((t, _, _)) = intersect(tri, a, dir)
                    && t > t_min
                    && t < t_max
                {
                    through *= tri.transmittance;
                    if through <= 0.0 {
                        return 0.0;
                    }
                }
            }
        }
        through
    }

    /// Whether anything opaque or partly opaque lies on the open segment `a`–`b`.
    pub fn occluded(&self, a: Vec3, b: Vec3) -> bool {
        self.transmittance(a, b, [u32::MAX; 2]) < 1.0
    }

    /// Nearest hit along `origin + t·direction` for `t` in (`t_min`, `t_max`), ignoring
    /// the triangle `skip` (pass `u32::MAX` for none).
    pub fn closest_hit(
        &self,
        origin: Vec3,
        direction: Vec3,
        t_min: f32,
        t_max: f32,
        skip: u32,
    ) -> Option<Hit> {
        let wide = self.wide.as_ref()?;
        if !origin.is_finite() || !direction.is_finite() {
            return None;
        }
        wide.closest_hit(origin, direction, t_min, t_max, skip)
    }

    /// [`Bvh::closest_hit`] by our own binary tree: the baseline of
    /// examples/bvh_compare.rs, checked by the same property tests.
    pub fn closest_hit_binary(
        &self,
        origin: Vec3,
        direction: Vec3,
        t_min: f32,
        t_max: f32,
        skip: u32,
    ) -> Option<Hit> {
        if self.tris.is_empty() {
            return None;
        }
        let inv = direction.recip();
        let mut best: Option<Hit> = None;
        let mut t_best = t_max;
        let mut stack = [0u32; STACK];
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let node = &self.nodes[stack[sp] as usize];
            if !slab(node, origin, inv, t_best) {
                continue;
            }
            if node.count == 0 {
                if sp + 2 > STACK {
                    continue;
                }
                // Visit the nearer child first: push it last.
                let (near, far) = self.order_children(node, origin, direction);
                stack[sp] = far;
                stack[sp + 1] = near;
                sp += 2;
                continue;
            }
            for tri in &self.tris[node.start as usize..(node.start + node.count) as usize] {
                if tri.id == skip {
                    continue;
                }
                if let Some((t, u, v)) = intersect(tri, origin, direction)
                    && t > t_min
                    && t < t_best
                {
                    t_best = t;
                    best = Some(Hit {
                        t,
                        triangle: tri.id,
                        u,
                        v,
                        transmittance: tri.transmittance,
                    });
                }
            }
        }
        best
    }

    /// The first surface along `origin + t·direction` (t > 0) that stops the ray, leaving
    /// triangle `skip`, and the point where it stops. A triangle of transmittance τ > 0 (an
    /// alpha cut-out's uncovered share, glass) lets the ray through where `pass(τ)` says
    /// so, a draw the caller makes true with probability τ: the ray then goes on from
    /// there, past that triangle. `None` where the ray leaves the scene, or passes
    /// [`MAX_PASSES`] cut-outs.
    pub fn stopping_hit(
        &self,
        origin: Vec3,
        direction: Vec3,
        skip: u32,
        mut pass: impl FnMut(f32) -> bool,
    ) -> Option<(Vec3, Hit)> {
        let (mut origin, mut skip) = (origin, skip);
        for _ in 0..MAX_PASSES {
            let hit = self.closest_hit(origin, direction, 0.0, f32::INFINITY, skip)?;
            let y = origin + direction * hit.t;
            if hit.transmittance <= 0.0 || !pass(hit.transmittance) {
                return Some((y, hit));
            }
            (origin, skip) = (y, hit.triangle);
        }
        None
    }

    /// The children of interior `node` as (nearer, farther) along `direction` from `origin`,
    /// judged by their box centres.
    #[inline]
    fn order_children(&self, node: &Node, origin: Vec3, direction: Vec3) -> (u32, u32) {
        let l = &self.nodes[node.start as usize];
        let r = &self.nodes[node.start as usize + 1];
        let dl = ((l.lo + l.hi) * 0.5 - origin).dot(direction);
        let dr = ((r.lo + r.hi) * 0.5 - origin).dot(direction);
        if dl <= dr {
            (node.start, node.start + 1)
        } else {
            (node.start + 1, node.start)
        }
    }

    /// Checks the structural invariants of both trees: every node's box contains its
    /// children or its triangles, and every triangle is referenced by exactly one leaf.
    pub fn validate(&self) -> Result<(), String> {
        if self.tris.is_empty() {
            return Ok(());
        }
        let mut seen = vec![false; self.tris.len()];
        let mut stack = vec![0u32];
        while let Some(i) = stack.pop() {
            let n = &self.nodes[i as usize];
            let contains = |lo: Vec3, hi: Vec3| lo.cmpge(n.lo).all() && hi.cmple(n.hi).all();
            if n.count == 0 {
                for c in [n.start, n.start + 1] {
                    let child = self
                        .nodes
                        .get(c as usize)
                        .ok_or("child index out of range")?;
                    if !contains(child.lo, child.hi) {
                        return Err(format!("node {i}: child {c} outside its box"));
                    }
                    stack.push(c);
                }
            } else {
                for k in n.start..n.start + n.count {
                    let t = self
                        .tris
                        .get(k as usize)
                        .ok_or("triangle index out of range")?;
                    for p in [t.v0, t.v0 + t.e1, t.v0 + t.e2] {
                        // v0 + e1 may round by one ulp against the box built from the
                        // original vertex; allow that much.
                        let slack = p.abs().max_element() * 1e-6;
                        if (p + slack).cmplt(n.lo).any() || (p - slack).cmpgt(n.hi).any() {
                            return Err(format!("leaf {i}: triangle {} outside its box", t.id));
                        }
                    }
                    if std::mem::replace(&mut seen[k as usize], true) {
                        return Err(format!("triangle slot {k} in two leaves"));
                    }
                }
            }
        }
        if !seen.iter().all(|&s| s) {
            return Err("a triangle is in no leaf".into());
        }
        let ids: Vec<u32> = self.tris.iter().map(|t| t.id).collect();
        match &self.wide {
            Some(wide) => wide.validate(&ids).map_err(|e| format!("wide tree: {e}")),
            None => Err("no wide tree over the triangles".into()),
        }
    }
}

/// Ray/box slab test for `t` in [0, t_max].
#[inline]
fn slab(node: &Node, origin: Vec3, inv: Vec3, t_max: f32) -> bool {
    let t0 = (node.lo - origin) * inv;
    let t1 = (node.hi - origin) * inv;
    // NaN (0 · ∞ for a ray lying in a slab plane) is dropped by min/max, keeping the test
    // conservative.
    let tnear = t0.min(t1).max_element().max(0.0);
    let tfar = t0.max(t1).min_element().min(t_max);
    tnear <= tfar
}

/// Möller–Trumbore ray/triangle intersection (Möller & Trumbore 1997): `(t, u, v)` for a hit
/// at `origin + t·dir`, double-sided.
#[inline]
fn intersect(tri: &Tri, origin: Vec3, dir: Vec3) -> Option<(f32, f32, f32)> {
    let p = dir.cross(tri.e2);
    let det = tri.e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv_det = 1.0 / det;
    let s = origin - tri.v0;
    let u = s.dot(p) * inv_det;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(tri.e1);
    let v = dir.dot(q) * inv_det;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some((tri.e2.dot(q) * inv_det, u, v))
}

#[allow(clippy::too_many_arguments)]
fn build_node(
    nodes: &mut Vec<Node>,
    index: usize,
    tris: &[Tri],
    centroids: &[Vec3],
    order: &mut [u32],
    begin: usize,
    end: usize,
    depth: usize,
) {
    let mut bounds = Aabb::EMPTY;
    let mut cbounds = Aabb::EMPTY;
    for &i in &order[begin..end] {
        let t = &tris[i as usize];
        bounds.grow(t.v0);
        bounds.grow(t.v0 + t.e1);
        bounds.grow(t.v0 + t.e2);
        cbounds.grow(centroids[i as usize]);
    }
    nodes[index].lo = bounds.lo;
    nodes[index].hi = bounds.hi;
    let n = end - begin;
    let make_leaf = |nodes: &mut Vec<Node>| {
        nodes[index].start = begin as u32;
        nodes[index].count = n as u32;
    };
    if n <= MAX_LEAF || depth >= MAX_DEPTH {
        make_leaf(nodes);
        return;
    }
    // SAH over binned centroids on each axis.
    let extent = cbounds.hi - cbounds.lo;
    let mut best: Option<(usize, usize, f32)> = None;
    for axis in 0..3 {
        if extent[axis] <= 0.0 {
            continue;
        }
        let scale = BINS as f32 / extent[axis];
        let mut bin_box = [Aabb::EMPTY; BINS];
        let mut bin_n = [0usize; BINS];
        for &i in &order[begin..end] {
            let b =
                (((centroids[i as usize][axis] - cbounds.lo[axis]) * scale) as usize).min(BINS - 1);
            let t = &tris[i as usize];
            bin_box[b].grow(t.v0);
            bin_box[b].grow(t.v0 + t.e1);
            bin_box[b].grow(t.v0 + t.e2);
            bin_n[b] += 1;
        }
        let mut right_area = [0.0f32; BINS];
        let mut right_n = [0usize; BINS];
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        for b in (1..BINS).rev() {
            acc.merge(&bin_box[b]);
            cnt += bin_n[b];
            right_area[b] = acc.area();
            right_n[b] = cnt;
        }
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        for b in 0..BINS - 1 {
            acc.merge(&bin_box[b]);
            cnt += bin_n[b];
            if cnt == 0 || right_n[b + 1] == 0 {
                continue;
            }
            let cost = acc.area() * cnt as f32 + right_area[b + 1] * right_n[b + 1] as f32;
            if best.is_none_or(|(_, _, c)| cost < c) {
                best = Some((axis, b, cost));
            }
        }
    }
    let leaf_cost = bounds.area() * n as f32;
    let mid = match best {
        // Traversal cost relative to an intersection ≈ 1 (Wald 2007's usual setting).
        Some((axis, b, cost)) if cost + bounds.area() < leaf_cost || n > 4 * MAX_LEAF => {
            let scale = BINS as f32 / extent[axis];
            let slice = &mut order[begin..end];
            let mut left = 0;
            for k in 0..slice.len() {
                let c = centroids[slice[k] as usize][axis];
                let bin = (((c - cbounds.lo[axis]) * scale) as usize).min(BINS - 1);
                if bin <= b {
                    slice.swap(left, k);
                    left += 1;
                }
            }
            begin + left
        }
        Some(_) => {
            make_leaf(nodes);
            return;
        }
        // All centroids coincide: split the list in half to bound leaf size.
        None => begin + n / 2,
    };
    let left = nodes.len();
    let blank = Node {
        lo: Vec3::ZERO,
        hi: Vec3::ZERO,
        start: 0,
        count: 0,
    };
    nodes.push(blank);
    nodes.push(blank);
    nodes[index].start = left as u32;
    nodes[index].count = 0;
    build_node(nodes, left, tris, centroids, order, begin, mid, depth + 1);
    build_node(nodes, left + 1, tris, centroids, order, mid, end, depth + 1);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(z: f32) -> [[Vec3; 3]; 2] {
        let (a, b, c, d) = (
            Vec3::new(-1., -1., z),
            Vec3::new(1., -1., z),
            Vec3::new(1., 1., z),
            Vec3::new(-1., 1., z),
        );
        [[a, b, c], [a, c, d]]
    }

    #[test]
    fn segment_through_quad_is_blocked_and_beside_it_is_not() {
        let bvh = Bvh::build(&quad(0.0), &[]);
        bvh.validate().unwrap();
        assert!(bvh.occluded(Vec3::new(0.2, 0.1, -1.0), Vec3::new(0.2, 0.1, 1.0)));
        assert!(!bvh.occluded(Vec3::new(2.0, 0.1, -1.0), Vec3::new(2.0, 0.1, 1.0)));
        // A segment ending before the quad is not blocked.
        assert!(!bvh.occluded(Vec3::new(0.2, 0.1, -1.0), Vec3::new(0.2, 0.1, -0.5)));
    }

    #[test]
    fn transmittance_multiplies_through_partial_surfaces() {
        let mut tris = quad(0.0).to_vec();
        tris.extend(quad(0.5));
        let bvh = Bvh::build(&tris, &[0.5, 0.5, 0.25, 0.25]);
        let t = bvh.transmittance(
            Vec3::new(0.2, 0.1, -1.0),
            Vec3::new(0.2, 0.1, 1.0),
            [u32::MAX; 2],
        );
        assert!((t - 0.125).abs() < 1e-6, "0.5 × 0.25 expected, got {t}");
    }

    /// A ray towards the sky from just under a cut-out (τ = 0.5 at z = 0) and an opaque
    /// quad (z = 0.5): the cut-out 10⁻⁶ above the origin counts (a segment to a point
    /// 10⁴ away ignores it: its first 10⁻⁴ is 1 unit), the opaque quad then stops the ray,
    /// a grazing ray meets the cut-out only, and a ray beside them escapes whole.
    #[test]
    fn a_ray_towards_the_sky_counts_what_lies_just_past_its_origin() {
        let mut tris = quad(0.0).to_vec();
        tris.extend(quad(0.5));
        let bvh = Bvh::build(&tris, &[0.5, 0.5, 0.0, 0.0]);
        let origin = Vec3::new(0.2, 0.1, -1e-6);
        let up = bvh.transmittance_toward(origin, Vec3::Z, [u32::MAX; 2]);
        assert_eq!(up, 0.0, "the opaque quad stops it");
        let through = bvh.transmittance_toward(origin, Vec3::Z, [2, 3]);
        assert!(
            (through - 0.5).abs() < 1e-6,
            "the cut-out's 0.5, got {through}"
        );
        let far = bvh.transmittance(origin, origin + Vec3::Z * 1e4, [2, 3]);
        assert_eq!(far, 1.0, "a segment's first 1e-4 is 1 unit here");
        let beside = bvh.transmittance_toward(Vec3::new(3.0, 0.0, -1.0), Vec3::Z, [u32::MAX; 2]);
        assert_eq!(beside, 1.0);
        let tilted = bvh.transmittance_toward(origin, Vec3::new(0.0, 1.0, 1e-3), [u32::MAX; 2]);
        // It crosses z = 0 a thousandth along (inside the cut-out) and z = 0.5 far past
        // the opaque quad's edge.
        assert!(
            (tilted - 0.5).abs() < 1e-6,
            "grazing: the cut-out only, got {tilted}"
        );
    }

    /// Two cut-outs (τ = 0.5 at z = 0, 0.25 at z = 0.5) before an opaque quad at z = 1: a
    /// ray up the z axis stops where the caller's draw says, is asked only at the cut-outs,
    /// with their τ in order, and goes on from each past it.
    #[test]
    fn a_stopping_hit_passes_the_cut_outs_the_draw_lets_through() {
        let mut tris = quad(0.0).to_vec();
        tris.extend(quad(0.5));
        tris.extend(quad(1.0));
        let bvh = Bvh::build(&tris, &[0.5, 0.5, 0.25, 0.25, 0.0, 0.0]);
        let (from, up) = (Vec3::new(0.2, 0.1, -1.0), Vec3::Z);
        let mut asked = Vec::new();
        let (y, hit) = bvh
            .stopping_hit(from, up, u32::MAX, |tau| {
                asked.push(tau);
                true
            })
            .unwrap();
        assert_eq!(asked, [0.5, 0.25]);
        assert!(hit.triangle >= 4 && hit.transmittance == 0.0);
        assert!(
            (y - Vec3::new(0.2, 0.1, 1.0)).length() < 1e-5,
            "stopped at {y}"
        );
        let (y, hit) = bvh.stopping_hit(from, up, u32::MAX, |_| false).unwrap();
        assert!(hit.triangle < 2 && hit.transmittance == 0.5);
        assert!(y.z.abs() < 1e-5, "stopped at {y}");
        // Past MAX_PASSES cut-outs the ray is taken to stop nowhere.
        let many: Vec<[Vec3; 3]> = (0..=MAX_PASSES).map(|k| quad(k as f32)[0]).collect();
        let bvh = Bvh::build(&many, &vec![0.5; many.len()]);
        assert!(bvh.stopping_hit(from, up, u32::MAX, |_| true).is_none());
    }
}
