//! One link of the hierarchy, packed into 28 bytes with no heap allocation.
//!
//! What the sweeps read of a link (its three transfer values) keeps 16 bits of precision
//! relative to its largest value: the values share one power of two and each keeps a
//! 16-bit mantissa, so a value is off by at most 2⁻¹⁶ of the largest (1.5·10⁻⁵), far below
//! the visibility sampling's noise. What only the oracle reads (the spread, what the
//! linear transfer misses near the corners) is kept as bfloat16: the top 16 bits of the
//! f32, 8 bits of precision and the f32's range, the spread rounded up so that an error
//! bound stays a bound. Both encodings give back exactly what they were given a second
//! time, so a link the oracle keeps round after round does not drift.

use super::NodeId;
use super::transfer::Transfer;

/// One link: 28 bytes (the unpacked transfer took 40).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Link {
    pub receiver: NodeId,
    pub source: NodeId,
    /// Irradiance per unit radiosity of the source at the receiver's three quadrature
    /// points (see `transfer`): value k = `at[k]` · 2^(`scale` − 142).
    at: [u16; 3],
    /// The biased f32 exponent of the largest value: the largest mantissa then lies in
    /// [2¹⁵, 2¹⁶).
    scale: u8,
    /// A shadow boundary crosses the link.
    partial: bool,
    /// Where on a surface source the receiver's light comes from: the barycentric weights
    /// of its corners 1 and 2 in units of 1/65535 (see `transfer::kernel_centroid`).
    toward: [u16; 2],
    /// What the linear transfer may miss over the receiver (see `transfer`), bfloat16
    /// rounded up.
    spread: u16,
    /// What the linear transfer misses near the receiver's corners per unit radiosity of
    /// the source (`transfer::Transfer::miss`), bfloat16, for the oracle's check of a
    /// receiver's links together.
    miss: [u16; 3],
}

/// 2^k as an f64, for k in the range of f32 exponents and the mantissas below them.
fn power_of_two(k: i32) -> f64 {
    f64::from_bits(((k + 1023) as u64) << 52)
}

/// The step of the 16-bit mantissas under biased exponent `scale`: 2^(scale − 127 − 15).
fn step(scale: u8) -> f32 {
    power_of_two(scale as i32 - 142) as f32
}

/// Non-negative `values` as 16-bit mantissas of a shared power of two (see [`Link::at`]);
/// a value that is not finite carries nothing.
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

impl Link {
    pub fn new(receiver: NodeId, source: NodeId, t: &Transfer) -> Link {
        let (at, scale) = pack_values(t.values);
        Link {
            receiver,
            source,
            at,
            scale,
            partial: t.partial,
            toward: t
                .toward
                .map(|w| (w.clamp(0.0, 1.0) * 65535.0).round() as u16),
            spread: bf16_up(t.spread),
            miss: t.miss.map(bf16_nearest),
        }
    }
    /// The barycentric weights of the source's corners at [`Link::toward`].
    pub fn toward(&self) -> [f32; 3] {
        let [u, v] = self.toward.map(|w| w as f32 / 65535.0);
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
        self.partial
    }
    /// What the linear transfer may miss over the receiver (infinite where the ends
    /// overlap).
    pub fn spread(&self) -> f32 {
        from_bf16(self.spread)
    }
    /// What the linear transfer misses near the receiver's corners (see
    /// [`Transfer::miss`]).
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
    fn a_link_is_28_bytes() {
        assert_eq!(std::mem::size_of::<Link>(), 28);
    }

    /// Values from 10⁻³⁰ to 10³⁰, with the smaller two down to 10⁻⁶ of the largest: each
    /// comes back within 2⁻¹⁶ of the largest (half a step of a 16-bit mantissa whose top
    /// bit is set, or a whole step where the largest rounds up to 2¹⁶ and is held below), the spread never below what it was and within 2⁻⁷ above it
    /// (bfloat16 keeps 8 bits), the misses within 2⁻⁸ (nearest); and packing what came
    /// back gives the same link.
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
            let t = transfer(values, spread, miss);
            let link = Link::new(NodeId(1), NodeId(2), &t);
            for (got, want) in link.values().iter().zip(values) {
                assert!(
                    (got - want).abs() <= magnitude * 2f32.powi(-16),
                    "{got} against {want} (largest {magnitude})"
                );
            }
            let s = link.spread();
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
            let again = Link::new(
                NodeId(1),
                NodeId(2),
                &Transfer {
                    values: link.values(),
                    spread: link.spread(),
                    miss: link.miss(),
                    ..t
                },
            );
            assert_eq!(again, link);
        }
    }

    #[test]
    fn zero_infinite_and_tiny_transfers_survive() {
        let zero = Link::new(NodeId(0), NodeId(0), &transfer([0.0; 3], 0.0, [0.0; 3]));
        assert_eq!(zero.values(), [0.0; 3]);
        assert_eq!(zero.factor(), 0.0);
        let overlap = transfer([0.5, 0.25, 0.125], f32::INFINITY, [f32::NAN; 3]);
        let link = Link::new(NodeId(0), NodeId(0), &overlap);
        assert!(link.spread().is_infinite());
        assert!(link.miss().iter().all(|m| m.is_nan()));
        assert_eq!(link.values(), [0.5, 0.25, 0.125]);
        // Subnormal values keep their multiples of 2⁻¹⁴²; a value that is not finite
        // carries nothing.
        let tiny = 2f32.powi(-140);
        let link = Link::new(
            NodeId(0),
            NodeId(0),
            &transfer([tiny, 0.0, 0.0], 0.0, [0.0; 3]),
        );
        assert_eq!(link.values(), [tiny, 0.0, 0.0]);
        let link = Link::new(
            NodeId(0),
            NodeId(0),
            &transfer([f32::NAN, 1.0, 1.0], 0.0, [0.0; 3]),
        );
        assert_eq!(link.values(), [0.0, 1.0, 1.0]);
    }
}
