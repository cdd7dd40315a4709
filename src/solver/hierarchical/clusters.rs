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
    /// Σ A_i |n_i| (componentwise) over the surfaces below it: what light arriving
    /// equally from every axis direction reaches (see `Octants::add_mean`).
    pub abs_area: Vec3,
    /// Largest reflectance channel below it (for the refinement oracle).
    pub reflectance: f32,
    /// Children in [`Clusters::children`].
    pub children: Range<u32>,
    /// Parent cluster (`u32::MAX` for the root).
    pub parent: u32,
    /// Patches that stand for the cluster in visibility tests and near transfers, drawn
    /// with probability proportional to area (stratified).
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

/// [`SAMPLES`] indices into `areas` drawn with probability proportional to area,
/// stratified: draw k lands in the k-th of SAMPLES equal shares of the running area, so
/// each stands for an equal share of the surface (a few large patches are not outvoted by
/// many small ones, and one covering most of the area is drawn most of the times).
pub(super) fn draw_by_area(areas: &[f32], seed: u64) -> [usize; SAMPLES] {
    let mut running = Vec::with_capacity(areas.len());
    let mut sum = 0.0f64;
    for a in areas {
        sum += a.max(0.0) as f64;
        running.push(sum);
    }
    std::array::from_fn(|k| {
        let h = hash(seed ^ k as u64);
        let u = (k as f64 + (h >> 11) as f64 / (1u64 << 53) as f64) / SAMPLES as f64;
        running
            .partition_point(|&a| a <= u * sum)
            .min(areas.len().saturating_sub(1))
    })
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
        let mut abs_area = Vec3::ZERO;
        let mut reflectance = 0.0f32;
        for &p in patches.iter() {
            let patch = &mesh.patches[p as usize];
            for v in patch.verts {
                lo = lo.min(v);
                hi = hi.max(v);
            }
            area += patch.area;
            area_vector += patch.normal * patch.area;
            abs_area += patch.normal.abs() * patch.area;
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
        let areas: Vec<f32> = patches
            .iter()
            .map(|&p| mesh.patches[p as usize].area)
            .collect();
        let seed = (patches.len() as u64) << 8 ^ (patches[0] as u64) << 32;
        let samples = draw_by_area(&areas, seed).map(|i| patches[i]);
        let index = self.nodes.len() as u32;
        self.nodes.push(Cluster {
            centre: (lo + hi) * 0.5,
            radius: (hi - lo).length() * 0.5,
            area,
            area_vector,
            abs_area,
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

    /// Recomputes the largest reflectance of the clusters above the `edited` patches
    /// (after an edit), leaves first (a child's index is larger than its parent's).
    pub fn update_reflectance(
        &mut self,
        edited: impl Iterator<Item = u32>,
        patch_of_root: impl Fn(u32) -> f32,
    ) {
        let mut above = vec![false; self.nodes.len()];
        let mut order = Vec::new();
        for p in edited {
            let mut c = self
                .patch_parent
                .get(p as usize)
                .copied()
                .unwrap_or(u32::MAX);
            while c != u32::MAX && !above[c as usize] {
                above[c as usize] = true;
                order.push(c as usize);
                c = self.nodes[c as usize].parent;
            }
        }
        order.sort_unstable_by(|a, b| b.cmp(a));
        for c in order {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the distribution it must follow: over many seeds each index is drawn in
    /// proportion to its area (within four binomial standard errors), and stratification
    /// puts at least three of four draws on a patch holding 97 % of the area.
    #[test]
    fn samples_are_drawn_in_proportion_to_area() {
        let areas = [0.5f32, 0.05, 0.3, 0.0, 0.15];
        let total: f32 = areas.iter().sum();
        let mut counts = [0usize; 5];
        let seeds = 20_000u64;
        for seed in 0..seeds {
            for i in draw_by_area(&areas, seed * 7919) {
                counts[i] += 1;
            }
        }
        let n = (seeds * SAMPLES as u64) as f64;
        for (i, (&c, &a)) in counts.iter().zip(&areas).enumerate() {
            let p = (a / total) as f64;
            let sigma = (n * p * (1.0 - p)).sqrt().max(1.0);
            assert!(
                (c as f64 - n * p).abs() <= 4.0 * sigma,
                "index {i}: drawn {c} times, expected {:.0}",
                n * p
            );
        }
        for seed in 0..100 {
            let drawn = draw_by_area(&[0.97, 0.01, 0.01, 0.01], seed);
            assert!(drawn.iter().filter(|&&i| i == 0).count() >= 3, "{drawn:?}");
        }
    }
}
