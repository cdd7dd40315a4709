//! What the GPU holds and when it draws: the renderer with its offscreen target and egui
//! texture ([`Gpu`], for the whole window), the opened scene's mesh, snapshot values and
//! Hermite vertex slopes on the GPU ([`Uploads`], per scene), snapshot uploads throttled
//! by their own measured cost, auto exposure after each upload, and the 3D picture drawn
//! again only when what it depends on changes.

use super::app::App;
use super::camera::Camera;
use super::render::{Display, GpuMesh, Renderer, Target};
use super::textures::{GpuTextures, TextureMemory};
use crate::mesh::{Mesh, Reconstruction};
use crate::worker::Command;
use eframe::egui;
use eframe::egui_wgpu;
use glam::Vec3;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The renderer and what it draws into, for the life of the window.
pub(super) struct Gpu {
    state: egui_wgpu::RenderState,
    renderer: Renderer,
    target: Option<Target>,
    /// `target` registered with egui.
    texture: Option<egui::TextureId>,
    /// What the 3D target shows now: it is drawn again only when this changes.
    drawn: Option<DrawKey>,
    /// When the last 3D draw started and what it cost (the interval to the next frame).
    last_draw: Option<(Instant, Duration)>,
    draw_started: Option<Instant>,
}

/// The opened scene on the GPU.
#[derive(Default)]
pub(super) struct Uploads {
    /// The scene's images, uploaded when it loads.
    textures: Option<GpuTextures>,
    /// The scene's current mesh.
    mesh: Option<GpuMesh>,
    /// The reflectance and emission on the GPU (they change only with edits).
    surfaces: Option<crate::worker::Surfaces>,
    /// The snapshot version whose values are on the GPU; 0 while `mesh` has none.
    pub(super) uploaded: u64,
    /// The snapshot version whose Hermite vertex slopes are on the GPU (0: none for this
    /// mesh).
    pub(super) hermite: u64,
    /// What the last snapshot upload cost, and when it ended.
    cost: Duration,
    last: Option<Instant>,
}

/// Everything the 3D picture depends on.
#[derive(Clone, Copy, PartialEq)]
struct DrawKey {
    camera: Camera,
    display: Display,
    uploaded: u64,
    hermite: u64,
    size: [u32; 2],
}

impl Gpu {
    pub(super) fn new(state: egui_wgpu::RenderState) -> Gpu {
        Gpu {
            renderer: Renderer::new(&state.device),
            state,
            target: None,
            texture: None,
            drawn: None,
            last_draw: None,
            draw_started: None,
        }
    }

    /// The adapter's name and backend.
    pub(super) fn adapter(&self) -> String {
        super::render::adapter_name(&self.state.adapter)
    }

    /// Draws the 3D picture of `uploads` into a target of `size` pixels when it is due,
    /// and returns the egui texture that shows the target.
    ///
    /// What a person did (camera, size, display choices) is drawn at once, and so are a
    /// first snapshot and the Hermite data a display choice asked for. What the solver did
    /// (a new snapshot, and the auto exposure that follows it) waits until the last draw
    /// has had 4× its cost to itself, so on a slow (software) renderer most frames stay
    /// cheap while a big scene streams. An unchanged picture is not drawn again.
    pub(super) fn draw(
        &mut self,
        size: [u32; 2],
        camera: &Camera,
        display: &Display,
        uploads: &Uploads,
    ) -> Option<egui::TextureId> {
        if self.target.as_ref().is_none_or(|t| t.size != size) {
            let target = Target::new(&self.state.device, size);
            let mut r = self.state.renderer.write();
            match self.texture {
                Some(id) => r.update_egui_texture_from_wgpu_texture(
                    &self.state.device,
                    &target.encoded_view,
                    eframe::wgpu::FilterMode::Linear,
                    id,
                ),
                None => {
                    self.texture = Some(r.register_native_texture(
                        &self.state.device,
                        &target.encoded_view,
                        eframe::wgpu::FilterMode::Linear,
                    ))
                }
            }
            self.target = Some(target);
        }
        // Hermite display shows Gouraud until the worker's first Hermite data for this
        // mesh are on the GPU, and then the newest it sent.
        let mut display = *display;
        if display.reconstruction == Reconstruction::Hermite && uploads.hermite == 0 {
            display.reconstruction = Reconstruction::Gouraud;
        }
        let display = &display;
        let key = DrawKey {
            camera: *camera,
            display: *display,
            uploaded: uploads.uploaded,
            hermite: uploads.hermite,
            size,
        };
        let urgent = self.drawn.is_none_or(|k| {
            let mut d = k.display;
            d.ev = display.ev;
            d.log_range = display.log_range;
            k.camera != *camera
                || k.size != size
                || d != *display
                || (k.uploaded == 0) != (uploads.uploaded == 0)
                || k.hermite != uploads.hermite
        });
        // The frame after a draw: the interval since it started is the draw's cost.
        if let Some(t) = self.draw_started.take() {
            self.last_draw = Some((t, t.elapsed()));
        }
        let due = self
            .last_draw
            .is_none_or(|(t, cost)| t.elapsed() >= cost * 4);
        if let Some(target) = &self.target
            && self.drawn != Some(key)
            && (urgent || due)
        {
            self.drawn = Some(key);
            self.draw_started = Some(Instant::now());
            self.renderer.render(
                &self.state.device,
                &self.state.queue,
                target,
                if uploads.uploaded > 0 {
                    uploads.mesh.as_ref()
                } else {
                    None
                },
                camera,
                display,
            );
        }
        self.texture
    }
}

impl App {
    /// Puts a new mesh of the opened scene on the GPU. It shows nothing until a snapshot
    /// for it is uploaded; the snapshot held (for the old mesh) is dropped.
    pub(super) fn upload_mesh(&mut self, mesh: &Mesh) {
        let s = &mut self.session;
        let u = &mut s.uploads;
        if let Some(g) = &self.gpu {
            let (device, queue) = (&g.state.device, &g.state.queue);
            let textures = u
                .textures
                .get_or_insert_with(|| GpuTextures::new(device, queue, &s.images));
            u.mesh = Some(
                g.renderer
                    .upload(device, queue, mesh, &s.materials, textures),
            );
        }
        u.uploaded = 0;
        u.hermite = 0;
        u.surfaces = None;
        s.snapshot = None;
    }

    /// What the scene's textures cost on the GPU (`None` before they are uploaded).
    pub fn texture_memory(&self) -> Option<TextureMemory> {
        self.session
            .uploads
            .textures
            .as_ref()
            .map(GpuTextures::memory)
    }

    /// Uploads the newest snapshot unless the last upload was too recent for its cost.
    pub(super) fn upload(&mut self) {
        let s = &mut self.session;
        let Some(snap) = &s.snapshot else { return };
        let u = &mut s.uploads;
        if snap.version == u.uploaded {
            return;
        }
        // A fresh GPU mesh has nothing to show: upload at once. Otherwise at most a quarter
        // of the time goes to uploads.
        if u.uploaded != 0
            && let Some(t) = u.last
            && t.elapsed() < u.cost * 3
        {
            return;
        }
        let Some(g) = &self.gpu else { return };
        let Some(gm) = &u.mesh else { return };
        let start = Instant::now();
        let same = |a: &Arc<[Vec3]>, b: &Arc<[Vec3]>| Arc::ptr_eq(a, b);
        if u.surfaces
            .as_ref()
            .is_none_or(|(r, e)| !same(r, &snap.reflectance) || !same(e, &snap.emission))
            && gm.set_surfaces(&g.state.queue, &snap.reflectance, &snap.emission)
        {
            u.surfaces = Some((Arc::clone(&snap.reflectance), Arc::clone(&snap.emission)));
        }
        if u.surfaces.is_some() && gm.set_values(&g.state.queue, &snap.irradiance, &snap.vertex) {
            u.uploaded = snap.version;
            // The edit's first snapshot is on the GPU and is drawn this frame.
            if let Some((t, Some(v))) = s.edits.edit_sent
                && u.uploaded >= v
            {
                s.edits.edit_latency = Some(t.elapsed());
                s.edits.edit_sent = None;
            }
        }
        u.cost = start.elapsed();
        u.last = Some(Instant::now());
        if self.auto_exposure {
            self.expose();
        }
    }

    /// Hermite display needs the vertex values and slopes of the uploaded snapshot: the
    /// worker adds them to its snapshots while the display asks (`Command::SetHermite`),
    /// and they are uploaded when the mode is on and they are missing, so the other modes
    /// never pay for them.
    pub(super) fn upload_hermite(&mut self) {
        let want = self.display.reconstruction == Reconstruction::Hermite;
        if want != self.hermite_asked {
            self.worker.send(Command::SetHermite(want));
            self.hermite_asked = want;
            // Snapshots without it may follow: what is on the GPU would go stale.
            self.session.uploads.hermite = 0;
        }
        let s = &mut self.session;
        if !want || s.uploads.uploaded == 0 || s.uploads.hermite == s.uploads.uploaded {
            return;
        }
        let (Some(g), Some(snap)) = (&self.gpu, &s.snapshot) else {
            return;
        };
        let Some(gm) = &s.uploads.mesh else { return };
        if !gm.supports_hermite() {
            self.display.reconstruction = Reconstruction::Gouraud;
            self.status = "too many elements for Hermite display on this device".into();
            return;
        }
        // A snapshot made before the worker heard the request has no Hermite data: the
        // next one will.
        if snap.version == s.uploads.uploaded
            && let Some(hermite) = &snap.hermite
            && gm.set_hermite(&g.state.queue, hermite)
        {
            s.uploads.hermite = s.uploads.uploaded;
        }
    }

    /// Sets the exposure and the false-colour range from the newest snapshot, metered on
    /// the current view (`view_exposure`).
    fn expose(&mut self) {
        let s = &mut self.session;
        let aspect = self
            .viewport_rect
            .map_or(1.0, |r| r.width() / r.height().max(1.0));
        if let (Some(snap), Some(mesh), Some(bvh)) = (&s.snapshot, &s.mesh, &s.bvh)
            && let Some((ev, range)) =
                super::view_exposure(mesh, bvh, &snap.radiosity, &self.camera, aspect)
        {
            self.display.ev = ev;
            self.display.log_range = range;
        }
        s.metered = Some(self.camera);
    }

    /// With auto exposure on, meters the view again when the camera has moved since it
    /// last did (about 1,500 rays, a few milliseconds).
    pub(super) fn meter_view(&mut self) {
        if self.auto_exposure
            && self.session.snapshot.is_some()
            && self.session.metered != Some(self.camera)
        {
            self.expose();
        }
    }
}
