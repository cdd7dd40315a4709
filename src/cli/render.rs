//! `radiosity render`: solve, then draw the viewer's picture offscreen with the same wgpu
//! renderer, camera defaults and auto exposure, or gather every pixel's visible point
//! (`--final-gather`) with the same camera, exposure and tone mapping.

use super::options::{RenderOptions, SolveOptions};
use super::{load_scene, prepare, run_with_progress};
use crate::accel::Bvh;
use crate::mesh::Mesh;
use crate::view;
use crate::view::camera::Camera;
use crate::view::gathered::{GatheredView, SurfaceTextures, to_image};
use crate::view::render::{Display, Solution, render_image};
use anyhow::Result;
use glam::Vec3;
use std::path::Path;

/// Solves `scene` with `options` and writes the rendered PNG to `out`.
pub fn render(
    scene: &str,
    out: &Path,
    picture: &RenderOptions,
    options: &SolveOptions,
    quiet: bool,
) -> Result<()> {
    let s = load_scene(scene, options, quiet)?;
    // A machine that cannot draw the picture says so before the solve, not after.
    let headless = if picture.final_gather {
        None
    } else {
        Some(view::render::headless_device()?)
    };
    let prepared = prepare(&s, options, quiet);
    let mut solver = prepared.solver(options.solver_settings())?;
    run_with_progress(&mut solver, options.time_limit, quiet)?;
    let Some(headless) = headless else {
        anyhow::ensure!(
            !picture.false_colour && !picture.wireframe,
            "--final-gather draws tone-mapped light only (no --false-colour or --wireframe)"
        );
        let gatherer = solver.gatherer(options.gather_settings());
        let (camera, display) = view_of(solver.mesh(), &prepared.bvh, &solver.radiosity(), picture);
        let textures = SurfaceTextures {
            materials: s.materials.clone(),
            images: s.images.clone(),
        };
        let view = GatheredView {
            gatherer: &gatherer,
            camera: &camera,
            size: [picture.size.0, picture.size.1],
            samples: picture.samples,
            display,
            textures: &textures,
        };
        let bar = super::progress_bar(quiet);
        bar.set_length(picture.size.1 as u64);
        bar.set_message("final gather, rows");
        let t = std::time::Instant::now();
        let pixels = view.image(&|rows| bar.set_position(rows as u64));
        bar.finish_and_clear();
        view::write_png(out, &to_image(view.size, &pixels))?;
        if !quiet {
            eprintln!(
                "rendered {} by final gather in {:.1} s ({}×{} pixels, {} samples each)",
                out.display(),
                t.elapsed().as_secs_f64(),
                picture.size.0,
                picture.size.1,
                picture.samples.max(1).pow(2)
            );
        }
        return Ok(());
    };
    let radiosity = solver.radiosity();
    let (reflectance, emission) = (solver.reflectance(), solver.emission());
    let solution = Solution {
        radiosity: &radiosity,
        reflectance: &reflectance,
        emission: &emission,
    };
    let (camera, display) = view_of(solver.mesh(), &prepared.bvh, &radiosity, picture);
    let image = render_image(
        &headless,
        solver.mesh(),
        &solution,
        &s.materials,
        &s.images,
        &camera,
        &display,
        [picture.size.0, picture.size.1],
    )?;
    view::write_png(out, &image)?;
    if !quiet {
        eprintln!(
            "rendered {} with {} (EV {:.2}, {} tone map)",
            out.display(),
            headless.adapter,
            display.ev,
            display.tonemap.name()
        );
    }
    Ok(())
}

/// The camera and display `picture` asks for: the viewer's starting camera and auto
/// exposure unless given.
fn view_of(
    mesh: &Mesh,
    bvh: &Bvh,
    radiosity: &[Vec3],
    picture: &RenderOptions,
) -> (Camera, Display) {
    let mut camera = view::default_camera(mesh, bvh);
    if let Some((yaw, pitch, zoom)) = picture.camera {
        camera.yaw = yaw.to_radians();
        camera.pitch = pitch.clamp(-89.0, 89.0).to_radians();
        camera.distance *= zoom;
    }
    let aspect = picture.size.0 as f32 / picture.size.1 as f32;
    let auto = view::view_exposure(mesh, bvh, radiosity, &camera, aspect);
    let display = Display {
        reconstruction: picture.mode,
        ev: picture.ev.or(auto.map(|a| a.0)).unwrap_or(0.0),
        tonemap: picture.tonemap,
        false_colour: picture.false_colour,
        log_range: auto.map(|a| a.1).unwrap_or((-2.0, 2.0)),
        wireframe: picture.wireframe,
        selected: None,
        textures: !picture.no_textures,
    };
    (camera, display)
}
