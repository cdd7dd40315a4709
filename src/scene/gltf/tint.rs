//! The texture pass: per-triangle reflectance / emission factors and alpha transmittance
//! from the textures, computed after the geometry is built; and for the display, the
//! decoded images (8 bits per channel, as encoded), each material's texture references
//! and each textured triangle's coordinates and means.
//!
//! Each used image is decoded once, reduced to the per-triangle means of every primitive
//! that uses it, and dropped, so at most one decoded image per worker thread is in memory.
//! Images are processed in parallel (scoped threads, one image each at a time); the
//! results are merged in image order, so the outcome does not depend on the thread count.

use super::material::{AlphaMode, MatInfo};
use super::source::Buffers;
use super::texture::{self, Pyramid};
use super::{CANCELLED, Warnings};
use crate::scene::{Image, Material, Object, Slot, TextureRef, TexturedTriangle};
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

/// The per-triangle outcome of one (job, slot).
struct Outcome {
    job: usize,
    slot: Slot,
    /// Mean linear RGB of the texture over each triangle.
    mean: Vec<Vec3>,
    /// Each triangle's texture coordinates (transformed).
    uv: Vec<[Vec2; 3]>,
    /// Transmittance per triangle, for MASK and BLEND base-colour textures.
    transmittance: Option<Vec<f32>>,
}

/// One image's outcomes and its decoded pixels (or why it could not be used), tagged with
/// its index.
type ImageResult = (usize, Result<(Vec<Outcome>, Image), String>);

/// Decodes every image used by `jobs`, writes the per-triangle factors into `objects` and
/// the texture references into `materials`, and returns the decoded images the references
/// index. An image that cannot be read or decoded is a warning (those surfaces stay
/// untextured); a buffer that cannot be loaded (image in a buffer view) is an error.
#[allow(clippy::too_many_arguments)]
pub(super) fn apply_textures(
    root: &Value,
    buffers: &Buffers<'_>,
    dir: &Path,
    jobs: &[TexJob],
    infos: &[MatInfo],
    materials: &mut [Material],
    objects: &mut [Object],
    warn: &mut Warnings,
    cancel: &AtomicBool,
) -> Result<Vec<std::sync::Arc<Image>>, String> {
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
                Ok(b) => Pyramid::decode(b, image_name(root, *image)).map(|(p, decoded)| {
                    let mut coverage = Vec::new();
                    let outcomes = uses
                        .iter()
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
                        .collect();
                    (outcomes, decoded)
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
    let mut images = Vec::new();
    for (image, outcome) in results {
        match outcome {
            Ok((list, decoded)) => {
                let index = images.len() as u32;
                images.push(std::sync::Arc::new(decoded));
                for (m, info) in infos.iter().enumerate() {
                    let material = &mut materials[m];
                    if let Some(t) = info.base_tex.as_ref().filter(|t| t.image == image) {
                        material.base_texture = Some(TextureRef {
                            image: index,
                            wrap: t.wrap,
                        });
                        material.alpha_cutoff = match info.alpha_mode {
                            AlphaMode::Mask(cutoff) if info.base_alpha > 0.0 => {
                                Some(cutoff / info.base_alpha)
                            }
                            AlphaMode::Mask(_) => Some(f32::MAX),
                            _ => None,
                        };
                    }
                    if let Some(t) = info.emissive_tex.as_ref().filter(|t| t.image == image) {
                        material.emissive_texture = Some(TextureRef {
                            image: index,
                            wrap: t.wrap,
                        });
                    }
                }
                for o in list {
                    merge(o, jobs, materials, objects);
                }
            }
            Err(e) => warn.line(format!(
                "{}: {e}; surfaces using it are untextured",
                image_name(root, image)
            )),
        }
    }
    Ok(images)
}

/// `images[i]`, with its URI unless it is a `data:` URI.
fn image_name(root: &Value, image: usize) -> String {
    let uri = root["images"][image]["uri"]
        .as_str()
        .filter(|u| !u.starts_with("data:"));
    let what = uri.map(|u| format!(" ('{u}')")).unwrap_or_default();
    format!("images[{image}]{what}")
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
    let mut uv_out = Vec::with_capacity(uvs.len());
    let mut transmittance = (mask.is_some() || blend).then(|| Vec::with_capacity(uvs.len()));
    for uv in uvs {
        let uv = uv.map(|p| texture::transform_uv(tref, p));
        let m = pyramid.triangle_mean(uv, tref.wrap);
        mean.push(Vec3::new(m[0], m[1], m[2]));
        uv_out.push(uv);
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
        uv: uv_out,
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
    object.textured.resize(count, TexturedTriangle::NONE);
    for (k, (m, uv)) in o.mean.iter().zip(&o.uv).enumerate() {
        let t = &mut object.textured[job.first + k];
        t.mean[o.slot as usize] = *m;
        t.uv[o.slot as usize] = *uv;
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
