//! Hierarchical radiosity with clustering (Hanrahan, Salzman & Aupperle, "A rapid
//! hierarchical radiosity algorithm", SIGGRAPH 1991; clusters after Smits, Arvo & Greenberg
//! 1994 and Sillion 1995): [`Method::Hierarchical`](super::Method::Hierarchical).
//!
//! The nodes are the scene's clusters ([`clusters`]) above the patches' element quadtrees
//! (`Mesh::nodes`, extended on demand by midpoint subdivision). A link joins two nodes at
//! any levels and carries the transfer from its source to its receiver ([`transfer`]):
//! H_r += factor · B_s. The solve alternates two stages:
//!
//! - **refine** ([`oracle`]): every link whose estimated error ρ_r · (spread · B_s +
//!   factor · ΔB_s) exceeds ε times the scene's mean E' (what its surfaces emit or first
//!   reflect) is replaced by links to the children of one end, recursively, down to the
//!   minimum element size; a leaf that must split is split in the mesh first. The oracle
//!   runs again each time the sweeps converge (B_s grows as light spreads), from 16 ε down
//!   to ε ([`COARSE_START`]; the sweeps before a coarse round stop early, see
//!   `Solver::round_sweep_tolerance`), and the solve is done when a round at ε changes
//!   nothing, or makes at most a thousandth of its links new and the sweeps after it
//!   converge ([`ROUND_TOLERANCE`]).
//! - **sweep** (Jacobi over the links, then push–pull): pull B up the hierarchy as area
//!   means and, over each surface node, the slope of the linear fit to its leaves; gather
//!   H at every node over its links, each surface source sending its linear B at the
//!   point the receiver sees it best (the kernel-weighted centroid the link keeps), each
//!   cluster the radiosity of its surfaces that face the receiver ([`Facing`]); push H down (a
//!   leaf receives the sum over its ancestors, clusters included, scaled back where
//!   its links add up to more than one hemisphere: [`Hierarchy::conservation_caps`])
//!   and set B_leaf = E'_leaf + ρ_leaf · H; take Anderson's step from the last sweeps
//!   ([`anderson`](super::anderson): Jacobi alone needs thousands of sweeps at ρ̄ near
//!   1); repeat until the area-weighted change per sweep is below the tolerance.
//!
//! A link's factor does not depend on ρ or E, so an edit of a material only sweeps again
//! (and lets the oracle look again): no existing form factor is recomputed. Each leaf
//! keeps the H of the last sweep, so the edited leaves show the edit at once, B = E' +
//! ρ_new H, before any sweep (`edits`). Past the link budget the oracle has nothing left to
//! decide, so no round runs after the sweeps converge.
//!
//! Results do not depend on the thread count: each link's rays are seeded by its ends'
//! ids, links are sorted by (receiver, source), and every sum runs in that order.

pub(super) mod clusters;
mod external;
mod incremental;
mod inspect;
mod link;
mod oracle;
mod sight;
mod table;
#[cfg(test)]
mod tests;
pub(super) mod transfer;

use super::anderson::{Anderson, LightScales};
use super::types::Stop;
use super::{ELEMENT_CHUNK, Solver, ordered_sum, sum3d};
use crate::accel::Bvh;
use crate::geometry::closest_point_on_triangle;
use crate::mesh::Mesh;
use clusters::Clusters;
use glam::{DVec2, DVec3, Vec3};
pub use inspect::{ElementLinks, LinkView};
use link::Link;
use rayon::prelude::*;
use sight::{ClusterLight, Sight, StaleSight};
use std::sync::atomic::AtomicBool;
use std::time::Instant;
use table::{LinkTable, StoredLink};

/// A node of the hierarchy: a quadtree node of `Mesh::nodes` or, with the top bit set, a
/// cluster.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(in crate::solver) struct NodeId(pub u32);

const CLUSTER_BIT: u32 = 1 << 31;
const NONE: u32 = u32::MAX;

/// The first refinement round's threshold over the oracle's; each round after converged sweeps
/// halves it, down to the oracle's own (16 ε, 8 ε, 4 ε, 2 ε, ε), and the solve is done only when a
/// round at ε changes nothing or little (`ROUND_TOLERANCE`). Each round keeps the last one's links
/// and refines those above its threshold. Refining to ε at once showed only the top levels'
/// previews until the whole first round was done: on the Cornell box (`bench builtin:cornell
/// --methods hierarchical`) 8.1 % off the truth from 1.5 s to 8.6 s, then 1.8 %; coarse to fine,
/// 5.3 % at 1.5 s, 3.2 % at 2.5 s, 2.1 % at 5 s, and 1.75 % converged at 10.7 s instead of 11.8 s.
/// (Before the clusters' light went along the leaves' rays, a first round at 4 ε or 16 ε came out
/// 50 % too bright.) A scene the link budget will cut goes on at ε once a coarse round holds a
/// quarter of the budget (`oracle`): spent coarse-first, the budget went deep in a few places, and
/// Sponza's interior points came out 20.5 % off instead of 16.4 %.
const COARSE_START: f32 = 16.0;

/// The smallest change per sweep the sweeps are asked to reach: f32 irradiance rounds
/// each element's B by up to 2⁻²⁴ relative, and the area-weighted change between two
/// sweeps that only round differently stays below about 10⁻⁷.
const SWEEP_FLOOR: f64 = 1e-6;

/// A round at ε that makes at most this share of the solution's links new is the oracle's
/// last: the sweeps after it converge, and the solve is done. Such a round only refines
/// links that the last sweeps nudged just past the threshold, and the next round nudges
/// others: on the Cornell box the rounds after the second at ε made 11,700, 132, 35 and
/// 525 new links of 3.38 M, about 0.6 s each with their sweeps, before one changed
/// nothing. Stopping after the one of 132 (`solve builtin:cornell`, two runs each,
/// alternated): 13.5 and 14.1 s against 16.3 and 15.7 s, and the same error against the
/// path-traced points to three digits (`bench builtin:cornell`: 1.53 %, the final gather
/// 0.80 %).
pub const ROUND_TOLERANCE: f64 = 1e-3;

impl NodeId {
    pub fn surface(node: u32) -> NodeId {
        NodeId(node)
    }
    pub fn of_cluster(c: u32) -> NodeId {
        NodeId(c | CLUSTER_BIT)
    }
    /// The cluster index, if this is a cluster.
    pub fn cluster(self) -> Option<usize> {
        (self.0 & CLUSTER_BIT != 0).then_some((self.0 & !CLUSTER_BIT) as usize)
    }
}

/// Irradiance arriving at a cluster from many directions, kept per axis direction (±x,
/// ±y, ±z) as what a surface facing that way would receive: irradiance E from unit
/// direction ω adds E · max(0, ±ω_a) to the faces of its octant. A surface with normal n
/// inside takes Σ_a |n_a| · C(sign n_a, a), which is E · (n · ω) exactly when n and ω lie
/// in the same octant and nothing when n faces away from every source, so a box's lit
/// and unlit faces get different light from one cluster link.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Octants([Vec3; 6]);

impl Octants {
    fn face(axis: usize, positive: bool) -> usize {
        2 * axis + usize::from(!positive)
    }
    fn add(&mut self, e: Vec3, w: Vec3) {
        for a in 0..3 {
            self.0[Self::face(a, w[a] >= 0.0)] += e * w[a].abs();
        }
    }
    /// Adds `e`, the mean irradiance over `cluster`'s surfaces, arriving from every side
    /// (a near link's, whose ends overlap): every face gets e · A / Σ_a (Σ A_i |n_i|)_a,
    /// so a surface with normal n takes that times Σ_a |n_a|, and the area-weighted mean
    /// over the cluster's surfaces is e.
    fn add_mean(&mut self, e: Vec3, cluster: &clusters::Cluster) {
        let per_face = e * cluster.area / cluster.abs_area.element_sum();
        for f in &mut self.0 {
            *f += per_face;
        }
    }
    fn merge(&mut self, o: &Octants) {
        for k in 0..6 {
            self.0[k] += o.0[k];
        }
    }
    fn at(&self, n: Vec3) -> Vec3 {
        (0..3)
            .map(|a| self.0[Self::face(a, n[a] >= 0.0)] * n[a].abs())
            .fold(Vec3::ZERO, |x, y| x + y)
    }
}

/// What a cluster sends towards each side, the dual of [`Octants`]: per axis direction
/// (±x, ±y, ±z), the sums Σ A_i max(0, ±n_i,a) · B_i and Σ A_i max(0, ±n_i,a) over the
/// surfaces inside. Towards unit direction w the cluster sends the radiosity of the
/// surfaces that face w, Σ_a |w_a| · (Σ A B)_a / Σ_a |w_a| · (Σ A)_a: exact for surfaces
/// facing along the axes ([`Sender::toward`] is what the gather reads). Its mean
/// radiosity alone would send the light of a wall's lit outer face out of its dark inner
/// face as well, when both fall in one cluster: a leak of the bright outside into a
/// closed room (Sponza sits inside such a shell).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Facing {
    power: [Vec3; 6],
    area: [f32; 6],
}

impl Facing {
    fn add_surface(&mut self, normal: Vec3, area: f32, b: Vec3) {
        for a in 0..3 {
            let f = Octants::face(a, normal[a] >= 0.0);
            let projected = area * normal[a].abs();
            self.power[f] += b * projected;
            self.area[f] += projected;
        }
    }
    fn merge(&mut self, o: &Facing) {
        for f in 0..6 {
            self.power[f] += o.power[f];
            self.area[f] += o.area[f];
        }
    }
}

/// What a cluster sends, laid out for the gather's reads in link order, which jump about
/// the scene: one 96-byte record (two cache lines) per cluster holding everything a link
/// from it reads, where [`Facing`]'s sums, the cluster's centre and its mean had been
/// three reads from three arrays. The radiosity of the surfaces facing each axis
/// direction stays f32 (a rounded B would bias a near-1 furnace by ρ/(1 − ρ) times the
/// rounding); their projected areas, which only weigh the faces against each other, are
/// kept relative to the largest in units of 1/65535.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(32))]
struct Sender {
    /// Per axis direction (see [`Octants::face`]): power over projected area, 0 where no
    /// surface faces that way.
    b: [Vec3; 6],
    area: [u16; 6],
    centre: Vec3,
}

impl Sender {
    fn new(facing: &Facing, centre: Vec3) -> Sender {
        let largest = facing.area.iter().fold(0.0f32, |m, a| m.max(*a));
        let mut s = Sender {
            centre,
            ..Sender::default()
        };
        for f in 0..6 {
            if facing.area[f] > 0.0 {
                s.b[f] = facing.power[f] / facing.area[f];
                s.area[f] = (facing.area[f] / largest * 65535.0).round() as u16;
            }
        }
        s
    }

    /// The radiosity sent towards unit direction `w`: Σ_a |w_a| A_a B_a / Σ_a |w_a| A_a
    /// over the three faces `w` looks at. Where no surface faces that way (or `w` is
    /// zero), the mean over all faces weighted by their projected areas.
    fn toward(&self, w: Vec3) -> Vec3 {
        let (mut p, mut a) = (Vec3::ZERO, 0.0f32);
        for axis in 0..3 {
            let f = Octants::face(axis, w[axis] >= 0.0);
            let weight = self.area[f] as f32 * w[axis].abs();
            p += self.b[f] * weight;
            a += weight;
        }
        if a > 0.0 {
            return p / a;
        }
        let (mut p, mut a) = (Vec3::ZERO, 0.0f32);
        for f in 0..6 {
            p += self.b[f] * self.area[f] as f32;
            a += self.area[f] as f32;
        }
        if a > 0.0 { p / a } else { Vec3::ZERO }
    }

    /// The record whose radiosities are this one's less `then`'s (same centre and
    /// projected areas).
    fn less(&self, then: &Sender) -> Sender {
        debug_assert_eq!((self.area, self.centre), (then.area, then.centre));
        Sender {
            b: std::array::from_fn(|f| self.b[f] - then.b[f]),
            ..*self
        }
    }

    /// What it sends to a receiver at `at` ([`Sender::toward`] the direction from its
    /// centre to `at`), and the unit direction from `at` to its centre.
    fn seen_from(&self, at: Vec3) -> (Vec3, Vec3) {
        let w = (at - self.centre).normalize_or_zero();
        (self.toward(w), -w)
    }
}

/// Whether the gather at a surface node takes link `l`'s light: all but a link from a
/// cluster where the leaves' rays are cast (`by_rays`), whose light they bring instead
/// (see [`sight`]).
fn gathered_at_surface(by_rays: bool, l: &StoredLink) -> bool {
    !(by_rays && l.source.cluster().is_some())
}

/// A linear function over a triangle, given by its values at the corners, at the point
/// whose barycentric weights are `w`.
fn mix(corners: &[Vec3; 3], w: [f32; 3]) -> Vec3 {
    corners[0] * w[0] + corners[1] * w[1] + corners[2] * w[2]
}

/// The linear function with values `corners` at the corners of surface node `node`, at
/// the point of the node closest to `x`.
fn linear_at(mesh: &Mesh, node: u32, corners: &[Vec3; 3], x: Vec3) -> Vec3 {
    let (_, w) = closest_point_on_triangle(x, &mesh.nodes[node as usize].verts);
    mix(corners, w)
}

/// The largest residual G(B)_e − B_e of any element in its own equation, relative to its
/// own light (`scales`: [`LightScales::of`] the image `swept` = G(B)): where the sweeps'
/// area-weighted change says the scene has converged, this says whether every corner
/// of it has.
fn worst_element_residual(old: &[DVec3], swept: &[DVec3], scales: &LightScales) -> f64 {
    let scales = &scales.per_element;
    (0..swept.len())
        .into_par_iter()
        .with_min_len(ELEMENT_CHUNK)
        .map(|e| {
            let change = sum3d((swept[e] - old[e]).abs());
            if change > 0.0 {
                change / scales[e]
            } else {
                0.0
            }
        })
        .reduce(|| 0.0, f64::max)
}

/// What a surface source whose linear B has the values `corners` at its corners sends from
/// the point of barycentric weights `w` (a link's kernel centroid, where the receiver sees
/// it best): never negative.
fn sent_at(corners: &[Vec3; 3], w: [f32; 3]) -> Vec3 {
    mix(corners, w).max(Vec3::ZERO)
}

/// The moments behind a surface node's linear fit (see [`Hierarchy::pull`]), in its
/// plane's basis (t, b): the first moments Σ A (B − B̄) (c − c̄)·t and ·b, and the second
/// moments Σ A (c − c̄)_t², _t _b, _b² over its leaves. Kept so that an incremental sweep
/// can pull up just the nodes above the leaves that changed.
#[derive(Clone, Copy, Debug, Default)]
struct Moments {
    first: [Vec3; 2],
    second: [f32; 3],
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    Refine,
    Sweep,
}

/// The hierarchy's state beside the solver's per-element arrays (which hold the leaves'
/// B, E', ρ and E).
pub(super) struct Hierarchy {
    clusters: Clusters,
    /// Sorted by (receiver, source), stored by receiver.
    links: LinkTable,
    /// Per mesh node: parent node (`NONE` at a patch root), patch, area, B and gathered H.
    parent: Vec<u32>,
    node_patch: Vec<u32>,
    node_area: Vec<f32>,
    node_b: Vec<Vec3>,
    /// The linear fit to B over each surface node (see [`Hierarchy::pull`]), as its values
    /// at the node's corners: a link's source sends their barycentric mix at the link's
    /// kernel centroid, read from this one array.
    node_corners: Vec<[Vec3; 3]>,
    /// What the linear fit of each surface node is made from (see [`Moments`]).
    node_moments: Vec<Moments>,
    /// Gathered H at each node as a linear function: its values at the node's corners.
    node_h: Vec<[Vec3; 3]>,
    /// Per node, the range of the external light's irradiance over it (see [`external`]),
    /// NaN until a refinement round asks for it.
    node_external_range: Vec<f32>,
    /// Leaves that may not split below the minimum size, for a contact or along their
    /// length: their split would have made some element too narrow for balance (see
    /// `Solver::split_leaves`).
    ungraded: std::collections::HashSet<u32>,
    cluster_b: Vec<Vec3>,
    /// What each cluster's surfaces send by direction: see [`Facing`].
    cluster_facing: Vec<Facing>,
    /// The same as the gather reads it: see [`Sender`].
    cluster_send: Vec<Sender>,
    /// Irradiance a cluster receives, by direction: see [`Octants`].
    cluster_h: Vec<Octants>,
    /// What each leaf sees, to weigh what the clusters push down to it (see [`sight`]);
    /// `None` until the first round's links are made, and after the leaves change.
    sight: Option<sight::Sight>,
    /// The sight cast for leaves split since, carried through the splits: refreshed
    /// instead of cast anew when the links are next matched.
    stale_sight: Option<StaleSight>,
    /// The leaf node of each element.
    element_node: Vec<u32>,
    /// Per element, its area and the cluster above its patch (`NONE` for none): what the
    /// sweeps read of every element, kept apart so that a sweep after an edit does not
    /// stream the elements themselves (72 bytes each) to find them.
    element_area: Vec<f32>,
    element_cluster: Vec<u32>,
    /// Per element, the factor its gathered H is scaled by so that its links' form
    /// factors sum to at most 1 (see [`Hierarchy::conservation_caps`]); empty or stale
    /// (another length) while a refinement round changes the links.
    leaf_cap: Vec<f32>,
    /// The radiosity the last full or incremental sweep started from, while the node
    /// values, the gathered H and `Solver::gathered` are still what it computed from it
    /// with the current links and caps (see [`incremental`]); `None` once any changes
    /// otherwise.
    basis: Option<Vec<DVec3>>,
    /// The links by source, for incremental sweeps: made when one first needs it, dropped
    /// when the links change.
    by_source: Option<incremental::BySource>,
    /// Each leaf's H before the cut at zero and the cap, from the last sweep (see
    /// [`Hierarchy::leaf_irradiance_linear`]): incremental sweeps add to it.
    leaf_linear: Vec<Vec3>,
    /// The last sweep met the tolerance: its input may stand for the solution (see
    /// `Solver::rebase_on_sweep_basis`).
    converged: bool,
    /// An edit came while a refinement round was under way.
    edited_in_round: bool,
    /// The last round at ε made few enough new links (see `ROUND_TOLERANCE`): once the
    /// sweeps after it converge, the solve is done.
    last_round: bool,
    /// The new links the last refinement round made.
    round_new_links: usize,
    /// Incremental sweeps since the last full one (see [`incremental`]).
    incremental_in_a_row: u32,
    /// Patches edited since the last sweep while there was a converged basis (see
    /// `Solver::rebase_on_sweep_basis`).
    edited: Vec<u32>,
    /// Largest reflectance channel per patch (edits change it).
    patch_reflectance: Vec<f32>,
    stage: Stage,
    /// The sweeps' acceleration ([`Anderson`]), restarted whenever the links, the
    /// elements or the materials change.
    acceleration: Anderson,
    /// The refinement round under way.
    round: Option<oracle::Round>,
    /// The largest oracle threshold so far (see `Solver::held_threshold`).
    threshold: f32,
    /// What the next refinement round's threshold is multiplied by: the rounds go from
    /// coarse to fine (see [`COARSE_START`]), 1 from the last of them on.
    coarseness: f32,
    /// Whether the first refinement round decides the links from lit sources first
    /// (see `oracle::Round::unlit_pairs`; off only to test what it changes), and whether
    /// it was started again in breadth-first order (see `oracle::Round::restart`).
    lit_first: bool,
    first_round_restarted: bool,
    /// The scene's mean radiosity (largest channel) when the last refinement round
    /// began, zero before the first sweep (no receiver counts as dark): receivers darker
    /// than it are held to a threshold scaled by their own radiosity (see
    /// `View::darkness`). The mean of that moment, not the one the held threshold came
    /// from, so that an edit that dims every light leaves each receiver's darkness as it
    /// was; kept so that the link inspector judges as the round did.
    dark_mean: f32,
    sweeps: u64,
    /// Sweeps that were incremental.
    incremental_sweeps: u64,
    started: Instant,
}

impl Hierarchy {
    fn new(mesh: &Mesh, reflectance: &[Vec3]) -> Hierarchy {
        let inside: Vec<u32> = (0..mesh.patches.len() as u32)
            .filter(|&p| !mesh.patches[p as usize].covered)
            .collect();
        let clusters = Clusters::build(mesh, &inside);
        let patch_reflectance = mesh
            .patches
            .iter()
            .map(|p| {
                reflectance
                    .get(p.elements.start as usize)
                    .copied()
                    .unwrap_or(p.reflectance)
                    .max_element()
            })
            .collect();
        let mut h = Hierarchy {
            cluster_b: vec![Vec3::ZERO; clusters.nodes.len()],
            cluster_facing: vec![Facing::default(); clusters.nodes.len()],
            cluster_send: vec![Sender::default(); clusters.nodes.len()],
            cluster_h: vec![Octants::default(); clusters.nodes.len()],
            sight: None,
            stale_sight: None,
            clusters,
            links: LinkTable::default(),
            parent: Vec::new(),
            node_patch: Vec::new(),
            node_area: Vec::new(),
            node_b: Vec::new(),
            node_corners: Vec::new(),
            node_moments: Vec::new(),
            node_h: Vec::new(),
            node_external_range: Vec::new(),
            ungraded: Default::default(),
            element_node: Vec::new(),
            element_area: Vec::new(),
            element_cluster: Vec::new(),
            leaf_cap: Vec::new(),
            basis: None,
            by_source: None,
            edited: Vec::new(),
            converged: false,
            edited_in_round: false,
            last_round: false,
            round_new_links: 0,
            incremental_in_a_row: 0,
            leaf_linear: Vec::new(),
            patch_reflectance,
            stage: Stage::Refine,
            acceleration: Anderson::default(),
            round: None,
            threshold: 0.0,
            coarseness: COARSE_START,
            lit_first: true,
            first_round_restarted: false,
            dark_mean: 0.0,
            sweeps: 0,
            incremental_sweeps: 0,
            started: Instant::now(),
        };
        h.grow(mesh);
        h
    }

    /// Extends the per-node arrays to nodes the mesh gained, and maps elements to leaves.
    fn grow(&mut self, mesh: &Mesh) {
        self.links_changed();
        self.sight = None;
        let old = self.parent.len();
        let n = mesh.nodes.len();
        self.parent.resize(n, NONE);
        self.node_patch.resize(n, NONE);
        self.node_area.resize(n, 0.0);
        self.node_b.resize(n, Vec3::ZERO);
        self.node_corners.resize(n, [Vec3::ZERO; 3]);
        self.node_moments.resize(n, Moments::default());
        self.node_h.resize(n, [Vec3::ZERO; 3]);
        self.node_external_range.resize(n, f32::NAN);
        if old == 0 {
            for (p, patch) in mesh.patches.iter().enumerate() {
                self.node_patch[patch.root as usize] = p as u32;
            }
        }
        // Parents come before their children, so one pass in index order sets both.
        for i in 0..n {
            if let Some(kids) = mesh.nodes[i].children {
                for k in kids {
                    let k = k as usize;
                    if k >= old {
                        self.parent[k] = i as u32;
                        self.node_patch[k] = self.node_patch[i];
                        self.node_b[k] = self.node_b[i];
                    }
                }
            }
        }
        for i in old..n {
            self.node_area[i] = crate::geometry::triangle_area(&mesh.nodes[i].verts);
        }
        self.element_node = vec![NONE; mesh.elements.len()];
        for (i, node) in mesh.nodes.iter().enumerate() {
            if let Some(e) = node.element {
                self.element_node[e as usize] = i as u32;
            }
        }
        self.element_area = mesh.elements.iter().map(|e| e.area).collect();
        let above = &self.clusters.patch_parent;
        self.element_cluster = mesh
            .elements
            .iter()
            .map(|e| above[e.patch as usize])
            .collect();
    }

    /// Where a node is: a surface node's centroid or a cluster's centre.
    fn centre(&self, mesh: &Mesh, id: NodeId) -> Vec3 {
        match id.cluster() {
            Some(c) => self.clusters.nodes[c].centre,
            None => transfer::centroid(&mesh.nodes[id.0 as usize].verts),
        }
    }

    fn b(&self, id: NodeId) -> Vec3 {
        match id.cluster() {
            Some(c) => self.cluster_b[c],
            None => self.node_b[id.0 as usize],
        }
    }

    /// The radiosity a link's source sends to a receiver centred at `at`: what a cluster
    /// sends that way ([`Sender::toward`]; where nothing in it faces that way, the mean of
    /// its faces weighted by their projected areas), or a
    /// surface node's linear fit at the link's kernel centroid
    /// (`transfer::kernel_centroid`, barycentric weights of the node's corners), never
    /// negative.
    fn source_b(&self, l: &StoredLink, at: Vec3) -> Vec3 {
        match l.source.cluster() {
            Some(c) => self.cluster_send[c].seen_from(at).0,
            None => sent_at(&self.node_corners[l.source.0 as usize], l.transfer.toward()),
        }
    }

    /// Pulls B up: each inner node and cluster gets the area mean of its children, and
    /// each inner surface node the slope of the least-squares linear fit to its leaves'
    /// radiosity (each leaf's B at its centroid, weighted by its area): g = M⁻¹ Σ_l A_l B_l
    /// (c_l − c), with M = Σ_l A_l (c_l − c)(c_l − c)ᵀ in the node's plane, both moments
    /// gathered up the tree by the parallel-axis rule. A leaf's B is constant (slope 0).
    fn pull(&mut self, mesh: &Mesh, radiosity: &[DVec3]) {
        for i in (0..mesh.nodes.len()).rev() {
            self.pull_node(mesh, i, radiosity);
        }
        for c in (0..self.clusters.nodes.len()).rev() {
            self.pull_cluster(mesh, c);
        }
        self.basis = None;
    }

    /// [`Hierarchy::pull`] at surface node `i`, whose children are pulled already.
    fn pull_node(&mut self, mesh: &Mesh, i: usize, radiosity: &[DVec3]) {
        let centre = |i: usize| transfer::centroid(&mesh.nodes[i].verts);
        let node = &mesh.nodes[i];
        self.node_b[i] = match (node.element, node.children) {
            (Some(e), _) => {
                let b = radiosity[e as usize].as_vec3();
                self.node_corners[i] = [b; 3];
                self.node_moments[i] = Moments::default();
                b
            }
            (None, Some(kids)) => {
                let mut s = Vec3::ZERO;
                let mut a = 0.0;
                for k in kids {
                    s += self.node_b[k as usize] * self.node_area[k as usize];
                    a += self.node_area[k as usize];
                }
                let mean = if a > 0.0 { s / a } else { Vec3::ZERO };
                let normal = mesh.patches[self.node_patch[i] as usize].normal;
                let (t, b) = crate::geometry::orthonormal_basis(normal);
                let c = centre(i);
                let (mut f, mut m) = ([Vec3::ZERO; 2], [0.0f32; 3]);
                for k in kids {
                    let k = k as usize;
                    let d = centre(k) - c;
                    let (dt, db) = (d.dot(t), d.dot(b));
                    let area = self.node_area[k];
                    let weighted = (self.node_b[k] - mean) * area;
                    let below = &self.node_moments[k];
                    f[0] += below.first[0] + weighted * dt;
                    f[1] += below.first[1] + weighted * db;
                    m[0] += below.second[0] + area * dt * dt;
                    m[1] += below.second[1] + area * dt * db;
                    m[2] += below.second[2] + area * db * db;
                }
                let det = m[0] * m[2] - m[1] * m[1];
                let (mut gt, mut gb) = (Vec3::ZERO, Vec3::ZERO);
                if det > 1e-6 * (m[0] + m[2]) * (m[0] + m[2]) {
                    gt = (f[0] * m[2] - f[1] * m[1]) / det;
                    gb = (f[1] * m[0] - f[0] * m[1]) / det;
                }
                self.node_corners[i] = node.verts.map(|v| {
                    let d = v - c;
                    mean + gt * d.dot(t) + gb * d.dot(b)
                });
                self.node_moments[i] = Moments {
                    first: f,
                    second: m,
                };
                mean
            }
            (None, None) => {
                self.node_corners[i] = [Vec3::ZERO; 3];
                self.node_moments[i] = Moments::default();
                Vec3::ZERO
            }
        };
    }

    /// [`Hierarchy::pull`] at cluster `c`, whose children are pulled already.
    fn pull_cluster(&mut self, mesh: &Mesh, c: usize) {
        let mut s = Vec3::ZERO;
        let mut a = 0.0;
        let mut facing = Facing::default();
        for &k in self.clusters.children_of(c) {
            let area = match k.cluster() {
                Some(j) => {
                    facing.merge(&self.cluster_facing[j]);
                    self.clusters.nodes[j].area
                }
                None => {
                    let n = k.0 as usize;
                    let normal = mesh.patches[self.node_patch[n] as usize].normal;
                    facing.add_surface(normal, self.node_area[n], self.node_b[n]);
                    self.node_area[n]
                }
            };
            s += self.b(k) * area;
            a += area;
        }
        self.cluster_b[c] = if a > 0.0 { s / a } else { Vec3::ZERO };
        self.cluster_facing[c] = facing;
        self.cluster_send[c] = Sender::new(&facing, self.clusters.nodes[c].centre);
    }

    /// Gathers H at every receiver over its links (at a surface node's corners; by
    /// direction for a cluster).
    fn gather(&mut self, mesh: &Mesh) {
        let centre = |id: NodeId| self.centre(mesh, id);
        // Along the leaves' rays the links with a cluster at either end carry nothing the
        // leaves read (see [`sight`]).
        let by_rays = self.leaf_sight().is_some();
        let sums: Vec<(NodeId, [Vec3; 3], Octants)> = self
            .links
            .par_groups()
            .map(|(r, group)| {
                let mut h = [Vec3::ZERO; 3];
                let mut o = Octants::default();
                if by_rays && r.cluster().is_some() {
                    return (r, h, o);
                }
                if let Some(c) = r.cluster() {
                    let cluster = &self.clusters.nodes[c];
                    let at = cluster.centre;
                    for l in group {
                        // The way to the source's centre, from a cluster source's
                        // sender record (the direction its light is read for).
                        let (b, to_source) = match l.source.cluster() {
                            Some(s) => self.cluster_send[s].seen_from(at),
                            None => (
                                self.source_b(l, at),
                                (centre(l.source) - at).normalize_or_zero(),
                            ),
                        };
                        let e = b * l.transfer.factor();
                        if l.transfer.spread().is_infinite() {
                            // Ends that overlap (`transfer::overlap`): a sampled near link
                            // carries the mean irradiance over the cluster's surfaces.
                            o.add_mean(e, cluster);
                        } else {
                            o.add(e, to_source);
                        }
                    }
                } else {
                    let at = centre(r);
                    for l in group.iter().filter(|l| gathered_at_surface(by_rays, l)) {
                        let b = self.source_b(l, at);
                        let c = l.transfer.corners();
                        for k in 0..3 {
                            h[k] += b * c[k];
                        }
                    }
                }
                (r, h, o)
            })
            .collect();
        self.node_h.iter_mut().for_each(|h| *h = [Vec3::ZERO; 3]);
        self.cluster_h
            .iter_mut()
            .for_each(|h| *h = Octants::default());
        for (r, h, o) in sums {
            match r.cluster() {
                Some(c) => self.cluster_h[c] = o,
                None => self.node_h[r.0 as usize] = h,
            }
        }
    }

    /// The light of the links to clusters, laid out for the leaves: along their rays
    /// where the sight fits the leaves (from the elements' radiosity `b` and `opacity`, a
    /// ray taking its hit's covered part's: see `Mesh::opacity`), by facing otherwise (see
    /// [`sight`]).
    fn cluster_down(&self, b: &[DVec3], opacity: &[f32]) -> ClusterLight {
        match self.leaf_sight() {
            Some(_) => ClusterLight::rays(b, opacity),
            None => ClusterLight::facing(&self.cluster_h, &self.clusters),
        }
    }

    /// The leaves' sight, where it was cast for these leaves.
    fn leaf_sight(&self) -> Option<&Sight> {
        self.sight
            .as_ref()
            .filter(|s| s.fits(self.element_node.len()))
    }

    /// The part of a leaf's H its own links and its quadtree ancestors' bring.
    fn leaf_surface_irradiance(&self, mesh: &Mesh, element: usize) -> Vec3 {
        let mut node = self.element_node[element];
        let x = mesh.elements[element].centroid();
        let mut h = Vec3::ZERO;
        while node != NONE {
            h += linear_at(mesh, node, &self.node_h[node as usize], x);
            node = self.parent[node as usize];
        }
        h
    }

    /// Irradiance H a leaf receives: its own links', its ancestors' and its clusters'.
    /// Each ancestor's linear H is evaluated at the leaf's centroid (so a node's children
    /// receive, area-weighted, exactly what it gathered: push conserves power).
    fn leaf_irradiance_linear(&self, mesh: &Mesh, element: usize, down: &ClusterLight) -> Vec3 {
        let (surfaces, clusters) = self.leaf_irradiance_parts(mesh, element, down);
        surfaces + clusters
    }

    /// [`Hierarchy::leaf_irradiance_linear`] in its two parts: what the surface links
    /// bring, and what the links to clusters bring (along the leaf's rays, see [`sight`]).
    fn leaf_irradiance_parts(
        &self,
        mesh: &Mesh,
        element: usize,
        down: &ClusterLight,
    ) -> (Vec3, Vec3) {
        let surfaces = self.leaf_surface_irradiance(mesh, element);
        let c = self.element_cluster[element];
        let clusters = if c != NONE {
            let normal = mesh.elements[element].normal;
            Sight::leaf(self.leaf_sight(), element, normal, c, down)
        } else {
            Vec3::ZERO
        };
        (surfaces, clusters)
    }

    /// A leaf's H from [`Hierarchy::leaf_irradiance_linear`]: the negative values that
    /// extrapolated linear functions can reach (beside a shadow boundary) cut off at zero,
    /// and scaled by the leaf's conservation cap.
    fn capped(&self, element: usize, linear: Vec3) -> Vec3 {
        let cap = if self.leaf_cap.len() == self.element_node.len() {
            self.leaf_cap[element]
        } else {
            1.0
        };
        linear.max(Vec3::ZERO) * cap
    }

    /// Sets each leaf's conservation cap, 1 / max(1, T), where T is the total form factor
    /// its links hand it: the irradiance it gathers when every source's covered part has
    /// B = 1 (a cut-out sends its opacity, `Mesh::opacity`). A point
    /// sees at most its whole hemisphere, so T ≤ 1 (T = 1 inside a closed scene). Links
    /// that refinement left coarse can deliver more: a linear transfer extrapolated from
    /// its quadrature points into a corner the receiver shares with the source, a
    /// cluster's push by direction to a tilted surface. Such a leaf's H is scaled back to
    /// a whole hemisphere. Without it, nvpro's Cornell box (ρ = 0.999, whose link budget
    /// stops refinement early: T up to 3.7 at its corners and on its spheres) gained
    /// light with every sweep, without bound; the built-in box has T ≤ 1.06.
    ///
    /// T sums the links' transfers with their signs: a linear transfer can dip below zero
    /// at a corner of its receiver, and a source's linear fit can send a little more than
    /// its brightest leaf, so the caps bound the light a leaf takes without proving the
    /// sweeps a contraction. A capped leaf's links are all scaled alike, whichever of them
    /// brought the excess. Leaves the node values at `radiosity`, as a pull does.
    /// `opacity`: each element's (`Solver::opacity`, empty where all are opaque).
    fn conservation_caps(&mut self, mesh: &Mesh, bvh: &Bvh, radiosity: &[DVec3], opacity: &[f32]) {
        if self.leaf_sight().is_none() {
            self.sight = Some(match self.stale_sight.take() {
                Some(stale) => stale.refresh(mesh, bvh),
                None => Sight::cast(mesh, bvh),
            });
        }
        if let Some(sight) = self.sight.as_mut() {
            let nodes = (
                &self.element_node[..],
                &self.parent[..],
                &self.node_patch[..],
            );
            sight.match_links(mesh, &self.links, nodes);
        }
        // Every surface's covered part at B = 1: an element then sends its opacity
        // (`Mesh::opacity`), and a cut-out's link counts its covered share of the
        // hemisphere, the light through it the rest.
        let ones: Vec<DVec3> = if opacity.is_empty() {
            vec![DVec3::ONE; mesh.elements.len()]
        } else {
            opacity.iter().map(|o| DVec3::splat(*o as f64)).collect()
        };
        self.pull(mesh, &ones);
        self.gather(mesh);
        let share = (0..mesh.elements.len())
            .into_par_iter()
            .with_min_len(1024)
            .map(|e| self.leaf_surface_irradiance(mesh, e).x)
            .collect();
        if let Some(sight) = self.sight.as_mut() {
            sight.set_surface_share(share);
        }
        let down = self.cluster_down(&ones, opacity);
        self.leaf_cap = (0..mesh.elements.len())
            .into_par_iter()
            .with_min_len(1024)
            .map(|e| {
                let t = self.leaf_irradiance_linear(mesh, e, &down).x;
                if t > 1.0 { 1.0 / t } else { 1.0 }
            })
            .collect();
        // The oracle and the inspector read the node values before the next sweep.
        self.pull(mesh, radiosity);
    }

    /// Forgets what incremental sweeps keep of the links and the last sweep: the links,
    /// the nodes or the elements changed.
    fn links_changed(&mut self) {
        self.basis = None;
        self.by_source = None;
        self.edited.clear();
    }

    /// The refinement round under way among the rounds from coarse to fine (see
    /// [`COARSE_START`]), counted from 0, and their number: the round at 16 ε is 0 of 5,
    /// those at ε are 4.
    pub fn refinement_round(&self) -> (u32, u32) {
        let rounds = COARSE_START.log2().round() as u32 + 1;
        let round = (COARSE_START / self.coarseness.max(1.0)).log2().round() as u32;
        (round.min(rounds - 1), rounds)
    }

    /// The links there are: the solution's, or during a refinement round those it holds.
    pub fn link_count(&self) -> usize {
        self.links.len() + self.round.as_ref().map_or(0, oracle::Round::links)
    }

    /// Bytes the links take: the solution's table, or during a refinement round the
    /// links it holds.
    pub fn link_bytes(&self) -> usize {
        self.links.bytes()
            + self
                .round
                .as_ref()
                .map_or(0, |r| r.links() * std::mem::size_of::<Link>())
    }

    /// Bytes the links' index by source takes (see [`incremental`]), once made.
    pub fn link_index_bytes(&self) -> usize {
        self.by_source
            .as_ref()
            .map_or(0, incremental::BySource::bytes)
    }
}

impl Solver {
    /// One piece of the hierarchical solve: a refinement round or one sweep.
    pub(super) fn hierarchical_work(&mut self, cancel: &AtomicBool) -> Result<(), Stop> {
        let mut h = match self.hierarchy.take() {
            Some(h) => h,
            None => {
                let mut h = Hierarchy::new(&self.mesh, &self.reflectance);
                h.pull(&self.mesh, &self.radiosity);
                h
            }
        };
        let result = self.hierarchical_piece(&mut h, cancel);
        self.stats.links = Some(h.link_count());
        self.stats.link_bytes = Some(h.link_bytes());
        self.stats.link_budget_reached = Some(h.threshold.is_infinite());
        self.stats.incremental_sweeps = Some(h.incremental_sweeps);
        self.stats.link_index_bytes = Some(h.link_index_bytes());
        self.stats.refinement_round = Some(h.refinement_round());
        self.hierarchy = Some(h);
        result
    }

    fn hierarchical_piece(&mut self, h: &mut Hierarchy, cancel: &AtomicBool) -> Result<(), Stop> {
        match h.stage {
            Stage::Refine => match self.refine_piece(h, cancel)? {
                None => {}
                // Done when a round at the full threshold changed nothing (or, once its
                // sweeps converge, little: `ROUND_TOLERANCE`).
                Some(false) if h.sweeps > 0 && !h.edited_in_round && h.coarseness <= 1.0 => {
                    self.finish(h);
                }
                Some(changed) => {
                    h.last_round = h.sweeps > 0
                        && !h.edited_in_round
                        && h.coarseness <= 1.0
                        && h.round_new_links as f64
                            <= self.settings.hierarchy.round_tolerance * h.link_count() as f64;
                    if h.sweeps == 0 && h.first_round_restarted {
                        // The picture kept through the restarted round came from coarser
                        // links and may hold light where these hold none: the inside of a
                        // sealed sphere of ρ = 0.999 would take thousands of sweeps to
                        // give it back (nvpro: 581 sweeps instead of 75). The sweeps start
                        // from E' instead, as they would have without the restart.
                        self.radiosity = self.source.iter().map(|s| s.as_dvec3()).collect();
                    }
                    h.edited_in_round = false;
                    h.stage = Stage::Sweep;
                    h.acceleration.restart();
                    if changed {
                        h.conservation_caps(&self.mesh, &self.bvh, &self.radiosity, &self.opacity);
                    }
                }
            },
            Stage::Sweep => {
                // Leaves split in a round that kept its links: caps of another length.
                if h.leaf_cap.len() != self.mesh.elements.len() {
                    h.conservation_caps(&self.mesh, &self.bvh, &self.radiosity, &self.opacity);
                }
                let change = self.sweep(h, true);
                h.sweeps += 1;
                self.note_first_solution(h);
                self.stats.residual = Some(change);
                self.stats.iterations += 1;
                // Converged to the full tolerance (what an edit's rebase needs), or only
                // as far as the next, coarser round needs.
                let absorbed = self.absorbed();
                h.converged = change <= self.sweep_tolerance(absorbed);
                if h.last_round && h.converged {
                    self.finish(h);
                } else if change <= self.round_sweep_tolerance(h, absorbed) {
                    h.stage = Stage::Refine;
                }
            }
        }
        Ok(())
    }

    /// One Jacobi sweep with push–pull, then Anderson's step from it; returns the
    /// area-weighted relative change of B the sweep made (the residual of the iterate it
    /// started from). Where few elements changed since the last sweep (an edit) and
    /// `may_be_incremental` (not for a preview, whose links are gone after it), the sweep
    /// is incremental ([`incremental`]): the same result up to f32 rounding, through the
    /// links out of what changed.
    fn sweep(&mut self, h: &mut Hierarchy, may_be_incremental: bool) -> f64 {
        self.rebase_on_sweep_basis(h);

        let mesh = &self.mesh;
        let incremental = may_be_incremental
            && h.sweep_incrementally(mesh, (&self.radiosity, &self.opacity), &mut self.gathered)
                .is_some();
        if incremental {
            h.incremental_sweeps += 1;
            h.incremental_in_a_row += 1;
        } else {
            h.incremental_in_a_row = 0;
            h.pull(mesh, &self.radiosity);
            h.gather(mesh);
            let down = h.cluster_down(&self.radiosity, &self.opacity);
            let parts: Vec<(Vec3, Vec3)> = (0..mesh.elements.len())
                .into_par_iter()
                .with_min_len(1024)
                .map(|e| h.leaf_irradiance_parts(mesh, e, &down))
                .collect();
            // The gathered H is kept for edits: B = E' + ρ H answers a reflectance change
            // at once (`edits`); the linear H for incremental sweeps.
            (h.leaf_linear, self.gathered) = parts
                .par_iter()
                .enumerate()
                .with_min_len(1024)
                .map(|(e, (surfaces, clusters))| {
                    let linear = surfaces + clusters;
                    (linear, h.capped(e, linear).as_dvec3())
                })
                .unzip();
            let area = &h.element_area;
            let light = ordered_sum(parts.len(), |e| {
                let (surfaces, clusters) = parts[e];
                let a = area[e] as f64;
                DVec2::new(
                    clusters.element_sum() as f64,
                    (surfaces + clusters).element_sum() as f64,
                ) * a
            });
            self.stats.cluster_light_share = (light.y > 0.0).then(|| light.x / light.y);
        }
        let (source, reflectance) = (&self.source, &self.reflectance);
        let swept: Vec<DVec3> = self
            .gathered
            .par_iter()
            .enumerate()
            .with_min_len(ELEMENT_CHUNK)
            .map(|(e, hh)| source[e].as_dvec3() + (reflectance[e] * hh.as_vec3()).as_dvec3())
            .collect();
        // The area-weighted change and total, as x and y.
        let old = &self.radiosity;
        let area = &h.element_area;
        let sums = ordered_sum(swept.len(), |e| {
            let b = swept[e];
            DVec2::new(sum3d((b - old[e]).abs()), sum3d(b.abs())) * area[e] as f64
        });
        let (changed, total) = (sums.x, sums.y);
        let scales = LightScales::of(&swept, |e| area[e]);
        self.stats.worst_element_residual = Some(worst_element_residual(old, &swept, &scales));
        let next = h.acceleration.next(&self.radiosity, swept, &scales);
        h.basis = Some(std::mem::replace(&mut self.radiosity, next));
        if total > 0.0 { changed / total } else { 0.0 }
    }

    /// Before the first sweep after an edit: takes the last sweep's input as the current
    /// solution, except on the edited patches' elements, which keep what the edit made
    /// of them, so that the sweep differs from the last one only through those and can be
    /// incremental. The two differ by one sweep's change, below the tolerance once the
    /// solve has converged. Copied here rather than at the edit, whose first update must
    /// be quick.
    fn rebase_on_sweep_basis(&mut self, h: &mut Hierarchy) {
        let edited = std::mem::take(&mut h.edited);
        let Some(basis) = h.basis.as_ref() else {
            return;
        };
        if edited.is_empty() || basis.len() != self.radiosity.len() {
            return;
        }
        let kept: Vec<(usize, DVec3)> = edited
            .iter()
            .flat_map(|&p| self.mesh.patches[p as usize].elements.clone())
            .map(|e| (e as usize, self.radiosity[e as usize]))
            .collect();
        self.radiosity.copy_from_slice(basis);
        for (e, b) in kept {
            self.radiosity[e] = b;
        }
    }

    /// 1 − ρ̄, at least 10⁻³: what a bounce absorbs (one pass over the elements).
    fn absorbed(&self) -> f64 {
        (1.0 - self.mean_reflectance()).max(1e-3)
    }

    /// The change per sweep the sweeps stop at: the tolerance scaled by `absorbed`,
    /// 1 − ρ̄ (Jacobi's change per sweep shrinks by about ρ̄ each sweep, so what is left
    /// is change · ρ̄ / (1 − ρ̄)). The sweep gathers H in f32, so its change cannot fall
    /// below f32 rounding (a few 10⁻⁸ per element): a tighter tolerance would let the
    /// sweeps cycle at that level for ever, so it is held at [`SWEEP_FLOOR`].
    fn sweep_tolerance(&self, absorbed: f64) -> f64 {
        (self.settings.tolerance * absorbed).max(SWEEP_FLOOR)
    }

    /// The change per sweep at which a refinement round's sweeps hand over to the next
    /// round. The last rounds (at ε) go on to the solve's tolerance. A coarser round's
    /// oracle judges links against c ε times the scene's scale (c its coarseness), so
    /// the sweeps before it need B only to a tenth of that: what is left after a change
    /// δ per sweep is about δ / (1 − ρ̄), so they stop at δ = c ε (1 − ρ̄) / 10. To the
    /// full tolerance, each of the coarse rounds cost as many sweeps as the last one: the
    /// closed box at ρ = 0.999 of `tests/hierarchical.rs` took 30 sweeps (22 now), and
    /// with the threshold from the scene's gain, whose rounds really do go from coarse
    /// to fine there, 329 (56 now; the box cut to 3,000 links 117–152 with a looser
    /// restart of Anderson's window, 12 now).
    fn round_sweep_tolerance(&self, h: &Hierarchy, absorbed: f64) -> f64 {
        let full = self.sweep_tolerance(absorbed);
        // Past the link budget (or at an infinite ε) no round refines anything.
        if h.coarseness <= 1.0 || !h.threshold.is_finite() {
            return full;
        }
        let eps = self.settings.hierarchy.link_error as f64;
        let coarse = 0.1 * h.coarseness as f64 * eps * absorbed;
        full.max(coarse)
    }

    /// The solve is converged: the sweeps met the tolerance after a round at ε that
    /// changed nothing, or little (see `ROUND_TOLERANCE`).
    fn finish(&mut self, h: &mut Hierarchy) {
        self.phase = super::Phase::Done;
        h.last_round = false;
        // Edits come to a converged solve: their sweeps need the links by source, which
        // would otherwise cost the first edit.
        h.index_links_by_source(&self.mesh);
    }

    /// Records when the first solution of the whole scene was ready.
    fn note_first_solution(&mut self, h: &Hierarchy) {
        if self.stats.first_solution_seconds.is_none() {
            self.stats.first_solution_seconds = Some(h.started.elapsed().as_secs_f64());
        }
    }

    /// Streaming: up to `sweeps` accelerated sweeps over the links a first refinement
    /// round holds so far, stopping at the solve's tolerance, so that a whole-scene
    /// picture is there long before the round ends (on a large scene the round takes
    /// minutes); returns the sweeps made. Between two generations, the links kept, the
    /// links just made and those waiting for a leaf split cover every pair of the scene's
    /// surfaces exactly once, at the levels refinement has reached: the picture comes
    /// from the top levels first and sharpens as they refine. Each preview starts from the
    /// last one's B. The round's own decisions are unchanged (the node values the oracle
    /// reads are put back); the sweeps after it start warm, so the converged answer moves
    /// only within their tolerance.
    ///
    /// One sweep per preview showed one more bounce each time, far below the light the
    /// links carry: on the Cornell box the previews were 63 % off the reference at 1 s
    /// and 27 % at 5 s; converged, 17 % and 8 %.
    fn preview(&mut self, h: &mut Hierarchy, mut links: Vec<&Link>, sweeps: usize) -> usize {
        let saved = (
            h.node_b.clone(),
            h.node_corners.clone(),
            h.cluster_b.clone(),
        );
        // Sorted by reference: the round's links are not copied.
        links.par_sort_unstable_by_key(|l| (l.receiver, l.source));
        h.links = LinkTable::new(&links, false);
        drop(links);
        // The caps belong to the links of the last round, not to these, and so do the
        // sight's marks of which rays the clusters carry.
        let caps = std::mem::take(&mut h.leaf_cap);
        let sight = h.sight.take();
        // The acceleration's history is for one set of links: these are not the last
        // preview's, nor those the round's own sweeps will have.
        h.acceleration.restart();
        let tolerance = self.sweep_tolerance(self.absorbed());
        let made = (1..=sweeps)
            .find(|_| self.sweep(h, false) <= tolerance)
            .unwrap_or(sweeps);
        h.acceleration.restart();
        h.leaf_cap = caps;
        h.sight = sight;
        h.links = LinkTable::default();
        h.links_changed();
        (h.node_b, h.node_corners, h.cluster_b) = saved;
        self.note_first_solution(h);
        made
    }

    /// Area-weighted mean over the elements of `value(i)`; `None` without area.
    pub(super) fn area_mean(&self, value: impl Fn(usize) -> f64) -> Option<f64> {
        let (mut sum, mut area) = (0.0f64, 0.0f64);
        for (i, e) in self.mesh.elements.iter().enumerate() {
            sum += value(i) * e.area as f64;
            area += e.area as f64;
        }
        (area > 0.0).then(|| sum / area)
    }

    /// Area-weighted mean of the largest reflectance channel.
    pub(super) fn mean_reflectance(&self) -> f64 {
        self.area_mean(|i| self.reflectance[i].max_element() as f64)
            .unwrap_or(0.0)
    }

    /// After an edit of the `edited` patches: sweep again from the current solution, then
    /// let the oracle look.
    pub(super) fn hierarchy_edited(&mut self, edited: &[u32]) {
        if let Some(h) = &mut self.hierarchy {
            let mesh = &self.mesh;
            for &p in edited {
                let first = mesh.patches[p as usize].elements.start as usize;
                if let Some(rho) = self.reflectance.get(first) {
                    h.patch_reflectance[p as usize] = rho.max_element();
                }
            }
            let (roots, rho) = (&h.node_patch, &h.patch_reflectance);
            h.clusters
                .update_reflectance(edited.iter().copied(), |root| {
                    rho[roots[root as usize] as usize]
                });
            h.acceleration.restart();
            // Only a converged solve may be put back on its last sweep's input: while
            // edits keep coming (a slider dragged), the sweeps must keep moving the rest.
            if h.basis.is_some() && h.converged {
                h.edited.extend_from_slice(edited);
            }
            h.last_round = false;
            if h.round.is_none() {
                h.stage = Stage::Sweep;
            } else {
                // The round may end without changing a link; the edit still needs sweeps.
                h.edited_in_round = true;
            }
        }
    }
}
