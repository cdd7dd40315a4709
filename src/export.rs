//! Baked output: a binary glTF (.glb) of the element mesh with the solved radiosity as
//! linear radiance per vertex (`COLOR_0` = B / π, W/(m²·sr), Gouraud vertex values), one
//! primitive per material, written atomically (temporary file, then rename).

use crate::mesh::Mesh;
use crate::scene::Scene;
use glam::Vec3;
use serde_json::json;

/// Builds the .glb bytes for `mesh` with per-vertex values `vertex_radiosity` (B, W/m²).
pub fn baked_glb(scene: &Scene, mesh: &Mesh, vertex_radiosity: &[Vec3]) -> Vec<u8> {
    let mut bin: Vec<u8> = Vec::new();
    let mut buffer_views = Vec::new();
    let mut accessors = Vec::new();
    let mut push_view = |bin: &mut Vec<u8>, data: &[u8], target: u32| -> usize {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        buffer_views.push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": data.len(), "target": target}));
        bin.extend_from_slice(data);
        buffer_views.len() - 1
    };
    let f32_bytes = |v: &[Vec3]| -> Vec<u8> {
        v.iter()
            .flat_map(|p| p.to_array())
            .flat_map(f32::to_le_bytes)
            .collect()
    };
    // Shared vertex attributes (positions relative to the mesh origin; the node translates).
    let (lo, hi) = mesh.display.positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let pos_view = push_view(&mut bin, &f32_bytes(&mesh.display.positions), 34962);
    let n = mesh.display.positions.len();
    accessors.push(
        json!({"bufferView": pos_view, "componentType": 5126, "count": n, "type": "VEC3",
        "min": if n > 0 { lo.to_array().to_vec() } else { vec![0.0; 3] },
        "max": if n > 0 { hi.to_array().to_vec() } else { vec![0.0; 3] }}),
    );
    let nrm_view = push_view(&mut bin, &f32_bytes(&mesh.display.normals), 34962);
    accessors
        .push(json!({"bufferView": nrm_view, "componentType": 5126, "count": n, "type": "VEC3"}));
    let radiance: Vec<Vec3> = vertex_radiosity
        .iter()
        .map(|b| *b / std::f32::consts::PI)
        .collect();
    let col_view = push_view(&mut bin, &f32_bytes(&radiance), 34962);
    accessors
        .push(json!({"bufferView": col_view, "componentType": 5126, "count": n, "type": "VEC3"}));
    // One primitive per material, indices from the element corners.
    let mut by_material: Vec<Vec<u32>> = vec![Vec::new(); scene.materials.len().max(1)];
    for e in &mesh.elements {
        let m = mesh.patches[e.patch as usize].material as usize;
        if let Some(list) = by_material.get_mut(m) {
            list.extend(e.corners);
        }
    }
    let mut primitives = Vec::new();
    for (m, indices) in by_material.iter().enumerate() {
        if indices.is_empty() {
            continue;
        }
        let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = push_view(&mut bin, &bytes, 34963);
        accessors.push(json!({"bufferView": view, "componentType": 5125, "count": indices.len(), "type": "SCALAR"}));
        primitives.push(json!({"attributes": {"POSITION": 0, "NORMAL": 1, "COLOR_0": 2}, "indices": accessors.len() - 1, "material": m}));
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let materials: Vec<_> = scene
        .materials
        .iter()
        .map(|m| {
            let strength = m.emission.max_element().max(1.0);
            json!({"name": m.name, "doubleSided": m.double_sided,
                "pbrMetallicRoughness": {"baseColorFactor": [m.reflectance.x, m.reflectance.y, m.reflectance.z, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
                "emissiveFactor": (m.emission / strength).to_array(),
                "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": strength}}})
        })
        .collect();
    let doc = json!({
        "asset": {"version": "2.0", "generator": concat!("radiosity ", env!("CARGO_PKG_VERSION"))},
        "extensionsUsed": ["KHR_materials_emissive_strength"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "radiosity", "translation": mesh.origin.to_array()}],
        "meshes": [{"primitives": primitives}],
        "materials": materials,
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": buffer_views,
        "accessors": accessors,
    });
    let mut json_bytes = serde_json::to_vec(&doc).unwrap_or_default();
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let total = 12 + 8 + json_bytes.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_bytes);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}
