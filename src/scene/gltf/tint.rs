//! The texture pass: per-triangle reflectance / emission factors and alpha transmittance
//! from the textures, computed after the geometry is built.
//!
//! Each used image is decoded once, reduced to the per-triangle means of every primitive
//! that uses it, and dropped, so at most one decoded image per worker thread is in memory.
//! Images are processed in parallel (scoped threads, one image each at a time); the
//! results are merged in image order, so the outcome does not depend on the thread count.

use super::material::{AlphaMode, MatInfo};
use super::source::Buffers;
use super::texture::{self, Pyramid};
use super::{CANCELLED, Warnings};
use crate::scene::{Material, Object};
use glam::{Vec2, Vec3};
use serde_json::Value;
use std::path::Path;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// UV triangles of one primitive's kept triangles, for the texture pass.
pub(super) struct TexJob {
    /// Index into the scene's objects.
    pub object: usize,
    /// First triangle of this primitive in that object.
    pub first: usize,
    /// Material index.
    pub material: usize,
    /// Per TEXCOORD set used: the UVs of each triangle's three corners.
    pub uv_sets: Vec<(u32, Vec<[Vec2; 3]>)>,
}

/// Which texture of a material a job samples.
#[derive(Clone, Copy, PartialEq)]
enum Slot {
    Base,
    Emissive,
}

/// The per-triangle outcome of one (job, slot).
struct Outcome {
    job: usize,
    slot: Slot,
    /// Mean linear RGB of the texture over each triangle.
    mean: Vec<Vec3>,
    /// Transmittance per triangle, for MASK and BLEND base-colour textures.
    transmittance: Option<Vec<f32>>,
}

/// One image's outcomes (or why it could not be used), tagged with its index.
type ImageResult = (usize, Result<Vec<Outcome>, String>);

/// Decodes every image used by `jobs` and writes the per-triangle factors into `objects`.
/// An image that cannot be read or decoded is a warning (those surfaces stay untextured);
/// a buffer that cannot be loaded (image in a buffer view) is an error.
#[allow(clippy::too_many_arguments)]
pub(super) fn apply_textures(
    root: &Value,
    buffers: &Buffers<'_>,
    dir: &Path,
    jobs: &[TexJob],
    infos: &[MatInfo],
    materials: &[Material],
    objects: &mut [Object],
    warn: &mut Warnings,
    cancel: &AtomicBool,
) -> Result<(), String> {
    let mut by_image: std::collections::BTreeMap<usize, Vec<(usize, Slot)>> = Default::default();
    for (j, job) in jobs.iter().enumerate() {
        let info = &infos[job.material];
        if let Some(t) = &info.base_tex {
            by_image.entry(t.image).or_default().push((j, Slot::Base));
        }
        if let Some(t) = &info.emissive_tex {
            by_image
                .entry(t.image)
                .or_default()
                .push((j, Slot::Emissive));
        }
    }
    // Encoded bytes are fetched here (buffers are not shared across threads); they are
    // small next to the decoded images.
    let mut work = Vec::new();
    for (image, uses) in by_image {
        if cancel.load(Ordering::Relaxed) {
            return Err(CANCELLED.into());
        }
        let bytes = texture::image_bytes(root, buffers, dir, image);
        if let Some(fatal) = buffers.failure() {
            return Err(fatal);
        }
        work.push((image, uses, bytes));
    }
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(work.len())
        .max(1);
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<ImageResult>> = Mutex::new(Vec::new());
    let worker = || {
        loop {
            let k = next.fetch_add(1, Ordering::Relaxed);
            let Some((image, uses, bytes)) = work.get(k) else {
                break;
            };
            if cancel.load(Ordering::Relaxed) {
                break;
            }
            let outcome = match bytes {
                Ok(b) => Pyramid::decode(b).map(|p| {
                    let mut coverage = Vec::new();
                    uses.iter()
                        .filter_map(|&(j, slot)| {
                            compute(
                                &jobs[j],
                                j,
                                slot,
                                &infos[jobs[j].material],
                                &p,
                                &mut coverage,
                            )
                        })
                        .collect()
                }),
                Err(e) => Err(e.clone()),
            };
            if let Ok(mut r) = results.lock() {
                r.push((*image, outcome));
            }
        }
    };
    if threads == 1 {
        worker();
    } else {
        std::thread::scope(|s| {
            for _ in 0..threads {
                s.spawn(worker);
            }
        });
    }
    if cancel.load(Ordering::Relaxed) {
        return Err(CANCELLED.into());
    }
    let mut results = results.into_inner().unwrap_or_default();
    results.sort_by_key(|(image, _)| *image);
    for (image, outcome) in results {
        match outcome {
            Ok(list) => {
                for o in list {
                    merge(o, jobs, materials, objects);
                }
            }
            Err(e) => {
                let uri = root["images"][image]["uri"]
                    .as_str()
                    .filter(|u| !u.starts_with("data:"));
                let what = uri.map(|u| format!(" ('{u}')")).unwrap_or_default();
                warn.line(format!(
                    "images[{image}]{what}: {e}; surfaces using it are untextured"
                ));
            }
        }
    }
    Ok(())
}

/// Per-triangle means of one texture slot of one job.
fn compute(
    job: &TexJob,
    j: usize,
    slot: Slot,
    info: &MatInfo,
    pyramid: &Pyramid,
    coverage: &mut Vec<(f32, Pyramid)>,
) -> Option<Outcome> {
    let tref = match slot {
        Slot::Base => info.base_tex.as_ref(),
        Slot::Emissive => info.emissive_tex.as_ref(),
    }?;
    let (_, uvs) = job.uv_sets.iter().find(|(s, _)| *s == tref.tex_coord)?;
    // Alpha coverage per MASK triangle: the fraction of texels with
    // baseColorFactor.a × texture alpha ≥ alphaCutoff, i.e. texture alpha ≥ cutoff / factor.
    let mask = match (slot, info.alpha_mode) {
        (Slot::Base, AlphaMode::Mask(cutoff)) => {
            let threshold = if info.base_alpha > 0.0 {
                cutoff / info.base_alpha
            } else {
                f32::INFINITY
            };
            let at = match coverage.iter().position(|(t, _)| *t == threshold) {
                Some(k) => k,
                None => {
                    coverage.push((threshold, pyramid.coverage(threshold)));
                    coverage.len() - 1
                }
            };
            Some(&coverage[at].1)
        }
        _ => None,
    };
    let blend = slot == Slot::Base && info.alpha_mode == AlphaMode::Blend;
    let mut mean = Vec::with_capacity(uvs.len());
    let mut transmittance = (mask.is_some() || blend).then(|| Vec::with_capacity(uvs.len()));
    for uv in uvs {
        let uv = uv.map(|p| texture::transform_uv(tref, p));
        let m = pyramid.triangle_mean(uv, tref.wrap);
        mean.push(Vec3::new(m[0], m[1], m[2]));
        if let Some(t) = &mut transmittance {
            let covered = match mask {
                Some(mask) => mask.triangle_mean(uv, tref.wrap)[0],
                None => info.base_alpha * m[3],
            };
            t.push(info.transmittance(covered));
        }
    }
    Some(Outcome {
        job: j,
        slot,
        mean,
        transmittance,
    })
}

/// Writes one outcome into its object (tints multiply, so `COLOR_0` factors are kept).
fn merge(o: Outcome, jobs: &[TexJob], materials: &[Material], objects: &mut [Object]) {
    let job = &jobs[o.job];
    let object = &mut objects[job.object];
    let count = object.triangles.len();
    let tint = match o.slot {
        Slot::Base => &mut object.reflectance_tint,
        Slot::Emissive => &mut object.emission_tint,
    };
    tint.resize(count, Vec3::ONE);
    for (k, m) in o.mean.iter().enumerate() {
        tint[job.first + k] *= *m;
    }
    if let Some(t) = o.transmittance {
        if object.transmittance.len() != count {
            object.transmittance = object
                .triangle_material
                .iter()
                .map(|&m| materials[m as usize].transmittance)
                .collect();
        }
        object.transmittance[job.first..job.first + t.len()].copy_from_slice(&t);
    }
}
