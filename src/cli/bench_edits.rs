//! `radiosity bench SCENE --edits N --out DIR`: how fast a converged solve follows material
//! edits. After convergence, N reflectance changes of ±30 % on materials drawn with a fixed
//! seed, one at a time; for each, the milliseconds from the edit until the first solution
//! that includes it (the edit itself where the method updates the edited elements at once,
//! as the progressive and hierarchical methods do; otherwise the first step after it,
//! steps of 1 ms) and until the solve has converged again to its tolerance. Written to
//! `DIR/edits.csv` with the header `material,first_update_ms,converged_ms`.

use super::options::SolveOptions;
use crate::files::write_atomic;
use crate::geometry::sampling::hash;
use crate::scene::Scene;
use crate::solver::{PatchEdit, StepOutcome};
use anyhow::{Context, Result};
use glam::Vec3;
use std::path::Path;
use std::time::{Duration, Instant};

/// Runs the edit benchmark; prints p50 / p95 of both latencies.
pub fn edits(
    scene: &Scene,
    options: &SolveOptions,
    n: usize,
    out: &Path,
    quiet: bool,
) -> Result<()> {
    let prepared = super::prepare(scene, options, quiet);
    let mut settings = options.solver_settings();
    settings.step_budget = Duration::from_millis(1);
    let method = settings.method;
    let mut solver = prepared.solver(settings)?;
    let cancel = crate::cancel::never();
    let limit = options.time_limit.map(Duration::from_secs_f64);
    if solver.run(limit, cancel)? != StepOutcome::Converged {
        anyhow::bail!(
            "{}: the first solve did not converge within the time limit",
            scene.name
        );
    }
    // Materials some patch uses and that reflect light.
    let mesh = solver.mesh().clone();
    let mut used: Vec<u32> = mesh.patches.iter().map(|p| p.material).collect();
    used.sort_unstable();
    used.dedup();
    let mut rho: Vec<Vec3> = scene.materials.iter().map(|m| m.reflectance).collect();
    used.retain(|&m| rho[m as usize].max_element() > 0.0);
    anyhow::ensure!(
        !used.is_empty(),
        "{}: no reflecting material to edit",
        scene.name
    );
    let mut csv = String::from("material,first_update_ms,converged_ms\n");
    let (mut first, mut done) = (Vec::new(), Vec::new());
    for k in 0..n {
        let h = hash(0xed17 ^ k as u64);
        let m = used[(h % used.len() as u64) as usize];
        let factor = if (h >> 32) & 1 == 0 { 1.3 } else { 0.7 };
        rho[m as usize] = (rho[m as usize] * factor).min(Vec3::splat(0.999));
        let mesh = solver.mesh().clone();
        let edits: Vec<PatchEdit> = mesh
            .patches
            .iter()
            .enumerate()
            .filter(|(_, p)| p.material == m)
            .map(|(i, p)| PatchEdit {
                patch: i as u32,
                reflectance: rho[m as usize]
                    * (p.reflectance
                        / scene.materials[m as usize]
                            .reflectance
                            .max(Vec3::splat(1e-6))),
                emission: p.emission,
            })
            .collect();
        let t = Instant::now();
        let shown = solver.edit_patches(&edits);
        let mut first_ms = t.elapsed().as_secs_f64() * 1e3;
        let mut outcome = solver.step(cancel)?;
        if !shown {
            first_ms = t.elapsed().as_secs_f64() * 1e3;
        }
        while outcome == StepOutcome::Working {
            if limit.is_some_and(|l| t.elapsed() >= l) {
                break;
            }
            outcome = solver.step(cancel)?;
        }
        let converged_ms = t.elapsed().as_secs_f64() * 1e3;
        csv.push_str(&format!("{m},{first_ms:.3},{converged_ms:.3}\n"));
        first.push(first_ms);
        done.push(converged_ms);
    }
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    write_atomic(&out.join("edits.csv"), csv.as_bytes())?;
    let pct = |v: &mut Vec<f64>, q: f64| {
        v.sort_by(f64::total_cmp);
        v[((v.len() - 1) as f64 * q).round() as usize]
    };
    println!(
        "{}: {method}, {n} edits: first update p50 {:.1} ms, p95 {:.1} ms; converged p50 {:.1} ms, p95 {:.1} ms",
        scene.name,
        pct(&mut first, 0.5),
        pct(&mut first, 0.95),
        pct(&mut done, 0.5),
        pct(&mut done, 0.95),
    );
    println!("wrote {}", out.join("edits.csv").display());
    Ok(())
}
