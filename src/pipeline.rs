//! Scene → mesh → BVH → solver, the sequence the command line and the viewer's worker share.

use crate::accel::Bvh;
use crate::cancel::{Cancelled, check};
use crate::light::ExternalLight;
use crate::mesh::{Mesh, MeshSettings, Reconstruction, Reconstructor};
use crate::scene::Scene;
use crate::solver::{Solver, SolverError, SolverSettings};
use glam::{DVec3, Vec3};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// A meshed scene with its visibility structure, ready to solve.
pub struct Prepared {
    pub mesh: Arc<Mesh>,
    pub bvh: Arc<Bvh>,
    pub external: ExternalLight,
    /// Seconds spent meshing and building the BVH.
    pub mesh_seconds: f64,
    pub bvh_seconds: f64,
}

impl Prepared {
    /// Meshes `scene` and builds its BVH.
    pub fn new(scene: &Scene, settings: &MeshSettings) -> Prepared {
        match Prepared::new_cancellable(scene, settings, crate::cancel::never()) {
            Ok(prepared) => prepared,
            Err(Cancelled) => unreachable!("the never-raised cancel flag was raised"),
        }
    }

    /// [`Prepared::new`], stopped with `Err(Cancelled)` soon after `cancel` is raised:
    /// meshing looks at it between and inside its stages, and it is looked at before and
    /// after the BVH build (which cannot be interrupted).
    pub fn new_cancellable(
        scene: &Scene,
        settings: &MeshSettings,
        cancel: &AtomicBool,
    ) -> Result<Prepared, Cancelled> {
        let t = Instant::now();
        // Meshing builds the BVH itself when it looks for shadow lines (its time is then
        // in `mesh_seconds`).
        let (mesh, bvh) = Mesh::build_cancellable(scene, settings, cancel)?;
        let mesh_seconds = t.elapsed().as_secs_f64();
        check(cancel)?;
        let t = Instant::now();
        let bvh = bvh.unwrap_or_else(|| Bvh::build(&mesh.triangles, &mesh.transmittance));
        let bvh_seconds = t.elapsed().as_secs_f64();
        check(cancel)?;
        Ok(Prepared {
            mesh: Arc::new(mesh),
            bvh: Arc::new(bvh),
            external: ExternalLight {
                lights: scene.lights.clone(),
                environment: scene.environment.clone(),
            },
            mesh_seconds,
            bvh_seconds,
        })
    }

    /// A solver over this mesh.
    pub fn solver(&self, settings: SolverSettings) -> Result<Solver, SolverError> {
        Solver::new(
            Arc::clone(&self.mesh),
            Arc::clone(&self.bvh),
            self.external.clone(),
            settings,
        )
    }
}

/// Reconstructed radiosity at world points with outward normals (zero where no element
/// faces that way).
pub fn probe_values(
    mesh: &Mesh,
    radiosity: &[Vec3],
    points: &[(DVec3, DVec3)],
    mode: Reconstruction,
) -> Vec<Vec3> {
    let patches = locate_patches(mesh, points);
    probe_values_on(mesh, radiosity, points, &patches, mode)
}

/// The patch under each of `points` (world position, normal; see [`Mesh::locate_patch`]).
/// Refinement never changes a mesh's patches, so these serve every later solution of it.
pub fn locate_patches(mesh: &Mesh, points: &[(DVec3, DVec3)]) -> Vec<Option<u32>> {
    use rayon::prelude::*;
    points
        .par_iter()
        .map(|(p, n)| mesh.locate_patch(mesh.to_local(*p), n.as_vec3()))
        .collect()
}

/// [`probe_values`] at points whose patches are known ([`locate_patches`]).
pub fn probe_values_on(
    mesh: &Mesh,
    radiosity: &[Vec3],
    points: &[(DVec3, DVec3)],
    patches: &[Option<u32>],
    mode: Reconstruction,
) -> Vec<Vec3> {
    let r = Reconstructor::new(mode, &mesh.display, &mesh.elements, radiosity);
    points
        .iter()
        .zip(patches)
        .map(|((p, _), patch)| match patch {
            Some(patch) => {
                let (e, bary) = mesh.locate_in_patch(mesh.to_local(*p), *patch);
                r.at(&mesh.elements, radiosity, e, bary)
            }
            None => Vec3::ZERO,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_raised_flag_stops_preparing() {
        let scene = crate::scene::builtin::by_name("cornell").expect("built-in Cornell box");
        let raised = AtomicBool::new(true);
        let settings = MeshSettings::default();
        assert!(matches!(
            Prepared::new_cancellable(&scene, &settings, &raised),
            Err(Cancelled)
        ));
        let down = AtomicBool::new(false);
        let prepared = Prepared::new_cancellable(&scene, &settings, &down).unwrap();
        assert_eq!(
            prepared.mesh.elements.len(),
            Prepared::new(&scene, &settings).mesh.elements.len()
        );
    }
}
