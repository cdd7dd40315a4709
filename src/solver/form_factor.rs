//! Form factors from a receiving element to a shooting patch.
//!
//! The estimator used by every solver is the *ray-cast form factor* of Wallace, Elmquist &
//! Haines ("A ray tracing algorithm for progressive radiosity", SIGGRAPH 1989): the exact
//! differential-area-to-polygon form factor at the receiver's centroid, from Lambert's
//! contour integral (Lambert 1760; Baum, Rushmeier & Winget 1989, eq. 2),
//!
//! F(dA → A_j) = 1/(2π) Σ_k γ_k · n · (R_k × R_{k+1}) / |R_k × R_{k+1}|,
//!
//! where R_k are the vectors from the receiving point to the polygon's vertices and γ_k the
//! angle between R_k and R_{k+1}, times the visibility of the patch from the receiver: the
//! patch is cut into k² congruent strata and one shadow ray goes to a jittered point in
//! each; where the rays disagree, each stratum's transmittance is weighted by its own form
//! factor (so visibility is weighted by the kernel, as the definition of F requires, and
//! the unoccluded parts stay exact; [`strata_visibility`], which every method shares). The polygon is first clipped to
//! the receiver's upper hemisphere, so the value is exact for any unoccluded configuration,
//! never exceeds 1 and tends to 0 (not infinity) as surfaces touch: a receiver can never get
//! more than the shooter sends. The shadow-ray count grows with the unoccluded form factor
//! (a large solid angle needs more samples to resolve partial occlusion).
//!
//! Before any ray, a shaft cull ([`Bvh::shaft_clear`]) tests whether any triangle can lie in
//! the tetrahedron spanned by the receiving point and the patch; most pairs in a room are
//! proven clear that way and cost no ray.
//!
//! What it is good at: exact near field, no aliasing of small patches, bounded at contact.
//! Where it fails: visibility is a sample mean, so penumbrae are noisy with few rays; the
//! value is for the element's centroid, so large elements near a shooter are only
//! collocation-accurate (the mesh must be fine there).

use crate::accel::Bvh;
use crate::geometry::sampling::{hash, stratified_point, stratum, sub_strata};
use crate::mesh::Mesh;
use glam::Vec3;
use std::cmp::Ordering;
use std::f32::consts::PI;

/// Controls the visibility sampling of [`element_to_patch`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FormFactorSettings {
    /// Most shadow rays per element–patch pair (reached when the unoccluded form factor
    /// approaches 1).
    pub max_rays: u32,
    /// Fewest shadow rays per pair with a non-zero unoccluded form factor.
    pub min_rays: u32,
    /// Shadow rays for a pair whose first rays disagree (a penumbra or a partly hidden
    /// patch): the pair is sampled again with this many strata, each weighted by its own
    /// form factor.
    pub penumbra_rays: u32,
}

impl Default for FormFactorSettings {
    fn default() -> Self {
        // Measured on the Cornell box (probe at 288 floor and back-wall points, against a
        // run with 64–256 rays per pair): with 1–16 rays per pair the visibility noise left
        // 3 % RMS (25 % worst) in the converged B; 4 → 1.7 %, 9 → 0.65 %, 16 → 0.36 %
        // (2.4 % worst), at 3.3× the time of 1–16. A first pass of 16 strata finds nearly
        // every partly hidden patch; penumbra pairs are then sampled with 64.
        FormFactorSettings {
            max_rays: 64,
            min_rays: 16,
            penumbra_rays: 64,
        }
    }
}

/// Exact form factor from a differential area at `p` with unit normal `n` to the planar
/// polygon `poly` (any winding, at most six vertices), clipped to the hemisphere
/// `n · (x − p) ≥ 0`. Result in [0, 1].
///
/// Lambert's contour integral in f32, each edge's plane normal taken as R_k × (R_{k+1} −
/// R_k) (no cancellation when the polygon is far and R_k ∥ R_{k+1}) and its angle from
/// [`angle_between`]. Every term is at most π and carries a few f32 ulps of relative
/// error, so F is off by at most about 10⁻⁶ · Σ_k γ_k / 2π absolute: negligible against
/// the solid angle the polygon subtends, A/(π d²), unless the polygon is small and far,
/// where the terms cancel and the far field takes over. A polygon wholly above the
/// horizon whose bounding radius r is under [`FAR_FIELD`] of its distance d gets the point
/// formula F = (n · ω) |a · ω| / (π d²) (ω towards its area centroid, a its vector area),
/// whose error is of order (r/d)² F. Either way F stays within 1.3·10⁻⁴ A/(π d²) of the
/// f64 contour (tested from 3 to 10⁵ radii away), and `tests/form_factor_closed_forms.rs`
/// holds it to the closed forms. (The f64 contour with libm's atan2 made the hierarchical
/// solve of the Cornell box 1.4× slower.)
pub fn point_to_polygon(p: Vec3, n: Vec3, poly: &[Vec3]) -> f32 {
    let mut rel: [Vec3; 8] = [Vec3::ZERO; 8];
    let count = poly.len().min(6);
    for k in 0..count {
        rel[k] = poly[k] - p;
    }
    let rel = &rel[..count];
    if let Some(f) = far_field(rel, n, FAR_FIELD) {
        return f;
    }
    let (clipped, m) = clip_to_hemisphere(rel, n);
    contour_integral(&clipped[..m], n)
}

/// [`point_to_polygon`] for a triangle, to within a few per cent: the point formula
/// wherever the triangle's bounding radius is under [`WEIGHT_FAR_FIELD`] of its distance
/// (its error, of order (r/d)², is then under about 6 %), the exact contour elsewhere.
/// For weights that only need to be about right (of strata, of parts of a source), at a
/// fraction of the contour's cost.
pub(in crate::solver) fn form_factor_weight(p: Vec3, n: Vec3, tri: &[Vec3; 3]) -> f32 {
    let rel = tri.map(|v| v - p);
    far_field(&rel, n, WEIGHT_FAR_FIELD).unwrap_or_else(|| {
        let (clipped, m) = clip_to_hemisphere(&rel, n);
        contour_integral(&clipped[..m], n)
    })
}

/// Below this ratio of a triangle's bounding radius to its distance, [`form_factor_weight`]
/// uses the point formula.
const WEIGHT_FAR_FIELD: f32 = 0.25;

/// [`point_to_polygon`] for a triangle, to within `max_error`: the point formula wherever
/// the bound on its error (see [`triangle_far_field`]) is under `max_error`, the exact
/// contour elsewhere. The final gather asks each node's form factor to a tolerance set by
/// the light it carries.
pub(in crate::solver) fn point_to_triangle_within(
    p: Vec3,
    n: Vec3,
    tri: &[Vec3; 3],
    max_error: f32,
) -> f32 {
    let rel = tri.map(|v| v - p);
    match triangle_far_field(&rel, n) {
        Some((f, bound)) if bound <= max_error => f,
        _ => {
            let (clipped, m) = clip_to_hemisphere(&rel, n);
            contour_integral(&clipped[..m], n)
        }
    }
}

/// The point formula for a triangle (relative to the receiving point) wholly in the upper
/// hemisphere whose bounding radius r is under [`WEIGHT_FAR_FIELD`] of its centroid's
/// distance d, and a bound on its error: (r/d)² · A/(π d²), A the area. Over random
/// triangles in every direction above the horizon with r/d up to 1/4, the point
/// formula's error reaches half this bound (`the_point_formula_stays_within_its_bound`).
/// `None` for other triangles.
fn triangle_far_field(rel: &[Vec3; 3], n: Vec3) -> Option<(f32, f32)> {
    // A triangle's area centroid is the mean of its corners.
    let c = (rel[0] + rel[1] + rel[2]) / 3.0;
    let d2 = c.length_squared();
    let r2 = rel
        .iter()
        .map(|r| (*r - c).length_squared())
        .fold(0.0, f32::max);
    let area = 0.5 * (rel[1] - rel[0]).cross(rel[2] - rel[0]);
    let size = area.length();
    // NaN (a degenerate triangle) fails every comparison: the contour handles it.
    let far = r2 < WEIGHT_FAR_FIELD * WEIGHT_FAR_FIELD * d2
        && size > 0.0
        && rel.iter().all(|r| n.dot(*r) >= 0.0);
    if !far {
        return None;
    }
    let w = c / d2.sqrt();
    let f = (n.dot(w).max(0.0) * area.dot(w).abs() / (PI * d2)).clamp(0.0, 1.0);
    Some((f, r2 / d2 * size / (PI * d2)))
}

/// Below this ratio of a polygon's bounding radius to its distance, [`point_to_polygon`]
/// uses the point formula.
const FAR_FIELD: f32 = 5e-3;

/// The point formula for a polygon (relative to the receiving point) that lies wholly in
/// the upper hemisphere and whose bounding radius is under `ratio` of its distance;
/// `None` otherwise.
fn far_field(rel: &[Vec3], n: Vec3, ratio: f32) -> Option<f32> {
    if rel.len() < 3 || rel.iter().any(|r| n.dot(*r) < 0.0) {
        return None;
    }
    // Cheap rejection first (most calls are near): the bounding radius r is at least half
    // the longest span e from the first vertex, and the centroid's distance d at most
    // |R_0| + r, so r < ratio · d needs e / 2 < ratio · |R_0| / (1 − ratio).
    let span2 = rel[1..]
        .iter()
        .map(|r| (*r - rel[0]).length_squared())
        .fold(0.0, f32::max);
    let bound = ratio / (1.0 - ratio);
    if span2 * 0.25 >= bound * bound * rel[0].length_squared() {
        return None;
    }
    // Vector area and area centroid by a fan from the first vertex.
    let (mut area, mut moment, mut total) = (Vec3::ZERO, Vec3::ZERO, 0.0f32);
    for k in 1..rel.len() - 1 {
        let a = 0.5 * (rel[k] - rel[0]).cross(rel[k + 1] - rel[0]);
        let size = a.length();
        area += a;
        moment += size * (rel[0] + rel[k] + rel[k + 1]) / 3.0;
        total += size;
    }
    if total.partial_cmp(&0.0) != Some(Ordering::Greater) {
        return None;
    }
    let centroid = moment / total;
    let d2 = centroid.length_squared();
    let r2 = rel
        .iter()
        .map(|r| (*r - centroid).length_squared())
        .fold(0.0, f32::max);
    // NaN (a degenerate polygon) compares as neither: the contour handles it.
    if r2.partial_cmp(&(ratio * ratio * d2)) != Some(Ordering::Less) {
        return None;
    }
    let w = centroid / d2.sqrt();
    Some((n.dot(w).max(0.0) * area.dot(w).abs() / (PI * d2)).clamp(0.0, 1.0))
}

/// Sutherland–Hodgman clip of a convex polygon (relative to the receiving point) to the
/// half-space `n · r ≥ 0`. A triangle gains at most one vertex per clip, so 8 slots hold
/// any input of up to 6 vertices.
fn clip_to_hemisphere(rel: &[Vec3], n: Vec3) -> ([Vec3; 8], usize) {
    let mut out = [Vec3::ZERO; 8];
    let mut m = 0;
    let len = rel.len();
    for k in 0..len {
        let a = rel[k];
        let b = rel[(k + 1) % len];
        let da = n.dot(a);
        let db = n.dot(b);
        if da >= 0.0 && m < 8 {
            out[m] = a;
            m += 1;
        }
        if (da >= 0.0) != (db >= 0.0) && m < 8 {
            let t = da / (da - db);
            out[m] = a + (b - a) * t;
            m += 1;
        }
    }
    (out, m)
}

fn contour_integral(rel: &[Vec3], n: Vec3) -> f32 {
    if rel.len() < 3 {
        return 0.0;
    }
    let mut sum = 0.0f32;
    for k in 0..rel.len() {
        let a = rel[k];
        let b = rel[(k + 1) % rel.len()];
        if a == Vec3::ZERO || b == Vec3::ZERO {
            // The receiving point is a vertex of the polygon: that corner subtends no
            // angle; its edges still do through their other ends.
            continue;
        }
        let c = a.cross(b - a);
        let lc = c.length();
        if lc.partial_cmp(&f32::MIN_POSITIVE) != Some(Ordering::Greater) {
            continue;
        }
        sum += angle_between(lc, a.dot(b)) * n.dot(c) / lc;
    }
    (sum.abs() / std::f32::consts::TAU).clamp(0.0, 1.0)
}

/// atan2(`sin`, `cos`) for `sin` ≥ 0: the angle in [0, π] between two vectors whose cross
/// product has length `sin` and whose dot product is `cos` (any common scale). Cephes'
/// `atanf` (Moshier 1989): reduction to |x| ≤ tan(π/8), then a degree-9 odd polynomial,
/// within 2 f32 ulps of the true angle.
#[inline]
fn angle_between(sin: f32, cos: f32) -> f32 {
    use std::f32::consts::{FRAC_PI_2, FRAC_PI_4};
    let (big, small) = (sin.max(cos.abs()), sin.min(cos.abs()));
    if big <= 0.0 {
        return 0.0;
    }
    // x = small / big ∈ [0, 1]; atan(x) by reduction around π/8.
    let x = small / big;
    let (offset, x) = if x > 0.414_213_57 {
        (FRAC_PI_4, (x - 1.0) / (x + 1.0))
    } else {
        (0.0, x)
    };
    let z = x * x;
    let atan = offset
        + ((((8.053_744_5e-2 * z - 1.387_768_6e-1) * z + 1.997_771_1e-1) * z - 3.333_295e-1)
            * z
            * x
            + x);
    // Undo the octant folding: atan2 for sin ≥ 0.
    let first_octant = if sin > cos.abs() {
        FRAC_PI_2 - atan
    } else {
        atan
    };
    if cos < 0.0 {
        PI - first_octant
    } else {
        first_octant
    }
}

/// The regularised disk approximation F ≈ cosθ_i cosθ_j A_j / (π r² + A_j) (Wallace et al.
/// 1989, eq. 7 with a disk of the patch's area), bounded as r → 0. Cheap; used where the
/// exact value is not needed.
pub fn disk_approximation(p: Vec3, n: Vec3, q: Vec3, nq: Vec3, area: f32) -> f32 {
    let d = q - p;
    let r2 = d.length_squared();
    if r2 <= 0.0 {
        return 0.0;
    }
    let r = r2.sqrt();
    let cos_i = n.dot(d) / r;
    let cos_j = -nq.dot(d) / r;
    if cos_i <= 0.0 || cos_j <= 0.0 {
        return 0.0;
    }
    (cos_i * cos_j * area / (std::f32::consts::PI * r2 + area)).min(1.0)
}

/// A seed for an element's random numbers from its geometry, not its index: an element
/// kept through an adaptive refinement (which renumbers elements) draws the same rays.
pub fn element_seed(e: &crate::mesh::Element) -> u64 {
    let mut h = 0x9e37_79b9_7f4a_7c15u64;
    for v in e.verts {
        for c in v.to_array() {
            h = hash(h ^ c.to_bits() as u64);
        }
    }
    h
}

/// Visibility-weighted form factor from element `element` (receiver, at its centroid) to
/// patch `patch` (shooter), and the number of shadow rays cast. Zero when the receiver is
/// behind the patch or the patch is below the receiver's horizon.
pub fn element_to_patch(
    mesh: &Mesh,
    bvh: &Bvh,
    element: usize,
    patch: usize,
    settings: &FormFactorSettings,
) -> (f32, u32) {
    let e = &mesh.elements[element];
    let p = &mesh.patches[patch];
    let x = e.centroid();
    // The shooter emits from its front side only (each side of a double-sided surface is
    // its own patch).
    if p.normal.dot(x - p.verts[0]) <= 0.0 || e.patch as usize == patch {
        return (0.0, 0);
    }
    let f = point_to_polygon(x, e.normal, &p.verts);
    if f <= 0.0 {
        return (0.0, 0);
    }
    let receiver_patch = &mesh.patches[e.patch as usize];
    let n = ((f.sqrt() * settings.max_rays as f32).ceil() as u32)
        .clamp(settings.min_rays.max(1), settings.max_rays.max(1));
    // k² strata, at most MAX_SAMPLES (k ≤ 16).
    let k = ((n as f32).sqrt().ceil() as u32).min(16);
    let samples = k * k;
    let eps = mesh.epsilon();
    let from = x + e.normal * eps;
    let skip = [receiver_patch.scene_triangle, p.scene_triangle];
    // Shaft cull: when nothing can lie between the receiver and the patch, the patch is
    // wholly visible and F is exact without a single ray.
    let base = p.verts.map(|v| v + p.normal * eps);
    if bvh.shaft_clear(from, &base, skip, eps * 0.1) {
        return (f, 0);
    }
    let seed = hash(element_seed(e) ^ patch as u64);
    // One shadow ray per stratum. Where the rays disagree, the pair is sampled again with
    // `penumbra_rays` strata, each weighted by its own form factor (see
    // [`strata_visibility`]).
    let (at, source) = ((x, e.normal), (&p.verts, p.normal));
    let first = StrataRays::cast(bvh, at, source, (eps, skip), k, seed);
    if first.lo == first.hi {
        return (f * first.lo, samples);
    }
    // Penumbra strata: at least `penumbra_rays`, more for pairs that carry much light.
    // Stratified visibility errs by about f·k^-1.5 (the ~k boundary strata each miss a
    // random part of 1/k² of the patch), so k grows as (f / F_REF)^(2/3) to keep that
    // absolute error near its value for a pair of F_REF, up to the 16 × 16 cap: small,
    // refined elements in the penumbra of a main light then get values as sharp as their
    // size, while the many weak pairs keep the base count.
    const F_REF: f32 = 0.01;
    let base = (settings.penumbra_rays.max(1) as f32).sqrt();
    let kp = ((base * (f / F_REF).powf(2.0 / 3.0).max(1.0)).ceil() as u32).min(16);
    if kp > k {
        let second = strata_visibility(bvh, at, source, (eps, skip), kp, hash(seed));
        (f * second.fraction, samples + kp * kp)
    } else {
        (f * first.fraction(x, e.normal, &p.verts), samples)
    }
}

/// What [`strata_visibility`] found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::solver) struct StrataVisibility {
    /// The visible fraction of the source's form factor.
    pub fraction: f32,
    /// The least and the greatest transmittance of one ray.
    pub lo: f32,
    pub hi: f32,
}

/// The visible fraction of a source triangle's form factor from point `x` with normal `n`
/// (rays leave from `x` lifted by `eps` along `n`): the triangle is cut into `k²`
/// congruent strata ([`stratum`]), one shadow ray goes to a jittered point of each (lifted
/// off the source along its normal `sn`), and each ray's transmittance T_s is weighted by
/// its stratum's form factor F_s ([`form_factor_weight`]): Σ F_s T_s / Σ F_s. This is
/// visibility weighted by the kernel, as the definition of the form factor requires.
/// Weighted by area instead, a large, near, partly hidden source is misjudged whenever
/// what hides it lies where the kernel is small (area weights made the hierarchical
/// links to the Cornell blocks' faces 4 % short). The weights cost nothing where the rays
/// agree. `k` is at most 16.
pub(in crate::solver) fn strata_visibility(
    bvh: &Bvh,
    (x, n): (Vec3, Vec3),
    (source, sn): (&[Vec3; 3], Vec3),
    (eps, skip): (f32, [u32; 2]),
    k: u32,
    seed: u64,
) -> StrataVisibility {
    StrataRays::cast(bvh, (x, n), (source, sn), (eps, skip), k, seed).visibility(x, n, source)
}

/// The shadow rays of [`strata_visibility`], before they are weighted.
pub(in crate::solver) struct StrataRays {
    k: u32,
    through: [f32; MAX_SAMPLES],
    /// The least and the greatest transmittance of one ray.
    pub lo: f32,
    pub hi: f32,
}

impl StrataRays {
    /// One shadow ray from `x` (lifted by `eps` along `n`) to a jittered point of each of
    /// the k² strata of `source` ([`stratified_point`], lifted off it along `sn`); `k` is
    /// at most 16.
    pub(in crate::solver) fn cast(
        bvh: &Bvh,
        (x, n): (Vec3, Vec3),
        (source, sn): (&[Vec3; 3], Vec3),
        (eps, skip): (f32, [u32; 2]),
        k: u32,
        seed: u64,
    ) -> StrataRays {
        let k = k.clamp(1, 16);
        StrataRays::cast_each(bvh, (x, n), (eps, skip), k, |s| {
            stratified_point(source, k, s, seed) + sn * eps
        })
    }

    /// [`StrataRays::cast`] with the points [`StrataRays::refine`] reuses: stratum s's
    /// point is the point [`stratified_point`] draws in one of its four [`sub_strata`] of
    /// the 2k cut, chosen at random ([`nested_choice`]), which is uniform in s all the
    /// same. `k` is at most 8.
    pub(in crate::solver) fn cast_nested(
        bvh: &Bvh,
        (x, n): (Vec3, Vec3),
        (source, sn): (&[Vec3; 3], Vec3),
        (eps, skip): (f32, [u32; 2]),
        k: u32,
        seed: u64,
    ) -> StrataRays {
        let k = k.clamp(1, 8);
        StrataRays::cast_each(bvh, (x, n), (eps, skip), k, |s| {
            let fine = sub_strata(k, s)[nested_choice(seed, s)];
            stratified_point(source, 2 * k, fine, seed) + sn * eps
        })
    }

    /// One ray from `x` (lifted by `eps` along `n`) to `point(s)` for each stratum s of
    /// the k² cut ([`ray_in_front`]).
    fn cast_each(
        bvh: &Bvh,
        (x, n): (Vec3, Vec3),
        (eps, skip): (f32, [u32; 2]),
        k: u32,
        point: impl Fn(u32) -> Vec3,
    ) -> StrataRays {
        let mut rays = StrataRays::empty(k);
        for s in 0..k * k {
            rays.record(s, ray_in_front(bvh, (x, n), (eps, skip), point(s)));
        }
        rays
    }

    /// The rays of the (2k)² cut from the rays of [`StrataRays::cast_nested`] with the
    /// same arguments: each of its rays is the fine ray of the sub-stratum its point was
    /// drawn in, and the other three sub-strata get their own points. Every fine stratum
    /// then holds one uniform point, as [`StrataRays::cast`] draws them, so the estimate's
    /// expectation is that of a fresh (2k)² cut; 3k² rays are cast instead of 4k².
    pub(in crate::solver) fn refine(
        &self,
        bvh: &Bvh,
        (x, n): (Vec3, Vec3),
        (source, sn): (&[Vec3; 3], Vec3),
        (eps, skip): (f32, [u32; 2]),
        seed: u64,
    ) -> StrataRays {
        let k = self.k;
        let mut rays = StrataRays::empty(2 * k);
        for s in 0..k * k {
            let subs = sub_strata(k, s);
            let reused = subs[nested_choice(seed, s)];
            for fine in subs {
                let t = if fine == reused {
                    self.through[s as usize]
                } else {
                    let y = stratified_point(source, 2 * k, fine, seed) + sn * eps;
                    ray_in_front(bvh, (x, n), (eps, skip), y)
                };
                rays.record(fine, t);
            }
        }
        rays
    }

    /// The strata of the cut, k², one ray each. For [`StrataRays::refine`]'s cut, a
    /// quarter of them are the coarse cut's rays: it cast only the difference.
    pub(in crate::solver) fn strata(&self) -> u32 {
        self.k * self.k
    }

    fn empty(k: u32) -> StrataRays {
        StrataRays {
            k,
            through: [0.0; MAX_SAMPLES],
            lo: f32::INFINITY,
            hi: f32::NEG_INFINITY,
        }
    }

    fn record(&mut self, s: u32, t: f32) {
        self.through[s as usize] = t;
        self.lo = self.lo.min(t);
        self.hi = self.hi.max(t);
    }

    /// What the rays found from `x` with normal `n` (see [`strata_visibility`]).
    pub(in crate::solver) fn visibility(
        &self,
        x: Vec3,
        n: Vec3,
        source: &[Vec3; 3],
    ) -> StrataVisibility {
        StrataVisibility {
            fraction: self.fraction(x, n, source),
            lo: self.lo,
            hi: self.hi,
        }
    }

    /// Σ F_s T_s / Σ F_s (the common transmittance where every ray agrees).
    fn fraction(&self, x: Vec3, n: Vec3, source: &[Vec3; 3]) -> f32 {
        if self.hi == self.lo {
            return self.lo;
        }
        let strata = (self.k * self.k) as usize;
        let (mut seen, mut total) = (0.0f32, 0.0f32);
        for (s, t) in self.through[..strata].iter().enumerate() {
            let f = form_factor_weight(x, n, &stratum(source, self.k, s as u32));
            seen += f * t;
            total += f;
        }
        if total > 0.0 {
            (seen / total).clamp(0.0, 1.0)
        } else {
            // Every stratum below the horizon: nothing to weight by but the rays' mean.
            self.through[..strata].iter().sum::<f32>() / strata as f32
        }
    }
}

/// The transmittance of the segment from `x` lifted by `eps` along its surface's normal
/// `n` to `y`, skipping the triangles `skip`: zero where `y` does not lie in front of the
/// surface.
///
/// The segment's test skips the receiver's own triangle (it starts on it), so a point
/// behind the receiver's plane would be reached through the receiver itself. Such a point
/// has no weight in the form factor, but a stratum that straddles the receiver's plane
/// does, and its one ray may land in the part behind: on the inside of a double-sided
/// box standing in a floor, a stratum of the floor outside the box's corner, half in
/// front of the wall's inner side and hidden there by the next wall, sent its ray around
/// that wall's edge and through the inner side's own triangle, and the box's inside took
/// 1.3·10⁻⁴ of the floor's light at ρ = 0.5. At ρ = 0.999, whose cavity keeps what
/// leaks in for a thousand bounces, the inside came to 5.6 % of the floor outside
/// (`cornell-box-nvpro`'s tall box: as bright as the floor outside it).
///
/// "In front" is tested against the surface through `x`, not the lifted start: the strip
/// of a wall within `eps` of the floor it stands on lies below the lifted start and in
/// front of the floor all the same, and a floor point 0.1 mm from the wall sees much of
/// its light there (blocked, it lost 2.3 %: `tests/gather.rs`, perpendicular plates).
pub(in crate::solver) fn ray_in_front(
    bvh: &Bvh,
    (x, n): (Vec3, Vec3),
    (eps, skip): (f32, [u32; 2]),
    y: Vec3,
) -> f32 {
    if n.dot(y - x) > 0.0 {
        bvh.transmittance(x + n * eps, y, skip)
    } else {
        0.0
    }
}

/// Which of stratum s's four [`sub_strata`] its nested point is drawn in: uniform, and
/// independent of where in it (a different stream of the seed than `stratified_point`'s).
fn nested_choice(seed: u64, s: u32) -> usize {
    (hash(seed ^ 0x6e65_7374 ^ (s as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)) >> 62) as usize
}

/// The most strata [`element_to_patch`] samples (`max_rays` is capped to this).
pub const MAX_SAMPLES: usize = 256;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::sampling::unit;

    #[test]
    fn angle_between_matches_atan2_to_a_few_ulps() {
        // Against libm's f64 atan2 of the same f32 inputs, over every octant and down to
        // tiny angles: the doc's 2 ulps, with one more for the final rounding.
        let mut worst = 0.0f64;
        for i in 0..20_000u64 {
            let h = hash(i);
            let angle = std::f64::consts::PI * unit(h) as f64;
            let scale = 10f64.powi((h % 7) as i32 - 3);
            let (sin, cos) = ((angle.sin() * scale) as f32, (angle.cos() * scale) as f32);
            let want = (sin as f64).atan2(cos as f64);
            let got = angle_between(sin, cos) as f64;
            if want > 0.0 {
                worst = worst.max((got - want).abs() / want);
            }
        }
        assert!(
            worst <= 3.0 * f32::EPSILON as f64,
            "worst relative error {worst:e}"
        );
        assert_eq!(angle_between(0.0, 0.0), 0.0);
        assert_eq!(angle_between(0.0, -1.0), std::f32::consts::PI);
    }

    /// A triangle of unit size about the origin from the draws `u(4)` … `u(12)`, its
    /// centroid and its bounding radius about it.
    fn random_triangle(u: &impl Fn(u64) -> f32) -> ([Vec3; 3], Vec3, f32) {
        let tri = [
            Vec3::new(u(4), u(5), u(6)) - 0.5,
            Vec3::new(u(7), u(8), u(9)) - 0.5,
            Vec3::new(u(10), u(11), u(12)) - 0.5,
        ];
        let c = (tri[0] + tri[1] + tri[2]) / 3.0;
        let r = tri.iter().map(|v| (*v - c).length()).fold(0.0, f32::max);
        (tri, c, r)
    }

    /// Lambert's contour integral in f64 with libm's atan2, for a polygon (relative to the
    /// point) wholly above the horizon: the reference.
    fn contour_f64(rel: &[Vec3], n: Vec3) -> f64 {
        let n = n.as_dvec3();
        let sum: f64 = (0..rel.len())
            .map(|k| {
                let (a, b) = (rel[k].as_dvec3(), rel[(k + 1) % rel.len()].as_dvec3());
                let c = a.cross(b);
                let lc = c.length();
                lc.atan2(a.dot(b)) * n.dot(c) / lc
            })
            .sum();
        sum.abs() / std::f64::consts::TAU
    }

    #[test]
    fn point_to_polygon_stays_close_to_the_f64_contour_at_every_distance() {
        // Triangles of unit size in many orientations above the horizon, from 3 to 10⁵ of
        // their radii away (either side of the switch to the point formula): the error,
        // against the f64 contour of the same f32 vertices, relative to the solid-angle
        // scale A/(π d²), must stay within the doc's few 10⁻⁴.
        let mut worst = (0.0f64, 0.0f32);
        for i in 0..4000u64 {
            let h = hash(i);
            let u = |k: u64| unit(hash(h ^ k));
            let dir = Vec3::new(u(1) - 0.5, u(2) - 0.5, 0.2 + u(3)).normalize();
            let (tri, c, r) = random_triangle(&u);
            let area = 0.5 * (tri[1] - tri[0]).cross(tri[2] - tri[0]).length();
            let ratio = 10f32.powf(-0.5 - 4.5 * u(13));
            let d = r / ratio;
            let rel = tri.map(|v| v - c + dir * d);
            if rel.iter().any(|v| v.z < 0.0) {
                continue;
            }
            let got = point_to_polygon(Vec3::ZERO, Vec3::Z, &rel) as f64;
            let want = contour_f64(&rel, Vec3::Z);
            let scale = (area / (PI * d * d)) as f64;
            let err = (got - want).abs() / scale;
            if err > worst.0 {
                worst = (err, ratio);
            }
        }
        assert!(
            worst.0 <= 3e-4,
            "error {:e} of the scale at r/d = {:e}",
            worst.0,
            worst.1
        );
    }

    #[test]
    fn the_point_formula_stays_within_its_bound() {
        // Random triangles in every direction above the horizon, from 100 to 4 of their
        // radii away: the point formula's error against the f64 contour stays under the
        // bound `triangle_far_field` reports (measured: under half of it, in f64 over
        // 2·10⁵ such triangles).
        let (mut worst, mut tested) = (0.0f64, 0);
        for i in 0..20_000u64 {
            let h = hash(i ^ 0xfa12);
            let u = |k: u64| unit(hash(h ^ k));
            let dir = Vec3::new(u(1) - 0.5, u(2) - 0.5, u(3).powi(3)).normalize();
            let (tri, c, r) = random_triangle(&u);
            let d = r / 10f32.powf(-2.0 + 1.39 * u(13));
            let rel = tri.map(|v| v - c + dir * d);
            if rel.iter().any(|v| v.z < 0.0) {
                continue;
            }
            if let Some((f, bound)) = triangle_far_field(&rel, Vec3::Z) {
                let err = (f as f64 - contour_f64(&rel, Vec3::Z)).abs();
                // f32 rounding of the point formula itself adds a few ulps of f.
                worst = worst.max((err - 1e-6 * f as f64) / bound as f64);
                tested += 1;
            }
        }
        assert!(tested > 5000, "only {tested} triangles tested");
        assert!(worst <= 0.6, "error {worst} of the bound");
    }

    /// A source triangle 1 above the origin, facing down, 3 wide: large enough that its
    /// strata see the kernel vary.
    fn overhead_source() -> [Vec3; 3] {
        [
            Vec3::new(-1.0, -1.0, 1.0),
            Vec3::new(2.0, -1.0, 1.0),
            Vec3::new(-1.0, 2.0, 1.0),
        ]
    }

    #[test]
    fn refined_strata_reuse_the_coarse_rays_and_keep_the_expectation() {
        // A point under a large source triangle, with an opaque triangle halfway between
        // whose shadow on the source lies inside it. The claim of `StrataRays::refine`:
        // its estimate has the expectation of a fresh 4 × 4 cut. Both means, over 3000
        // seeds each, must agree within 4 standard errors of their difference (a false
        // failure once in ~16,000 runs). Both also stand near the exact visible form
        // factor, F(source) − F(occluder) (the shadow lies inside the source), within
        // what weighting each stratum by its own form factor misses of the kernel's
        // variation inside it: the strata are 0.75 wide at a distance of 1 to 1.7, where
        // cos²θ / r² changes by up to about 30 % across one, so the shadowed part may be
        // misjudged by that fraction (8.6 % measured).
        let source = overhead_source();
        let occluder = [
            Vec3::new(0.0, 0.0, 0.5),
            Vec3::new(0.4, 0.0, 0.5),
            Vec3::new(0.0, 0.4, 0.5),
        ];
        let bvh = Bvh::build(&[source, occluder], &[]);
        let (x, n, sn) = (Vec3::ZERO, Vec3::Z, -Vec3::Z);
        let ray = (1e-4, [u32::MAX, 0]);
        let draws = 3000u64;
        let (mut fresh, mut reused) = ((0.0f64, 0.0f64), (0.0f64, 0.0f64));
        for d in 0..draws {
            let seed = hash(d);
            let coarse = StrataRays::cast_nested(&bvh, (x, n), (&source, sn), ray, 2, seed);
            let refined = coarse.refine(&bvh, (x, n), (&source, sn), ray, seed);
            // The refined cut holds the coarse rays: its range covers theirs.
            assert!(refined.lo <= coarse.lo && refined.hi >= coarse.hi);
            let a = StrataRays::cast(&bvh, (x, n), (&source, sn), ray, 4, hash(seed))
                .fraction(x, n, &source) as f64;
            let b = refined.fraction(x, n, &source) as f64;
            fresh = (fresh.0 + a, fresh.1 + a * a);
            reused = (reused.0 + b, reused.1 + b * b);
        }
        let stats = |(s, s2): (f64, f64)| {
            let mean = s / draws as f64;
            (
                mean,
                (s2 / draws as f64 - mean * mean).max(0.0) / draws as f64,
            )
        };
        let ((ma, va), (mb, vb)) = (stats(fresh), stats(reused));
        assert!(
            (ma - mb).abs() <= 4.0 * (va + vb).sqrt(),
            "fresh {ma}, reused {mb}"
        );
        let f = point_to_polygon(x, n, &source) as f64;
        let exact = 1.0 - point_to_polygon(x, n, &occluder) as f64 / f;
        assert!(exact < 0.9, "the occluder hides a visible part: {exact}");
        for m in [ma, mb] {
            assert!(
                (m - exact).abs() <= 0.3 * (1.0 - exact),
                "{m} against {exact}"
            );
        }
    }

    #[test]
    fn refined_strata_put_each_ray_in_its_own_fine_stratum() {
        // An opaque triangle whose shadow on the source, seen from the point, is exactly
        // one fine stratum X (the middle of a coarse one): every ray that ends in X is
        // blocked and every other one is not, so the refined cut's fraction must be
        // 1 − F_X / Σ F_s for every seed (to f32 rounding). A ray counted for the wrong
        // fine stratum, or a point drawn outside its own, breaks this for most seeds.
        let source = overhead_source();
        let (x, n, sn) = (Vec3::ZERO, Vec3::Z, -Vec3::Z);
        for (coarse_stratum, child) in [(0, 1), (1, 0), (2, 3), (3, 2)] {
            let hidden = sub_strata(2, coarse_stratum)[child];
            let occluder = stratum(&source, 4, hidden).map(|v| v * 0.5);
            let bvh = Bvh::build(&[source, occluder], &[]);
            let ray = (1e-7, [u32::MAX, 0]);
            let weights: Vec<f32> = (0..16)
                .map(|s| form_factor_weight(x, n, &stratum(&source, 4, s)))
                .collect();
            let expected = 1.0 - weights[hidden as usize] / weights.iter().sum::<f32>();
            for d in 0..200u64 {
                let seed = hash(d);
                let coarse = StrataRays::cast_nested(&bvh, (x, n), (&source, sn), ray, 2, seed);
                let refined = coarse.refine(&bvh, (x, n), (&source, sn), ray, seed);
                let got = refined.fraction(x, n, &source);
                assert!(
                    (got - expected).abs() <= 1e-5,
                    "X = {hidden}, seed {d}: {got} against {expected}"
                );
            }
        }
    }
}
