//! Light from outside the element system, as one concept: the scene's punctual lights
//! (`KHR_lights_punctual` point, spot and directional lights) and its environment (sun and
//! uniform sky). [`direct`] computes the irradiance they deliver at a point (their first
//! bounce); [`Punctual`] is the view of the hard-shadow-casting ones that discontinuity
//! meshing and the hard-shadow display use.

pub mod direct;

use crate::accel::Bvh;
use crate::scene::{Environment, Light};
use glam::{DVec3, Vec3};

/// The scene's lights outside the element system: punctual lights (positions in world
/// space) and the environment (sun and sky).
#[derive(Clone, Debug, Default)]
pub struct ExternalLight {
    pub lights: Vec<Light>,
    pub environment: Option<Environment>,
}

impl ExternalLight {
    /// Whether there is no external light at all.
    pub fn is_empty(&self) -> bool {
        self.lights.is_empty() && self.environment.is_none()
    }

    /// The point, spot and directional lights and the sun, in the frame whose origin is
    /// `origin` (see [`punctual_lights`]).
    pub fn punctual(&self, origin: DVec3) -> Vec<Punctual> {
        punctual_lights(&self.lights, self.environment.as_ref(), origin)
    }
}

/// A light whose shadows have sharp edges, in the mesh frame.
#[derive(Clone, Copy, Debug)]
pub enum Punctual {
    /// A point (or spot) light here.
    Point(Vec3),
    /// A light at infinity in this direction (unit, towards the light).
    Direction(Vec3),
}

impl Punctual {
    /// From `p` towards the light (not normalised).
    pub fn towards(self, p: Vec3) -> Vec3 {
        match self {
            Punctual::Point(l) => l - p,
            Punctual::Direction(d) => d,
        }
    }

    /// Whether the light is seen from `x` (the rays skip the triangles `skip`).
    pub fn visible(self, bvh: &Bvh, x: Vec3, skip: [u32; 2]) -> bool {
        let through = match self {
            Punctual::Point(l) => bvh.transmittance(x, l, skip),
            Punctual::Direction(d) => bvh.transmittance_toward(x, d, skip),
        };
        through > 0.5
    }
}

/// The point, spot and directional `lights` and the sun of `environment`, in the mesh
/// frame whose origin is `origin`; those with non-finite or zero data left out.
pub fn punctual_lights(
    lights: &[Light],
    environment: Option<&Environment>,
    origin: DVec3,
) -> Vec<Punctual> {
    let mut out: Vec<Punctual> = lights
        .iter()
        .map(|l| match l {
            Light::Point { position, .. } | Light::Spot { position, .. } => {
                Punctual::Point((*position - origin).as_vec3())
            }
            Light::Directional { direction, .. } => {
                Punctual::Direction((-*direction).normalize_or_zero().as_vec3())
            }
        })
        .collect();
    if let Some((d, _)) = environment.and_then(|e| e.sun) {
        out.push(Punctual::Direction(d.normalize_or_zero().as_vec3()));
    }
    out.retain(|l| match l {
        Punctual::Point(p) => p.is_finite(),
        Punctual::Direction(d) => d.is_finite() && *d != Vec3::ZERO,
    });
    out
}
