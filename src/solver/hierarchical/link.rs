//! One link of the hierarchy, packed with no heap allocation: what the sweeps read of it
//! (its source and [`PackedTransfer`]) in 16 bytes, the receiver implied by where the
//! solution stores it (`table`), and what only the oracle's rounds read (the misses near
//! the receiver's corners) in 6 bytes beside it.
//!
//! The three transfer values keep 16 bits of precision relative to the largest: they share
//! one power of two and each keeps a 16-bit mantissa, so a value is off by at most 2⁻¹⁶ of
//! the largest (1.5·10⁻⁵), far below the visibility sampling's noise. The spread and the
//! misses are kept as bfloat16 (the top 16 bits of the f32: 8 bits of precision and the
//! f32's range), the spread rounded up so that an error bound stays a bound; the spread's
//! sign bit, which a spread never needs, says whether a shadow boundary crosses the link.
//! Where on the source the light comes from is two barycentric weights of 12 bits each
//! (1/4095 of the source's extent). Every encoding gives back exactly what it was given a
//! second time, so a link the oracle keeps round after round does not drift.

use super::NodeId;
use super::transfer::Transfer;

/// A link's transfer as the sweeps read it: 12 bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct PackedTransfer {
    /// Irradiance per unit radiosity of the source at the receiver's three quadrature
    /// points (see `transfer`): value k = `at[k]` · 2^(`scale` − 142).
    at: [u16; 3],
    /// What the linear transfer may miss over the receiver (see `transfer`), bfloat16
    /// rounded up, with the sign bit set where a shadow boundary crosses the link.
    spread_partial: u16,
    /// The biased f32 exponent of the largest value: the largest mantissa then lies in
    /// [2¹⁵, 2¹⁶).
    scale: u8,
    /// Where on a surface source the receiver's light comes from: the barycentric weights
    /// of its corners 1 and 2 in units of 1/4095, 12 bits each, little end first (see
    /// `transfer::kernel_centroid`).
    toward: [u8; 3],
}

/// One link as the refinement rounds handle it: both ends, the transfer and what the
/// linear transfer misses near the receiver's corners.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Link {
    pub receiver: NodeId,
    pub source: NodeId,
    pub transfer: PackedTransfer,
    /// What the linear transfer misses near the receiver's corners per unit radiosity of
    /// the source (`transfer::Transfer::miss`), bfloat16, for the oracle's check of a
    /// receiver's links together; NaN where it is no longer kept (see `table`).
    pub miss: [u16; 3],
}

/// A bfloat16 NaN (what a miss no longer known reads as).
pub(super) const BF16_NAN: u16 = 0x7fc0;

/// 2^k as an f64, for k in the range of f32 exponents and the mantissas below them.
fn power_of_two(k: i32) -> f64 {
    f64::from_bits(((k + 1023) as u64) << 52)
}

/// The step of the 16-bit mantissas under biased exponent `scale`: 2^(scale − 127 − 15).
fn step(scale: u8) -> f32 {
    power_of_two(scale as i32 - 142) as f32
}

/// Non-negative `values` as 16-bit mantissas of a shared power of two (see
/// [`PackedTransfer::at`]); a value that is not finite carries nothing.
fn pack_values(values: [f32; 3]) -> ([u16; 3], u8) {
    let values = values.map(|v| if v.is_finite() { v.abs() } else { 0.0 });
    let largest = values[0].max(values[1]).max(values[2]);
    let scale = (largest.to_bits() >> 23) as u8;
    let step = power_of_two(scale as i32 - 142);
    let at = values.map(|v| (v as f64 / step).round().min(65535.0) as u16);
    (at, scale)
}

/// `x` as bfloat16, rounded to nearest (ties to even); infinities and NaN stay what they
/// are.
fn bf16_nearest(x: f32) -> u16 {
    let bits = x.to_bits();
    if !x.is_finite() {
        return (bits >> 16) as u16 | if x.is_nan() { 0x40 } else { 0 };
    }
    let rounded = bits as u64 + 0x7fff + ((bits >> 16) & 1) as u64;
    (rounded >> 16) as u16
}

/// `x` as bfloat16, rounded towards +∞ (never below `x`).
fn bf16_up(x: f32) -> u16 {
    let bits = x.to_bits();
    let high = (bits >> 16) as u16;
    if x > 0.0 && x.is_finite() && bits & 0xffff != 0 {
        high + 1
    } else if x.is_nan() {
        high | 0x40
    } else {
        high
    }
}

fn from_bf16(b: u16) -> f32 {
    f32::from_bits((b as u32) << 16)
}

/// The sign bit of the packed spread: a shadow boundary crosses the link.
const PARTIAL: u16 = 0x8000;

/// The largest of the 12-bit weights of [`PackedTransfer::toward`].
const TOWARD_ONE: f32 = 4095.0;

impl PackedTransfer {
    pub fn new(t: &Transfer) -> PackedTransfer {
        let (at, scale) = pack_values(t.values);
        // A spread is never below zero (it bounds a difference); the sign of -0 or of a
        // NaN must not read as the partial flag.
        let spread = if t.spread.is_nan() {
            BF16_NAN
        } else {
            bf16_up(t.spread.max(0.0))
        };
        let [u, v] = t
            .toward
            .map(|w| (w.clamp(0.0, 1.0) * TOWARD_ONE).round() as u32);
        let toward = u | v << 12;
        PackedTransfer {
            at,
            spread_partial: spread | if t.partial { PARTIAL } else { 0 },
            scale,
            toward: [toward as u8, (toward >> 8) as u8, (toward >> 16) as u8],
        }
    }
    /// The barycentric weights of the source's corners at [`PackedTransfer::toward`].
    pub fn toward(&self) -> [f32; 3] {
        let [a, b, c] = self.toward.map(u32::from);
        let bits = a | b << 8 | c << 16;
        let (u, v) = (
            (bits & 0xfff) as f32 * (1.0 / TOWARD_ONE),
            (bits >> 12) as f32 * (1.0 / TOWARD_ONE),
        );
        [(1.0 - u - v).max(0.0), u, v]
    }
    /// The transfer at the three quadrature points.
    pub fn values(&self) -> [f32; 3] {
        let step = step(self.scale);
        self.at.map(|q| q as f32 * step)
    }
    /// The transfer averaged over the receiver.
    pub fn factor(&self) -> f32 {
        let v = self.values();
        (v[0] + v[1] + v[2]) / 3.0
    }
    /// The linear function through the quadrature values, at the receiver's corners:
    /// 2 v_k − mean (each point lies halfway between the centroid and corner k).
    pub fn corners(&self) -> [f32; 3] {
        let v = self.values();
        let m = (v[0] + v[1] + v[2]) / 3.0;
        v.map(|x| 2.0 * x - m)
    }
    /// A shadow boundary crosses the link.
    pub fn partial(&self) -> bool {
        self.spread_partial & PARTIAL != 0
    }
    /// What the linear transfer may miss over the receiver (infinite where the ends
    /// overlap).
    pub fn spread(&self) -> f32 {
        from_bf16(self.spread_partial & !PARTIAL)
    }
}

impl Link {
    pub fn new(receiver: NodeId, source: NodeId, t: &Transfer) -> Link {
        Link {
            receiver,
            source,
            transfer: PackedTransfer::new(t),
            miss: t.miss.map(bf16_nearest),
        }
    }
    /// What the linear transfer misses near the receiver's corners (see
    /// [`Transfer::miss`]); NaN where no longer known.
    pub fn miss(&self) -> [f32; 3] {
        self.miss.map(from_bf16)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::sampling::{hash, unit};

    fn transfer(values: [f32; 3], spread: f32, miss: [f32; 3]) -> Transfer {
        Transfer {
            values,
            spread,
            partial: false,
            rays: 0,
            toward: [0.25, 0.5],
            miss,
        }
    }

    #[test]
    fn a_packed_transfer_is_12_bytes() {
        assert_eq!(std::mem::size_of::<PackedTransfer>(), 12);
    }

    /// Values from 10⁻³⁰ to 10³⁰, with the smaller two down to 10⁻⁶ of the largest: each
    /// comes back within 2⁻¹⁶ of the largest (half a step of a 16-bit mantissa whose top
    /// bit is set, or a whole step where the largest rounds up to 2¹⁶ and is held below),
    /// the spread never below what it was and within 2⁻⁷ above it (bfloat16 keeps 8
    /// bits), the misses within 2⁻⁸ (nearest), the partial flag as it was, the weights of
    /// `toward` within half of 1/4095 (12 bits); and packing what came back gives the same
    /// link.
    #[test]
    fn packing_keeps_the_values_to_their_stated_precision_and_is_stable() {
        for k in 0..20_000u64 {
            let h = hash(k);
            let magnitude = 10f32.powf(unit(hash(h ^ 1)) * 60.0 - 30.0);
            let values = [
                magnitude,
                magnitude * unit(hash(h ^ 2)),
                magnitude * 10f32.powf(-6.0 * unit(hash(h ^ 3))),
            ];
            let spread = magnitude * unit(hash(h ^ 4)) * 3.0;
            let miss = [magnitude * (unit(hash(h ^ 5)) - 0.5), -magnitude, 0.0];
            let u = unit(hash(h ^ 6));
            let toward = [u, (1.0 - u) * unit(hash(h ^ 7))];
            let t = Transfer {
                partial: k.is_multiple_of(3),
                toward,
                ..transfer(values, spread, miss)
            };
            let link = Link::new(NodeId(1), NodeId(2), &t);
            let packed = link.transfer;
            for (got, want) in packed.values().iter().zip(values) {
                assert!(
                    (got - want).abs() <= magnitude * 2f32.powi(-16),
                    "{got} against {want} (largest {magnitude})"
                );
            }
            let s = packed.spread();
            assert!(
                s >= spread && s <= spread * (1.0 + 2f32.powi(-7)),
                "{s} {spread}"
            );
            for (got, want) in link.miss().iter().zip(miss) {
                assert!(
                    (got - want).abs() <= want.abs() * 2f32.powi(-8),
                    "{got} {want}"
                );
            }
            assert_eq!(packed.partial(), t.partial);
            let w = packed.toward();
            for (got, want) in w[1..].iter().zip(toward) {
                assert!((got - want).abs() <= 0.5 / 4095.0 + 1e-7, "{got} {want}");
            }
            assert!((w[0] + w[1] + w[2] - 1.0).abs() < 1e-6 || w[0] == 0.0);
            let again = Link::new(
                NodeId(1),
                NodeId(2),
                &Transfer {
                    values: packed.values(),
                    spread: packed.spread(),
                    miss: link.miss(),
                    toward: [w[1], w[2]],
                    ..t
                },
            );
            assert_eq!(again, link);
        }
    }

    #[test]
    fn zero_infinite_and_tiny_transfers_survive() {
        let zero = Link::new(NodeId(0), NodeId(0), &transfer([0.0; 3], 0.0, [0.0; 3]));
        assert_eq!(zero.transfer.values(), [0.0; 3]);
        assert_eq!(zero.transfer.factor(), 0.0);
        assert!(!zero.transfer.partial());
        let overlap = Transfer {
            partial: true,
            ..transfer([0.5, 0.25, 0.125], f32::INFINITY, [f32::NAN; 3])
        };
        let link = Link::new(NodeId(0), NodeId(0), &overlap);
        assert!(link.transfer.spread().is_infinite());
        assert!(link.transfer.partial());
        assert!(link.miss().iter().all(|m| m.is_nan()));
        assert_eq!(link.transfer.values(), [0.5, 0.25, 0.125]);
        // A spread of -0 or NaN does not set the partial flag.
        for spread in [-0.0, f32::NAN] {
            let link = Link::new(NodeId(0), NodeId(0), &transfer([1.0; 3], spread, [0.0; 3]));
            assert!(!link.transfer.partial());
        }
        // Subnormal values keep their multiples of 2⁻¹⁴²; a value that is not finite
        // carries nothing.
        let tiny = 2f32.powi(-140);
        let link = Link::new(
            NodeId(0),
            NodeId(0),
            &transfer([tiny, 0.0, 0.0], 0.0, [0.0; 3]),
        );
        assert_eq!(link.transfer.values(), [tiny, 0.0, 0.0]);
        let link = Link::new(
            NodeId(0),
            NodeId(0),
            &transfer([f32::NAN, 1.0, 1.0], 0.0, [0.0; 3]),
        );
        assert_eq!(link.transfer.values(), [0.0, 1.0, 1.0]);
        // The centroid's weights come back to f32 precision (4095 = 3 · 1365).
        let centre = Link::new(
            NodeId(0),
            NodeId(0),
            &Transfer {
                toward: [1.0 / 3.0; 2],
                ..transfer([1.0; 3], 0.0, [0.0; 3])
            },
        );
        for w in centre.transfer.toward() {
            assert!((w - 1.0 / 3.0).abs() < 1e-6);
        }
    }
}
