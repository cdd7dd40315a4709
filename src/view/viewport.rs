//! The 3D view: camera controls (orbit, pan, zoom, frame all, the starting view), picking
//! an object by clicking it, and painting the GPU's picture with a stage note while the
//! scene has no mesh yet.

use super::app::App;
use super::final_gather::{Key, Pass, REST, VIEW_GATHER_ERROR, colour_image};
use super::gathered::SurfaceTextures;
use crate::solver::gather::GatherSettings;
use crate::worker::{Command, Stage};
use eframe::egui;
use std::time::{Duration, Instant};

impl App {
    /// The 3D view in the rest of `ui`. Left drag orbits, middle drag or shift+left drag
    /// pans, the wheel zooms, a click selects.
    pub(super) fn viewport_ui(&mut self, ui: &mut egui::Ui) {
        let rect = ui.available_rect_before_wrap();
        self.viewport_rect = Some(rect);
        let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
        let shift = ui.input(|i| i.modifiers.shift);
        let delta = response.drag_delta();
        if response.dragged_by(egui::PointerButton::Middle)
            || (response.dragged_by(egui::PointerButton::Primary) && shift)
        {
            self.camera.pan(delta.x, delta.y, rect.height());
        } else if response.dragged_by(egui::PointerButton::Primary) {
            self.camera.orbit(delta.x, delta.y);
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.camera.zoom(scroll);
            }
        }
        if response.clicked()
            && let Some(pos) = response.interact_pointer_pos()
        {
            let p = pos - rect.min;
            self.pick(p.x, p.y, rect.width(), rect.height());
        }
        let ppp = ui.ctx().pixels_per_point();
        let size = [
            (rect.width() * ppp).round().max(1.0) as u32,
            (rect.height() * ppp).round().max(1.0) as u32,
        ];
        let Some(g) = &mut self.gpu else {
            ui.painter()
                .rect_filled(rect, 0.0, egui::Color32::from_gray(20));
            return;
        };
        if self.orbit && self.session.mesh.is_some() {
            self.camera.yaw += 0.5f32.to_radians();
        }
        if let Some(id) = g.draw(size, &self.camera, &self.display, &self.session.uploads) {
            ui.painter().image(
                id,
                rect,
                egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
                egui::Color32::WHITE,
            );
        }
        self.final_gather_ui(ui, rect, size);
        if self.session.mesh.is_none() {
            ui.painter().text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                match self.session.stage {
                    Some(Stage::Loading) => "loading…",
                    Some(Stage::Meshing) => "meshing…",
                    _ => "",
                },
                egui::FontId::proportional(18.0),
                egui::Color32::LIGHT_GRAY,
            );
        }
    }

    /// The final gather over the 3D view (see `final_gather`): asks the worker for the
    /// converged solution prepared for gathering, starts a pass once the camera has rested,
    /// paints what it has so far over the rasterised picture, and says how far it is.
    fn final_gather_ui(&mut self, ui: &egui::Ui, rect: egui::Rect, size: [u32; 2]) {
        let s = &mut self.session;
        if !self.final_gather {
            s.pass = None;
            s.pass_texture = None;
            return;
        }
        let note = |text: String| {
            ui.painter().text(
                rect.left_bottom() + egui::vec2(8.0, -8.0),
                egui::Align2::LEFT_BOTTOM,
                text,
                egui::FontId::proportional(14.0),
                egui::Color32::LIGHT_GRAY,
            );
        };
        let Some(snap) = &s.snapshot else {
            return;
        };
        if self.display.false_colour || self.display.wireframe {
            s.pass = None;
            note("Final gather: shows light only (turn off false colour and wireframe)".into());
            return;
        }
        if !s.converged {
            s.pass = None;
            s.pass_texture = None;
            note("Final gather: waits for the solution to converge".into());
            return;
        }
        let version = snap.version;
        let Some(gatherer) = s.gatherer.as_ref().filter(|(v, _)| *v == version) else {
            if s.gatherer_asked != Some(version) {
                self.worker.send(Command::Gather(GatherSettings {
                    error: VIEW_GATHER_ERROR,
                    ..Default::default()
                }));
                s.gatherer_asked = Some(version);
            }
            note("Final gather: preparing the solution…".into());
            ui.ctx().request_repaint_after(Duration::from_millis(100));
            return;
        };
        let now = Instant::now();
        let rested = match s.camera_rest {
            Some((camera, since)) if camera == self.camera => now - since >= REST,
            _ => {
                s.camera_rest = Some((self.camera, now));
                false
            }
        };
        let key = Key {
            camera: self.camera,
            size,
            ev: self.display.ev,
            tonemap: self.display.tonemap,
            textures: self.display.textures,
            version,
        };
        if s.pass.as_ref().is_some_and(|p| p.key != key) {
            s.pass = None;
            s.pass_texture = None;
        }
        if !rested {
            ui.ctx().request_repaint_after(REST);
            return;
        }
        let pass = s.pass.get_or_insert_with(|| {
            let textures = SurfaceTextures {
                materials: s.materials.clone(),
                images: s.images.clone(),
            };
            Pass::start(key, gatherer.1.clone(), self.display, textures)
        });
        let (finished, done, level, seconds) = {
            let mut p = pass.picture.lock().unwrap_or_else(|e| e.into_inner());
            if p.changed {
                p.changed = false;
                let image = colour_image(&p);
                match &mut s.pass_texture {
                    Some(t) => t.set(image, egui::TextureOptions::NEAREST),
                    None => {
                        s.pass_texture = Some(ui.ctx().load_texture(
                            "final gather",
                            image,
                            egui::TextureOptions::NEAREST,
                        ))
                    }
                }
            }
            (p.finished, p.done, p.level, p.seconds)
        };
        if let Some(t) = &s.pass_texture {
            ui.painter().image(
                t.id(),
                rect,
                egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
                egui::Color32::WHITE,
            );
        }
        if finished {
            note(format!("Final gather: done in {seconds:.1} s"));
        } else {
            note(format!(
                "Final gather: {:.0} % (blocks of {level} px), {seconds:.0} s",
                done * 100.0
            ));
            ui.ctx().request_repaint_after(Duration::from_millis(100));
        }
    }

    /// Selects the object under pixel (`x`, `y`) of a `w`×`h` view, or clears the selection.
    pub fn pick(&mut self, x: f32, y: f32, w: f32, h: f32) {
        let s = &mut self.session;
        let (Some(mesh), Some(bvh)) = (&s.mesh, &s.bvh) else {
            return;
        };
        let (o, d) = self.camera.ray(x, y, w, h);
        let hit = bvh.closest_hit(o, d, 0.0, f32::INFINITY, u32::MAX);
        let patch = hit.and_then(|h| {
            let r = mesh.triangle_patches.get(h.triangle as usize)?;
            (!r.is_empty()).then(|| &mesh.patches[r.start as usize])
        });
        s.selected = patch.map(|p| p.object);
        s.material = patch.map(|p| p.material);
        self.display.selected = s.selected;
    }

    /// The starting view of the scene's mesh ([`super::default_camera`]), once per scene.
    pub(super) fn default_camera(&mut self) {
        let s = &mut self.session;
        if let (Some(mesh), Some(bvh)) = (&s.mesh, &s.bvh) {
            self.camera = super::default_camera(mesh, bvh);
            s.camera_set = true;
        }
    }

    /// Frames the whole mesh, keeping the view direction.
    pub(super) fn frame_all(&mut self) {
        if let Some((c, r)) = self.session.mesh.as_deref().and_then(super::bounds) {
            self.camera.frame(c, r);
        }
    }
}
