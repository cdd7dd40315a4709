//! Long thin triangles under the light, as the walls of Sponza are modelled (fans of
//! triangles metres long and centimetres wide): the Gouraud picture must show the light,
//! not the triangles.
//!
//! Where two triangles meet, every vertex one side's refinement puts on the shared edge
//! must hang at the midpoint of the other side's edge (2:1 balance across the edge).
//! Otherwise the display takes a value there, fitted to one side's elements alone, that
//! the other side does not: a line along the edge, dark or bright, and a spot where it
//! ends.
//!
//! The scene is `common::opening`'s floor under a square opening to the sky, whose light
//! has a closed form (Howell's C-11, `analytic::parallel_square`), with the floor cut into
//! a fan.

mod common;

use glam::Vec3;
use radiosity::mesh::Mesh;
use radiosity::scene::Scene;

const RHO: f64 = 0.5;
/// Half the opening's side, m.
const HALF: f32 = 0.2;

/// The floor of `common::opening` as a fan of 14 long triangles from one corner (as the
/// walls of Sponza are modelled), their far ends spaced unevenly and three of them slivers
/// 1.5–2 cm wide, so their elements meet along the shared edges at different sizes.
fn fan_opening() -> Scene {
    let mut scene = common::opening(RHO as f32, HALF);
    let floor = &mut scene.objects[0];
    let c = Vec3::new(-0.5, 0.0, -0.5);
    let mut chain = vec![Vec3::new(-0.5, 0.0, 0.5)];
    chain.extend(
        [0.13f32, 0.15, 0.29, 0.52, 0.535, 0.71, 0.9, 1.0].map(|t| Vec3::new(-0.5 + t, 0.0, 0.5)),
    );
    chain.extend([0.17f32, 0.38, 0.395, 0.55, 0.8, 1.0].map(|t| Vec3::new(0.5, 0.0, 0.5 - t)));
    floor.positions = std::iter::once(c).chain(chain.iter().copied()).collect();
    floor.triangles = (1..chain.len() as u32).map(|k| [0, k, k + 1]).collect();
    floor.triangle_material = vec![0; floor.triangles.len()];
    scene
}

/// The display vertices of material-0 elements lying inside an element's edge (further
/// than 10⁻⁴ of its length from either end, within 10⁻⁵ m of it: f32 positions of a
/// 1 m floor) that are not that edge's hanging midpoint: there Gouraud would take the
/// vertex's own value on one side and the edge's interpolation on the other, a crack in the
/// light along the edge. Brute force over every pair.
fn unhung_vertices(mesh: &Mesh) -> Vec<(u32, usize)> {
    let d = &mesh.display;
    let on_floor = |e: &&radiosity::mesh::Element| mesh.patches[e.patch as usize].material == 0;
    let mut used = std::collections::BTreeSet::new();
    for e in mesh.elements.iter().filter(on_floor) {
        used.extend(e.corners);
    }
    let hanging: std::collections::HashSet<[u32; 3]> = d
        .hanging
        .iter()
        .filter(|h| h.is_midpoint())
        .flat_map(|h| {
            [
                [h.vertex, h.edge[0], h.edge[1]],
                [h.vertex, h.edge[1], h.edge[0]],
            ]
        })
        .collect();
    let mut bad = Vec::new();
    for (i, e) in mesh
        .elements
        .iter()
        .enumerate()
        .filter(|(_, e)| on_floor(e))
    {
        for k in 0..3 {
            let (a, b) = (e.verts[k], e.verts[(k + 1) % 3]);
            let (ca, cb) = (e.corners[k], e.corners[(k + 1) % 3]);
            for &v in &used {
                let p = d.positions[v as usize];
                let t = (p - a).dot(b - a) / (b - a).length_squared();
                let off = (a + (b - a) * t - p).length();
                if t > 1e-4 && t < 1.0 - 1e-4 && off < 1e-5 && !hanging.contains(&[v, ca, cb]) {
                    bad.push((v, i));
                }
            }
        }
    }
    bad
}

/// A floor modelled as a fan of long thin triangles under the opening: the hierarchical
/// solve refines its triangles to different depths where the sky's light varies, and
/// where two of them meet, every vertex one side puts on the shared edge must be a hanging
/// midpoint of the other side's edge (2:1 balance across the edge), or Gouraud draws a
/// line along it (the fans on Sponza's walls). Then the light is as close to the closed
/// form as on the two-triangle floor: the same 10 % RMS bound as
/// `the_hierarchical_solve_splits_a_floor_where_the_sky_varies`.
#[test]
fn a_fan_of_long_thin_triangles_is_refined_without_cracks() {
    let s = common::opening_solved(&fan_opening());
    let mesh = s.mesh();
    let bad = unhung_vertices(mesh);
    assert!(
        bad.is_empty(),
        "{} vertices inside an edge and not hanging on it, e.g. vertex {} in element {}",
        bad.len(),
        bad[0].0,
        bad[0].1
    );
    let rms = common::opening_gouraud_rms(&s, RHO, HALF);
    let leaves = common::floor_leaves(mesh);
    assert!(rms < 0.10, "RMS {rms} over {leaves} floor leaves");
}
