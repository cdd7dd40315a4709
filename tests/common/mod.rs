//! Scene pieces shared by the integration tests that build their scenes in code.

use glam::{DMat4, Vec3};
use radiosity::scene::Object;

/// Appends the quad `v` (two triangles, the winding of `v`) with `material` to `o`.
pub fn quad(o: &mut Object, v: [[f32; 3]; 4], material: u32) {
    let base = o.positions.len() as u32;
    o.positions.extend(v.iter().map(|p| Vec3::from(*p)));
    o.triangles.push([base, base + 1, base + 2]);
    o.triangles.push([base, base + 2, base + 3]);
    o.triangle_material.extend([material, material]);
}

/// A 2 m square floor at y = 0 facing +y (counter-clockwise seen from above), of material
/// 0, placed by `world_from_local`.
pub fn floor(world_from_local: DMat4) -> Object {
    let mut floor = Object {
        name: "floor".into(),
        world_from_local,
        ..Default::default()
    };
    quad(
        &mut floor,
        [
            [-1.0, 0.0, -1.0],
            [-1.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 0.0, -1.0],
        ],
        0,
    );
    floor
}
