//! Baked output: a binary glTF (.glb) that other glTF viewers (Blender, three.js, the
//! Khronos sample viewer) show as our viewer does, written atomically by the callers.
//!
//! Representation: the light per vertex in `COLOR_0`, under the scene's own materials
//! and textures made unlit (`KHR_materials_unlit`). An unlit glTF material shows
//! baseColorFactor × baseColorTexture(uv) × COLOR_0 (the extension's README), and COLOR_0
//! must lie in [0, 1] (glTF 2.0 §3.7.2.1), so it carries the light as our viewer displays
//! it, divided by the surface's mean albedo ρ̄ (the element's reflectance):
//!
//!   COLOR_0 = min(1, tonemap(ρ̄ · k · H / π) / ρ̄),
//!
//! with H the irradiance (what the viewer reconstructs) and k = 2^EV the exposure the file
//! was baked at. A viewer then shows albedo(uv) · COLOR_0, which on an untextured surface
//! is our displayed colour exactly and on a textured one our tone-mapped light times the
//! texture's deviation from its mean. Emitters cannot be written that way (unlit ignores
//! emission): their base colour is white and COLOR_0 = min(1, tonemap(k · B / π)). Why not
//! a lightmap: it needs a second, non-overlapping UV set over the whole scene (an atlas),
//! which most files do not have; vertex colours need nothing and follow the adaptive mesh
//! exactly.
//!
//! What is kept: one node per scene object with its name and transform (the positions in
//! the object's own frame), one primitive per material and side, the materials with their
//! base-colour factors, base-colour textures (the files' own encoded images, embedded),
//! wrap modes and alpha cut-outs; emission is in the light (and in `extras`). Transforms are flattened: the file's parent–child
//! hierarchy is not kept (the scene holds world transforms only). Each side of a
//! double-sided surface is its own single-sided primitive (the sides carry different
//! light). The physical values (reflectance, emission, sidedness) are in each material's
//! `extras.radiosity`, and the back sides are marked, so that our loader reads a baked
//! file as the scene it was baked from (its `COLOR_0` is light, not albedo).

use crate::exposure::ToneMap;
use crate::mesh::Mesh;
use crate::scene::{Scene, Slot, TextureRef, Wrap};
use glam::{Vec2, Vec3};
use serde_json::{Value, json};
use std::collections::HashMap;

/// A solution to bake, per element, and the exposure to bake it at.
pub struct Bake<'a> {
    pub radiosity: &'a [Vec3],
    pub reflectance: &'a [Vec3],
    pub emission: &'a [Vec3],
    /// Multiplier from radiance (W/(m²·sr)) to the file's colours: 2^EV.
    pub exposure: f32,
    pub tonemap: ToneMap,
}

/// One primitive being written: the vertices of one object, material and side.
#[derive(Default)]
struct Primitive {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    colours: Vec<Vec3>,
    uv: Vec<Vec2>,
    indices: Vec<u32>,
    /// (display vertex, texture coordinates' bits) → index: vertices are shared where
    /// both agree (texture seams split them).
    shared: HashMap<(u32, [u32; 2]), u32>,
}

/// The binary chunk and the glTF arrays that point into it.
#[derive(Default)]
struct Writer {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Writer {
    fn view(&mut self, data: &[u8], target: Option<u32>) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let mut v = json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": data.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.views.push(v);
        self.bin.extend_from_slice(data);
        self.views.len() - 1
    }

    /// A float accessor of `N` components per element.
    fn floats<const N: usize>(&mut self, data: &[[f32; N]], kind: &str, bounds: bool) -> usize {
        let bytes: Vec<u8> = data
            .iter()
            .flatten()
            .flat_map(|f| f.to_le_bytes())
            .collect();
        let view = self.view(&bytes, Some(34962));
        let mut a =
            json!({"bufferView": view, "componentType": 5126, "count": data.len(), "type": kind});
        if bounds && !data.is_empty() {
            let lo = (0..N).map(|k| data.iter().map(|v| v[k]).fold(f32::INFINITY, f32::min));
            let hi = (0..N).map(|k| data.iter().map(|v| v[k]).fold(f32::NEG_INFINITY, f32::max));
            a["min"] = json!(lo.collect::<Vec<_>>());
            a["max"] = json!(hi.collect::<Vec<_>>());
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn indices(&mut self, data: &[u32]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(34963));
        self.accessors.push(
            json!({"bufferView": view, "componentType": 5125, "count": data.len(), "type": "SCALAR"}),
        );
        self.accessors.len() - 1
    }
}

fn wrap_code(w: Wrap) -> u32 {
    match w {
        Wrap::Repeat => 10497,
        Wrap::Mirror => 33648,
        Wrap::Clamp => 33071,
    }
}

/// Builds the .glb bytes of `bake` on `mesh` (the solver's mesh of `scene`).
pub fn baked_glb(scene: &Scene, mesh: &Mesh, bake: &Bake) -> Vec<u8> {
    let irradiance = crate::solver::irradiance(bake.radiosity, bake.reflectance, bake.emission);
    let vertex_h = mesh.display.vertex_values(&mesh.elements, &irradiance);
    let vertex_b = mesh.display.vertex_values(&mesh.elements, bake.radiosity);
    let emits = |m: u32| {
        scene
            .materials
            .get(m as usize)
            .is_some_and(|m| m.emission.max_element() > 0.0)
    };
    let k = bake.exposure / std::f32::consts::PI;

    // Primitives by (object, material, back side).
    let mut primitives: std::collections::BTreeMap<(u32, u32, bool), Primitive> =
        Default::default();
    let inverses: Vec<glam::DMat4> = scene
        .objects
        .iter()
        .map(|o| o.world_from_local.inverse())
        .collect();
    let t_vertices = mesh.t_vertices();
    for (e, element) in mesh.elements.iter().enumerate() {
        let patch = &mesh.patches[element.patch as usize];
        let Some(object) = scene.objects.get(patch.object as usize) else {
            continue;
        };
        let local = &inverses[patch.object as usize];
        // Normals map by the transpose of the inverse of local → world's inverse.
        let normal = object
            .world_from_local
            .transpose()
            .transform_vector3(patch.normal.as_dvec3())
            .normalize_or_zero()
            .as_vec3();
        if normal == Vec3::ZERO {
            continue; // a degenerate element: nothing to see
        }
        let emitter = emits(patch.material);
        let p = primitives
            .entry((patch.object, patch.material, patch.back))
            .or_default();
        mesh.conforming_triangles(e as u32, &t_vertices, |corners| {
            for c in corners {
                let uv = mesh
                    .texture_uv(e as u32, c.position, Slot::Base)
                    .unwrap_or(Vec2::ZERO);
                let bits = [uv.x.to_bits(), uv.y.to_bits()];
                let next = p.positions.len() as u32;
                let index = *p.shared.entry((c.vertex, bits)).or_insert(next);
                if index == next {
                    let world = mesh.origin + c.position.as_dvec3();
                    p.positions.push(local.transform_point3(world).as_vec3());
                    p.normals.push(normal);
                    let colour = if emitter {
                        bake.tonemap
                            .apply(vertex_b[c.vertex as usize].max(Vec3::ZERO) * k)
                    } else {
                        let rho = bake.reflectance[e];
                        let shown = bake
                            .tonemap
                            .apply(rho * vertex_h[c.vertex as usize].max(Vec3::ZERO) * k);
                        Vec3::select(rho.cmpgt(Vec3::ZERO), shown / rho, Vec3::ZERO)
                    };
                    p.colours.push(colour.clamp(Vec3::ZERO, Vec3::ONE));
                    p.uv.push(uv);
                }
                p.indices.push(index);
            }
        });
    }

    let mut w = Writer::default();
    // Images (the files' encoded bytes), textures (image and wrap modes), samplers.
    let mut images = Vec::new();
    let mut image_index: HashMap<u32, usize> = HashMap::new();
    let mut textures = Vec::new();
    let mut texture_index: HashMap<TextureRef, usize> = HashMap::new();
    let mut samplers: Vec<[Wrap; 2]> = Vec::new();
    let mut texture = |t: TextureRef, w: &mut Writer| -> Option<usize> {
        let image = scene.images.get(t.image as usize)?;
        if let Some(&i) = texture_index.get(&t) {
            return Some(i);
        }
        let source = *image_index.entry(t.image).or_insert_with(|| {
            let view = w.view(&image.encoded, None);
            images.push(json!({"bufferView": view, "mimeType": image.mime, "name": image.name}));
            images.len() - 1
        });
        let sampler = match samplers.iter().position(|s| *s == t.wrap) {
            Some(s) => s,
            None => {
                samplers.push(t.wrap);
                samplers.len() - 1
            }
        };
        textures.push(json!({"source": source, "sampler": sampler}));
        texture_index.insert(t, textures.len() - 1);
        Some(textures.len() - 1)
    };
    let mut materials = Vec::new();
    for m in &scene.materials {
        let emitter = m.emission.max_element() > 0.0;
        let base = if emitter { Vec3::ONE } else { m.reflectance };
        let mut pbr = json!({"baseColorFactor": [base.x, base.y, base.z, 1.0],
            "metallicFactor": 0.0, "roughnessFactor": 1.0});
        let mut material = json!({
            "name": m.name,
            "doubleSided": false,
            "extensions": {"KHR_materials_unlit": {}},
            "extras": {"radiosity": {
                "reflectance": m.reflectance.to_array(),
                "emission": m.emission.to_array(),
                "doubleSided": m.double_sided
            }}
        });
        if !emitter && let Some(t) = m.base_texture.and_then(|t| texture(t, &mut w)) {
            pbr["baseColorTexture"] = json!({"index": t, "texCoord": 0});
            if let Some(cutoff) = m.alpha_cutoff {
                material["alphaMode"] = json!("MASK");
                material["alphaCutoff"] = json!(cutoff.min(1.0));
            }
        }
        material["pbrMetallicRoughness"] = pbr;
        materials.push(material);
    }

    // Meshes and nodes: one of each per object with geometry.
    let mut meshes = Vec::new();
    let mut nodes = Vec::new();
    let mut by_object: std::collections::BTreeMap<u32, Vec<Value>> = Default::default();
    for ((object, material, back), p) in &primitives {
        if p.indices.is_empty() {
            continue;
        }
        let textured = scene
            .materials
            .get(*material as usize)
            .is_some_and(|m| m.base_texture.is_some() && m.emission.max_element() <= 0.0);
        let position = w.floats(
            &p.positions.iter().map(|v| v.to_array()).collect::<Vec<_>>(),
            "VEC3",
            true,
        );
        let normal = w.floats(
            &p.normals.iter().map(|v| v.to_array()).collect::<Vec<_>>(),
            "VEC3",
            false,
        );
        let colour = w.floats(
            &p.colours.iter().map(|v| v.to_array()).collect::<Vec<_>>(),
            "VEC3",
            false,
        );
        let mut attributes = json!({"POSITION": position, "NORMAL": normal, "COLOR_0": colour});
        if textured {
            let uv: Vec<[f32; 2]> = p.uv.iter().map(|v| v.to_array()).collect();
            attributes["TEXCOORD_0"] = json!(w.floats(&uv, "VEC2", false));
        }
        let indices = w.indices(&p.indices);
        let mut primitive =
            json!({"attributes": attributes, "indices": indices, "material": material});
        if *back {
            primitive["extras"] = json!({"radiosity": {"side": "back"}});
        }
        by_object.entry(*object).or_default().push(primitive);
    }
    for (object, prims) in by_object {
        let o = &scene.objects[object as usize];
        meshes.push(json!({"name": o.name, "primitives": prims}));
        let mut node = json!({"name": o.name, "mesh": meshes.len() - 1});
        if o.world_from_local != glam::DMat4::IDENTITY {
            node["matrix"] = json!(o.world_from_local.to_cols_array());
        }
        nodes.push(node);
    }
    while !w.bin.len().is_multiple_of(4) {
        w.bin.push(0);
    }
    let mut doc = json!({
        "asset": {
            "version": "2.0",
            "generator": concat!("radiosity ", env!("CARGO_PKG_VERSION")),
            "extras": {"radiosity": {
                "exposure": bake.exposure,
                "tonemap": bake.tonemap.name(),
                "COLOR_0": "min(1, tonemap(ρ·exposure·H/π)/ρ) with H the irradiance (W/m²) and ρ the element's reflectance; min(1, tonemap(exposure·B/π)) on emitters (white, unlit)"
            }}
        },
        "extensionsUsed": ["KHR_materials_unlit"],
        "scene": 0,
        "scenes": [{"nodes": (0..nodes.len()).collect::<Vec<_>>()}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "buffers": [{"byteLength": w.bin.len()}],
        "bufferViews": w.views,
        "accessors": w.accessors,
    });
    if !images.is_empty() {
        doc["images"] = json!(images);
        doc["textures"] = json!(textures);
        doc["samplers"] = json!(samplers
            .iter()
            .map(|s| json!({"magFilter": 9729, "minFilter": 9987, "wrapS": wrap_code(s[0]), "wrapT": wrap_code(s[1])}))
            .collect::<Vec<_>>());
    }
    glb(&doc, &w.bin)
}

/// The GLB container (glTF 2.0 §4.4): header, JSON chunk (space-padded), BIN chunk.
fn glb(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json_bytes = serde_json::to_vec(doc).unwrap_or_default();
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
    out.extend_from_slice(bin);
    out
}
