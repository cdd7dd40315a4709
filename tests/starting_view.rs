//! The viewer's and `render`'s starting view (`radiosity::view::default_camera`) shows the
//! scene: most of what its rays meet are surfaces seen from their front (or double-sided),
//! not the backs of one-sided surfaces, which draw black. The truth here is geometric: which
//! side of each triangle a camera ray meets.

mod common;

use radiosity::cli::SolveOptions;
use radiosity::geometry::triangle_cross;
use radiosity::pipeline::Prepared;

/// Over a 32 × 20 grid of the view's rays: the share of the frame that meets the scene,
/// and the share of those that meet a surface from its front.
fn what_the_starting_view_sees(spec: &str) -> (f64, f64) {
    let options = SolveOptions::default();
    let scene = radiosity::cli::load_scene(spec, &options, true).unwrap();
    let prepared = Prepared::new(&scene, &options.mesh_settings());
    let mesh = &prepared.mesh;
    let camera = radiosity::view::default_camera(mesh, &prepared.bvh);
    let (w, h) = (32.0f32, 20.0f32);
    let (mut hits, mut fronts, mut rays) = (0usize, 0usize, 0usize);
    for j in 0..20 {
        for i in 0..32 {
            let (eye, d) = camera.ray(i as f32 + 0.5, j as f32 + 0.5, w, h);
            rays += 1;
            let Some(hit) = prepared
                .bvh
                .closest_hit(eye, d, 0.0, f32::INFINITY, u32::MAX)
            else {
                continue;
            };
            hits += 1;
            let facing = triangle_cross(&mesh.triangles[hit.triangle as usize]).dot(d) < 0.0;
            if facing || mesh.double_sided(hit.triangle) {
                fronts += 1;
            }
        }
    }
    (
        hits as f64 / rays as f64,
        fronts as f64 / hits.max(1) as f64,
    )
}

#[test]
fn the_starting_view_looks_at_the_fronts_of_the_scene_s_surfaces() {
    let Some(dir) = common::shared_scenes() else {
        return;
    };
    let scenes = [
        "builtin:cornell".to_string(),
        // Open at the front, its logo through the very centre of its bounds: the view stood
        // inside the logo (fronts 0 %, the picture black) until rays from the centre took
        // only what lies beyond a tenth of the bounds' radius.
        dir.join("cornell-box-vinc3r/cornellBox-2.80-Eevee-gltf.gltf")
            .display()
            .to_string(),
        dir.join("cornell-box-nvpro/cornellBox.gltf")
            .display()
            .to_string(),
        // A closed object: seen from outside.
        dir.join("khronos-sample-assets/Duck/glTF-Quantized/Duck.gltf")
            .display()
            .to_string(),
    ];
    for spec in scenes {
        let (in_frame, fronts) = what_the_starting_view_sees(&spec);
        eprintln!(
            "{spec}: {:.0} % of the frame on the scene, {:.0} % of it fronts",
            in_frame * 100.0,
            fronts * 100.0
        );
        // A tenth of the frame at least: the scene is in view, not a speck (the view
        // frames the bounds' sphere, so a box fills about a fifth of it). Nine tenths
        // fronts: a picture of surfaces lit on the side the light reaches (what is left
        // are silhouettes and the odd back face seen through an opening).
        assert!(
            in_frame >= 0.1,
            "{spec}: {in_frame} of the frame shows the scene"
        );
        assert!(
            fronts >= 0.9,
            "{spec}: {fronts} of what the view sees are fronts"
        );
    }
}
