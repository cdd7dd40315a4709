//! The glTF loader (`radiosity::scene::gltf`) on files written here: the built-in Cornell
//! box through `write_gltf`, and small hand-written files for textures, lights, URIs and
//! missing files. The sample files of the test-scene corpus are in `loader_corpus.rs`.

mod common;
use common::scratch_dir;
use glam::{DVec3, Vec3};
use radiosity::scene::gltf::{LoadError, load, write_gltf};
use radiosity::scene::{Light, builtin};

#[test]
fn cornell_box_round_trips_through_write_gltf() {
    let original = builtin::cornell_box();
    let text = write_gltf(&original);
    // An independent check that the export is valid glTF 2.0: the `gltf` crate's validation.
    if let Err(e) = gltf::Gltf::from_slice(text.as_bytes()) {
        panic!("write_gltf output fails gltf validation: {e}");
    }
    let dir = scratch_dir("loader-round-trip");
    let path = dir.join("cornell round trip.gltf");
    std::fs::write(&path, &text).unwrap();
    let loaded = load(&path).unwrap_or_else(|e| panic!("{e}"));
    std::fs::remove_file(&path).ok();

    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    assert_eq!(loaded.triangle_count(), original.triangle_count());
    assert_eq!(loaded.objects.len(), original.objects.len());
    assert_eq!(loaded.materials.len(), original.materials.len());
    // Materials: reflectance is written as the shortest decimal of the f32 and emission as
    // factor × strength recomputed in f64, so both come back to within f32 rounding
    // (1e-6 relative covers one f32 ulp of values up to 17).
    for (a, b) in original.materials.iter().zip(&loaded.materials) {
        assert_eq!(a.name, b.name);
        assert!(
            (a.reflectance - b.reflectance).abs().max_element() <= 1e-6,
            "{a:?} vs {b:?}"
        );
        assert!(
            (a.emission - b.emission).abs().max_element()
                <= 1e-6 * a.emission.max_element().max(1.0),
            "{a:?} vs {b:?}"
        );
        assert_eq!(a.double_sided, b.double_sided);
        assert_eq!(a.transmittance, b.transmittance);
    }
    // Geometry: world positions are written as f32 (the builtin stores f32 too), so each
    // triangle corner matches to 1e-6 m (f32 resolution at ~0.5 m is 6e-8 m).
    for (oa, ob) in original.objects.iter().zip(&loaded.objects) {
        assert_eq!(oa.name, ob.name);
        // Same triangles in the same order, same material, same corners.
        assert_eq!(oa.triangles.len(), ob.triangles.len());
        assert_eq!(oa.triangle_material, ob.triangle_material);
        for (ta, tb) in oa.triangles.iter().zip(&ob.triangles) {
            for (&va, &vb) in ta.iter().zip(tb) {
                let (pa, pb) = (oa.world_position(va), ob.world_position(vb));
                assert!((pa - pb).abs().max_element() <= 1e-6, "{pa} vs {pb}");
            }
        }
    }
}

/// One triangle with UVs (0,0), (1,0), (0,1) in an embedded buffer, with the given
/// `materials` and `images` arrays (texture 0 = image 0) and optional root `extensions`.
fn one_triangle(
    materials: serde_json::Value,
    images: serde_json::Value,
    node: serde_json::Value,
) -> String {
    use base64::Engine as _;
    let mut bin = Vec::new();
    for p in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        bin.extend_from_slice(&p.to_le_bytes());
    }
    for p in [0.0f32, 0.0, 1.0, 0.0, 0.0, 1.0] {
        bin.extend_from_slice(&p.to_le_bytes());
    }
    let b64 = base64::engine::general_purpose::STANDARD.encode(&bin);
    let mut nodes = vec![serde_json::json!({"mesh": 0})];
    if !node.is_null() {
        nodes.push(node);
    }
    serde_json::json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": (0..nodes.len()).collect::<Vec<_>>()}],
        "nodes": nodes,
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "material": 0}]}],
        "materials": materials,
        "textures": [{"source": 0}],
        "images": images,
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 0, "byteOffset": 36, "componentType": 5126, "count": 3, "type": "VEC2"}
        ],
        "bufferViews": [{"buffer": 0, "byteLength": bin.len()}],
        "buffers": [{"byteLength": bin.len(), "uri": format!("data:application/octet-stream;base64,{b64}")}]
    })
    .to_string()
}

/// One triangle whose material has a base colour texture at `image_uri`.
fn triangle_with_image(image_uri: &str) -> String {
    one_triangle(
        serde_json::json!([{"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "baseColorTexture": {"index": 0}}}]),
        serde_json::json!([{"uri": image_uri}]),
        serde_json::Value::Null,
    )
}

#[test]
fn texture_means_are_linear_and_alpha_gives_coverage() {
    let dir = scratch_dir("loader-alpha");
    // 64×64 texture: sRGB colour (128, 64, 255); alpha 0 where u < 0.5, else 1.
    let img = image::RgbaImage::from_fn(64, 64, |x, _| {
        image::Rgba([128, 64, 255, if x < 32 { 0 } else { 255 }])
    });
    img.save(dir.join("half.png")).unwrap();
    // The sRGB EOTF (IEC 61966-2-1) of 128/255 and 64/255.
    let lin = |c: f32| ((c / 255.0 + 0.055) / 1.055).powf(2.4);
    let want = Vec3::new(lin(128.0), lin(64.0), 1.0);
    for (mode, cutoff) in [("MASK", Some(0.5)), ("BLEND", None), ("OPAQUE", None)] {
        let mut m = serde_json::json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}, "alphaMode": mode});
        if let Some(c) = cutoff {
            m["alphaCutoff"] = serde_json::json!(c);
        }
        let path = dir.join(format!("{mode}.gltf"));
        std::fs::write(
            &path,
            one_triangle(
                serde_json::json!([m]),
                serde_json::json!([{"uri": "half.png"}]),
                serde_json::Value::Null,
            ),
        )
        .unwrap();
        let s = load(&path).unwrap_or_else(|e| panic!("{e}"));
        // Default base colour 1 is clamped to 0.999 silently.
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        assert_eq!(s.materials[0].reflectance, Vec3::splat(0.999));
        let o = &s.objects[0];
        // A uniform colour: the mean is the colour itself (1e-5: f32 arithmetic).
        assert!(
            (o.reflectance_tint[0] - want).abs().max_element() < 1e-5,
            "{mode}: {}",
            o.reflectance_tint[0]
        );
        // The triangle (0,0),(1,0),(0,1) has a quarter of its area at u > 0.5, so coverage
        // (MASK) and mean alpha (BLEND) are 1/4 and transmittance 3/4. Tolerance 0.03: each of
        // the 16 samples stands for 128 texels, so it reads mip level ~3.5, whose box-filtered,
        // repeat-wrapped texels blur the alpha edge by a few percent of the area.
        match mode {
            "OPAQUE" => assert!(o.transmittance.is_empty()),
            _ => assert!(
                (o.transmittance[0] - 0.75).abs() < 0.03,
                "{mode}: {:?}",
                o.transmittance
            ),
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn spot_and_directional_lights_are_placed_by_their_nodes() {
    let dir = scratch_dir("loader-lights");
    let lights = serde_json::json!({"KHR_lights_punctual": {"lights": [
        {"type": "spot", "intensity": 2.0, "color": [1.0, 0.5, 0.25], "range": 10.0},
        {"type": "directional", "intensity": 3.0},
        {"type": "spot", "spot": {"innerConeAngle": 1.0, "outerConeAngle": 0.5}}
    ]}});
    // A parent turning −Z into −Y (rotation of −90° about X) with three light children.
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let parent = serde_json::json!({"rotation": [-s, 0.0, 0.0, s], "translation": [0.0, 3.0, 0.0], "children": [2, 3, 4]});
    let mut doc: serde_json::Value = serde_json::from_str(&one_triangle(
        serde_json::json!([{}]),
        serde_json::json!([]),
        parent,
    ))
    .unwrap();
    doc["meshes"][0]["primitives"][0]["attributes"]
        .as_object_mut()
        .unwrap()
        .remove("TEXCOORD_0");
    doc["textures"] = serde_json::json!([]);
    doc["extensions"] = lights;
    for l in 0..3 {
        doc["nodes"]
            .as_array_mut()
            .unwrap()
            .push(serde_json::json!({"extensions": {"KHR_lights_punctual": {"light": l}}}));
    }
    let path = dir.join("lights.gltf");
    std::fs::write(&path, doc.to_string()).unwrap();
    let scene = load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.lights.len(), 2, "{:?}", scene.lights);
    // The bad cone (inner > outer) is skipped with a warning naming the light.
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("light 2") && w.contains("cone")),
        "{:?}",
        scene.warnings
    );
    let close = |a: DVec3, b: DVec3| (a - b).length() < 1e-12;
    match &scene.lights[0] {
        Light::Spot {
            position,
            direction,
            intensity,
            range,
            inner_cone,
            outer_cone,
        } => {
            assert!(
                close(*position, DVec3::new(0.0, 3.0, 0.0)) && close(*direction, DVec3::NEG_Y),
                "{position} {direction}"
            );
            assert_eq!(*intensity, Vec3::new(2.0, 1.0, 0.5));
            assert_eq!(
                (*range, *inner_cone, *outer_cone),
                (Some(10.0), 0.0, std::f64::consts::FRAC_PI_4)
            );
        }
        other => panic!("{other:?}"),
    }
    match &scene.lights[1] {
        Light::Directional {
            direction,
            irradiance,
        } => {
            assert!(close(*direction, DVec3::NEG_Y));
            assert_eq!(*irradiance, Vec3::splat(3.0));
        }
        other => panic!("{other:?}"),
    }
    // Lights survive write_gltf → load (directions to 1e-12, values exactly).
    let again = dir.join("again.gltf");
    std::fs::write(&again, write_gltf(&scene)).unwrap();
    let back = load(&again).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(back.lights.len(), 2);
    for (a, b) in scene.lights.iter().zip(&back.lights) {
        match (a, b) {
            (
                Light::Spot {
                    direction: d1,
                    intensity: i1,
                    ..
                },
                Light::Spot {
                    direction: d2,
                    intensity: i2,
                    ..
                },
            )
            | (
                Light::Directional {
                    direction: d1,
                    irradiance: i1,
                },
                Light::Directional {
                    direction: d2,
                    irradiance: i2,
                },
            ) => {
                assert!(close(*d1, *d2), "{d1} {d2}");
                assert!((*i1 - *i2).abs().max_element() < 1e-6);
            }
            _ => panic!("{a:?} vs {b:?}"),
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn uris_must_stay_inside_the_scene_folder() {
    let dir = scratch_dir("loader-uri");
    // Buffers: refused with an error naming the file and the problem.
    for uri in [
        "../../etc/passwd",
        "/etc/passwd",
        "sub/../../x.bin",
        "file:///etc/passwd",
    ] {
        let doc = serde_json::json!({
            "asset": {"version": "2.0"},
            "buffers": [{"byteLength": 4, "uri": uri}],
            "bufferViews": [{"buffer": 0, "byteLength": 4}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 1, "type": "VEC3"}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "nodes": [{"mesh": 0}],
            "scenes": [{"nodes": [0]}]
        });
        let path = dir.join("escape.gltf");
        std::fs::write(&path, doc.to_string()).unwrap();
        let err = load(&path).expect_err(uri).to_string();
        assert!(err.contains("escape.gltf") && err.contains(uri), "{err}");
        assert!(
            err.contains("outside") || err.contains("absolute") || err.contains("relative path"),
            "{err}"
        );
    }
    // Images: a warning, and the surface is untextured.
    let path = dir.join("escape image.gltf");
    std::fs::write(&path, triangle_with_image("../../etc/passwd")).unwrap();
    let s = load(&path).expect("an escaping image URI is only a warning");
    assert_eq!(s.triangle_count(), 1);
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("outside the scene's folder")),
        "{:?}",
        s.warnings
    );
    assert!(s.objects[0].reflectance_tint.is_empty());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn missing_files() {
    // A missing image: a warning naming it; the geometry loads.
    let dir = scratch_dir("loader-missing");
    let path = dir.join("missing image.gltf");
    std::fs::write(&path, triangle_with_image("no%20such%20image.png")).unwrap();
    let s = load(&path).expect("a missing image is only a warning");
    assert!(
        s.warnings.iter().any(|w| w.contains("no such image.png")),
        "{:?}",
        s.warnings
    );
    // A missing scene file.
    let err = load(&dir.join("no such scene.gltf")).unwrap_err();
    assert!(matches!(err, LoadError::Io { .. }) && err.to_string().contains("no such scene.gltf"));
    std::fs::remove_dir_all(&dir).ok();
}
