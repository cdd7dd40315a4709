//! Every patch faces the way its scene triangle does, however thin the piece of it that
//! contact lines cut off. `Mesh::validate` holds the invariant; here it is checked on a
//! real scene where the cuts leave slivers.

mod common;
use radiosity::mesh::{Mesh, MeshSettings};

/// `cornell-box-nvpro`: a white sphere sunk 5 cm into the floor slab, whose triangles the
/// floor's contact line cuts into slivers of 10⁻¹⁰ m². Before, a patch's normal was the
/// cross product of its own corners, which for a sliver whose corners are nearly in line
/// points anywhere: some of the sphere's slivers faced up to 90° away from their triangle, so
/// their rays started on the wrong side of the sphere.
#[test]
fn slivers_cut_along_a_contact_face_the_way_their_triangle_does() {
    let Some(scenes) = common::shared_scenes() else {
        return;
    };
    let path = scenes.join("cornell-box-nvpro/cornellBox.gltf");
    let scene = radiosity::scene::open(path.to_str().unwrap(), None, None).unwrap();
    let mesh = Mesh::build(&scene, &MeshSettings::default());
    let slivers = mesh.elements.iter().filter(|e| e.area < 1e-8).count();
    assert!(slivers > 0, "the contact lines cut no slivers");
    assert_eq!(mesh.validate(), Ok(()));
}
