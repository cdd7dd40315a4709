//! Discretisation of a [`Scene`] into patches (shooters) and elements (receivers).
//!
//! Substructuring (Cohen, Greenberg, Immel & Brock, "An efficient radiosity approach for
//! realistic image synthesis", 1986): each input triangle is cut into *patches* by
//! longest-edge bisection until no edge exceeds the patch size (so slivers become chains of
//! short patches instead of huge quadtrees), and each patch is the root of a quadtree of
//! *elements* made by midpoint subdivision. Patches shoot light, elements receive it;
//! the leaves of a patch's quadtree are stored contiguously so `Patch::elements` is a range.
//!
//! Geometry is re-centred: `Mesh::origin` (f64, world) is subtracted from every position
//! before it is stored in f32, so a kilometre-sized scene a thousand kilometres from the
//! origin keeps millimetre precision.
//!
//! Double-sided materials give two patches per piece of surface, one per side, each with its
//! own radiosity; single-sided ones give one, on the front (counter-clockwise) side.

mod adaptive;
mod contact;
mod display;
mod hard_shadows;
mod shadow;

pub use adaptive::{AdaptiveSettings, Moved, size as element_size};
pub use display::{
    Bezier, DisplayMesh, Hermite, Reconstruction, Reconstructor, ShadowSides, eval_bezier,
};
pub use hard_shadows::LightTargets;

use crate::geometry::{
    Frame, closest_point_on_triangle, subdivide, triangle_area as area, triangle_cross,
};
use crate::light::{Punctual, punctual_lights};
use crate::scene::Scene;
use glam::{DVec3, Vec3};
use std::ops::Range;

/// How finely to mesh. `element_size` wins over `max_elements`; with neither, the element
/// size is chosen so that the mesh has at most [`DEFAULT_ELEMENTS`] elements, or 1.5 per
/// triangle side for scenes with more triangles than that.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshSettings {
    /// Target element size in metres: an element's `sqrt(2·area)` (the leg of a right
    /// isosceles triangle of the same area) is at most this.
    pub element_size: Option<f64>,
    /// Upper bound on the number of elements when `element_size` is not given.
    pub max_elements: Option<usize>,
    /// Split triangles where other surfaces touch or pierce them (D0 discontinuity
    /// meshing along contact lines; see `contact`). On by default; off for comparisons.
    pub contact_lines: bool,
    /// Split triangles where the hard shadows of point, spot and directional lights and
    /// the sun fall (shadow lines; see `shadow`). On by default.
    pub shadow_lines: bool,
}

impl Default for MeshSettings {
    fn default() -> Self {
        MeshSettings {
            element_size: None,
            max_elements: None,
            contact_lines: true,
            shadow_lines: true,
        }
    }
}

/// Default element budget: enough for visibly smooth Cornell-box lighting while keeping the
/// dense direct reference (O(N³)) to seconds.
pub const DEFAULT_ELEMENTS: usize = 3000;

/// Patches are at most this many element sizes long (so at most ~16–64 elements each).
const PATCH_PER_ELEMENT: f64 = 4.0;

/// Surfaces closer than this fraction of the scene's diagonal count as touching (contact
/// lines, `contact`): 0.2 mm in a 1 m box, where the Cornell box's light hangs 0.1 mm
/// under the ceiling.
const CONTACT_TOLERANCE: f32 = 2e-4;

/// A shooter: a piece of one input triangle, seen from one side.
#[derive(Clone, Debug)]
pub struct Patch {
    /// Vertices in the mesh frame, counter-clockwise seen from the side this patch is on.
    pub verts: [Vec3; 3],
    /// Unit normal on the side this patch is on.
    pub normal: Vec3,
    /// Area in m².
    pub area: f32,
    /// Index of the scene triangle (the BVH's numbering) this patch lies on.
    pub scene_triangle: u32,
    /// Index of that triangle within its object.
    pub triangle: u32,
    /// Object and material indices in the scene.
    pub object: u32,
    pub material: u32,
    /// Whether this is the back side of a double-sided surface.
    pub back: bool,
    /// Reflectance ρ (material × texture tint, clamped to [0, 0.999]).
    pub reflectance: Vec3,
    /// Emitted radiosity E = π L_e (W/m²).
    pub emission: Vec3,
    /// The patch's elements (leaves of its quadtree), contiguous.
    pub elements: Range<u32>,
    /// Root of its quadtree in `Mesh::nodes`.
    pub root: u32,
    /// Which side of the contact lines cutting its triangle it lies on: patches of one
    /// triangle share a region when they meet without crossing a contact line (see
    /// `contact`). Display vertices on a contact line are shared only within a region.
    pub region: u32,
    /// The contact segments its triangle was split along, in `Mesh::cut_edges` (empty
    /// when it was not split).
    pub cuts: Range<u32>,
    /// Hidden under a face pressed against its front (a box's bottom on a floor, a lamp
    /// flush under a ceiling): it receives no light and is not drawn.
    pub covered: bool,
}

impl Patch {
    /// Centroid in the mesh frame.
    pub fn centroid(&self) -> Vec3 {
        (self.verts[0] + self.verts[1] + self.verts[2]) / 3.0
    }
}

/// A receiver: a leaf of a patch's quadtree.
#[derive(Clone, Debug)]
pub struct Element {
    /// Vertices in the mesh frame, same orientation as the patch.
    pub verts: [Vec3; 3],
    pub normal: Vec3,
    pub area: f32,
    /// The patch it belongs to.
    pub patch: u32,
    /// Depth in the quadtree (0 = the patch itself).
    pub level: u8,
    /// Display-mesh vertex of each corner.
    pub corners: [u32; 3],
}

impl Element {
    /// Centroid in the mesh frame.
    pub fn centroid(&self) -> Vec3 {
        (self.verts[0] + self.verts[1] + self.verts[2]) / 3.0
    }
}

/// A quadtree node: four children by midpoint subdivision, or a leaf holding an element.
#[derive(Clone, Debug)]
pub struct QuadNode {
    pub verts: [Vec3; 3],
    pub children: Option<[u32; 4]>,
    pub element: Option<u32>,
}

/// The meshed scene.
#[derive(Clone, Debug)]
pub struct Mesh {
    /// World position of the mesh frame's origin (the scene's bounding-box centre).
    pub origin: DVec3,
    /// Length of the scene's bounding-box diagonal in metres (the scale for epsilons).
    pub scale: f32,
    pub patches: Vec<Patch>,
    pub elements: Vec<Element>,
    pub nodes: Vec<QuadNode>,
    /// All scene triangles in the mesh frame (the BVH's input), and their transmittance.
    pub triangles: Vec<[Vec3; 3]>,
    pub transmittance: Vec<f32>,
    /// Shared-vertex mesh for display and Gouraud reconstruction.
    pub display: DisplayMesh,
    /// The element size used, metres.
    pub element_size: f64,
    /// Problems met while meshing (degenerate triangles dropped, reflectance clamped).
    pub warnings: Vec<String>,
    /// Patches of each scene triangle: `triangle_patches[t]` is a range of patch indices
    /// (front side first, then back side for double-sided materials; empty when the
    /// triangle is degenerate).
    pub triangle_patches: Vec<Range<u32>>,
    /// Contact (D0) segments the triangles were split along, each triangle's one after
    /// another; mesh frame.
    pub cut_edges: Vec<[Vec3; 2]>,
}

/// An input triangle in the mesh frame with everything the patches need.
#[derive(Clone)]
struct Source {
    verts: [Vec3; 3],
    /// Region and contact segments (in `cut_edges`) of the piece of the input triangle
    /// this is, after splitting along contact lines (see `Patch::region`).
    region: u32,
    cuts: Range<u32>,
    covered: bool,
    scene_triangle: u32,
    triangle: u32,
    object: u32,
    material: u32,
    reflectance: Vec3,
    emission: Vec3,
    double_sided: bool,
}

fn longest_edge(v: &[Vec3; 3]) -> (usize, f32) {
    let e = [
        (v[1] - v[0]).length_squared(),
        (v[2] - v[1]).length_squared(),
        (v[0] - v[2]).length_squared(),
    ];
    let k = if e[0] >= e[1] && e[0] >= e[2] {
        0
    } else if e[1] >= e[2] {
        1
    } else {
        2
    };
    (k, e[k].sqrt())
}

/// Longest-edge bisection until every edge is at most `max_len`.
fn split_patches(v: [Vec3; 3], max_len: f32, out: &mut Vec<[Vec3; 3]>) {
    let (k, len) = longest_edge(&v);
    // The depth guard bounds the work on absurd inputs (a 1e9:1 sliver); 2^24 pieces
    // would already exceed any sane element budget.
    fn go(v: [Vec3; 3], max_len: f32, out: &mut Vec<[Vec3; 3]>, k: usize, len: f32, depth: u32) {
        if len <= max_len || depth >= 24 {
            out.push(v);
            return;
        }
        let (a, b, c) = (v[k], v[(k + 1) % 3], v[(k + 2) % 3]);
        let m = (a + b) * 0.5;
        for t in [[a, m, c], [m, b, c]] {
            let (k2, l2) = longest_edge(&t);
            go(t, max_len, out, k2, l2, depth + 1);
        }
    }
    go(v, max_len, out, k, len, 0);
}

/// Quadtree depth that brings `sqrt(2·area)` to at most `size` (each level halves it).
fn depth_for(area: f32, size: f64) -> u32 {
    let m = (2.0 * area as f64).sqrt();
    if m <= size || size <= 0.0 {
        return 0;
    }
    ((m / size).log2().ceil() as u32).min(12)
}

fn count_elements(sources: &[Source], size: f64) -> usize {
    let patch_len = (size * PATCH_PER_ELEMENT) as f32;
    let mut pieces = Vec::new();
    let mut total = 0usize;
    for s in sources {
        pieces.clear();
        split_patches(s.verts, patch_len, &mut pieces);
        let sides = if s.double_sided { 2 } else { 1 };
        for p in &pieces {
            total += sides * 4usize.pow(depth_for(area(p), size));
        }
    }
    total
}

impl Mesh {
    /// Meshes `scene` with `settings`. Degenerate (zero-area or non-finite) triangles are
    /// kept out of the patches (with one warning) but stay in the BVH if finite.
    pub fn build(scene: &Scene, settings: &MeshSettings) -> Mesh {
        Mesh::build_keeping_bvh(scene, settings).0
    }

    /// [`Mesh::build`], and the BVH of its scene triangles when meshing needed one (to
    /// find shadow lines), so the caller need not build it again.
    pub fn build_keeping_bvh(
        scene: &Scene,
        settings: &MeshSettings,
    ) -> (Mesh, Option<crate::accel::Bvh>) {
        let (lo, hi) = scene.bounds().unwrap_or((DVec3::ZERO, DVec3::ZERO));
        let origin = (lo + hi) * 0.5;
        let scale = ((hi - lo).length() as f32).max(f32::MIN_POSITIVE);
        let mut warnings = Vec::new();
        let mut triangles = Vec::with_capacity(scene.triangle_count());
        let mut transmittance = Vec::with_capacity(scene.triangle_count());
        let mut sources = Vec::new();
        let (mut degenerate, mut clamped) = (0usize, 0usize);
        for (oi, o) in scene.objects.iter().enumerate() {
            for (ti, t) in o.triangles.iter().enumerate() {
                let verts = t.map(|v| (o.world_position(v) - origin).as_vec3());
                let m = o.triangle_material.get(ti).copied().unwrap_or(0);
                let Some(mat) = scene.materials.get(m as usize) else {
                    degenerate += 1;
                    continue;
                };
                let scene_triangle = triangles.len() as u32;
                triangles.push(verts);
                transmittance.push(
                    o.transmittance
                        .get(ti)
                        .copied()
                        .unwrap_or(mat.transmittance),
                );
                // Degenerate: non-finite, or area below f32 resolution at this scale.
                let a = area(&verts);
                if !verts.iter().all(|p| p.is_finite()) || a.is_nan() || a <= scale * scale * 1e-14
                {
                    degenerate += 1;
                    continue;
                }
                let (rho, emission, was_clamped) = surface_values(mat, o, ti);
                clamped += was_clamped as usize;
                sources.push(Source {
                    verts,
                    region: 0,
                    cuts: 0..0,
                    covered: false,
                    scene_triangle,
                    triangle: ti as u32,
                    object: oi as u32,
                    material: m,
                    reflectance: rho,
                    emission,
                    double_sided: mat.double_sided,
                });
            }
        }
        if degenerate > 0 {
            warnings.push(format!(
                "{}: {degenerate} degenerate triangle(s) (zero area, non-finite or no material) receive no light",
                scene.name
            ));
        }
        if clamped > 0 {
            warnings.push(format!(
                "{}: reflectance above 0.999 clamped on {clamped} triangle(s)",
                scene.name
            ));
        }
        let total_area: f64 = sources.iter().map(|s| area(&s.verts) as f64).sum();
        let mut element_size = choose_element_size(&sources, total_area, settings, None);
        // D0 discontinuities: split each triangle along the lines where other surfaces
        // touch or pierce it; contacts shorter than half an element are finer than the
        // mesh and left to adaptive refinement. The element size is then chosen again for
        // the pieces, so an element budget still holds; when even one element per piece
        // would exceed it, the triangles stay whole.
        let mut cut_edges: Vec<[Vec3; 2]> = Vec::new();
        let mut bvh = None;
        let lights: Vec<Punctual> = if settings.shadow_lines {
            punctual_lights(&scene.lights, scene.environment.as_ref(), origin)
        } else {
            Vec::new()
        };
        if settings.contact_lines || !lights.is_empty() {
            let mut receivers = vec![false; triangles.len()];
            for s in &sources {
                receivers[s.scene_triangle as usize] = true;
            }
            let tol = scale * CONTACT_TOLERANCE;
            let min_len = (element_size * 0.5) as f32;
            let contacts = if settings.contact_lines {
                contact::find_cuts(&triangles, &receivers, tol, min_len)
            } else {
                contact::Contacts {
                    cuts: vec![Vec::new(); triangles.len()],
                    covers: vec![Vec::new(); triangles.len()],
                }
            };
            let mut cuts = contacts.cuts.clone();
            if !lights.is_empty() {
                let built = bvh.insert(crate::accel::Bvh::build(&triangles, &transmittance));
                let shadows = shadow::shadow_cuts(
                    &triangles,
                    &transmittance,
                    &receivers,
                    &lights,
                    &shadow::Lengths {
                        scale,
                        tol,
                        min_len,
                    },
                    built,
                );
                for (list, extra) in cuts.iter_mut().zip(shadows) {
                    for s in extra {
                        // Once: not again where a contact line runs (a box's foot
                        // casts its shadow from there too), nor where another
                        // silhouette edge's shadow already did.
                        let s2 = s.map(|p| p.as_dvec3());
                        let same = |o: &[Vec3; 2]| {
                            contact::same_segment(s2, o.map(|p| p.as_dvec3()), tol as f64)
                        };
                        if !list.iter().any(same) {
                            list.push(s);
                        }
                    }
                }
            }
            contact::carry_cut_ends(&triangles, &receivers, &mut cuts, tol as f64);
            let (mut pieces, edges, unsplit) =
                split_sources(&sources, &cuts, element_size * PATCH_PER_ELEMENT);
            // Pieces lying under a face pressed against them (a box's bottom, a flush
            // lamp) are hidden: not drawn (they would z-fight with that face).
            let mut any_covered = false;
            for p in pieces.iter_mut() {
                let c = (p.verts[0] + p.verts[1] + p.verts[2]) / 3.0;
                p.covered = p.emission.max_element() <= 0.0
                    && contact::is_covered(
                        c,
                        &contacts.covers[p.scene_triangle as usize],
                        &triangles,
                    );
                any_covered |= p.covered;
            }
            if unsplit > 0 {
                warnings.push(format!(
                    "{}: {unsplit} triangle(s) could not be split along their contact lines",
                    scene.name
                ));
            }
            if (pieces.len() > sources.len() || any_covered)
                && settings.max_elements.is_none_or(|b| sides(&pieces) <= b)
            {
                // The default budget stays that of the input triangles: splitting
                // along contacts refines where it cuts, and coarsens the rest a little,
                // rather than growing the mesh.
                element_size = choose_element_size(
                    &pieces,
                    total_area,
                    settings,
                    Some(default_budget(sides(&sources))),
                );
                sources = pieces;
                cut_edges = edges;
            }
        }
        let mut mesh = Mesh {
            origin,
            scale,
            patches: Vec::new(),
            elements: Vec::new(),
            nodes: Vec::new(),
            triangles,
            transmittance,
            display: DisplayMesh::default(),
            element_size,
            warnings,
            triangle_patches: Vec::new(),
            cut_edges,
        };
        mesh.triangle_patches = vec![0..0; mesh.triangles.len()];
        let patch_len = (element_size * PATCH_PER_ELEMENT) as f32;
        let mut pieces = Vec::new();
        for s in &sources {
            pieces.clear();
            split_patches(s.verts, patch_len, &mut pieces);
            for side in 0..if s.double_sided { 2 } else { 1 } {
                for p in &pieces {
                    let verts = if side == 0 { *p } else { [p[0], p[2], p[1]] };
                    mesh.push_patch(s, verts, side == 1, depth_for(area(p), element_size));
                }
            }
        }
        mesh.display =
            DisplayMesh::build(&mut mesh.elements, &mesh.patches, &mesh.cut_edges, scale);
        mesh.finish_triangle_ranges();
        (mesh, bvh)
    }

    fn push_patch(&mut self, s: &Source, verts: [Vec3; 3], back: bool, depth: u32) {
        let n = triangle_cross(&verts);
        let first = self.elements.len() as u32;
        let patch = self.patches.len() as u32;
        let root = self.push_node(verts, depth, patch, 0);
        self.patches.push(Patch {
            verts,
            normal: n.normalize_or_zero(),
            area: 0.5 * n.length(),
            scene_triangle: s.scene_triangle,
            triangle: s.triangle,
            object: s.object,
            material: s.material,
            back,
            reflectance: s.reflectance,
            emission: s.emission,
            elements: first..self.elements.len() as u32,
            root,
            region: s.region,
            cuts: s.cuts.clone(),
            covered: s.covered,
        });
    }

    fn push_node(&mut self, verts: [Vec3; 3], depth: u32, patch: u32, level: u8) -> u32 {
        let index = self.nodes.len() as u32;
        self.nodes.push(QuadNode {
            verts,
            children: None,
            element: None,
        });
        if depth == 0 {
            let n = triangle_cross(&verts);
            self.nodes[index as usize].element = Some(self.elements.len() as u32);
            self.elements.push(Element {
                verts,
                normal: n.normalize_or_zero(),
                area: 0.5 * n.length(),
                patch,
                level,
                corners: [0; 3],
            });
        } else {
            let kids = subdivide(&verts).map(|c| self.push_node(c, depth - 1, patch, level + 1));
            self.nodes[index as usize].children = Some(kids);
        }
        index
    }

    fn finish_triangle_ranges(&mut self) {
        let mut k = 0;
        while k < self.patches.len() {
            let t = self.patches[k].scene_triangle;
            let start = k;
            while k < self.patches.len() && self.patches[k].scene_triangle == t {
                k += 1;
            }
            self.triangle_patches[t as usize] = start as u32..k as u32;
        }
    }

    /// The element under point `x` (mesh frame, on scene triangle `triangle`) on the side
    /// whose normal has a positive dot product with `toward` (the direction back to an
    /// observer). `None` for the back of single-sided surfaces and degenerate triangles.
    pub fn element_at(&self, triangle: u32, x: Vec3, toward: Vec3) -> Option<u32> {
        let range = self.triangle_patches.get(triangle as usize)?.clone();
        let mut best: Option<(f32, u32)> = None;
        for p in range {
            let patch = &self.patches[p as usize];
            if patch.normal.dot(toward) <= 0.0 {
                continue;
            }
            let (q, _) = closest_point_on_triangle(x, &patch.verts);
            let d = (q - x).length_squared();
            if best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, p));
            }
        }
        let (_, p) = best?;
        // Descend the quadtree to the leaf whose triangle is nearest to x.
        let mut node = &self.nodes[self.patches[p as usize].root as usize];
        while let Some(children) = node.children {
            let mut best = (f32::INFINITY, children[0]);
            for c in children {
                let (q, _) = closest_point_on_triangle(x, &self.nodes[c as usize].verts);
                let d = (q - x).length_squared();
                if d < best.0 {
                    best = (d, c);
                }
            }
            node = &self.nodes[best.1 as usize];
        }
        node.element
    }

    /// The frame the mesh's f32 positions are stored in.
    pub fn frame(&self) -> Frame {
        Frame {
            origin: self.origin,
            scale: self.scale,
        }
    }

    /// Converts a world-space point to the mesh frame.
    pub fn to_local(&self, world: DVec3) -> Vec3 {
        self.frame().to_local(world)
    }

    /// Total area of all patches (both sides of double-sided surfaces counted), m².
    pub fn total_area(&self) -> f64 {
        self.patches.iter().map(|p| p.area as f64).sum()
    }

    /// Offset used to lift ray endpoints off surfaces ([`Frame::epsilon`]).
    pub fn epsilon(&self) -> f32 {
        self.frame().epsilon()
    }

    /// The element whose surface point is nearest to `p` (mesh frame) among elements facing
    /// the side `normal` asks about (element normal · `normal` > 0.5), with the barycentric
    /// coordinates of the nearest point. `None` if no element faces that way.
    pub fn locate(&self, p: Vec3, normal: Vec3) -> Option<(u32, [f32; 3])> {
        let n = normal.normalize_or_zero();
        let mut best: Option<(f32, u32, [f32; 3])> = None;
        for (i, e) in self.elements.iter().enumerate() {
            if e.normal.dot(n) <= 0.5 {
                continue;
            }
            let (q, bary) = closest_point_on_triangle(p, &e.verts);
            let d = (q - p).length_squared();
            if best.is_none_or(|(bd, _, _)| d < bd) {
                best = Some((d, i as u32, bary));
            }
        }
        best.map(|(_, i, b)| (i, b))
    }
}

/// Reflectance ρ (clamped to [0, 0.999]) and emitted radiosity E = π L_e of triangle `t`
/// of object `o` with material `mat`, and whether ρ had to be clamped.
pub fn surface_values(
    mat: &crate::scene::Material,
    o: &crate::scene::Object,
    t: usize,
) -> (Vec3, Vec3, bool) {
    let raw = mat.reflectance * o.reflectance_tint(t);
    let rho = sanitize(raw).min(Vec3::splat(0.999));
    let emission = sanitize(mat.emission * o.emission_tint(t)) * std::f32::consts::PI;
    (rho, emission, raw.max_element() > 0.999)
}

/// Negative and non-finite channels become 0.
pub(crate) fn sanitize(v: Vec3) -> Vec3 {
    Vec3::new(
        if v.x.is_finite() { v.x.max(0.0) } else { 0.0 },
        if v.y.is_finite() { v.y.max(0.0) } else { 0.0 },
        if v.z.is_finite() { v.z.max(0.0) } else { 0.0 },
    )
}

/// The sources cut along their contact segments (`cuts`, per scene triangle) into pieces
/// with edges up to about `max_len` (the patch length): the pieces (consecutive per
/// triangle, as the patch ranges need), the segments of the triangles that were split
/// (each piece's `cuts` is its triangle's), and how many triangles could not be split
/// (kept whole). Pieces thinner than
/// 1e-7 of their triangle's area are dropped (rounding slivers along a cut).
fn split_sources(
    sources: &[Source],
    cuts: &[Vec<[Vec3; 2]>],
    max_len: f64,
) -> (Vec<Source>, Vec<[Vec3; 2]>, usize) {
    use rayon::prelude::*;
    // Split in parallel (regions numbered from 0 per triangle), then number the regions.
    let splits: Vec<Option<Vec<contact::Piece>>> = sources
        .par_iter()
        .map(|s| {
            let c = &cuts[s.scene_triangle as usize];
            if c.is_empty() {
                None
            } else {
                Some(contact::split(s.verts, c, max_len).unwrap_or_default())
            }
        })
        .collect();
    let mut out = Vec::with_capacity(sources.len());
    let mut edges = Vec::new();
    let mut unsplit = 0;
    let mut next_region = 0u32;
    for (s, split) in sources.iter().zip(splits) {
        let split = match split {
            Some(pieces) if !pieces.is_empty() => pieces,
            failed => {
                unsplit += failed.is_some() as usize;
                out.push(Source {
                    region: next_region,
                    cuts: 0..0,
                    ..s.clone()
                });
                next_region += 1;
                continue;
            }
        };
        let a = area(&s.verts);
        let base = next_region;
        let first = edges.len() as u32;
        edges.extend_from_slice(&cuts[s.scene_triangle as usize]);
        let range = first..edges.len() as u32;
        for piece in split {
            next_region = next_region.max(base + piece.region + 1);
            if area(&piece.verts) <= a * 1e-7 {
                continue;
            }
            out.push(Source {
                verts: piece.verts,
                region: base + piece.region,
                cuts: range.clone(),
                ..s.clone()
            });
        }
    }
    (out, edges, unsplit)
}

/// Patch sides of `sources`: one per single-sided source, two per double-sided one (the
/// fewest elements they can have).
fn sides(sources: &[Source]) -> usize {
    sources
        .iter()
        .map(|s| if s.double_sided { 2 } else { 1 })
        .sum()
}

/// The element budget when none is given: [`DEFAULT_ELEMENTS`], or half as many elements
/// again as there are patch sides for large scenes, so their biggest triangles (floors,
/// walls) are still subdivided.
fn default_budget(sides: usize) -> usize {
    DEFAULT_ELEMENTS.max(sides + sides / 2)
}

/// The element size for `sources`: `settings.element_size`, or the largest size whose
/// element count fits the budget (`settings.max_elements`, else `default`, else
/// [`default_budget`] of these sources), never below one element per patch side.
fn choose_element_size(
    sources: &[Source],
    total_area: f64,
    settings: &MeshSettings,
    default: Option<usize>,
) -> f64 {
    if let Some(s) = settings.element_size.filter(|s| *s > 0.0) {
        return s;
    }
    if sources.is_empty() || total_area <= 0.0 {
        return 1.0;
    }
    // The coarsest mesh has one element per patch side; no budget can go below it.
    let coarsest = sides(sources);
    let budget = settings
        .max_elements
        .unwrap_or(default.unwrap_or(default_budget(coarsest)))
        .max(coarsest);
    if budget == coarsest {
        // Every triangle is one patch and one element: the size is that of the largest.
        return sources
            .iter()
            .map(|s| {
                (2.0 * area(&s.verts) as f64)
                    .sqrt()
                    .max(longest_edge(&s.verts).1 as f64 / PATCH_PER_ELEMENT)
            })
            .fold(0.0, f64::max);
    }
    // Bisection on log(size): count_elements is monotone non-increasing in size. Start
    // from the size that tiles the area with `budget` right isosceles triangles.
    let guess = (2.0 * total_area / budget as f64).sqrt();
    let (mut lo, mut hi) = (guess * 0.25, guess * 64.0);
    while count_elements(sources, hi) > budget && hi < 1e30 {
        hi *= 4.0;
    }
    for _ in 0..20 {
        let mid = (lo * hi).sqrt();
        if count_elements(sources, mid) > budget {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin;

    #[test]
    fn element_areas_sum_to_patch_and_scene_area() {
        let scene = builtin::cornell_box();
        let mesh = Mesh::build(&scene, &MeshSettings::default());
        for p in &mesh.patches {
            let sum: f32 = mesh.elements[p.elements.start as usize..p.elements.end as usize]
                .iter()
                .map(|e| e.area)
                .sum();
            // f32 sums of ≤ 4^12 terms: relative error well under 1e-4.
            assert!((sum - p.area).abs() <= 1e-4 * p.area, "{sum} vs {}", p.area);
        }
        assert!(mesh.elements.len() <= DEFAULT_ELEMENTS);
        assert!(
            mesh.elements.len() > DEFAULT_ELEMENTS / 8,
            "{}",
            mesh.elements.len()
        );
    }

    #[test]
    fn max_elements_is_respected() {
        let scene = builtin::cornell_box();
        for budget in [100, 500, 5000] {
            let mesh = Mesh::build(
                &scene,
                &MeshSettings {
                    max_elements: Some(budget),
                    ..Default::default()
                },
            );
            assert!(mesh.elements.len() <= budget);
        }
    }
}
