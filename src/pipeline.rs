//! Scene → mesh → BVH → solver, the sequence the command line and the viewer's worker share.

use crate::accel::Bvh;
use crate::light::ExternalLight;
use crate::mesh::{Mesh, MeshSettings, Reconstruction, Reconstructor};
use crate::scene::Scene;
use crate::solver::{Solver, SolverError, SolverSettings};
use glam::{DVec3, Vec3};
use std::sync::Arc;
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
        let t = Instant::now();
        // Meshing builds the BVH itself when it looks for shadow lines (its time is then
        // in `mesh_seconds`).
        let (mesh, bvh) = Mesh::build_keeping_bvh(scene, settings);
        let mesh_seconds = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let bvh = bvh.unwrap_or_else(|| Bvh::build(&mesh.triangles, &mesh.transmittance));
        let bvh_seconds = t.elapsed().as_secs_f64();
        Prepared {
            mesh: Arc::new(mesh),
            bvh: Arc::new(bvh),
            external: ExternalLight {
                lights: scene.lights.clone(),
                environment: scene.environment.clone(),
            },
            mesh_seconds,
            bvh_seconds,
        }
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
    let r = Reconstructor::new(mode, &mesh.display, &mesh.elements, radiosity);
    points
        .iter()
        .map(|(p, n)| match mesh.locate(mesh.to_local(*p), n.as_vec3()) {
            Some((e, bary)) => r.at(&mesh.elements, radiosity, e, bary),
            None => Vec3::ZERO,
        })
        .collect()
}
