//! The cluster hierarchy above the patches (Smits, Arvo & Greenberg, "A clustering algorithm
//! for radiosity in complex environments", SIGGRAPH 1994; Sillion, "A unified hierarchical
//! algorithm for global illumination with scattering volumes and object clusters", 1995).
//!
//! A binary tree built top-down by median splits of the patch centroids along the longest
//! axis of their bounding box, down to clusters of at most [`LEAF_PATCHES`] patches, whose
//! children are the patches' quadtree roots. The root cluster holds the whole scene, so a
//! solve starts from one link (the root to itself) instead of patches². Clusters are stored
//! in preorder: a parent's index is below its children's.

use super::NodeId;
use crate::geometry::sampling::hash;
use crate::mesh::Mesh;
use glam::Vec3;
use std::ops::Range;

/// Most patches under a leaf cluster.
pub(super) const LEAF_PATCHES: usize = 4;

/// How many patches a cluster's transfers sample for visibility.
pub(in crate::solver) const SAMPLES: usize = 4;

/// One cluster: a bounding box of surfaces, seen from outside through its projected area
/// (see `transfer`).
#[derive(Clone, Debug)]
pub(in crate::solver) struct Cluster {
    pub centre: Vec3,
    /// Radius of the bounding sphere around `centre` (half the box diagonal).
    pub radius: f32,
    /// Total surface area below it, m².
    pub area: f32,
    /// Σ A_i n_i over the surfaces below it (its area vector; |a| = A when they are
    /// coplanar and face one way, 0 for a closed surface).
    pub area_vector: Vec3,
    /// Largest reflectance channel below it (for the refinement oracle).
    pub reflectance: f32,
    /// Children in [`Clusters::children`].
    pub children: Range<u32>,
    /// Parent cluster (`u32::MAX` for the root).
    pub parent: u32,
    /// Patches whose centroids stand for the cluster in visibility tests.
    pub samples: [u32; SAMPLES],
    /// The bounding box of its surfaces.
    pub lo: Vec3,
    pub hi: Vec3,
    /// Which way its surfaces face (see [`Facing`]).
    pub facing: Facing,
}

/// A cone holding the normals of a set of single-sided surfaces, and where they lie along
/// its axis: every surface's normal n has n · axis ≥ `cos`, and every point p of them
/// axis · p ≥ `low`. With `cos` ≤ 0 the surfaces face every way and the cone says nothing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::solver) struct Facing {
    pub axis: Vec3,
    pub cos: f32,
    pub low: f32,
}

impl Facing {
    /// No surface of these sees, or is seen from, any point whose largest projection on
    /// the axis is `ahead` (the other end's extent along it), within distance `reach` of
    /// every surface point, up to `tol`: for a surface point p with normal n and a point x,
    /// n · (x − p) ≤ n_∥ axis · (x − p) + sin θ |x − p| with n_∥ ∈ [cos θ, 1], so nothing
    /// passes when that is at most `tol` for the largest axis · (x − p), `ahead − low`.
    /// A flat set of surfaces (θ = 0) sees nothing behind its plane; two clusters on one
    /// wall see nothing of each other.
    pub fn blind_to(&self, ahead: f32, reach: f32, tol: f32) -> bool {
        if self.cos <= 0.0 {
            return false;
        }
        let along = ahead - self.low;
        let lead = if along <= 0.0 {
            self.cos * along
        } else {
            along
        };
        let sin = (1.0 - self.cos * self.cos).max(0.0).sqrt();
        lead + sin * reach <= tol
    }
}

/// The cluster tree.
#[derive(Clone, Debug, Default)]
pub(in crate::solver) struct Clusters {
    pub nodes: Vec<Cluster>,
    /// Child lists of the clusters: other clusters or patch roots.
    pub children: Vec<NodeId>,
    /// The leaf cluster each patch hangs from (`u32::MAX` for patches outside the
    /// hierarchy: covered ones).
    pub patch_parent: Vec<u32>,
}

impl Clusters {
    /// Clusters over `patches` (indices into `mesh.patches`); empty when there are none.
    pub fn build(mesh: &Mesh, patches: &[u32]) -> Clusters {
        let mut c = Clusters {
            patch_parent: vec![u32::MAX; mesh.patches.len()],
            ..Default::default()
        };
        if !patches.is_empty() {
            let mut order = patches.to_vec();
            c.build_node(mesh, &mut order, u32::MAX);
        }
        c
    }

    fn build_node(&mut self, mesh: &Mesh, patches: &mut [u32], parent: u32) -> u32 {
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let mut area = 0.0f32;
        let mut area_vector = Vec3::ZERO;
        let mut reflectance = 0.0f32;
        for &p in patches.iter() {
            let patch = &mesh.patches[p as usize];
            for v in patch.verts {
                lo = lo.min(v);
                hi = hi.max(v);
            }
            area += patch.area;
            area_vector += patch.normal * patch.area;
            reflectance = reflectance.max(patch.reflectance.max_element());
        }
        let axis = area_vector.normalize_or_zero();
        let mut facing = Facing {
            axis,
            cos: if axis == Vec3::ZERO { -1.0 } else { 1.0 },
            low: f32::INFINITY,
        };
        for &p in patches.iter() {
            let patch = &mesh.patches[p as usize];
            facing.cos = facing.cos.min(patch.normal.dot(axis));
            for v in patch.verts {
                facing.low = facing.low.min(axis.dot(v));
            }
        }
        let mut samples = [patches[0]; SAMPLES];
        for (k, s) in samples.iter_mut().enumerate() {
            let h = hash((patches.len() as u64) << 8 ^ k as u64 ^ (patches[0] as u64) << 32);
            *s = patches[(h % patches.len() as u64) as usize];
        }
        let index = self.nodes.len() as u32;
        self.nodes.push(Cluster {
            centre: (lo + hi) * 0.5,
            radius: (hi - lo).length() * 0.5,
            area,
            area_vector,
            reflectance,
            children: 0..0,
            parent,
            samples,
            lo,
            hi,
            facing,
        });
        let kids: Vec<NodeId> = if patches.len() <= LEAF_PATCHES {
            patches
                .iter()
                .map(|&p| {
                    self.patch_parent[p as usize] = index;
                    NodeId::surface(mesh.patches[p as usize].root)
                })
                .collect()
        } else {
            // Median split of the centroids along the box's longest axis; ties broken by
            // patch index so the tree does not depend on sort stability.
            let axis = (hi - lo).max_position();
            let key = |p: &u32| (mesh.patches[*p as usize].centroid()[axis], *p);
            let mid = patches.len() / 2;
            patches.select_nth_unstable_by(mid, |a, b| {
                key(a)
                    .partial_cmp(&key(b))
                    .unwrap_or(std::cmp::Ordering::Equal)
            });
            let (left, right) = patches.split_at_mut(mid);
            let l = self.build_node(mesh, left, index);
            let r = self.build_node(mesh, right, index);
            vec![NodeId::of_cluster(l), NodeId::of_cluster(r)]
        };
        let start = self.children.len() as u32;
        self.children.extend(kids);
        self.nodes[index as usize].children = start..self.children.len() as u32;
        index
    }

    /// The children of cluster `c`.
    pub fn children_of(&self, c: usize) -> &[NodeId] {
        let r = &self.nodes[c].children;
        &self.children[r.start as usize..r.end as usize]
    }

    /// Recomputes each cluster's largest reflectance from `patch_reflectance` (after an
    /// edit), leaves first.
    pub fn update_reflectance(&mut self, patch_of_root: impl Fn(u32) -> f32) {
        for c in (0..self.nodes.len()).rev() {
            let mut r = 0.0f32;
            for &k in self.children_of(c) {
                r = r.max(match k.cluster() {
                    Some(j) => self.nodes[j].reflectance,
                    None => patch_of_root(k.0),
                });
            }
            self.nodes[c].reflectance = r;
        }
    }
}
