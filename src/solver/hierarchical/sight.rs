//! What each leaf sees, for the light that reaches it through links to the clusters
//! above it.
//!
//! A link whose receiver is a cluster gathers one irradiance for all the cluster's
//! surfaces, by direction (`Octants`), and pushing it down handed it to every leaf below
//! that faced its way. A leaf inside a closed space of the cluster (a room whose walls
//! face in, the void between a gallery's ceiling and its roof) then took light that
//! cannot reach it: on Sponza, 88 of the 188 bench points are black in the path-traced
//! truth, and the solver put 1–28 % of the scene's mean on them. Dropping every cluster's
//! push brought those points from 5.0 to 0.78 of the mean's 2 % (RMS, flat
//! reconstruction).
//!
//! So each leaf casts [`RAYS`] cosine-distributed rays once, and takes the light of the
//! links above it along them instead. In the hierarchy every source surface reaches a
//! leaf through exactly one link: one from a surface node to the leaf or a quadtree
//! ancestor (a surface link, whose transfer the sweeps use as before), one from a cluster
//! to the leaf or an ancestor, or one to a cluster above its patch. A ray whose hit no
//! surface link's source holds is the clusters' to carry: it brings the radiosity of the
//! element it hits, 1/16 of the leaf's hemisphere each (the rays are cosine-distributed),
//! so the leaf takes
//!
//! H_clusters(x) = (1 − F_s)₊ / (16 − s) · Σ_{rays r not held by a surface link} B(hit_r),
//!
//! where s of the 16 rays hit what the surface links hold and F_s is the form factor
//! those links hand the leaf (what they gather where every source has B = 1): the rays
//! estimate the mean radiosity over the part of the hemisphere the surface links leave,
//! and F_s, which the links compute deterministically, its size. Taking (16 − s)/16 for
//! that size instead would make the leaf's form factors sum to 1 only on average (in a
//! closed furnace at ρ = 0.99 an error δ in the sum moves B by about 99 δ); with 1 − F_s
//! they sum to 1 where every ray hits something. The estimate is seen from x itself
//! rather than from four sample patches of a cluster: a leaf in a closed space takes only
//! what its own walls send. A ray that misses (the sky: the external light's own term) or
//! hits the back of a single-sided surface brings nothing.
//!
//! The links from a cluster to a surface node leave their light to the rays too. Their
//! transfer is the cluster model's (a cluster sends the projected-area mean radiosity of
//! its surfaces facing the receiver, [`Sender`](super::Sender)), which missed what the
//! receiver actually sees of the cluster: on the Cornell box stopped at 20 k links, the
//! white walls' links from clusters handed them a form factor of 0.121 where 0.104 of
//! their hemisphere was those clusters' (256 rays a leaf), and 16 % less light than the
//! rays found there; the scene's power was 5.7 % under the full solve's. Along the rays
//! it is 1.8 % under. Such links still stand for their pair in the oracle, the inspector
//! and the previews (which sweep without the sight).
//!
//! The mean radiosity the rays estimate is pooled over the leaf and the other leaf
//! children of its quadtree parent (same surface, side by side): Σ over their carried rays
//! of B(hit) / Σ of their (16 − s), times the leaf's own (1 − F_s)₊. Sixteen rays alone
//! left the estimate noisy enough to show in the error: on Sponza's interior bench points
//! (Gouraud) 12.9 % with each leaf's own rays, 10.6 % pooled, 8.2 % with 64 rays a leaf
//! (which cost 50 % more solving time). A furnace stays exact: where every B is the same,
//! so is any pool's mean. A leaf whose own rays all meet what surface links hold takes
//! the pool's estimate too (nothing only where no ray of the pool is left to the
//! clusters): taking nothing there left a closed box at ρ = 0.999, cut to 3,000 links,
//! at 68 % of its power balance, a form-factor sum short by 5·10⁻⁴ on average.
//!
//! A leaf with no leaf siblings (a patch's root kept whole, as many slivers are, or a
//! child whose siblings were all split) pooled its sixteen rays alone. On one of
//! Sponza's slivers they summed to 0.75 W/m² of B where sixteen more from each of its
//! corner children's centroids summed to 0.24–0.54: an estimate 67 % high from noise
//! alone. So every pool holds at least four blocks of sixteen rays: a leaf pooling with
//! fewer than three other leaves casts extra blocks ([`extra_blocks`]), each from the
//! centroid of one of its corner children-to-be (where a split's siblings would cast
//! theirs), and pools them with its siblings' own and extra blocks (vinc3r's box, at the
//! bench's points in Hermite: 17.0 → 14.5 %).
//!
//! The rays are cast when a round's links are first used, and matched against the
//! surface links again whenever the links change. When leaves split, the rays of those
//! kept whole stay ([`StaleSight`]): only the new leaves' rays and those that hit a leaf
//! since split are cast again, which gives the sight a new cast would.

use super::NONE;
use super::table::LinkTable;
use super::{NodeId, Octants};
use crate::accel::Bvh;
use crate::geometry::orthonormal_basis;
use crate::geometry::sampling::{cosine_direction, hash, unit};
use crate::mesh::{Mesh, Moved};
use crate::solver::form_factor::element_seed;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// Rays per block, a 4 × 4 stratified grid over the cosine-weighted hemisphere: each
/// stands for 1/16 of it. Every leaf casts one block from its centroid, and leaves with
/// fewer than two leaf siblings more (see [`extra_blocks`]).
pub(super) const RAYS: usize = 16;

/// The blocks of rays a leaf's estimate pools at least (see [`extra_blocks`]).
const POOLED_BLOCKS: usize = 4;

/// The extra blocks a leaf casts that pools with `leaves` leaves (itself included):
/// enough for its pool to hold [`POOLED_BLOCKS`] blocks when each of them casts as
/// many, so 3 alone, 1 for two; none for three (48 rays) or four.
fn extra_blocks(leaves: usize) -> usize {
    match leaves {
        1 => 3,
        2 => 1,
        _ => 0,
    }
}

/// One of a leaf's rays.
#[derive(Clone, Copy, Debug)]
struct SightRay {
    /// The element it hits on its front side; `NONE` where it leaves the scene or hits
    /// the back of a single-sided surface.
    element: u32,
    /// Whether the clusters carry its light: no link to the leaf or its quadtree
    /// ancestors has a source that holds what it hits.
    by_clusters: bool,
}

impl SightRay {
    /// Ray `k` of block `block` of leaf `e`: cell k of a 4 × 4 stratified grid over the
    /// cosine-weighted hemisphere, jittered by a hash of the leaf's corners and the
    /// block; block 0 from the leaf's centroid, block c + 1 from the centroid of its
    /// corner child at corner c, (4 v_c + v_a + v_b) / 6.
    fn cast(mesh: &Mesh, bvh: &Bvh, e: usize, block: usize, k: usize) -> SightRay {
        let element = &mesh.elements[e];
        let own = mesh.patches[element.patch as usize].scene_triangle;
        let n = element.normal;
        let seed = element_seed(element) ^ 0x5167_4854;
        let centre = match block {
            0 => element.centroid(),
            b => {
                let [a, v, c] = [b - 1, b % 3, (b + 1) % 3].map(|i| element.verts[i]);
                (4.0 * a + v + c) / 6.0
            }
        };
        let from = centre + n * mesh.epsilon();
        let (i, j) = ((k % 4) as f32, (k / 4) as f32);
        let h = hash(seed ^ (block * RAYS + k) as u64);
        let u = (i + unit(h)) / 4.0;
        let v = (j + unit(hash(h))) / 4.0;
        let w = cosine_direction(n, orthonormal_basis(n), u, v);
        SightRay {
            element: first_stop(mesh, bvh, (from, w, own), hash(h ^ 0x7A55)),
            by_clusters: false,
        }
    }
}

/// Every leaf's rays.
pub(super) struct Sight {
    /// The blocks of [`RAYS`] rays: one per leaf, block e leaf e's from its centroid,
    /// then the leaves' extra blocks.
    rays: Vec<SightRay>,
    /// Where the blocks are and which its estimates pool.
    layout: Layout,
    /// Per leaf, the form factor its surface links hand it, F_s: what they gather where
    /// every source has B = 1 (empty until [`Sight::set_surface_share`]).
    surface_share: Vec<f32>,
}

/// What the clusters push down, laid out for the leaves.
pub(super) enum ClusterLight {
    /// By facing alone, without sight: each cluster's light by direction, its own and
    /// its ancestors' (see `Octants`).
    Facing(Vec<Octants>),
    /// Along the leaves' rays: each element's radiosity.
    Rays(Vec<Vec3>),
}

impl ClusterLight {
    /// By facing alone, from `gathered`: each cluster's light by direction.
    pub fn facing(gathered: &[Octants], clusters: &super::Clusters) -> ClusterLight {
        let mut down = gathered.to_vec();
        // Parents come first: one pass adds each cluster's ancestors' light to its own.
        for c in 0..down.len() {
            let p = clusters.nodes[c].parent;
            if p != NONE {
                let above = down[p as usize];
                down[c].merge(&above);
            }
        }
        ClusterLight::Facing(down)
    }

    /// Along the leaves' rays, from the elements' radiosity `b` over their `opacity`
    /// (their covered parts', which a ray that stops there brings; `opacity` empty where
    /// every element is opaque).
    pub fn rays(b: &[DVec3], opacity: &[f32]) -> ClusterLight {
        ClusterLight::Rays(if opacity.is_empty() {
            b.iter().map(|v| v.as_vec3()).collect()
        } else {
            b.iter()
                .zip(opacity)
                .map(|(v, o)| v.as_vec3() / *o)
                .collect()
        })
    }
}

impl Sight {
    /// Casts every leaf's rays.
    pub fn cast(mesh: &Mesh, bvh: &Bvh) -> Sight {
        let layout = Layout::of(mesh);
        let rays: Vec<SightRay> = (0..layout.blocks())
            .into_par_iter()
            .with_min_len(256)
            .flat_map_iter(|b| {
                let (e, block) = layout.block(b);
                (0..RAYS).map(move |k| SightRay::cast(mesh, bvh, e, block, k))
            })
            .collect();
        Sight {
            rays,
            layout,
            surface_share: Vec::new(),
        }
    }

    /// Sets each leaf's F_s (see [`Sight::leaf`]), after the links changed.
    pub fn set_surface_share(&mut self, share: Vec<f32>) {
        self.surface_share = share;
    }

    /// Whether it was cast for these elements.
    pub fn fits(&self, elements: usize) -> bool {
        self.layout.extra.len() == elements
    }

    /// The rays of block `b`.
    fn of(&self, b: usize) -> &[SightRay] {
        &self.rays[b * RAYS..(b + 1) * RAYS]
    }

    /// Marks the rays the clusters carry, after the links changed: those whose hit no
    /// surface source of a link to the leaf's node or its quadtree ancestors holds.
    /// `element_node`: each element's leaf node; `parent`: each node's parent.
    pub fn match_links(
        &mut self,
        mesh: &Mesh,
        links: &LinkTable,
        (element_node, parent, node_patch): (&[u32], &[u32], &[u32]),
    ) {
        // Whether source `s` holds element `hit`: a surface node its patch's quadtree
        // node above it. A cluster holds none: its light comes along the rays.
        let holds = |s: NodeId, hit: u32| -> bool {
            let element = &mesh.elements[hit as usize];
            if s.cluster().is_some() || node_patch[s.0 as usize] != element.patch {
                return false;
            }
            let mut n = element_node[hit as usize];
            while n != NONE && n != s.0 {
                n = parent[n as usize];
            }
            n != NONE
        };
        let layout = &self.layout;
        self.rays
            .par_chunks_mut(RAYS)
            .with_min_len(256)
            .enumerate()
            .for_each(|(b, rays)| {
                for r in rays.iter_mut() {
                    r.by_clusters = r.element != NONE;
                }
                let mut node = element_node[layout.block(b).0];
                while node != NONE {
                    for l in links.to(NodeId::surface(node)) {
                        for r in rays.iter_mut() {
                            if r.by_clusters && holds(l.source, r.element) {
                                r.by_clusters = false;
                            }
                        }
                    }
                    node = parent[node as usize];
                }
            });
    }

    /// Leaves whose pooled rays (see [`Sight::leaf`]) the clusters carry to any of the
    /// `changed` elements (flags by element).
    pub fn sees_any(&self, e: usize, changed: &[bool]) -> bool {
        self.pool(e).any(|j| {
            self.of(j)
                .iter()
                .any(|r| r.by_clusters && changed[r.element as usize])
        })
    }

    /// The blocks leaf `e` pools: its own, its leaf siblings' and their extra blocks.
    fn pool(&self, e: usize) -> impl Iterator<Item = usize> + '_ {
        self.layout.pool[e]
            .into_iter()
            .filter(|&j| j != NONE)
            .map(|j| j as usize)
    }

    /// Over block `b`'s rays: the sum of B(hit) over those the clusters carry, and how
    /// many no surface link holds (16 − s).
    fn carried(&self, b: usize, hits: &[Vec3]) -> (Vec3, u32) {
        let (mut sum, mut held) = (Vec3::ZERO, 0u32);
        for r in self.of(b) {
            if r.by_clusters {
                sum += hits[r.element as usize];
            } else if r.element != NONE {
                held += 1;
            }
        }
        (sum, RAYS as u32 - held)
    }

    /// The irradiance leaf `e` (normal `n`, below cluster `c`) takes from the clusters:
    /// along its rays and its siblings' ([`ClusterLight::Rays`], with `sight` their rays;
    /// none where no ray of the pool is left to the clusters), or by facing.
    pub fn leaf(sight: Option<&Sight>, e: usize, n: Vec3, c: u32, light: &ClusterLight) -> Vec3 {
        match (light, sight) {
            (ClusterLight::Rays(b), Some(sight)) if c != NONE => {
                let (mut sum, mut rest) = (Vec3::ZERO, 0u32);
                for j in sight.pool(e) {
                    let (s, n) = sight.carried(j, b);
                    sum += s;
                    rest += n;
                }
                if rest == 0 {
                    return Vec3::ZERO;
                }
                let share = sight.surface_share.get(e).copied().unwrap_or(0.0);
                sum * ((1.0 - share).max(0.0) / rest as f32)
            }
            (ClusterLight::Facing(down), _) if c != NONE => down[c as usize].at(n),
            _ => Vec3::ZERO,
        }
    }
}

/// A sight cast for leaves some of which have since been split. What it holds stays
/// true of the leaves kept whole: their rays are the ones they would cast again (the
/// directions come from their corners), and so are the hits on leaves kept whole.
pub(super) struct StaleSight {
    sight: Sight,
    /// For each leaf it was cast for, its index now; `NONE` where it was split.
    now: Vec<u32>,
}

impl StaleSight {
    /// After a refinement of the leaves (`moved`: where each went): `sight` if it was
    /// cast for them, or `stale` if it was, carried on.
    pub fn after(
        sight: Option<Sight>,
        stale: Option<StaleSight>,
        moved: &[Moved],
    ) -> Option<StaleSight> {
        let now = |m: &Moved| match m {
            Moved::Kept(k) => *k,
            Moved::Split(_) => NONE,
        };
        match (sight.filter(|s| s.fits(moved.len())), stale) {
            (Some(sight), _) => Some(StaleSight {
                sight,
                now: moved.iter().map(now).collect(),
            }),
            (None, Some(mut stale)) => {
                for n in &mut stale.now {
                    if *n != NONE {
                        *n = moved.get(*n as usize).map_or(NONE, now);
                    }
                }
                Some(stale)
            }
            _ => None,
        }
    }

    /// The sight of `mesh`, casting only what changed: the new leaves' rays, and the rays
    /// of a kept leaf that hit a leaf since split (which of its children holds the hit is
    /// not kept). This is the sight [`Sight::cast`] would make, for the rays of what
    /// changed. Its links are to be matched again ([`Sight::match_links`]) and F_s set.
    pub fn refresh(self, mesh: &Mesh, bvh: &Bvh) -> Sight {
        let StaleSight { sight, now } = self;
        let mut was = vec![NONE; mesh.elements.len()];
        for (old, &k) in now.iter().enumerate() {
            if let Some(w) = was.get_mut(k as usize) {
                *w = old as u32;
            }
        }
        // Ray k of block `block` of the leaf that was `old`, where it still holds: what
        // it hits now, `NONE` where it left the scene (it still does); `None` where the
        // hit was split or the leaf did not cast that block.
        let kept = &|old: u32, block: usize, k: usize| -> Option<u32> {
            let b = sight.layout.block_of(old, block)?;
            match sight.rays[b * RAYS + k].element {
                NONE => Some(NONE),
                hit => Some(now[hit as usize]).filter(|&h| h != NONE),
            }
        };
        let layout = Layout::of(mesh);
        let rays: Vec<SightRay> = (0..layout.blocks())
            .into_par_iter()
            .with_min_len(256)
            .flat_map_iter(|b| {
                let (e, block) = layout.block(b);
                let old = was[e];
                (0..RAYS).map(move |k| match kept(old, block, k) {
                    Some(element) => SightRay {
                        element,
                        by_clusters: false,
                    },
                    None => SightRay::cast(mesh, bvh, e, block, k),
                })
            })
            .collect();
        Sight {
            rays,
            layout,
            surface_share: Vec::new(),
        }
    }
}

/// The element where the ray from `from` along `w` (leaving triangle `own`) stops, or
/// `NONE` where it leaves the scene or meets the back of a single-sided surface. It passes
/// a triangle of transmittance τ (an alpha cut-out's uncovered share, glass) with
/// probability τ, drawn from `draw`, as the unbiased reference's paths do; where it stops
/// on one it brings the covered part's radiosity (`ClusterLight::rays`).
fn first_stop(mesh: &Mesh, bvh: &Bvh, (from, w, own): (Vec3, Vec3, u32), mut draw: u64) -> u32 {
    let pass = |tau: f32| {
        draw = hash(draw);
        unit(draw) < tau
    };
    bvh.stopping_hit(from, w, own, pass)
        .and_then(|(y, hit)| mesh.element_at(hit.triangle, y, -w))
        .unwrap_or(NONE)
}

/// Where a sight's blocks of rays are: block e is leaf e's own, and the extra blocks
/// follow, each leaf's together.
struct Layout {
    /// Per leaf, its extra blocks' range of block indices (empty where it casts none).
    extra: Vec<(u32, u32)>,
    /// Per extra block (from block `extra.len()` on, in order), the leaf that casts it.
    owner: Vec<u32>,
    /// Per leaf, the blocks its estimate pools (`NONE` for the rest): its own and those
    /// of the other leaf children of its quadtree parent, then their extra blocks.
    pool: Vec<[u32; POOLED_BLOCKS]>,
}

impl Layout {
    fn of(mesh: &Mesh) -> Layout {
        let leaves = mesh.elements.len();
        let siblings = siblings(mesh);
        let mut extra = Vec::with_capacity(leaves);
        let mut owner = Vec::new();
        for (e, pool) in siblings.iter().enumerate() {
            let n = extra_blocks(pool.iter().filter(|&&j| j != NONE).count());
            let start = (leaves + owner.len()) as u32;
            owner.extend(std::iter::repeat_n(e as u32, n));
            extra.push((start, start + n as u32));
        }
        let pool = siblings
            .iter()
            .map(|leaves| {
                let mut pool = [NONE; POOLED_BLOCKS];
                let own = leaves.iter().filter(|&&j| j != NONE).copied();
                let extras = own
                    .clone()
                    .flat_map(|j| extra[j as usize].0..extra[j as usize].1);
                for (slot, b) in pool.iter_mut().zip(own.chain(extras)) {
                    *slot = b;
                }
                pool
            })
            .collect();
        Layout { extra, owner, pool }
    }

    fn blocks(&self) -> usize {
        self.extra.len() + self.owner.len()
    }

    /// The leaf that casts block `b`, and which of its blocks it is (0: its own).
    fn block(&self, b: usize) -> (usize, usize) {
        match b.checked_sub(self.extra.len()) {
            None => (b, 0),
            Some(x) => {
                let e = self.owner[x] as usize;
                (e, 1 + b - self.extra[e].0 as usize)
            }
        }
    }

    /// The index of leaf `e`'s block `block`, where it casts one.
    fn block_of(&self, e: u32, block: usize) -> Option<usize> {
        let (start, end) = *self.extra.get(e as usize)?;
        match block {
            0 => Some(e as usize),
            k => Some(start as usize + k - 1).filter(|&b| b < end as usize),
        }
    }
}

/// Per leaf element, itself and the other leaf children of its quadtree parent (`NONE`
/// for the rest; itself alone at a patch's root).
fn siblings(mesh: &Mesh) -> Vec<[u32; 4]> {
    let mut siblings: Vec<[u32; 4]> = (0..mesh.elements.len() as u32)
        .map(|e| [e, NONE, NONE, NONE])
        .collect();
    for node in &mesh.nodes {
        let Some(kids) = node.children else { continue };
        let leaves = kids.map(|k| mesh.nodes[k as usize].element.unwrap_or(NONE));
        for e in leaves.into_iter().filter(|&e| e != NONE) {
            siblings[e as usize] = leaves;
        }
    }
    siblings
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::MeshSettings;
    use crate::scene::builtin;

    fn hits(sight: &Sight) -> Vec<u32> {
        sight.rays.iter().map(|r| r.element).collect()
    }

    #[test]
    fn a_sight_carried_through_splits_is_the_one_cast_anew() {
        // The Cornell box, its leaves split twice (every third, then every fifth of the
        // new ones, so some split leaves are split again): refreshing the sight cast
        // before must give every leaf the hits a new cast gives it, exactly (the same
        // rays, traced by the same code).
        let scene = builtin::cornell_box();
        let mut mesh = Mesh::build(
            &scene,
            &MeshSettings {
                element_size: Some(0.15),
                ..Default::default()
            },
        );
        let bvh = Bvh::build(&mesh.triangles, &mesh.transmittance);
        let mut stale = None;
        let mut sight = Some(Sight::cast(&mesh, &bvh));
        for every in [3, 5] {
            let marked: Vec<bool> = (0..mesh.elements.len()).map(|e| e % every == 0).collect();
            let moved = mesh.refine(&marked);
            stale = StaleSight::after(sight.take(), stale, &moved);
        }
        let carried = stale.expect("carried").refresh(&mesh, &bvh);
        let fresh = Sight::cast(&mesh, &bvh);
        assert_eq!(carried.rays.len(), fresh.rays.len());
        let (a, b) = (hits(&carried), hits(&fresh));
        let differ = a.iter().zip(&b).filter(|(x, y)| x != y).count();
        assert_eq!(differ, 0, "{differ} of {} rays differ", a.len());
        assert_eq!(carried.layout.pool, fresh.layout.pool);
    }
}
