//! The refinement oracle and the link refinement it drives (Hanrahan, Salzman & Aupperle
//! 1991, §4 "Refine"; with B-weighting and the source's variation as in Hanrahan et al.'s
//! "BF refinement").
//!
//! A link's error estimate is ρ_r · (spread · B_s + factor · ΔB_s · min(1, r_s / d)): the kernel's variation
//! over the link's ends (partial visibility included, see `transfer`) times the radiosity
//! it carries, plus what averaging the source hides (ΔB_s, the spread of its children's
//! radiosity, times the kernel's relative variation across a source of radius r_s at
//! distance d). A link above ε · Ē' (Ē' the scene's area-weighted mean of what its
//! surfaces emit or first reflect of the sky, sun and lamps; see
//! [`Solver::link_threshold`]; for a receiver darker than the mean radiosity B̄, scaled by
//! B_r / B̄, floored at a tenth: see `View::darkness`) is
//! replaced by links to the children of one end: the source when its own variation
//! dominates, otherwise the larger end (by area between surfaces, by radius when a cluster
//! is involved; a cluster linked to itself splits both ends). A leaf that must split and is
//! at least twice the minimum size is split in the mesh first, all such leaves at once.
//! Where a link's ends touch (the foot of a block, a room's corner), the link is held to a
//! quarter of the threshold and its leaves may go to a quarter of the minimum size (see
//! [`CONTACT_GRADING`]).
//!
//! A receiver's links are also judged together: near its corners their linear transfers
//! can miss the kernel all the same way, so a receiver whose links together miss by more
//! than the threshold is split even when each link is within it (see
//! `View::receiver_overloaded`).
//!
//! Refinement runs in generations (every link decided in parallel, the new links evaluated
//! in parallel) until no link needs it, so one round refines as deep as the current
//! solution asks; the order of the links does not matter, since they are sorted at the end.

use super::clusters::SAMPLES;
use super::external;
use super::sight::StaleSight;
use super::table::LinkTable;
use super::transfer::{self, Sample, Shape};
use super::{Hierarchy, Link, NONE, NodeId};
use crate::cancel::check;
use crate::geometry::{MIDDLE_CHILD, closest_point_on_triangle, longest_edge, shortest_altitude};
use crate::mesh::Mesh;
use crate::solver::refine::split_children;
use crate::solver::types::{MAX_LINK_BUDGET, Stop};
use crate::solver::{Method, Solver, external_factor};
use glam::Vec3;
use rayon::prelude::*;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

/// How much stricter the oracle is with links from a cluster (see `View::decide`).
const CLUSTER_STRICTNESS: f32 = 4.0;

/// The darkest a receiver counts as, relative to the scene's mean radiosity, when its
/// threshold is scaled by its radiosity (see `View::darkness`).
const DARK_FLOOR: f32 = 0.1;

/// A refinement round under way, kept between steps.
#[derive(Default)]
pub(super) struct Round {
    threshold: f32,
    /// The threshold the round began with, which the external light's splits keep when
    /// the link budget makes `threshold` infinite (they add elements, not links).
    external_threshold: f32,
    /// Before the first sweep only the emitters have light, so every other link would stay
    /// at the top, where cluster transfers are coarsest (the first solution came out 50 %
    /// too bright on the Cornell box). The first round takes each source's B to be its
    /// E' plus ρ_s times the ambient radiosity the scene will reach, Σ A E' / Σ A ·
    /// ρ̄ / (1 − ρ̄) (the ambient term of Cohen et al. 1988), so it links as the lit scene
    /// needs; later rounds use the solution itself.
    ambient: f32,
    /// Links decided to stay.
    kept: Vec<Link>,
    /// Links above their threshold kept only because no end could split: decided again
    /// when one of their ends is split for balance (see `Decision::Stuck`).
    stuck: Vec<Link>,
    /// Links to decide (the next generation).
    work: Vec<Link>,
    /// New pairs to evaluate, and how many are done.
    pairs: Vec<(NodeId, NodeId)>,
    next_pair: usize,
    /// Evaluated new links of this generation.
    made: Vec<Link>,
    /// Links waiting for a leaf split, and the leaves.
    waiting: Vec<Link>,
    /// The light first. In a scene lit by its emitting surfaces alone, the first round's
    /// previews were nearly black until the round ended: a link the oracle will split
    /// carries nothing, and the links from the emitters are the ones it splits most, so
    /// breadth first they were among the last to carry anything (nvpro's 8.7 M previewed
    /// links at 5.4 s held 38 k from lit sources, 2.5 k of them carrying light; its
    /// picture stayed 81 % off the path-traced truth until 26 s). So the first round puts
    /// off the pairs whose source has no light yet (no E'; every node holding an emitter
    /// has) until the lit ones are all decided, and previews then: the emitters' light
    /// reaches every surface at the levels the round keeps, and each later preview adds
    /// bounces as the unlit links refine. Each decision is the one breadth first would
    /// make (the oracle reads the same node values), so the links come out the same but
    /// for a few a receiver splits along with its lit links when those miss light near
    /// its corners (0.26 % fewer on the Cornell box, `tests`). A link whose pairs are all
    /// put off stays in `unlit_parents`, standing for them in the previews.
    ///
    /// `bench builtin:cornell --methods hierarchical` against the path-traced reference,
    /// one run after the other: 19.5 → 9.2 % at 1 s, 8.9 → 5.9 % at 1.5 s, 5.2 → 4.1 % at
    /// 2 s, 3.1 → 2.7 % at 4 s, converged the same (1.55 %, 37 sweeps). vinc3r's box: 92
    /// → 67 % at 0.5 s, 90 → 49 % at 5 s. A scene lit by a sky, a sun or lamps outside
    /// the mesh has its first bounce in E' already (Sponza), and keeps the breadth-first
    /// order.
    unlit_pairs: Vec<(NodeId, NodeId)>,
    unlit_parents: Vec<Link>,
    /// Whether pairs from unlit sources are still put off: in the first round, until its
    /// lit pairs are all decided.
    defer_unlit: bool,
    /// Whether any pair was put off.
    deferred: bool,
    /// A round whose links pass a quarter of the link budget with pairs put off starts
    /// again, in breadth-first order and without previews. Where the budget cuts depends
    /// on the order: with the light first, nvpro's converged picture came out 40 % too
    /// bright (45 % off the truth instead of 21 %; at ρ = 0.999 a per cent more transfer
    /// makes a quarter more light), even with only the first 65 k links in that order.
    /// Started again, it ends with the very links of the breadth-first order (21.5 %, the
    /// final gather 8.1 %, as before), about 4 s later (`solve`: 23.3 → 27.2 s and 23.8 →
    /// 27.7 s, one after the other), and shows the emitters' light from 2 s on (67 % off
    /// at 5–25 s instead of 81 %).
    restart: bool,
    /// The new links the round has made (pairs evaluated).
    new_links: usize,
    leaves: Vec<u32>,
    changed: bool,
    /// What one sweep of the last preview cost, in links (see `preview_cost`); zero
    /// before the first.
    previewed: usize,
    /// What the round's previews have cost so far, in links.
    preview_spent: usize,
    /// The last sweep's basis (see `Hierarchy::basis`), put back if the round changes
    /// nothing.
    basis: Option<Vec<glam::DVec3>>,
}

impl Round {
    /// The links the round holds: kept, stuck, to decide, made in this generation, and
    /// waiting.
    pub fn links(&self) -> usize {
        self.kept.len()
            + self.stuck.len()
            + self.work.len()
            + self.made.len()
            + self.waiting.len()
            + self.unlit_parents.len()
    }

    /// Stops putting off the unlit pairs: they join the next generation.
    fn resume_unlit(&mut self) {
        self.defer_unlit = false;
        self.pairs.append(&mut self.unlit_pairs);
        self.unlit_parents = Vec::new();
    }
}

/// What a preview sweep costs, in links: its links, and a sweep's pass over every element
/// (a pull, the push and the sums), which on Sponza costs as much as about 4 links each
/// (a preview of a few links over its 445,768 elements took 80 ms, one of 18.7 M links
/// 0.77 s).
fn preview_cost(links: usize, elements: usize) -> usize {
    links + 4 * elements
}

/// The most sweeps one preview makes: each converges the light over the links it has
/// (with Anderson's step, as the solve's sweeps do), so that it shows every bounce, not
/// one more per preview. On the Cornell box eight sweeps instead of four moved no
/// preview's error against the reference by more than 0.9 % (the budget below allows
/// five or six there).
const PREVIEW_SWEEPS: usize = 8;

/// What the previews of a round may cost in all, in links (see `preview_cost`) per ray
/// the solve has cast (in the first round, nearly all of them the round's). A sweep costs
/// about 12 ns a link on the Cornell box and 41 ns on Sponza, the round about 0.25 µs a
/// ray on both (2 cores), so the first round's previews take at most
/// 5 % of the round on the Cornell box and 16 % on Sponza (whose previews meet the
/// tolerance after one sweep: its sweeps converge in three). Measured on the Cornell box:
/// at half a link per ray the early previews got two sweeps and were 43 % off the
/// reference at 0.25 s, at one link per ray five and 23 %, at two eight and 23 %.
const PREVIEW_LINKS_PER_RAY: f64 = 1.0;

/// A round after the first solution previews its links each time a sweep over them has
/// grown by this factor. The coarse-to-fine rounds (`COARSE_START`) each keep the last
/// one's links and refine them for as long as the last one took, or longer: on the Cornell
/// box the round at 8 ε ran from 0.5 to 1.4 s while the picture stayed the 16 ε round's,
/// 19 % off the path-traced truth. With a preview at each quarter's growth it is 8.5 % off
/// at 0.8 s and 6.8 % at 1.0 s, 3.6 % at 2.3 s instead of 5.2 %, 2.2 % at 4.5 s instead of
/// 3.3 %; it converges as before (11.2 s against 11.8 s, both 1.75 %). Before the first
/// solution the previews wait for a doubling instead: the links grow from one. Sponza,
/// which the link budget cuts in its first round, has none.
const LATER_PREVIEW_GROWTH: f64 = 1.25;

/// A coarse round (see `COARSE_START`) whose links pass this share of the link budget goes
/// on at the full threshold.
const COARSE_SHARE: usize = 4;

/// Links decided per parallel chunk when a generation's decisions are applied.
const APPLY_CHUNK: usize = 65_536;

/// What one chunk of a generation's decisions adds to the round (see `View::apply`).
#[derive(Default)]
struct Outcome {
    kept: Vec<Link>,
    stuck: Vec<Link>,
    leaves: Vec<u32>,
    waiting: Vec<Link>,
    pairs: Vec<(NodeId, NodeId)>,
    unlit_pairs: Vec<(NodeId, NodeId)>,
    unlit_parents: Vec<Link>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Decision {
    Keep,
    /// Above its threshold, but no end may split: kept unless an end is split later in
    /// the round (for balance), when it is decided again.
    Stuck,
    Receiver,
    Source,
    /// A cluster linked to itself: every pair of its children.
    Both,
    /// This leaf must be split in the mesh before the link can refine.
    Leaf(u32),
}

/// A link's error estimate, W/m² of B at the receiver: ρ_r · (spread · B_s + factor ·
/// ΔB_s · min(1, r_s / d)), its kernel and source-variation parts, infinite for ends whose
/// bounding spheres overlap; and the threshold it is held to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Estimate {
    pub kernel: f32,
    pub variation: f32,
    pub error: f32,
    pub threshold: f32,
}

/// What the oracle needs of the hierarchy and the mesh, borrowed once per generation.
struct View<'a> {
    h: &'a Hierarchy,
    mesh: &'a Mesh,
    min_size: f64,
    threshold: f32,
    /// The light a source is expected to reflect before any sweep (see `Round::ambient`).
    ambient: f32,
}

/// Where a node is and how large, which is all the oracle's decisions read of its
/// geometry ([`View::shape`] also copies a cluster's sample patches, for transfers).
#[derive(Clone, Copy, Debug)]
struct Bounds {
    centre: Vec3,
    radius: f32,
    area: f32,
}

impl View<'_> {
    fn bounds(&self, id: NodeId) -> Bounds {
        match id.cluster() {
            Some(c) => {
                let c = &self.h.clusters.nodes[c];
                Bounds {
                    centre: c.centre,
                    radius: c.radius,
                    area: c.area,
                }
            }
            None => {
                let n = id.0 as usize;
                let verts = &self.mesh.nodes[n].verts;
                Bounds {
                    centre: transfer::centroid(verts),
                    radius: transfer::radius(verts),
                    area: self.h.node_area[n],
                }
            }
        }
    }

    fn shape(&self, id: NodeId) -> Shape {
        match id.cluster() {
            Some(c) => {
                let c = &self.h.clusters.nodes[c];
                Shape::Cluster {
                    centre: c.centre,
                    radius: c.radius,
                    lo: c.lo,
                    hi: c.hi,
                    facing: c.facing,
                    area: c.area,
                    area_vector: c.area_vector,
                    // Filled in by `with_samples` where rays are cast.
                    samples: [Sample::default(); SAMPLES],
                }
            }
            None => {
                let n = id.0 as usize;
                let p = &self.mesh.patches[self.h.node_patch[n] as usize];
                Shape::Surface {
                    verts: self.mesh.nodes[n].verts,
                    normal: p.normal,
                    area: self.h.node_area[n],
                    triangle: p.scene_triangle,
                }
            }
        }
    }

    /// `shape` (of node `id`) with a cluster's sample patches filled in.
    fn with_samples(&self, shape: &Shape, id: NodeId) -> Shape {
        let mut shape = *shape;
        if let (Shape::Cluster { samples, .. }, Some(c)) = (&mut shape, id.cluster()) {
            *samples = self.h.clusters.nodes[c].samples.map(|p| {
                let p = &self.mesh.patches[p as usize];
                Sample {
                    verts: p.verts,
                    normal: p.normal,
                    area: p.area,
                    triangle: p.scene_triangle,
                }
            });
        }
        shape
    }

    fn reflectance(&self, id: NodeId) -> f32 {
        match id.cluster() {
            Some(c) => self.h.clusters.nodes[c].reflectance,
            None => self.h.patch_reflectance[self.h.node_patch[id.0 as usize] as usize],
        }
    }

    /// Calls `f` with each child of a node, if it has any now.
    fn for_children(&self, id: NodeId, mut f: impl FnMut(NodeId)) {
        match id.cluster() {
            Some(c) => self.h.clusters.children_of(c).iter().for_each(|&k| f(k)),
            None => {
                if let Some(kids) = self.mesh.nodes[id.0 as usize].children {
                    kids.into_iter().for_each(|k| f(NodeId::surface(k)));
                }
            }
        }
    }

    /// What the `decisions` of `links` add to a round: links kept, leaves to split with
    /// the links that wait for them, and the pairs of the next generation.
    /// With `defer_unlit`, the pairs whose source has no light yet go to `unlit_pairs`,
    /// and a link all of whose pairs do to `unlit_parents` (see `Round::unlit_pairs`).
    fn apply(&self, links: &[Link], decisions: &[Decision], defer_unlit: bool) -> Outcome {
        let mut o = Outcome::default();
        for (l, d) in links.iter().zip(decisions) {
            let start = o.pairs.len();
            match d {
                Decision::Keep => o.kept.push(*l),
                Decision::Stuck => o.stuck.push(*l),
                Decision::Leaf(n) => {
                    o.leaves.push(*n);
                    o.waiting.push(*l);
                }
                Decision::Receiver => {
                    self.for_children(l.receiver, |c| o.pairs.push((c, l.source)))
                }
                Decision::Source => self.for_children(l.source, |c| o.pairs.push((l.receiver, c))),
                Decision::Both => self.for_children(l.receiver, |a| {
                    self.for_children(l.receiver, |b| o.pairs.push((a, b)))
                }),
            }
            if !defer_unlit || o.pairs.len() == start {
                continue;
            }
            if !self.lit(l.source) {
                // The children of a source without light have none either.
                o.unlit_parents.push(*l);
                o.unlit_pairs.extend(o.pairs.drain(start..));
            } else {
                // This link's pairs from unlit sources move out, the others stay in order.
                let mut kept = start;
                for i in start..o.pairs.len() {
                    let p = o.pairs[i];
                    if self.lit(p.1) {
                        o.pairs[kept] = p;
                        kept += 1;
                    } else {
                        o.unlit_pairs.push(p);
                    }
                }
                o.pairs.truncate(kept);
            }
        }
        o
    }

    /// Whether a source has light before the first sweep (its E').
    fn lit(&self, s: NodeId) -> bool {
        self.h.b(s).max_element() > 0.0
    }

    /// Whether surface nodes `r` and `s` (with their [`View::bounds`] `rb` and `sb`) touch
    /// or nearly touch: a corner of either lies within [`CONTACT_GAP`] of `r`'s size (as
    /// `sqrt(2 · area)`) of the other.
    fn in_contact(&self, (r, rb): (NodeId, &Bounds), (s, sb): (NodeId, &Bounds)) -> bool {
        if r.cluster().is_some() || s.cluster().is_some() {
            return false;
        }
        let gap = CONTACT_GAP * (2.0 * rb.area).sqrt();
        // Bounding spheres further apart than the gap: no corner can be near (most links).
        if rb.centre.distance(sb.centre) > rb.radius + sb.radius + gap {
            return false;
        }
        let (rv, sv) = (
            &self.mesh.nodes[r.0 as usize].verts,
            &self.mesh.nodes[s.0 as usize].verts,
        );
        let near = |p: &Vec3, t: &[Vec3; 3]| closest_point_on_triangle(*p, t).0.distance(*p) < gap;
        rv.iter().any(|p| near(p, sv)) || sv.iter().any(|p| near(p, rv))
    }

    /// Whether leaf `n` may be split for a link whose ends are in contact (see
    /// [`CONTACT_GRADING`]); never a sliver (shortest altitude under a quarter of its size):
    /// one along the contact is already narrow across it, and its children would only be
    /// shorter along it, where the light changes no faster than elsewhere (splitting the
    /// slivers that line a furnace's edges lost 2.4 % of their light).
    fn leaf_can_split_in_contact(&self, n: u32) -> bool {
        let area = self.h.node_area[n as usize];
        let width = shortest_altitude(&self.mesh.nodes[n as usize].verts);
        width >= 0.25 * (2.0 * area).sqrt()
            && can_split(area, self.min_size / CONTACT_GRADING)
            && !self.h.ungraded.contains(&n)
    }

    /// Whether a leaf surface node may be split (see [`can_split`]).
    fn leaf_can_split(&self, n: u32) -> bool {
        can_split(self.h.node_area[n as usize], self.min_size)
    }

    /// Whether a leaf surface node may be split along its length for a link whose error
    /// asks for it (see [`can_split_along`]), where balance has not refused it. It still
    /// counts as unsplittable elsewhere (its transfers computed as for final ends, and
    /// the summed misfit of its links not asking): letting it split there too lost
    /// vinc3r's gains at its edge points (Hermite 14.5 → 17.0 %).
    fn leaf_can_split_along(&self, n: u32) -> bool {
        can_split_along(&self.mesh.nodes[n as usize].verts, self.min_size)
            && !self.h.ungraded.contains(&n)
    }

    /// Spread of the children's radiosity (largest channel) of a surface node.
    fn source_variation(&self, id: NodeId) -> f32 {
        if id.cluster().is_some() {
            return 0.0;
        }
        let Some(kids) = self.mesh.nodes[id.0 as usize].children else {
            return 0.0;
        };
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for k in kids {
            let b = self.h.node_b[k as usize].max_element();
            lo = lo.min(b);
            hi = hi.max(b);
        }
        (hi - lo).max(0.0)
    }

    /// The kernel part of a link's error estimate, ρ_r · spread · B_s.
    /// The radiosity the oracle takes for a source: its B, plus before the first sweep
    /// the ambient it will reflect.
    fn source_b(&self, s: NodeId) -> f32 {
        self.h.b(s).max_element() + self.reflectance(s) * self.ambient
    }

    fn kernel_error(&self, l: &Link) -> f32 {
        self.reflectance(l.receiver) * l.transfer.spread() * self.source_b(l.source)
    }

    /// Splits the receiver of a group of links whose linear transfers together miss the
    /// kernel by more than the threshold near the receiver's corners. Each link is within
    /// the threshold on its own, but their misses can add up (the kernels over one receiver
    /// bend alike where its other links moved to its children), so the sum
    /// ρ_r · |Σ_l B_l (F_l(x) − L_l(x))| is checked at points 90 % of the way from the
    /// centroid to each corner, F_l the exact unoccluded form factor there times the link's
    /// visibility (its transfer over its unoccluded one) and L_l its linear function. Each
    /// link keeps its F_l − L_l from when it was made (`Link::miss`): recomputing it took
    /// six form factors per link per round, 45 % of the Cornell box's solve.
    fn receiver_overloaded(&self, group: &[Link]) -> Option<Decision> {
        let r = group[0].receiver;
        if group.len() < 2 || r.cluster().is_some() {
            return None;
        }
        let node = &self.mesh.nodes[r.0 as usize];
        let mut miss = [Vec3::ZERO; 3];
        for l in group.iter().filter(|l| l.source.cluster().is_none()) {
            let b = self.h.b(l.source);
            for (m, g) in miss.iter_mut().zip(l.miss()) {
                *m += b * g;
            }
        }
        let rho = self.reflectance(r);
        let worst = miss
            .iter()
            .map(|m| m.abs().max_element())
            .fold(0.0, f32::max)
            * rho;
        if worst.is_nan() || worst <= self.threshold * self.darkness(r) {
            return None;
        }
        if node.children.is_some() {
            Some(Decision::Receiver)
        } else if self.leaf_can_split(r.0) {
            Some(Decision::Leaf(r.0))
        } else {
            None
        }
    }

    /// The link's error estimate and the threshold it is held to; `r` and `s` are the
    /// bounds of its receiver and source.
    fn estimate(&self, l: &Link, r: &Bounds, s: &Bounds) -> Estimate {
        let rho = self.reflectance(l.receiver);
        // Averaging B over the source errs by ΔB_s times how much the kernel varies across
        // the source, about its radius over the distance (at most 1).
        let d = (r.centre - s.centre).length();
        let across = if d > 0.0 {
            (s.radius / d).min(1.0)
        } else {
            1.0
        };
        let variation = rho * l.transfer.factor() * self.source_variation(l.source) * across;
        // A cluster's transfer errs the same way on every link (the far-field kernel of a
        // nearby cluster is low, as the mean of 1/r² exceeds 1/r̄²), so its errors add up
        // over a receiver's cluster links instead of averaging out, and a receiving
        // cluster shares its light out by an approximate orientation (`Octants`): links
        // with a cluster at either end are held to a quarter of the threshold (a sixteenth
        // gave the Cornell box's errors to three digits at many more links on Sponza; none
        // at all left its umbrae 4.7 % off, against 3.3 %).
        let mut threshold = self.held_to(l.receiver, l.source);
        let kernel = self.kernel_error(l);
        // Ends in contact are held to a quarter of it (see `CONTACT_STRICTNESS`), whatever
        // the error (which end splits depends on the threshold too, and a link must not
        // refine further at a smaller error); the contact test runs only where it decides.
        if kernel + variation > threshold / CONTACT_STRICTNESS
            && self.in_contact((l.receiver, r), (l.source, s))
        {
            threshold /= CONTACT_STRICTNESS;
        }
        // Ends whose bounding spheres overlap (a cluster and itself, or two that
        // interpenetrate) have no bound on their kernel: they split, even before their
        // source carries light (the light it is expected to reflect counts, see
        // `source_b`), or the light between them would be lost until it did. (Judging a
        // small receiving cluster's near pairs by the power they may carry let tiny detail
        // keep sampled transfers, and a furnace lined with slivers then missed its closed
        // form by 6 % at the slivers: `tests/hard_geometry.rs`.) But such a pair kept
        // carries nothing and so misses at most all a receiver could take of its source,
        // ρ_r B_s (a whole hemisphere of it): where that is within the threshold it is
        // kept. Sponza's first round split such pairs of dim surfaces for 7 % of its
        // rays: 261 M in all against 242 M.
        let error = if l.transfer.spread().is_infinite() && rho > 0.0 {
            let most = rho * self.source_b(l.source);
            if most > threshold {
                f32::INFINITY
            } else {
                most
            }
        } else {
            kernel + variation
        };
        Estimate {
            kernel,
            variation,
            error,
            threshold,
        }
    }

    /// The threshold a link between `r` and `s` is held to: a quarter of the oracle's with
    /// a cluster at either end (see `estimate`), scaled by the receiver's darkness.
    fn held_to(&self, r: NodeId, s: NodeId) -> f32 {
        let threshold = if r.cluster().is_some() || s.cluster().is_some() {
            self.threshold / CLUSTER_STRICTNESS
        } else {
            self.threshold
        };
        threshold * self.darkness(r)
    }

    /// The receiver's radiosity over the scene's mean, between [`DARK_FLOOR`] and 1 (1
    /// before the first sweep, whose B is the emitters' alone): the threshold ε · Ē' is
    /// absolute, and would let a receiver at a tenth of the mean keep an error of 10 ε of
    /// its own light (after the bounces). A viewer sees (and the bench measures) error
    /// relative to what a surface shows, so a dark receiver is held to ε · Ē' · B_r / B̄,
    /// down to the floor. On the Cornell box the short block's front face, lit only by
    /// interreflection at 4–13 % of the mean, went from 2.2 % to 0.6 % RMS against the
    /// path-traced reference.
    fn darkness(&self, r: NodeId) -> f32 {
        let mean = self.h.dark_mean;
        if mean > 0.0 {
            (self.h.b(r).max_element() / mean).clamp(DARK_FLOOR, 1.0)
        } else {
            1.0
        }
    }

    fn decide(&self, l: &Link) -> Decision {
        let (r, s) = (self.bounds(l.receiver), self.bounds(l.source));
        let Estimate {
            kernel,
            variation,
            error,
            threshold,
        } = self.estimate(l, &r, &s);
        if error.is_nan() || error <= threshold {
            return Decision::Keep;
        }
        if l.receiver == l.source {
            return Decision::Both;
        }
        let surfaces = l.receiver.cluster().is_none() && l.source.cluster().is_none();
        // Which ends may split, in order of preference. Between surfaces the point-to-
        // polygon factor integrates the source exactly, so the kernel's variation is the
        // receiver's to resolve; the source splits for its own variation of B, or when the
        // receiver cannot split and either the source's variation alone is above the
        // threshold or, at a shadow boundary, the source is more than four times the
        // receiver's area (finer visibility). With a cluster the larger end splits.
        // (Without the first fallback, a link whose two parts were about equal kept or
        // split its source by which part came out larger in the last digit: the same link
        // at half the light refined where it had been kept.)
        let order: &[(NodeId, Decision)] = if !surfaces {
            if r.radius >= s.radius {
                &[
                    (l.receiver, Decision::Receiver),
                    (l.source, Decision::Source),
                ]
            } else {
                &[
                    (l.source, Decision::Source),
                    (l.receiver, Decision::Receiver),
                ]
            }
        } else if variation > kernel {
            &[(l.source, Decision::Source)]
        } else if (l.transfer.partial() && s.area > 4.0 * r.area) || variation > threshold {
            &[
                (l.receiver, Decision::Receiver),
                (l.source, Decision::Source),
            ]
        } else {
            &[(l.receiver, Decision::Receiver)]
        };
        for &(id, d) in order {
            if id.cluster().is_some() || self.mesh.nodes[id.0 as usize].children.is_some() {
                return d;
            }
            if self.leaf_can_split(id.0)
                || self.leaf_can_split_along(id.0)
                || self.leaf_can_split_in_contact(id.0)
                    && self.in_contact((l.receiver, &r), (l.source, &s))
            {
                return Decision::Leaf(id.0);
            }
        }
        Decision::Stuck
    }

    /// Whether a node is a leaf that cannot be split further.
    fn unsplittable(&self, id: NodeId) -> bool {
        id.cluster().is_none()
            && self.mesh.nodes[id.0 as usize].children.is_none()
            && !self.leaf_can_split(id.0)
    }

    /// Whether the receiver `r` and the source `s` of a link are leaves that the oracle
    /// can no longer split for it.
    fn final_ends(&self, r: NodeId, s: NodeId) -> (bool, bool) {
        let (fr, fs) = (self.unsplittable(r), self.unsplittable(s));
        let graded = |id: NodeId, f: bool| {
            f && !(self.leaf_can_split_in_contact(id.0)
                && self.in_contact((r, &self.bounds(r)), (s, &self.bounds(s))))
        };
        (graded(r, fr), graded(s, fs))
    }

    /// Gives the links among `links` that skipped their transfer (a cluster at either end
    /// and a kernel range the oracle could not keep) the transfer they would carry if
    /// kept; returns the rays cast. For the previews of links that wait for a leaf split
    /// (the sweeps after the round take a cluster link's light along the leaves' rays, not
    /// from its transfer: `sight`). The decisions on such a link do not change: its spread
    /// is the same or larger (a shadow boundary across it), and it was already above its
    /// threshold.
    fn carry_skipped(&self, bvh: &crate::accel::Bvh, links: &mut [Link]) -> u64 {
        links
            .par_iter_mut()
            .with_min_len(256)
            .map(|l| {
                let skipped = (l.receiver.cluster().is_some() || l.source.cluster().is_some())
                    && l.transfer.values().iter().all(|v| *v == 0.0);
                if !skipped {
                    return 0;
                }
                match self.link_keeping(bvh, l.receiver, l.source, f32::INFINITY) {
                    Some((carried, rays)) => {
                        *l = carried;
                        rays as u64
                    }
                    None => 0,
                }
            })
            .sum()
    }

    /// The link from `s` to `r`, or `None` when it provably carries nothing.
    fn link(&self, bvh: &crate::accel::Bvh, r: NodeId, s: NodeId) -> Option<(Link, u32)> {
        // The largest spread the oracle could keep a cluster link with (see `estimate`;
        // the source's variation only adds to the error): infinite past the link budget.
        let keep_spread = if r.cluster().is_some() || s.cluster().is_some() {
            let carried = self.reflectance(r) * self.source_b(s);
            if carried > 0.0 {
                self.held_to(r, s) / carried
            } else {
                f32::INFINITY
            }
        } else {
            f32::INFINITY
        };
        self.link_keeping(bvh, r, s, keep_spread)
    }

    /// The link from `s` to `r` (see [`View::link`]), a cluster link whose kernel range
    /// is above `keep_spread` skipping its transfer.
    fn link_keeping(
        &self,
        bvh: &crate::accel::Bvh,
        r: NodeId,
        s: NodeId,
        keep_spread: f32,
    ) -> Option<(Link, u32)> {
        if r.cluster().is_none()
            && s.cluster().is_none()
            && self.h.node_patch[r.0 as usize] == self.h.node_patch[s.0 as usize]
        {
            return None; // a plane does not see itself
        }
        let (rs, ss) = (self.shape(r), self.shape(s));
        if transfer::blind(&rs, &ss, self.mesh.epsilon()) {
            return None;
        }
        let t = transfer::evaluate(
            bvh,
            self.mesh.epsilon(),
            (r, &rs),
            (s, &ss),
            self.final_ends(r, s),
            keep_spread,
            |shape, id| self.with_samples(shape, id),
        );
        // Nothing passes: a cluster's kernel bound is zero, or no part of a surface
        // receiver lies in front of the source (`transfer`).
        if t.spread <= 0.0 && t.values.iter().all(|v| *v <= 0.0) {
            return None;
        }
        Some((Link::new(r, s, &t), t.rays))
    }
}

/// How much stricter the oracle is with links whose ends are in contact (a corner of one
/// within half the receiver's size of the other: the foot of a block, a room's corner).
/// The kernel there varies across the receiver on the scale of the gap, which its
/// quadrature points (a sixth of the way in from its edges) do not see, and the dark
/// corner it makes is the light a person measures there. With 1 (graded leaves alone) the
/// Cornell box's viewer error came to 2.55 %, with 4 to 2.31 % (see `CONTACT_GRADING`).
const CONTACT_STRICTNESS: f32 = 4.0;

/// How far below the minimum size a leaf may split for a link whose ends are in contact:
/// the light at a contact changes within millimetres (on the Cornell box the foot of the
/// short block's front face goes from 0.031 at 0.1 mm to 0.056 at 4 mm), so leaves there
/// are graded down to a quarter of the minimum size; a sixteenth of the patch's starting
/// size with the default minimum. Measured (`radiosity bench builtin:cornell`, viewer's
/// Gouraud): 4.41 % RMS over the reference points without this, 10.8 % at the contact
/// points, in 9.2 s; 2.31 % and 4.1 % with it, in 17.9 s; a half gave 2.49 % and an
/// eighth 2.40 %.
const CONTACT_GRADING: f64 = 4.0;

/// The narrowest children that grading at a contact may make balance split an element
/// into, in ray offsets (`Mesh::epsilon`): a strip 1.25 · 10⁻⁵ m wide (1.4 offsets) along
/// a furnace's edge, split so beside leaves graded at the contact, received nothing from
/// the wall it touches and came out at half its light.
const THINNEST: f32 = 4.0;

/// The gap, as a fraction of the receiver's size, within which two surface nodes are in
/// contact.
const CONTACT_GAP: f32 = 0.5;

/// Whether a leaf of `area` may be split: its children are at least `min_size` (as
/// `sqrt(2 · area)`).
fn can_split(area: f32, min_size: f64) -> bool {
    (2.0 * area as f64).sqrt() * 0.5 >= min_size * 0.999
}

/// Whether a leaf may be split by its length: its children's longest edge, half its own,
/// is at least `min_size`. [`can_split`] measures a leaf by its area, and a sliver too
/// thin for it (a strip the contact lines cut along a wall) can be long, its one value
/// standing for light that changes along it: one of Sponza's, 1.5 cm by 70 cm on a
/// gallery floor, held the sky's irradiance at its centroid, 0.027 W/m², where the
/// path-traced truth at its end is 0.083 (`tests/hard_geometry.rs` cuts a floor into such
/// strips under a shadow: 15 % RMS error, now 2.4 %). Other triangles' longest edges are
/// up to 1.42 times their √(2A) (a right triangle's hypotenuse), so they too may go a
/// level deeper where a link asks: on the built-in Cornell box that, not its slivers,
/// brought three floor points in the blocks' umbrae beside the walls from 6–13 % off to
/// under 1.5 %.
fn can_split_along(verts: &[Vec3; 3], min_size: f64) -> bool {
    longest_edge(verts) as f64 * 0.5 >= min_size * 0.999
}

impl Solver {
    /// The starting links: the root cluster to itself, or (clustering off) every pair of
    /// patches.
    fn initial_links(&self, h: &Hierarchy, min_size: f64) -> (Vec<Link>, u64) {
        let view = View {
            h,
            mesh: &self.mesh,
            min_size,
            threshold: 0.0,
            ambient: 0.0,
        };
        let pairs: Vec<(NodeId, NodeId)> = if self.settings.hierarchy.clustering {
            if h.clusters.nodes.is_empty() {
                Vec::new()
            } else {
                vec![(NodeId::of_cluster(0), NodeId::of_cluster(0))]
            }
        } else {
            let roots: Vec<NodeId> = (0..self.mesh.patches.len())
                .filter(|&p| h.clusters.patch_parent[p] != NONE)
                .map(|p| NodeId::surface(self.mesh.patches[p].root))
                .collect();
            roots
                .iter()
                .flat_map(|&r| roots.iter().map(move |&s| (r, s)))
                .collect()
        };
        let bvh = &self.bvh;
        let made: Vec<(Link, u32)> = pairs
            .par_iter()
            .filter_map(|&(r, s)| view.link(bvh, r, s))
            .collect();
        let rays = made.iter().map(|m| m.1 as u64).sum();
        (made.into_iter().map(|m| m.0).collect(), rays)
    }

    /// The oracle's error estimate of link `l` and the threshold it is held to, as the
    /// last round judged it.
    pub(super) fn link_estimate(&self, h: &Hierarchy, l: &Link) -> Estimate {
        let view = View {
            h,
            mesh: &self.mesh,
            min_size: self.hierarchy_min_size(),
            threshold: h.threshold,
            ambient: 0.0,
        };
        let (r, s) = (view.bounds(l.receiver), view.bounds(l.source));
        view.estimate(l, &r, &s)
    }

    /// The oracle's threshold: ε · Ē', with Ē' the area-weighted mean over the scene of
    /// what its surfaces emit or first reflect of the sky, sun and lamps (largest
    /// channels). An error δ in every transfer grows over the bounces by the scene's gain
    /// G = B̄ / Ē' (B̄ the mean radiosity), so this keeps the converged error near
    /// ε · Ē' · G = ε · B̄: in a closed furnace G = 1 / (1 − ρ̄), and one at ρ = 0.99 refines
    /// a hundred times deeper, relative to its light, than one at ρ = 0. Ē' is known before
    /// the first sweep, so the first rounds judge as the last ones do.
    ///
    /// It was ε · B̄ · (1 − ρ̄), which is the same in a closed scene but not in an open
    /// one, whose gain is far below 1 / (1 − ρ̄): cornell-box-vinc3r (open front, walls at
    /// ρ = 0.8) has a gain of 3.2 against 8.2, and was held 2.6 times tighter than it needed,
    /// and before the first sweep (B̄ = Ē') eight times. `bench cornellBox-2.80-Eevee-gltf.gltf
    /// --methods hierarchical --time-limit 60`: 48 → 31 % off the path-traced points at
    /// 10 s, 19.7 → 16.7 % at 60 s, the final gather 9.1 → 5.6 % (ε 0.03 → 0.02, which gives
    /// the built-in Cornell box, gain 2, about the threshold it had; README, "The oracle's
    /// threshold from the scene's gain").
    pub(super) fn link_threshold(&self) -> f32 {
        let first_light = self.area_mean(|i| self.source[i].max_element() as f64);
        (self.settings.hierarchy.link_error as f64 * first_light.unwrap_or(0.0)) as f32
    }

    /// The area-weighted mean of the radiosity's largest channel over the scene.
    fn mean_radiosity(&self) -> f64 {
        self.area_mean(|i| self.radiosity[i].max_element())
            .unwrap_or(0.0)
    }

    /// [`Solver::link_threshold`], never below the largest it has been in this solve: an
    /// edit that darkens the scene lowers every link's error and must not refine (it would
    /// when the mean E' falls faster than the errors do).
    fn held_threshold(&self, h: &mut Hierarchy) -> f32 {
        // Past the link budget it stays infinite, and the means over every element that
        // the threshold takes would cost each edit a pass over the scene for nothing.
        if h.threshold != f32::INFINITY {
            h.threshold = h.threshold.max(self.link_threshold());
        }
        h.threshold
    }

    /// Σ A E' / Σ A · ρ̄ / (1 − ρ̄) (largest channels): see `Round::ambient`.
    fn ambient_estimate(&self) -> f32 {
        let Some(e) = self.area_mean(|i| self.source[i].max_element() as f64) else {
            return 0.0;
        };
        let rho = self.mean_reflectance().min(0.999);
        (e * rho / (1.0 - rho)) as f32
    }

    /// Whether the scene's light all comes from its emitting surfaces (no sky, sun or
    /// lamp outside the mesh): its E' then holds no first bounce, which only the links
    /// from the emitters bring (see `Round::unlit_pairs`).
    fn lit_by_surfaces_alone(&self) -> bool {
        self.external_in.iter().all(|h| *h == Vec3::ZERO)
            && self.emission.iter().any(|e| e.max_element() > 0.0)
    }

    /// The smallest element the hierarchy may make.
    pub(super) fn hierarchy_min_size(&self) -> f64 {
        self.settings
            .hierarchy
            .min_size
            .filter(|m| *m > 0.0)
            .unwrap_or(self.mesh.element_size / 8.0)
    }

    /// One piece of a refinement round (a generation's decisions, a chunk of new links
    /// evaluated, or one split of leaves in the mesh), so a step keeps its time budget;
    /// `Some(changed)` when the round is over, with whether any link changed.
    pub(super) fn refine_piece(
        &mut self,
        h: &mut Hierarchy,
        cancel: &AtomicBool,
    ) -> Result<Option<bool>, Stop> {
        let min_size = self.hierarchy_min_size();
        let mut round = match h.round.take() {
            Some(r) => r,
            None => {
                h.round_new_links = 0;
                let mut changed = false;
                if h.sweeps == 0 && h.links.is_empty() {
                    let (mut links, rays) = self.initial_links(h, min_size);
                    links.par_sort_unstable_by_key(|l| (l.receiver, l.source));
                    h.links = LinkTable::new(&links, true);
                    h.links_changed();
                    self.stats.rays += rays;
                    changed = true;
                }
                // From coarse to fine (see `COARSE_START`): each round after the sweeps
                // converged halves the factor.
                if h.sweeps > 0 {
                    h.coarseness = (h.coarseness * 0.5).max(1.0);
                }
                if h.threshold.is_infinite() {
                    h.coarseness = 1.0; // past the link budget nothing refines
                }
                let threshold = self.held_threshold(h) * h.coarseness;
                // Past the link budget (an infinite threshold) every link is kept: the
                // round would only re-decide them all.
                if threshold.is_nan() || threshold <= 0.0 || threshold.is_infinite() {
                    return Ok(Some(changed));
                }
                let basis = h.basis.take();
                h.pull(&self.mesh, &self.radiosity);
                let ambient = if h.sweeps == 0 {
                    self.ambient_estimate()
                } else {
                    0.0
                };
                h.dark_mean = if h.sweeps == 0 {
                    0.0
                } else {
                    self.mean_radiosity() as f32
                };
                Round {
                    threshold,
                    external_threshold: threshold,
                    ambient,
                    work: h.links.take(),
                    changed,
                    basis,
                    defer_unlit: h.sweeps == 0
                        && h.lit_first
                        && !h.first_round_restarted
                        && self.lit_by_surfaces_alone(),
                    ..Default::default()
                }
            }
        };
        let result = self.advance(h, &mut round, min_size, cancel);
        if round.restart {
            // Its links are dropped and it starts again from the top, with the same
            // thresholds (the mean radiosity they come from now holds the previews').
            h.first_round_restarted = true;
            let (mut links, rays) = self.initial_links(h, min_size);
            links.par_sort_unstable_by_key(|l| (l.receiver, l.source));
            self.stats.rays += rays;
            h.round = Some(Round {
                threshold: round.threshold,
                external_threshold: round.external_threshold,
                ambient: round.ambient,
                work: links,
                changed: true,
                ..Default::default()
            });
            return Ok(None);
        }
        match result {
            Ok(true) => {
                // The link budget's infinite threshold holds for later rounds too.
                if round.threshold.is_infinite() {
                    h.threshold = f32::INFINITY;
                }
                h.round_new_links = round.new_links;
                let mut kept = std::mem::take(&mut round.kept);
                kept.par_sort_unstable_by_key(|l| (l.receiver, l.source));
                // Past the link budget no round runs again: the misses are not needed.
                h.links = LinkTable::new(&kept, h.threshold.is_finite());
                match round.basis.take() {
                    // The same links: what the last sweep computed from its input holds,
                    // once the node values are pulled from it again.
                    Some(basis) if !round.changed && basis.len() == self.radiosity.len() => {
                        h.pull(&self.mesh, &basis);
                        h.basis = Some(basis);
                    }
                    _ => h.links_changed(),
                }
                Ok(Some(round.changed))
            }
            Ok(false) => {
                h.round = Some(round);
                Ok(None)
            }
            Err(e) => {
                h.round = Some(round);
                Err(e)
            }
        }
    }

    /// Does the next piece of `round`; true when it is over (its links all in `kept`).
    fn advance(
        &mut self,
        h: &mut Hierarchy,
        round: &mut Round,
        min_size: f64,
        cancel: &AtomicBool,
    ) -> Result<bool, Stop> {
        check(cancel)?;
        let view = View {
            h,
            mesh: &self.mesh,
            min_size,
            threshold: round.threshold,
            ambient: round.ambient,
        };
        if round.next_pair < round.pairs.len() {
            // Evaluate the next chunk of new links.
            let chunk = 16_384 * rayon::current_num_threads().max(1);
            let end = (round.next_pair + chunk).min(round.pairs.len());
            let bvh = &self.bvh;
            let made: Vec<(Link, u32)> = round.pairs[round.next_pair..end]
                .par_iter()
                .filter_map(|&(r, s)| view.link(bvh, r, s))
                .collect();
            self.stats.rays += made.iter().map(|m| m.1 as u64).sum::<u64>();
            round.made.extend(made.into_iter().map(|m| m.0));
            round.new_links += end - round.next_pair;
            round.next_pair = end;
            if end == round.pairs.len() {
                round.pairs = Vec::new();
                round.next_pair = 0;
                round.work = std::mem::take(&mut round.made);
                // A preview each time a sweep's cost has grown by `LATER_PREVIEW_GROWTH`
                // since the last (doubled, before the first solution), of as many sweeps
                // as the previews' share of the solve's rays allows (at least one, at most
                // PREVIEW_SWEEPS). Before the first solution the round's first generation
                // is previewed at once; a later round's first only sets the base, since it
                // holds the last round's links, whose solution is already shown. None past
                // the link budget (but the first): the links are then final, and the
                // round's own sweeps follow as soon as its last generation is decided.
                let held = [
                    &round.kept[..],
                    &round.stuck,
                    &round.work,
                    &round.waiting,
                    &round.unlit_parents,
                ];
                let cover = held.iter().map(|links| links.len()).sum();
                let cost = preview_cost(cover, self.mesh.elements.len());
                let first = round.previewed == 0;
                let growth = if h.sweeps == 0 {
                    2.0
                } else {
                    LATER_PREVIEW_GROWTH
                };
                let due = if first {
                    h.sweeps == 0
                } else {
                    round.threshold.is_finite() && cost as f64 >= growth * round.previewed as f64
                };
                if first || due {
                    round.previewed = cost;
                }
                // A round started again shows nothing until it ends: its previews would
                // be darker than those of the round it replaces (see `Round::restart`).
                if due && !(h.first_round_restarted && h.sweeps == 0) {
                    let allowed = (self.stats.rays as f64 * PREVIEW_LINKS_PER_RAY) as usize;
                    let sweeps = (allowed.saturating_sub(round.preview_spent) / cost)
                        .clamp(1, PREVIEW_SWEEPS);
                    let links = held.into_iter().flatten().collect();
                    round.preview_spent += cost * self.preview(h, links, sweeps);
                }
            }
            return Ok(false);
        }
        if !round.work.is_empty() {
            // Decide a generation.
            round
                .work
                .par_sort_unstable_by_key(|l| (l.receiver, l.source));
            let decisions: Vec<Decision> = round
                .work
                .par_chunk_by(|a, b| a.receiver == b.receiver)
                .flat_map_iter(|group| {
                    let view = &view;
                    let overloaded = view.receiver_overloaded(group);
                    group
                        .iter()
                        .map(move |l| overloaded.unwrap_or_else(|| view.decide(l)))
                })
                .collect();
            // What each decision adds, in parallel by chunks and appended in link order.
            let outcomes: Vec<Outcome> = round
                .work
                .par_chunks(APPLY_CHUNK)
                .zip(decisions.par_chunks(APPLY_CHUNK))
                .map(|(links, decisions)| view.apply(links, decisions, round.defer_unlit))
                .collect();
            let waited = round.waiting.len();
            for mut o in outcomes {
                round.kept.append(&mut o.kept);
                round.stuck.append(&mut o.stuck);
                round.leaves.append(&mut o.leaves);
                round.waiting.append(&mut o.waiting);
                round.pairs.append(&mut o.pairs);
                round.deferred |= !o.unlit_pairs.is_empty();
                round.unlit_pairs.append(&mut o.unlit_pairs);
                round.unlit_parents.append(&mut o.unlit_parents);
            }
            if round.defer_unlit {
                // The light's links waiting for a leaf split (a large emitter's leaf that
                // must split before it can link to a cluster) bring their light to the
                // previews meanwhile.
                self.stats.rays += view.carry_skipped(&self.bvh, &mut round.waiting[waited..]);
            }
            round.work = Vec::new();
            round.changed |= !round.pairs.is_empty() || !round.unlit_pairs.is_empty();
            // Past the link budget refinement stops: the pairs just made are the last
            // (evaluated, and then kept, at an infinite threshold, so that those whose
            // ends overlap carry their sampled transfer), and later rounds keep it.
            let links = round.kept.len()
                + round.stuck.len()
                + round.waiting.len()
                + round.pairs.len()
                + round.unlit_pairs.len();
            let budget = self.settings.hierarchy.max_links.min(MAX_LINK_BUDGET);
            if round.deferred && links > budget / COARSE_SHARE {
                // The budget will cut this scene, and where it cuts depends on the order
                // the links were refined in: start the round again in the breadth-first
                // order (see `Round::unlit_pairs`).
                round.restart = true;
                return Ok(false);
            }
            if links > budget {
                round.threshold = f32::INFINITY;
            } else if h.coarseness > 1.0 && links > budget / COARSE_SHARE {
                // The budget will cut this scene: refining coarse first would spend it deep
                // in a few places instead of across the scene as the full threshold does.
                // Go on at the full threshold from here, the links kept so far decided
                // again with the next generation.
                round.threshold /= h.coarseness;
                round.external_threshold /= h.coarseness;
                h.coarseness = 1.0;
                let again = round.kept.drain(..).chain(round.stuck.drain(..));
                if round.pairs.is_empty() {
                    round.work.extend(again);
                } else {
                    round.made.extend(again);
                }
            }
            return Ok(false);
        }
        if !round.unlit_pairs.is_empty() {
            // The lit pairs are all decided: the unlit ones go on from where they were put
            // off, with a preview first (`previewed` back to zero), which now shows the
            // light's first bounce at the levels the round will keep.
            round.resume_unlit();
            round.previewed = 0;
            return Ok(false);
        }
        // Every generation is decided: split the leaves the waiting links need and those
        // the external light asks for, then decide the waiting links again.
        let Some(lit) = self.external_splits(h, min_size, round.external_threshold) else {
            return Ok(false);
        };
        if round.waiting.is_empty() && lit.is_empty() {
            round.kept.append(&mut round.stuck);
            return Ok(true);
        }
        let mut leaves = std::mem::take(&mut round.leaves);
        leaves.extend(lit);
        leaves.sort_unstable();
        leaves.dedup();
        let Some(split) = self.split_leaves(h, &leaves) else {
            round.kept.append(&mut round.waiting);
            round.kept.append(&mut round.stuck);
            return Ok(true);
        };
        round.changed = true;
        round.work = std::mem::take(&mut round.waiting);
        // A link stuck above its threshold at an end that has now been split (for
        // balance) is decided again: otherwise the next round would refine it, and a
        // converged solve would not be the oracle's last word.
        let mut was_split = vec![false; self.mesh.nodes.len()];
        for n in split {
            was_split[n as usize] = true;
        }
        let at_split = |id: NodeId| id.cluster().is_none() && was_split[id.0 as usize];
        let (again, stuck): (Vec<Link>, Vec<Link>) = std::mem::take(&mut round.stuck)
            .into_iter()
            .partition(|l| at_split(l.receiver) || at_split(l.source));
        round.stuck = stuck;
        round.work.extend(again);
        Ok(false)
    }

    /// The leaf nodes to split for the external light (see [`external`]): those that may
    /// split and whose ρ · range / 2 is above `threshold`. The ranges not yet known are
    /// computed first, a chunk per call, so a step keeps its time budget: `None` until
    /// they all are.
    fn external_splits(
        &mut self,
        h: &mut Hierarchy,
        min_size: f64,
        threshold: f32,
    ) -> Option<Vec<u32>> {
        if self.external.is_empty() || !(threshold > 0.0 && threshold.is_finite()) {
            return Some(Vec::new());
        }
        let mesh = &self.mesh;
        let candidate = |e: usize| {
            let n = h.element_node[e] as usize;
            (!mesh.patches[mesh.elements[e].patch as usize].covered
                && (can_split(h.node_area[n], min_size)
                    || can_split_along(&mesh.nodes[n].verts, min_size)))
            .then_some(n)
        };
        let missing: Vec<usize> = (0..mesh.elements.len())
            .filter(|&e| candidate(e).is_some_and(|n| h.node_external_range[n].is_nan()))
            .collect();
        let chunk = 4096 * rayon::current_num_threads().max(1);
        let now = &missing[..missing.len().min(chunk)];
        let (bvh, external) = (&self.bvh, &self.external);
        let ranges: Vec<(f32, u32)> = now
            .par_iter()
            .map(|&e| external::range(mesh, bvh, external, e))
            .collect();
        for (&e, (range, rays)) in now.iter().zip(ranges) {
            h.node_external_range[h.element_node[e] as usize] = range;
            self.stats.rays += rays as u64;
        }
        if missing.len() > chunk {
            return None;
        }
        let reflectance = &self.reflectance;
        Some(
            (0..mesh.elements.len())
                .filter_map(|e| {
                    let n = candidate(e)?;
                    let error = reflectance[e].max_element() * h.node_external_range[n] * 0.5;
                    (error > threshold).then_some(n as u32)
                })
                .collect(),
        )
    }

    /// Splits the leaf nodes `leaves` (and what 2:1 balance adds) in the mesh, carrying the
    /// per-element state over; the nodes split, or `None` when the element budget would be
    /// exceeded.
    fn split_leaves(&mut self, h: &mut Hierarchy, leaves: &[u32]) -> Option<Vec<u32>> {
        // The elements of `leaves`, closed under balance.
        let balanced = |leaves: &[u32]| {
            let mut marked = vec![false; self.mesh.elements.len()];
            for &n in leaves {
                if let Some(e) = self.mesh.nodes[n as usize].element {
                    marked[e as usize] = true;
                }
            }
            self.mesh.balance(&mut marked);
            marked
        };
        let mut marked = balanced(leaves);
        // Leaves split below the minimum size for a contact (see `CONTACT_GRADING`) must not
        // make balance split any element to children narrower than `THINNEST` ray offsets
        // (a strip along a furnace's edge beside them was): if they would, they are left
        // whole, now and in later rounds.
        let min_size = self.hierarchy_min_size();
        let thinnest = THINNEST * self.mesh.epsilon();
        let positions = &self.mesh.display.positions;
        let too_thin = |marked: &[bool]| {
            marked.iter().zip(&self.mesh.elements).any(|(m, e)| {
                *m && 0.5 * shortest_altitude(&e.corners.map(|c| positions[c as usize])) < thinnest
            })
        };
        let graded = |n: &u32| !can_split(h.node_area[*n as usize], min_size);
        if leaves.iter().any(graded) && too_thin(&marked) {
            // Slivers split along their length are refused first, then every leaf below
            // the minimum: refusing them all at once took the contacts' grading with the
            // slivers (vinc3r's box ended with 44,712 elements instead of 69,732, the
            // floor under its objects, 1.3–1.6 mm below them, 6 cm coarse and 5× too
            // bright, and the objects' undersides with it).
            let along = |n: &u32| {
                graded(n) && can_split_along(&self.mesh.nodes[*n as usize].verts, min_size)
            };
            let (mut refused, mut kept): (Vec<u32>, Vec<u32>) =
                leaves.iter().partition(|n| along(n));
            marked = balanced(&kept);
            if too_thin(&marked) {
                let (more, rest): (Vec<u32>, Vec<u32>) = kept.iter().partition(|n| graded(n));
                refused.extend(more);
                kept = rest;
                marked = balanced(&kept);
            }
            h.ungraded.extend(refused);
        }
        let count = marked.iter().filter(|m| **m).count();
        if count == 0 || self.mesh.elements.len() + 3 * count > self.settings.hierarchy.max_elements
        {
            return None;
        }
        let split: Vec<u32> = (0..marked.len())
            .filter(|&e| marked[e])
            .map(|e| h.element_node[e])
            .collect();
        // In place unless another holder (the viewer) still has the mesh.
        let mesh = Arc::make_mut(&mut self.mesh);
        let moved = mesh.refine(&marked);
        mesh.mark_hard_shadows(&self.bvh, &self.external, min_size);
        let n = mesh.elements.len();
        self.carry_elements(&moved, n);
        // A middle child has its parent's centroid and normal, so the external
        // irradiance carried from its parent is its own: only corner children cast rays.
        let children: Vec<u32> = split_children(&moved)
            .chunks_exact(4)
            .flat_map(|kids| (0..4).filter(|&k| k != MIDDLE_CHILD).map(move |k| kids[k]))
            .collect();
        let (mesh, bvh, external) = (&self.mesh, &self.bvh, &self.external);
        let lit: Vec<(Vec3, u32)> = children
            .par_iter()
            .map(|&c| external_factor(mesh, bvh, external, c as usize))
            .collect();
        for (&c, (hx, rays)) in children.iter().zip(lit) {
            let c = c as usize;
            let s = self.emission[c] + self.reflectance[c] * hx;
            let s = if s.is_finite() { s } else { Vec3::ZERO };
            self.radiosity[c] += (s - self.source[c]).as_dvec3();
            self.source[c] = s;
            self.external_in[c] = hx;
            self.stats.rays += rays as u64;
        }
        h.stale_sight = StaleSight::after(h.sight.take(), h.stale_sight.take(), &moved);
        h.grow(&self.mesh);
        self.stats.elements = n;
        self.mesh_version += 1;
        self.update_source_power();
        debug_assert_eq!(self.settings.method, Method::Hierarchical);
        Some(split)
    }
}
