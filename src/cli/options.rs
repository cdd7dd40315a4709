//! Argument types shared by the subcommands: solve options (meshing and solver settings)
//! and the camera and display options of `render`, with their parsers.

#[cfg(feature = "viewer")]
use crate::mesh::Reconstruction;
use crate::mesh::{AdaptiveSettings, MeshSettings};
use crate::solver::form_factor::FormFactorSettings;
use crate::solver::gather::GatherSettings;
use crate::solver::{HierarchySettings, Method, SolverSettings};
use clap::Args;
use glam::{DVec3, Vec3};

/// The light added to a scene: a uniform sky and a sun (a scene with no light at all gets
/// a white sky of radiance 1).
#[derive(Args, Debug, Clone)]
pub struct LightOptions {
    /// Uniform sky radiance, W/(m²·sr): one value or r,g,b. Default for scenes without light: 1.
    #[arg(long, value_parser = parse_rgb)]
    pub sky: Option<Vec3>,
    /// Sun: direction towards the sun x,y,z and optionally its irradiance (W/m²), default 3.
    #[arg(long, value_parser = parse_sun)]
    pub sun: Option<(DVec3, Vec3)>,
}

/// What `probe` reports at a point: the final gather there, or a reconstruction of the
/// mesh solution (what the viewer shows).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProbeValue {
    Gather,
    Mesh(crate::mesh::Reconstruction),
}

impl std::str::FromStr for ProbeValue {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "gather" => Ok(ProbeValue::Gather),
            _ => s.parse().map(ProbeValue::Mesh).map_err(|_| {
                format!("unknown reconstruction '{s}' (expected gather, flat, gouraud or hermite)")
            }),
        }
    }
}

/// Options shared by every command that solves.
#[derive(Args, Debug, Clone)]
pub struct SolveOptions {
    /// hierarchical (default), progressive, jacobi, gauss-seidel, stochastic-jacobi or
    /// direct.
    #[arg(long)]
    pub method: Option<Method>,
    /// Stop when the unshot fraction (progressive) or relative residual falls below this.
    #[arg(long, default_value_t = 1e-3)]
    pub tolerance: f64,
    /// Stop after this many seconds even if not converged (bench: per method, default 60).
    #[arg(long)]
    pub time_limit: Option<f64>,
    /// The final gather's error per node of its sum, relative to the light the point
    /// receives (smaller: more nodes and shadow rays per point).
    #[arg(long, default_value_t = GatherSettings::default().error)]
    pub gather_error: f32,
    /// Element size in metres (default: chosen for about 3000 elements).
    #[arg(long)]
    pub element_size: Option<f64>,
    /// Most elements when --element-size is not given.
    #[arg(long)]
    pub max_elements: Option<usize>,
    /// Split triangles along the lines where other surfaces touch or pierce them (D0
    /// discontinuity meshing); `--no-contact-lines` turns it off.
    #[arg(long = "no-contact-lines", action = clap::ArgAction::SetFalse)]
    pub contact_lines: bool,
    /// Split triangles along the hard shadow edges of point, spot and directional lights
    /// and the sun; `--no-shadow-lines` turns it off.
    #[arg(long = "no-shadow-lines", action = clap::ArgAction::SetFalse)]
    pub shadow_lines: bool,
    #[command(flatten)]
    pub lights: LightOptions,
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
    /// Smallest element adaptive subdivision or the hierarchy may make, metres (default:
    /// an eighth of the starting element size); the hierarchy goes to a quarter of it
    /// where a leaf touches the surface it receives from (a contact).
    #[arg(long)]
    pub min_element_size: Option<f64>,
    /// Hierarchical: the refinement oracle's relative threshold ε (a link is refined when
    /// its estimated error exceeds ε times the mean light the surfaces emit or first
    /// reflect, scaled down where the receiver is darker than the mean, to a tenth at
    /// most); smaller means more links and elements.
    #[arg(long, default_value_t = HierarchySettings::default().link_error)]
    pub link_error: f32,
    /// Hierarchical: start from every pair of patches instead of the root cluster.
    #[arg(long)]
    pub no_clustering: bool,
    /// Hierarchical: about the most links (16–22 bytes each in the solution, 28 while a
    /// refinement round holds them) the solution may hold, at most 2^27; when refinement
    /// passes it, it stops after the generation under way (the stats say so)
    #[arg(long, default_value_t = HierarchySettings::default().max_links)]
    pub max_links: usize,
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

impl Default for SolveOptions {
    /// The command line's defaults (what `radiosity solve SCENE` uses with no options).
    fn default() -> Self {
        use clap::{Args as _, FromArgMatches};
        let command = SolveOptions::augment_args(clap::Command::new("defaults"));
        let matches = command.get_matches_from(["defaults"]);
        SolveOptions::from_arg_matches(&matches).expect("every option has a default")
    }
}

impl SolveOptions {
    /// The final gather these options ask for.
    pub fn gather_settings(&self) -> GatherSettings {
        GatherSettings {
            error: self.gather_error,
            ..Default::default()
        }
    }

    /// The meshing these options ask for.
    pub fn mesh_settings(&self) -> MeshSettings {
        MeshSettings {
            element_size: self.element_size,
            max_elements: self.max_elements,
            contact_lines: self.contact_lines,
            shadow_lines: self.shadow_lines,
        }
    }

    /// The solver settings these options ask for.
    pub fn solver_settings(&self) -> SolverSettings {
        let mut s = SolverSettings {
            method: self.method.unwrap_or(Method::Hierarchical),
            tolerance: self.tolerance,
            ..Default::default()
        };
        s.form_factors.max_rays = self.max_rays.max(1);
        s.form_factors.penumbra_rays = self.penumbra_rays.max(1);
        s.form_factors.min_rays = self.min_rays.clamp(1, s.form_factors.max_rays);
        s.hierarchy = HierarchySettings {
            link_error: self.link_error,
            clustering: !self.no_clustering,
            min_size: self.min_element_size.filter(|m| *m > 0.0),
            max_links: self.max_links.max(1),
            ..Default::default()
        };
        s.adaptive = (self.adaptive_threshold > 0.0).then(|| AdaptiveSettings {
            threshold: self.adaptive_threshold,
            min_size: self.min_element_size.filter(|m| *m > 0.0),
            ..Default::default()
        });
        s
    }
}

/// Camera and display options of `render` (the viewer's defaults when absent).
#[cfg(feature = "viewer")]
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
    /// flat, gouraud or hermite (the viewer's default).
    #[arg(long, alias = "reconstruction", default_value = "hermite")]
    pub mode: Reconstruction,
    /// Exposure in stops (default: auto exposure, as the viewer).
    #[arg(long, allow_hyphen_values = true)]
    pub ev: Option<f32>,
    /// clamp, reinhard, aces or agx.
    #[arg(long, default_value = "agx")]
    pub tonemap: crate::view::render::ToneMap,
    /// False colour of log10 radiosity.
    #[arg(long)]
    pub false_colour: bool,
    /// Draw element edges.
    #[arg(long)]
    pub wireframe: bool,
    /// Draw each surface in the mean colour the solver used instead of its base-colour
    /// and emissive textures under the light.
    #[arg(long)]
    pub no_textures: bool,
    /// Gather every pixel's visible point (the final gather, as `probe` reports it)
    /// instead of drawing the mesh solution.
    #[arg(long)]
    pub final_gather: bool,
    /// With --final-gather: samples per pixel side (N² per pixel, anti-aliasing).
    #[arg(long, default_value_t = 2)]
    pub samples: u32,
}

#[cfg(feature = "viewer")]
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

#[cfg(feature = "viewer")]
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
