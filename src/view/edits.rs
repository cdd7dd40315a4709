//! Edits of the opened scene: moving objects ([`Placement`]s, with undo and redo) and
//! live material edits, sent to the worker as they are made, and the time from a material
//! edit to the first frame that shows it.

use super::app::App;
use crate::worker::Command;
use glam::{DMat4, DQuat, DVec3, Vec3};
use std::collections::HashMap;
use std::time::{Duration, Instant};

/// An object's placement edit, relative to how it was loaded: about the centre of its
/// loaded bounding box, scale, then rotate (yaw, pitch, roll in degrees), then translate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    pub translate: [f64; 3],
    pub rotate_deg: [f64; 3],
    pub scale: [f64; 3],
}

impl Default for Placement {
    fn default() -> Self {
        Placement {
            translate: [0.0; 3],
            rotate_deg: [0.0; 3],
            scale: [1.0; 3],
        }
    }
}

impl Placement {
    /// World-from-local after this edit of an object loaded with `base`, centred at `c`.
    pub fn apply(&self, base: DMat4, c: DVec3) -> DMat4 {
        let [y, p, r] = self.rotate_deg.map(f64::to_radians);
        let rot = DQuat::from_euler(glam::EulerRot::YXZ, y, p, r);
        DMat4::from_translation(c + DVec3::from_array(self.translate))
            * DMat4::from_quat(rot)
            * DMat4::from_scale(DVec3::from_array(self.scale))
            * DMat4::from_translation(-c)
            * base
    }
}

/// One placement change: the object, its placement before and after.
pub(super) type Move = (u32, Placement, Placement);

/// The edits of one opened scene.
#[derive(Default)]
pub(super) struct Edits {
    /// Each object's world-from-local as first loaded; placements are relative to it.
    pub(super) base: Vec<DMat4>,
    /// The objects placed so far: placement and the centre it turns about (world frame).
    pub(super) placements: HashMap<u32, (Placement, DVec3)>,
    /// Moves that undo takes back, the newest last.
    pub(super) undo: Vec<Move>,
    /// Moves undone that redo makes again, the newest undone last.
    pub(super) redo: Vec<Move>,
    /// The placement fields being edited (object, values) before they are committed.
    pub(super) draft: Option<(u32, Placement)>,
    /// When the last material edit was sent, and the version of the first snapshot that
    /// carries it once it has arrived.
    pub(super) edit_sent: Option<(Instant, Option<u64>)>,
    /// Time from the last material edit to the frame that first showed it.
    pub(super) edit_latency: Option<Duration>,
}

impl App {
    /// Sends a material edit (reflectance ρ linear, emitted radiance L_e) to the worker.
    pub fn edit_material(&mut self, material: u32, reflectance: Vec3, emission: Vec3) {
        let s = &mut self.session;
        if let Some(m) = s.materials.get_mut(material as usize) {
            m.reflectance = reflectance;
            m.emission = emission;
            self.worker.send(Command::SetMaterial {
                material,
                reflectance,
                emission,
            });
            s.edits.edit_sent = Some((Instant::now(), None));
            s.converged = false;
        }
    }

    /// Places object `object` by `placement` (relative to how it was loaded), with undo.
    pub fn place(&mut self, object: u32, placement: Placement) {
        let s = &mut self.session;
        let Some(mesh) = &s.mesh else { return };
        let entry = s.edits.placements.entry(object).or_insert_with(|| {
            // Centre of the object's loaded bounding box, world frame.
            let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            for p in mesh.patches.iter().filter(|p| p.object == object) {
                for v in p.verts {
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
            let c = if lo.x <= hi.x {
                ((lo + hi) * 0.5).as_dvec3() + mesh.origin
            } else {
                DVec3::ZERO
            };
            (Placement::default(), c)
        });
        let before = entry.0;
        if before == placement {
            return;
        }
        s.edits.undo.push((object, before, placement));
        s.edits.redo.clear();
        self.send_placement(object, placement);
    }

    /// Takes back the newest move.
    pub fn undo(&mut self) {
        if let Some((o, before, after)) = self.session.edits.undo.pop() {
            self.session.edits.redo.push((o, before, after));
            self.send_placement(o, before);
        }
    }

    /// Makes the newest undone move again.
    pub fn redo(&mut self) {
        if let Some((o, before, after)) = self.session.edits.redo.pop() {
            self.session.edits.undo.push((o, before, after));
            self.send_placement(o, after);
        }
    }

    /// Records `placement` as object `object`'s and sends its transform to the worker,
    /// which meshes the scene again. Nothing happens for an object never placed.
    fn send_placement(&mut self, object: u32, placement: Placement) {
        let s = &mut self.session;
        let Some(base) = s.edits.base.get(object as usize).copied() else {
            return;
        };
        let Some(entry) = s.edits.placements.get_mut(&object) else {
            return;
        };
        entry.0 = placement;
        s.edits.draft = None;
        let m = placement.apply(base, entry.1);
        self.worker.send(Command::SetTransform {
            object,
            world_from_local: m,
        });
        s.converged = false;
        self.status = format!("moving object {object}: meshing again");
    }
}
