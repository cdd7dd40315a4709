//! Textures reduced to per-triangle factors: decode an image once, build a box-filtered
//! mip pyramid in linear light, and average it over each triangle's UV footprint.
//!
//! Colour: base-colour and emissive texels are sRGB-encoded ("The first three components
//! (RGB) MUST be encoded with the sRGB transfer function", glTF 2.0 §5.22.2
//! `pbrMetallicRoughness.baseColorTexture` and §5.19.7 `emissiveTexture`); they are decoded
//! with the sRGB EOTF of IEC 61966-2-1 before averaging. Alpha is linear coverage.

use super::json;
use super::source::{Buffers, Target, resolve_uri, view};
use crate::scene::textures::{linear_to_srgb, srgb_to_linear};
use crate::scene::{Image, ImageLevel, Wrap};
use glam::Vec2;
use serde_json::Value;
use std::path::Path;

/// A resolved `textureInfo`: which image, which UV set, how to wrap and transform.
#[derive(Clone, Debug)]
pub(super) struct TexRef {
    /// Index into `images`.
    pub image: usize,
    /// TEXCOORD_n set (after the KHR_texture_transform `texCoord` override).
    pub tex_coord: u32,
    /// Wrap modes for u and v.
    pub wrap: [Wrap; 2],
    /// KHR_texture_transform as two affine rows: u' = r0·(u, v, 1), v' = r1·(u, v, 1).
    pub transform: [[f32; 3]; 2],
}

fn wrap_mode(sampler: Option<&Value>, key: &str) -> Wrap {
    match sampler.and_then(|s| json::uint(s, key).ok().flatten()) {
        Some(33071) => Wrap::Clamp,
        Some(33648) => Wrap::Mirror,
        _ => Wrap::Repeat,
    }
}

/// Resolves a `textureInfo` object (`{index, texCoord, extensions}`) to a [`TexRef`], or
/// `Err(reason)` when it cannot be used (the caller warns and treats it as untextured).
pub(super) fn resolve(root: &Value, info: &Value) -> Result<TexRef, String> {
    let t = json::index(info, "index")?.ok_or("textureInfo has no `index`")?;
    let texture = json::array(root, "textures")?
        .get(t)
        .ok_or_else(|| format!("texture {t} does not exist"))?;
    let image = match json::index(texture, "source").map_err(|e| format!("textures[{t}]: {e}"))? {
        Some(i) => i,
        None => {
            let ext = texture
                .get("extensions")
                .and_then(Value::as_object)
                .and_then(|m| m.keys().next().cloned());
            return Err(match ext {
                Some(e) => format!("textures[{t}] uses an image format we cannot decode ({e})"),
                None => format!("textures[{t}] has no image (`source`)"),
            });
        }
    };
    if image >= json::array(root, "images")?.len() {
        return Err(format!(
            "textures[{t}].source: image {image} does not exist"
        ));
    }
    let sampler = json::index(texture, "sampler")
        .ok()
        .flatten()
        .and_then(|s| root.get("samplers")?.get(s));
    let mut tex_coord = json::uint(info, "texCoord")?.unwrap_or(0);
    let mut transform = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    if let Some(tt) = json::extension(info, "KHR_texture_transform") {
        // KHR_texture_transform: matrix = Translation(offset) · Rotation(rotation) · Scale(scale),
        // with Rotation = [[cos, sin], [−sin, cos]] (the extension's README).
        let off = json::numbers::<2>(tt, "offset")?.unwrap_or([0.0, 0.0]);
        let rot = json::number(tt, "rotation")?.unwrap_or(0.0);
        let scale = json::numbers::<2>(tt, "scale")?.unwrap_or([1.0, 1.0]);
        let (s, c) = rot.sin_cos();
        transform = [
            [(c * scale[0]) as f32, (s * scale[1]) as f32, off[0] as f32],
            [(-s * scale[0]) as f32, (c * scale[1]) as f32, off[1] as f32],
        ];
        if let Some(tc) = json::uint(tt, "texCoord")? {
            tex_coord = tc;
        }
    }
    Ok(TexRef {
        image,
        tex_coord: tex_coord.min(u32::MAX as u64) as u32,
        wrap: [wrap_mode(sampler, "wrapS"), wrap_mode(sampler, "wrapT")],
        transform,
    })
}

/// The encoded bytes of `images[i]` (from a URI or a buffer view).
pub(super) fn image_bytes(
    root: &Value,
    buffers: &Buffers<'_>,
    dir: &Path,
    i: usize,
) -> Result<Vec<u8>, String> {
    let def = json::array(root, "images")?
        .get(i)
        .ok_or_else(|| format!("image {i} does not exist"))?;
    if let Some(uri) = json::string(def, "uri")? {
        return match resolve_uri(dir, uri)? {
            Target::Data(d) => Ok(d),
            Target::File(p) => {
                std::fs::read(&p).map_err(|e| format!("cannot read '{}': {e}", p.display()))
            }
        };
    }
    let v = json::index(def, "bufferView")?.ok_or("image has neither `uri` nor `bufferView`")?;
    Ok(view(root, buffers, v)?.bytes.to_vec())
}

/// Linear value in [0, 1] to an sRGB-encoded byte.
fn encode_srgb(c: f32) -> u8 {
    (linear_to_srgb(c.clamp(0.0, 1.0)) * 255.0).round() as u8
}

/// One mip level: `channels` floats per texel, row-major.
struct Level {
    w: usize,
    h: usize,
    channels: usize,
    px: Vec<f32>,
}

impl Level {
    /// The next level down: 2×2 box filter (odd edges reuse the last row/column).
    fn half(&self) -> Level {
        let (w, h, ch) = ((self.w / 2).max(1), (self.h / 2).max(1), self.channels);
        let mut px = vec![0.0; w * h * ch];
        for y in 0..h {
            let (y0, y1) = ((2 * y).min(self.h - 1), (2 * y + 1).min(self.h - 1));
            for x in 0..w {
                let (x0, x1) = ((2 * x).min(self.w - 1), (2 * x + 1).min(self.w - 1));
                for c in 0..ch {
                    let at = |xx: usize, yy: usize| self.px[(yy * self.w + xx) * ch + c];
                    px[(y * w + x) * ch + c] =
                        0.25 * (at(x0, y0) + at(x1, y0) + at(x0, y1) + at(x1, y1));
                }
            }
        }
        Level {
            w,
            h,
            channels: ch,
            px,
        }
    }

    /// The level as sRGB-encoded RGBA8 (4 channels; IEC 61966-2-1 OETF, rounded).
    fn to_srgb8(&self) -> ImageLevel {
        let rgba = self
            .px
            .chunks_exact(4)
            .flat_map(|t| {
                [
                    encode_srgb(t[0]),
                    encode_srgb(t[1]),
                    encode_srgb(t[2]),
                    (t[3].clamp(0.0, 1.0) * 255.0).round() as u8,
                ]
            })
            .collect();
        ImageLevel {
            width: self.w as u32,
            height: self.h as u32,
            rgba,
        }
    }

    /// Bilinear sample at texture coordinates (u, v), wrapped per `wrap`.
    fn bilinear(&self, u: f32, v: f32, wrap: [Wrap; 2], out: &mut [f32; 4]) {
        let wrap_i = |i: i64, n: usize, mode: Wrap| -> usize {
            let n = n as i64;
            (match mode {
                Wrap::Repeat => i.rem_euclid(n),
                Wrap::Clamp => i.clamp(0, n - 1),
                Wrap::Mirror => {
                    let p = i.rem_euclid(2 * n);
                    if p < n { p } else { 2 * n - 1 - p }
                }
            }) as usize
        };
        // Keep coordinates in a range where f32 → i64 is exact and cheap.
        let fold = |t: f32, mode: Wrap| match mode {
            Wrap::Repeat => t - t.floor(),
            Wrap::Mirror => t - 2.0 * (t * 0.5).floor(),
            Wrap::Clamp => t.clamp(0.0, 1.0),
        };
        let (u, v) = (fold(u, wrap[0]), fold(v, wrap[1]));
        let x = u * self.w as f32 - 0.5;
        let y = v * self.h as f32 - 0.5;
        let (xf, yf) = (x.floor(), y.floor());
        let (fx, fy) = (x - xf, y - yf);
        let (xi, yi) = (xf as i64, yf as i64);
        let xs = [wrap_i(xi, self.w, wrap[0]), wrap_i(xi + 1, self.w, wrap[0])];
        let ys = [wrap_i(yi, self.h, wrap[1]), wrap_i(yi + 1, self.h, wrap[1])];
        let weights = [
            (1.0 - fx) * (1.0 - fy),
            fx * (1.0 - fy),
            (1.0 - fx) * fy,
            fx * fy,
        ];
        let ch = self.channels;
        *out = [0.0; 4];
        for (k, wgt) in weights.iter().enumerate() {
            let base = (ys[k / 2] * self.w + xs[k % 2]) * ch;
            for (o, p) in out.iter_mut().zip(&self.px[base..base + ch]) {
                *o += wgt * p;
            }
        }
    }
}

/// A mip pyramid (level 0 = the image).
pub(super) struct Pyramid {
    levels: Vec<Level>,
}

impl Pyramid {
    fn build(level0: Level) -> Pyramid {
        let mut levels = vec![level0];
        while let Some(last) = levels.last()
            && (last.w > 1 || last.h > 1)
        {
            let next = last.half();
            levels.push(next);
        }
        Pyramid { levels }
    }

    /// Decodes an encoded PNG or JPEG into linear RGBA (sRGB decoded for RGB), and the
    /// image as it was encoded (8 bits per channel) for the display, named `name`.
    pub fn decode(bytes: &[u8], name: String) -> Result<(Pyramid, Image), String> {
        let decoded = std::panic::catch_unwind(|| -> Result<image::DynamicImage, String> {
            let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
                .with_guessed_format()
                .map_err(|e| e.to_string())?;
            let mut limits = image::Limits::default();
            limits.max_image_width = Some(16384);
            limits.max_image_height = Some(16384);
            reader.limits(limits);
            reader.decode().map_err(|e| e.to_string())
        })
        .map_err(|_| "the image decoder panicked".to_string())??;
        let (w, h) = (decoded.width() as usize, decoded.height() as usize);
        if w == 0 || h == 0 {
            return Err("the image is empty".into());
        }
        let color = decoded.color();
        let rgba8 = decoded.to_rgba8();
        let px: Vec<f32> = if color.bytes_per_pixel() == color.channel_count() {
            // 8 bits per channel: decode sRGB through a 256-entry table.
            let lut: Vec<f32> = (0..256).map(|i| srgb_to_linear(i as f32 / 255.0)).collect();
            let mut px = Vec::with_capacity(w * h * 4);
            for t in rgba8.pixels() {
                let [r, g, b, a] = t.0;
                px.extend([
                    lut[r as usize],
                    lut[g as usize],
                    lut[b as usize],
                    a as f32 / 255.0,
                ]);
            }
            px
        } else {
            let mut px = decoded.to_rgba32f().into_raw();
            for t in px.chunks_exact_mut(4) {
                for c in &mut t[..3] {
                    *c = srgb_to_linear(c.clamp(0.0, 1.0));
                }
            }
            px
        };
        let pyramid = Pyramid::build(Level {
            w,
            h,
            channels: 4,
            px,
        });
        let mut levels = vec![ImageLevel {
            width: w as u32,
            height: h as u32,
            rgba: rgba8.into_raw(),
        }];
        levels.extend(pyramid.levels[1..].iter().map(Level::to_srgb8));
        let mime = match image::guess_format(bytes) {
            Ok(image::ImageFormat::Jpeg) => "image/jpeg",
            _ => "image/png",
        };
        let image = Image {
            name,
            levels,
            encoded: bytes.to_vec(),
            mime,
        };
        Ok((pyramid, image))
    }

    /// Coverage pyramid: level 0 is 1 where alpha ≥ `threshold`, else 0; higher levels hold
    /// the covered fraction, so sampling them gives the fraction of texels that pass.
    pub fn coverage(&self, threshold: f32) -> Pyramid {
        let l0 = &self.levels[0];
        let px = l0
            .px
            .chunks_exact(4)
            .map(|t| f32::from(t[3] >= threshold))
            .collect();
        Pyramid::build(Level {
            w: l0.w,
            h: l0.h,
            channels: 1,
            px,
        })
    }

    /// Size of level 0 in texels.
    fn texels(&self) -> f32 {
        (self.levels[0].w * self.levels[0].h) as f32
    }

    /// Trilinear sample at UV with fractional mip level `lod`.
    fn sample(&self, uv: Vec2, lod: f32, wrap: [Wrap; 2]) -> [f32; 4] {
        let top = (self.levels.len() - 1) as f32;
        let lod = lod.clamp(0.0, top);
        let l0 = lod.floor() as usize;
        let t = lod - l0 as f32;
        let mut a = [0.0; 4];
        self.levels[l0].bilinear(uv.x, uv.y, wrap, &mut a);
        if t > 0.0 && l0 + 1 < self.levels.len() {
            let mut b = [0.0; 4];
            self.levels[l0 + 1].bilinear(uv.x, uv.y, wrap, &mut b);
            for c in 0..4 {
                a[c] += t * (b[c] - a[c]);
            }
        }
        a
    }

    /// Mean over a triangle with texture coordinates `uv` (already transformed): the
    /// average of [`SAMPLES`] stratified samples, each read at the mip level whose texel
    /// area matches the sample's share of the footprint (so a triangle covering the
    /// texture many times over averages all of it rather than aliasing).
    pub fn triangle_mean(&self, uv: [Vec2; 3], wrap: [Wrap; 2]) -> [f32; 4] {
        let area_texels = 0.5 * (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]).abs() * self.texels();
        let per_sample = area_texels / SAMPLES.len() as f32;
        let lod = if per_sample.is_finite() && per_sample > 1.0 {
            0.5 * per_sample.log2()
        } else {
            0.0
        };
        let mut sum = [0.0f32; 4];
        for &(b1, b2) in SAMPLES.iter() {
            let p = uv[0] + (uv[1] - uv[0]) * b1 + (uv[2] - uv[0]) * b2;
            let p = if p.is_finite() { p } else { Vec2::ZERO };
            let s = self.sample(p, lod, wrap);
            for c in 0..4 {
                sum[c] += s[c];
            }
        }
        sum.map(|s| s / SAMPLES.len() as f32)
    }
}

/// Applies a [`TexRef`]'s KHR_texture_transform to a UV.
pub(super) fn transform_uv(t: &TexRef, uv: Vec2) -> Vec2 {
    let [r0, r1] = t.transform;
    Vec2::new(
        r0[0] * uv.x + r0[1] * uv.y + r0[2],
        r1[0] * uv.x + r1[1] * uv.y + r1[2],
    )
}

/// Barycentric sample points (b1, b2) at the centroids of the 16 equal-area sub-triangles
/// of a 4× midpoint subdivision: a stratified, symmetric cover of the triangle.
const SAMPLES: [(f32, f32); 16] = {
    let mut out = [(0.0f32, 0.0f32); 16];
    let n = 4;
    let mut k = 0;
    let mut i = 0;
    while i < n {
        let mut j = 0;
        while j < n - i {
            out[k] = (
                (i as f32 + 1.0 / 3.0) / n as f32,
                (j as f32 + 1.0 / 3.0) / n as f32,
            );
            k += 1;
            if i + j < n - 1 {
                out[k] = (
                    (i as f32 + 2.0 / 3.0) / n as f32,
                    (j as f32 + 2.0 / 3.0) / n as f32,
                );
                k += 1;
            }
            j += 1;
        }
        i += 1;
    }
    out
};

#[cfg(test)]
mod tests {
    use super::*;

    fn checker(n: usize) -> Pyramid {
        let mut px = Vec::new();
        for y in 0..n {
            for x in 0..n {
                let v = ((x + y) % 2) as f32;
                px.extend([v, v, v, 1.0]);
            }
        }
        Pyramid::build(Level {
            w: n,
            h: n,
            channels: 4,
            px,
        })
    }

    #[test]
    fn samples_cover_the_triangle_evenly() {
        let (mut s1, mut s2) = (0.0, 0.0);
        for &(a, b) in SAMPLES.iter() {
            assert!(a > 0.0 && b > 0.0 && a + b < 1.0);
            s1 += a;
            s2 += b;
        }
        // The mean of uniform points over a triangle is its centroid (1/3, 1/3).
        assert!((s1 / 16.0 - 1.0 / 3.0).abs() < 1e-6 && (s2 / 16.0 - 1.0 / 3.0).abs() < 1e-6);
    }

    #[test]
    fn large_footprint_averages_the_whole_texture() {
        let p = checker(64);
        // A triangle covering the texture 8×8 times over (repeat): mean must be 1/2.
        let uv = [Vec2::ZERO, Vec2::new(16.0, 0.0), Vec2::new(0.0, 16.0)];
        let m = p.triangle_mean(uv, [Wrap::Repeat; 2]);
        assert!((m[0] - 0.5).abs() < 0.02, "{m:?}");
    }

    #[test]
    fn srgb_bytes_round_trip() {
        for b in 0..=255u8 {
            assert_eq!(encode_srgb(srgb_to_linear(b as f32 / 255.0)), b);
        }
    }

    #[test]
    fn srgb() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_to_linear(0.5) - 0.214).abs() < 1e-3);
    }
}
