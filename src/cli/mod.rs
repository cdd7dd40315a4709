//! The command line: `solve`, `probe`, `bench` and `render` drive scene → mesh → accel →
//! solver directly, with no thread and no window; `view` (the default with no subcommand)
//! opens the viewer. One file per subcommand; argument types in [`options`], CSV files in
//! [`csv`]. Errors surface as one line naming the file and the problem, and exit status 1.
//! The viewer and `render` exist only with the `viewer` cargo feature (on by default).

mod bench;
mod bench_edits;
pub mod csv;
pub mod options;
mod probe;
mod reference;
#[cfg(feature = "viewer")]
mod render;
mod solve;

pub use bench::register_font;
#[cfg(feature = "viewer")]
pub use options::RenderOptions;
pub use options::SolveOptions;

#[cfg(all(test, feature = "viewer"))]
use crate::mesh::Reconstruction;
use crate::pipeline::Prepared;
use crate::scene::Scene;
use crate::solver::{Method, Solver, StepOutcome};
#[cfg(not(feature = "viewer"))]
use anyhow::bail;
use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

/// Diffuse global illumination (radiosity) for glTF scenes.
#[derive(Parser, Debug)]
#[command(
    name = "radiosity",
    version,
    about,
    long_about = None
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
    #[cfg(feature = "viewer")]
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
        /// Start with the textures off (each surface in the mean colour the solver used).
        #[arg(long)]
        no_textures: bool,
        /// Turn the camera continuously (for measuring frame times while orbiting).
        #[arg(long)]
        orbit: bool,
        /// Start with the final gather on (the resting view fills in with gathered pixels
        /// once the solution has converged).
        #[arg(long)]
        final_gather: bool,
    },
    /// Solve, then render an image offscreen with the viewer's renderer.
    #[cfg(feature = "viewer")]
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
        /// gather (the final gather at each point: point-by-point values), or the mesh
        /// solution as the viewer shows it: flat, gouraud or hermite (the viewer's default).
        #[arg(long, default_value = "gather")]
        reconstruction: options::ProbeValue,
        #[command(flatten)]
        options: SolveOptions,
    },
    /// Unbiased path-traced radiosity at surface points, with its standard error: reads
    /// x,y,z,nx,ny,nz rows, writes x,y,z,r,g,b,sr,sg,sb.
    Reference {
        scene: String,
        /// CSV with header x,y,z,nx,ny,nz (a point and the outward normal of the side asked about).
        #[arg(long)]
        points: PathBuf,
        /// Output CSV (x,y,z,r,g,b,sr,sg,sb).
        #[arg(long)]
        out: PathBuf,
        /// Target 1-sigma standard error relative to max(B, 2 % of the mean B), per channel.
        #[arg(long, default_value_t = 0.01)]
        rel_error: f64,
        /// Stop after this many seconds even if some points have not reached --rel-error.
        #[arg(long)]
        time_limit: Option<f64>,
        /// Seed of the sample streams (the same seed gives the same values).
        #[arg(long, default_value_t = 1)]
        seed: u64,
        #[command(flatten)]
        lights: options::LightOptions,
    },
    /// Compare methods: error against a reference over time; or ray throughput with --occlusion.
    Bench {
        scene: String,
        /// Comma-separated methods (default: all).
        #[arg(long, value_delimiter = ',')]
        methods: Option<Vec<Method>>,
        /// `path` (the truth: a path-traced reference at probe points the bench picks —
        /// uniform, near edges and contacts, in penumbrae and umbrae —, cached in DIR),
        /// `direct` (the exact solve on the same mesh, or a long Gauss–Seidel/progressive
        /// run when the mesh is too big: the solver's convergence) or a CSV
        /// x,y,z,nx,ny,nz,r,g,b of reference values.
        #[arg(long, default_value = "path")]
        reference: String,
        /// With `--reference path`: the path tracer's target standard error, relative to
        /// max(B, 2 % of the mean B) per channel (as `reference --rel-error`). Halving it
        /// takes four times as long; each value is cached apart.
        #[arg(long, default_value_t = 0.01)]
        reference_error: f64,
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
        /// With --occlusion: also write the scene's triangles and the segments to this file
        /// for another ray engine (`scripts/embree_occlusion.py`): "RADSEG1", then the
        /// triangle and segment counts as u64, the triangles (9 f32 each) and the segments
        /// (6 f32 each), little-endian, in the mesh frame.
        #[arg(long)]
        segments_out: Option<PathBuf>,
        /// Measure material edits instead: after convergence, N reflectance changes of
        /// ±30 % on materials drawn with a fixed seed, one at a time; writes DIR/edits.csv
        /// (material,first_update_ms,converged_ms).
        #[arg(long)]
        edits: Option<usize>,
        #[command(flatten)]
        options: SolveOptions,
    },
}

/// Loads `spec` (a path or `builtin:NAME`), adds the default sky when it has no light, and
/// prints its warnings unless `quiet`.
pub fn load_scene(spec: &str, options: &SolveOptions, quiet: bool) -> Result<Scene> {
    let scene = crate::scene::open(spec, options.lights.sky, options.lights.sun)?;
    if !quiet {
        for w in &scene.warnings {
            eprintln!("warning: {w}");
        }
    }
    Ok(scene)
}

pub(crate) fn progress_bar(quiet: bool) -> indicatif::ProgressBar {
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
pub(crate) fn run_with_progress(
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

pub(crate) fn prepare(scene: &Scene, options: &SolveOptions, quiet: bool) -> Prepared {
    let prepared = Prepared::new(scene, &options.mesh_settings());
    if !quiet {
        for w in &prepared.mesh.warnings {
            eprintln!("warning: {w}");
        }
    }
    prepared
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
    let command = match (cli.command, cli.scene) {
        (Some(c), None) => c,
        (None, scene) => default_command(scene)?,
        (Some(_), Some(scene)) => anyhow::bail!(
            "{scene}: a scene given before a subcommand; give it after the subcommand's name"
        ),
    };
    match command {
        #[cfg(feature = "viewer")]
        Command::View {
            scene,
            options,
            screenshot,
            screenshot_after,
            frame_stats,
            wireframe,
            no_textures,
            orbit,
            final_gather,
        } => crate::view::app::run(crate::view::app::Options {
            scene: scene.unwrap_or_else(|| "builtin:cornell".into()),
            mesh: options.mesh_settings(),
            solver: options.solver_settings(),
            outside: crate::scene::Outside {
                sky: options.lights.sky,
                sun: options.lights.sun,
            },
            screenshot,
            screenshot_after,
            frame_stats,
            wireframe,
            no_textures,
            orbit,
            final_gather,
        }),
        #[cfg(feature = "viewer")]
        Command::Render {
            scene,
            out,
            view,
            options,
        } => render::render(&scene, &out, &view, &options, quiet),
        Command::Solve {
            scene,
            options,
            out,
            stats,
        } => solve::solve(&scene, &options, out.as_deref(), stats.as_deref(), quiet),
        Command::Probe {
            scene,
            points,
            out,
            reconstruction,
            options,
        } => probe::probe(
            &scene,
            &points,
            out.as_deref(),
            reconstruction,
            &options,
            quiet,
        ),
        Command::Reference {
            scene,
            points,
            out,
            rel_error,
            time_limit,
            seed,
            lights,
        } => reference::reference(
            &scene,
            &points,
            &out,
            &crate::reference::ReferenceSettings {
                rel_error,
                time_limit: time_limit.map(Duration::from_secs_f64),
                seed,
                ..Default::default()
            },
            &lights,
            quiet,
        ),
        Command::Bench {
            scene,
            methods,
            reference,
            reference_error,
            out,
            occlusion,
            segments,
            segments_out,
            edits,
            options,
        } => {
            anyhow::ensure!(
                reference_error > 0.0 && reference_error.is_finite(),
                "--reference-error must be a positive number, not {reference_error}"
            );
            let s = load_scene(&scene, &options, quiet)?;
            if occlusion {
                return bench::occlusion(&s, segments, segments_out.as_deref());
            }
            let out = out.context("bench needs --out DIR (or --occlusion)")?;
            if let Some(n) = edits {
                return bench_edits::edits(&s, &options, n.max(1), &out, quiet);
            }
            // --time-limit applies per method here; 60 s when not given.
            let time_limit = options.time_limit.unwrap_or(60.0);
            let reference = bench::ReferenceSpec {
                kind: &reference,
                rel_error: reference_error,
            };
            bench::convergence(&s, &options, methods, &reference, time_limit, &out, quiet)
        }
    }
}

/// No subcommand: the viewer on `scene` (the built-in Cornell box when absent), with every
/// default.
#[cfg(feature = "viewer")]
fn default_command(scene: Option<String>) -> Result<Command> {
    let mut args = vec!["radiosity".to_string(), "view".to_string()];
    args.extend(scene);
    Cli::try_parse_from(args)?
        .command
        .context("the default command")
}

/// No subcommand, in a build without the viewer: say so.
#[cfg(not(feature = "viewer"))]
fn default_command(_scene: Option<String>) -> Result<Command> {
    bail!(
        "this radiosity was built without the viewer (cargo feature `viewer`); use a subcommand: solve, probe or bench"
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn command_line_definition_is_consistent() {
        Cli::command().debug_assert();
    }

    #[cfg(feature = "viewer")]
    #[test]
    fn a_bare_scene_opens_the_viewer_and_subcommands_still_parse() {
        // The command-line contract: `radiosity [view] [SCENE]`.
        let cli = Cli::try_parse_from(["radiosity", "room.gltf"]).unwrap();
        assert_eq!(cli.scene.as_deref(), Some("room.gltf"));
        assert!(cli.command.is_none());
        let cli = Cli::try_parse_from(["radiosity", "solve", "builtin:cornell"]).unwrap();
        assert!(matches!(cli.command, Some(Command::Solve { .. })));
        let cli = Cli::try_parse_from(["radiosity"]).unwrap();
        assert!(cli.scene.is_none() && cli.command.is_none());
        // The global flags go before the subcommand as well as after it (`radiosity -q
        // solve …` used to read `solve` as a scene and fail).
        for args in [
            &[
                "radiosity",
                "-q",
                "--threads",
                "1",
                "solve",
                "builtin:cornell",
            ][..],
            &[
                "radiosity",
                "solve",
                "builtin:cornell",
                "-q",
                "--threads",
                "1",
            ][..],
        ] {
            let cli = Cli::try_parse_from(args).unwrap();
            assert!(
                matches!(cli.command, Some(Command::Solve { .. })),
                "{args:?}"
            );
            assert!(
                cli.quiet && cli.threads == Some(1) && cli.scene.is_none(),
                "{args:?}"
            );
        }
        let cli = Cli::try_parse_from(["radiosity", "-q", "room.gltf"]).unwrap();
        assert_eq!(cli.scene.as_deref(), Some("room.gltf"));
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
