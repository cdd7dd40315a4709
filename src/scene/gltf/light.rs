//! `KHR_lights_punctual` light definitions and their placement by nodes.
//!
//! Per the extension (README, "Directional" / "Point" / "Spot"): lights shine along the
//! node's local −Z; point and spot lights sit at the node's origin; scale does not change
//! the cone. Intensities are taken radiometrically (ARCHITECTURE.md, "Units and conventions"): `color × intensity` is
//! W/sr for point and spot lights and W/m² of irradiance for directional ones.
//!
//! The spot cone is stored as its two half-angles; the angular falloff between them is the
//! extension's reference ("Inner and Outer Cone Angles"): with
//! `scale = 1 / max(0.001, cos(inner) − cos(outer))` and `offset = −cos(outer) · scale`,
//! the attenuation at angle θ from the axis is `saturate(cos θ · scale + offset)²`. The
//! solver evaluates it; defaults are inner 0 and outer π/4.

use super::json;
use crate::scene::Light;
use glam::{DMat4, DVec3, Vec3};
use serde_json::Value;

/// A validated light definition, not yet placed.
#[derive(Clone, Debug)]
pub(super) struct LightDef {
    kind: Kind,
    /// color × intensity.
    radiant: Vec3,
    range: Option<f64>,
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    Point,
    Spot { inner: f64, outer: f64 },
    Directional,
}

/// Parses the root `extensions.KHR_lights_punctual.lights` array. Invalid entries are
/// `Err(reason)` so that nodes referring to them can be skipped with a warning.
pub(super) fn definitions(root: &Value) -> Vec<Result<LightDef, String>> {
    let Some(ext) = json::extension(root, "KHR_lights_punctual") else {
        return Vec::new();
    };
    match json::array(ext, "lights") {
        Ok(lights) => lights.iter().map(definition).collect(),
        Err(_) => Vec::new(),
    }
}

fn definition(def: &Value) -> Result<LightDef, String> {
    let color = json::numbers::<3>(def, "color")?.unwrap_or([1.0; 3]);
    if color.iter().any(|c| !c.is_finite() || *c < 0.0) {
        return Err(format!(
            "color {color:?} has a negative or non-finite component"
        ));
    }
    let intensity = json::number(def, "intensity")?.unwrap_or(1.0);
    if !intensity.is_finite() || intensity < 0.0 {
        return Err(format!("intensity {intensity} must be ≥ 0"));
    }
    let range = json::number(def, "range")?;
    if let Some(r) = range
        && !(r.is_finite() && r > 0.0)
    {
        return Err(format!("range {r} must be > 0"));
    }
    let kind = match json::string(def, "type")? {
        Some("point") => Kind::Point,
        Some("directional") => Kind::Directional,
        Some("spot") => {
            let spot = def.get("spot").cloned().unwrap_or(Value::Null);
            let inner = json::number(&spot, "innerConeAngle")?.unwrap_or(0.0);
            let outer =
                json::number(&spot, "outerConeAngle")?.unwrap_or(std::f64::consts::FRAC_PI_4);
            if !(0.0 <= inner && inner < outer && outer <= std::f64::consts::FRAC_PI_2) {
                return Err(format!(
                    "spot cone angles inner {inner}, outer {outer} do not satisfy 0 ≤ inner < outer ≤ π/2"
                ));
            }
            Kind::Spot { inner, outer }
        }
        Some(other) => return Err(format!("unknown light type '{other}'")),
        None => return Err("no light type".into()),
    };
    let radiant = Vec3::new(
        (color[0] * intensity) as f32,
        (color[1] * intensity) as f32,
        (color[2] * intensity) as f32,
    );
    Ok(LightDef {
        kind,
        radiant,
        range,
    })
}

/// Places a light definition with the node's `world_from_local`.
pub(super) fn place(def: &LightDef, world: DMat4) -> Result<Light, String> {
    let position = world.transform_point3(DVec3::ZERO);
    let direction = world.transform_vector3(DVec3::NEG_Z).normalize_or_zero();
    if !position.is_finite() {
        return Err("its node's transform is not finite".into());
    }
    let needs_direction = !matches!(def.kind, Kind::Point);
    if needs_direction && direction == DVec3::ZERO {
        return Err("its node's transform collapses the light's direction (zero scale)".into());
    }
    Ok(match def.kind {
        Kind::Point => Light::Point {
            position,
            intensity: def.radiant,
            range: def.range,
        },
        Kind::Spot { inner, outer } => Light::Spot {
            position,
            direction,
            intensity: def.radiant,
            range: def.range,
            inner_cone: inner,
            outer_cone: outer,
        },
        Kind::Directional => Light::Directional {
            direction,
            irradiance: def.radiant,
        },
    })
}
