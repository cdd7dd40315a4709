//! glTF materials → [`Material`] (units: ARCHITECTURE.md, "Units and conventions") plus what the texture pass needs.

use super::Warnings;
use super::json;
use super::texture::{self, TexRef};
use crate::scene::Material;
use glam::Vec3;
use serde_json::Value;

/// Largest reflectance kept: a perfectly white (ρ = 1) surface would make the radiosity
/// system singular in a closed scene.
pub(super) const MAX_REFLECTANCE: f32 = 0.999;

/// How alpha is interpreted (`material.alphaMode`, glTF 2.0 §3.9.4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum AlphaMode {
    /// Alpha ignored.
    Opaque,
    /// Covered where alpha ≥ the cutoff (default 0.5).
    Mask(f32),
    /// Partly transparent by alpha.
    Blend,
}

/// The per-material facts the geometry and texture passes need beyond [`Material`].
#[derive(Clone, Debug)]
pub(super) struct MatInfo {
    /// Base colour texture, when usable.
    pub base_tex: Option<TexRef>,
    /// Emissive texture, when usable.
    pub emissive_tex: Option<TexRef>,
    /// Alpha interpretation.
    pub alpha_mode: AlphaMode,
    /// `baseColorFactor.a`.
    pub base_alpha: f32,
    /// `KHR_materials_transmission.transmissionFactor` (0 when absent).
    pub transmission: f32,
    /// Written by our baked export (`extras.radiosity`): the primitives' `COLOR_0` is
    /// baked light, not a vertex colour.
    pub baked: bool,
}

impl MatInfo {
    /// Transmittance of a surface whose alpha coverage is `coverage` ∈ [0, 1]: the
    /// uncovered part lets everything through, the covered part the transmission factor.
    pub fn transmittance(&self, coverage: f32) -> f32 {
        (1.0 - coverage.clamp(0.0, 1.0) * (1.0 - self.transmission)).clamp(0.0, 1.0)
    }

    /// Transmittance when no texture modulates alpha.
    pub fn untextured_transmittance(&self) -> f32 {
        self.transmittance(match self.alpha_mode {
            AlphaMode::Opaque => 1.0,
            AlphaMode::Mask(cutoff) => f32::from(self.base_alpha >= cutoff),
            AlphaMode::Blend => self.base_alpha,
        })
    }
}

/// The glTF default material (§3.9.6): white, opaque, single-sided, no emission. Its
/// base colour 1 is clamped to [`MAX_REFLECTANCE`] without a warning.
pub(super) fn default_material() -> (Material, MatInfo) {
    let info = MatInfo {
        base_tex: None,
        emissive_tex: None,
        alpha_mode: AlphaMode::Opaque,
        base_alpha: 1.0,
        transmission: 0.0,
        baked: false,
    };
    (
        Material::diffuse("default", Vec3::splat(MAX_REFLECTANCE)),
        info,
    )
}

/// Replaces NaN and negative components by 0; says whether any was replaced.
fn sanitize(v: &mut [f64]) -> bool {
    let mut bad = false;
    for x in v.iter_mut() {
        if !x.is_finite() || *x < 0.0 {
            bad = true;
            *x = 0.0;
        }
    }
    bad
}

/// Converts `materials[i]`. Problems are recorded in `warn`; the result is always usable.
pub(super) fn convert(
    root: &Value,
    i: usize,
    def: &Value,
    warn: &mut Warnings,
) -> (Material, MatInfo) {
    let name = json::name(def)
        .map(str::to_string)
        .unwrap_or_else(|| format!("material {i}"));
    let at = format!("materials[{i}] ('{name}')");
    // Problems are collected here and written as warnings at the end.
    let mut problems: Vec<String> = Vec::new();
    let pbr = def.get("pbrMetallicRoughness").filter(|v| v.is_object());

    let mut base = [1.0f64; 4];
    if let Some(p) = pbr {
        match json::numbers::<4>(p, "baseColorFactor") {
            Ok(Some(b)) => base = b,
            Ok(None) => {}
            Err(e) => problems.push(format!("{e}; using white")),
        }
    }
    if sanitize(&mut base) {
        problems.push("negative or non-numeric baseColorFactor component set to 0".into());
    }
    if base[..3].iter().any(|&c| c > 1.0) {
        warn.clamped_reflectance.push(name.clone());
    }
    let reflectance = Vec3::new(base[0] as f32, base[1] as f32, base[2] as f32)
        .clamp(Vec3::ZERO, Vec3::splat(MAX_REFLECTANCE));
    let base_alpha = base[3].min(1.0) as f32;

    let mut emissive = match json::numbers::<3>(def, "emissiveFactor") {
        Ok(e) => e.unwrap_or([0.0; 3]),
        Err(e) => {
            problems.push(format!("{e}; no emission"));
            [0.0; 3]
        }
    };
    if sanitize(&mut emissive) {
        problems.push("negative or non-numeric emissiveFactor component set to 0".into());
    }
    if emissive.iter().any(|&e| e > 1.0) {
        warn.hdr_emission.push(name.clone());
    }
    let mut strength = 1.0f64;
    if let Some(ext) = json::extension(def, "KHR_materials_emissive_strength") {
        match json::number(ext, "emissiveStrength") {
            Ok(Some(s)) if s.is_finite() && s >= 0.0 => strength = s,
            Ok(None) => {}
            Ok(Some(s)) => problems.push(format!(
                "emissiveStrength {s} is invalid (must be ≥ 0); using 1"
            )),
            Err(e) => problems.push(format!("KHR_materials_emissive_strength: {e}; using 1")),
        }
    }
    // Products in f64 so that factor × strength written by `write_gltf` round-trips exactly.
    let emission = Vec3::new(
        (emissive[0] * strength) as f32,
        (emissive[1] * strength) as f32,
        (emissive[2] * strength) as f32,
    );

    let double_sided = json::boolean(def, "doubleSided").unwrap_or_else(|e| {
        problems.push(format!("{e}; single-sided"));
        None
    });
    let alpha_mode = match json::string(def, "alphaMode") {
        Ok(None | Some("OPAQUE")) => AlphaMode::Opaque,
        Ok(Some("BLEND")) => AlphaMode::Blend,
        Ok(Some("MASK")) => {
            let cutoff = match json::number(def, "alphaCutoff") {
                Ok(Some(c)) if c.is_finite() && c >= 0.0 => c as f32,
                Ok(None) => 0.5,
                Ok(Some(c)) => {
                    problems.push(format!("alphaCutoff {c} is invalid; using 0.5"));
                    0.5
                }
                Err(e) => {
                    problems.push(format!("{e}; using 0.5"));
                    0.5
                }
            };
            AlphaMode::Mask(cutoff)
        }
        Ok(Some(other)) => {
            problems.push(format!("unknown alphaMode '{other}'; opaque"));
            AlphaMode::Opaque
        }
        Err(e) => {
            problems.push(format!("{e}; opaque"));
            AlphaMode::Opaque
        }
    };
    let mut transmission = 0.0;
    if let Some(ext) = json::extension(def, "KHR_materials_transmission") {
        match json::number(ext, "transmissionFactor") {
            Ok(Some(t)) if t.is_finite() => {
                if !(0.0..=1.0).contains(&t) {
                    problems.push(format!("transmissionFactor {t} is outside [0, 1]; clamped"));
                }
                transmission = t.clamp(0.0, 1.0) as f32;
            }
            Ok(Some(t)) => problems.push(format!("transmissionFactor {t} is invalid; opaque")),
            Ok(None) => {}
            Err(e) => problems.push(format!("KHR_materials_transmission: {e}; opaque")),
        }
    }

    let mut tex = |info: Option<&Value>, what: &str| -> Option<TexRef> {
        let info = info?;
        match texture::resolve(root, info) {
            Ok(t) => Some(t),
            Err(e) => {
                problems.push(format!("{what}: {e}; ignored (untextured)"));
                None
            }
        }
    };
    let base_tex = tex(
        pbr.and_then(|p| p.get("baseColorTexture")),
        "baseColorTexture",
    );
    let emissive_tex = if emission.max_element() > 0.0 {
        tex(def.get("emissiveTexture"), "emissiveTexture")
    } else {
        None // an emissive texture times a zero factor is no emission at all
    };

    // A file baked by our export carries the scene's physical values (its visible
    // material is unlit, emitters white) in `extras.radiosity`.
    let baked = def.get("extras").and_then(|e| e.get("radiosity"));
    let physical = |key: &str| {
        baked
            .and_then(|b| json::numbers::<3>(b, key).ok().flatten())
            .map(|v| Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32))
    };
    let (reflectance, emission, double_sided) =
        match (physical("reflectance"), physical("emission")) {
            (Some(r), Some(e)) => (
                r.clamp(Vec3::ZERO, Vec3::splat(MAX_REFLECTANCE)),
                e.max(Vec3::ZERO),
                baked.and_then(|b| json::boolean(b, "doubleSided").ok().flatten()),
            ),
            _ => (reflectance, emission, double_sided),
        };
    let info = MatInfo {
        base_tex,
        emissive_tex,
        alpha_mode,
        base_alpha,
        transmission,
        baked: baked.is_some(),
    };
    for p in problems {
        warn.line(format!("{at}: {p}"));
    }
    let material = Material {
        name,
        reflectance,
        emission,
        double_sided: double_sided.unwrap_or(false),
        transmittance: info.untextured_transmittance(),
        base_texture: None,
        emissive_texture: None,
        alpha_cutoff: None,
    };
    (material, info)
}
