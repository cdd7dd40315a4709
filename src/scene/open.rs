//! Opening a scene by name: a glTF path or `builtin:NAME`, with the default light added to
//! scenes that have none.

use super::{Scene, builtin, gltf};
use glam::{DVec3, Vec3};
use std::path::Path;
use std::sync::atomic::AtomicBool;

/// Why a scene could not be opened. Its `Display` is one line naming the scene and the
/// problem.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    /// The glTF file could not be loaded.
    #[error(transparent)]
    Load(#[from] gltf::LoadError),
    /// `builtin:NAME` with a name that is not built in.
    #[error("{spec}: unknown built-in scene (known: {known})")]
    UnknownBuiltin { spec: String, known: String },
    /// The scene loaded but has nothing to light.
    #[error("{spec}: the scene has no triangles")]
    NoTriangles { spec: String },
}

/// Loads `spec` (a path or `builtin:NAME`) and adds `sky`/`sun` (or the default sky) when
/// it has no light ([`Scene::ensure_light`]). Warnings stay in `Scene::warnings`.
pub fn open(spec: &str, sky: Option<Vec3>, sun: Option<(DVec3, Vec3)>) -> Result<Scene, OpenError> {
    open_cancellable(spec, sky, sun, crate::cancel::never())
}

/// [`open`], stopping soon after `cancel` is raised (a glTF load fails with
/// [`gltf::LoadError::Cancelled`]).
pub fn open_cancellable(
    spec: &str,
    sky: Option<Vec3>,
    sun: Option<(DVec3, Vec3)>,
    cancel: &AtomicBool,
) -> Result<Scene, OpenError> {
    let mut scene = match spec.strip_prefix("builtin:") {
        Some(name) => builtin::by_name(name).ok_or_else(|| OpenError::UnknownBuiltin {
            spec: spec.to_string(),
            known: builtin::NAMES.join(", "),
        })?,
        None => gltf::load_cancellable(Path::new(spec), cancel)?,
    };
    if scene.triangle_count() == 0 {
        return Err(OpenError::NoTriangles {
            spec: spec.to_string(),
        });
    }
    scene.ensure_light(sky, sun);
    Ok(scene)
}
