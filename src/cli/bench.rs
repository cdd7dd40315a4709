//! `radiosity bench`: error against a reference over time for each method
//! (convergence.csv, convergence.png), and occlusion-ray throughput (`--occlusion`).

use super::csv::read_table;
use super::{SolveOptions, prepare};
use crate::files::write_atomic;
use crate::geometry::sampling::hash;
use crate::mesh::Reconstruction;
use crate::pipeline::Prepared;
use crate::pipeline::{locate_patches, probe_values_on};
use crate::reference::probes::{self, Class, ProbeCounts};
use crate::reference::{ReferenceSettings, Surfaces, estimate};
use crate::scene::Scene;
use crate::solver::{
    MAX_DIRECT_PATCHES, MAX_MATRIX_PAIRS, Method, SolverSettings, Stats, StepOutcome,
};
use anyhow::{Context, Result};
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

/// What errors are measured against.
enum Reference {
    /// Per-element values on the same mesh (the solver's convergence, not the truth).
    Elements(Vec<Vec3>, String),
    /// Values at points (world position, normal), compared after reconstruction (the
    /// viewer's Hermite), with each point's class when known.
    Points {
        points: Vec<(DVec3, DVec3)>,
        values: Vec<Vec3>,
        /// Each value's own standard error, when known (the path-traced reference).
        std_errors: Option<Vec<Vec3>>,
        classes: Option<Vec<Class>>,
        label: String,
    },
}

/// Which reference `bench` measures against.
pub struct ReferenceSpec<'a> {
    /// `path`, `direct` or a CSV file of values.
    pub kind: &'a str,
    /// With `path`: the path tracer's target standard error, relative to
    /// max(B, 2 % of the mean B) per channel.
    pub rel_error: f64,
}

/// One row of convergence.csv.
struct Row {
    /// The method, with "+gather" for its final gather at the points.
    label: String,
    seconds: f64,
    iterations: u64,
    rays: u64,
    unshot: Option<f64>,
    residual: Option<f64>,
    rms: f64,
    max: f64,
    /// RMS and max of the per-point error for each class of point present.
    classes: Vec<(Class, f64, f64)>,
}

/// Overall (rms, max) and per class (class, rms, max) errors of one solution.
type Errors = ((f64, f64), Vec<(Class, f64, f64)>);

impl Row {
    /// A row labelled `label` for a solver with `stats`, at `seconds`, with `errors`.
    fn new(label: String, stats: &Stats, seconds: f64, ((rms, max), classes): Errors) -> Row {
        Row {
            label,
            seconds,
            iterations: stats.iterations,
            rays: stats.rays,
            unshot: stats.unshot_fraction,
            residual: stats.residual,
            rms,
            max,
            classes,
        }
    }
}

/// Prints the per-class lines under a method's summary.
fn print_classes(classes: &[(Class, f64, f64)]) {
    for (class, rms, max) in classes {
        println!("    {:<9} RMS {:.2e}, max {:.2e}", class.name(), rms, max);
    }
}

/// Prints the reference's own noise: the RMS over the points (overall and per class) of
/// its standard error in the per-point metric, ‖σ‖ / ‖max(R, 0.02 · mean R)‖. A solution
/// exactly right everywhere would show about this much error against the reference;
/// independent errors add in squares, so sqrt(RMS² − noise²) is what is left of a
/// measured RMS once the reference's noise is taken out.
fn print_reference_noise(values: &[Vec3], std_errors: &[Vec3], classes: Option<&[Class]>) {
    let shifted: Vec<Vec3> = values
        .iter()
        .zip(std_errors)
        .map(|(v, s)| *v + *s)
        .collect();
    let noise = point_errors(&shifted, values);
    let mut line = format!(
        "reference noise, RMS per point: all {:.2e}",
        rms_max(noise.iter().copied()).0
    );
    for (class, rms, _) in classes.map_or(Vec::new(), |c| per_class(&noise, c)) {
        let _ = write!(line, ", {} {rms:.2e}", class.name());
    }
    println!("{line}");
}

/// RMS and max of `errors` over the points of each class present in `classes` (the
/// points' classes, in the same order), in [`Class::ALL`]'s order.
fn per_class(errors: &[f64], classes: &[Class]) -> Vec<(Class, f64, f64)> {
    Class::ALL
        .into_iter()
        .filter(|k| classes.contains(k))
        .map(|k| {
            let of_class = errors.iter().zip(classes).filter(|(_, c)| **c == k);
            let (rms, max) = rms_max(of_class.map(|(e, _)| *e));
            (k, rms, max)
        })
        .collect()
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

/// The per-point relative error of `values` against `reference`:
/// ‖B − R‖ / ‖max(R, 0.02 · mean R)‖ (Euclidean norms over RGB, the max per channel), so a
/// dark point is measured against a floor of 2 % of the mean instead of its own near-zero
/// value, and bright surfaces do not outweigh dark ones.
pub fn point_errors(values: &[Vec3], reference: &[Vec3]) -> Vec<f64> {
    let n = reference.len().max(1) as f64;
    let mean = reference.iter().map(|r| r.as_dvec3()).sum::<DVec3>() / n;
    let floor = mean * 0.02;
    values
        .iter()
        .zip(reference)
        .map(|(b, r)| {
            let denom = r.as_dvec3().max(floor).length();
            let d = (*b - *r).as_dvec3().length();
            if denom > 0.0 { d / denom } else { 0.0 }
        })
        .collect()
}

/// RMS and max of `errors`.
fn rms_max(errors: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut sum, mut max, mut n) = (0.0, 0.0f64, 0usize);
    for e in errors {
        sum += e * e;
        max = max.max(e);
        n += 1;
    }
    if n == 0 {
        (0.0, 0.0)
    } else {
        ((sum / n as f64).sqrt(), max)
    }
}

fn compute_reference(
    scene: &Scene,
    prepared: &Prepared,
    spec: &ReferenceSpec,
    out: &Path,
    quiet: bool,
) -> Result<Reference> {
    if spec.kind == "path" {
        return path_reference(scene, spec.rel_error, out, quiet);
    }
    let spec = spec.kind;
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
        return Ok(Reference::Points {
            points,
            values,
            std_errors: None,
            classes: None,
            label: format!("the reference values in {spec}"),
        });
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

/// The path-traced reference at probe points picked for `scene` ([`probes::pick`]), to
/// `rel_error` standard error, cached in `out` by scene and settings (`reference-KEY.csv`,
/// with each point's class), so a second bench of the same scene reuses it.
fn path_reference(scene: &Scene, rel_error: f64, out: &Path, quiet: bool) -> Result<Reference> {
    let settings = ReferenceSettings {
        rel_error,
        // A bound so a scene with points lit only by rare paths still finishes (10 minutes
        // at the default 1 %; a tighter reference needs (1 %/rel_error)² as many samples).
        time_limit: Some(Duration::from_secs_f64(
            600.0 * (0.01 / rel_error).powi(2).max(1.0),
        )),
        ..Default::default()
    };
    let counts = ProbeCounts::default();
    let key = cache_key(scene, &settings, &counts);
    let cache = out.join(format!("reference-{key:016x}.csv"));
    let label = |n: usize, what: &str| {
        format!(
            "path-traced reference at {n} probe points ({}% standard error{what})",
            settings.rel_error * 100.0
        )
    };
    if let Ok(rows) = read_table(
        &cache,
        &[
            "x", "y", "z", "nx", "ny", "nz", "class", "r", "g", "b", "sr", "sg", "sb",
        ],
    ) {
        let points = rows
            .iter()
            .map(|r| (DVec3::new(r[0], r[1], r[2]), DVec3::new(r[3], r[4], r[5])))
            .collect();
        let classes = rows
            .iter()
            .map(|r| Class::ALL[(r[6] as usize).min(Class::ALL.len() - 1)])
            .collect();
        let values = rows
            .iter()
            .map(|r| Vec3::new(r[7] as f32, r[8] as f32, r[9] as f32))
            .collect();
        let std_errors = rows
            .iter()
            .map(|r| Vec3::new(r[10] as f32, r[11] as f32, r[12] as f32))
            .collect();
        if !quiet {
            eprintln!("reference: {} (cached)", cache.display());
        }
        return Ok(Reference::Points {
            label: label(rows.len(), ", cached"),
            points,
            values,
            std_errors: Some(std_errors),
            classes: Some(classes),
        });
    }
    let surfaces = Surfaces::new(scene);
    let bvh = crate::accel::Bvh::build(&surfaces.triangles, &surfaces.transmittance);
    let probes = probes::pick(&surfaces, &bvh, &counts, settings.seed);
    let points: Vec<(DVec3, DVec3)> = probes.iter().map(|p| (p.point, p.normal)).collect();
    let bar = super::progress_bar(quiet);
    bar.set_length(points.len() as u64);
    let report = |done: usize, _: usize, worst: f64| {
        bar.set_position(done as u64);
        bar.set_message(format!("reference: worst {:.2} %", worst * 100.0));
    };
    let estimates = estimate(scene, &points, &settings, &report, crate::cancel::never())?;
    bar.finish_and_clear();
    // Points the path tracer finds black away from shadows are a class of their own
    // (`Class::Dark`): the light a solution puts there leaks through walls, and it
    // should not hide in the error of what a person sees.
    let classes: Vec<Class> = probes
        .iter()
        .zip(&estimates)
        .map(|(p, e)| probes::with_reference(p.class, e.value, e.samples))
        .collect();
    let mut csv = String::from("x,y,z,nx,ny,nz,class,r,g,b,sr,sg,sb\n");
    for ((p, e), class) in probes.iter().zip(&estimates).zip(&classes) {
        let class = Class::ALL.iter().position(|c| c == class).unwrap_or(0);
        let (v, se) = (e.value, e.std_error);
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{class},{},{},{},{},{},{}",
            p.point.x,
            p.point.y,
            p.point.z,
            p.normal.x,
            p.normal.y,
            p.normal.z,
            v.x,
            v.y,
            v.z,
            se.x,
            se.y,
            se.z
        );
    }
    write_atomic(&cache, csv.as_bytes())?;
    if !quiet {
        let mut counts = String::new();
        for c in Class::ALL {
            let n = classes.iter().filter(|k| **k == c).count();
            let _ = write!(counts, " {} {n}", c.name());
        }
        eprintln!(
            "reference: {} points ({counts}), {}",
            probes.len(),
            cache.display()
        );
    }
    Ok(Reference::Points {
        label: label(probes.len(), ""),
        points,
        values: estimates.iter().map(|e| e.value.as_vec3()).collect(),
        std_errors: Some(estimates.iter().map(|e| e.std_error.as_vec3()).collect()),
        classes: Some(classes),
    })
}

/// A key for the reference cache: the scene (name, triangles, lights) and the settings.
fn cache_key(scene: &Scene, settings: &ReferenceSettings, counts: &ProbeCounts) -> u64 {
    let text = format!(
        "{}|{}|{}|{:?}|{:?}|{}|{}|{:?}",
        probes::SCHEME,
        scene.name,
        scene.triangle_count(),
        scene.lights,
        scene.environment,
        settings.rel_error,
        settings.seed,
        counts
    );
    text.bytes()
        .fold(0xcbf2_9ce4_8422_2325u64, |h, b| hash(h ^ b as u64))
}

/// How much a method's step time grows between two points of its convergence curve.
const SAMPLE_GROWTH: f64 = 1.02;

/// The solve's time at which the final gather at the points is first taken on the way;
/// then each time the solve's time has doubled (see `GatherCurve`).
const FIRST_GATHER_SECONDS: f64 = 0.25;

/// The final gather at the reference points taken on the way, not only at the end: how
/// fast the gathered answer gets how close. A gather is due each time the solve's time has
/// doubled since the last one, while the gathers so far have cost no more than the solve
/// (on Sponza one takes 30 s, on the Cornell box 0.5 s); each row stands at the solve's
/// time plus that gather's own, what a user waits for that answer.
struct GatherCurve {
    next: f64,
    spent: f64,
    rows: Vec<Row>,
}

impl GatherCurve {
    fn new() -> GatherCurve {
        GatherCurve {
            next: FIRST_GATHER_SECONDS,
            spent: 0.0,
            rows: Vec::new(),
        }
    }

    /// Whether a gather is due at solve time `seconds` (always at the solve's end).
    fn due(&self, seconds: f64, last: bool) -> bool {
        last || (seconds >= self.next && self.spent <= seconds)
    }

    /// Gathers at `points` from `solver`'s solution as it is, and keeps the row.
    fn take(
        &mut self,
        solver: &crate::solver::Solver,
        points: &[(glam::DVec3, glam::DVec3)],
        settings: crate::solver::gather::GatherSettings,
        label: &str,
        errors: impl Fn(&[Vec3]) -> Errors,
    ) {
        let t = Instant::now();
        let values = solver.gatherer(settings).at_points(points);
        let gather_seconds = t.elapsed().as_secs_f64();
        let s = solver.stats();
        self.spent += gather_seconds;
        self.next = 2.0 * s.seconds.max(self.next);
        let row = Row::new(
            label.to_string(),
            s,
            s.seconds + gather_seconds,
            errors(&values),
        );
        self.rows.push(row);
    }
}

/// `bench SCENE --out DIR`: runs each method against the reference, writes the curves.
pub fn convergence(
    scene: &Scene,
    options: &SolveOptions,
    methods: Option<Vec<Method>>,
    reference: &ReferenceSpec,
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
    let reference = compute_reference(scene, &prepared, reference, out, quiet)?;
    let reference_seconds = t.elapsed().as_secs_f64();
    if let Reference::Points {
        values,
        std_errors: Some(std_errors),
        classes,
        ..
    } = &reference
    {
        print_reference_noise(values, std_errors, classes.as_deref());
    }
    let areas: Vec<f32> = mesh.elements.iter().map(|e| e.area).collect();
    // Overall (rms, max) and per class, of values at the reference points.
    let point_stats = |at_points: &[Vec3]| match &reference {
        Reference::Elements(..) => ((0.0, 0.0), Vec::new()),
        Reference::Points {
            values: r, classes, ..
        } => {
            let e = point_errors(at_points, r);
            let per_class = classes.as_ref().map_or(Vec::new(), |c| per_class(&e, c));
            (rms_max(e.iter().copied()), per_class)
        }
    };
    // The points' patches, located once: no method's refinement changes them.
    let patches = match &reference {
        Reference::Points { points, .. } => locate_patches(mesh, points),
        Reference::Elements(..) => Vec::new(),
    };
    // The same, for a solution on `mesh` (its Hermite reconstruction at the points, or its
    // elements against the elements).
    let errors = |mesh: &crate::mesh::Mesh, values: &[Vec3]| match &reference {
        Reference::Elements(r, _) => (element_errors(values, r, &areas), Vec::new()),
        Reference::Points { points, .. } => point_stats(&probe_values_on(
            mesh,
            values,
            points,
            &patches,
            Reconstruction::Hermite,
        )),
    };
    let truth = matches!(reference, Reference::Points { .. });
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
            // Against the truth, each method runs as the command line runs it (adaptive
            // refinement included); against the same mesh, the mesh must stay.
            adaptive: if truth {
                options.solver_settings().adaptive
            } else {
                None
            },
            hierarchy: options.solver_settings().hierarchy,
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
        let mut gathers = GatherCurve::new();
        let gather_label = format!("{}+gather", method.name());
        loop {
            let outcome = solver.step(&cancel)?;
            let s = solver.stats();
            let last = outcome != StepOutcome::Working || s.seconds >= time_limit;
            // The curve is sampled where the solve's time has grown by 2 % since the last
            // sample (and at its end), so that measuring (a reconstruction of the whole
            // mesh: ~0.3 s on Sponza) does not take longer than solving. Times read off the
            // curve, such as the time to 1 %, are late by at most those 2 %.
            let due = rows[first..]
                .last()
                .is_none_or(|r| s.seconds >= r.seconds * SAMPLE_GROWTH);
            if due || last {
                let errors = errors(solver.mesh(), &solver.radiosity());
                rows.push(Row::new(method.name().to_string(), s, s.seconds, errors));
            }
            if let Reference::Points { points, .. } = &reference
                && gathers.due(s.seconds, last)
            {
                let settings = options.gather_settings();
                gathers.take(&solver, points, settings, &gather_label, point_stats);
            }
            if last {
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
        print_classes(&last.classes);
        summary += &line;
        summary.push('\n');
        if let (Reference::Points { points, .. }, Some(row)) = (&reference, gathers.rows.last()) {
            // The final gather at the points from the converged (or last) solution, and the
            // first time a gather on the way was within 1 %.
            let to_1pct = gathers.rows.iter().find(|r| r.rms <= 0.01);
            println!(
                "{:<17} time to 1% RMS: {:>9}  final gather at {} points: {:.3} s, RMS {:.2e}, max {:.2e} ({} gathers)",
                row.label,
                to_1pct.map_or("never".into(), |r| format!("{:.3} s", r.seconds)),
                points.len(),
                row.seconds - last.seconds,
                row.rms,
                row.max,
                gathers.rows.len()
            );
            print_classes(&row.classes);
            rows.append(&mut gathers.rows);
        }
    }
    let (label, metric) = match &reference {
        Reference::Elements(_, what) => (
            format!("{what}, {reference_seconds:.2} s"),
            "element-norm relative: sqrt(ΣA‖B−R‖² / ΣA‖R‖²)",
        ),
        Reference::Points { label, .. } => (
            label.clone(),
            "per-point relative: ‖B−R‖ / ‖max(R, 0.02·mean R)‖",
        ),
    };
    let classes: Vec<Class> = Class::ALL
        .into_iter()
        .filter(|c| rows.iter().any(|r| r.classes.iter().any(|(k, ..)| k == c)))
        .collect();
    let mut csv =
        String::from("method,seconds,iterations,rays,unshot_fraction,residual,rms_error,max_error");
    for c in &classes {
        let _ = write!(csv, ",rms_{0},max_{0}", c.name());
    }
    csv += ",reference,metric\n";
    for r in &rows {
        let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:e}"));
        let _ = write!(
            csv,
            "{},{},{},{},{},{},{:e},{:e}",
            r.label,
            r.seconds,
            r.iterations,
            r.rays,
            opt(r.unshot),
            opt(r.residual),
            r.rms,
            r.max
        );
        for c in &classes {
            match r.classes.iter().find(|(k, ..)| k == c) {
                Some((_, rms, max)) => {
                    let _ = write!(csv, ",{rms:e},{max:e}");
                }
                None => csv += ",,",
            }
        }
        let _ = writeln!(csv, ",\"{label}\",\"{metric}\"");
    }
    write_atomic(&out.join("convergence.csv"), csv.as_bytes())?;
    let short = match &reference {
        Reference::Elements(..) => "RMS error vs the same mesh's direct solve (element norm)",
        Reference::Points { .. } => "RMS per-point error vs the truth (‖B−R‖ / ‖max(R, 2 % mean)‖)",
    };
    let png = plot(&rows, &format!("{} — vs {label}", scene.name), short)?;
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
fn plot(rows: &[Row], title: &str, y_label: &str) -> Result<Vec<u8>> {
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
                .y_desc(y_label)
                .x_label_formatter(&|v| format!("{v:.2e}"))
                .y_label_formatter(&|v| format!("{v:.0e}"));
        } else {
            mesh.disable_x_axis().disable_y_axis();
        }
        mesh.draw().map_err(|e| anyhow::anyhow!("plot: {e}"))?;
        let colours = [RED, BLUE, GREEN, MAGENTA, CYAN, BLACK];
        let mut labels: Vec<&str> = Vec::new();
        for r in rows {
            if !labels.contains(&r.label.as_str()) {
                labels.push(&r.label);
            }
        }
        for (k, label) in labels.iter().enumerate() {
            let pts: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.label == *label && r.rms > 0.0 && r.seconds > 0.0)
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
                series.label(*label).legend(move |(x, y)| {
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
/// scene's triangles (fixed seed), timed single-threaded and on all threads (best of
/// three runs each).
pub fn occlusion(scene: &Scene, segments: usize, out: Option<&Path>) -> Result<()> {
    let t = Instant::now();
    let prepared = Prepared::new(scene, &Default::default());
    let setup = t.elapsed().as_secs_f64();
    let mesh = &prepared.mesh;
    let bvh = &prepared.bvh;
    let pairs = crate::accel::sample_segments(&mesh.triangles, segments)
        .ok_or_else(|| anyhow::anyhow!("{}: the scene has no surface area", scene.name))?;
    if let Some(out) = out {
        let mut bytes = b"RADSEG1".to_vec();
        bytes.extend((mesh.triangles.len() as u64).to_le_bytes());
        bytes.extend((pairs.len() as u64).to_le_bytes());
        for t in &mesh.triangles {
            for v in t {
                bytes.extend(v.to_array().iter().flat_map(|c| c.to_le_bytes()));
            }
        }
        for (a, b, _) in &pairs {
            for v in [a, b] {
                bytes.extend(v.to_array().iter().flat_map(|c| c.to_le_bytes()));
            }
        }
        write_atomic(out, &bytes)?;
    }
    // Best of three runs each: one run of 10⁶ rays lasts a fifth of a second, where a
    // scheduler hiccup on the other core shows as ±5 %.
    let best_of_3 = |trace: &dyn Fn() -> usize| {
        let mut best = f64::INFINITY;
        let mut blocked = 0;
        for _ in 0..3 {
            let t = Instant::now();
            blocked = trace();
            best = best.min(t.elapsed().as_secs_f64());
        }
        (blocked, best)
    };
    let (blocked_1, single) = best_of_3(&|| {
        pairs
            .iter()
            .filter(|(a, b, s)| bvh.transmittance(*a, *b, *s) < 1.0)
            .count()
    });
    let (blocked_n, multi) = best_of_3(&|| {
        pairs
            .par_iter()
            .filter(|(a, b, s)| bvh.transmittance(*a, *b, *s) < 1.0)
            .count()
    });
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
