//! The command line (DESIGN.md §5): `solve`, `probe`, `bench` and `render` drive scene →
//! mesh → accel → solver directly, with no thread and no window; `view` (the default with
//! no subcommand) opens the viewer. Errors surface as one line naming
//! the file and the problem, and exit status 1.

use crate::export::{baked_glb, write_atomic};
use crate::mesh::{AdaptiveSettings, MeshSettings, Reconstruction};
use crate::pipeline::Prepared;
use crate::scene::{Scene, builtin};
use crate::solver::form_factor::FormFactorSettings;
use crate::solver::{Method, Solver, SolverSettings, Stats, StepOutcome};
use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use glam::{DVec3, Vec3};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

mod bench;

pub use bench::register_font;

/// Diffuse global illumination (radiosity) for glTF scenes.
#[derive(Parser, Debug)]
#[command(
    name = "radiosity",
    version,
    about,
    long_about = None,
    args_conflicts_with_subcommands = true
)]
pub struct Cli {
    /// With no subcommand: open the viewer on this scene (default builtin:cornell).
    pub scene: Option<String>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, global = true)]
    pub threads: Option<usize>,
    /// Print no warnings or progress.
    #[arg(long, short, global = true)]
    pub quiet: bool,
    /// With no subcommand: `view builtin:cornell`.
    #[command(subcommand)]
    pub command: Option<Command>,
}

/// The subcommands.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// Open the interactive viewer on a scene (default builtin:cornell).
    View {
        scene: Option<String>,
        #[command(flatten)]
        options: SolveOptions,
        /// Save a screenshot of the window to this PNG after --screenshot-after seconds of
        /// solving, then exit.
        #[arg(long)]
        screenshot: Option<PathBuf>,
        #[arg(long, default_value_t = 3.0)]
        screenshot_after: f64,
        /// On exit, write frame-time statistics (p50/p99 while solving) as JSON here.
        #[arg(long)]
        frame_stats: Option<PathBuf>,
        /// Start with the wireframe on.
        #[arg(long)]
        wireframe: bool,
        /// Turn the camera continuously (for measuring frame times while orbiting).
        #[arg(long)]
        orbit: bool,
    },
    /// Solve, then render an image offscreen with the viewer's renderer.
    Render {
        scene: String,
        /// Output PNG.
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        view: RenderOptions,
        #[command(flatten)]
        options: SolveOptions,
    },
    /// Solve a scene; optionally write a baked .glb and a stats JSON.
    Solve {
        /// A .gltf/.glb file, or builtin:cornell, builtin:furnace-cube, builtin:furnace-sphere.
        scene: String,
        #[command(flatten)]
        options: SolveOptions,
        /// Baked output: .glb with linear radiance per vertex (COLOR_0).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Statistics as JSON (elements, patches, shots, rays, seconds, unshot fraction,
        /// residual, energy balance).
        #[arg(long)]
        stats: Option<PathBuf>,
    },
    /// Radiosity B at surface points: reads x,y,z,nx,ny,nz rows, writes x,y,z,r,g,b.
    Probe {
        scene: String,
        /// CSV with header x,y,z,nx,ny,nz (a point and the outward normal of the side asked about).
        #[arg(long)]
        points: PathBuf,
        /// Output CSV (x,y,z,r,g,b); standard output when absent.
        #[arg(long)]
        out: Option<PathBuf>,
        /// flat, gouraud (the viewer's default) or hermite.
        #[arg(long, default_value = "gouraud")]
        reconstruction: Reconstruction,
        #[command(flatten)]
        options: SolveOptions,
    },
    /// Compare methods: error against a reference over time; or ray throughput with --occlusion.
    Bench {
        scene: String,
        /// Comma-separated methods (default: all).
        #[arg(long, value_delimiter = ',')]
        methods: Option<Vec<Method>>,
        /// `direct` (the exact solve on the same mesh, or a long Gauss–Seidel/progressive run
        /// when the mesh is too big) or a CSV x,y,z,nx,ny,nz,r,g,b of reference values.
        #[arg(long, default_value = "direct")]
        reference: String,
        /// Output folder for convergence.csv and convergence.png.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Measure occlusion rays per second instead (1,000,000 segments between points drawn
        /// uniformly by area, fixed seed; one thread and all threads).
        #[arg(long)]
        occlusion: bool,
        /// Segments for --occlusion.
        #[arg(long, default_value_t = 1_000_000)]
        segments: usize,
        #[command(flatten)]
        options: SolveOptions,
    },
}

/// Camera and display options of `render` (the viewer's defaults when absent).
#[derive(Args, Debug, Clone)]
pub struct RenderOptions {
    /// Image size in pixels, WxH.
    #[arg(long, default_value = "1280x800", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Camera YAW,PITCH[,ZOOM]: degrees around +y (0 looks from +z), degrees above the
    /// horizontal, and distance as a multiple of the one that frames the scene (default 1).
    /// Default: the whole scene from its open side, as the viewer starts.
    #[arg(long, allow_hyphen_values = true, value_parser = parse_camera)]
    pub camera: Option<(f32, f32, f32)>,
    /// flat, gouraud or hermite.
    #[arg(long, alias = "reconstruction", default_value = "gouraud")]
    pub mode: Reconstruction,
    /// Exposure in stops (default: auto exposure, as the viewer).
    #[arg(long, allow_hyphen_values = true)]
    pub ev: Option<f32>,
    /// clamp, reinhard or aces.
    #[arg(long, default_value = "reinhard")]
    pub tonemap: crate::view::render::ToneMap,
    /// False colour of log10 radiosity.
    #[arg(long)]
    pub false_colour: bool,
    /// Draw element edges.
    #[arg(long)]
    pub wireframe: bool,
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}': expected WxH, e.g. 1280x800"))?;
    let w: u32 = w.trim().parse().map_err(|e| format!("'{w}': {e}"))?;
    let h: u32 = h.trim().parse().map_err(|e| format!("'{h}': {e}"))?;
    if !(1..=16384).contains(&w) || !(1..=16384).contains(&h) {
        return Err("width and height must be between 1 and 16384".into());
    }
    Ok((w, h))
}

fn parse_camera(s: &str) -> Result<(f32, f32, f32), String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>().map_err(|e| format!("'{x}': {e}")))
        .collect::<Result<_, _>>()?;
    let c = match v.as_slice() {
        [y, p] => (*y, *p, 1.0),
        [y, p, z] => (*y, *p, *z),
        _ => return Err("expected YAW,PITCH or YAW,PITCH,ZOOM".into()),
    };
    if !(c.0.is_finite() && c.1.is_finite() && c.2.is_finite() && c.2 > 0.0) {
        return Err("values must be finite and ZOOM positive".into());
    }
    Ok(c)
}

/// Options shared by every command that solves.
#[derive(Args, Debug, Clone)]
pub struct SolveOptions {
    /// progressive (default), jacobi, gauss-seidel, stochastic-jacobi or direct. The viewer,
    /// when none is given, takes stochastic-jacobi for scenes over 100,000 elements.
    #[arg(long)]
    pub method: Option<Method>,
    /// Stop when the unshot fraction (progressive) or relative residual falls below this.
    #[arg(long, default_value_t = 1e-3)]
    pub tolerance: f64,
    /// Stop after this many seconds even if not converged (bench: per method, default 60).
    #[arg(long)]
    pub time_limit: Option<f64>,
    /// Element size in metres (default: chosen for about 3000 elements).
    #[arg(long)]
    pub element_size: Option<f64>,
    /// Most elements when --element-size is not given.
    #[arg(long)]
    pub max_elements: Option<usize>,
    /// Do not split triangles along the lines where other surfaces touch or pierce them
    /// (D0 discontinuity meshing is on by default).
    #[arg(long)]
    pub no_contact_lines: bool,
    /// Do not split triangles along the hard shadow edges of point, spot and directional
    /// lights and the sun (on by default).
    #[arg(long)]
    pub no_shadow_lines: bool,
    /// Uniform sky radiance, W/(m²·sr): one value or r,g,b. Default for scenes without light: 1.
    #[arg(long, value_parser = parse_rgb)]
    pub sky: Option<Vec3>,
    /// Sun: direction towards the sun x,y,z and optionally its irradiance (W/m²), default 3.
    #[arg(long, value_parser = parse_sun)]
    pub sun: Option<(DVec3, Vec3)>,
    /// Most shadow rays per element–patch form factor.
    #[arg(long, default_value_t = FormFactorSettings::default().max_rays)]
    pub max_rays: u32,
    /// Fewest shadow rays per element–patch form factor.
    #[arg(long, default_value_t = FormFactorSettings::default().min_rays)]
    pub min_rays: u32,
    /// Shadow rays for an element–patch pair in penumbra (first rays disagree).
    #[arg(long, default_value_t = FormFactorSettings::default().penumbra_rays)]
    pub penumbra_rays: u32,
    /// Adaptive subdivision after the solve converges: split elements whose log-luminance
    /// contrast to a neighbour exceeds this (0.2 ≈ a 22 % step); 0 turns it off.
    #[arg(long, default_value_t = AdaptiveSettings::default().threshold)]
    pub adaptive_threshold: f32,
    /// Smallest element adaptive subdivision may make, metres (default: an eighth of the
    /// starting element size).
    #[arg(long)]
    pub min_element_size: Option<f64>,
}

fn parse_rgb(s: &str) -> Result<Vec3, String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>().map_err(|e| format!("'{x}': {e}")))
        .collect::<Result<_, _>>()?;
    let rgb = match v.as_slice() {
        [x] => Vec3::splat(*x),
        [r, g, b] => Vec3::new(*r, *g, *b),
        _ => return Err("expected one value or r,g,b".into()),
    };
    if !rgb.is_finite() || rgb.min_element() < 0.0 {
        return Err("values must be finite and non-negative".into());
    }
    Ok(rgb)
}

fn parse_sun(s: &str) -> Result<(DVec3, Vec3), String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|e| format!("'{x}': {e}")))
        .collect::<Result<_, _>>()?;
    let (d, e) = match v.as_slice() {
        [x, y, z] => (DVec3::new(*x, *y, *z), 3.0),
        [x, y, z, e] => (DVec3::new(*x, *y, *z), *e),
        _ => return Err("expected x,y,z or x,y,z,irradiance".into()),
    };
    if !d.is_finite() || d.length() == 0.0 || !e.is_finite() || e < 0.0 {
        return Err("the direction must be finite and non-zero, the irradiance ≥ 0".into());
    }
    Ok((d.normalize(), Vec3::splat(e as f32)))
}

impl SolveOptions {
    fn mesh_settings(&self) -> MeshSettings {
        MeshSettings {
            element_size: self.element_size,
            max_elements: self.max_elements,
            no_contact_lines: self.no_contact_lines,
            no_shadow_lines: self.no_shadow_lines,
        }
    }

    fn solver_settings(&self) -> SolverSettings {
        let mut s = SolverSettings {
            method: self.method.unwrap_or(Method::Progressive),
            tolerance: self.tolerance,
            ..Default::default()
        };
        s.form_factors.max_rays = self.max_rays.max(1);
        s.form_factors.penumbra_rays = self.penumbra_rays.max(1);
        s.form_factors.min_rays = self.min_rays.clamp(1, s.form_factors.max_rays);
        s.adaptive = (self.adaptive_threshold > 0.0).then(|| AdaptiveSettings {
            threshold: self.adaptive_threshold,
            min_size: self.min_element_size.filter(|m| *m > 0.0),
            ..Default::default()
        });
        s
    }
}

/// Loads `spec` (a path or `builtin:NAME`), adds the default sky when it has no light, and
/// prints its warnings unless `quiet`.
pub fn load_scene(spec: &str, options: &SolveOptions, quiet: bool) -> Result<Scene> {
    let scene = open_scene(spec, options.sky, options.sun)?;
    if !quiet {
        for w in &scene.warnings {
            eprintln!("warning: {w}");
        }
    }
    Ok(scene)
}

/// Loads `spec` (a path or `builtin:NAME`) and adds `sky`/`sun` (or the default sky) when
/// it has no light. Warnings stay in `Scene::warnings`.
pub fn open_scene(spec: &str, sky: Option<Vec3>, sun: Option<(DVec3, Vec3)>) -> Result<Scene> {
    let mut scene = if let Some(name) = spec.strip_prefix("builtin:") {
        builtin::by_name(name).with_context(|| {
            format!(
                "{spec}: unknown built-in scene (known: {})",
                builtin::NAMES.join(", ")
            )
        })?
    } else {
        crate::scene::gltf::load(Path::new(spec))?
    };
    if scene.triangle_count() == 0 {
        bail!("{spec}: the scene has no triangles");
    }
    scene.ensure_light(sky, sun);
    Ok(scene)
}

fn progress_bar(quiet: bool) -> indicatif::ProgressBar {
    if quiet {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(1000);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar
}

/// Runs `solver` to convergence or the time limit with a progress bar (position: log of the
/// unshot fraction or residual between 1 and the tolerance).
fn run_with_progress(
    solver: &mut Solver,
    time_limit: Option<f64>,
    quiet: bool,
) -> Result<StepOutcome> {
    let bar = progress_bar(quiet);
    let start = Instant::now();
    let cancel = AtomicBool::new(false);
    let tol = solver.settings().tolerance.max(1e-12);
    let outcome = loop {
        let outcome = solver.step(&cancel)?;
        let s = solver.stats();
        if let Some(r) = s.unshot_fraction.or(s.residual) {
            let done = (r.max(tol).ln() / tol.ln()).clamp(0.0, 1.0);
            bar.set_position((done * 1000.0) as u64);
            bar.set_message(format!("{} iterations, residual {r:.2e}", s.iterations));
        }
        if outcome != StepOutcome::Working
            || time_limit.is_some_and(|t| start.elapsed() >= Duration::from_secs_f64(t))
        {
            break outcome;
        }
    };
    bar.finish_and_clear();
    Ok(outcome)
}

fn prepare(scene: &Scene, options: &SolveOptions, quiet: bool) -> Prepared {
    let prepared = Prepared::new(scene, &options.mesh_settings());
    if !quiet {
        for w in &prepared.mesh.warnings {
            eprintln!("warning: {w}");
        }
    }
    prepared
}

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

/// Runs the parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    if let Some(n) = cli.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build_global()
            .context("cannot set the thread count")?;
    }
    let quiet = cli.quiet;
    let command = match cli.command {
        Some(c) => c,
        // No subcommand: the viewer on the built-in Cornell box, with every default.
        None => {
            let mut args = vec!["radiosity".to_string(), "view".to_string()];
            args.extend(cli.scene);
            Cli::try_parse_from(args)?
                .command
                .context("the default command")?
        }
    };
    match command {
        Command::View {
            scene,
            options,
            screenshot,
            screenshot_after,
            frame_stats,
            wireframe,
            orbit,
        } => crate::view::app::run(crate::view::app::Options {
            scene: scene.unwrap_or_else(|| "builtin:cornell".into()),
            mesh: options.mesh_settings(),
            solver: options.solver_settings(),
            screenshot,
            screenshot_after,
            frame_stats,
            wireframe,
            orbit,
            auto_method: options.method.is_none(),
        }),
        Command::Render {
            scene,
            out,
            view,
            options,
        } => {
            let s = load_scene(&scene, &options, quiet)?;
            let prepared = prepare(&s, &options, quiet);
            let mut solver = prepared.solver(options.solver_settings())?;
            run_with_progress(&mut solver, options.time_limit, quiet)?;
            render(
                solver.mesh(),
                &prepared.bvh,
                &solver.radiosity(),
                &view,
                &out,
                quiet,
            )
        }
        Command::Solve {
            scene,
            options,
            out,
            stats,
        } => {
            let s = load_scene(&scene, &options, quiet)?;
            let prepared = prepare(&s, &options, quiet);
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
                write_atomic(&path, serde_json::to_string_pretty(&file)?.as_bytes())?;
            }
            if let Some(path) = out {
                // The solver's mesh: adaptive refinement may have replaced the prepared one.
                let mesh = solver.mesh();
                let values = mesh
                    .display
                    .vertex_values(&mesh.elements, &solver.radiosity());
                write_atomic(&path, &baked_glb(&s, mesh, &values))?;
            }
            Ok(())
        }
        Command::Probe {
            scene,
            points,
            out,
            reconstruction,
            options,
        } => {
            let pts = read_points(&points)?;
            let s = load_scene(&scene, &options, quiet)?;
            let prepared = prepare(&s, &options, quiet);
            let mut solver = prepared.solver(options.solver_settings())?;
            run_with_progress(&mut solver, options.time_limit, quiet)?;
            let values = probe_values(solver.mesh(), &solver.radiosity(), &pts, reconstruction);
            let mut csv = String::from("x,y,z,r,g,b\n");
            for ((p, _), v) in pts.iter().zip(&values) {
                csv += &format!("{},{},{},{},{},{}\n", p.x, p.y, p.z, v.x, v.y, v.z);
            }
            match out {
                Some(path) => write_atomic(&path, csv.as_bytes()),
                None => {
                    print!("{csv}");
                    Ok(())
                }
            }
        }
        Command::Bench {
            scene,
            methods,
            reference,
            out,
            occlusion,
            segments,
            options,
        } => {
            let s = load_scene(&scene, &options, quiet)?;
            if occlusion {
                return bench::occlusion(&s, segments);
            }
            let out = out.context("bench needs --out DIR (or --occlusion)")?;
            // --time-limit applies per method here; 60 s when not given.
            let time_limit = options.time_limit.unwrap_or(60.0);
            bench::convergence(&s, &options, methods, &reference, time_limit, &out, quiet)
        }
    }
}

/// Renders `radiosity` on `mesh` to the PNG `out` with the viewer's renderer.
fn render(
    mesh: &crate::mesh::Mesh,
    bvh: &crate::accel::Bvh,
    radiosity: &[Vec3],
    view: &RenderOptions,
    out: &Path,
    quiet: bool,
) -> Result<()> {
    use crate::view::render::{Display, render_image};
    let mut camera = crate::view::default_camera(mesh, bvh);
    if let Some((yaw, pitch, zoom)) = view.camera {
        camera.yaw = yaw.to_radians();
        camera.pitch = pitch.clamp(-89.0, 89.0).to_radians();
        camera.distance *= zoom;
    }
    let auto = crate::view::auto_exposure(mesh, radiosity);
    let display = Display {
        reconstruction: view.mode,
        ev: view.ev.or(auto.map(|a| a.0)).unwrap_or(0.0),
        tonemap: view.tonemap,
        false_colour: view.false_colour,
        log_range: auto.map(|a| a.1).unwrap_or((-2.0, 2.0)),
        wireframe: view.wireframe,
        selected: None,
    };
    let (image, adapter) = render_image(
        mesh,
        radiosity,
        &camera,
        &display,
        [view.size.0, view.size.1],
    )?;
    crate::view::write_png(out, &image)?;
    if !quiet {
        eprintln!("rendered {} with {adapter}", out.display());
    }
    Ok(())
}

/// Reads a points CSV: header naming x,y,z,nx,ny,nz (any order, extra columns ignored).
/// Returns world-space points and normals, and the extra columns' values by name.
pub fn read_points(path: &Path) -> Result<Vec<(DVec3, DVec3)>> {
    Ok(read_table(path, &["x", "y", "z", "nx", "ny", "nz"])?
        .into_iter()
        .map(|r| (DVec3::new(r[0], r[1], r[2]), DVec3::new(r[3], r[4], r[5])))
        .collect())
}

/// Reads the named numeric columns of a CSV with a header row.
pub fn read_table(path: &Path, columns: &[&str]) -> Result<Vec<Vec<f64>>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let header: Vec<&str> = lines
        .next()
        .with_context(|| {
            format!(
                "{}: empty file (expected a header {})",
                path.display(),
                columns.join(",")
            )
        })?
        .split(',')
        .map(str::trim)
        .collect();
    let index: Vec<usize> = columns
        .iter()
        .map(|c| {
            header.iter().position(|h| h == c).with_context(|| {
                format!(
                    "{}: header has no column '{c}' (expected {})",
                    path.display(),
                    columns.join(",")
                )
            })
        })
        .collect::<Result<_>>()?;
    let mut rows = Vec::new();
    for (k, line) in lines.enumerate() {
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        let row = index
            .iter()
            .map(|&i| {
                let cell = cells.get(i).copied().unwrap_or("");
                cell.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .with_context(|| {
                        format!(
                            "{}: line {}: '{cell}' is not a finite number",
                            path.display(),
                            k + 2
                        )
                    })
            })
            .collect::<Result<Vec<f64>>>()?;
        rows.push(row);
    }
    Ok(rows)
}

/// Reconstructed radiosity at world points with outward normals (zero where no element
/// faces that way).
pub fn probe_values(
    mesh: &crate::mesh::Mesh,
    radiosity: &[Vec3],
    points: &[(DVec3, DVec3)],
    mode: Reconstruction,
) -> Vec<Vec3> {
    let r = crate::mesh::Reconstructor::new(mode, &mesh.display, &mesh.elements, radiosity);
    points
        .iter()
        .map(|(p, n)| match mesh.locate(mesh.to_local(*p), n.as_vec3()) {
            Some((e, bary)) => r.at(&mesh.elements, radiosity, e, bary),
            None => Vec3::ZERO,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn command_line_definition_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn a_bare_scene_opens_the_viewer_and_subcommands_still_parse() {
        // DESIGN.md §5: `radiosity [view] [SCENE]`.
        let cli = Cli::try_parse_from(["radiosity", "room.gltf"]).unwrap();
        assert_eq!(cli.scene.as_deref(), Some("room.gltf"));
        assert!(cli.command.is_none());
        let cli = Cli::try_parse_from(["radiosity", "solve", "builtin:cornell"]).unwrap();
        assert!(matches!(cli.command, Some(Command::Solve { .. })));
        let cli = Cli::try_parse_from(["radiosity"]).unwrap();
        assert!(cli.scene.is_none() && cli.command.is_none());
        let cli = Cli::try_parse_from([
            "radiosity",
            "render",
            "builtin:cornell",
            "--out",
            "x.png",
            "--size",
            "64x48",
            "--camera",
            "-30,10,1.5",
            "--mode",
            "hermite",
        ])
        .unwrap();
        match cli.command {
            Some(Command::Render { view, .. }) => {
                assert_eq!(view.size, (64, 48));
                assert_eq!(view.camera, Some((-30.0, 10.0, 1.5)));
                assert_eq!(view.mode, Reconstruction::Hermite);
            }
            other => panic!("{other:?}"),
        }
        assert!(
            Cli::try_parse_from(["radiosity", "render", "s", "--out", "x", "--size", "0x5"])
                .is_err()
        );
    }
}
