//! `radiosity reference`: the unbiased path-traced radiosity at given points, with its
//! standard error, for measuring the solvers against ([`crate::reference`]).

use super::csv::read_points;
use super::options::LightOptions;
use super::progress_bar;
use crate::files::write_atomic;
use crate::reference::{ReferenceSettings, estimate};
use anyhow::Result;
use std::path::Path;

/// Reads `points`, estimates B there in `scene` and writes `ref.csv` to `out`.
pub fn reference(
    scene: &str,
    points: &Path,
    out: &Path,
    settings: &ReferenceSettings,
    lights: &LightOptions,
    quiet: bool,
) -> Result<()> {
    let pts = read_points(points)?;
    let s = crate::scene::open(scene, lights.sky, lights.sun)?;
    if !quiet {
        for w in &s.warnings {
            eprintln!("warning: {w}");
        }
    }
    let bar = progress_bar(quiet);
    bar.set_length(pts.len() as u64);
    let report = |done: usize, _: usize, worst: f64| {
        bar.set_position(done as u64);
        bar.set_message(format!(
            "points at {:.2} %, worst {:.2} %",
            settings.rel_error * 100.0,
            worst * 100.0
        ));
    };
    let estimates = estimate(&s, &pts, settings, &report, crate::cancel::never())?;
    bar.finish_and_clear();
    let mut csv = String::from("x,y,z,r,g,b,sr,sg,sb\n");
    for ((p, _), e) in pts.iter().zip(&estimates) {
        let (v, se) = (e.value, e.std_error);
        csv += &format!(
            "{},{},{},{},{},{},{},{},{}\n",
            p.x, p.y, p.z, v.x, v.y, v.z, se.x, se.y, se.z
        );
    }
    write_atomic(out, csv.as_bytes())?;
    Ok(())
}
