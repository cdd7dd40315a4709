//! The scene's images on the GPU: sRGB textures with their mip levels, a sampler per wrap
//! mode (trilinear, 16× anisotropic), and a 1×1 white texture for materials without one.
//!
//! GPU memory is bounded: images larger than the device's texture limit, and then the
//! largest images until all of them fit [`TEXTURE_BUDGET`], lose their top mip levels
//! (each dropped level halves both sides). What was uploaded, and what was dropped, is
//! reported ([`GpuTextures::memory`]).

use crate::scene::{Image, TextureRef, Wrap};
use eframe::egui_wgpu::wgpu;
use std::sync::Arc;

/// The most bytes of textures put on the GPU (all mip levels).
pub const TEXTURE_BUDGET: u64 = 768 << 20;

/// Textures on the GPU, one per scene image.
pub struct GpuTextures {
    views: Vec<wgpu::TextureView>,
    white: wgpu::TextureView,
    /// One sampler per (wrap S, wrap T).
    samplers: Vec<([Wrap; 2], wgpu::Sampler)>,
    memory: TextureMemory,
}

/// What the textures cost on the GPU.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TextureMemory {
    pub images: usize,
    /// Bytes on the GPU, all levels.
    pub bytes: u64,
    /// Images shown smaller than they are (top levels dropped to fit).
    pub downscaled: usize,
}

const WRAPS: [Wrap; 3] = [Wrap::Repeat, Wrap::Mirror, Wrap::Clamp];

fn address(w: Wrap) -> wgpu::AddressMode {
    match w {
        Wrap::Repeat => wgpu::AddressMode::Repeat,
        Wrap::Mirror => wgpu::AddressMode::MirrorRepeat,
        Wrap::Clamp => wgpu::AddressMode::ClampToEdge,
    }
}

/// How many top levels of each image to drop so that each fits `max_side` and all of them
/// `budget` bytes: first the images over the side limit, then the largest level 0 among
/// all, until the sum fits (or every image is down to 1×1).
pub fn levels_to_drop(images: &[Arc<Image>], max_side: u32, budget: u64) -> Vec<usize> {
    let bytes_from = |im: &Image, skip: usize| -> u64 {
        im.levels[skip.min(im.levels.len() - 1)..]
            .iter()
            .map(|l| l.rgba.len() as u64)
            .sum()
    };
    let mut skip: Vec<usize> = images
        .iter()
        .map(|im| {
            im.levels
                .iter()
                .position(|l| l.width.max(l.height) <= max_side)
                .unwrap_or(im.levels.len() - 1)
        })
        .collect();
    let mut total: u64 = images
        .iter()
        .zip(&skip)
        .map(|(im, &s)| bytes_from(im, s))
        .sum();
    while total > budget {
        let largest = (0..images.len())
            .filter(|&i| skip[i] + 1 < images[i].levels.len())
            .max_by_key(|&i| (images[i].levels[skip[i]].rgba.len(), std::cmp::Reverse(i)));
        let Some(i) = largest else { break };
        total -= bytes_from(&images[i], skip[i]) - bytes_from(&images[i], skip[i] + 1);
        skip[i] += 1;
    }
    skip
}

impl GpuTextures {
    /// Uploads `images` (an empty list gives only the white texture).
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue, images: &[Arc<Image>]) -> GpuTextures {
        let max_side = device.limits().max_texture_dimension_2d;
        let skip = levels_to_drop(images, max_side, TEXTURE_BUDGET);
        let mut memory = TextureMemory {
            images: images.len(),
            ..Default::default()
        };
        let views = images
            .iter()
            .zip(&skip)
            .map(|(im, &skip)| {
                let levels = &im.levels[skip.min(im.levels.len() - 1)..];
                memory.bytes += levels.iter().map(|l| l.rgba.len() as u64).sum::<u64>();
                memory.downscaled += (skip > 0) as usize;
                upload(device, queue, &im.name, levels)
            })
            .collect();
        let white = upload(
            device,
            queue,
            "white",
            &[crate::scene::ImageLevel {
                width: 1,
                height: 1,
                rgba: vec![255; 4],
            }],
        );
        let samplers = WRAPS
            .iter()
            .flat_map(|&s| WRAPS.iter().map(move |&t| [s, t]))
            .map(|wrap| {
                let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
                    label: Some("radiosity texture sampler"),
                    address_mode_u: address(wrap[0]),
                    address_mode_v: address(wrap[1]),
                    mag_filter: wgpu::FilterMode::Linear,
                    min_filter: wgpu::FilterMode::Linear,
                    mipmap_filter: wgpu::MipmapFilterMode::Linear,
                    anisotropy_clamp: 16,
                    ..Default::default()
                });
                (wrap, sampler)
            })
            .collect();
        GpuTextures {
            views,
            white,
            samplers,
            memory,
        }
    }

    /// The view and sampler `texture` samples, or white (repeating) for none.
    pub fn binding(&self, texture: Option<TextureRef>) -> (&wgpu::TextureView, &wgpu::Sampler) {
        let (view, wrap) =
            match texture.and_then(|t| Some((self.views.get(t.image as usize)?, t.wrap))) {
                Some(found) => found,
                None => (&self.white, [Wrap::Repeat; 2]),
            };
        let sampler = self
            .samplers
            .iter()
            .find(|(w, _)| *w == wrap)
            .map(|(_, s)| s)
            .unwrap_or(&self.samplers[0].1);
        (view, sampler)
    }

    pub fn memory(&self) -> TextureMemory {
        self.memory
    }
}

/// One sRGB texture holding `levels` (level 0 first).
fn upload(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    name: &str,
    levels: &[crate::scene::ImageLevel],
) -> wgpu::TextureView {
    let top = &levels[0];
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some(name),
        size: wgpu::Extent3d {
            width: top.width,
            height: top.height,
            depth_or_array_layers: 1,
        },
        mip_level_count: levels.len() as u32,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8UnormSrgb,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    for (k, l) in levels.iter().enumerate() {
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &texture,
                mip_level: k as u32,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            &l.rgba,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * l.width),
                rows_per_image: None,
            },
            wgpu::Extent3d {
                width: l.width,
                height: l.height,
                depth_or_array_layers: 1,
            },
        );
    }
    texture.create_view(&Default::default())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::ImageLevel;

    fn image(side: u32) -> Arc<Image> {
        let mut levels = Vec::new();
        let mut s = side;
        loop {
            levels.push(ImageLevel {
                width: s,
                height: s,
                rgba: vec![0; (4 * s * s) as usize],
            });
            if s == 1 {
                break;
            }
            s /= 2;
        }
        Arc::new(Image {
            name: format!("{side}"),
            levels,
            encoded: Vec::new(),
            mime: "image/png",
        })
    }

    #[test]
    fn dropping_levels_fits_the_side_limit_and_the_budget() {
        let images = [image(1024), image(256), image(64)];
        // Nothing to drop with room to spare.
        assert_eq!(levels_to_drop(&images, 8192, u64::MAX), vec![0, 0, 0]);
        // The side limit alone.
        assert_eq!(levels_to_drop(&images, 512, u64::MAX), vec![1, 0, 0]);
        // A budget of 1 MiB: the 1024² image (5.3 MiB with its levels) is the largest, then
        // at 512² still larger than the 256² one, so it drops to 256²: 341 KiB + 341 KiB +
        // 21 KiB fits.
        let skip = levels_to_drop(&images, 8192, 1 << 20);
        let bytes: u64 = images
            .iter()
            .zip(&skip)
            .map(|(im, &s)| {
                im.levels[s..]
                    .iter()
                    .map(|l| l.rgba.len() as u64)
                    .sum::<u64>()
            })
            .sum();
        assert!(bytes <= 1 << 20, "{skip:?}: {bytes}");
        assert_eq!(skip, vec![2, 0, 0]);
    }
}
