//! The transfer a link carries and the kernel variation the oracle judges it by.
//!
//! A link from source s to receiver r adds `F · B_s` to the irradiance r gathers
//! (B_r = E'_r + ρ_r H_r, H_r = Σ F · B_s), F the form factor from points of the receiver
//! to the source times visibility, kept at the receiver's three quadrature points so that
//! the receiver gets it as a linear function (see `Link::corners`):
//!
//! - surface ← surface: Lambert's exact point-to-polygon form factor
//!   ([`point_to_polygon`], clipped to the receiver's hemisphere, zero behind the source's
//!   front) at the three points of the degree-2 triangle rule (barycentric (2/3, 1/6, 1/6)
//!   and permutations; Strang & Fix), each times the visible fraction of the source seen
//!   from it (shadow rays to stratified points of the source, each weighted by its
//!   stratum's form factor: `form_factor::StrataRays`). The points lie halfway
//!   between the centroid and the corners; the receiver gets the linear function through them, and the link's `spread`
//!   is what that function may miss: how far the kernel at the centroid bends away from it,
//!   plus the form factor where the shadow rays disagree (a shadow boundary crosses it);
//!   where the points see nothing, what the receiver's corners see or, hidden from them
//!   too, the unoccluded form factor (`seen_at_corners`).
//!   Near a corner or a contact, where the kernel rises faster than three points follow,
//!   the oracle also judges a receiver's links together (`oracle`).
//! - clusters (Sillion 1995) are seen through their projected area P(ω) (see
//!   [`projected_area`]: exact for a flat cluster, the isotropic A/4 for a closed one): a
//!   cluster whose surfaces facing ω have radiosity B(ω) emits B(ω)·P(ω)/π W/sr towards
//!   ω (`Facing` in the sweeps: its mean B would leak a wall's lit side through its dark
//!   one); a receiving cluster's
//!   factor is the irradiance on a plane facing the source, shared out to its surfaces by
//!   their orientation when it is pushed down (`Octants`). For a cluster link, `spread` is
//!   the range of the unoccluded kernel between any two points of the ends' bounding
//!   spheres (`ClusterKernel`; infinite when they overlap), plus the whole transfer where
//!   its shadow rays disagree.
//! - a pair whose surfaces face away from each other (by the cone of their normals, see
//!   [`blind`]) gets no link at all: two clusters on one wall, however close, exchange
//!   nothing, and neither do any of their children.

use super::NodeId;
use super::clusters::{Facing, SAMPLES};
use crate::accel::{Bvh, Shaft};
use crate::geometry::sampling::{hash, stratified_point, stratum};
use crate::solver::form_factor::point_to_polygon;
use crate::solver::form_factor::{StrataRays, form_factor_weight};
use glam::Vec3;
use std::f32::consts::PI;

/// A patch standing for a cluster in its transfers (see `Cluster::samples`).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Sample {
    pub verts: [Vec3; 3],
    pub normal: Vec3,
    pub area: f32,
    pub triangle: u32,
}

/// What a node looks like to a transfer. Built on the stack for each link the oracle
/// makes or judges, so a cluster's samples stay inline rather than behind an allocation.
/// They are filled in only where a transfer casts rays ([`evaluate`]'s `samples`): most
/// cluster links are judged by their kernel alone, and reading a cluster's sample patches
/// is four reads scattered over the scene's patches.
#[derive(Clone, Copy, Debug)]
#[allow(clippy::large_enum_variant)]
pub(super) enum Shape {
    Surface {
        verts: [Vec3; 3],
        normal: Vec3,
        area: f32,
        /// Scene triangle (skipped by its own shadow rays).
        triangle: u32,
    },
    Cluster {
        centre: Vec3,
        radius: f32,
        /// Bounding box.
        lo: Vec3,
        hi: Vec3,
        facing: Facing,
        area: f32,
        /// Σ A_i n_i of the surfaces inside.
        area_vector: Vec3,
        /// Patches inside it, drawn by area.
        samples: [Sample; SAMPLES],
    },
}

impl Shape {
    pub fn centre(&self) -> Vec3 {
        match self {
            Shape::Surface { verts, .. } => centroid(verts),
            Shape::Cluster { centre, .. } => *centre,
        }
    }

    /// Radius of a sphere around [`Shape::centre`] holding the node.
    pub fn radius(&self) -> f32 {
        match self {
            Shape::Surface { verts, .. } => radius(verts),
            Shape::Cluster { radius, .. } => *radius,
        }
    }

    /// Which way the node's surfaces face.
    fn facing(&self) -> Facing {
        match self {
            Shape::Surface { verts, normal, .. } => Facing {
                axis: *normal,
                cos: 1.0,
                low: verts
                    .iter()
                    .map(|v| normal.dot(*v))
                    .fold(f32::INFINITY, f32::min),
            },
            Shape::Cluster { facing, .. } => *facing,
        }
    }

    /// The largest projection of the node onto direction `w`.
    fn extent_along(&self, w: Vec3) -> f32 {
        match self {
            Shape::Surface { verts, .. } => verts
                .iter()
                .map(|v| w.dot(*v))
                .fold(f32::NEG_INFINITY, f32::max),
            Shape::Cluster { lo, hi, .. } => (w * *lo).max(w * *hi).element_sum(),
        }
    }
}

/// Whether no light can pass between the two nodes, either way, by which way their
/// surfaces face (see [`Facing::blind_to`]), up to `tol`: then the pair needs no link,
/// however close the two are (its children's pairs would all be empty too).
pub(super) fn blind(r: &Shape, s: &Shape, tol: f32) -> bool {
    let reach = (r.centre() - s.centre()).length() + r.radius() + s.radius();
    let (fr, fs) = (r.facing(), s.facing());
    fs.blind_to(r.extent_along(fs.axis), reach, tol)
        || fr.blind_to(s.extent_along(fr.axis), reach, tol)
}

/// A link's transfer at the receiver's three quadrature points, whether a shadow boundary
/// crosses it, and the shadow rays it took.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Transfer {
    pub values: [f32; 3],
    /// What the linear function through `values` may miss (see the module doc).
    pub spread: f32,
    /// Shadow rays of the link disagree.
    pub partial: bool,
    pub rays: u32,
    /// Where on a surface source the receiver's light comes from (see [`kernel_centroid`]).
    pub toward: [f32; 2],
    /// What the linear transfer misses per unit radiosity of the source 90 % of the way
    /// from the receiver's centroid to each corner: the exact unoccluded form factor there
    /// times the link's visible fraction, less the linear function (zero for clusters).
    pub miss: [f32; 3],
}

/// The form factor from point `x` with normal `n` to the source triangle `sv` with normal
/// `sn`, which emits from its front side only: zero when `x` is not in front of it.
pub(in crate::solver) fn front_form_factor(x: Vec3, n: Vec3, sv: &[Vec3; 3], sn: Vec3) -> f32 {
    if sn.dot(x - sv[0]) > 0.0 {
        point_to_polygon(x, n, sv)
    } else {
        0.0
    }
}

/// Barycentric points of the degree-2 rule, each halfway from the centroid to a corner.
fn quadrature(v: &[Vec3; 3]) -> [Vec3; 3] {
    let at = |a: usize, b: usize, c: usize| v[a] * (2.0 / 3.0) + (v[b] + v[c]) * (1.0 / 6.0);
    [at(0, 1, 2), at(1, 2, 0), at(2, 0, 1)]
}

/// Seed of a link's rays from its two ends (node ids are stable through refinement).
fn seed(receiver: NodeId, source: NodeId) -> u64 {
    hash(((receiver.0 as u64) << 32) ^ source.0 as u64 ^ 0x005e_ed0f_11ab)
}

/// The transfer from `source` to `receiver`. `final_ends`: whether the receiver and the
/// source are leaves that cannot be split further. When both are, a partly visible link
/// is sampled with 16 strata per receiver point instead of 4 (12 new rays: the 4 of the
/// coarse cut are reused, see `StrataRays::refine`); a final source is constant
/// (see `Hierarchy::pull`), so where its light comes from is not needed. `keep_spread`:
/// the largest spread the oracle could keep this link with. A cluster link whose
/// unoccluded kernel range alone exceeds it will be split whatever its visibility, so it
/// gets no shadow rays and carries nothing (such links took 16 % of Sponza's shadow rays,
/// and the solve 8 % longer). A link whose ends overlap carries its sampled transfer only
/// when that is infinite (past the link budget, when the oracle keeps every link); the
/// oracle splits it otherwise, or keeps it carrying nothing where its source sends at most
/// the threshold's worth. `samples(shape, node)`: the shape of a cluster with its
/// sample patches filled in (see [`Shape`]), asked for only where rays are cast.
pub(super) fn evaluate(
    bvh: &Bvh,
    eps: f32,
    (receiver, r): (NodeId, &Shape),
    (source, s): (NodeId, &Shape),
    final_ends: (bool, bool),
    keep_spread: f32,
    samples: impl Fn(&Shape, NodeId) -> Shape,
) -> Transfer {
    let seed = seed(receiver, source);
    match (r, s) {
        (
            Shape::Surface {
                verts: rv,
                normal: rn,
                triangle: rt,
                ..
            },
            Shape::Surface {
                verts: sv,
                normal: sn,
                triangle: st,
                ..
            },
        ) => surface_to_surface(bvh, eps, (rv, *rn, *rt), (sv, *sn, *st), final_ends, seed),
        _ => {
            let samples = || (samples(r, receiver), samples(s, source));
            with_cluster(bvh, eps, (r, s), samples, seed, keep_spread)
        }
    }
}

fn surface_to_surface(
    bvh: &Bvh,
    eps: f32,
    (rv, rn, rt): (&[Vec3; 3], Vec3, u32),
    (sv, sn, st): (&[Vec3; 3], Vec3, u32),
    (final_receiver, final_source): (bool, bool),
    seed: u64,
) -> Transfer {
    if rt == st {
        // The two sides of one double-sided triangle: the point-to-polygon factor between
        // them is 0 · ∞ wherever rounding puts a receiver point off the plane, and the
        // shadow rays skip that very triangle. Nothing passes from one side to the other.
        return Transfer {
            values: [0.0; 3],
            spread: 0.0,
            partial: false,
            rays: 0,
            toward: CENTROID,
            miss: [0.0; 3],
        };
    }
    let fine = final_receiver && final_source;
    let q = quadrature(rv);
    let f = q.map(|x| front_form_factor(x, rn, sv, sn));
    let hi = f[0].max(f[1]).max(f[2]);
    let skip = [rt, st];
    if hi <= 0.0 {
        // No quadrature point is in front of the source, but a corner may be (the part of
        // a triangle in front of a plane is convex, so if any of it is, a corner is): the
        // zero function may miss up to the unoccluded factor there.
        let edge = rv
            .iter()
            .map(|x| front_form_factor(*x, rn, sv, sn))
            .fold(0.0, f32::max);
        return Transfer {
            values: [0.0; 3],
            spread: edge,
            partial: false,
            rays: 0,
            toward: CENTROID,
            miss: [0.0; 3],
        };
    }
    let base = sv.map(|v| v + sn * eps);
    let from = q.map(|x| x + rn * eps);
    // What a shaft test proves from each receiver point: all of the source seen, or all
    // of it hidden behind one opaque triangle; shadow rays go only where neither holds.
    // `None`: the point sees none of the source, and its visibility does not matter.
    let proofs: [Option<Shaft>; 3] =
        std::array::from_fn(|k| (f[k] > 0.0).then(|| bvh.shaft(from[k], &base, skip, eps * 0.1)));
    let mut rays = 0u32;
    let (mut visible, mut vlo, mut vhi) = ([1.0f32; 3], 1.0f32, 1.0f32);
    // What a link hidden from its three points may miss (see `seen_at_corners`).
    let (mut lit_corner, mut hidden) = (0.0f32, 0.0f32);
    if proofs.iter().any(|p| p.is_some_and(|p| p != Shaft::Clear)) {
        // 2 × 2 shadow rays from each unproven receiver point to stratified points of the
        // source; where the rays of a final link disagree, 4 × 4 that reuse them (a fifth
        // fewer rays than 16 fresh ones, the same expectation; and a quarter less bias
        // from choosing the finer cut by what the rays found, since the rays that chose it
        // count for a quarter of the result rather than nothing).
        let points = |j: usize| ((q[j], rn), (sv, sn), (eps, skip));
        let seeds = [0, 1, 2].map(|j| hash(seed ^ j as u64));
        let mut cast: [Option<StrataRays>; 3] = std::array::from_fn(|j| {
            (proofs[j] == Some(Shaft::Unknown)).then(|| {
                let (at, source, ray) = points(j);
                StrataRays::cast_nested(bvh, at, source, ray, 2, seeds[j])
            })
        });
        // The least and the greatest transmittance of one ray over the points.
        let range = |cast: &[Option<StrataRays>; 3]| {
            let mut range = (f32::INFINITY, f32::NEG_INFINITY);
            for j in 0..3 {
                let (lo, hi) = match (proofs[j], &cast[j]) {
                    (None, _) => continue,
                    (_, Some(rays)) => (rays.lo, rays.hi),
                    (Some(Shaft::Blocked), _) => (0.0, 0.0),
                    _ => (1.0, 1.0),
                };
                range = (range.0.min(lo), range.1.max(hi));
            }
            range
        };
        (vlo, vhi) = range(&cast);
        rays = cast.iter().flatten().map(StrataRays::strata).sum();
        if fine && vhi > vlo {
            for (j, c) in cast.iter_mut().enumerate() {
                if let Some(coarse) = c {
                    let (at, source, ray) = points(j);
                    let refined = coarse.refine(bvh, at, source, ray, seeds[j]);
                    rays += refined.strata() - coarse.strata();
                    *c = Some(refined);
                }
            }
            (vlo, vhi) = range(&cast);
        }
        visible = std::array::from_fn(|j| match (proofs[j], &cast[j]) {
            (_, Some(r)) => r.visibility(q[j], rn, sv).fraction,
            (Some(Shaft::Blocked), _) => 0.0,
            _ => 1.0,
        });
        if vhi <= 0.0 {
            // Hidden from every point, unproven for the rest of the receiver.
            let at = seen_at_corners(bvh, eps, (rv, rn), (sv, sn, &base), skip, seed);
            rays += at.rays;
            if at.seen > 0.0 {
                (vhi, lit_corner) = (at.hi, at.seen);
            } else {
                hidden = hi.max(at.unoccluded);
            }
        }
    }
    let values: [f32; 3] = std::array::from_fn(|k| f[k] * visible[k]);
    let mean = (values[0] + values[1] + values[2]) / 3.0;
    let lo = values[0].min(values[1]).min(values[2]);
    let vhi_values = values[0].max(values[1]).max(values[2]);
    // The linear function through the three values predicts `mean` at the centroid; the
    // kernel there (visibility taken as the mean) says how far it bends. Four times the
    // miss at the centroid bounds the miss at the corners for a quadratic, plus a quarter of
    // the linear spread for bends the centroid cannot see, plus the mean where a shadow
    // boundary crosses the link.
    let c = (rv[0] + rv[1] + rv[2]) / 3.0;
    let fc = front_form_factor(c, rn, sv, sn);
    let mean_visible = (visible[0] + visible[1] + visible[2]) / 3.0;
    let partial = vhi > vlo;
    // The link's visible fraction as a whole: its transfer over its unoccluded one.
    let unoccluded = (f[0] + f[1] + f[2]) / 3.0;
    let seen = (mean / unoccluded).min(1.0);
    let corners = values.map(|v| 2.0 * v - mean);
    let miss = std::array::from_fn(|k| {
        // The linear function at 90 % towards corner k: 0.9 of corner k's value plus
        // the centroid's share of all three.
        let linear = corners[k] * (0.1 / 3.0 + 0.9)
            + (corners[(k + 1) % 3] + corners[(k + 2) % 3]) * (0.1 / 3.0);
        let x = c + (rv[k] - c) * 0.9;
        front_form_factor(x, rn, sv, sn) * seen - linear
    });
    Transfer {
        miss,
        values,
        spread: 4.0 * (fc * mean_visible - mean).abs()
            + 0.25 * (vhi_values - lo)
            + if partial { mean.max(lit_corner) } else { 0.0 }
            + hidden,
        partial,
        rays,
        toward: if final_source || radius(sv) < NEAR_SOURCE * (centroid(sv) - c).length() {
            CENTROID
        } else {
            kernel_centroid(c, rn, sv)
        },
    }
}

/// What the receiver's corners see of a source hidden from its three quadrature points
/// (see [`seen_at_corners`]).
struct Corners {
    /// The greatest transmittance of one ray from a corner in front of the source (0 or
    /// 1 by a shaft's proof).
    hi: f32,
    /// The most any corner sees: its unoccluded form factor times its visible fraction.
    seen: f32,
    /// The largest unoccluded form factor at a corner.
    unoccluded: f32,
    rays: u32,
}

/// Looks at a source hidden from the receiver's three quadrature points from its corners
/// (`base`: the source lifted off its plane, as the points' shafts take it), by a shaft's
/// proof or 2 × 2 shadow rays: a shadow edge that crosses the receiver near a
/// corner passes between the points unseen. A corner that sees the source makes the link
/// partial, its spread at least what that corner sees (the zero function misses it
/// there). A link hidden from its corners too may still have a lit part between them,
/// and its spread is its largest unoccluded form factor: it splits until the source's
/// light times that is within the oracle's threshold, so a receiver in the umbra of a
/// bright source goes on splitting and one in the shadow of a dim wall stops.
///
/// Before, a link its points saw nothing of split whenever its source had light, which
/// refined every receiver hidden from any lit source down to the minimum size, whatever
/// ε: the Cornell box at `--link-error 2` came to 36,574 leaves, 7,351 with this rule;
/// converged at the default ε, 72,160 leaves and 5.1 M links in 20.2–20.4 s, then 65,083
/// and 3.5 M in 14.4–14.9 s (run in turn, before the rounds went from coarse to fine).
/// Dropping such links instead (nothing splits) took away light the receiver's corner
/// saw: a floor node 2 mm from the red wall lost a quarter of the lamp, which the tall
/// block hides from the node's six points but not from all of it, and came out 16 % too
/// dark.
fn seen_at_corners(
    bvh: &Bvh,
    eps: f32,
    (rv, rn): (&[Vec3; 3], Vec3),
    (sv, sn, base): (&[Vec3; 3], Vec3, &[Vec3; 3]),
    skip: [u32; 2],
    seed: u64,
) -> Corners {
    let mut at = Corners {
        hi: 0.0,
        seen: 0.0,
        unoccluded: 0.0,
        rays: 0,
    };
    for (k, x) in rv.iter().enumerate() {
        let f = front_form_factor(*x, rn, sv, sn);
        if f <= 0.0 {
            continue;
        }
        let (hi, visible) = match bvh.shaft(*x + rn * eps, base, skip, eps * 0.1) {
            Shaft::Clear => (1.0, 1.0),
            Shaft::Blocked => (0.0, 0.0),
            Shaft::Unknown => {
                let seed = hash(seed ^ (3 + k) as u64);
                let cast = StrataRays::cast_nested(bvh, (*x, rn), (sv, sn), (eps, skip), 2, seed);
                at.rays += cast.strata();
                (cast.hi, cast.visibility(*x, rn, sv).fraction)
            }
        };
        at.hi = at.hi.max(hi);
        at.seen = at.seen.max(f * visible);
        at.unoccluded = at.unoccluded.max(f);
    }
    at
}

/// A source whose bounding radius is below this fraction of its distance sends from its
/// centroid: the kernel then varies by under about 10 % across it, and its kernel-weighted
/// centroid moves from the centroid by under a twentieth of its radius, which changes the
/// light its linear fit sends by under a twentieth of its variation.
const NEAR_SOURCE: f32 = 0.05;

/// A triangle's centroid.
pub(super) fn centroid(v: &[Vec3; 3]) -> Vec3 {
    (v[0] + v[1] + v[2]) / 3.0
}

/// The radius of the sphere around a triangle's centroid that holds it.
pub(super) fn radius(v: &[Vec3; 3]) -> f32 {
    let c = centroid(v);
    v.iter().map(|p| (*p - c).length()).fold(0.0, f32::max)
}

/// The barycentric weights of corners 1 and 2 of a triangle's centroid.
const CENTROID: [f32; 2] = [1.0 / 3.0, 1.0 / 3.0];

/// The kernel-weighted centroid of source triangle `sv` seen from point `x` with normal
/// `n`, y* = ∫ K(x, y) y dy / ∫ K(x, y) dy, as the barycentric weights of the source's
/// corners 1 and 2: from the form factors of its four strata ([`stratum`],
/// `form_factor_weight`) and their centroids. For a source whose radiosity varies
/// linearly, B(y) = B̄ + g · (y − ȳ), the light it sends to x is exactly F · B(y*)
/// (∫ K B = F B̄ + g · ∫ K (y − ȳ)), where its mean B̄ alone gives F · B̄: a wall brighter towards its middle than at its top
/// and bottom sends more light to the ceiling's centre than its mean says, since the
/// ceiling's centre sees its middle best (the mean made the Cornell ceiling 1.4 % too
/// dark).
fn kernel_centroid(x: Vec3, n: Vec3, sv: &[Vec3; 3]) -> [f32; 2] {
    let simplex = [Vec3::X, Vec3::Y, Vec3::Z];
    let (mut sum, mut total) = (Vec3::ZERO, 0.0f32);
    for s in 0..4 {
        let f = form_factor_weight(x, n, &stratum(sv, 2, s));
        let t = stratum(&simplex, 2, s);
        sum += (t[0] + t[1] + t[2]) * (f / 3.0);
        total += f;
    }
    if total > 0.0 && sum.is_finite() {
        let w = sum / total;
        [w.y, w.z]
    } else {
        CENTROID
    }
}

/// The area a cluster shows towards unit direction `w`: max(0, a · w) for the part of its
/// area that is oriented (the area vector a = Σ A_i n_i) plus a quarter of the rest
/// (isotropic). Exact for coplanar surfaces facing one way (|a| = A), Sillion's isotropic
/// A / 4 for a closed surface (a = 0).
pub(in crate::solver) fn projected_area(area: f32, area_vector: Vec3, w: Vec3) -> f32 {
    area_vector.dot(w).max(0.0) + (area - area_vector.length()).max(0.0) * 0.25
}

/// Points standing for a node in visibility tests towards point `other`: (point lifted off
/// its surface, the surface's triangle). A cluster's are its sample patches that face
/// `other` (repeated to fill the slots), or all of them when none does: a patch facing
/// away sends nothing that way, and the cluster's projected area already leaves it out,
/// so its shadow rays (through the cluster's own surfaces) would count that twice.
fn sample_points(shape: &Shape, eps: f32, seed: u64, other: Vec3) -> [(Vec3, u32); SAMPLES] {
    match shape {
        Shape::Surface {
            verts,
            normal,
            triangle,
            ..
        } => std::array::from_fn(|i| {
            (
                stratified_point(verts, 2, i as u32, seed) + *normal * eps,
                *triangle,
            )
        }),
        Shape::Cluster { samples, .. } => {
            let mut facing = [0usize; SAMPLES];
            let mut count = 0;
            for (k, p) in samples.iter().enumerate() {
                if p.normal.dot(other - centroid(&p.verts)) > 0.0 {
                    facing[count] = k;
                    count += 1;
                }
            }
            std::array::from_fn(|i| {
                let p = samples[if count > 0 { facing[i % count] } else { i }];
                (centroid(&p.verts) + p.normal * eps, p.triangle)
            })
        }
    }
}

/// Whether the bounding spheres of two nodes overlap: their cluster kernel has no bound
/// (see [`ClusterKernel`]) and their transfer is sampled instead ([`near_transfer`]).
fn overlap(r: &Shape, s: &Shape) -> bool {
    (s.centre() - r.centre()).length() <= r.radius() + s.radius()
}

/// A link with a cluster at either end: judged by its kernel from the ends' bounds, with
/// `samples()` the two shapes with their sample patches, for the rays.
fn with_cluster(
    bvh: &Bvh,
    eps: f32,
    (r, s): (&Shape, &Shape),
    samples: impl FnOnce() -> (Shape, Shape),
    seed: u64,
    keep_spread: f32,
) -> Transfer {
    let (cr, cs) = (r.centre(), s.centre());
    let d = (cs - cr).length();
    let nothing = |spread| Transfer {
        values: [0.0; 3],
        spread,
        partial: false,
        rays: 0,
        toward: CENTROID,
        miss: [0.0; 3],
    };
    if overlap(r, s) {
        // No bound on the kernel: the oracle splits such a link (it then carries
        // nothing) or keeps it carrying nothing (a source too dim to matter), unless it
        // keeps every link (past the link budget), when it carries the sampled transfer.
        return if keep_spread.is_infinite() {
            let (r, s) = samples();
            near_transfer(bvh, eps, &r, &s, seed)
        } else {
            nothing(f32::INFINITY)
        };
    }
    let towards = (cs - cr) / d;
    let kernel = ClusterKernel::new(r, s, d, towards);
    let spread = kernel.hi - kernel.lo;
    if kernel.centre <= 0.0 || !kernel.centre.is_finite() || spread > keep_spread {
        return nothing(spread);
    }
    let (r, s) = samples();
    let from = sample_points(&r, eps, seed, cs);
    let to = sample_points(&s, eps, hash(seed), cr);
    let through: [f32; SAMPLES] =
        std::array::from_fn(|i| bvh.transmittance(from[i].0, to[i].0, [from[i].1, to[i].1]));
    let seen = through.iter().sum::<f32>() / SAMPLES as f32;
    let partial = through.iter().any(|t| *t != through[0]);
    let value = kernel.centre * seen;
    Transfer {
        values: [value; 3],
        // Where the rays disagree, a shadow boundary crosses the link and the whole of
        // the light it carries is uncertain (as for surface links).
        spread: spread + if partial { kernel.centre } else { 0.0 },
        partial,
        rays: SAMPLES as u32,
        // Cluster ends are far apart, where the kernel barely varies over the source.
        toward: CENTROID,
        miss: [0.0; 3],
    }
}

/// The transfer between ends whose bounding spheres overlap, sampled over the source's
/// surfaces: F(x → S) ≈ Σ_j (A_S / (n A_j)) F(x → P_j) V(x, P_j), the P_j the source's n
/// sample patches (drawn with probability A_j / A_S, so the sum is unbiased), F the exact
/// point-to-polygon factor from the front of P_j, V one shadow ray to P_j's centroid. A
/// surface source is its own single sample (the sum is then exact up to visibility). A
/// surface receiver takes it at its three quadrature points; a receiving cluster the mean
/// over its sample patches' centroids (also drawn by area, so the mean estimates the
/// irradiance averaged over its surfaces), which reaches its surfaces from every
/// direction alike (see `Octants::add_mean`). `spread` is infinite: no kernel bound
/// holds between overlapping ends.
fn near_transfer(bvh: &Bvh, eps: f32, r: &Shape, s: &Shape, seed: u64) -> Transfer {
    // The source's samples and the weight A_S / (n A_j) of each.
    let (sources, weight): (&[Sample], [f32; SAMPLES]) = match s {
        Shape::Surface {
            verts,
            normal,
            area,
            triangle,
        } => (
            &[Sample {
                verts: *verts,
                normal: *normal,
                area: *area,
                triangle: *triangle,
            }],
            [1.0; SAMPLES],
        ),
        Shape::Cluster { samples, area, .. } => (
            samples,
            samples.map(|p| {
                if p.area > 0.0 {
                    area / (SAMPLES as f32 * p.area)
                } else {
                    0.0
                }
            }),
        ),
    };
    let mut rays = 0u32;
    let mut at = |x: Vec3, n: Vec3, own: u32| -> f32 {
        let mut f = 0.0;
        for (j, (p, w)) in sources.iter().zip(&weight).enumerate() {
            let k = front_form_factor(x, n, &p.verts, p.normal);
            if k <= 0.0 || *w <= 0.0 {
                continue;
            }
            let y = stratified_point(&p.verts, 1, 0, hash(seed ^ j as u64)) + p.normal * eps;
            rays += 1;
            // A point behind the receiver's plane is not blocked here (its single ray stands
            // for the whole of a patch the plane may cut: blocking it halved the transfer).
            f += w * k * bvh.transmittance(x + n * eps, y, [own, p.triangle]);
        }
        f
    };
    let values = match r {
        Shape::Surface {
            verts,
            normal,
            triangle,
            ..
        } => quadrature(verts).map(|x| at(x, *normal, *triangle)),
        Shape::Cluster { samples, .. } => {
            let mean = samples
                .iter()
                .map(|p| at(centroid(&p.verts), p.normal, p.triangle))
                .sum::<f32>()
                / SAMPLES as f32;
            [mean; 3]
        }
    };
    Transfer {
        values: values.map(|v| if v.is_finite() { v } else { 0.0 }),
        spread: f32::INFINITY,
        partial: false,
        rays,
        toward: CENTROID,
        miss: [0.0; 3],
    }
}

/// The unoccluded transfer of a link with a cluster at either end, per unit radiosity of
/// the source, and the range it takes between any two points of the ends' bounding
/// spheres.
///
/// At the centres, the transfer is I_s(ω) · c_r(ω) / d²: the source's intensity per unit
/// radiosity towards the receiver, its projected area P(ω) / π (Sillion 1995; a surface's
/// A cos θ_s / π), times how much of it a receiving surface takes (cos θ_r; a cluster takes
/// the irradiance on a plane facing the source and shares it out by orientation,
/// `Octants`). Between points of spheres of radii r_r and r_s whose centres are d apart,
/// the distance lies in [d − r_r − r_s, d + r_r + r_s] and the direction within
/// α = asin((r_r + r_s) / d) of the centres' (Holzschuch & Sillion 1998 bound the kernel the
/// same way): each cosine moves by at most α (|d cos/dθ| ≤ 1), a cluster's oriented area
/// |a| by at most |a| α. The range [lo, hi] is what the oracle judges a cluster link by:
/// its kernel's variation, so a far link carries a transfer known to a few per cent of
/// itself, where the bound of the whole transfer (A_s / (π gap²)) held every link near a
/// cluster to its full value.
struct ClusterKernel {
    centre: f32,
    lo: f32,
    hi: f32,
}

impl ClusterKernel {
    fn new(r: &Shape, s: &Shape, d: f32, towards: Vec3) -> ClusterKernel {
        let reach = r.radius() + s.radius();
        let gap = d - reach;
        let alpha = (reach / d).min(1.0).asin();
        // (at the centres, least, most) for the source's intensity and the receiver's share.
        let emitted = match s {
            Shape::Surface { normal, area, .. } => {
                let c = normal.dot(-towards);
                [
                    c.max(0.0),
                    (c - alpha).max(0.0),
                    (c + alpha).clamp(0.0, 1.0),
                ]
                .map(|c| c * area)
            }
            Shape::Cluster {
                area, area_vector, ..
            } => {
                let oriented = area_vector.length();
                let centre = projected_area(*area, *area_vector, -towards);
                [
                    centre,
                    (centre - oriented * alpha).max(0.0),
                    (centre + oriented * alpha).min(*area),
                ]
            }
        }
        .map(|p| p / PI);
        let received = match r {
            Shape::Surface { normal, .. } => {
                let c = normal.dot(towards);
                [
                    c.max(0.0),
                    (c - alpha).max(0.0),
                    (c + alpha).clamp(0.0, 1.0),
                ]
            }
            Shape::Cluster { .. } => [1.0; 3],
        };
        let near = if gap > 0.0 { gap * gap } else { 0.0 };
        let far = (d + reach) * (d + reach);
        ClusterKernel {
            centre: emitted[0] * received[0] / (d * d),
            lo: emitted[1] * received[1] / far,
            hi: if near > 0.0 {
                emitted[2] * received[2] / near
            } else {
                f32::INFINITY
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::geometry::sampling::hash;

    /// A deterministic number in [0, 1) from `k`.
    fn uniform(k: u64) -> f32 {
        (hash(k) >> 40) as f32 / (1u64 << 24) as f32
    }

    /// A deterministic unit vector from `k` (rejection sampling in the unit ball).
    fn unit(k: u64) -> Vec3 {
        (0..)
            .map(|i: u64| {
                let k = hash(k ^ i << 48);
                Vec3::new(uniform(k), uniform(k ^ 7), uniform(k ^ 13)) * 2.0 - Vec3::ONE
            })
            .find(|v| v.length_squared() > 1e-3 && v.length_squared() <= 1.0)
            .map_or(Vec3::Z, Vec3::normalize)
    }

    fn point_in_sphere(centre: Vec3, radius: f32, k: u64) -> Vec3 {
        centre + unit(k) * radius * uniform(k ^ 99).cbrt()
    }

    /// Brute force: the cluster model's kernel between any two points of the ends'
    /// spheres lies within the range `ClusterKernel` gives, for a receiving surface or
    /// cluster and a sending surface or cluster, near (gap a tenth of the radii) and far.
    #[test]
    fn the_cluster_kernel_range_holds_every_pair_of_points_in_the_spheres() {
        for case in 0..400u64 {
            let seed = case * 1_000;
            let rn = unit(seed + 1);
            let rv = [Vec3::ZERO, Vec3::X * 0.4, Vec3::Y * 0.3].map(|v| v + unit(seed + 2) * 0.05);
            // A receiver in the plane with normal rn: rotate the triangle into it.
            let (t, b) = crate::geometry::orthonormal_basis(rn);
            let rv = rv.map(|v| t * v.x + b * v.y);
            let receiving_cluster = case % 2 == 0;
            let r = if receiving_cluster {
                Shape::Cluster {
                    centre: Vec3::ZERO,
                    radius: 0.5,
                    lo: Vec3::splat(-0.3),
                    hi: Vec3::splat(0.3),
                    facing: Facing {
                        axis: Vec3::Z,
                        cos: -1.0,
                        low: 0.0,
                    },
                    area: 1.0,
                    area_vector: Vec3::ZERO,
                    samples: [Sample {
                        verts: [Vec3::ZERO; 3],
                        normal: Vec3::Z,
                        area: 0.0,
                        triangle: 0,
                    }; SAMPLES],
                }
            } else {
                Shape::Surface {
                    verts: rv,
                    normal: rn,
                    area: crate::geometry::triangle_area(&rv),
                    triangle: 0,
                }
            };
            let reach = r.radius() + 0.6;
            let d = reach * (1.1 + 20.0 * uniform(seed + 3).powi(2));
            let cs = unit(seed + 4) * d + r.centre();
            let a = unit(seed + 5) * (0.2 + 0.8 * uniform(seed + 6)) * 1.5;
            let s = if case % 3 == 0 {
                let sn = unit(seed + 7);
                let (t, b) = crate::geometry::orthonormal_basis(sn);
                let sv = [Vec3::ZERO, t * 0.5, b * 0.5].map(|v| v + cs - (t + b) * 0.5 / 3.0);
                Shape::Surface {
                    verts: sv,
                    normal: sn,
                    area: crate::geometry::triangle_area(&sv),
                    triangle: 1,
                }
            } else {
                Shape::Cluster {
                    centre: cs,
                    radius: 0.6,
                    lo: cs - Vec3::splat(0.3),
                    hi: cs + Vec3::splat(0.3),
                    facing: Facing {
                        axis: Vec3::Z,
                        cos: -1.0,
                        low: 0.0,
                    },
                    area: 1.5,
                    area_vector: a,
                    samples: [Sample {
                        verts: [cs; 3],
                        normal: Vec3::Z,
                        area: 0.0,
                        triangle: 1,
                    }; SAMPLES],
                }
            };
            let (cr, cs) = (r.centre(), s.centre());
            let k = ClusterKernel::new(&r, &s, (cs - cr).length(), (cs - cr).normalize());
            assert!(
                k.lo <= k.centre && k.centre <= k.hi,
                "case {case}: centre outside its range"
            );
            for j in 0..200u64 {
                let x = match &r {
                    Shape::Surface { verts, .. } => stratified_point(verts, 1, 0, hash(seed ^ j)),
                    Shape::Cluster { centre, radius, .. } => {
                        point_in_sphere(*centre, *radius, seed ^ j ^ 55)
                    }
                };
                let y = match &s {
                    Shape::Surface { verts, .. } => {
                        stratified_point(verts, 1, 0, hash(seed ^ j ^ 77))
                    }
                    Shape::Cluster { centre, radius, .. } => {
                        point_in_sphere(*centre, *radius, seed ^ j ^ 66)
                    }
                };
                let w = (y - x).normalize();
                let emitted = match &s {
                    Shape::Surface { normal, area, .. } => area * normal.dot(-w).max(0.0),
                    Shape::Cluster {
                        area, area_vector, ..
                    } => projected_area(*area, *area_vector, -w),
                } / PI;
                let received = match &r {
                    Shape::Surface { normal, .. } => normal.dot(w).max(0.0),
                    Shape::Cluster { .. } => 1.0,
                };
                let kernel = emitted * received / (y - x).length_squared();
                // f32 rounding of the range's own arithmetic: a few ulps.
                let slack = 1e-5 * k.hi.max(kernel);
                assert!(
                    k.lo - slack <= kernel && kernel <= k.hi + slack,
                    "case {case}, pair {j}: kernel {kernel} outside [{}, {}]",
                    k.lo,
                    k.hi
                );
            }
        }
    }

    /// The sampled transfer between overlapping ends is unbiased: over many draws of a
    /// cluster's sample patches (by area, as `clusters::draw_by_area` draws them), its mean
    /// at each quadrature point of a receiver standing on the cluster's floor matches the
    /// exact unoccluded sum of the point-to-polygon factors of all the cluster's triangles,
    /// within four standard errors of the mean. The triangles' areas differ by 40×, so
    /// the weights A_S / (n A_j) that undo the drawing by area matter.
    #[test]
    fn the_near_transfer_is_an_unbiased_estimate_of_the_exact_one() {
        use crate::solver::hierarchical::clusters::draw_by_area;
        // A floor of six triangles of very different sizes, facing up, and a receiver
        // standing on it, facing +x, inside the floor's bounding sphere.
        let floor: Vec<[Vec3; 3]> = vec![
            [
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
            [
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
            [
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.2, 0.0, 0.0),
                Vec3::new(1.0, 0.2, 0.0),
            ],
            [
                Vec3::new(1.0, 0.2, 0.0),
                Vec3::new(1.2, 0.0, 0.0),
                Vec3::new(1.2, 0.3, 0.0),
            ],
            [
                Vec3::new(1.0, 0.2, 0.0),
                Vec3::new(1.2, 0.3, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
            ],
            [
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(1.2, 0.3, 0.0),
                Vec3::new(1.3, 1.0, 0.0),
            ],
        ];
        let areas: Vec<f32> = floor.iter().map(crate::geometry::triangle_area).collect();
        let total: f32 = areas.iter().sum();
        let rv = [
            Vec3::new(0.5, 0.3, 0.0),
            Vec3::new(0.5, 0.7, 0.0),
            Vec3::new(0.5, 0.5, 0.4),
        ];
        let r = Shape::Surface {
            verts: rv,
            normal: Vec3::X,
            area: crate::geometry::triangle_area(&rv),
            triangle: floor.len() as u32,
        };
        let mut triangles = floor.clone();
        triangles.push(rv);
        let bvh = Bvh::build(&triangles, &[]);
        let exact = quadrature(&rv).map(|x| {
            floor
                .iter()
                .map(|t| front_form_factor(x, Vec3::X, t, Vec3::Z))
                .sum::<f32>()
        });
        let (mut sum, mut sum2) = ([0.0f64; 3], [0.0f64; 3]);
        let draws = 4_000u64;
        for d in 0..draws {
            let samples = draw_by_area(&areas, hash(d)).map(|i| Sample {
                verts: floor[i],
                normal: Vec3::Z,
                area: areas[i],
                triangle: i as u32,
            });
            let s = Shape::Cluster {
                centre: Vec3::new(0.65, 0.5, 0.0),
                radius: 0.85,
                lo: Vec3::ZERO,
                hi: Vec3::new(1.3, 1.0, 0.0),
                facing: Facing {
                    axis: Vec3::Z,
                    cos: 1.0,
                    low: 0.0,
                },
                area: total,
                area_vector: Vec3::Z * total,
                samples,
            };
            assert!(overlap(&r, &s));
            let t = near_transfer(&bvh, 1e-5, &r, &s, hash(d ^ 99));
            assert!(t.spread.is_infinite());
            for k in 0..3 {
                sum[k] += t.values[k] as f64;
                sum2[k] += (t.values[k] as f64).powi(2);
            }
        }
        for k in 0..3 {
            let n = draws as f64;
            let mean = sum[k] / n;
            let error = ((sum2[k] / n - mean * mean).max(0.0) / n).sqrt();
            assert!(
                (mean - exact[k] as f64).abs() <= 4.0 * error + 1e-6,
                "point {k}: sampled {mean} ± {error}, exact {}",
                exact[k]
            );
            assert!(exact[k] > 0.01, "the receiver sees the floor");
        }
    }

    /// Brute force: where a cone of normals says its surfaces see nothing of a box, no
    /// surface point p with a normal n inside the cone (at or above `low` along the axis)
    /// has any point x of the box in front of it, n · (x − p) ≤ tol; and two flat pieces
    /// of one wall are blind to each other, two walls meeting at a corner are not.
    #[test]
    fn a_blind_cone_sees_nothing_of_the_other_end() {
        let mut blind_cases = 0;
        for case in 0..2_000u64 {
            let axis = unit(case * 31 + 1);
            let cos = 1.0 - uniform(case * 31 + 2).powi(3) * 0.3;
            let low = uniform(case * 31 + 3) - 0.5;
            let facing = Facing { axis, cos, low };
            let ahead = low - 0.5 + uniform(case * 31 + 4) * 0.6;
            let reach = 0.5 + uniform(case * 31 + 5) * 2.0;
            if !facing.blind_to(ahead, reach, 0.0) {
                continue;
            }
            blind_cases += 1;
            for j in 0..100u64 {
                let k = case * 1_000 + j;
                // A normal inside the cone.
                let (t, b) = crate::geometry::orthonormal_basis(axis);
                let sin = (1.0 - cos * cos).sqrt() * uniform(k + 1);
                let phi = uniform(k + 2) * std::f32::consts::TAU;
                let n = (axis * (1.0 - sin * sin).sqrt() + (t * phi.cos() + b * phi.sin()) * sin)
                    .normalize();
                // p at or above `low`, x at or below `ahead`, within `reach` of each other.
                let p = axis * (low + uniform(k + 3) * 0.2)
                    + (t * (uniform(k + 4) - 0.5) + b * (uniform(k + 5) - 0.5)) * 0.5;
                let mut x = p + unit(k + 6) * reach * uniform(k + 7);
                let along = axis.dot(x);
                if along > ahead {
                    x -= axis * (along - ahead);
                }
                if (x - p).length() > reach {
                    continue;
                }
                assert!(
                    n.dot(x - p) <= 1e-5,
                    "case {case}: a surface point sees the box"
                );
            }
        }
        assert!(
            blind_cases > 100,
            "too few blind cases to test: {blind_cases}"
        );
        let square = |origin: Vec3, u: Vec3, v: Vec3| {
            let verts = [origin, origin + u, origin + v];
            let normal = u.cross(v).normalize();
            Shape::Surface {
                verts,
                normal,
                area: crate::geometry::triangle_area(&verts),
                triangle: 0,
            }
        };
        let floor_a = square(Vec3::ZERO, Vec3::X, Vec3::NEG_Z);
        let floor_b = square(Vec3::X, Vec3::X, Vec3::NEG_Z);
        let wall = square(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y);
        assert!(blind(&floor_a, &floor_b, 1e-6));
        assert!(!blind(&floor_a, &wall, 1e-6));
    }

    /// A receiver on the floor under a source whose three quadrature points are hidden by
    /// an opaque plate 1 cm above them. Where the plate leaves the receiver's corner
    /// (1, 0) open, the link is partial and its spread holds what that corner sees, its
    /// unoccluded form factor (Lambert's closed form, `point_to_polygon`): the plate
    /// stops 3 cm short of the corner, so no ray from it meets the plate. Where the plate
    /// covers the whole receiver, nothing is seen, and the spread is the largest
    /// unoccluded form factor at a point or corner: a lit part could lie between them.
    /// (A link its points saw nothing of had a spread of 1 whatever its source,
    /// and dropping it took the light of a corner the points could not see.)
    #[test]
    fn a_link_hidden_from_its_points_is_judged_by_what_its_corners_may_see() {
        let rv = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let sv = [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.7, 0.0, 1.0),
            Vec3::new(0.0, 0.7, 1.0),
        ];
        let (rn, sn) = (Vec3::Z, Vec3::NEG_Z);
        let plate = |hi: f32| {
            let (a, b) = (Vec3::new(-0.5, -0.5, 0.01), Vec3::new(hi, hi, 0.01));
            [
                [a, Vec3::new(b.x, a.y, 0.01), b],
                [a, b, Vec3::new(a.x, b.y, 0.01)],
            ]
        };
        let corner_factors = rv.map(|x| front_form_factor(x, rn, &sv, sn));
        let point_factors = quadrature(&rv).map(|x| front_form_factor(x, rn, &sv, sn));
        for (hi, open_corner) in [(0.7, true), (1.5, false)] {
            let [p, q] = plate(hi);
            let bvh = Bvh::build(&[rv, sv, p, q], &[]);
            let t = surface_to_surface(&bvh, 1e-5, (&rv, rn, 0), (&sv, sn, 1), (false, false), 7);
            assert_eq!(t.values, [0.0; 3], "the plate hides every quadrature point");
            if open_corner {
                assert!(t.partial);
                // The corner (1, 0) sees the whole source: 2 × 2 rays, all clear.
                assert!(
                    t.spread >= corner_factors[1] * 0.999,
                    "spread {} below the open corner's factor {}",
                    t.spread,
                    corner_factors[1]
                );
            } else {
                assert!(!t.partial);
                let bound = corner_factors
                    .into_iter()
                    .chain(point_factors)
                    .fold(0.0, f32::max);
                assert!(bound > 0.05);
                assert!(
                    (t.spread - bound).abs() <= 1e-6,
                    "spread {} against the largest unoccluded factor {bound}",
                    t.spread
                );
            }
        }
    }

    #[test]
    fn quadrature_points_lie_halfway_between_centroid_and_corners() {
        let v = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let c = (v[0] + v[1] + v[2]) / 3.0;
        for (k, q) in quadrature(&v).into_iter().enumerate() {
            assert!((q - (c + v[k]) * 0.5).length() < 1e-6);
        }
    }
}
