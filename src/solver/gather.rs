//! The final gather: the radiosity at one surface point, computed at the point from the
//! solution (the second pass of two-pass methods; Lischinski, Tampieri & Greenberg,
//! "Combining hierarchical radiosity and discontinuity meshing", SIGGRAPH 1993, §5; Smits,
//! Arvo & Salesin 1994).
//!
//! A mesh solution is an average over each element; where light changes within a few
//! millimetres (a corner, the foot of a block, a penumbra) no practical mesh follows it. At
//! a point x with normal n on an element of reflectance ρ and emission E,
//!
//!   B(x) = E + ρ · (H_ext(x) + Σ_s F(x → s) · V(x, s) · B_s)
//!
//! - H_ext: punctual lights, sun and sky at x itself (`light::direct`), the sky by
//!   [`POINT_SKY_RAYS`] stratified rays at the point asked about: seen through an opening
//!   of a few percent of the hemisphere (Sponza's atrium from its galleries), the 64 rays
//!   the solver's elements take hit it once or twice, and the point's value swung by tens
//!   of percent with them.
//! - The sum runs over the scene's surfaces as a hierarchy seen from x: the cluster tree
//!   above the patches (`hierarchical::clusters`), the patches' element quadtrees, and
//!   below each leaf element a few levels of virtual midpoint subdivision. A node is taken
//!   whole when the error of doing so is below δ (see below); otherwise its children are.
//!   - A surface node contributes Lambert's exact point-to-polygon form factor F (zero behind
//!     its front) times its mean radiosity; its error bound is F · ΔB, ΔB the spread of the
//!     solution over it. Below a leaf, the solution is the linear function through the
//!     leaf's corners that keeps its mean: B_e + α (g_k − ḡ), g_k the Gouraud vertex values
//!     (a least-squares fit to the neighbouring elements), so a corner sees the adjacent
//!     wall's value near the corner, not that wall element's average; α ≤ 1 limits the
//!     slope so that no corner leaves [B_e/2, 3B_e/2] (where the vertices disagree with
//!     the element, beside a contact or a shadow, the plain function is far off).
//!   - Visibility: a node whose shaft from x is clear of every other triangle (Haines &
//!     Wallace's shaft cull) is fully visible, one whose shaft a single opaque triangle
//!     crosses whole is hidden (`accel::Shaft`), and what a node's test proves holds for
//!     its children. A node carrying more than 2 δ that no test proves either way is split;
//!     below that, stratified shadow rays estimate it (4; 1 for nodes under δ in the near
//!     field's gathers; 16 for a node over 16 δ that cannot be split), and where they
//!     disagree (a shadow boundary crosses the node) it is split while it carries more
//!     than δ; at the last level a disagreeing node takes 16.
//!   - Form factors are exact (Lambert's contour integral), or the point formula where its
//!     error bound is under a quarter of δ over the light the node carries.
//!   - The near field: a node x lies within two of its radii of (the wall beside a corner,
//!     the floor at the foot of a block) is split down to the last level, and the last
//!     level's nodes within six radii have their radiosity gathered at their centroids
//!     in turn (two levels deep, at coarser errors; [`NEAR`]) instead of read from the mesh, which
//!     does not resolve the light within millimetres of a corner or a contact. Those
//!     centroids are fixed points of the mesh, shared by neighbouring pixels and probes,
//!     so their gathers are memoised ([`NearField`]).
//!   - A cluster contributes its mean radiosity through its projected area (as the
//!     hierarchical solver's cluster links do) times the visibility of its sample patches,
//!     when its bound A · B_max / (π gap²) is below δ; otherwise its children are visited.
//! - δ = `error` · max(H_e, 2 % of the scene's mean H), H_e = (B_e − E_e)/ρ_e the solution's
//!   irradiance at x's element: each node is allowed an error that is small against the
//!   light x receives, in umbrae as well as in the open. Where the sum comes to under half
//!   of H_e (x deep in a penumbra on a lit element), it is taken again with H_e replaced
//!   by the light x was found to receive.
//!
//! Each point is deterministic (its rays are seeded by its position), and points are
//! independent, so a set of points is gathered in parallel with results that do not depend
//! on the thread count.

use super::form_factor::{point_to_triangle_within, ray_in_front, strata_visibility};
use super::hierarchical::clusters::Clusters;
use super::hierarchical::transfer::projected_area;
use crate::accel::{Bvh, Shaft};
use crate::geometry::sampling::{hash, stratified_point};
use crate::light::ExternalLight;
use crate::light::direct::{SKY_RAYS, irradiance_with_sky_rays};
use crate::mesh::Mesh;
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use std::collections::HashMap;
use std::f32::consts::PI;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// How closely the gather follows the light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GatherSettings {
    /// Error allowed per node of the sum, relative to the light the point receives.
    pub error: f32,
    /// Levels of virtual subdivision below a leaf element.
    pub virtual_levels: u8,
}

impl Default for GatherSettings {
    fn default() -> Self {
        GatherSettings {
            error: 0.0005,
            virtual_levels: 7,
        }
    }
}

/// Mean and spread of the solution over a node.
#[derive(Clone, Copy, Debug, Default)]
struct Value {
    mean: Vec3,
    lo: Vec3,
    hi: Vec3,
}

impl Value {
    fn spread(&self) -> f32 {
        (self.hi - self.lo).max(Vec3::ZERO).element_sum()
    }
}

/// A node of the hierarchy as seen from a gathering point.
#[derive(Clone, Copy, Debug)]
enum Node {
    Cluster(u32),
    /// A quadtree node, and what a shaft test of an ancestor proved about it.
    Quad(u32, Shaft),
    /// Part of leaf element `element`: its corners in the element's barycentric
    /// coordinates, how many levels below the leaf it is, and what a shaft test of an
    /// ancestor proved about it.
    Virtual {
        element: u32,
        bary: [Vec3; 3],
        level: u8,
        seen: Shaft,
    },
}

/// The point a sum is taken at: x with normal n on scene triangle `own`, `from` (x lifted
/// off its surface by ε, where its rays start), the error `delta` allowed per node, and
/// its depth in the near field (0: the point asked about).
#[derive(Clone, Copy, Debug)]
struct At {
    x: Vec3,
    n: Vec3,
    from: Vec3,
    own: u32,
    delta: f32,
    depth: u8,
}

/// What the sum does with a surface node.
enum Visit {
    Skip,
    /// Split, with what its shaft test proved for the children (a shaft from x to a
    /// child lies inside its parent's).
    Open(Shaft),
    /// Taken whole: its form factor times visibility.
    Add(f32),
}

/// A solution prepared for gathering at points.
pub struct Gatherer {
    mesh: Arc<Mesh>,
    bvh: Arc<Bvh>,
    external: ExternalLight,
    radiosity: Vec<Vec3>,
    reflectance: Vec<Vec3>,
    emission: Vec<Vec3>,
    settings: GatherSettings,
    clusters: Clusters,
    /// Per cluster: mean radiosity and largest channel sum below it.
    cluster_values: Vec<(Vec3, f32)>,
    /// Per quadtree node: the solution over it, and its patch.
    node_values: Vec<Value>,
    node_patch: Vec<u32>,
    /// Per element: the solution at its corners (mean-preserving linear function).
    corners: Vec<[Vec3; 3]>,
    /// The floor of the irradiance scale: 2 % of the scene's area-mean H (channel sum).
    floor: f32,
    near: NearField,
}

/// The near field's gathers, memoised by element, depth and point.
///
/// A near-field gather at a node's centroid c of element e depends on (e, c) and its depth
/// alone (its rays are seeded by c), so a remembered value is exactly the value it would
/// compute again, whichever thread asks first: results stay independent of the thread
/// count and of the order of the points. On a 160 × 120 final-gathered Cornell box, each pixel asked for
/// 17 of them on average, 82 % of the gather's work, and neighbouring pixels ask for the
/// same ones.
struct NearField {
    shards: Vec<Mutex<HashMap<NearKey, Vec3>>>,
    len: AtomicUsize,
}

/// Element, depth and the point's coordinate bits.
type NearKey = (u32, u8, [u32; 3]);

/// Lock shards: enough that threads rarely wait on one another.
const NEAR_SHARDS: usize = 64;
/// Remembered values at most (about 40 bytes each: 40 MB); past this, values are computed
/// and not kept, so a long viewer session cannot grow the table without bound.
const NEAR_CAPACITY: usize = 1 << 20;

impl NearField {
    fn new() -> NearField {
        NearField {
            shards: (0..NEAR_SHARDS)
                .map(|_| Mutex::new(HashMap::new()))
                .collect(),
            len: AtomicUsize::new(0),
        }
    }

    /// The value for `(e, depth, c)`, computed by `gather` when not remembered.
    fn get_or_gather(&self, e: u32, depth: u8, c: Vec3, gather: impl FnOnce() -> Vec3) -> Vec3 {
        let key = (e, depth, c.to_array().map(f32::to_bits));
        let [cx, cy, cz] = key.2.map(u64::from);
        let h = hash(u64::from(e) ^ u64::from(depth) << 32 ^ cx << 8 ^ cy << 24 ^ cz << 40);
        let shard = &self.shards[h as usize % NEAR_SHARDS];
        // A poisoned lock only means another thread panicked mid-insert; the map is intact.
        if let Some(v) = shard.lock().unwrap_or_else(|p| p.into_inner()).get(&key) {
            return *v;
        }
        let v = gather();
        if self.len.load(Ordering::Relaxed) < NEAR_CAPACITY {
            let mut map = shard.lock().unwrap_or_else(|p| p.into_inner());
            if map.insert(key, v).is_none() {
                self.len.fetch_add(1, Ordering::Relaxed);
            }
        }
        v
    }
}

/// A solution: radiosity, reflectance and emission per element.
pub struct Solution {
    pub radiosity: Vec<Vec3>,
    pub reflectance: Vec<Vec3>,
    pub emission: Vec<Vec3>,
}

impl std::fmt::Debug for Gatherer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Gatherer")
            .field("elements", &self.radiosity.len())
            .field("settings", &self.settings)
            .finish_non_exhaustive()
    }
}

impl Gatherer {
    /// Prepares `solution` (per element of `mesh`) for gathering with visibility from
    /// `bvh` and the `external` lights.
    pub fn new(
        mesh: Arc<Mesh>,
        bvh: Arc<Bvh>,
        external: ExternalLight,
        solution: Solution,
        settings: GatherSettings,
    ) -> Gatherer {
        let Solution {
            radiosity,
            reflectance,
            emission,
        } = solution;
        let vertex = mesh.display.vertex_values(&mesh.elements, &radiosity);
        let corners: Vec<[Vec3; 3]> = mesh
            .elements
            .iter()
            .zip(&radiosity)
            .map(|(e, b)| limited_corners(*b, e.corners.map(|c| vertex[c as usize])))
            .collect();
        let mut node_values = vec![Value::default(); mesh.nodes.len()];
        let mut area_sums = vec![0.0f32; mesh.nodes.len()];
        let mut node_patch = vec![0u32; mesh.nodes.len()];
        for (i, p) in mesh.patches.iter().enumerate() {
            let mut tree = Tree {
                mesh: &mesh,
                radiosity: &radiosity,
                corners: &corners,
                patch: i as u32,
                values: &mut node_values,
                area: &mut area_sums,
                node_patch: &mut node_patch,
            };
            tree.fill(p.root);
        }
        let open: Vec<u32> = (0..mesh.patches.len() as u32)
            .filter(|&p| !mesh.patches[p as usize].covered)
            .collect();
        let clusters = Clusters::build(&mesh, &open);
        let mut cluster_values = vec![(Vec3::ZERO, 0.0f32); clusters.nodes.len()];
        // Preorder: children come after their parent, so leaves first from the back.
        for c in (0..clusters.nodes.len()).rev() {
            let (mut sum, mut area, mut hi) = (Vec3::ZERO, 0.0f32, 0.0f32);
            for k in clusters.children_of(c) {
                let (mean, a, h) = match k.cluster() {
                    Some(j) => (
                        cluster_values[j].0,
                        clusters.nodes[j].area,
                        cluster_values[j].1,
                    ),
                    None => {
                        let v = &node_values[k.0 as usize];
                        (v.mean, area_sums[k.0 as usize], v.hi.element_sum())
                    }
                };
                sum += mean * a;
                area += a;
                hi = hi.max(h);
            }
            cluster_values[c] = (if area > 0.0 { sum / area } else { Vec3::ZERO }, hi);
        }
        let (mut h_sum, mut a_sum) = (0.0f64, 0.0f64);
        for (i, e) in mesh.elements.iter().enumerate() {
            if mesh.patches[e.patch as usize].covered {
                continue;
            }
            h_sum +=
                e.area as f64 * irradiance_of(radiosity[i], reflectance[i], emission[i]) as f64;
            a_sum += e.area as f64;
        }
        let floor = if a_sum > 0.0 {
            (0.02 * h_sum / a_sum) as f32
        } else {
            0.0
        };
        Gatherer {
            mesh,
            bvh,
            external,
            radiosity,
            reflectance,
            emission,
            settings,
            clusters,
            cluster_values,
            node_values,
            node_patch,
            corners,
            floor,
            near: NearField::new(),
        }
    }

    /// The mesh the solution lies on (element indices refer to it).
    pub fn mesh(&self) -> &Arc<Mesh> {
        &self.mesh
    }

    /// The scene's triangles for visibility.
    pub fn bvh(&self) -> &Arc<Bvh> {
        &self.bvh
    }

    /// Element `e`'s reflectance ρ and emitted radiosity E on its covered part (those it
    /// was solved with over its opacity, see `Mesh::opacity`).
    pub fn surface(&self, e: u32) -> (Vec3, Vec3) {
        let opacity = self.opacity(e);
        (
            self.reflectance[e as usize] / opacity,
            self.emission[e as usize] / opacity,
        )
    }

    /// The opacity of element `e`'s patch (`Mesh::opacity`).
    fn opacity(&self, e: u32) -> f32 {
        let patch = self.mesh.elements[e as usize].patch;
        self.mesh.opacity(&self.mesh.patches[patch as usize])
    }

    /// B at each world-space point with the normal of the side asked about (as `probe`
    /// reads them); zero where no element faces that way.
    pub fn at_points(&self, points: &[(DVec3, DVec3)]) -> Vec<Vec3> {
        points
            .par_iter()
            .map(|(p, n)| {
                let p = self.mesh.to_local(*p);
                match self.mesh.locate(p, n.as_vec3()) {
                    // The point itself, projected onto the element's plane (not clamped to
                    // the element: the nearest element may stop short of a point a few
                    // microns from an edge, and a point on the edge would see the face
                    // beyond it edge-on).
                    Some((e, _)) => self.at(e, self.mesh.elements[e as usize].project(p)),
                    None => Vec3::ZERO,
                }
            })
            .collect()
    }

    /// B at point `x` (mesh frame) of element `e`: its covered part's, as a probe reports
    /// it (the near field's sources send the solved B, their opacity times that).
    pub fn at(&self, e: u32, x: Vec3) -> Vec3 {
        self.at_depth(e, x, 0) / self.opacity(e)
    }

    /// [`Gatherer::at`] at `depth` levels of the near field below the point asked about:
    /// below [`NEAR_DEPTH`] the nearest sources' radiosity is gathered at them in turn (see
    /// [`Gatherer::source_value`]), at it the solution's is taken.
    fn at_depth(&self, e: u32, x: Vec3, depth: u8) -> Vec3 {
        let mesh = &self.mesh;
        let i = e as usize;
        let element = &mesh.elements[i];
        let n = element.normal;
        let own = mesh.patches[element.patch as usize].scene_triangle;
        let seed = hash(
            x.x.to_bits() as u64 ^ (x.y.to_bits() as u64) << 21 ^ (x.z.to_bits() as u64) << 42,
        );
        let sky_rays = if depth == 0 { POINT_SKY_RAYS } else { SKY_RAYS };
        let (external, _) = irradiance_with_sky_rays(
            &mesh.frame(),
            &self.bvh,
            &self.external,
            (x, n, own),
            seed,
            sky_rays,
        );
        let scale = irradiance_of(self.radiosity[i], self.reflectance[i], self.emission[i]);
        // The near field's own gathers reach x through a form factor below 1 and are many:
        // they are allowed a coarser error per node.
        let error = self.settings.error * NEAR[depth as usize].error;
        let at = |light: f32| At {
            x,
            n,
            from: x + n * mesh.epsilon(),
            own,
            delta: error * light.max(self.floor),
            depth,
        };
        let mut gathered = self.gathered(at(scale), seed);
        // δ follows the element's light, which can be many times the point's own: a point
        // deep in a penumbra on a lit element. When the sum comes to under half the
        // element's, it is taken again with δ from the point's own light (in the penumbra
        // scene this took the penumbra points from 0.84 % to 0.71 % RMS against a 0.3 %
        // path-traced reference).
        let here = (external + gathered).element_sum();
        if depth == 0 && 2.0 * here < scale && scale > self.floor {
            gathered = self.gathered(at(here), seed);
        }
        self.emission[i] + self.reflectance[i] * (external + gathered)
    }

    /// The radiosity a leaf or virtual node of element `e` with centroid `c` and bounding
    /// radius `r` sends to x through `factor`: the solution's `mean`, or, below
    /// [`NEAR_DEPTH`] for a node close to x that carries a noticeable share of its light,
    /// the gather at the node's centroid itself. This is the near field of a corner or a
    /// contact: there the adjacent wall's light changes over millimetres and x sees that
    /// wall at a large solid angle, so the element's linear function is not enough.
    fn source_value(&self, at: &At, e: u32, (c, r): (Vec3, f32), mean: Vec3, factor: f32) -> Vec3 {
        let depth = at.depth;
        if depth < NEAR_DEPTH
            && factor > NEAR[depth as usize].gather_factor
            && (c - at.x).length() < GATHER_RADII * r
        {
            self.near
                .get_or_gather(e, depth + 1, c, || self.at_depth(e, c, depth + 1))
        } else {
            mean
        }
    }

    /// Σ_s F(x → s) V(x, s) B_s over the hierarchy, each node to within δ.
    fn gathered(&self, at: At, seed: u64) -> Vec3 {
        let At { x, n, own, .. } = at;
        let mesh = &self.mesh;
        let virtual_levels = self
            .settings
            .virtual_levels
            .min(NEAR[at.depth as usize].virtual_levels);
        let mut stack: Vec<Node> = Vec::with_capacity(64);
        if self.clusters.nodes.is_empty() {
            return Vec3::ZERO;
        }
        stack.push(Node::Cluster(0));
        let mut h = Vec3::ZERO;
        while let Some(node) = stack.pop() {
            match node {
                Node::Cluster(c) => {
                    let cluster = &self.clusters.nodes[c as usize];
                    let d = cluster.centre - x;
                    if n.dot(d) < -cluster.radius {
                        continue;
                    }
                    let dist = d.length();
                    let gap = dist - cluster.radius;
                    let (mean, hi) = self.cluster_values[c as usize];
                    if gap > 0.0 && cluster.area * hi / (PI * gap * gap) <= at.delta {
                        h += mean * self.cluster_factor(c as usize, x, n, own, seed);
                    } else {
                        for k in self.clusters.children_of(c as usize) {
                            stack.push(match k.cluster() {
                                Some(j) => Node::Cluster(j as u32),
                                None => Node::Quad(k.0, Shaft::Unknown),
                            });
                        }
                    }
                }
                Node::Quad(q, seen) => {
                    let quad = &mesh.nodes[q as usize];
                    let patch = &mesh.patches[self.node_patch[q as usize] as usize];
                    let value = self.node_values[q as usize];
                    let can_open = quad.children.is_some() || virtual_levels > 0;
                    let visit = self.visit(
                        (&at, seed ^ q as u64),
                        (&quad.verts, patch.normal, patch.scene_triangle),
                        value,
                        (can_open, seen),
                    );
                    match visit {
                        Visit::Skip => {}
                        Visit::Add(f) => {
                            h += f * match quad.element {
                                Some(e) => {
                                    let c = (quad.verts[0] + quad.verts[1] + quad.verts[2]) / 3.0;
                                    let r = radius(&quad.verts, c);
                                    self.source_value(&at, e, (c, r), value.mean, f)
                                }
                                None => value.mean,
                            }
                        }
                        Visit::Open(seen) => match (quad.children, quad.element) {
                            (Some(children), _) => {
                                stack.extend(children.map(|c| Node::Quad(c, seen)));
                            }
                            (None, Some(element)) => {
                                let b = [Vec3::X, Vec3::Y, Vec3::Z];
                                stack.extend(virtual_children(b).map(|bary| Node::Virtual {
                                    element,
                                    bary,
                                    level: 1,
                                    seen,
                                }));
                            }
                            (None, None) => {}
                        },
                    }
                }
                Node::Virtual {
                    element,
                    bary,
                    level,
                    seen,
                } => {
                    let el = &mesh.elements[element as usize];
                    let patch = &mesh.patches[el.patch as usize];
                    let point = |b: Vec3| el.verts[0] * b.x + el.verts[1] * b.y + el.verts[2] * b.z;
                    let verts = bary.map(point);
                    let c = &self.corners[element as usize];
                    let value_at = |b: Vec3| c[0] * b.x + c[1] * b.y + c[2] * b.z;
                    let corner_values = bary.map(value_at);
                    let value = Value {
                        mean: (corner_values[0] + corner_values[1] + corner_values[2]) / 3.0,
                        lo: corner_values[0].min(corner_values[1]).min(corner_values[2]),
                        hi: corner_values[0].max(corner_values[1]).max(corner_values[2]),
                    };
                    let node_seed = hash(seed ^ (element as u64) << 8 ^ bary[0].x.to_bits() as u64);
                    match self.visit(
                        (&at, node_seed),
                        (&verts, patch.normal, patch.scene_triangle),
                        value,
                        (level < virtual_levels, seen),
                    ) {
                        Visit::Skip => {}
                        Visit::Add(f) => {
                            let c = (verts[0] + verts[1] + verts[2]) / 3.0;
                            let r = radius(&verts, c);
                            h += f * self.source_value(&at, element, (c, r), value.mean, f);
                        }
                        Visit::Open(seen) => {
                            stack.extend(virtual_children(bary).map(|bary| Node::Virtual {
                                element,
                                bary,
                                level: level + 1,
                                seen,
                            }));
                        }
                    }
                }
            }
        }
        h
    }

    /// What a surface node with `verts`, `normal` and scene triangle `triangle` adds at x;
    /// `seen`: what a shaft test of an ancestor proved about its visibility.
    fn visit(
        &self,
        (at, seed): (&At, u64),
        (verts, normal, triangle): (&[Vec3; 3], Vec3, u32),
        value: Value,
        (can_open, seen): (bool, Shaft),
    ) -> Visit {
        let x = at.x;
        let delta = at.delta;
        // x is behind the node, or on the node's own triangle: its front is coplanar with
        // x and its back (a double-sided surface's other side) faces away, though a
        // rounding error of x off the plane made the back a disc right above x (F ≈ 1:
        // the outside of a white sphere took the light of its sealed inside).
        if normal.dot(x - verts[0]) <= 0.0 || triangle == at.own {
            return Visit::Skip;
        }
        // The form factor to within a quarter of δ of the light it carries.
        let bright = value.hi.max(value.mean).element_sum();
        let tolerance = if bright > 0.0 {
            0.25 * delta / bright
        } else {
            f32::INFINITY
        };
        let f = point_to_triangle_within(x, at.n, verts, tolerance);
        if f <= 0.0 || !f.is_finite() {
            return Visit::Skip;
        }
        let eps = self.mesh.epsilon();
        let skip = [at.own, triangle];
        let shaft = || {
            if seen != Shaft::Unknown {
                return seen;
            }
            let base = verts.map(|v| v + normal * eps);
            self.bvh.shaft(at.from, &base, skip, eps * 0.1)
        };
        // A node about to be split is tested first: a hidden one is skipped whole, and
        // what the test proves holds for its children.
        let open = || match shaft() {
            Shaft::Blocked => Visit::Skip,
            seen => Visit::Open(seen),
        };
        if can_open && f * value.spread() > delta {
            return open();
        }
        let carried = f * value.mean.element_sum();
        if carried <= 0.0 {
            return Visit::Skip;
        }
        // A node x lies within two radii of (the wall beside a corner, the floor at the foot
        // of a block) is split down to the last level whatever the solution says there: the
        // mesh does not resolve the light within millimetres of x, and the last level's
        // nodes near x have their radiosity gathered at them (`source_value`). At the last
        // depth of the near field nothing is gathered in turn, and the split is left to
        // the solution's spread.
        let c = (verts[0] + verts[1] + verts[2]) / 3.0;
        if can_open
            && at.depth < NEAR_DEPTH
            && carried > delta
            && (c - x).length() < NEAR_RADII * radius(verts, c)
        {
            return open();
        }
        // A node carrying at most δ can be off by all of it: a shaft test of its own would
        // cost more than its rays (it still has what an ancestor's proved).
        let seen = if carried > delta { shaft() } else { seen };
        match seen {
            Shaft::Clear => return Visit::Add(f),
            Shaft::Blocked => return Visit::Skip,
            Shaft::Unknown => {}
        }
        // Shadow rays agreeing prove nothing about a node brighter than δ: k × k
        // stratified rays all blocked can miss a sliver of up to 1/k of it past an
        // occluder's edge. Such a node is split until its rays' worst miss is within δ.
        if can_open && carried > BLIND_NODE * delta {
            return Visit::Open(Shaft::Unknown);
        }
        let k = if carried > 16.0 * delta {
            4
        } else if carried > delta || at.depth == 0 {
            2
        } else {
            // One ray is within δ; the near field's gathers are many and reach the point
            // through form factors below one, so their noise averages out.
            1
        };
        let strata = |k: u32, seed: u64| {
            let seen =
                strata_visibility(&self.bvh, (x, at.n), (verts, normal), (eps, skip), k, seed);
            (seen.fraction, seen.hi > seen.lo)
        };
        let (mut visible, partial) = strata(k, seed);
        if partial && carried > delta {
            if can_open {
                return Visit::Open(Shaft::Unknown);
            }
            if k < 4 {
                visible = strata(4, hash(seed)).0;
            }
        }
        Visit::Add(f * visible)
    }

    /// The factor through which cluster `c` sends its mean radiosity to x: its projected
    /// area towards x over π d², times n · ω and the visibility of its sample patches.
    fn cluster_factor(&self, c: usize, x: Vec3, n: Vec3, own: u32, seed: u64) -> f32 {
        let cluster = &self.clusters.nodes[c];
        let d = cluster.centre - x;
        let dist2 = d.length_squared();
        if dist2 <= 0.0 {
            return 0.0;
        }
        let w = d / dist2.sqrt();
        let unoccluded = n.dot(w).max(0.0) * projected_area(cluster.area, cluster.area_vector, -w)
            / (PI * dist2);
        if unoccluded <= 0.0 {
            return 0.0;
        }
        // Shadow rays go to the sample patches that face x (a patch facing away sends
        // nothing this way, and the projected area already leaves it out), or to all of
        // them when none does.
        let eps = self.mesh.epsilon();
        let facing = |p: &u32| {
            let patch = &self.mesh.patches[*p as usize];
            patch.normal.dot(x - patch.centroid()) > 0.0
        };
        let count = cluster.samples.iter().filter(|p| facing(p)).count();
        let through: f32 = cluster
            .samples
            .iter()
            .filter(|p| count == 0 || facing(p))
            .enumerate()
            .map(|(k, &p)| {
                let patch = &self.mesh.patches[p as usize];
                let y = stratified_point(&patch.verts, 1, 0, hash(seed ^ k as u64))
                    + patch.normal * eps;
                ray_in_front(&self.bvh, (x, n), (eps, [own, patch.scene_triangle]), y)
            })
            .sum();
        let used = if count == 0 {
            cluster.samples.len()
        } else {
            count
        };
        unoccluded * through / used as f32
    }
}

/// Sky rays at the point asked about (a 32 × 32 stratified grid; the near field's own
/// gathers take the solver's [`SKY_RAYS`]).
const POINT_SKY_RAYS: u32 = 1024;

/// How far, relative to an element's radiosity, the linear function below it may reach at
/// its corners (see [`limited_corners`]).
const SLOPE_LIMIT: f32 = 0.5;

/// The corner values of the linear function below an element of radiosity `b` whose
/// display vertices have the values `g`: b + α (g_k − ḡ), which keeps the element's mean.
/// α (per channel, at most 1) is a slope limiter, as in finite-volume schemes: no corner
/// leaves [b/2, 3b/2]. Where the vertex values disagree with the element (a floor element
/// at a block's foot, whose vertices average in brighter neighbours across a shadow), the
/// plain function put most of the neighbours' light at the foot: the block's face 2 mm
/// above the floor got 13 % too much green light.
fn limited_corners(b: Vec3, g: [Vec3; 3]) -> [Vec3; 3] {
    let mean = (g[0] + g[1] + g[2]) / 3.0;
    let d = g.map(|g| g - mean);
    let worst = d[0].abs().max(d[1].abs()).max(d[2].abs());
    let limit = (b * SLOPE_LIMIT / worst).min(Vec3::ONE);
    let limit = Vec3::select(worst.cmpgt(Vec3::ZERO), limit, Vec3::ONE);
    d.map(|d| (b + d * limit).max(Vec3::ZERO))
}

/// A node whose visibility no shaft test proved and that carries more than this many δ is
/// split rather than trusted to its shadow rays (2 × 2 rays can miss half of it). At 64,
/// 16 agreeing rays took nodes of 35 δ whole along the penumbra scene's shadow edges, and
/// its deep-penumbra points were off by up to 3.4 %; at 2 the penumbra points came to
/// 0.43 % RMS against a 0.3 % path-traced reference, 0.24 % against the closed form.
/// Umbrae stay cheap because a shaft test proves a node hidden behind one triangle.
const BLIND_NODE: f32 = 2.0;

/// A node whose centroid lies within this many of its bounding radii from x is split
/// while it can be.
const NEAR_RADII: f32 = 2.0;
/// A leaf or virtual node whose form factor from x exceeds its depth's `gather_factor`
/// and whose centroid lies within [`GATHER_RADII`] of its radii from x has its radiosity
/// gathered at its centroid. Measured on the Cornell box's contact points (block sides
/// 0.1–2 mm above the floor) against a 0.3 % path-traced reference, with the near field
/// two levels deep: 4 radii left them 0.78 % RMS, 6 radii 0.56 %, 12 radii 0.60 % at
/// 1.4 times the time.
const GATHER_RADII: f32 = 6.0;

/// How the gather works at one depth of the near field.
struct NearLevel {
    /// The error allowed per node, as a multiple of the point's own.
    error: f32,
    /// The form factor above which a nearby node's radiosity is gathered at it in turn.
    gather_factor: f32,
    /// The most levels of virtual subdivision below a leaf element.
    virtual_levels: u8,
}

/// The near field, level by level (index 0 is the point asked about); its gathers go
/// [`NEAR_DEPTH`] levels deep.
///
/// Why two levels: at a contact both surfaces are darker near the contact line than
/// their elements' means (each hides part of the other's sky), and the form factor from
/// a point there weighs the part nearest the line most, so a mean taken too close to the
/// point is too bright. One level left the block faces 0.2–4 mm above the Cornell floor
/// 1.07 % RMS too bright (3.1 % at worst, +1.6 % signed mean) against a 0.26 % path-traced
/// reference (`bench builtin:cornell --reference-error 0.003`); the second level, which
/// gathers the light of the floor points near the foot from the block face near the
/// foot and not from its elements' means, left 0.62 % (1.6 %).
///
/// The errors: 32× at the first level (64× left the contacts at 0.84 %, 8× gained 0.1 %
/// for twice the time), 64× at the second (256× was 15 % faster, but each node could then
/// carry 13 % of the light: a furnace's corners came out 0.7 % too bright, against 0.08 %
/// now; `tests/hard_geometry.rs`). The first level's gathers ask for the second's above
/// a form factor of 10⁻² rather than 10⁻³, and both stop three levels below a leaf
/// rather than seven: on the Cornell box's 295 bench points each saved 15–20 % of the
/// time and moved no class by more than 0.02 %.
const NEAR: [NearLevel; 3] = [
    NearLevel {
        error: 1.0,
        gather_factor: 1e-3,
        virtual_levels: u8::MAX,
    },
    NearLevel {
        error: 32.0,
        gather_factor: 1e-2,
        virtual_levels: 3,
    },
    NearLevel {
        error: 64.0,
        gather_factor: f32::INFINITY,
        virtual_levels: 3,
    },
];
const NEAR_DEPTH: u8 = NEAR.len() as u8 - 1;

/// Largest distance from `c` to a corner of `v`.
fn radius(v: &[Vec3; 3], c: Vec3) -> f32 {
    v.iter().map(|p| (*p - c).length()).fold(0.0, f32::max)
}

/// The irradiance H = (B − E)/ρ the solution gives an element (channel sum), with ρ
/// floored so that black surfaces do not divide by zero.
fn irradiance_of(b: Vec3, rho: Vec3, e: Vec3) -> f32 {
    ((b - e).max(Vec3::ZERO) / rho.max(Vec3::splat(0.05))).element_sum()
}

/// The quadtree of one patch being filled with the solution's mean and spread per node.
struct Tree<'t> {
    mesh: &'t Mesh,
    radiosity: &'t [Vec3],
    corners: &'t [[Vec3; 3]],
    patch: u32,
    values: &'t mut [Value],
    area: &'t mut [f32],
    node_patch: &'t mut [u32],
}

impl Tree<'_> {
    /// Fills node `q` and everything below it from the leaves' values.
    fn fill(&mut self, q: u32) {
        let node = &self.mesh.nodes[q as usize];
        let (children, element) = (node.children, node.element);
        self.node_patch[q as usize] = self.patch;
        let value = match (children, element) {
            (Some(children), _) => {
                let mut v = Value {
                    mean: Vec3::ZERO,
                    lo: Vec3::splat(f32::INFINITY),
                    hi: Vec3::ZERO,
                };
                let mut a = 0.0;
                for c in children {
                    self.fill(c);
                    let (cv, ca) = (self.values[c as usize], self.area[c as usize]);
                    v.mean += cv.mean * ca;
                    a += ca;
                    v.lo = v.lo.min(cv.lo);
                    v.hi = v.hi.max(cv.hi);
                }
                v.mean /= a.max(f32::MIN_POSITIVE);
                self.area[q as usize] = a;
                v
            }
            (None, Some(e)) => {
                let (c, b) = (&self.corners[e as usize], self.radiosity[e as usize]);
                self.area[q as usize] = self.mesh.elements[e as usize].area;
                Value {
                    mean: b,
                    lo: c[0].min(c[1]).min(c[2]).min(b),
                    hi: c[0].max(c[1]).max(c[2]).max(b),
                }
            }
            (None, None) => Value::default(),
        };
        self.values[q as usize] = value;
    }
}

/// The four midpoint children of a triangle given by barycentric corners (the order of
/// `geometry::subdivide`).
fn virtual_children(b: [Vec3; 3]) -> [[Vec3; 3]; 4] {
    let m01 = (b[0] + b[1]) * 0.5;
    let m12 = (b[1] + b[2]) * 0.5;
    let m20 = (b[2] + b[0]) * 0.5;
    [
        [b[0], m01, m20],
        [m01, b[1], m12],
        [m20, m12, b[2]],
        [m01, m12, m20],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_limited_linear_function_keeps_the_mean_and_stays_near_it() {
        // Gentle vertex values pass unchanged; values far off the element's are scaled
        // down to reach at most half its radiosity away, and the mean stays the element's.
        let b = Vec3::new(1.0, 0.2, 0.0);
        let gentle = [
            Vec3::new(1.1, 0.25, 0.0),
            Vec3::new(0.9, 0.2, 0.0),
            Vec3::new(1.0, 0.2, 0.0),
        ];
        let steep = [
            Vec3::new(4.0, 0.1, 1.0),
            Vec3::new(0.1, 0.9, 0.0),
            Vec3::splat(2.0),
        ];
        for g in [gentle, steep] {
            let c = limited_corners(b, g);
            let mean = (c[0] + c[1] + c[2]) / 3.0;
            assert!((mean - b).abs().max_element() < 1e-6, "{mean} vs {b}");
            for v in c {
                assert!(
                    (v - b).abs().cmple(b * SLOPE_LIMIT + 1e-6).all(),
                    "{v} vs {b}"
                );
            }
        }
        let m = (gentle[0] + gentle[1] + gentle[2]) / 3.0;
        let plain = gentle.map(|g| b + g - m);
        let c = limited_corners(b, gentle);
        assert!(
            (0..3).all(|k| (c[k] - plain[k]).abs().max_element() < 1e-6),
            "{c:?} vs {plain:?}"
        );
        // A black channel stays black.
        assert!(limited_corners(b, steep).iter().all(|v| v.z == 0.0));
    }
}
