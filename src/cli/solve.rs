//! `radiosity solve`: solve a scene to the tolerance or time limit; print a summary, and
//! optionally write the baked .glb and the stats JSON.

use super::options::SolveOptions;
use super::{load_scene, prepare, run_with_progress};
use crate::export::{Bake, baked_glb};
use crate::files::write_atomic;
use crate::solver::{Stats, StepOutcome};
use anyhow::Result;
use std::path::Path;

/// The stats JSON of `solve --stats`.
#[derive(serde::Serialize)]
struct StatsFile<'a> {
    scene: &'a str,
    triangles: usize,
    element_size: f64,
    mesh_seconds: f64,
    bvh_seconds: f64,
    #[serde(flatten)]
    stats: &'a Stats,
}

/// Solves `scene`; writes the baked glTF to `out` and the statistics to `stats` when given.
pub fn solve(
    scene: &str,
    options: &SolveOptions,
    out: Option<&Path>,
    stats: Option<&Path>,
    quiet: bool,
) -> Result<()> {
    let s = load_scene(scene, options, quiet)?;
    let prepared = prepare(&s, options, quiet);
    let mut solver = prepared.solver(options.solver_settings())?;
    let outcome = run_with_progress(&mut solver, options.time_limit, quiet)?;
    let st = solver.stats();
    println!(
        "{}: {} triangles, {} patches, {} elements; {} in {:.3} s ({} iterations, {} rays), residual {}, energy balance {}{}",
        s.name,
        s.triangle_count(),
        st.patches,
        st.elements,
        solver.settings().method,
        st.seconds,
        st.iterations,
        st.rays,
        st.residual.map_or("-".into(), |r| format!("{r:.2e}")),
        st.energy_balance.map_or("-".into(), |r| format!("{r:.4}")),
        if outcome == StepOutcome::Converged {
            ""
        } else {
            " (time limit; not converged)"
        }
    );
    if let Some(path) = stats {
        let file = StatsFile {
            scene: &s.name,
            triangles: s.triangle_count(),
            element_size: prepared.mesh.element_size,
            mesh_seconds: prepared.mesh_seconds,
            bvh_seconds: prepared.bvh_seconds,
            stats: st,
        };
        write_atomic(path, serde_json::to_string_pretty(&file)?.as_bytes())?;
    }
    if let Some(path) = out {
        // The solver's mesh: adaptive refinement may have replaced the prepared one.
        let mesh = solver.mesh();
        let radiosity = solver.radiosity();
        let ev = crate::exposure::auto_exposure(mesh, &radiosity).map_or(0.0, |a| a.0);
        let (reflectance, emission) = (solver.reflectance(), solver.emission());
        let bake = Bake {
            radiosity: &radiosity,
            reflectance: &reflectance,
            emission: &emission,
            exposure: 2f32.powf(ev),
            tonemap: Default::default(),
        };
        write_atomic(path, &baked_glb(&s, mesh, &bake))?;
    }
    Ok(())
}
