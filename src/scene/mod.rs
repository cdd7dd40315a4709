//! The scene as the CPU holds it: objects (triangle meshes with a `world_from_local`
//! transform), materials, punctual lights and the environment (sky, sun).
//!
//! This is the truth every later stage (mesh, accel, solver) derives from. Units
//! (ARCHITECTURE.md, "Units and conventions"): reflectance ρ is unitless in [0, 0.999] per
//! channel; `Material::emission`
//! is the emitted *radiance* L_e in W/(m²·sr) (emitted radiosity E = π L_e); point and spot
//! light intensities are in W/sr, directional lights and the sun give irradiance in W/m².

pub mod builtin;
pub mod gltf;
mod open;
pub mod textures;

pub use open::{OpenError, open, open_cancellable};
pub use textures::{Image, ImageLevel, Slot, TextureRef, TexturedTriangle, Wrap};

use glam::{DMat4, DVec3, Vec3};

/// A diffuse material. Edited live by the viewer, so per-triangle texture factors live on
/// the object (`Object::reflectance_tint`) and multiply this.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name from the file, or a generated one.
    pub name: String,
    /// Diffuse reflectance ρ per RGB channel, in [0, 0.999].
    pub reflectance: Vec3,
    /// Emitted radiance L_e per channel, W/(m²·sr). Emitted radiosity is π L_e.
    pub emission: Vec3,
    /// Double-sided surfaces reflect and emit on both faces and carry two radiosities.
    /// Single-sided ones reflect on the front face only but block light on both sides.
    pub double_sided: bool,
    /// Fraction of light that passes through the surface, in [0, 1]: 0 for opaque, the
    /// uncovered fraction for `alphaMode: MASK` cut-outs, the transmission factor for
    /// `KHR_materials_transmission` glass. Shadow rays are attenuated by it.
    pub transmittance: f32,
    /// The base-colour texture the display shows under the light (its mean over each
    /// triangle is in `Object::reflectance_tint`).
    pub base_texture: Option<TextureRef>,
    /// The emissive texture the display shows (its mean is in `Object::emission_tint`).
    pub emissive_texture: Option<TextureRef>,
    /// `alphaMode: MASK` with a base-colour texture: the display discards texels whose
    /// texture alpha is below this (the cutoff over `baseColorFactor.a`).
    pub alpha_cutoff: Option<f32>,
}

impl Material {
    /// An opaque, single-sided, non-emitting material of reflectance `rho`.
    pub fn diffuse(name: &str, rho: Vec3) -> Self {
        Material {
            name: name.to_string(),
            reflectance: rho,
            emission: Vec3::ZERO,
            double_sided: false,
            transmittance: 0.0,
            base_texture: None,
            emissive_texture: None,
            alpha_cutoff: None,
        }
    }

    /// A material that emits radiance `radiance` (W/(m²·sr)) and reflects `rho`.
    pub fn emitter(name: &str, rho: Vec3, radiance: Vec3) -> Self {
        Material {
            emission: radiance,
            ..Material::diffuse(name, rho)
        }
    }
}

/// A triangle mesh placed in the world.
#[derive(Clone, Debug, Default)]
pub struct Object {
    /// Node or mesh name from the file.
    pub name: String,
    /// Vertex positions in the object's local frame (metres after `world_from_local`).
    pub positions: Vec<Vec3>,
    /// Triangles as indices into `positions`, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
    /// Material index per triangle (into `Scene::materials`).
    pub triangle_material: Vec<u32>,
    /// Per-triangle factor on the material's reflectance (the mean of the base-colour
    /// texture over the triangle); empty means 1 everywhere.
    pub reflectance_tint: Vec<Vec3>,
    /// Per-triangle factor on the material's emission (mean of the emissive texture);
    /// empty means 1 everywhere.
    pub emission_tint: Vec<Vec3>,
    /// Per-triangle transmittance override (alpha-mask coverage); empty means the material's.
    pub transmittance: Vec<f32>,
    /// Per-triangle texture coordinates and means for the display; empty when no triangle
    /// of the object is textured.
    pub textured: Vec<TexturedTriangle>,
    /// Local-to-world transform (f64 so that kilometre scenes far from the origin keep
    /// their precision until the mesh re-centres them).
    pub world_from_local: DMat4,
}

impl Object {
    /// World-space position of vertex `v`.
    pub fn world_position(&self, v: u32) -> DVec3 {
        self.world_from_local
            .transform_point3(self.positions[v as usize].as_dvec3())
    }

    /// Whether the transform mirrors space (negative determinant). The glTF loader has
    /// already swapped the winding of such objects' triangles so that they are
    /// counter-clockwise in world space; downstream code must not flip again.
    pub fn mirrors(&self) -> bool {
        self.world_from_local.determinant() < 0.0
    }

    /// The reflectance tint of triangle `t` (1 when untextured).
    pub fn reflectance_tint(&self, t: usize) -> Vec3 {
        self.reflectance_tint.get(t).copied().unwrap_or(Vec3::ONE)
    }

    /// Texture coordinates and means of triangle `t` (means of 1 when untextured).
    pub fn textured(&self, t: usize) -> TexturedTriangle {
        self.textured
            .get(t)
            .copied()
            .unwrap_or(TexturedTriangle::NONE)
    }

    /// The emission tint of triangle `t` (1 when untextured).
    pub fn emission_tint(&self, t: usize) -> Vec3 {
        self.emission_tint.get(t).copied().unwrap_or(Vec3::ONE)
    }
}

/// A punctual light (`KHR_lights_punctual`), in world space. Intensities are radiometric:
/// no 683 lm/W factor (ARCHITECTURE.md, "Units and conventions").
#[derive(Clone, Debug, PartialEq)]
pub enum Light {
    /// Isotropic point light: irradiance I cosθ / r² (times the range falloff).
    Point {
        position: DVec3,
        /// Radiant intensity per channel, W/sr.
        intensity: Vec3,
        /// glTF `range`: beyond it the light contributes nothing; `None` is infinite.
        range: Option<f64>,
    },
    /// Spot light: a point light with the glTF smooth cone falloff.
    Spot {
        position: DVec3,
        /// Unit direction the light points to (world).
        direction: DVec3,
        intensity: Vec3,
        range: Option<f64>,
        /// Cone half-angles in radians, inner ≤ outer.
        inner_cone: f64,
        outer_cone: f64,
    },
    /// Directional light: irradiance I cosθ on surfaces facing it.
    Directional {
        /// Unit direction the light travels (world).
        direction: DVec3,
        /// Irradiance on a surface facing the light, W/m² per channel.
        irradiance: Vec3,
    },
}

/// Light from outside the scene, used when a file has no emitters and no lights.
#[derive(Clone, Debug, PartialEq)]
pub struct Environment {
    /// Uniform sky radiance per channel, W/(m²·sr); an unoccluded upward surface receives π L.
    pub sky: Vec3,
    /// Optional sun: unit direction *towards* the sun and its irradiance (W/m²).
    pub sun: Option<(DVec3, Vec3)>,
}

/// The light from outside given on the command line (`--sky`, `--sun`): it replaces a
/// scene's default sky (`Scene::ensure_light`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Outside {
    /// Uniform sky radiance per channel, W/(m²·sr).
    pub sky: Option<Vec3>,
    /// Unit direction towards the sun and its irradiance (W/m²).
    pub sun: Option<(DVec3, Vec3)>,
}

/// A whole scene.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// Where it came from (a path or `builtin:NAME`), for messages.
    pub name: String,
    pub objects: Vec<Object>,
    pub materials: Vec<Material>,
    pub lights: Vec<Light>,
    /// Sky and sun; `None` means the scene is closed to the outside.
    pub environment: Option<Environment>,
    /// The decoded images materials' textures refer to (`TextureRef::image`).
    pub images: Vec<std::sync::Arc<Image>>,
    /// Problems that were recovered from while building the scene (one line each).
    pub warnings: Vec<String>,
}

impl Scene {
    /// Number of triangles over all objects.
    pub fn triangle_count(&self) -> usize {
        self.objects.iter().map(|o| o.triangles.len()).sum()
    }

    /// Whether any material emits or any punctual light exists.
    pub fn has_light(&self) -> bool {
        !self.lights.is_empty()
            || self.objects.iter().any(|o| {
                o.triangle_material.iter().enumerate().any(|(t, &m)| {
                    let e = self.materials[m as usize].emission * o.emission_tint(t);
                    e.max_element() > 0.0
                })
            })
    }

    /// World-space axis-aligned bounds of all vertices (f64), or `None` for an empty scene.
    /// The frame meshes and the reference store positions in: centred on the bounds,
    /// `scale` their diagonal (at least the smallest positive f32).
    pub fn frame(&self) -> crate::geometry::Frame {
        let (lo, hi) = self.bounds().unwrap_or((DVec3::ZERO, DVec3::ZERO));
        crate::geometry::Frame {
            origin: (lo + hi) * 0.5,
            scale: ((hi - lo).length() as f32).max(f32::MIN_POSITIVE),
        }
    }

    pub fn bounds(&self) -> Option<(DVec3, DVec3)> {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for o in &self.objects {
            for t in &o.triangles {
                for &v in t {
                    let p = o.world_position(v);
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
            }
        }
        (lo.x <= hi.x).then_some((lo, hi))
    }

    /// Adds the default environment (uniform sky, optional sun) when the scene has no light
    /// of its own, and records a warning saying so. `sky` and `sun` override the defaults.
    pub fn ensure_light(&mut self, sky: Option<Vec3>, sun: Option<(DVec3, Vec3)>) {
        if sky.is_some() || sun.is_some() {
            self.environment = Some(Environment {
                sky: sky.unwrap_or(Vec3::ZERO),
                sun,
            });
            return;
        }
        if !self.has_light() && self.environment.is_none() {
            self.warnings.push(format!(
                "{}: no emissive material and no light; using a uniform white sky of radiance 1 W/(m²·sr) (set --sky / --sun)",
                self.name
            ));
            self.environment = Some(Environment {
                sky: Vec3::ONE,
                sun: None,
            });
        }
    }
}
