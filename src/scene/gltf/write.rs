//! glTF 2.0 export of a [`Scene`]: one JSON file with one embedded base64 buffer.
//!
//! Geometry is written in world space (f32 positions, u32 indices; one node and one mesh
//! per object; one primitive per run of consecutive triangles sharing a material, so that
//! loading gives the triangles back in order), so transforms need not round-trip.
//! Materials round-trip through [`super::load`]: `baseColorFactor` = reflectance;
//! emission L_e as `emissiveFactor` = L_e / max(L_e) with `KHR_materials_emissive_strength`
//! = max(L_e) when that exceeds 1 (the factor must stay in [0, 1]); transmittance as
//! `KHR_materials_transmission`. Punctual lights are written as `KHR_lights_punctual`.
//! Not exported: per-triangle texture tints and transmittance overrides (they would need
//! textures) and the environment (glTF has no sky).

use crate::scene::{Light, Scene};
use base64::Engine as _;
use glam::{DQuat, DVec3, Vec3};
use serde_json::{Map, Value, json};

/// An f32 as the JSON number with the shortest decimal that reads back as the same f32
/// (`0.725`, not `0.7250000238418579`). Non-finite values become 0.
fn num(x: f32) -> Value {
    if !x.is_finite() {
        return json!(0.0);
    }
    let shortest: f64 = format!("{x}").parse().unwrap_or(x as f64);
    json!(shortest)
}

fn vec3(v: Vec3) -> Value {
    json!([num(v.x), num(v.y), num(v.z)])
}

/// Splits a colour-times-intensity into (colour with max component 1, intensity).
fn color_intensity(v: Vec3) -> (Vec3, f32) {
    let m = v.max_element();
    if m > 0.0 {
        (v / m, m)
    } else {
        (Vec3::ONE, 0.0)
    }
}

/// Writes `scene` as a glTF 2.0 JSON document with an embedded buffer (see the module doc).
/// Used to produce `assets/cornell_box.gltf`; `load(write_gltf(s))` gives back the same
/// world-space triangles and materials.
pub fn write_gltf(scene: &Scene) -> String {
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut meshes = Vec::new();
    let mut nodes = Vec::new();
    let mut used_ext: Vec<String> = Vec::new();

    for object in &scene.objects {
        if object.triangles.is_empty() {
            continue;
        }
        let world: Vec<Vec3> = (0..object.positions.len() as u32)
            .map(|v| object.world_position(v).as_vec3())
            .collect();
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for p in &world {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        let offset = bin.len();
        for p in &world {
            for c in p.to_array() {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        }
        views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": bin.len() - offset, "target": 34962}));
        let position_accessor = accessors.len();
        accessors.push(json!({
            "bufferView": views.len() - 1, "componentType": 5126, "count": world.len(),
            "type": "VEC3", "min": vec3(lo), "max": vec3(hi)
        }));
        // Triangles are already counter-clockwise in world space (the scene convention).
        // One primitive per run of consecutive triangles with the same material, so that
        // loading gives the triangles back in the same order.
        let mut runs: Vec<(u32, Vec<u32>)> = Vec::new();
        for (t, tri) in object.triangles.iter().enumerate() {
            let m = object.triangle_material.get(t).copied().unwrap_or(0);
            match runs.last_mut() {
                Some((last, indices)) if *last == m => indices.extend_from_slice(tri),
                _ => runs.push((m, tri.to_vec())),
            }
        }
        let mut primitives = Vec::new();
        for (material, indices) in runs {
            let offset = bin.len();
            for i in &indices {
                bin.extend_from_slice(&i.to_le_bytes());
            }
            views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": bin.len() - offset, "target": 34963}));
            accessors.push(json!({
                "bufferView": views.len() - 1, "componentType": 5125, "count": indices.len(), "type": "SCALAR"
            }));
            let mut prim = json!({
                "attributes": {"POSITION": position_accessor},
                "indices": accessors.len() - 1,
                "mode": 4
            });
            if (material as usize) < scene.materials.len() {
                prim["material"] = json!(material);
            }
            primitives.push(prim);
        }
        meshes.push(json!({"name": object.name, "primitives": primitives}));
        nodes.push(json!({"name": object.name, "mesh": meshes.len() - 1}));
    }

    let materials: Vec<Value> = scene
        .materials
        .iter()
        .map(|m| {
            let mut out = json!({
                "name": m.name,
                "pbrMetallicRoughness": {
                    "baseColorFactor": [num(m.reflectance.x), num(m.reflectance.y), num(m.reflectance.z), 1.0],
                    "metallicFactor": 0.0,
                    "roughnessFactor": 1.0
                },
                "doubleSided": m.double_sided
            });
            let mut ext = Map::new();
            let e = m.emission.max(Vec3::ZERO);
            let peak = e.max_element();
            if peak > 1.0 {
                // factor × strength is recomputed in f64 by the loader, so it round-trips.
                let f = e.as_dvec3() / peak as f64;
                out["emissiveFactor"] = json!([f.x, f.y, f.z]);
                ext.insert("KHR_materials_emissive_strength".into(), json!({"emissiveStrength": num(peak)}));
            } else if peak > 0.0 {
                out["emissiveFactor"] = vec3(e);
            }
            if m.transmittance > 0.0 {
                ext.insert("KHR_materials_transmission".into(), json!({"transmissionFactor": num(m.transmittance)}));
            }
            for k in ext.keys() {
                if !used_ext.contains(k) {
                    used_ext.push(k.clone());
                }
            }
            if !ext.is_empty() {
                out["extensions"] = Value::Object(ext);
            }
            out
        })
        .collect();

    let mut lights = Vec::new();
    for light in &scene.lights {
        let mut def = Map::new();
        let (node, radiant) = match light {
            Light::Point {
                position,
                intensity,
                range,
            } => {
                def.insert("type".into(), json!("point"));
                if let Some(r) = range {
                    def.insert("range".into(), json!(r));
                }
                (json!({"translation": position.to_array()}), *intensity)
            }
            Light::Spot {
                position,
                direction,
                intensity,
                range,
                inner_cone,
                outer_cone,
            } => {
                def.insert("type".into(), json!("spot"));
                def.insert(
                    "spot".into(),
                    json!({"innerConeAngle": inner_cone, "outerConeAngle": outer_cone}),
                );
                if let Some(r) = range {
                    def.insert("range".into(), json!(r));
                }
                let q =
                    DQuat::from_rotation_arc(DVec3::NEG_Z, direction.normalize_or(DVec3::NEG_Z));
                (
                    json!({"translation": position.to_array(), "rotation": q.to_array()}),
                    *intensity,
                )
            }
            Light::Directional {
                direction,
                irradiance,
            } => {
                def.insert("type".into(), json!("directional"));
                let q =
                    DQuat::from_rotation_arc(DVec3::NEG_Z, direction.normalize_or(DVec3::NEG_Z));
                (json!({"rotation": q.to_array()}), *irradiance)
            }
        };
        let (color, intensity) = color_intensity(radiant);
        def.insert("color".into(), vec3(color));
        def.insert("intensity".into(), num(intensity));
        let mut node = node;
        node["name"] = json!(format!("light {}", lights.len()));
        node["extensions"] = json!({"KHR_lights_punctual": {"light": lights.len()}});
        nodes.push(node);
        lights.push(Value::Object(def));
    }

    let mut doc = json!({
        "asset": {"version": "2.0", "generator": format!("radiosity {}", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"name": scene.name, "nodes": (0..nodes.len()).collect::<Vec<_>>()}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{
            "byteLength": bin.len(),
            "uri": format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bin))
        }]
    });
    if !lights.is_empty() {
        used_ext.push("KHR_lights_punctual".into());
        doc["extensions"] = json!({"KHR_lights_punctual": {"lights": lights}});
    }
    if !used_ext.is_empty() {
        doc["extensionsUsed"] = json!(used_ext);
    }
    let mut text = serde_json::to_string_pretty(&doc).unwrap_or_default();
    text.push('\n');
    text
}
