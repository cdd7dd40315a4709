//! Discretisation of a [`Scene`] into patches (shooters) and elements (receivers).
//!
//! Substructuring (Cohen, Greenberg, Immel & Brock, "An efficient radiosity approach for
//! realistic image synthesis", 1986): each input triangle is cut into *patches* by
//! longest-edge bisection until no edge exceeds the patch size and no element of a needle
//! is much longer than the element size (so slivers become chains of short patches instead
//! of huge quadtrees or elements as long as themselves), and each patch is the root of a
//! quadtree of *elements* made by midpoint subdivision. Patches shoot light, elements
//! receive it; the leaves of a patch's quadtree are stored contiguously so
//! `Patch::elements` is a range.
//!
//! Geometry is re-centred: `Mesh::origin` (f64, world) is subtracted from every position
//! before it is stored in f32, so a kilometre-sized scene a thousand kilometres from the
//! origin keeps millimetre precision.
//!
//! Double-sided materials give two patches per piece of surface, one per side, each with its
//! own radiosity; single-sided ones give one, on the front (counter-clockwise) side.
//!
//! This file owns the mesh's types and its queries. Building it is in stages (`build`):
//! sources, discontinuity lines (`contact`, `shadow`), split (`split`), element size
//! (`sizing`), emit (patches, quadtrees and the display mesh, `display`); its index
//! invariants are checked by [`Mesh::validate`] (`validate`).

mod adaptive;
mod build;
mod conforming;
mod contact;
mod display;
mod hanging;
mod hard_shadows;
mod patch_grid;
mod shadow;
mod sizing;
mod split;
mod texture;
mod validate;

pub use adaptive::{AdaptiveSettings, Moved, size as element_size};
pub use conforming::{Corner, TVertices};
pub use display::{
    Bezier, DisplayMesh, Hermite, Reconstruction, Reconstructor, ShadowSides, eval_bezier,
    luminance,
};
pub use hanging::Hanging;
pub use hard_shadows::LightTargets;
pub use patch_grid::PatchGrid;
pub use texture::{PatchTexture, barycentric};

use crate::accel::Bvh;
use crate::cancel::Cancelled;
use crate::geometry::{Frame, MIDDLE_CHILD, closest_point_on_triangle, triangle_area};
use crate::scene::Scene;
use glam::{DVec3, Vec3};
use std::ops::Range;
use std::sync::atomic::AtomicBool;

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

/// The least opacity a patch is given ([`Mesh::opacity`]): a fully clear pane still
/// reflects a thousandth, so that its irradiance H = (B − E) / ρ, which the display draws
/// under its texture, stays defined.
pub const MIN_OPACITY: f32 = 1e-3;

/// How close to a point, in ray offsets ([`Mesh::epsilon`]), a patch must come for
/// [`Mesh::element_at`] to take it without looking further.
const PATCH_REACH: f32 = 0.1;

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
    /// The element over display vertices `corners` at `positions`, of patch 0 at the top
    /// of its quadtree: for meshes built by hand (tests).
    pub fn over(positions: &[Vec3], corners: [u32; 3]) -> Element {
        let verts = corners.map(|c| positions[c as usize]);
        let cross = (verts[1] - verts[0]).cross(verts[2] - verts[0]);
        Element {
            verts,
            normal: cross.normalize(),
            area: 0.5 * cross.length(),
            patch: 0,
            level: 0,
            corners,
        }
    }

    /// Centroid in the mesh frame.
    pub fn centroid(&self) -> Vec3 {
        (self.verts[0] + self.verts[1] + self.verts[2]) / 3.0
    }

    /// `p` (mesh frame) projected onto the element's plane.
    pub fn project(&self, p: Vec3) -> Vec3 {
        p - self.normal * self.normal.dot(p - self.verts[0])
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
    /// Per patch, its texture coordinates and means for the display (`texture`); empty
    /// when the scene has no textures.
    pub textures: Vec<PatchTexture>,
    /// Which patches of a triangle cut into many may hold a point (`element_at`).
    pub patch_grid: PatchGrid,
}

impl Mesh {
    /// Meshes `scene` with `settings`. Degenerate (zero-area or non-finite) triangles are
    /// kept out of the patches (with one warning) but stay in the BVH if finite.
    pub fn build(scene: &Scene, settings: &MeshSettings) -> Mesh {
        Mesh::build_keeping_bvh(scene, settings).0
    }

    /// [`Mesh::build`], and the BVH of its scene triangles when meshing needed one (to
    /// find shadow lines), so the caller need not build it again.
    pub fn build_keeping_bvh(scene: &Scene, settings: &MeshSettings) -> (Mesh, Option<Bvh>) {
        match Mesh::build_cancellable(scene, settings, crate::cancel::never()) {
            Ok(built) => built,
            Err(Cancelled) => unreachable!("the never-raised cancel flag was raised"),
        }
    }

    /// [`Mesh::build_keeping_bvh`], stopped with `Err(Cancelled)` soon after `cancel` is
    /// raised: it is looked at between the stages (sources, discontinuity lines, split,
    /// element size, emit; see `build`) and inside the long ones.
    pub fn build_cancellable(
        scene: &Scene,
        settings: &MeshSettings,
        cancel: &AtomicBool,
    ) -> Result<(Mesh, Option<Bvh>), Cancelled> {
        let (mesh, bvh) = build::build(scene, settings, cancel)?;
        debug_assert_eq!(mesh.validate(), Ok(()), "{}: invalid mesh", scene.name);
        Ok((mesh, bvh))
    }

    /// Whether scene triangle `triangle` is double-sided (it has patches on its back).
    pub fn double_sided(&self, triangle: u32) -> bool {
        self.triangle_patches
            .get(triangle as usize)
            .is_some_and(|r| r.clone().any(|p| self.patches[p as usize].back))
    }

    /// The element under point `x` (mesh frame, on scene triangle `triangle`) on the side
    /// whose normal has a positive dot product with `toward` (the direction back to an
    /// observer). `None` for the back of single-sided surfaces and degenerate triangles.
    ///
    /// The triangle's patches on that side tile it, so the first one within a tenth of the
    /// ray offset ([`Mesh::epsilon`]) of `x` holds it (or borders it that closely), and the
    /// search stops there: a wall's triangle is cut into hundreds of patches, and going
    /// through all of them for each of the leaves' rays took 5 % of Sponza's solve. On a
    /// triangle cut into many, only the patches its [`PatchGrid`] lists near `x` are
    /// looked at first, which finds the same patch; where none of them is that close, all.
    pub fn element_at(&self, triangle: u32, x: Vec3, toward: Vec3) -> Option<u32> {
        let range = self.triangle_patches.get(triangle as usize)?.clone();
        let inside = (PATCH_REACH * self.epsilon()).powi(2);
        let near = self
            .patch_grid
            .near(triangle, &self.triangles[triangle as usize], x)
            .and_then(|near| self.nearest_patch(near.iter().copied(), x, toward, inside))
            .filter(|(d, _)| *d <= inside);
        let (_, p) = near.or_else(|| self.nearest_patch(range, x, toward, inside))?;
        self.element_in_patch(p, x)
    }

    /// The element of patch `p` that holds `x` (or its projection on the patch).
    fn element_in_patch(&self, p: u32, x: Vec3) -> Option<u32> {
        let root = &self.nodes[self.patches[p as usize].root as usize];
        let (_, bary) = closest_point_on_triangle(x, &root.verts);
        self.leaf_at(root, bary.map(f64::from))
    }

    /// Among `patches`, those facing `toward`: the first within squared distance `inside`
    /// of `x`, or else the nearest; with its squared distance.
    fn nearest_patch(
        &self,
        patches: impl Iterator<Item = u32>,
        x: Vec3,
        toward: Vec3,
        inside: f32,
    ) -> Option<(f32, u32)> {
        let mut best: Option<(f32, u32)> = None;
        for p in patches {
            let patch = &self.patches[p as usize];
            if patch.normal.dot(toward) <= 0.0 {
                continue;
            }
            let (q, _) = closest_point_on_triangle(x, &patch.verts);
            let d = (q - x).length_squared();
            if best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, p));
                if d <= inside {
                    break;
                }
            }
        }
        best
    }

    /// The element of the quadtree leaf under `node` that holds the point at barycentric
    /// coordinates `bary` of `node`'s triangle. Every split is `geometry::subdivide`'s, so
    /// each level is a choice by the coordinates, which are then taken into the child: a
    /// corner child where one is at least ½ ((2u − 1, 2v, 2w) for the first), otherwise
    /// the middle one, [ab, bc, ca], whose coordinates are (u + v − w, v + w − u, u + w − v).
    /// A point on a child's edge goes to either side. In f64 the steps add no rounding of
    /// their own: the leaf holds the point to within the f32 rounding of its coordinates in
    /// the root.
    fn leaf_at<'a>(
        &'a self,
        mut node: &'a QuadNode,
        [mut u, mut v, mut w]: [f64; 3],
    ) -> Option<u32> {
        while let Some(kids) = node.children {
            let k = if u >= 0.5 {
                (u, v, w) = (2.0 * u - 1.0, 2.0 * v, 2.0 * w);
                0
            } else if v >= 0.5 {
                (u, v, w) = (2.0 * u, 2.0 * v - 1.0, 2.0 * w);
                1
            } else if w >= 0.5 {
                (u, v, w) = (2.0 * u, 2.0 * v, 2.0 * w - 1.0);
                2
            } else {
                (u, v, w) = (u + v - w, v + w - u, u + w - v);
                MIDDLE_CHILD
            };
            node = &self.nodes[kids[k] as usize];
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

    /// The share of patch `patch`'s area that reflects and emits: 1 − τ, with τ the
    /// transmittance of its scene triangle (an alpha cut-out's uncovered share, glass's
    /// transmission), at least [`MIN_OPACITY`]. A shadow ray passes such a triangle with
    /// τ (`Bvh::transmittance`), and the unbiased reference lets a path through with
    /// probability τ and reflects it otherwise; so the power a patch sends per unit of
    /// its area is (1 − τ) times the radiosity of its covered part. The solvers transport
    /// that (their ρ and E are the patch's times its opacity); the radiosity a probe or
    /// the display reports at a point is the covered part's.
    pub fn opacity(&self, patch: &Patch) -> f32 {
        let tau = self
            .transmittance
            .get(patch.scene_triangle as usize)
            .copied()
            .unwrap_or(0.0);
        if tau.is_finite() {
            (1.0 - tau).clamp(MIN_OPACITY, 1.0)
        } else {
            1.0
        }
    }

    /// Offset used to lift ray endpoints off surfaces ([`Frame::epsilon`]).
    pub fn epsilon(&self) -> f32 {
        self.frame().epsilon()
    }

    /// The element whose surface point is nearest to `p` (mesh frame) among elements facing
    /// the side `normal` asks about (normal · `normal` > 0.5), with the barycentric
    /// coordinates of the nearest point. `None` if no element faces that way.
    ///
    /// The nearest patch first, then the nearest of its elements: a patch is the union of
    /// its elements, so this is the nearest element overall.
    pub fn locate(&self, p: Vec3, normal: Vec3) -> Option<(u32, [f32; 3])> {
        self.locate_patch(p, normal)
            .map(|patch| self.locate_in_patch(p, patch))
    }

    /// The patch whose surface point is nearest to `p` among those facing `normal` (see
    /// [`Mesh::locate`]). Refinement splits elements but never patches, so a caller that
    /// looks up the same points in a mesh that refines can keep these.
    pub fn locate_patch(&self, p: Vec3, normal: Vec3) -> Option<u32> {
        let n = normal.normalize_or_zero();
        let mut best: Option<(f32, u32)> = None;
        for (i, patch) in self.patches.iter().enumerate() {
            if patch.normal.dot(n) <= 0.5 || patch.elements.is_empty() {
                continue;
            }
            let (q, _) = closest_point_on_triangle(p, &patch.verts);
            let d = (q - p).length_squared();
            if best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, i as u32));
            }
        }
        best.map(|(_, i)| i)
    }

    /// The element of `patch` whose surface point is nearest to `p`, with the barycentric
    /// coordinates of that point.
    pub fn locate_in_patch(&self, p: Vec3, patch: u32) -> (u32, [f32; 3]) {
        let mut best = (
            f32::INFINITY,
            self.patches[patch as usize].elements.start,
            [1.0, 0.0, 0.0],
        );
        for i in self.patches[patch as usize].elements.clone() {
            let (q, bary) = closest_point_on_triangle(p, &self.elements[i as usize].verts);
            let d = (q - p).length_squared();
            if d < best.0 {
                best = (d, i, bary);
            }
        }
        (best.1, best.2)
    }
}

/// One scene triangle as every light-transport stage reads it (the mesher's sources, the
/// path-traced reference's surfaces): its corners in the scene's frame, its material and
/// transmittance, and whether it is too degenerate to receive light.
pub struct SceneTriangle<'a> {
    pub verts: [Vec3; 3],
    pub material: u32,
    pub mat: &'a crate::scene::Material,
    /// Fraction of a shadow ray it lets through (alpha cut-outs, glass).
    pub transmittance: f32,
    /// Non-finite, or an area below f32 resolution at the frame's scale: it blocks rays
    /// but receives no light.
    pub degenerate: bool,
}

/// Triangle `t` of object `o` in `frame`; `None` when its material does not exist (such a
/// triangle neither blocks nor receives light).
pub fn scene_triangle<'a>(
    scene: &'a Scene,
    o: &crate::scene::Object,
    t: usize,
    frame: &Frame,
) -> Option<SceneTriangle<'a>> {
    let verts = o.triangles[t].map(|v| frame.to_local(o.world_position(v)));
    let material = o.triangle_material.get(t).copied().unwrap_or(0);
    let mat = scene.materials.get(material as usize)?;
    let transmittance = o.transmittance.get(t).copied().unwrap_or(mat.transmittance);
    let a = triangle_area(&verts);
    let scale = frame.scale;
    let degenerate =
        !verts.iter().all(|p| p.is_finite()) || a.is_nan() || a <= scale * scale * 1e-14;
    Some(SceneTriangle {
        verts,
        material,
        mat,
        transmittance,
        degenerate,
    })
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin;

    /// Brute force: at points drawn inside every patch of a Cornell box split four levels
    /// deep, `element_at` (which descends the quadtree by barycentric coordinates) returns
    /// an element of that patch whose triangle holds the point, within f32 rounding of the
    /// box's size (10⁻⁶ of 0.55 m).
    #[test]
    fn element_at_finds_the_leaf_that_holds_the_point() {
        let scene = builtin::cornell_box();
        let mut mesh = Mesh::build(&scene, &MeshSettings::default());
        // Four rounds of splitting a third of the elements (and what 2:1 balance adds).
        for _ in 0..4 {
            let mut marked: Vec<bool> = (0..mesh.elements.len()).map(|e| e % 3 == 0).collect();
            mesh.balance(&mut marked);
            mesh.refine(&marked);
        }
        let deepest = mesh.elements.iter().map(|e| e.level).max();
        assert!(deepest >= Some(4), "{deepest:?}");
        let mut k = 0u64;
        for (p, patch) in mesh.patches.iter().enumerate() {
            for _ in 0..16 {
                k += 1;
                use crate::geometry::sampling::{hash, point_in_triangle, unit};
                let x = point_in_triangle(&patch.verts, unit(hash(k)), unit(hash(k ^ 0x5eed)));
                let e = mesh
                    .element_at(patch.scene_triangle, x, patch.normal)
                    .unwrap();
                let element = &mesh.elements[e as usize];
                assert_eq!(element.patch as usize, p);
                let (q, _) = closest_point_on_triangle(x, &element.verts);
                assert!(
                    q.distance(x) <= 1e-6 * 0.55,
                    "patch {p}: {x} is {} off",
                    q.distance(x)
                );
            }
        }
    }

    /// The patch grid only narrows the search: on triangles cut into many patches,
    /// points inside patches, on their corners and edges, just off them and off the
    /// triangle find what the scan of all the triangle's patches finds.
    #[test]
    fn element_at_with_the_patch_grid_finds_what_the_full_scan_finds() {
        use crate::geometry::sampling::{hash, point_in_triangle, unit};
        let scene = builtin::cornell_box();
        let mesh = Mesh::build(
            &scene,
            &MeshSettings {
                element_size: Some(0.01),
                ..Default::default()
            },
        );
        let gridded: Vec<usize> = (0..mesh.triangles.len())
            .filter(|&t| mesh.patch_grid.covers(t))
            .collect();
        assert!(
            gridded.len() >= 10,
            "{} triangles have a grid",
            gridded.len()
        );
        let scan = |t: usize, x: Vec3, toward: Vec3| {
            let range = mesh.triangle_patches[t].clone();
            let inside = (PATCH_REACH * mesh.epsilon()).powi(2);
            mesh.nearest_patch(range, x, toward, inside).map(|(_, p)| p)
        };
        let eps = mesh.epsilon();
        let (mut k, mut checked) = (0u64, 0);
        for &t in &gridded {
            for p in mesh.triangle_patches[t].clone() {
                let patch = &mesh.patches[p as usize];
                let [a, b, c] = patch.verts;
                k += 1;
                let off = Vec3::new(unit(hash(k)), unit(hash(k ^ 1)), unit(hash(k ^ 2))) - 0.5;
                let points = [
                    point_in_triangle(&patch.verts, unit(hash(k ^ 3)), unit(hash(k ^ 4))),
                    a,
                    (a + b) * 0.5,
                    (b + c) * 0.5 + off * (0.1 * eps),
                    c + off * eps,
                    a + (a - c) * 0.3,
                ];
                for x in points {
                    for toward in [patch.normal, -patch.normal] {
                        let got = mesh.element_at(t as u32, x, toward);
                        let want = scan(t, x, toward).and_then(|p| mesh.element_in_patch(p, x));
                        assert_eq!(got, want, "triangle {t}, patch {p}, point {x}");
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 1000, "{checked}");
    }

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
