//! `radiosity bench`: error against a reference over time for each method
//! (convergence.csv, convergence.png), and occlusion-ray throughput (`--occlusion`).

use super::csv::read_table;
use super::{SolveOptions, prepare};
use crate::files::write_atomic;
use crate::mesh::Reconstruction;
use crate::pipeline::Prepared;
use crate::pipeline::probe_values;
use crate::scene::Scene;
use crate::solver::{MAX_DIRECT_PATCHES, MAX_MATRIX_PAIRS, Method, SolverSettings, StepOutcome};
use anyhow::{Context, Result};
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

/// What errors are measured against.
enum Reference {
    /// Per-element values on the same mesh.
    Elements(Vec<Vec3>, String),
    /// Values at points (world position, normal), compared after reconstruction.
    Points(Vec<(DVec3, DVec3)>, Vec<Vec3>),
}

/// One row of convergence.csv.
struct Row {
    method: Method,
    seconds: f64,
    iterations: u64,
    rays: u64,
    unshot: Option<f64>,
    residual: Option<f64>,
    rms: f64,
    max: f64,
}

/// Relative errors of `values` against `reference`, area-weighted over elements:
/// rms = sqrt(Σ A‖B − R‖² / Σ A‖R‖²), max = max ‖B − R‖∞ / sqrt(Σ A‖R‖² / (3 Σ A)).
fn element_errors(values: &[Vec3], reference: &[Vec3], areas: &[f32]) -> (f64, f64) {
    let (mut num, mut den, mut area, mut max) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for ((b, r), a) in values.iter().zip(reference).zip(areas) {
        let d = (*b - *r).as_dvec3();
        num += d.length_squared() * *a as f64;
        den += r.as_dvec3().length_squared() * *a as f64;
        area += *a as f64;
        max = max.max(d.abs().max_element());
    }
    if den <= 0.0 {
        return (0.0, 0.0);
    }
    ((num / den).sqrt(), max / (den / (3.0 * area)).sqrt())
}

fn point_errors(values: &[Vec3], reference: &[Vec3]) -> (f64, f64) {
    let areas = vec![1.0f32; values.len()];
    element_errors(values, reference, &areas)
}

fn compute_reference(prepared: &Prepared, spec: &str, quiet: bool) -> Result<Reference> {
    if spec != "direct" {
        let rows = read_table(
            Path::new(spec),
            &["x", "y", "z", "nx", "ny", "nz", "r", "g", "b"],
        )?;
        let points = rows
            .iter()
            .map(|r| (DVec3::new(r[0], r[1], r[2]), DVec3::new(r[3], r[4], r[5])))
            .collect();
        let values = rows
            .iter()
            .map(|r| Vec3::new(r[6] as f32, r[7] as f32, r[8] as f32))
            .collect();
        return Ok(Reference::Points(points, values));
    }
    let (n, m) = (prepared.mesh.elements.len(), prepared.mesh.patches.len());
    let (method, tolerance, what) =
        if m <= MAX_DIRECT_PATCHES && n.saturating_mul(m) <= MAX_MATRIX_PAIRS {
            (Method::Direct, 0.0, "direct solve")
        } else if n.saturating_mul(m) <= MAX_MATRIX_PAIRS {
            (Method::GaussSeidel, 1e-7, "Gauss–Seidel to residual 1e-7")
        } else {
            (Method::Progressive, 1e-5, "progressive to unshot 1e-5")
        };
    if !quiet {
        eprintln!("reference: {what} on {n} elements, {m} patches");
    }
    let mut solver = prepared.solver(SolverSettings {
        method,
        tolerance,
        ..Default::default()
    })?;
    solver.run(None, &AtomicBool::new(false))?;
    Ok(Reference::Elements(solver.radiosity(), what.to_string()))
}

/// `bench SCENE --out DIR`: runs each method against the reference, writes the curves.
pub fn convergence(
    scene: &Scene,
    options: &SolveOptions,
    methods: Option<Vec<Method>>,
    reference: &str,
    time_limit: f64,
    out: &Path,
    quiet: bool,
) -> Result<()> {
    std::fs::create_dir_all(out)
        .with_context(|| format!("{}: cannot create folder", out.display()))?;
    let prepared = prepare(scene, options, quiet);
    let mesh = &prepared.mesh;
    println!(
        "{}: {} triangles, {} patches, {} elements; mesh {:.3} s, BVH {:.3} s",
        scene.name,
        scene.triangle_count(),
        mesh.patches.len(),
        mesh.elements.len(),
        prepared.mesh_seconds,
        prepared.bvh_seconds
    );
    let t = Instant::now();
    let reference = compute_reference(&prepared, reference, quiet)?;
    let reference_seconds = t.elapsed().as_secs_f64();
    let areas: Vec<f32> = mesh.elements.iter().map(|e| e.area).collect();
    let errors = |values: &[Vec3]| match &reference {
        Reference::Elements(r, _) => element_errors(values, r, &areas),
        Reference::Points(p, r) => point_errors(
            &probe_values(&prepared.mesh, values, p, Reconstruction::Gouraud),
            r,
        ),
    };
    let methods = methods.unwrap_or(Method::ALL.to_vec());
    // Each method runs to 1e-5 (or the given tolerance if tighter) so the curves pass well
    // below 1 % error, or until the time limit.
    let tolerance = options.tolerance.min(1e-5);
    let mut rows: Vec<Row> = Vec::new();
    let mut summary = String::new();
    for method in methods {
        let settings = SolverSettings {
            method,
            tolerance,
            // Short steps give the curve its resolution; stats.seconds counts only step time.
            step_budget: Duration::from_millis(5),
            form_factors: options.solver_settings().form_factors,
            ..Default::default()
        };
        let mut solver = match prepared.solver(settings) {
            Ok(s) => s,
            Err(e) => {
                println!("{method}: skipped ({e})");
                continue;
            }
        };
        let cancel = AtomicBool::new(false);
        let first = rows.len();
        loop {
            let outcome = solver.step(&cancel)?;
            let s = solver.stats();
            let (rms, max) = errors(&solver.radiosity());
            rows.push(Row {
                method,
                seconds: s.seconds,
                iterations: s.iterations,
                rays: s.rays,
                unshot: s.unshot_fraction,
                residual: s.residual,
                rms,
                max,
            });
            if outcome != StepOutcome::Working || s.seconds >= time_limit {
                break;
            }
        }
        let mine = &rows[first..];
        let to_1pct = mine.iter().find(|r| r.rms <= 0.01).map(|r| r.seconds);
        let last = mine.last().context("no step ran")?;
        let line = format!(
            "{:<17} time to 1% RMS: {:>9}  final: {:.3} s, {} iterations, RMS {:.2e}, max {:.2e}{}",
            method.name(),
            to_1pct.map_or("never".into(), |t| format!("{t:.3} s")),
            last.seconds,
            last.iterations,
            last.rms,
            last.max,
            if solver.is_converged() {
                ""
            } else {
                " (time limit)"
            }
        );
        println!("{line}");
        summary += &line;
        summary.push('\n');
    }
    let label = match &reference {
        Reference::Elements(_, what) => format!("{what}, {reference_seconds:.2} s"),
        Reference::Points(p, _) => format!("{} reference points", p.len()),
    };
    let mut csv = String::from(
        "method,seconds,iterations,rays,unshot_fraction,residual,rms_error,max_error\n",
    );
    for r in &rows {
        let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:e}"));
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{:e},{:e}",
            r.method,
            r.seconds,
            r.iterations,
            r.rays,
            opt(r.unshot),
            opt(r.residual),
            r.rms,
            r.max
        );
    }
    write_atomic(&out.join("convergence.csv"), csv.as_bytes())?;
    let png = plot(&rows, &format!("{} — vs {label}", scene.name))?;
    write_atomic(&out.join("convergence.png"), &png)?;
    println!(
        "wrote {} and {}",
        out.join("convergence.csv").display(),
        out.join("convergence.png").display()
    );
    Ok(())
}

/// Registers DejaVu Sans with plotters if the system has it; returns whether text can be drawn.
pub fn register_font() -> bool {
    use std::sync::OnceLock;
    static OK: OnceLock<bool> = OnceLock::new();
    *OK.get_or_init(|| {
        for path in [
            "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
            "/usr/share/fonts/TTF/DejaVuSans.ttf",
            "/usr/share/fonts/dejavu/DejaVuSans.ttf",
        ] {
            if let Ok(bytes) = std::fs::read(path) {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font(
                    "sans-serif",
                    plotters::style::FontStyle::Normal,
                    bytes,
                )
                .is_ok()
                {
                    return true;
                }
            }
        }
        false
    })
}

/// RMS error against seconds, log-log, one curve per method, as PNG bytes.
fn plot(rows: &[Row], title: &str) -> Result<Vec<u8>> {
    use plotters::prelude::*;
    let (w, h) = (960u32, 600u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    let text = register_font();
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE)
            .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
        let pos = rows.iter().filter(|r| r.rms > 0.0 && r.seconds > 0.0);
        let (t0, t1) = pos.clone().fold((f64::INFINITY, 0.0f64), |(a, b), r| {
            (a.min(r.seconds), b.max(r.seconds))
        });
        let (e0, e1) = pos.fold((f64::INFINITY, 0.0f64), |(a, b), r| {
            (a.min(r.rms), b.max(r.rms))
        });
        let (t0, t1) = if t0.is_finite() {
            (t0 * 0.8, t1 * 1.25)
        } else {
            (1e-3, 1.0)
        };
        let (e0, e1) = if e0.is_finite() {
            (e0 * 0.5, e1 * 2.0)
        } else {
            (1e-6, 1.0)
        };
        let mut builder = ChartBuilder::on(&root);
        builder.margin(20);
        if text {
            builder
                .caption(title, ("sans-serif", 20))
                .x_label_area_size(45)
                .y_label_area_size(70);
        }
        let mut chart = builder
            .build_cartesian_2d((t0..t1).log_scale(), (e0..e1).log_scale())
            .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
        let mut mesh = chart.configure_mesh();
        if text {
            mesh.x_desc("solver seconds")
                .y_desc("RMS relative error")
                .x_label_formatter(&|v| format!("{v:.2e}"))
                .y_label_formatter(&|v| format!("{v:.0e}"));
        } else {
            mesh.disable_x_axis().disable_y_axis();
        }
        mesh.draw().map_err(|e| anyhow::anyhow!("plot: {e}"))?;
        let colours = [RED, BLUE, GREEN, MAGENTA, CYAN, BLACK];
        for (k, method) in Method::ALL.iter().enumerate() {
            let pts: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.method == *method && r.rms > 0.0 && r.seconds > 0.0)
                .map(|r| (r.seconds, r.rms))
                .collect();
            if pts.is_empty() {
                continue;
            }
            let colour = colours[k % colours.len()];
            let series = chart
                .draw_series(LineSeries::new(pts.clone(), colour.stroke_width(2)))
                .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
            if text {
                series.label(method.name()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                });
            }
            chart
                .draw_series(pts.iter().map(|p| Circle::new(*p, 2, colour.filled())))
                .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
        }
        if text {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
        }
        root.present().map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    }
    let img = image::RgbImage::from_raw(w, h, buf).context("plot buffer size")?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    Ok(png)
}

/// `bench --occlusion`: segments between pairs of points drawn uniformly by area over the
/// scene's triangles (fixed seed), timed single-threaded and on all threads.
pub fn occlusion(scene: &Scene, segments: usize) -> Result<()> {
    let t = Instant::now();
    let prepared = Prepared::new(scene, &Default::default());
    let setup = t.elapsed().as_secs_f64();
    let mesh = &prepared.mesh;
    let bvh = &prepared.bvh;
    let pairs = crate::accel::sample_segments(&mesh.triangles, segments)
        .ok_or_else(|| anyhow::anyhow!("{}: the scene has no surface area", scene.name))?;
    let t = Instant::now();
    let blocked_1: usize = pairs
        .iter()
        .filter(|(a, b, s)| bvh.transmittance(*a, *b, *s) < 1.0)
        .count();
    let single = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let blocked_n: usize = pairs
        .par_iter()
        .filter(|(a, b, s)| bvh.transmittance(*a, *b, *s) < 1.0)
        .count();
    let multi = t.elapsed().as_secs_f64();
    anyhow::ensure!(
        blocked_1 == blocked_n,
        "occlusion differs between thread counts"
    );
    println!(
        "{}: {} triangles, mesh+BVH {:.3} s; {} segments, {:.1} % occluded",
        scene.name,
        scene.triangle_count(),
        setup,
        segments,
        100.0 * blocked_1 as f64 / segments.max(1) as f64
    );
    println!(
        "1 thread:  {:.3} s, {:.2} M rays/s",
        single,
        segments as f64 / single / 1e6
    );
    println!(
        "{} threads: {:.3} s, {:.2} M rays/s",
        rayon::current_num_threads(),
        multi,
        segments as f64 / multi / 1e6
    );
    Ok(())
}
