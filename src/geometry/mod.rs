//! Shared geometry: triangles, bases, the mesh frame, and deterministic sampling
//! ([`sampling`]). The bottom layer: it imports nothing from the crate, and every other
//! layer may use it (see ARCHITECTURE.md).

pub mod sampling;

use glam::{DVec3, Vec3};

/// A triangle's three corners, counter-clockwise seen from its front side.
pub type Triangle = [Vec3; 3];

/// (b − a) × (c − a) for triangle `t` = [a, b, c]: the front-facing normal scaled by twice
/// the area.
pub fn triangle_cross(t: &Triangle) -> Vec3 {
    (t[1] - t[0]).cross(t[2] - t[0])
}

/// [`triangle_cross`] in f64, for triangles held in f64.
pub fn dtriangle_cross(t: &[DVec3; 3]) -> DVec3 {
    (t[1] - t[0]).cross(t[2] - t[0])
}

/// Area of triangle `t`, in the units of its coordinates squared.
pub fn triangle_area(t: &Triangle) -> f32 {
    0.5 * triangle_cross(t).length()
}

/// Unit front-facing normal of triangle `t`, or zero for a degenerate triangle.
pub fn triangle_normal(t: &Triangle) -> Vec3 {
    triangle_cross(t).normalize_or_zero()
}

/// Midpoint subdivision children of a triangle, same orientation: three corner triangles
/// and the middle one (at [`MIDDLE_CHILD`]).
pub fn subdivide(v: &Triangle) -> [Triangle; 4] {
    let ab = (v[0] + v[1]) * 0.5;
    let bc = (v[1] + v[2]) * 0.5;
    let ca = (v[2] + v[0]) * 0.5;
    [[v[0], ab, ca], [ab, v[1], bc], [ca, bc, v[2]], [ab, bc, ca]]
}

/// The index of [`subdivide`]'s middle child, whose centroid is its parent's:
/// (a+b)/2 + (b+c)/2 + (c+a)/2 = a + b + c.
pub const MIDDLE_CHILD: usize = 3;

/// An orthonormal basis (t, b) perpendicular to unit `n` (Duff et al., "Building an
/// orthonormal basis, revisited", JCGT 2017).
pub fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// The frame geometry is stored in: positions are kept in f32 relative to `origin` (f64,
/// world), so a kilometre-sized scene far from the world origin keeps millimetre
/// precision; `scale` is the scene's diagonal in that frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    pub origin: DVec3,
    pub scale: f32,
}

impl Frame {
    /// A world-space point in this frame.
    pub fn to_local(&self, world: DVec3) -> Vec3 {
        (world - self.origin).as_vec3()
    }

    /// Offset used to lift ray endpoints off surfaces: a hundred-thousandth of the scene
    /// size, which is at least a few f32 ulps of the coordinates involved (the frame is
    /// centred, so coordinates are at most `scale`).
    pub fn epsilon(&self) -> f32 {
        self.scale * 1e-5
    }
}

/// The length of triangle `t`'s longest edge.
pub fn longest_edge(t: &Triangle) -> f32 {
    (0..3)
        .map(|k| t[k].distance(t[(k + 1) % 3]))
        .fold(0.0, f32::max)
}

/// The shortest altitude of triangle `t`: twice its area over its longest edge (how wide
/// it is across; a sliver's is far below `sqrt(2 · area)`).
pub fn shortest_altitude(t: &Triangle) -> f32 {
    let twice_area = (t[1] - t[0]).cross(t[2] - t[0]).length();
    let longest = longest_edge(t);
    if longest > 0.0 {
        twice_area / longest
    } else {
        0.0
    }
}

/// Closest point on triangle `t` to `p` (Ericson, Real-Time Collision Detection, §5.1.5),
/// with its barycentric coordinates.
pub fn closest_point_on_triangle(p: Vec3, t: &Triangle) -> (Vec3, [f32; 3]) {
    let (a, b, c) = (t[0], t[1], t[2]);
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, [1.0, 0.0, 0.0]);
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (b, [0.0, 1.0, 0.0]);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, [1.0 - v, v, 0.0]);
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (c, [0.0, 0.0, 1.0]);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, [1.0 - w, 0.0, w]);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, [0.0, 1.0 - w, w]);
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    (a + ab * v + ac * w, [1.0 - v - w, v, w])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basis_is_orthonormal_for_every_octant() {
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(1.0, -2.0, 0.5).normalize(),
        ] {
            let (t, b) = orthonormal_basis(n);
            for (u, v) in [(t, b), (t, n), (b, n)] {
                assert!(u.dot(v).abs() < 1e-6);
            }
            assert!((t.length() - 1.0).abs() < 1e-6 && (b.length() - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn subdivision_keeps_area_and_orientation() {
        let t = [
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        let kids = subdivide(&t);
        let sum: f32 = kids.iter().map(triangle_area).sum();
        assert!((sum - triangle_area(&t)).abs() < 1e-6);
        for k in &kids {
            assert!(triangle_normal(k).dot(Vec3::Z) > 0.999);
        }
        // The middle child shares its parent's centroid (to f32 rounding of coordinates
        // of size 2), and no corner child does.
        let centroid = |t: &Triangle| (t[0] + t[1] + t[2]) / 3.0;
        for (i, k) in kids.iter().enumerate() {
            let same = (centroid(k) - centroid(&t)).length() < 1e-6;
            assert_eq!(same, i == MIDDLE_CHILD, "child {i}");
        }
    }
}
