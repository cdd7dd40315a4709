//! Hemicube form factors (Cohen & Greenberg, "The hemi-cube: a radiosity solution for complex
//! environments", SIGGRAPH 1985): a second estimator of the same element-to-patch form
//! factors F_ip that [`super::form_factor::element_to_patch`] computes, kept to compare
//! against (tests, benchmarks), not used by the solvers.
//!
//! A half cube of half-width 1 is centred on the receiving element's centroid and aligned with
//! its normal: a full top face at unit distance along the normal and four half side faces.
//! Every patch whose front faces the point is projected onto each face and scan-converted
//! with a z-buffer that keeps the nearest surface per pixel (an item buffer); each pixel then
//! adds its *delta form factor* to the patch it shows. With face coordinates at unit distance
//! (x, y ∈ [−1, 1] across a face, z ∈ [0, 1] up a side face) and pixel area ΔA:
//!
//! - top face:  ΔF = ΔA / (π (x² + y² + 1)²),
//! - side face: ΔF = z ΔA / (π (y² + z² + 1)²),
//!
//! the cosine-weighted solid angle of the pixel (Cohen & Greenberg 1985, eqs. 6–7), evaluated
//! at the pixel centre. The tables are computed once per resolution ([`Hemicube::new`]).
//!
//! Occluders that are not patches (the back of single-sided surfaces, fully opaque or partly
//! transmissive scene triangles) are scan-converted from `Mesh::triangles` with no patch id:
//! they write depth, and the pixels they win count for nobody. A scene triangle whose patches
//! are drawn is *not* drawn again as an occluder: its front-facing patches tile it exactly
//! (they come from bisecting it), so the occluder would only z-fight with them, coplanar to
//! the last bit; leaving it out removes the tie instead of biasing depths. The receiver's own
//! scene triangle is left out too (it lies in the hemicube's base plane), as in the ray-cast
//! estimator's skip list.
//!
//! What it is good at: one z-buffer pass gives a whole row F_i· with visibility for every
//! patch at once, at a cost of O(patches × faces + resolution²) per receiver whatever the
//! depth complexity; resolution trades accuracy for time smoothly.
//!
//! Where it fails:
//! - aliasing: each pixel belongs to one patch, so patches smaller than a pixel's solid angle
//!   are missed or counted a whole pixel, and regular grids beat against regular meshes
//!   (error per patch ~ one pixel's ΔF, up to 1/(π (res/2)²) at the top face's centre);
//! - the delta form factors are midpoint values: they sum to 1 only to O(1/res²)
//!   (1 + 1.3e-4 at 64, 1 + 8.3e-6 at 256; about 0.54/res²), so a closed scene's row sums
//!   are off by that;
//! - the receiver-point assumption: the whole element sees from its centroid, so near-field
//!   pairs (contact, adjacent walls) get the centroid's value and visibility; a patch nearer
//!   than the near plane (10⁻⁶ of the scene size) is clipped away;
//! - visibility is all-or-nothing: transmittance (cut-outs, glass) is treated as opaque.
//!
//! Compared with the ray-cast estimator (exact analytic F times a shadow-ray fraction): the
//! hemicube's unoccluded values carry discretisation error where the ray-cast ones are exact,
//! but its visibility is noise-free (aliased instead of sampled). At 256² both agree on the
//! Cornell box's walls to about a percent (see `tests/form_factors.rs`).

use crate::mesh::Mesh;
use glam::DVec3;
use std::cell::RefCell;

/// Item-buffer id of pixels showing no patch (background or a non-patch occluder).
const NONE: u32 = u32::MAX;

/// Near-plane distance relative to `Mesh::scale`: small enough to see touching surfaces,
/// large enough that 1/depth stays finite and well-conditioned in f64.
const NEAR: f64 = 1e-6;

/// Pixel-centre inclusion slack, in pixels: a centre lying on an edge shared by two patches
/// is counted by both (the z-test keeps one) rather than by neither through rounding.
const EDGE_SLACK: f64 = 1e-7;

/// A hemicube of a given resolution: delta form factor tables and reusable buffers.
#[derive(Clone, Debug)]
pub struct Hemicube {
    resolution: usize,
    /// ΔF per pixel of the top face, row-major `resolution × resolution`.
    top_delta: Vec<f64>,
    /// ΔF per pixel of a side face, `resolution / 2` rows (row 0 at the base) × `resolution`.
    side_delta: Vec<f64>,
    /// 1/depth per pixel of all five faces (0 = nothing), top face first.
    inv_depth: Vec<f64>,
    /// Patch index per pixel, [`NONE`] for none.
    ids: Vec<u32>,
}

/// The five faces: depth axis and face axes as a map from hemicube-frame coordinates
/// (a, b, c) = (along u, along v, along the normal) to face coordinates (s, t, d).
#[derive(Clone, Copy)]
enum Face {
    Top,
    PlusU,
    MinusU,
    PlusV,
    MinusV,
}

impl Face {
    const ALL: [Face; 5] = [
        Face::Top,
        Face::PlusU,
        Face::MinusU,
        Face::PlusV,
        Face::MinusV,
    ];

    /// (s across the face, t up the face, d depth) from frame coordinates.
    #[inline]
    fn map(self, p: DVec3) -> DVec3 {
        let (a, b, c) = (p.x, p.y, p.z);
        match self {
            Face::Top => DVec3::new(a, b, c),
            Face::PlusU => DVec3::new(b, c, a),
            Face::MinusU => DVec3::new(-b, c, -a),
            Face::PlusV => DVec3::new(a, c, b),
            Face::MinusV => DVec3::new(-a, c, -b),
        }
    }

    /// Lowest t/d on the face: −1 for the top, 0 (the base plane) for the sides.
    fn t_min(self) -> f64 {
        match self {
            Face::Top => -1.0,
            _ => 0.0,
        }
    }
}

impl Hemicube {
    /// A hemicube with `resolution` pixels across the top face (rounded up to an even number,
    /// at least 2, so the side faces have whole half-heights) and its delta form factor tables.
    pub fn new(resolution: u32) -> Hemicube {
        let res = (resolution.max(2) as usize).next_multiple_of(2);
        let half = res / 2;
        let pixel = 2.0 / res as f64;
        let area = pixel * pixel;
        let centre = |i: usize| -1.0 + (i as f64 + 0.5) * pixel;
        let pi = std::f64::consts::PI;
        let mut top_delta = Vec::with_capacity(res * res);
        for j in 0..res {
            for i in 0..res {
                let r2 = centre(i).powi(2) + centre(j).powi(2) + 1.0;
                top_delta.push(area / (pi * r2 * r2));
            }
        }
        let mut side_delta = Vec::with_capacity(res * half);
        for j in 0..half {
            let z = (j as f64 + 0.5) * pixel;
            for i in 0..res {
                let r2 = centre(i).powi(2) + z * z + 1.0;
                side_delta.push(z * area / (pi * r2 * r2));
            }
        }
        let pixels = res * res + 4 * res * half;
        Hemicube {
            resolution: res,
            top_delta,
            side_delta,
            inv_depth: vec![0.0; pixels],
            ids: vec![NONE; pixels],
        }
    }

    /// Pixels across the top face.
    pub fn resolution(&self) -> u32 {
        self.resolution as u32
    }

    /// Sum of all delta form factors: 1 for the exact hemisphere, 1 − O(1/res²) for the
    /// midpoint tables. The most a row can sum to.
    pub fn delta_sum(&self) -> f64 {
        self.top_delta.iter().sum::<f64>() + 4.0 * self.side_delta.iter().sum::<f64>()
    }

    /// The form factors F_ip from element `element` (seen from its centroid, over the
    /// hemisphere of its normal) to every patch p it sees, as (patch index, F), sorted by
    /// patch, zeros left out. Dimensionless, in [0, 1]; a row sums to at most
    /// [`Hemicube::delta_sum`]. Empty for an element index out of range.
    pub fn row(&mut self, mesh: &Mesh, element: usize) -> Vec<(u32, f32)> {
        let Some(e) = mesh.elements.get(element) else {
            return Vec::new();
        };
        let x = e.centroid();
        let origin = x.as_dvec3();
        let n = e.normal.as_dvec3();
        if !n.is_normalized() {
            return Vec::new();
        }
        let (u, v) = n.any_orthonormal_pair();
        let to_frame = |p: glam::Vec3| {
            let r = p.as_dvec3() - origin;
            DVec3::new(r.dot(u), r.dot(v), r.dot(n))
        };
        let near = NEAR * mesh.scale.max(f32::MIN_POSITIVE) as f64;
        self.inv_depth.fill(0.0);
        self.ids.fill(NONE);
        let mut covered = vec![false; mesh.triangles.len()];
        for (pi, p) in mesh.patches.iter().enumerate() {
            // The shooter emits from its front side only (same rule as element_to_patch).
            if pi == e.patch as usize || p.normal.dot(x - p.verts[0]) <= 0.0 {
                continue;
            }
            if let Some(c) = covered.get_mut(p.scene_triangle as usize) {
                *c = true;
            }
            self.draw(p.verts.map(to_frame), pi as u32, near);
        }
        let own = mesh
            .patches
            .get(e.patch as usize)
            .map(|p| p.scene_triangle as usize);
        for (ti, t) in mesh.triangles.iter().enumerate() {
            let clear = mesh.transmittance.get(ti).is_some_and(|&tr| tr >= 1.0);
            if covered[ti] || Some(ti) == own || clear || !t.iter().all(|p| p.is_finite()) {
                continue;
            }
            self.draw(t.map(to_frame), NONE, near);
        }
        self.accumulate(mesh.patches.len())
    }

    /// Sums the delta form factors of the pixels each patch won.
    fn accumulate(&self, patches: usize) -> Vec<(u32, f32)> {
        let mut sums = vec![0.0f64; patches];
        let top = self.resolution * self.resolution;
        for (k, &id) in self.ids.iter().enumerate() {
            if id == NONE {
                continue;
            }
            let delta = if k < top {
                self.top_delta[k]
            } else {
                self.side_delta[(k - top) % self.side_delta.len()]
            };
            sums[id as usize] += delta;
        }
        sums.iter()
            .enumerate()
            .filter(|(_, f)| **f > 0.0)
            .map(|(p, f)| (p as u32, *f as f32))
            .collect()
    }

    /// Draws a triangle (hemicube-frame coordinates) with item id `id` on every face it
    /// reaches.
    fn draw(&mut self, tri: [DVec3; 3], id: u32, near: f64) {
        for (k, face) in Face::ALL.into_iter().enumerate() {
            let p = tri.map(|q| face.map(q));
            let t_min = face.t_min();
            // Trivial reject: all three vertices outside one plane of the face's frustum
            // (|s| ≤ d, t_min·d ≤ t ≤ d, d ≥ near). The base plane t ≥ 0 of a side face is one
            // of them; the rest of the frustum is enforced by the scissor in `raster`.
            let outside = |f: &dyn Fn(DVec3) -> bool| p.iter().all(|&q| f(q));
            if outside(&|q| q.z < near)
                || outside(&|q| q.x > q.z)
                || outside(&|q| q.x < -q.z)
                || outside(&|q| q.y > q.z)
                || outside(&|q| q.y < t_min * q.z)
            {
                continue;
            }
            let (poly, m) = clip_near(&p, near);
            let half = self.resolution as f64 / 2.0;
            // Pixel coordinates (x right, y up from the face's t_min edge) and 1/depth, which
            // is affine in screen space for a planar polygon (perspective-correct depth).
            let screen = |q: DVec3| {
                let w = 1.0 / q.z;
                DVec3::new((q.x * w + 1.0) * half, (q.y * w - t_min) * half, w)
            };
            let s0 = screen(poly[0]);
            for j in 1..m.saturating_sub(1) {
                self.raster(k, [s0, screen(poly[j]), screen(poly[j + 1])], id);
            }
        }
    }

    /// Scan-converts one screen-space triangle into face `face`'s buffers: pixel centres
    /// inside it (with [`EDGE_SLACK`]) take `id` where its 1/depth is larger (nearer).
    fn raster(&mut self, face: usize, p: [DVec3; 3], id: u32) {
        let width = self.resolution;
        let (height, offset) = if face == 0 {
            (width, 0)
        } else {
            let h = width / 2;
            (h, width * width + (face - 1) * width * h)
        };
        let area = (p[1].x - p[0].x) * (p[2].y - p[0].y) - (p[1].y - p[0].y) * (p[2].x - p[0].x);
        if area.is_nan() || area == 0.0 || !area.is_finite() {
            return;
        }
        let lo = p[0].min(p[1]).min(p[2]);
        let hi = p[0].max(p[1]).max(p[2]);
        // Pixel i covers [i, i+1) with its centre at i + 0.5.
        let first = |v: f64| (v - 0.5).ceil().max(0.0);
        let last = |v: f64, n: usize| (v - 0.5).floor().min(n as f64 - 1.0);
        let (x0, x1) = (first(lo.x), last(hi.x, width));
        let (y0, y1) = (first(lo.y), last(hi.y, height));
        if x0 > x1 || y0 > y1 {
            return;
        }
        // Barycentric λ_k (opposite vertex k) as affine functions of the pixel centre:
        // λ_k = a_k + b_k·x + c_k·y; each inclusion slack is EDGE_SLACK pixels of distance
        // from edge k, converted to λ units by the edge length over the doubled area.
        let mut coef = [(0.0f64, 0.0f64, 0.0f64, 0.0f64); 3];
        for k in 0..3 {
            let a = p[(k + 1) % 3];
            let b = p[(k + 2) % 3];
            let (bx, by) = (-(b.y - a.y) / area, (b.x - a.x) / area);
            let c0 = -(bx * a.x + by * a.y);
            let slack = EDGE_SLACK * (b.x - a.x).hypot(b.y - a.y) / area.abs();
            coef[k] = (c0, bx, by, slack);
        }
        let (x0, x1, y0, y1) = (x0 as usize, x1 as usize, y0 as usize, y1 as usize);
        for y in y0..=y1 {
            let cy = y as f64 + 0.5;
            let row = offset + y * width;
            for x in x0..=x1 {
                let cx = x as f64 + 0.5;
                let mut z = 0.0;
                let mut inside = true;
                for (k, &(c0, bx, by, slack)) in coef.iter().enumerate() {
                    let l = c0 + bx * cx + by * cy;
                    inside &= l >= -slack;
                    z += l * p[k].z;
                }
                if inside && z > self.inv_depth[row + x] {
                    self.inv_depth[row + x] = z;
                    self.ids[row + x] = id;
                }
            }
        }
    }
}

/// Sutherland–Hodgman clip of a triangle (face coordinates, depth in z) to `z ≥ near`:
/// at most four vertices.
fn clip_near(p: &[DVec3; 3], near: f64) -> ([DVec3; 4], usize) {
    let mut out = [DVec3::ZERO; 4];
    let mut m = 0;
    for k in 0..3 {
        let a = p[k];
        let b = p[(k + 1) % 3];
        let (ina, inb) = (a.z >= near, b.z >= near);
        if ina {
            out[m] = a;
            m += 1;
        }
        if ina != inb {
            let t = (near - a.z) / (b.z - a.z);
            let mut q = a + (b - a) * t;
            q.z = near; // exactly on the plane, whatever the rounding of t
            out[m] = q;
            m += 1;
        }
    }
    (out, m)
}

thread_local! {
    /// The last hemicube used on this thread, so that repeated calls at one resolution
    /// reuse its tables and buffers.
    static CACHE: RefCell<Option<Hemicube>> = const { RefCell::new(None) };
}

/// [`Hemicube::row`] with a per-thread cached hemicube of `resolution` (tables are rebuilt
/// only when the resolution changes): the form factors from element `element`'s centroid to
/// every patch it sees, (patch index, F) sorted by patch, visibility by z-buffer.
pub fn hemicube_row(mesh: &Mesh, element: usize, resolution: u32) -> Vec<(u32, f32)> {
    let wanted = (resolution.max(2)).next_multiple_of(2);
    CACHE.with(|cache| {
        let mut cache = cache.borrow_mut();
        if cache.as_ref().is_none_or(|h| h.resolution() != wanted) {
            *cache = None;
        }
        cache
            .get_or_insert_with(|| Hemicube::new(wanted))
            .row(mesh, element)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn delta_tables_sum_to_one_up_to_the_midpoint_error() {
        // The midpoint rule on the hemicube faces: error O(1/res²), about 0.54/res² (computed
        // independently: +1.3e-4 at 64, +8.3e-6 at 256), so 1/res² bounds it.
        for res in [16u32, 64, 256] {
            let h = Hemicube::new(res);
            let err = (h.delta_sum() - 1.0).abs();
            assert!(err < 1.0 / (res as f64).powi(2), "res {res}: {err}");
        }
    }

    #[test]
    fn clipping_keeps_the_near_side() {
        let p = [
            DVec3::new(0.0, 0.0, -1.0),
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(0.0, 1.0, 1.0),
        ];
        let (q, m) = clip_near(&p, 0.5);
        assert_eq!(m, 4);
        assert!(q[..m].iter().all(|v| v.z >= 0.5));
    }
}
