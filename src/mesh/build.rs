//! `Mesh::build` as a sequence of stages: [`sources`] (the scene's triangles in the mesh
//! frame, degenerate ones dropped) → [`discontinuity_lines`] (contact and shadow lines) →
//! [`split`] (the triangles cut along them) → [`element_size`] (the size for the budget,
//! and whether the split is kept) → [`emit`] (patches, element quadtrees, display mesh).
//! [`build`] runs them, looking at the cancel flag between stages; the long stages look
//! at it inside too.

use super::PATCH_REACH;
use super::sizing::{
    PATCH_PER_ELEMENT, choose_element_size, default_budget, depth_for, sides, source_sides,
    split_patches,
};
use super::{
    DisplayMesh, Element, Mesh, MeshSettings, Patch, PatchGrid, QuadNode, contact, shadow,
};
use super::{scene_triangle, split as cdt, surface_values};
use crate::accel::Bvh;
use crate::cancel::{Cancelled, check};
use crate::geometry::{subdivide, triangle_area as area, triangle_cross};
use crate::light::{Punctual, punctual_lights};
use crate::scene::Scene;
use glam::{DVec3, Vec3};
use std::ops::Range;
use std::sync::atomic::AtomicBool;

/// Surfaces closer than this fraction of the scene's diagonal count as touching (contact
/// lines, `contact`): 0.2 mm in a 1 m box, where the Cornell box's light hangs 0.1 mm
/// under the ceiling.
const CONTACT_TOLERANCE: f32 = 2e-4;

/// Sources emitted between two looks at the cancel flag.
const SOURCES_PER_CHECK: usize = 256;

/// An input triangle in the mesh frame with everything the patches need.
#[derive(Clone)]
pub(super) struct Source {
    pub(super) verts: [Vec3; 3],
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
    pub(super) double_sided: bool,
}

/// The scene in the mesh frame: what [`sources`] makes.
struct Input {
    /// World position of the mesh frame's origin and the scene's diagonal (see `Mesh`).
    origin: DVec3,
    scale: f32,
    /// All scene triangles (the BVH's input) and their transmittance.
    triangles: Vec<[Vec3; 3]>,
    transmittance: Vec<f32>,
    /// The triangles that get patches, one source each.
    sources: Vec<Source>,
    warnings: Vec<String>,
}

/// What [`discontinuity_lines`] finds.
struct Lines {
    /// Per scene triangle, the segments to split it along: contact and shadow lines,
    /// merged, with the cut ends carried to the neighbours across an edge.
    cuts: Vec<Vec<[Vec3; 2]>>,
    /// Per scene triangle, the faces lying against its front (see `contact::Contacts`).
    covers: Vec<Vec<u32>>,
    /// The BVH built to find the shadow lines, if there were punctual lights.
    bvh: Option<Bvh>,
    /// Per scene triangle, whether short contact pieces are among its cuts (see
    /// `contact::Contacts`).
    outlined: Vec<bool>,
}

/// What [`element_size`] settles on: the sources to emit, the contact segments their
/// `cuts` index, and the element size.
struct Sized {
    sources: Vec<Source>,
    cut_edges: Vec<[Vec3; 2]>,
    element_size: f64,
}

/// What [`split`] makes of the sources.
struct Split {
    /// The pieces, consecutive per triangle; their `cuts` index `edges`.
    pieces: Vec<Source>,
    /// The segments of the triangles that were split.
    edges: Vec<[Vec3; 2]>,
    /// Whether some piece is hidden under a face pressed against it.
    any_covered: bool,
}

/// Meshes `scene` (see [`Mesh::build`]) and returns the BVH built on the way, if any;
/// `Err(Cancelled)` as soon as a look at `cancel` finds it raised.
pub(super) fn build(
    scene: &Scene,
    settings: &MeshSettings,
    cancel: &AtomicBool,
) -> Result<(Mesh, Option<Bvh>), Cancelled> {
    check(cancel)?;
    let mut input = sources(scene, cancel)?;
    let total_area: f64 = input.sources.iter().map(|s| area(&s.verts) as f64).sum();
    // A first size for the whole triangles: the shortest discontinuity line split along
    // and the length of the split's pieces follow from it. The size is chosen again for
    // the pieces, so an element budget still holds; when even one element per piece
    // would exceed it, the triangles stay whole.
    let first_size = choose_element_size(&input.sources, total_area, settings, None, cancel)?;
    check(cancel)?;
    let whole = |input: &mut Input| Sized {
        sources: std::mem::take(&mut input.sources),
        cut_edges: Vec::new(),
        element_size: first_size,
    };
    let (sized, bvh) = match discontinuity_lines(scene, settings, &input, first_size, cancel)? {
        None => (whole(&mut input), None),
        Some(lines) => {
            check(cancel)?;
            let pieces = split(&scene.name, &mut input, &lines, first_size, cancel)?;
            check(cancel)?;
            let sizes = (first_size, &lines.outlined[..]);
            let kept = element_size(&input.sources, &pieces, total_area, sizes, settings, cancel)?;
            let sized = match kept {
                Some(element_size) => Sized {
                    sources: pieces.pieces,
                    cut_edges: pieces.edges,
                    element_size,
                },
                None => whole(&mut input),
            };
            (sized, lines.bvh)
        }
    };
    check(cancel)?;
    let mut mesh = emit(input, sized, cancel)?;
    mesh.textures = super::texture::patch_textures(&mesh, scene);
    Ok((mesh, bvh))
}

/// Stage 1, sources: every scene triangle moved into the mesh frame (origin at the
/// centre of the scene's bounds, f32) for the BVH, and a [`Source`] with its reflectance
/// and emission for each one that gets patches. Degenerate triangles (non-finite, area
/// below f32 resolution at the scene's scale, or no material) get none, with one warning
/// for all of them; clamped reflectances get one too.
fn sources(scene: &Scene, cancel: &AtomicBool) -> Result<Input, Cancelled> {
    let frame = scene.frame();
    let (origin, scale) = (frame.origin, frame.scale);
    let mut warnings = Vec::new();
    let mut triangles = Vec::with_capacity(scene.triangle_count());
    let mut transmittance = Vec::with_capacity(scene.triangle_count());
    let mut sources = Vec::new();
    let (mut degenerate, mut clamped) = (0usize, 0usize);
    for (oi, o) in scene.objects.iter().enumerate() {
        check(cancel)?;
        for ti in 0..o.triangles.len() {
            let Some(st) = scene_triangle(scene, o, ti, &frame) else {
                degenerate += 1;
                continue;
            };
            let (verts, m, mat) = (st.verts, st.material, st.mat);
            let scene_triangle = triangles.len() as u32;
            triangles.push(verts);
            transmittance.push(st.transmittance);
            if st.degenerate {
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
    Ok(Input {
        origin,
        scale,
        triangles,
        transmittance,
        sources,
        warnings,
    })
}

/// Stage 2, discontinuity lines (D0): where other surfaces touch or pierce each source
/// (contact lines, when `settings.contact_lines`) and where the hard shadows of punctual
/// lights and the sun fall on it (shadow lines, when `settings.shadow_lines`). Lines
/// shorter than half an element (of `size`, the size chosen for the whole triangles) are
/// finer than the mesh and left to adaptive refinement. `None` when neither kind is
/// looked for.
fn discontinuity_lines(
    scene: &Scene,
    settings: &MeshSettings,
    input: &Input,
    size: f64,
    cancel: &AtomicBool,
) -> Result<Option<Lines>, Cancelled> {
    let lights: Vec<Punctual> = if settings.shadow_lines {
        punctual_lights(&scene.lights, scene.environment.as_ref(), input.origin)
    } else {
        Vec::new()
    };
    if !settings.contact_lines && lights.is_empty() {
        return Ok(None);
    }
    let triangles = &input.triangles;
    let mut receivers = vec![false; triangles.len()];
    let mut two_sided = vec![false; triangles.len()];
    for s in &input.sources {
        receivers[s.scene_triangle as usize] = true;
        two_sided[s.scene_triangle as usize] |= s.double_sided;
    }
    let tol = input.scale * CONTACT_TOLERANCE;
    let min_len = (size * 0.5) as f32;
    let contacts = if settings.contact_lines {
        contact::find_cuts(triangles, &receivers, &two_sided, tol, min_len, cancel)?
    } else {
        contact::Contacts {
            cuts: vec![Vec::new(); triangles.len()],
            covers: vec![Vec::new(); triangles.len()],
            outlined: vec![false; triangles.len()],
        }
    };
    let mut cuts = contacts.cuts;
    let mut bvh = None;
    if !lights.is_empty() {
        let lengths = shadow::Lengths {
            scale: input.scale,
            tol,
            min_len,
        };
        let built = shadow_lines(input, &receivers, &lights, &lengths, &mut cuts, cancel)?;
        bvh = Some(built);
    }
    check(cancel)?;
    contact::carry_cut_ends(triangles, &receivers, &mut cuts, tol as f64);
    Ok(Some(Lines {
        cuts,
        covers: contacts.covers,
        bvh,
        outlined: contacts.outlined,
    }))
}

/// The shadow lines of `lights` on the `receivers`, merged into `cuts` (each segment
/// once: not again where a contact line runs, nor where another silhouette edge's shadow
/// already lies). Builds the BVH the shadow rays need and returns it.
fn shadow_lines(
    input: &Input,
    receivers: &[bool],
    lights: &[Punctual],
    lengths: &shadow::Lengths,
    cuts: &mut [Vec<[Vec3; 2]>],
    cancel: &AtomicBool,
) -> Result<Bvh, Cancelled> {
    check(cancel)?;
    let bvh = Bvh::build(&input.triangles, &input.transmittance);
    check(cancel)?;
    let shadows = shadow::shadow_cuts(
        &input.triangles,
        &input.transmittance,
        receivers,
        lights,
        lengths,
        &bvh,
        cancel,
    )?;
    let tol = lengths.tol as f64;
    for (list, extra) in cuts.iter_mut().zip(shadows) {
        for s in extra {
            // Once: not again where a contact line runs (a box's foot casts its shadow
            // from there too), nor where another silhouette edge's shadow already did.
            let s2 = s.map(|p| p.as_dvec3());
            let same = |o: &[Vec3; 2]| contact::same_segment(s2, o.map(|p| p.as_dvec3()), tol);
            if !list.iter().any(same) {
                list.push(s);
            }
        }
    }
    Ok(bvh)
}

/// Stage 3, split: each source cut along its triangle's lines into pieces about a patch
/// long (for the element `size` of the whole triangles), pieces under a face pressed
/// against them marked covered (a box's bottom, a flush lamp: hidden and not drawn, or
/// they would z-fight with that face). Triangles whose triangulation fails stay whole,
/// with a warning in `input.warnings` (naming the scene `name`).
fn split(
    name: &str,
    input: &mut Input,
    lines: &Lines,
    size: f64,
    cancel: &AtomicBool,
) -> Result<Split, Cancelled> {
    let (mut split, unsplit) = split_sources(
        &input.sources,
        &lines.cuts,
        size * PATCH_PER_ELEMENT,
        cancel,
    )?;
    for p in split.pieces.iter_mut() {
        let c = (p.verts[0] + p.verts[1] + p.verts[2]) / 3.0;
        p.covered = p.emission.max_element() <= 0.0
            && contact::is_covered(
                c,
                &lines.covers[p.scene_triangle as usize],
                &input.triangles,
            );
        split.any_covered |= p.covered;
    }
    if unsplit > 0 {
        input.warnings.push(format!(
            "{}: {unsplit} triangle(s) could not be split along their contact lines",
            name
        ));
    }
    Ok(split)
}

/// Stage 4, element size: keeps the split when it cut something (more pieces than
/// sources, or some covered) and one element per piece still fits `settings.max_elements`,
/// and chooses the element size for the pieces then. The default budget stays that of the
/// whole triangles: splitting along contacts refines where it cuts, and coarsens the rest
/// a little, rather than growing the mesh. Except for the pieces of the triangles cut
/// along outlines of short contact pieces (`outlined`, see
/// `contact::outlines_long_enough`): each of their pieces smaller than an element at
/// `first_size` (the size chosen for the whole triangles) that the split added is one
/// element more in the budget. The contact circle of a tessellated sphere sunk into a
/// floor is ~100 chords of 1.5 cm, and taken from the budget its pieces coarsened all of
/// `cornell-box-nvpro`'s elements by 14 % (and, with single-sided outlines chained too,
/// Sponza's by 48 %). `None` when the split is not kept: the triangles stay whole, with
/// the size chosen for them.
fn element_size(
    sources: &[Source],
    split: &Split,
    total_area: f64,
    (first_size, outlined): (f64, &[bool]),
    settings: &MeshSettings,
    cancel: &AtomicBool,
) -> Result<Option<f64>, Cancelled> {
    let pieces = &split.pieces;
    if (pieces.len() > sources.len() || split.any_covered)
        && settings.max_elements.is_none_or(|b| sides(pieces) <= b)
    {
        // Sides of the outlined triangles' pieces smaller than one element (a right
        // isosceles triangle whose legs are `first_size` long).
        let small = |of: &[Source]| -> usize {
            let one = 0.5 * first_size * first_size;
            of.iter()
                .filter(|s| outlined[s.scene_triangle as usize])
                .filter(|s| (area(&s.verts) as f64) < one)
                .map(source_sides)
                .sum()
        };
        let added = small(pieces).saturating_sub(small(sources));
        let default = Some(default_budget(sides(sources)) + added);
        choose_element_size(pieces, total_area, settings, default, cancel).map(Some)
    } else {
        Ok(None)
    }
}

/// Stage 5, emit: each source cut into patches by longest-edge bisection (no longer than
/// [`PATCH_PER_ELEMENT`] element sizes, needles cut by their length: `split_patches`),
/// one per side (front, then back for double-sided materials), each the root of an
/// element quadtree deep enough for the element size; then the display mesh and the per-triangle patch ranges. Looks at
/// `cancel` every [`SOURCES_PER_CHECK`] sources.
fn emit(input: Input, sized: Sized, cancel: &AtomicBool) -> Result<Mesh, Cancelled> {
    let Sized {
        sources,
        cut_edges,
        element_size,
    } = sized;
    let scale = input.scale;
    let mut mesh = Mesh {
        origin: input.origin,
        scale,
        patches: Vec::new(),
        elements: Vec::new(),
        nodes: Vec::new(),
        triangle_patches: vec![0..0; input.triangles.len()],
        triangles: input.triangles,
        transmittance: input.transmittance,
        display: DisplayMesh::default(),
        element_size,
        warnings: input.warnings,
        cut_edges,
        textures: Vec::new(),
        patch_grid: PatchGrid::default(),
    };
    let mut pieces = Vec::new();
    for (k, s) in sources.iter().enumerate() {
        if k % SOURCES_PER_CHECK == 0 {
            check(cancel)?;
        }
        pieces.clear();
        split_patches(s.verts, element_size, &mut pieces);
        for side in 0..if s.double_sided { 2 } else { 1 } {
            for p in &pieces {
                let verts = if side == 0 { *p } else { [p[0], p[2], p[1]] };
                mesh.push_patch(s, verts, side == 1, depth_for(area(p), element_size));
            }
        }
    }
    check(cancel)?;
    mesh.display = DisplayMesh::build(&mut mesh.elements, &mesh.patches, &mesh.cut_edges, scale);
    mesh.finish_triangle_ranges();
    Ok(mesh)
}

/// The sources cut along their contact segments (`cuts`, per scene triangle) into pieces
/// with edges up to about `max_len` (the patch length): the pieces (consecutive per
/// triangle, as the patch ranges need), the segments of the triangles that were split
/// (each piece's `cuts` is its triangle's), and how many triangles could not be split
/// (kept whole; none covered yet). Pieces thinner than 1e-7 of their triangle's area are
/// dropped (rounding slivers along a cut). Looks at `cancel` before each triangulation.
fn split_sources(
    sources: &[Source],
    cuts: &[Vec<[Vec3; 2]>],
    max_len: f64,
    cancel: &AtomicBool,
) -> Result<(Split, usize), Cancelled> {
    use rayon::prelude::*;
    // Split in parallel (regions numbered from 0 per triangle), then number the regions.
    let splits: Vec<Option<Vec<cdt::Piece>>> = sources
        .par_iter()
        .map(|s| {
            let c = &cuts[s.scene_triangle as usize];
            if c.is_empty() {
                Ok(None)
            } else {
                check(cancel)?;
                Ok(Some(cdt::split(s.verts, c, max_len).unwrap_or_default()))
            }
        })
        .collect::<Result<_, Cancelled>>()?;
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
    let split = Split {
        pieces: out,
        edges,
        any_covered: false,
    };
    Ok((split, unsplit))
}

impl Mesh {
    /// Appends the patch `verts` of source `s` (its `back` side when `back`) and its
    /// element quadtree, `depth` levels deep.
    fn push_patch(&mut self, s: &Source, verts: [Vec3; 3], back: bool, depth: u32) {
        let n = triangle_cross(&verts);
        let normal = self.piece_normal(s.scene_triangle, n, back);
        let first = self.elements.len() as u32;
        let patch = self.patches.len() as u32;
        let root = self.push_node(verts, depth, patch, 0, normal);
        self.patches.push(Patch {
            verts,
            normal,
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

    /// The normal of a patch whose vertices' cross product is `n`, cut from scene triangle
    /// `t` (its `back` side when `back`): the scene triangle's own. A piece cut off along
    /// a contact line can be a sliver of 10⁻¹⁰ m² whose three corners are nearly in line,
    /// and the cross product of those corners points anywhere: on `cornell-box-nvpro`,
    /// slivers of a white sphere's inside where it meets the floor had normals lying
    /// flat, so their rays started outside the sphere and let the light of the floor
    /// into it (its inside, sealed, came to half the outside's light at ρ = 0.999).
    /// A degenerate scene triangle falls back to `n`.
    fn piece_normal(&self, t: u32, n: Vec3, back: bool) -> Vec3 {
        let whole = triangle_cross(&self.triangles[t as usize]).normalize_or_zero();
        match (whole == Vec3::ZERO, back) {
            (true, _) => n.normalize_or_zero(),
            (false, false) => whole,
            (false, true) => -whole,
        }
    }

    /// Appends the quadtree node `verts` of `patch` at `level`, and below it `depth`
    /// levels of midpoint subdivision with an element at each leaf, each with the patch's
    /// `normal`; returns its index.
    fn push_node(
        &mut self,
        verts: [Vec3; 3],
        depth: u32,
        patch: u32,
        level: u8,
        normal: Vec3,
    ) -> u32 {
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
                normal,
                area: 0.5 * n.length(),
                patch,
                level,
                corners: [0; 3],
            });
        } else {
            let kids =
                subdivide(&verts).map(|c| self.push_node(c, depth - 1, patch, level + 1, normal));
            self.nodes[index as usize].children = Some(kids);
        }
        index
    }

    /// Sets `triangle_patches` from the patches, which come consecutive per triangle, and
    /// the grids of those cut into many (`patch_grid`).
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
        let patches = &self.patches;
        self.patch_grid = PatchGrid::build(
            &self.triangles,
            &self.triangle_patches,
            |p| patches[p as usize].verts,
            PATCH_REACH * self.epsilon(),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cancel::never;
    use crate::scene::builtin;

    /// A raised flag stops the whole build, and each long stage on its own.
    #[test]
    fn a_raised_flag_stops_every_long_stage() {
        let raised = AtomicBool::new(true);
        let scene = builtin::by_name("cornell").expect("built-in Cornell box");
        let settings = MeshSettings::default();
        assert!(matches!(
            Mesh::build_cancellable(&scene, &settings, &raised),
            Err(Cancelled)
        ));
        let input = sources(&scene, never()).unwrap();
        let receivers = vec![true; input.triangles.len()];
        let tol = input.scale * CONTACT_TOLERANCE;
        assert!(
            contact::find_cuts(&input.triangles, &receivers, &receivers, tol, 0.01, &raised)
                .is_err()
        );
        let lights = [Punctual::Direction(Vec3::new(0.3, -1.0, 0.2).normalize())];
        let lengths = shadow::Lengths {
            scale: input.scale,
            tol,
            min_len: 0.01,
        };
        let mut cuts = vec![Vec::new(); input.triangles.len()];
        assert!(shadow_lines(&input, &receivers, &lights, &lengths, &mut cuts, &raised).is_err());
        let bvh = Bvh::build(&input.triangles, &input.transmittance);
        let shadows = shadow::shadow_cuts(
            &input.triangles,
            &input.transmittance,
            &receivers,
            &lights,
            &lengths,
            &bvh,
            &raised,
        );
        assert!(shadows.is_err());
        let lines = discontinuity_lines(&scene, &settings, &input, 0.05, never())
            .unwrap()
            .expect("contact lines");
        assert!(lines.cuts.iter().any(|c| !c.is_empty()));
        assert!(split_sources(&input.sources, &lines.cuts, 0.2, &raised).is_err());
        assert!(choose_element_size(&input.sources, 1.0, &settings, None, &raised).is_err());
        let sized = Sized {
            sources: input.sources.clone(),
            cut_edges: Vec::new(),
            element_size: 0.05,
        };
        assert!(emit(input, sized, &raised).is_err());
    }

    /// The never-raised flag gives the same mesh as the plain build.
    #[test]
    fn building_with_a_flag_that_stays_down_matches_the_plain_build() {
        let scene = builtin::by_name("cornell").expect("built-in Cornell box");
        let settings = MeshSettings::default();
        let down = AtomicBool::new(false);
        let (a, _) = Mesh::build_cancellable(&scene, &settings, &down).unwrap();
        let b = Mesh::build(&scene, &settings);
        assert_eq!(a.elements.len(), b.elements.len());
        assert_eq!(a.patches.len(), b.patches.len());
        assert_eq!(a.element_size, b.element_size);
        assert!(
            a.elements
                .iter()
                .zip(&b.elements)
                .all(|(x, y)| x.verts == y.verts)
        );
    }
}
