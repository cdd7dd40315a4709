//! What the display needs of a scene's textures: the decoded images, which image a
//! material's base colour and emission sample, and each textured triangle's coordinates.
//!
//! The solver never samples a texture: it uses each triangle's mean (the tints on
//! [`Object`](super::Object)). The display shows the texture under that light:
//! displayed radiance = albedo(uv) · H / π + L_e(uv), with H the solved irradiance.

use glam::{Vec2, Vec3, Vec4};

/// A decoded image with its mip levels, and the file's encoded bytes (for export).
#[derive(Clone, PartialEq)]
pub struct Image {
    /// Where it came from (`images[i]` and its URI), for messages and the stats panel.
    pub name: String,
    /// Level 0 is the image as encoded; each next level halves both sides (2×2 box filter
    /// in linear light), down to 1×1.
    pub levels: Vec<ImageLevel>,
    /// The encoded file (PNG or JPEG) and its media type.
    pub encoded: Vec<u8>,
    pub mime: &'static str,
}

/// One mip level: sRGB-encoded RGBA, 8 bits per channel, rows from the top.
#[derive(Clone, PartialEq)]
pub struct ImageLevel {
    pub width: u32,
    pub height: u32,
    /// `width × height × 4` bytes.
    pub rgba: Vec<u8>,
}

impl Image {
    /// Bytes of all levels.
    pub fn bytes(&self) -> usize {
        self.levels.iter().map(|l| l.rgba.len()).sum()
    }

    /// Bilinear sample of mip level `level` (clamped to the last) at `uv`, wrapped per
    /// `wrap`, with texel centres at half-integers as GPUs sample: linear RGB (sRGB
    /// decoded) and alpha.
    pub fn sample(&self, level: usize, uv: Vec2, wrap: [Wrap; 2]) -> Vec4 {
        let l = &self.levels[level.min(self.levels.len() - 1)];
        let (w, h) = (l.width as i64, l.height as i64);
        let x = uv.x * w as f32 - 0.5;
        let y = uv.y * h as f32 - 0.5;
        let (xf, yf) = (x.floor(), y.floor());
        let (fx, fy) = (x - xf, y - yf);
        let texel = |i: i64, j: i64| -> Vec4 {
            let (i, j) = (wrap_index(i, w, wrap[0]), wrap_index(j, h, wrap[1]));
            let t = &l.rgba[4 * (j * w + i) as usize..][..4];
            Vec4::new(
                srgb_decode(t[0]),
                srgb_decode(t[1]),
                srgb_decode(t[2]),
                t[3] as f32 / 255.0,
            )
        };
        let (i, j) = (xf as i64, yf as i64);
        let top = texel(i, j) * (1.0 - fx) + texel(i + 1, j) * fx;
        let bottom = texel(i, j + 1) * (1.0 - fx) + texel(i + 1, j + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }
}

/// Texel index `i` of a row of `n` wrapped per `mode` (glTF §5.26, as GPUs address).
fn wrap_index(i: i64, n: i64, mode: Wrap) -> i64 {
    match mode {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::Clamp => i.clamp(0, n - 1),
        Wrap::Mirror => {
            let p = i.rem_euclid(2 * n);
            if p < n { p } else { 2 * n - 1 - p }
        }
    }
}

/// An sRGB-encoded byte to linear (IEC 61966-2-1 EOTF).
fn srgb_decode(b: u8) -> f32 {
    srgb_to_linear(b as f32 / 255.0)
}

/// sRGB-encoded to linear, one channel in [0, 1] (the IEC 61966-2-1 EOTF; textures' base
/// and emissive colours are so encoded, glTF 2.0 §5.22.2 and §5.19.7).
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear to sRGB-encoded, one channel in [0, 1] (the inverse of [`srgb_to_linear`]).
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.0031308 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

impl std::fmt::Debug for Image {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (w, h) = self.levels.first().map_or((0, 0), |l| (l.width, l.height));
        write!(
            f,
            "Image({}, {w}×{h}, {} levels)",
            self.name,
            self.levels.len()
        )
    }
}

/// Texture coordinate wrap mode (glTF sampler `wrapS` / `wrapT`, §5.26).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Wrap {
    /// 10497, the default.
    Repeat,
    /// 33648.
    Mirror,
    /// 33071.
    Clamp,
}

/// A material's texture: which image (`Scene::images`) and how it wraps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TextureRef {
    pub image: u32,
    pub wrap: [Wrap; 2],
}

/// Which texture of a material.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Slot {
    /// `baseColorTexture`: multiplies the reflectance.
    Base = 0,
    /// `emissiveTexture`: multiplies the emission.
    Emissive = 1,
}

/// One triangle's texture coordinates and texture means, per [`Slot`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TexturedTriangle {
    /// The corners' coordinates with `KHR_texture_transform` applied (zero where the
    /// triangle's material has no texture in that slot).
    pub uv: [[Vec2; 3]; 2],
    /// The texture's linear RGB mean over the triangle (1 where there is no texture): the
    /// factor the solver's reflectance or emission carries for it.
    pub mean: [Vec3; 2],
}

impl TexturedTriangle {
    /// An untextured triangle: means of 1.
    pub const NONE: TexturedTriangle = TexturedTriangle {
        uv: [[Vec2::ZERO; 3]; 2],
        mean: [Vec3::ONE; 2],
    };
}
