//! The display's exposure: the auto exposure of a solution, shared by the viewer,
//! `radiosity render` and the baked export (which bakes it into the file's colours).

use crate::accel::Bvh;
use crate::mesh::{Mesh, luminance};
use glam::Vec3;

/// The value at quantile `q` ∈ [0, 1] of `v` (sorted in place; 0 for an empty slice).
pub fn percentile(v: &mut [f32], q: f32) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    v[((v.len() - 1) as f32 * q).round() as usize]
}

/// Auto exposure from per-element radiosity: the EV that maps the 95th percentile of the
/// non-emitting elements' radiance to 0.8 before tone mapping, and a false-colour range
/// (log10 W/m²) from three decades below that percentile to the brightest element.
pub fn auto_exposure(mesh: &Mesh, radiosity: &[Vec3]) -> Option<(f32, (f32, f32))> {
    let step = (radiosity.len() / 20_000).max(1);
    let mut lit: Vec<f32> = Vec::new();
    let mut top = 0.0f32;
    for (i, b) in radiosity.iter().enumerate().step_by(step) {
        let l = luminance(*b);
        if !l.is_finite() || l <= 0.0 {
            continue;
        }
        top = top.max(l);
        let patch = mesh.elements.get(i)?.patch as usize;
        if mesh.patches[patch].emission.max_element() <= 0.0 {
            lit.push(l);
        }
    }
    if lit.is_empty() {
        return None;
    }
    let p95 = percentile(&mut lit, 0.95);
    Some((ev_for(p95), (p95.log10() - 3.0, top.max(p95).log10())))
}

/// The EV that shows radiosity luminance `p95` (W/m²) at an exposed radiance of 0.8.
fn ev_for(p95: f32) -> f32 {
    (0.8 * std::f32::consts::PI / p95).log2().clamp(-40.0, 40.0)
}

/// Auto exposure metered on what a camera sees: [`auto_exposure`]'s rule (the 95th
/// percentile of the lit, non-emitting surfaces' radiance at 0.8) over the elements first
/// hit by `rays` (origin and unit direction, mesh frame; a grid over the view), as a
/// camera's meter reads its frame. A scene lit through its roof is then exposed for the
/// arcade in view, not for the sky-lit floor behind the camera. The EV, or `None` when
/// no ray meets a lit surface.
pub fn metered_exposure(
    mesh: &Mesh,
    bvh: &Bvh,
    radiosity: &[Vec3],
    rays: &[(Vec3, Vec3)],
) -> Option<f32> {
    let mut seen: Vec<f32> = rays
        .iter()
        .filter_map(|&(origin, dir)| {
            let hit = bvh.closest_hit(origin, dir, 0.0, f32::INFINITY, u32::MAX)?;
            let e = mesh.element_at(hit.triangle, origin + dir * hit.t, -dir)?;
            let patch = &mesh.patches[mesh.elements[e as usize].patch as usize];
            let l = luminance(*radiosity.get(e as usize)?);
            (patch.emission.max_element() <= 0.0 && l.is_finite() && l > 0.0).then_some(l)
        })
        .collect();
    if seen.is_empty() {
        return None;
    }
    Some(ev_for(percentile(&mut seen, 0.95)))
}

/// Tone-mapping operators, from exposed linear radiance to linear display values in
/// [0, 1] (the target then applies the sRGB transfer).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ToneMap {
    /// Linear, clipped at 1.
    Clamp,
    /// L / (1 + luminance).
    Reinhard,
    /// Narkowicz's fit of the ACES filmic curve (2015, "ACES Filmic Tone Mapping Curve").
    Aces,
    /// Troy Sobotka's AgX: a log encoding in an inset colour space, a sigmoid, and the
    /// outset back, so that bright saturated colours desaturate towards white instead of
    /// clipping per channel (the "minimal AgX" fit of the Blender 4 curve, Wrensch 2023).
    #[default]
    Agx,
}

/// AgX's inset and outset matrices (columns), and its log2 range around mid grey.
const AGX_INSET: [[f32; 3]; 3] = [
    [0.842_479_06, 0.042_328_24, 0.042_375_655],
    [0.078_433_6, 0.878_468_6, 0.078_433_6],
    [0.079_223_745, 0.079_166_13, 0.879_143],
];
const AGX_OUTSET: [[f32; 3]; 3] = [
    [1.196_879, -0.052_896_85, -0.052_971_635],
    [-0.098_020_88, 1.151_903_1, -0.098_043_45],
    [-0.099_029_74, -0.098_961_18, 1.151_073_7],
];
const AGX_MIN_EV: f32 = -12.473_931;
const AGX_MAX_EV: f32 = 4.026_069;

fn mat3(m: [[f32; 3]; 3]) -> glam::Mat3 {
    glam::Mat3::from_cols_array_2d(&m)
}

impl ToneMap {
    pub const ALL: [ToneMap; 4] = [
        ToneMap::Clamp,
        ToneMap::Reinhard,
        ToneMap::Aces,
        ToneMap::Agx,
    ];

    /// The operator on exposed linear radiance `l`, as the shader applies it
    /// (`tonemap` in `shader.wgsl`).
    pub fn apply(self, l: Vec3) -> Vec3 {
        match self {
            ToneMap::Clamp => l.clamp(Vec3::ZERO, Vec3::ONE),
            ToneMap::Reinhard => l / (1.0 + l.dot(Vec3::new(0.2126, 0.7152, 0.0722))),
            ToneMap::Aces => {
                let (a, b, c, d, e) = (2.51, 0.03, 2.43, 0.59, 0.14);
                ((l * (l * a + b)) / (l * (l * c + d) + e)).clamp(Vec3::ZERO, Vec3::ONE)
            }
            ToneMap::Agx => {
                let v = mat3(AGX_INSET) * l.max(Vec3::ZERO);
                let v = (v.max(Vec3::splat(1e-10)).to_array().map(f32::log2)).map(|x| {
                    (x.clamp(AGX_MIN_EV, AGX_MAX_EV) - AGX_MIN_EV) / (AGX_MAX_EV - AGX_MIN_EV)
                });
                let v = Vec3::from_array(v.map(agx_contrast));
                let v = mat3(AGX_OUTSET) * v;
                // The curve's output is display-encoded (gamma 2.2); the target encodes.
                Vec3::from_array(v.max(Vec3::ZERO).to_array().map(|c| c.powf(2.2)))
                    .clamp(Vec3::ZERO, Vec3::ONE)
            }
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            ToneMap::Clamp => "clamp",
            ToneMap::Reinhard => "reinhard",
            ToneMap::Aces => "aces",
            ToneMap::Agx => "agx",
        }
    }
}

/// AgX's sigmoid on the normalised log value: a 6th-order polynomial fit.
fn agx_contrast(x: f32) -> f32 {
    let x2 = x * x;
    let x4 = x2 * x2;
    15.5 * x4 * x2 - 40.14 * x4 * x + 31.96 * x4 - 6.868 * x2 * x + 0.4298 * x2 + 0.1191 * x
        - 0.00232
}

impl std::str::FromStr for ToneMap {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        ToneMap::ALL
            .into_iter()
            .find(|t| t.name() == s)
            .ok_or_else(|| {
                format!("unknown tone map '{s}' (expected clamp, reinhard, aces or agx)")
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tone_maps_are_monotone_and_bounded() {
        for t in ToneMap::ALL {
            let mut last = -1.0;
            for k in 0..200 {
                let l = 1e-3 * 1.06f32.powi(k);
                let v = t.apply(Vec3::splat(l));
                assert!(
                    v.max_element() <= 1.0 && v.min_element() >= 0.0,
                    "{t:?} {l}: {v}"
                );
                assert!(v.x >= last - 1e-6, "{t:?} not monotone at {l}");
                last = v.x;
            }
        }
        // AgX keeps a bright saturated red from clipping to a flat red: as it brightens 4×,
        // its green and blue rise (desaturation towards white), where Reinhard's and the
        // clamp's red sits at 1 with green and blue still near 0.
        let dim = ToneMap::Agx.apply(Vec3::new(2.0, 0.1, 0.1));
        let bright = ToneMap::Agx.apply(Vec3::new(8.0, 0.4, 0.4));
        assert!(
            bright.y > dim.y + 0.2 && bright.z > dim.z + 0.2,
            "{dim} {bright}"
        );
    }
}
