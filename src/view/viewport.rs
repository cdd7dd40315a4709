//! The 3D view: camera controls (orbit, pan, zoom, frame all, the starting view), picking
//! an object by clicking it (and asking the worker for the clicked element's links, drawn
//! over the view: the link inspector), and painting the GPU's picture with a stage note
//! while the scene has no mesh yet.

use super::app::App;
use super::final_gather::{Key, Pass, REST, VIEW_GATHER_ERROR, colour_image};
use super::gathered::SurfaceTextures;
use crate::solver::gather::GatherSettings;
use crate::worker::{Command, Stage};
use eframe::egui;
use glam::Vec3;
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
        self.links_ui(ui.painter(), rect);
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
        // The patch of the side the camera sees (a double-sided triangle has two).
        let patch = hit.and_then(|h| {
            let r = mesh.triangle_patches.get(h.triangle as usize)?;
            let sides = &mesh.patches[r.start as usize..r.end as usize];
            sides
                .iter()
                .find(|p| p.normal.dot(d) < 0.0)
                .or(sides.first())
        });
        s.selected = patch.map(|p| p.object);
        s.material = patch.map(|p| p.material);
        s.inspected = None;
        if let (Some(h), Some(p)) = (hit, patch) {
            self.worker.send(Command::Inspect {
                point: o + d * h.t,
                normal: p.normal,
            });
        }
        self.display.selected = s.selected;
    }

    /// The link inspector over the 3D view (`rect`): a line from each link's receiver
    /// (the clicked element or one of the nodes above it) to its source, coloured by the
    /// light it carries (its hue, and brighter the more it carries of the most any of
    /// them carries), and a dot on the element.
    fn links_ui(&self, painter: &egui::Painter, rect: egui::Rect) {
        let Some(inspected) = &self.session.inspected else {
            return;
        };
        let view_proj = self.camera.view_proj(rect.width() / rect.height().max(1.0));
        let screen = |p: Vec3| {
            let c = view_proj * p.extend(1.0);
            (c.w > 0.0).then(|| {
                let n = c.truncate() / c.w;
                rect.min
                    + egui::vec2(
                        (n.x + 1.0) * 0.5 * rect.width(),
                        (1.0 - n.y) * 0.5 * rect.height(),
                    )
            })
        };
        let most = inspected
            .links
            .iter()
            .map(|l| l.irradiance.max_element())
            .fold(0.0f32, f32::max);
        for l in &inspected.links {
            let (Some(a), Some(b)) = (screen(l.receiver), screen(l.source)) else {
                continue;
            };
            let peak = l.irradiance.max_element();
            let strength = if most > 0.0 {
                (peak / most).sqrt()
            } else {
                0.0
            };
            let hue = if peak > 0.0 {
                l.irradiance / peak
            } else {
                Vec3::ONE
            };
            let [r, g, b8] = (hue * 255.0).to_array().map(|c| c as u8);
            let alpha = (40.0 + 215.0 * strength) as u8;
            let colour = egui::Color32::from_rgba_unmultiplied(r, g, b8, alpha);
            let width = if l.from_cluster { 2.0 } else { 1.0 };
            painter.line_segment([a, b], egui::Stroke::new(width, colour));
        }
        if let Some(c) = screen(inspected.centroid) {
            painter.circle_filled(c, 4.0, egui::Color32::WHITE);
        }
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
