//! Textures under the light: the display shows B = albedo(uv)·H + E(uv) with H the solved
//! irradiance (`shader.wgsl`). Both tests use surfaces whose irradiance has a closed form,
//! H = π L under a uniform sky of radiance L on a surface that sees only the sky, and
//! compare every rendered pixel with the texture read on the CPU at the same surface point
//! (found by casting the pixel's ray), so the truth comes from neither the renderer nor the
//! solver.

mod common;

use glam::{Vec2, Vec3, Vec4};
use radiosity::mesh::Mesh;
use radiosity::pipeline::Prepared;
use radiosity::scene::textures::{linear_to_srgb, srgb_to_linear};
use radiosity::scene::{Scene, Slot};
use radiosity::solver::SolverSettings;
use radiosity::view::camera::Camera;
use radiosity::view::render::{Display, Solution, ToneMap, headless_device, render_image};
use std::path::{Path, PathBuf};

/// The element and point (mesh frame) seen through the centre of pixel (x, y).
fn visible(
    prepared: &Prepared,
    camera: &Camera,
    size: [u32; 2],
    x: u32,
    y: u32,
) -> Option<(u32, Vec3)> {
    let (w, h) = (size[0] as f32, size[1] as f32);
    let (origin, dir) = camera.ray(x as f32 + 0.5, y as f32 + 0.5, w, h);
    let hit = prepared
        .bvh
        .closest_hit(origin, dir, 0.0, f32::INFINITY, u32::MAX)?;
    let p = origin + dir * hit.t;
    Some((prepared.mesh.element_at(hit.triangle, p, -dir)?, p))
}

/// An sRGB byte to linear (IEC 61966-2-1; the target's encoding is the GPU's own, so a
/// wrong formula here would show as a mismatch).
fn linear(b: u8) -> f32 {
    srgb_to_linear(b as f32 / 255.0)
}

/// Linear to an sRGB byte.
fn encode(c: f32) -> u8 {
    (linear_to_srgb(c.clamp(0.0, 1.0)) * 255.0).round() as u8
}

/// Solves `scene` to convergence and renders it at EV 0 with the clamp tone map, textures
/// on: a pixel's linear value is then B/π of its surface point.
fn solve_and_render(
    scene: &Scene,
    camera: &Camera,
    size: [u32; 2],
) -> (Prepared, image::RgbaImage) {
    let prepared = common::prepared(scene, 4000);
    let mut solver = prepared.solver(SolverSettings::default()).unwrap();
    common::converge(&mut solver);
    let radiosity = solver.radiosity();
    let (reflectance, emission) = (solver.reflectance(), solver.emission());
    let solution = Solution {
        radiosity: &radiosity,
        reflectance: &reflectance,
        emission: &emission,
    };
    let display = Display {
        ev: 0.0,
        tonemap: ToneMap::Clamp,
        textures: true,
        ..Default::default()
    };
    let headless = headless_device().unwrap();
    let image = render_image(
        &headless,
        solver.mesh(),
        &solution,
        &scene.materials,
        &scene.images,
        camera,
        &display,
        size,
    )
    .unwrap();
    (prepared, image)
}

/// Per channel of every pixel of `image` that sees the scene, the difference in 8-bit
/// levels from `want` (the linear colour expected at the element and point seen, encoded
/// to sRGB), sorted; and the expected picture.
fn level_errors(
    prepared: &Prepared,
    camera: &Camera,
    image: &image::RgbaImage,
    want: impl Fn(u32, Vec3) -> Vec3,
) -> (Vec<i32>, image::RgbaImage) {
    let size = [image.width(), image.height()];
    let mut errors = Vec::new();
    let mut expected = image::RgbaImage::new(size[0], size[1]);
    for y in 0..size[1] {
        for x in 0..size[0] {
            let Some((e, p)) = visible(prepared, camera, size, x, y) else {
                continue;
            };
            let want = want(e, p).to_array().map(encode);
            expected.put_pixel(x, y, image::Rgba([want[0], want[1], want[2], 255]));
            let got = image.get_pixel(x, y).0;
            for c in 0..3 {
                errors.push((want[c] as i32 - got[c] as i32).abs());
            }
        }
    }
    errors.sort();
    (errors, expected)
}

/// The mean and 99th percentile of sorted `errors`.
fn mean_and_p99(errors: &[i32]) -> (f64, i32) {
    let mean = errors.iter().sum::<i32>() as f64 / errors.len() as f64;
    (mean, errors[errors.len() * 99 / 100])
}

/// The base-colour texture of element `e`'s material at surface point `p`, linear.
fn texel(scene: &Scene, mesh: &Mesh, e: u32, p: Vec3) -> Vec4 {
    let patch = &mesh.patches[mesh.elements[e as usize].patch as usize];
    let t = scene.materials[patch.material as usize]
        .base_texture
        .expect("a textured material");
    let uv: Vec2 = mesh
        .texture_uv(e, p, Slot::Base)
        .expect("texture coordinates");
    scene.images[t.image as usize].sample(0, uv, t.wrap)
}

/// A 1 m square facing +y at the origin, textured with a 32×32 image (`texture.png`,
/// clamped at the edges, magnified when drawn), as a glTF in `dir`. The image varies
/// smoothly (one period of a sine across, of a cosine down, a diagonal ramp), so that
/// what is compared is the light and the mapping, not the GPU's filter kernel: software
/// Vulkan filters anisotropically with a Gaussian-like kernel even when magnifying,
/// which blurs a random-texel image by up to 70 levels against bilinear filtering.
fn textured_quad(dir: &Path) -> PathBuf {
    textured_quad_placed(dir, None)
}

/// [`textured_quad`] with its node's `matrix` (column-major), when given.
fn textured_quad_placed(dir: &Path, matrix: Option<[f64; 16]>) -> PathBuf {
    let img = image::RgbaImage::from_fn(32, 32, |x, y| {
        let (u, v) = ((x as f32 + 0.5) / 32.0, (y as f32 + 0.5) / 32.0);
        let tau = std::f32::consts::TAU;
        let byte = |c: f32| (c.clamp(0.0, 1.0) * 255.0).round() as u8;
        image::Rgba([
            byte(0.5 + 0.45 * (tau * u).sin()),
            byte(0.5 + 0.45 * (tau * v).cos()),
            byte(0.1 + 0.8 * (u + v) * 0.5),
            255,
        ])
    });
    img.save(dir.join("texture.png")).unwrap();
    let positions: [[f32; 3]; 4] = [
        [-0.5, 0.0, -0.5],
        [-0.5, 0.0, 0.5],
        [0.5, 0.0, 0.5],
        [0.5, 0.0, -0.5],
    ];
    let uvs: [[f32; 2]; 4] = [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]];
    let indices: [u16; 6] = [0, 1, 2, 0, 2, 3];
    let mut bin: Vec<u8> = Vec::new();
    bin.extend(positions.iter().flatten().flat_map(|f| f.to_le_bytes()));
    bin.extend(uvs.iter().flatten().flat_map(|f| f.to_le_bytes()));
    bin.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    std::fs::write(dir.join("quad.bin"), &bin).unwrap();
    let gltf = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [match matrix {
            Some(m) => serde_json::json!({"mesh": 0, "matrix": m}),
            None => serde_json::json!({"mesh": 0}),
        }],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0, "TEXCOORD_0": 1},
            "indices": 2,
            "material": 0
        }]}],
        "materials": [{"pbrMetallicRoughness": {
            "baseColorTexture": {"index": 0}, "metallicFactor": 0.0
        }}],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"wrapS": 33071, "wrapT": 33071}],
        "images": [{"uri": "texture.png"}],
        "buffers": [{"uri": "quad.bin", "byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 32},
            {"buffer": 0, "byteOffset": 80, "byteLength": 12}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [-0.5, 0.0, -0.5], "max": [0.5, 0.0, 0.5]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ]
    });
    let path = dir.join("quad.gltf");
    std::fs::write(&path, serde_json::to_string_pretty(&gltf).unwrap()).unwrap();
    path
}

#[test]
fn a_textured_quad_under_a_uniform_sky_shows_its_texture() {
    let dir = common::scratch_dir("textured-quad");
    let sky = Vec3::new(0.8, 0.6, 0.4);
    let scene =
        radiosity::scene::open(textured_quad(&dir).to_str().unwrap(), Some(sky), None).unwrap();
    // A uniform sky of radiance L = `sky`: H = π L everywhere on the square (it sees only
    // sky), so the displayed radiance at EV 0 is albedo(uv) · H / π = the texture times L
    // (and the 0.999 reflectance clamp).
    let camera = Camera::framing(Vec3::ZERO, 0.3, 0.0, 89f32.to_radians());
    let size = [200, 200];
    let (prepared, image) = solve_and_render(&scene, &camera, size);
    let (errors, expected) = level_errors(&prepared, &camera, &image, |e, p| {
        texel(&scene, &prepared.mesh, e, p).truncate() * sky * 0.999
    });
    image.save(dir.join("rendered.png")).unwrap();
    expected.save(dir.join("expected.png")).unwrap();
    assert!(
        errors.len() > 3 * 20_000,
        "the square fills the view: {}",
        errors.len() / 3
    );
    let (mean, p99) = mean_and_p99(&errors);
    eprintln!(
        "textured quad: {} channel values, mean |Δ| {mean:.2}, p99 {p99}, max {}",
        errors.len(),
        errors.last().unwrap()
    );
    // Tolerance: the texture and the target round to 8 bits (half a level each), the GPU
    // filters in its own fixed-point precision, and a filter wider than bilinear flattens
    // one sine period over 32 texels by about 1 %, about 1 level.
    assert!(mean <= 1.0 && p99 <= 3, "mean {mean}, p99 {p99}");
}

#[test]
fn box_textured_faces_each_show_one_light_level() {
    let Some(scenes) = common::shared_scenes() else {
        return;
    };
    let path = scenes.join("khronos-sample-assets/BoxTextured/glTF/BoxTextured.gltf");
    let scene = radiosity::scene::open(path.to_str().unwrap(), None, None).unwrap();
    // A lone convex box under the uniform sky of radiance 1: every face sees only sky, so
    // H = π on all of it and a pixel over the texture T(uv) shows 0.999 · T(uv). Each face
    // is two triangles whose texture means differ; a display that reconstructed B (which
    // carries those means) instead of H would show the two halves at different levels.
    let prepared0 = common::prepared(&scene, 4000);
    let (centre, radius) = radiosity::view::bounds(&prepared0.mesh).unwrap();
    let camera = Camera::framing(centre, radius, 30f32.to_radians(), 25f32.to_radians());
    let size = [480, 360];
    let (prepared, image) = solve_and_render(&scene, &camera, size);
    let mesh = &prepared.mesh;
    // Per scene triangle, the ratios displayed / texture over texels bright enough to
    // divide by.
    let mut ratios: std::collections::BTreeMap<u32, Vec<f32>> = Default::default();
    for y in 0..size[1] {
        for x in 0..size[0] {
            let Some((e, p)) = visible(&prepared, &camera, size, x, y) else {
                continue;
            };
            let t = texel(&scene, mesh, e, p);
            let got = image.get_pixel(x, y).0;
            let triangle = mesh.patches[mesh.elements[e as usize].patch as usize].scene_triangle;
            for c in 0..3 {
                if t[c] > 0.1 {
                    ratios
                        .entry(triangle)
                        .or_default()
                        .push(linear(got[c]) / t[c]);
                }
            }
        }
    }
    let medians: Vec<(u32, f32, usize)> = ratios
        .into_iter()
        .filter(|(_, r)| r.len() > 500)
        .map(|(t, mut r)| {
            r.sort_by(f32::total_cmp);
            (t, r[r.len() / 2], r.len())
        })
        .collect();
    eprintln!("per triangle (scene index, median displayed / texture, samples): {medians:?}");
    // Three faces in view, two triangles each.
    assert!(medians.len() >= 6, "{medians:?}");
    for &(t, m, _) in &medians {
        // Tolerance: the median is robust to the texels the GPU filters differently near
        // the logo's sharp edges (it uses the mip chain where a face is minified); the
        // 8-bit target rounds by under 0.4 % at these levels.
        assert!(
            (m - 0.999).abs() < 0.02,
            "triangle {t}: displayed / texture {m}"
        );
    }
}

#[test]
fn the_final_gather_shows_the_texture_under_the_gathered_light() {
    let dir = common::scratch_dir("textured-quad-gather");
    let sky = Vec3::new(0.8, 0.6, 0.4);
    let scene =
        radiosity::scene::open(textured_quad(&dir).to_str().unwrap(), Some(sky), None).unwrap();
    // The same closed form as the rasterised test: H = π L at every point of the square,
    // here gathered at each pixel's point on the CPU (`view::gathered`), so the pixel is
    // the texture times L (and the 0.999 reflectance clamp).
    let prepared = common::prepared(&scene, 4000);
    let mut solver = prepared.solver(SolverSettings::default()).unwrap();
    common::converge(&mut solver);
    let gatherer = solver.gatherer(Default::default());
    let textures = radiosity::view::gathered::SurfaceTextures {
        materials: scene.materials.clone(),
        images: scene.images.clone(),
    };
    let camera = Camera::framing(Vec3::ZERO, 0.3, 0.0, 89f32.to_radians());
    let size = [64, 64];
    let view = radiosity::view::gathered::GatheredView {
        gatherer: &gatherer,
        camera: &camera,
        size,
        samples: 1,
        display: Display {
            ev: 0.0,
            tonemap: ToneMap::Clamp,
            textures: true,
            ..Default::default()
        },
        textures: &textures,
    };
    let mut errors = Vec::new();
    for y in 0..size[1] {
        for x in 0..size[0] {
            let Some((e, p)) = visible(&prepared, &camera, size, x, y) else {
                continue;
            };
            let want = texel(&scene, &prepared.mesh, e, p).truncate() * sky * 0.999;
            let got = view.pixel(x, y);
            errors.push((want - got).abs().max_element());
        }
    }
    assert!(
        errors.len() > 2000,
        "the square fills the view: {}",
        errors.len()
    );
    errors.sort_by(f32::total_cmp);
    let p99 = errors[errors.len() * 99 / 100];
    eprintln!(
        "gathered textured quad: {} pixels, p99 |Δ| {p99:.4} (linear)",
        errors.len()
    );
    // Tolerance: the sample lies anywhere in its pixel, not at the centre the truth is read
    // at. The red channel changes by up to 0.45 · 2π/32 · 0.8 ≈ 0.07 per texel, with about 2
    // pixels per texel, so by up to 0.018 within half a pixel; the gather's own error
    // (0.05 % of the light per node) is far below that.
    assert!(p99 < 0.02, "p99 {p99}");
}

#[test]
fn a_mirrored_object_shows_its_texture_mirrored() {
    let dir = common::scratch_dir("textured-quad-mirrored");
    let sky = Vec3::new(0.8, 0.6, 0.4);
    // The square mirrored in x (scale −1, 1, 1): the loader swaps its triangles' winding
    // to keep them counter-clockwise in the world, and each corner must keep its own
    // texture coordinates. The truth: the point (x, 0, z) of the world is the square's
    // local point (−x, 0, z), whose coordinates are (−x + ½, z + ½) (`textured_quad`).
    let mirror = [
        -1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    ];
    let path = textured_quad_placed(&dir, Some(mirror));
    let scene = radiosity::scene::open(path.to_str().unwrap(), Some(sky), None).unwrap();
    let camera = Camera::framing(Vec3::ZERO, 0.3, 0.0, 89f32.to_radians());
    let size = [100, 100];
    let (prepared, image) = solve_and_render(&scene, &camera, size);
    let t = scene.materials[0].base_texture.unwrap();
    let (errors, _) = level_errors(&prepared, &camera, &image, |_, p| {
        let world = prepared.mesh.origin.as_vec3() + p;
        let uv = Vec2::new(-world.x + 0.5, world.z + 0.5);
        scene.images[t.image as usize]
            .sample(0, uv, t.wrap)
            .truncate()
            * sky
            * 0.999
    });
    assert!(
        errors.len() > 3 * 5_000,
        "the square fills the view: {}",
        errors.len() / 3
    );
    let (mean, p99) = mean_and_p99(&errors);
    eprintln!("mirrored textured quad: mean |Δ| {mean:.2}, p99 {p99}");
    // The tolerance of the unmirrored square's test.
    assert!(mean <= 1.0 && p99 <= 3, "mean {mean}, p99 {p99}");
}
