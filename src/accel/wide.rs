//! The ray engine: a 4-wide BVH with four triangles per leaf, traced four boxes or four
//! triangles at a time, for shadow rays and closest hits.
//!
//! The layout is Embree's BVH4 with Triangle4 leaves (Wald, Woop, Benthin, Johnson & Ernst,
//! "Embree: a kernel framework for efficient CPU ray tracing", SIGGRAPH 2014): each node
//! holds its four children's boxes as structure-of-arrays lanes, so one ray meets all four
//! boxes in a handful of vector operations (the slab test, Kay & Kajiya 1986), and each
//! leaf holds up to four triangles the same way for a 4-lane Möller–Trumbore test
//! (Möller & Trumbore 1997). glam's `Vec4` is the 4-lane vector (SSE2 on x86-64, scalar
//! elsewhere), so there is no `unsafe` here.
//!
//! The tree itself comes from obvhs's binary builder (PLOC, Meister & Bittner 2018, with
//! reinsertion, Bittner et al. 2013, and leaves collapsed by SAH cost to at most four
//! triangles); [`WideBvh::build`] collapses it four-wide by opening, at every node, the
//! child of largest surface area until four children hang below it.
//!
//! Any-hit traversal visits a node's leaf children before its interior ones (a leaf is one
//! 4-lane test and may end the ray), and otherwise in no particular order: sorting the
//! children by distance cost more than it saved on the occlusion benchmark, whose rays are
//! 92 % blocked (Sponza, 10⁶ segments, a standalone copy of this kernel: 6.3 M rays/s
//! unsorted, 3.3–3.9 M/s nearest or farthest first).
//!
//! Closest-hit traversal is the other way: it opens the children nearest box first and skips
//! a box the ray enters beyond the nearest hit so far, which is what makes it fast; on
//! Sponza it traces at twice the binary tree's rate (`examples/bvh_compare.rs`).

use super::Hit;
use glam::{Vec3, Vec4};
use obvhs::{BvhBuildParams, bvh2::Bvh2, bvh2::builder::build_bvh2_from_tris, triangle::Triangle};

/// A child slot: an interior node's index, a leaf's index with this bit set, or [`EMPTY`].
const LEAF: u32 = 1 << 31;
const EMPTY: u32 = u32::MAX;
/// Stack entries a traversal needs per level of the tree: a node pushes at most four
/// children and pops one.
const STACK_PER_LEVEL: usize = 3;
/// The traversal stack lives on the machine stack up to this size (a tree 21 levels
/// deep, 4²¹ leaves: Sponza's is 18); deeper trees get a heap stack.
const INLINE_STACK: usize = 64;
/// Box exits are widened by 4 ulp so rounding in the slab test never culls a box the ray
/// touches (Ize, "Robust BVH ray traversal", JCGT 2013, uses 1 + 2γ₃ ≈ 1 + 3.6·10⁻⁷).
const ROBUST_EXIT: f32 = 1.0 + 4.0 * f32::EPSILON;

/// Four child boxes, one lane each; empty lanes have lo = +∞ and hi = −∞ and meet no ray.
#[derive(Clone, Copy, Debug)]
#[repr(align(64))]
struct Node4 {
    lo: [Vec4; 3],
    hi: [Vec4; 3],
    child: [u32; 4],
}

/// Four triangles as a vertex and two edges per lane; unused lanes are NaN and never hit.
/// What a hit lane stands for (the caller's triangle index and its transmittance) sits
/// beside the geometry, in the cache lines the test has just read.
#[derive(Clone, Copy, Debug)]
struct Leaf4 {
    v0: [Vec4; 3],
    e1: [Vec4; 3],
    e2: [Vec4; 3],
    id: [u32; 4],
    transmittance: [f32; 4],
}

/// A 4-wide BVH over a fixed set of triangles, for shadow rays and closest hits.
#[derive(Clone, Debug)]
pub(super) struct WideBvh {
    nodes: Vec<Node4>,
    leaves: Vec<Leaf4>,
    root: u32,
    /// Levels below the root: sizes the traversal stack.
    depth: usize,
}

impl WideBvh {
    /// Builds the tree over `triangles` (positions), `ids[i]` being the caller's index of
    /// triangle `i` and `transmittance[i]` the fraction of light it lets through. `None`
    /// for no triangles.
    pub(super) fn build(
        triangles: &[[Vec3; 3]],
        ids: &[u32],
        transmittance: &[f32],
    ) -> Option<WideBvh> {
        if triangles.is_empty() {
            return None;
        }
        let prims: Vec<Triangle> = triangles
            .iter()
            .map(|t| Triangle {
                v0: t[0].into(),
                v1: t[1].into(),
                v2: t[2].into(),
            })
            .collect();
        // Slow build without spatial splits: each triangle in exactly one leaf, so a
        // partly transparent one is counted once along a ray. It takes 0.3 s on Sponza's
        // 262k triangles against 0.13 s for the medium build, and traces 5–10 % faster.
        let params = BvhBuildParams {
            pre_split: false,
            max_prims_per_leaf: 4,
            ..BvhBuildParams::slow_build()
        };
        let binary = build_bvh2_from_tris(&prims, params, &mut std::time::Duration::default());
        let mut wide = WideBvh {
            nodes: Vec::with_capacity(binary.nodes.len() / 3 + 1),
            leaves: Vec::with_capacity(triangles.len() / 2 + 1),
            root: EMPTY,
            depth: 0,
        };
        wide.root = wide.collapse(&binary, triangles, ids, transmittance);
        Some(wide)
    }

    /// Converts `binary` four-wide, iteratively (a degenerate binary tree may be deep);
    /// returns the root's child slot.
    fn collapse(
        &mut self,
        binary: &Bvh2,
        triangles: &[[Vec3; 3]],
        ids: &[u32],
        transmittance: &[f32],
    ) -> u32 {
        /// A binary node waiting to become a slot, with the wide node and lane that will
        /// point at it (none for the root) and its depth in the wide tree.
        struct Pending {
            binary: usize,
            parent: Option<(usize, usize)>,
            depth: usize,
        }
        let mut todo = vec![Pending {
            binary: 0,
            parent: None,
            depth: 0,
        }];
        let mut root = EMPTY;
        while let Some(Pending {
            binary: n,
            parent,
            depth,
        }) = todo.pop()
        {
            self.depth = self.depth.max(depth);
            let node = &binary.nodes[n];
            let slot = if node.is_leaf() {
                let first = node.first_index as usize;
                let prims = &binary.primitive_indices[first..first + node.prim_count as usize];
                self.leaf(prims, triangles, ids, transmittance)
            } else {
                let mut kids = vec![node.first_index as usize, node.first_index as usize + 1];
                while kids.len() < 4 {
                    let widest = kids
                        .iter()
                        .enumerate()
                        .filter(|(_, k)| !binary.nodes[**k].is_leaf())
                        .max_by(|a, b| {
                            let area = |k: usize| binary.nodes[k].aabb.half_area();
                            area(*a.1).total_cmp(&area(*b.1))
                        })
                        .map(|(i, &k)| (i, k));
                    let Some((i, k)) = widest else { break };
                    let first = binary.nodes[k].first_index as usize;
                    kids[i] = first;
                    kids.push(first + 1);
                }
                let me = self.nodes.len();
                let mut wide = Node4 {
                    lo: [Vec4::INFINITY; 3],
                    hi: [Vec4::NEG_INFINITY; 3],
                    child: [EMPTY; 4],
                };
                for (lane, &k) in kids.iter().enumerate() {
                    let b = &binary.nodes[k].aabb;
                    for axis in 0..3 {
                        wide.lo[axis][lane] = b.min[axis];
                        wide.hi[axis][lane] = b.max[axis];
                    }
                    todo.push(Pending {
                        binary: k,
                        parent: Some((me, lane)),
                        depth: depth + 1,
                    });
                }
                self.nodes.push(wide);
                me as u32
            };
            match parent {
                Some((p, lane)) => self.nodes[p].child[lane] = slot,
                None => root = slot,
            }
        }
        root
    }

    /// Packs up to four triangles (the binary leaf's primitive indices) into one leaf.
    fn leaf(
        &mut self,
        prims: &[u32],
        triangles: &[[Vec3; 3]],
        ids: &[u32],
        transmittance: &[f32],
    ) -> u32 {
        debug_assert!(prims.len() <= 4, "obvhs leaf of {} triangles", prims.len());
        let mut leaf = Leaf4 {
            v0: [Vec4::NAN; 3],
            e1: [Vec4::NAN; 3],
            e2: [Vec4::NAN; 3],
            id: [u32::MAX; 4],
            transmittance: [1.0; 4],
        };
        for (lane, &p) in prims.iter().take(4).enumerate() {
            let t = &triangles[p as usize];
            let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
            for axis in 0..3 {
                leaf.v0[axis][lane] = t[0][axis];
                leaf.e1[axis][lane] = e1[axis];
                leaf.e2[axis][lane] = e2[axis];
            }
            leaf.id[lane] = ids[p as usize];
            leaf.transmittance[lane] = transmittance[p as usize];
        }
        self.leaves.push(leaf);
        LEAF | (self.leaves.len() as u32 - 1)
    }

    /// Product of the transmittances of the triangles met by `origin + t·dir` for t in
    /// (`t_min`, `t_max`), skipping the caller's triangles `skip`; 0 as soon as an opaque
    /// one is met.
    pub(super) fn transmittance(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_min: f32,
        t_max: f32,
        skip: [u32; 2],
    ) -> f32 {
        let ray = Ray4::new(origin, dir, t_min, t_max);
        let needed = (self.depth + 1) * STACK_PER_LEVEL + 1;
        if needed <= INLINE_STACK {
            self.walk(&mut [0; INLINE_STACK], &ray, skip)
        } else {
            self.walk(&mut vec![0; needed], &ray, skip)
        }
    }

    fn walk(&self, stack: &mut [u32], ray: &Ray4, skip: [u32; 2]) -> f32 {
        let mut through = 1.0f32;
        stack[0] = self.root;
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let slot = stack[sp];
            if slot & LEAF != 0 {
                let leaf = &self.leaves[(slot & !LEAF) as usize];
                let mut hits = ray.hit_triangles(leaf);
                while hits != 0 {
                    let lane = hits.trailing_zeros() as usize;
                    hits &= hits - 1;
                    if leaf.id[lane] == skip[0] || leaf.id[lane] == skip[1] {
                        continue;
                    }
                    through *= leaf.transmittance[lane];
                    if through <= 0.0 {
                        return 0.0;
                    }
                }
                continue;
            }
            let node = &self.nodes[slot as usize];
            let hit = ray.hit_boxes(node);
            // Interior children first onto the stack, leaves last: leaves pop first.
            for want_leaf in [false, true] {
                let mut m = hit;
                while m != 0 {
                    let lane = m.trailing_zeros() as usize;
                    m &= m - 1;
                    let child = node.child[lane];
                    if (child & LEAF != 0) == want_leaf {
                        stack[sp] = child;
                        sp += 1;
                    }
                }
            }
        }
        through
    }

    /// The nearest triangle met by `origin + t·dir` for t in (`t_min`, `t_max`), leaving
    /// out the caller's triangle `skip`. Children are visited nearest box first and a box
    /// entered beyond the nearest hit so far is not opened.
    pub(super) fn closest_hit(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_min: f32,
        t_max: f32,
        skip: u32,
    ) -> Option<Hit> {
        let ray = Ray4::new(origin, dir, t_min, t_max);
        let needed = (self.depth + 1) * STACK_PER_LEVEL + 1;
        if needed <= INLINE_STACK {
            self.nearest(&mut [(0, 0.0); INLINE_STACK], ray, skip)
        } else {
            self.nearest(&mut vec![(0, 0.0); needed], ray, skip)
        }
    }

    /// `stack` holds child slots with the t at which the ray enters their boxes.
    fn nearest(&self, stack: &mut [(u32, f32)], mut ray: Ray4, skip: u32) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        stack[0] = (self.root, ray.t_min.x);
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let (slot, enter) = stack[sp];
            // The nearest hit so far is before this box.
            if enter > ray.t_max.x {
                continue;
            }
            if slot & LEAF != 0 {
                let leaf = &self.leaves[(slot & !LEAF) as usize];
                let (mut hits, t, u, v) = ray.meet_triangles(leaf);
                while hits != 0 {
                    let lane = hits.trailing_zeros() as usize;
                    hits &= hits - 1;
                    if leaf.id[lane] == skip || t[lane] >= ray.t_max.x {
                        continue;
                    }
                    ray.t_max = Vec4::splat(t[lane]);
                    best = Some(Hit {
                        t: t[lane],
                        triangle: leaf.id[lane],
                        u: u[lane],
                        v: v[lane],
                        transmittance: leaf.transmittance[lane],
                    });
                }
                continue;
            }
            let node = &self.nodes[slot as usize];
            let (mut m, near) = ray.enter_boxes(node);
            // Farthest first onto the stack, so that the nearest pops first: each child
            // goes in below the nearer ones already pushed (insertion).
            let base = sp;
            while m != 0 {
                let lane = m.trailing_zeros() as usize;
                m &= m - 1;
                let entry = (node.child[lane], near[lane]);
                let mut at = sp;
                while at > base && stack[at - 1].1 < entry.1 {
                    stack[at] = stack[at - 1];
                    at -= 1;
                }
                stack[at] = entry;
                sp += 1;
            }
        }
        best
    }

    /// Checks that every box contains its children and its triangles, and that each of
    /// `ids` (the caller's indices the tree was built with) is in exactly one leaf lane.
    pub(super) fn validate(&self, ids: &[u32]) -> Result<(), String> {
        let mut seen = vec![false; ids.iter().max().map_or(0, |m| *m as usize + 1)];
        // (slot, the box it must lie in)
        let mut todo = vec![(self.root, None::<(Vec3, Vec3)>)];
        while let Some((slot, bounds)) = todo.pop() {
            let inside = |p: Vec3| {
                bounds.is_none_or(|(lo, hi)| {
                    let slack = p.abs().max_element() * 1e-6;
                    (p + slack).cmpge(lo).all() && (p - slack).cmple(hi).all()
                })
            };
            if slot & LEAF != 0 {
                let k = (slot & !LEAF) as usize;
                let leaf = self.leaves.get(k).ok_or("leaf index out of range")?;
                for lane in 0..4 {
                    let v0 = lane_of(&leaf.v0, lane);
                    if v0.is_nan() {
                        continue;
                    }
                    let (e1, e2) = (lane_of(&leaf.e1, lane), lane_of(&leaf.e2, lane));
                    if ![v0, v0 + e1, v0 + e2].into_iter().all(inside) {
                        return Err(format!("leaf {k}: lane {lane} outside its box"));
                    }
                    let id = leaf.id[lane] as usize;
                    if std::mem::replace(seen.get_mut(id).ok_or("lane id out of range")?, true) {
                        return Err(format!("triangle {id} in two leaf lanes"));
                    }
                }
                continue;
            }
            let node = self
                .nodes
                .get(slot as usize)
                .ok_or("node index out of range")?;
            for lane in 0..4 {
                if node.child[lane] == EMPTY {
                    continue;
                }
                let (lo, hi) = (lane_of(&node.lo, lane), lane_of(&node.hi, lane));
                if !(inside(lo) && inside(hi)) {
                    return Err(format!("node {slot}: child box {lane} outside its box"));
                }
                todo.push((node.child[lane], Some((lo, hi))));
            }
        }
        match ids.iter().find(|&&id| !seen[id as usize]) {
            Some(missing) => Err(format!("triangle {missing} is in no leaf")),
            None => Ok(()),
        }
    }
}

/// Lane `lane` of a vector stored as x, y and z lanes.
fn lane_of(v: &[Vec4; 3], lane: usize) -> Vec3 {
    Vec3::new(v[0][lane], v[1][lane], v[2][lane])
}

/// A ray broadcast to four lanes, with what the slab test needs precomputed.
struct Ray4 {
    origin: [Vec4; 3],
    dir: [Vec4; 3],
    inv: [Vec4; 3],
    negative: [bool; 3],
    t_min: Vec4,
    t_max: Vec4,
}

impl Ray4 {
    fn new(origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Ray4 {
        // A zero direction component becomes a huge finite inverse, never 0·∞ = NaN.
        let inv = |d: f32| {
            if d.abs() < 1e-30 {
                1e30f32.copysign(d)
            } else {
                1.0 / d
            }
        };
        let splat = |v: Vec3| [Vec4::splat(v.x), Vec4::splat(v.y), Vec4::splat(v.z)];
        let inv = Vec3::new(inv(dir.x), inv(dir.y), inv(dir.z));
        Ray4 {
            origin: splat(origin),
            dir: splat(dir),
            inv: splat(inv),
            negative: [inv.x < 0.0, inv.y < 0.0, inv.z < 0.0],
            t_min: Vec4::splat(t_min),
            t_max: Vec4::splat(t_max),
        }
    }

    /// Bit k set when the ray meets child box k within (t_min, t_max): slab test.
    #[inline(always)]
    fn hit_boxes(&self, node: &Node4) -> u32 {
        self.enter_boxes(node).0
    }

    /// [`Ray4::hit_boxes`]'s mask, with the t at which the ray enters each box.
    #[inline(always)]
    fn enter_boxes(&self, node: &Node4) -> (u32, Vec4) {
        let mut near = self.t_min;
        let mut far = self.t_max;
        for axis in 0..3 {
            let (enter, exit) = if self.negative[axis] {
                (node.hi[axis], node.lo[axis])
            } else {
                (node.lo[axis], node.hi[axis])
            };
            near = near.max((enter - self.origin[axis]) * self.inv[axis]);
            far = far.min((exit - self.origin[axis]) * self.inv[axis]);
        }
        (near.cmple(far * ROBUST_EXIT).bitmask(), near)
    }

    /// Bit k set when the ray meets triangle k of `leaf` at t in (t_min, t_max):
    /// Möller–Trumbore in four lanes, double-sided. A degenerate lane (det = 0) gives
    /// NaN or infinite coordinates and fails the comparisons.
    #[inline(always)]
    fn hit_triangles(&self, leaf: &Leaf4) -> u32 {
        self.meet_triangles(leaf).0
    }

    /// [`Ray4::hit_triangles`]'s mask, with each lane's t and barycentric u and v.
    #[inline(always)]
    fn meet_triangles(&self, leaf: &Leaf4) -> (u32, Vec4, Vec4, Vec4) {
        let cross = |a: &[Vec4; 3], b: &[Vec4; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let dot = |a: &[Vec4; 3], b: &[Vec4; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let p = cross(&self.dir, &leaf.e2);
        let inv_det = Vec4::ONE / dot(&leaf.e1, &p);
        let s = [
            self.origin[0] - leaf.v0[0],
            self.origin[1] - leaf.v0[1],
            self.origin[2] - leaf.v0[2],
        ];
        let u = dot(&s, &p) * inv_det;
        let q = cross(&s, &leaf.e1);
        let v = dot(&self.dir, &q) * inv_det;
        let t = dot(&leaf.e2, &q) * inv_det;
        let mask = (u.cmpge(Vec4::ZERO)
            & v.cmpge(Vec4::ZERO)
            & (u + v).cmple(Vec4::ONE)
            & t.cmpgt(self.t_min)
            & t.cmplt(self.t_max))
        .bitmask();
        (mask, t, u, v)
    }
}
