//! Colour conversions for the side panel: the false-colour legend's turbo map and the
//! sRGB transfer function between colour pickers (sRGB) and materials (linear).

/// The turbo colour map (Mikhailov 2019), the same polynomial as the shader's; sRGB.
pub(super) fn turbo(t: f32) -> [f32; 3] {
    let x = t.clamp(0.0, 1.0);
    let r = 0.135_721_38
        + x * (4.615_392_6
            + x * (-42.660_32 + x * (132.131_08 + x * (-152.942_4 + x * 59.286_38))));
    let g = 0.091_402_61
        + x * (2.194_188_4
            + x * (4.842_966_6 + x * (-14.185_033 + x * (4.277_298_6 + x * 2.829_566))));
    let b = 0.106_673_3
        + x * (12.641_946 + x * (-60.582_05 + x * (110.362_77 + x * (-89.903_11 + x * 27.348_25))));
    [r.clamp(0.0, 1.0), g.clamp(0.0, 1.0), b.clamp(0.0, 1.0)]
}

pub(super) use crate::scene::textures::{linear_to_srgb, srgb_to_linear};
