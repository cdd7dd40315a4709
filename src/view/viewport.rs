//! The 3D view: camera controls (orbit, pan, zoom, frame all, the starting view), picking
//! an object by clicking it, and painting the GPU's picture with a stage note while the
//! scene has no mesh yet.

use super::app::App;
use crate::worker::Stage;
use eframe::egui;

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
