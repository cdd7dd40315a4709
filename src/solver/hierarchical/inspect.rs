//! What the hierarchy knows of one element, for the viewer's link inspector: the element's
//! level in its patch's quadtree and every link that delivers its light (those of its
//! leaf, of the leaf's ancestors up to the patch and of the clusters above the patch, since
//! a leaf receives what all of them gather: `Hierarchy::leaf_irradiance_linear`, then `Hierarchy::capped`), each with where
//! its source is, what it carries and the oracle's estimate of its error.

use super::link::BF16_NAN;
use super::{NONE, NodeId};
use crate::solver::Solver;
use glam::Vec3;

/// One link as the inspector shows it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkView {
    /// Where the receiving node is: the centroid of the element's leaf or an ancestor, or
    /// a cluster's centre (the mesh's frame, m).
    pub receiver: Vec3,
    /// Where the source is: a surface node's centroid or a cluster's centre.
    pub source: Vec3,
    /// Whether the source is a cluster.
    pub from_cluster: bool,
    /// How many levels above the element's leaf the receiving node is (0: the leaf; the
    /// clusters count on above the patch).
    pub up: u32,
    /// The irradiance it carries to the receiver, W/m² per channel: its transfer averaged
    /// over the receiver times the radiosity the source sends it (before the element's
    /// conservation cap, which scales all of its links alike where they add up to more
    /// than one hemisphere).
    pub irradiance: Vec3,
    /// The oracle's error estimate and the threshold it is held to, W/m² of B at the
    /// receiver (infinite where the ends' bounding spheres overlap).
    pub error: f32,
    pub threshold: f32,
}

/// What the hierarchy knows of one element.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ElementLinks {
    pub element: u32,
    /// Its centroid (the mesh's frame, m).
    pub centroid: Vec3,
    /// Depth of its leaf in its patch's quadtree (0: the patch itself).
    pub level: u32,
    /// The links that deliver its light, leaf first.
    pub links: Vec<LinkView>,
}

impl Solver {
    /// The links that deliver element `element`'s light, with its level; `None` unless the
    /// method is hierarchical and the element exists. Between refinement rounds these are
    /// the solution's links; while a round runs it holds them, and the list is empty.
    pub fn element_links(&self, element: u32) -> Option<ElementLinks> {
        let h = self.hierarchy.as_ref()?;
        let mesh = &self.mesh;
        let e = mesh.elements.get(element as usize)?;
        let leaf = *h.element_node.get(element as usize)?;
        let mut receivers = Vec::new();
        let mut node = leaf;
        while node != NONE {
            receivers.push(NodeId::surface(node));
            node = h.parent[node as usize];
        }
        let level = receivers.len().saturating_sub(1) as u32;
        let mut cluster = h.clusters.patch_parent[e.patch as usize];
        while cluster != NONE {
            receivers.push(NodeId::of_cluster(cluster));
            cluster = h.clusters.nodes[cluster as usize].parent;
        }
        let mut links = Vec::new();
        for (up, &r) in receivers.iter().enumerate() {
            for l in h.links.to(r) {
                let estimate = self.link_estimate(h, &l.to(r, [BF16_NAN; 3]));
                links.push(LinkView {
                    receiver: h.centre(mesh, r),
                    source: h.centre(mesh, l.source),
                    from_cluster: l.source.cluster().is_some(),
                    up: up as u32,
                    irradiance: h.source_b(l, h.centre(mesh, r)) * l.transfer.factor(),
                    error: estimate.error,
                    threshold: estimate.threshold,
                });
            }
        }
        Some(ElementLinks {
            element,
            centroid: e.centroid(),
            level,
            links,
        })
    }
}
