//! Deterministic sampling: a hash instead of a random-number generator, so that every
//! sample depends only on what is being sampled (a pair of surfaces, a ray index), never on
//! thread scheduling, and results do not depend on the thread count.

use super::Triangle;
use glam::Vec3;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// A hash map with [`FastHasher`]: for keys of integers (grid cells, quantised positions)
/// that no adversary chooses.
pub type FastMap<K, V> = HashMap<K, V, BuildHasherDefault<FastHasher>>;

/// A fast hash of integer keys, a word at a time (the standard library's SipHash is
/// several times slower). Lookups only: nothing may depend on a map's iteration order.
#[derive(Default)]
pub struct FastHasher(u64);

impl Hasher for FastHasher {
    fn finish(&self) -> u64 {
        let x = self.0;
        (x ^ (x >> 31)).wrapping_mul(0x94d0_49bb_1331_11eb)
    }
    fn write(&mut self, bytes: &[u8]) {
        // Slices of integers come here as their bytes: a word at a time.
        let mut words = bytes.chunks_exact(8);
        for w in &mut words {
            self.write_u64(u64::from_le_bytes(w.try_into().unwrap_or_default()));
        }
        for &b in words.remainder() {
            self.write_u64(b as u64);
        }
    }
    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(21) ^ x).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    }
    fn write_u8(&mut self, x: u8) {
        self.write_u64(x as u64);
    }
    fn write_u32(&mut self, x: u32) {
        self.write_u64(x as u64);
    }
    fn write_i32(&mut self, x: i32) {
        self.write_u64(x as u32 as u64);
    }
    fn write_i64(&mut self, x: i64) {
        self.write_u64(x as u64);
    }
}

/// A small deterministic hash (the SplitMix64 finaliser; Steele, Lea & Flood, "Fast
/// splittable pseudorandom number generators", OOPSLA 2014).
pub fn hash(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// Uniform number in [0, 1) from a hash (its top 24 bits, all an f32 mantissa holds).
pub fn unit(h: u64) -> f32 {
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// The point of triangle `t` at (u, v) ∈ [0, 1)², folded into the triangle: uniform by area
/// when (u, v) is uniform.
pub fn point_in_triangle(t: &Triangle, mut u: f32, mut v: f32) -> Vec3 {
    if u + v > 1.0 {
        u = 1.0 - u;
        v = 1.0 - v;
    }
    t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v
}

/// The cosine-weighted direction above unit normal `n` (with `basis` its
/// [`orthonormal_basis`](super::orthonormal_basis)) for (u, v) ∈ [0, 1)², by Malley's
/// method: uniform on the unit disk, projected up to the hemisphere (pdf cosθ / π).
pub fn cosine_direction(n: Vec3, basis: (Vec3, Vec3), u: f32, v: f32) -> Vec3 {
    let (t, b) = basis;
    let r = u.sqrt();
    let phi = std::f32::consts::TAU * v;
    t * (r * phi.cos()) + b * (r * phi.sin()) + n * (1.0 - u).max(0.0).sqrt()
}

/// Sub-triangle `s` of the `k²` congruent sub-triangles that cut triangle `t` (rows of
/// 1, 3, 5, … triangles, upright and inverted alternating). Together they tile `t`.
pub fn stratum(t: &Triangle, k: u32, s: u32) -> Triangle {
    let (r, o) = row_of(s);
    let (i, upright) = (o / 2, o.is_multiple_of(2));
    let kf = k as f32;
    let e1 = (t[1] - t[0]) / kf;
    let e2 = (t[2] - t[0]) / kf;
    // Barycentric lattice: a steps along e1, b along e2; row r has b = k − 1 − r.
    let a = i as f32;
    let b = (k - 1 - r) as f32;
    if upright {
        let p0 = t[0] + e1 * a + e2 * b;
        [p0, p0 + e1, p0 + e2]
    } else {
        let p0 = t[0] + e1 * (a + 1.0) + e2 * (b + 1.0);
        [p0, p0 - e1, p0 - e2]
    }
}

/// The row r of stratum `s` and its offset in the row: rows have 2r + 1 sub-triangles
/// (upright at even offsets), so row r starts at r².
fn row_of(s: u32) -> (u32, u32) {
    let r = (s as f32).sqrt() as u32;
    let r = if (r + 1) * (r + 1) <= s { r + 1 } else { r };
    let r = if r * r > s { r - 1 } else { r };
    (r, s - r * r)
}

/// The four strata of the `(2k)²` cut ([`stratum`]) that tile stratum `s` of the `k²` cut:
/// every lattice line of the coarse cut is one of the fine cut's, so each coarse
/// sub-triangle is the midpoint subdivision of itself into four fine ones. A point drawn
/// uniformly in one of the four, chosen at random, is uniform in the coarse stratum; the
/// fine cut can then reuse it for the one it lies in.
pub fn sub_strata(k: u32, s: u32) -> [u32; 4] {
    let (r, o) = row_of(s);
    let (a, b, upright) = (o / 2, k - 1 - r, o.is_multiple_of(2));
    // Stratum (a, b) of the fine lattice: row 2k − 1 − b, upright at even offsets.
    let fine = |a: u32, b: u32, upright: bool| {
        let row = 2 * k - 1 - b;
        row * row + 2 * a + u32::from(!upright)
    };
    let (a2, b2) = (2 * a, 2 * b);
    if upright {
        [
            fine(a2, b2, true),
            fine(a2, b2, false),
            fine(a2 + 1, b2, true),
            fine(a2, b2 + 1, true),
        ]
    } else {
        [
            fine(a2 + 1, b2 + 1, false),
            fine(a2 + 1, b2, false),
            fine(a2, b2 + 1, false),
            fine(a2 + 1, b2 + 1, true),
        ]
    }
}

/// Point `s` of `k²` stratified, jittered points on triangle `t`: the triangle is cut into
/// `k²` congruent sub-triangles ([`stratum`]) and one uniform point is drawn in each.
pub fn stratified_point(t: &Triangle, k: u32, s: u32, seed: u64) -> Vec3 {
    let [p0, p1, p2] = stratum(t, k, s);
    let h = hash(seed ^ (s as u64).wrapping_mul(0x2545_F491_4F6C_DD1D));
    point_in_triangle(&[p0, p1, p2], unit(h), unit(hash(h)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::triangle_area;

    #[test]
    fn strata_tile_the_triangle() {
        // The k² strata have equal area summing to the triangle's and their centroids
        // average to its centroid (a tiling by congruent pieces does both; a gap or overlap
        // would break the area sum).
        let t = [
            Vec3::new(0.3, -1.0, 2.0),
            Vec3::new(4.0, 0.5, 1.0),
            Vec3::new(-1.0, 3.0, 0.0),
        ];
        let area = triangle_area;
        for k in 1..=16u32 {
            let mut sum = 0.0;
            let mut c = Vec3::ZERO;
            for s in 0..k * k {
                let st = stratum(&t, k, s);
                let a = area(&st);
                assert!(
                    (a - area(&t) / (k * k) as f32).abs() < 1e-4 * area(&t),
                    "k {k} s {s}"
                );
                sum += a;
                c += (st[0] + st[1] + st[2]) / 3.0;
            }
            assert!((sum - area(&t)).abs() < 1e-4 * area(&t));
            c /= (k * k) as f32;
            assert!(
                (c - (t[0] + t[1] + t[2]) / 3.0).length() < 1e-4,
                "k {k}: {c}"
            );
        }
    }

    #[test]
    fn stratified_points_lie_in_their_triangle_and_cover_it() {
        let t = [Vec3::ZERO, Vec3::X, Vec3::Y];
        for k in 1..5 {
            let mut centroid = Vec3::ZERO;
            for s in 0..k * k {
                let p = stratified_point(&t, k, s, 7);
                assert!(
                    p.x >= -1e-6 && p.y >= -1e-6 && p.x + p.y <= 1.0 + 1e-6,
                    "{p}"
                );
                centroid += p;
            }
            centroid /= (k * k) as f32;
            // The mean of k² stratified uniform points is within ~1/k of the centroid 1/3.
            assert!((centroid - Vec3::new(1.0 / 3.0, 1.0 / 3.0, 0.0)).length() < 0.5 / k as f32);
        }
    }

    #[test]
    fn sub_strata_tile_their_stratum() {
        // Each fine stratum lies inside its coarse one (its centroid does, and the fine
        // cut tiles the triangle: `strata_tile_the_triangle`), and the 4k² of them are
        // each named once: together the four are exactly the coarse stratum.
        let t = [
            Vec3::ZERO,
            Vec3::new(3.0, 0.5, 0.0),
            Vec3::new(-1.0, 2.0, 0.0),
        ];
        let inside = |p: Vec3, tri: &Triangle| {
            let area = |a: Vec3, b: Vec3, c: Vec3| (b - a).cross(c - a).z;
            let whole = area(tri[0], tri[1], tri[2]);
            [
                area(p, tri[1], tri[2]),
                area(tri[0], p, tri[2]),
                area(tri[0], tri[1], p),
            ]
            .iter()
            .all(|w| w / whole > 1e-4)
        };
        for k in 1..=8u32 {
            let mut named = vec![0; (4 * k * k) as usize];
            for s in 0..k * k {
                let coarse = stratum(&t, k, s);
                for f in sub_strata(k, s) {
                    let fine = stratum(&t, 2 * k, f);
                    let c = (fine[0] + fine[1] + fine[2]) / 3.0;
                    assert!(inside(c, &coarse), "k {k} s {s} fine {f}");
                    named[f as usize] += 1;
                }
            }
            assert!(named.iter().all(|&n| n == 1), "k {k}: {named:?}");
        }
    }
}
