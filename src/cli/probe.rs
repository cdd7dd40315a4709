//! `radiosity probe`: solve, then report the radiosity at given surface points:
//! point-by-point values from the final gather at each point (the default), or the mesh
//! solution as the viewer's reconstruction shows it there.

use super::csv::{read_points, values_csv};
use super::options::{ProbeValue, SolveOptions};
use super::{load_scene, prepare, run_with_progress};
use crate::files::write_atomic;
use crate::pipeline::probe_values;
use anyhow::Result;
use std::path::Path;

/// Reads `points`, solves `scene`, and writes `values.csv` to `out` (standard output when
/// `None`).
pub fn probe(
    scene: &str,
    points: &Path,
    out: Option<&Path>,
    value: ProbeValue,
    options: &SolveOptions,
    quiet: bool,
) -> Result<()> {
    let pts = read_points(points)?;
    let s = load_scene(scene, options, quiet)?;
    let prepared = prepare(&s, options, quiet);
    let mut solver = prepared.solver(options.solver_settings())?;
    run_with_progress(&mut solver, options.time_limit, quiet)?;
    let values = match value {
        ProbeValue::Gather => {
            let t = std::time::Instant::now();
            let values = solver.gatherer(options.gather_settings()).at_points(&pts);
            if !quiet {
                eprintln!(
                    "final gather at {} points: {:.3} s",
                    pts.len(),
                    t.elapsed().as_secs_f64()
                );
            }
            values
        }
        ProbeValue::Mesh(mode) => probe_values(solver.mesh(), &solver.radiosity(), &pts, mode),
    };
    let csv = values_csv(&pts, &values);
    match out {
        Some(path) => Ok(write_atomic(path, csv.as_bytes())?),
        None => {
            print!("{csv}");
            Ok(())
        }
    }
}
