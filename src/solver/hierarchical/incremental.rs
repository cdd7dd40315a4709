//! Incremental sweeps: the difference shot along the links (Chen, "Incremental radiosity",
//! Graphics Gems II, 1991, carried along the hierarchy's links as the issue of live edits
//! asks: a link's transfer does not depend on ρ or E, so an edit only moves light along
//! links that exist).
//!
//! A full sweep computes G(x) = E' + ρ · push(gather(pull(x))) over every link. It keeps
//! its input x as the hierarchy's basis y, with what it computed from it: the node values
//! pull(y), the gathered H at every node and cluster, and each leaf's linear H before the
//! cut at zero and the cap. After an edit, the next sweep starts from y with the edited
//! elements as the edit left them (`Solver::rebase_on_sweep_basis`), so its input x differs
//! from y on a few leaves S. Then:
//!
//! - pull(x) differs from pull(y) only at the nodes above S (their quadtree ancestors and
//!   the clusters above their patches): those are pulled again, children first, from the
//!   moments each node keeps;
//! - the gathered H changes only at the receivers of links from those nodes, by
//!   Σ T_l · (b_l(x) − b_l(y)) over those links (each source's new and old value at the
//!   link's point or direction, clamped as the full gather clamps them), summed per
//!   receiver in link order;
//! - a leaf's linear H changes only below a receiver that changed: by the change of its
//!   quadtree ancestors' linear H at its centroid and of what the clusters above its patch
//!   push down, which along the leaves' rays (`sight`) is the change of the elements its
//!   rays hit; it is cut at zero and capped again, and every leaf takes B = E' + ρ H.
//!
//! Where the leaves' rays are cast (`sight`), the full gather takes nothing from a cluster
//! and gives nothing to one, so only the links out of changed surface nodes into surface
//! nodes are gone through.
//!
//! This is the full sweep from x up to the f32 rounding of the sums (pull, gather and push
//! are linear in B, and the clamps are applied to the new totals). It costs the links out
//! of the changed nodes instead of all links; where more than a quarter of the elements or
//! of the links would be touched, the full sweep is cheaper and runs instead.

use super::sight::{ClusterLight, Sight};
use super::table::{LinkTable, StoredLink};
use super::{Hierarchy, NONE, NodeId, Octants, Sender, gathered_at_surface, linear_at, sent_at};
use crate::mesh::Mesh;
use crate::solver::ELEMENT_CHUNK;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// Incremental sweeps in a row before a full one: each adds f32 rounding of about 2⁻²⁴
/// of a receiver's sum per term to what the last full sweep summed.
const MAX_IN_A_ROW: u32 = 32;

/// The links by source: for each surface node n the links from it are
/// `links[start[n]..start[n + 1]]`, and for cluster c those at key `nodes + c` (link
/// indices, ascending).
pub(super) struct BySource {
    nodes: usize,
    start: Vec<u32>,
    links: Vec<u32>,
}

impl BySource {
    /// A counting sort of the links by source key: two passes over them.
    pub fn build(links: &LinkTable, nodes: usize, clusters: usize) -> BySource {
        let key = |id: NodeId| match id.cluster() {
            Some(c) => nodes + c,
            None => id.0 as usize,
        };
        let mut start = vec![0u32; nodes + clusters + 1];
        for (_, l) in links.iter() {
            start[key(l.source) + 1] += 1;
        }
        for k in 1..start.len() {
            start[k] += start[k - 1];
        }
        let mut next = start.clone();
        let mut by = vec![0u32; links.len()];
        for (i, (_, l)) in links.iter().enumerate() {
            let k = key(l.source);
            by[next[k] as usize] = i as u32;
            next[k] += 1;
        }
        BySource {
            nodes,
            start,
            links: by,
        }
    }

    fn of(&self, id: NodeId) -> &[u32] {
        let k = match id.cluster() {
            Some(c) => self.nodes + c,
            None => id.0 as usize,
        };
        &self.links[self.start[k] as usize..self.start[k + 1] as usize]
    }

    /// Bytes it takes.
    pub fn bytes(&self) -> usize {
        (self.start.len() + self.links.len()) * std::mem::size_of::<u32>()
    }
}

/// What the changed sources send now and sent before they were pulled again, in arrays
/// as short as the lists of changed sources (the gather of the changes reads them once per
/// link, in an order that jumps about the scene): their positions in `corners` (surface
/// nodes) and `send` (clusters), `NONE` for a source that did not change.
struct Sent {
    at_node: Vec<u32>,
    at_cluster: Vec<u32>,
    /// A changed surface node's linear fit at its corners: now, then.
    corners: Vec<[[Vec3; 3]; 2]>,
    /// What a changed cluster sends now less what it sent: [`Sender::toward`] is linear
    /// in the radiosities for given projected areas, which an edit does not change.
    send: Vec<Sender>,
}

/// Each item's position in `items`, over `0..len` (`NONE` where absent).
fn position_of(items: &[u32], len: usize) -> Vec<u32> {
    let mut at = vec![NONE; len];
    for (k, &i) in items.iter().enumerate() {
        at[i as usize] = k as u32;
    }
    at
}

/// The change one receiver gathers.
enum Change {
    Surface(u32, [Vec3; 3]),
    Cluster(usize, Octants),
}

impl Hierarchy {
    /// The gathered H of a sweep from `x` through what differs from the basis: updates
    /// the node values, the gathered H, each leaf's linear H and `gathered` (each leaf's
    /// H) as the module documentation says; the sweep then makes `x` the basis. `None`,
    /// with nothing changed, where there is no basis or too much changed for this to pay.
    pub(super) fn sweep_incrementally(
        &mut self,
        mesh: &Mesh,
        (x, opacity): (&[DVec3], &[f32]),
        gathered: &mut [DVec3],
    ) -> Option<()> {
        // Each incremental sweep adds its changes to sums the last full sweep made, so
        // their rounding adds up: a full sweep now and then starts them afresh.
        if self.incremental_in_a_row >= MAX_IN_A_ROW {
            return None;
        }
        let basis = self.basis.as_ref()?;
        if basis.len() != x.len() || gathered.len() != x.len() || self.leaf_linear.len() != x.len()
        {
            return None;
        }
        let changed: Vec<usize> = (0..x.len())
            .into_par_iter()
            .with_min_len(ELEMENT_CHUNK)
            .filter(|&e| x[e] != basis[e])
            .collect();
        if changed.len() > x.len() / 4 {
            return None;
        }
        // Along the leaves' rays, the clusters bring the change of the elements they hit.
        let by_rays = self.leaf_sight().is_some();
        let (mut b_change, mut is_changed) = (Vec::new(), Vec::new());
        if by_rays {
            (b_change, is_changed) = (vec![DVec3::ZERO; x.len()], vec![false; x.len()]);
            for &e in &changed {
                (b_change[e], is_changed[e]) = (x[e] - basis[e], true);
            }
        }
        let (nodes, clusters) = self.above(mesh, &changed);
        // Along the leaves' rays the full gather takes nothing from a cluster and gives
        // nothing to one (`Hierarchy::gather`): the links that move light are those out of
        // the changed surface nodes into surface nodes.
        let sending_clusters: &[u32] = if by_rays { &[] } else { &clusters };
        self.index_links_by_source(mesh);
        let by_source = self.by_source.as_ref()?;
        let reach: usize = nodes
            .iter()
            .map(|&n| by_source.of(NodeId::surface(n)).len())
            .chain(
                sending_clusters
                    .iter()
                    .map(|&c| by_source.of(NodeId::of_cluster(c)).len()),
            )
            .sum();
        if reach > self.links.len() / 4 {
            return None;
        }

        // What the changed sources sent, then pull them again (children first: a child's
        // index is larger than its parent's, in the quadtrees and in the cluster tree).
        let then: Vec<[Vec3; 3]> = nodes
            .iter()
            .map(|&n| self.node_corners[n as usize])
            .collect();
        let sent_then: Vec<Sender> = clusters
            .iter()
            .map(|&c| self.cluster_send[c as usize])
            .collect();
        for &n in nodes.iter().rev() {
            self.pull_node(mesh, n as usize, x);
        }
        for &c in clusters.iter().rev() {
            self.pull_cluster(mesh, c as usize);
        }
        let sent = Sent {
            at_node: position_of(&nodes, mesh.nodes.len()),
            at_cluster: position_of(&clusters, self.clusters.nodes.len()),
            corners: nodes
                .iter()
                .zip(then)
                .map(|(&n, then)| [self.node_corners[n as usize], then])
                .collect(),
            send: clusters
                .iter()
                .zip(&sent_then)
                .map(|(&c, then)| self.cluster_send[c as usize].less(then))
                .collect(),
        };

        // The links out of them, in link order (receiver, then source): marked in a
        // bitmap over the links and read back in order, then what each receiver's
        // gathered H changes by.
        let by_source = self.by_source.as_ref()?;
        let mut hit = vec![0u64; self.links.len().div_ceil(64)];
        let sources = nodes.iter().map(|&n| NodeId::surface(n));
        for s in sources.chain(sending_clusters.iter().map(|&c| NodeId::of_cluster(c))) {
            for &i in by_source.of(s) {
                hit[i as usize / 64] |= 1 << (i % 64);
            }
        }
        let mut reached = Vec::new();
        for (w, &word) in hit.iter().enumerate() {
            let mut bits = word;
            while bits != 0 {
                reached.push((w * 64) as u32 + bits.trailing_zeros());
                bits &= bits - 1;
            }
        }
        let changes: Vec<Change> = self
            .links
            .split_by_receiver(&reached)
            .into_par_iter()
            .filter(|(r, _)| !(by_rays && r.cluster().is_some()))
            .map(|(r, group)| self.change_at(mesh, r, group, &sent))
            .collect();

        // The change of each leaf's H below the receivers that changed: the change of its
        // ancestors' linear H at its centroid and of what its cluster pushes down.
        let mut surface = Vec::new();
        let mut delta = Vec::new();
        let mut cluster_change = vec![Octants::default(); self.clusters.nodes.len()];
        let mut pushed = vec![false; self.clusters.nodes.len()];
        for change in changes {
            match change {
                Change::Surface(r, h) => {
                    let at = &mut self.node_h[r as usize];
                    for k in 0..3 {
                        at[k] += h[k];
                    }
                    surface.push(r);
                    delta.push(h);
                }
                Change::Cluster(c, o) => {
                    self.cluster_h[c].merge(&o);
                    cluster_change[c] = o;
                    pushed[c] = o != Octants::default();
                }
            }
        }
        let down = if by_rays {
            ClusterLight::rays(&b_change, opacity)
        } else {
            ClusterLight::facing(&cluster_change, &self.clusters)
        };
        // Parents come first: a cluster below one that changed takes its change.
        for c in 1..pushed.len() {
            let p = self.clusters.nodes[c].parent;
            if p != NONE && pushed[p as usize] {
                pushed[c] = true;
            }
        }
        // Below a surface receiver that changed, a leaf walks up its ancestors for their
        // changes; below a cluster that changed, it takes what the cluster pushes down.
        let surface_at = position_of(&surface, mesh.nodes.len());
        let mut below_surface = vec![false; mesh.nodes.len()];
        for &r in &surface {
            below_surface[r as usize] = true;
        }
        for i in 0..below_surface.len() {
            let p = self.parent[i];
            if p != NONE && below_surface[p as usize] {
                below_surface[i] = true;
            }
        }
        // Each leaf's own entries, in parallel: the leaves' linear H is taken out of
        // `self` while the rest of it is read.
        let mut leaf_linear = std::mem::take(&mut self.leaf_linear);
        let this = &*self;
        leaf_linear
            .par_iter_mut()
            .zip(gathered.par_iter_mut())
            .enumerate()
            .with_min_len(ELEMENT_CHUNK)
            .for_each(|(e, (linear, gathered))| {
                // Decided from short per-element arrays: the elements themselves (72 bytes
                // each) are read only for the leaves that changed.
                let n = this.element_node[e];
                let c = this.element_cluster[e];
                let from_cluster = c != NONE
                    && match this.leaf_sight() {
                        Some(sight) => sight.sees_any(e, &is_changed),
                        None => pushed[c as usize],
                    };
                let from_surface = n != NONE && below_surface[n as usize];
                if !(from_cluster || from_surface) {
                    return;
                }
                let element = &mesh.elements[e];
                // As `leaf_irradiance_linear` sums it, over the changes.
                let mut d = Vec3::ZERO;
                let x = element.centroid();
                let mut k = if from_surface { n } else { NONE };
                while k != NONE {
                    let at = surface_at[k as usize];
                    if at != NONE {
                        d += linear_at(mesh, k, &delta[at as usize], x);
                    }
                    k = this.parent[k as usize];
                }
                if from_cluster {
                    d += Sight::leaf(this.leaf_sight(), e, element.normal, c, &down);
                }
                *linear += d;
                *gathered = this.capped(e, *linear).as_dvec3();
            });
        self.leaf_linear = leaf_linear;
        Some(())
    }

    /// Makes the links' index by source if there is none.
    pub(super) fn index_links_by_source(&mut self, mesh: &Mesh) {
        // Link indices and offsets are u32.
        if self.by_source.is_none() && self.links.len() < u32::MAX as usize {
            let index = BySource::build(&self.links, mesh.nodes.len(), self.clusters.nodes.len());
            self.by_source = Some(index);
        }
    }

    /// The surface nodes above the `changed` elements and the clusters above their
    /// patches, each once, in ascending index order (parents first).
    fn above(&self, mesh: &Mesh, changed: &[usize]) -> (Vec<u32>, Vec<u32>) {
        let mut node_seen = vec![false; mesh.nodes.len()];
        let mut cluster_seen = vec![false; self.clusters.nodes.len()];
        let (mut nodes, mut clusters) = (Vec::new(), Vec::new());
        for &e in changed {
            let mut n = self.element_node[e];
            while n != NONE && !node_seen[n as usize] {
                node_seen[n as usize] = true;
                nodes.push(n);
                n = self.parent[n as usize];
            }
            let mut c = self.element_cluster[e];
            while c != NONE && !cluster_seen[c as usize] {
                cluster_seen[c as usize] = true;
                clusters.push(c);
                c = self.clusters.nodes[c as usize].parent;
            }
        }
        nodes.sort_unstable();
        clusters.sort_unstable();
        (nodes, clusters)
    }

    /// What receiver `r`'s gathered H changes by over the links at indices `group` (all
    /// to it, in link order, all from sources that changed): the terms of
    /// [`Hierarchy::gather`] for these links, each source's value now less what it sent
    /// before (`sent`), each clamped as the gather clamps it.
    fn change_at(&self, mesh: &Mesh, r: NodeId, group: &[u32], sent: &Sent) -> Change {
        let group = group.iter().map(|&i| self.links.link(i as usize));
        // A source's change towards `at`, and for a cluster source the unit direction
        // from `at` to it.
        let change = |l: &StoredLink, at: Vec3| -> (Vec3, Option<Vec3>) {
            match l.source.cluster() {
                Some(c) => {
                    let (d, to_source) = sent.send[sent.at_cluster[c] as usize].seen_from(at);
                    (d, Some(to_source))
                }
                None => {
                    let [now, then] = &sent.corners[sent.at_node[l.source.0 as usize] as usize];
                    let w = l.transfer.toward();
                    (sent_at(now, w) - sent_at(then, w), None)
                }
            }
        };
        match r.cluster() {
            Some(c) => {
                let cluster = &self.clusters.nodes[c];
                let at = cluster.centre;
                let mut o = Octants::default();
                for l in group {
                    let (d, to_source) = change(l, at);
                    let e = d * l.transfer.factor();
                    if l.transfer.spread().is_infinite() {
                        o.add_mean(e, cluster);
                    } else {
                        let to_source = to_source.unwrap_or_else(|| {
                            (self.centre(mesh, l.source) - at).normalize_or_zero()
                        });
                        o.add(e, to_source);
                    }
                }
                Change::Cluster(c, o)
            }
            None => {
                // As the full gather.
                let by_rays = self.leaf_sight().is_some();
                let at = self.centre(mesh, r);
                let mut h = [Vec3::ZERO; 3];
                for l in group.filter(|l| gathered_at_surface(by_rays, l)) {
                    let d = change(l, at).0;
                    let c = l.transfer.corners();
                    for k in 0..3 {
                        h[k] += d * c[k];
                    }
                }
                Change::Surface(r.0, h)
            }
        }
    }
}
