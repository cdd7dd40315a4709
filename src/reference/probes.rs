//! Probe points for measuring a solution against the truth where a person would look:
//! spread uniformly by area, close to edges and corners between faces, close to where
//! objects touch (contact lines), and in the penumbrae and umbrae of area lights. Each
//! point is classified by what is around it, not by how it was drawn, so a uniform point
//! that happens to sit in an umbra counts as umbra.

use super::Surfaces;
use crate::accel::Bvh;
use crate::geometry::orthonormal_basis;
use crate::geometry::sampling::{cosine_direction, hash, point_in_triangle, unit};
use crate::geometry::{closest_point_on_triangle, triangle_area};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// What is around a probe point.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Class {
    /// Away from edges, contacts and shadows.
    Interior,
    /// Within the near distance of another face of the same object (a corner of a room).
    Edge,
    /// Within the near distance of another object's face (the foot of a block).
    Contact,
    /// Some but not all of the area lights' shadow rays blocked.
    Penumbra,
    /// Every area light blocked (while facing the point).
    Umbra,
    /// Away from the area lights' shadows, yet every path-traced sample left it black:
    /// no light reaches it (a space sealed off from the sky and the lights, such as the
    /// insides of Sponza's walls), so whatever light a solution gives it leaked in. Set by
    /// the reference, not by [`pick`].
    Dark,
}

impl Class {
    pub const ALL: [Class; 6] = [
        Class::Interior,
        Class::Edge,
        Class::Contact,
        Class::Penumbra,
        Class::Umbra,
        Class::Dark,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Class::Interior => "interior",
            Class::Edge => "edge",
            Class::Contact => "contact",
            Class::Penumbra => "penumbra",
            Class::Umbra => "umbra",
            Class::Dark => "dark",
        }
    }
}

/// The class of a probe of class `drawn` once the reference has estimated it: [`Class::Dark`]
/// where every sample was black away from the shadows of area lights (`samples` > 0; the
/// reference samples a black point until a hit would have shown, see `reference`).
pub fn with_reference(drawn: Class, value: DVec3, samples: u64) -> Class {
    let shadow = matches!(drawn, Class::Penumbra | Class::Umbra);
    if !shadow && samples > 0 && value == DVec3::ZERO {
        Class::Dark
    } else {
        drawn
    }
}

/// A probe: a world point on a surface, the outward normal of its side, its class.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Probe {
    pub point: DVec3,
    pub normal: DVec3,
    pub class: Class,
}

/// How many probes of each kind to look for.
#[derive(Clone, Copy, Debug)]
pub struct ProbeCounts {
    pub uniform: usize,
    pub near_edges: usize,
    pub penumbra: usize,
    pub umbra: usize,
}

impl Default for ProbeCounts {
    fn default() -> Self {
        ProbeCounts {
            uniform: 120,
            near_edges: 80,
            penumbra: 50,
            umbra: 50,
        }
    }
}

/// How the probes are drawn, for keys of cached references: a change here must change it.
pub const SCHEME: &str = "uniform by area; edges by length, half contacts, covered and hidden points left out; shadows of area lights by area; black in the reference, the rule of three met: dark";

/// Shadow rays per probe for its shadow class, to points spread over the emitters.
const SHADOW_RAYS: u32 = 64;

/// Rays per candidate point that look for a way out (see [`hidden`]).
const HIDDEN_RAYS: u32 = 64;

/// The near distance: 1 cm, or 1 % of the scene's size for scenes under a metre.
fn near_distance(s: &Surfaces) -> f32 {
    0.01f32.min(s.frame.scale * 0.01)
}

/// Probes for `surfaces` (seeded by `seed`): `counts.uniform` by area; `counts.near_edges`
/// at 0.1 mm to 1 cm (log-uniform) inside a triangle edge that another face is near (half
/// of them near another object's face, contacts, where the scene has enough);
/// penumbra and umbra points drawn by area until their counts are met (or a budget of
/// candidates is spent: a scene may have none). Only reflective sides are probed.
pub fn pick(s: &Surfaces, bvh: &Bvh, counts: &ProbeCounts, seed: u64) -> Vec<Probe> {
    let receivers: Vec<u32> = (0..s.triangles.len() as u32)
        .filter(|&t| s.area[t as usize] > 0.0 && s.reflectance[t as usize].max_element() > 0.0)
        .collect();
    if receivers.is_empty() {
        return Vec::new();
    }
    let mut cdf = Vec::with_capacity(receivers.len());
    let mut total = 0.0f64;
    for &t in &receivers {
        total += s.area[t as usize] as f64;
        cdf.push(total);
    }
    let by_area = |h: u64| {
        let x = unit(h) as f64 * total;
        receivers[cdf.partition_point(|c| *c <= x).min(receivers.len() - 1)]
    };
    let near = near_distance(s);
    let classify = |t: u32, p: Vec3, h: u64| classify(s, bvh, t, p, near, h);
    let mut out = Vec::new();
    // Uniform by area.
    let uniform: Vec<Probe> = (0..counts.uniform as u64)
        .into_par_iter()
        .filter_map(|k| {
            let h = hash(seed ^ hash(k));
            let t = by_area(h);
            let p = point_in_triangle(
                &s.triangles[t as usize],
                unit(hash(h ^ 1)),
                unit(hash(h ^ 2)),
            );
            classify(t, p, h)
        })
        .collect();
    out.extend(uniform);
    // Near edges: a point on a triangle edge (uniform by length over every edge, so the
    // small faces of objects standing on others get their share), moved inwards by
    // 0.1 mm..1 cm.
    let mut edge_cdf = Vec::with_capacity(receivers.len() * 3);
    let mut perimeter = 0.0f64;
    for &t in &receivers {
        let v = s.triangles[t as usize];
        for e in 0..3 {
            perimeter += (v[(e + 1) % 3] - v[e]).length() as f64;
            edge_cdf.push(perimeter);
        }
    }
    let candidates = counts.near_edges as u64 * 40;
    let edges: Vec<Probe> = (0..candidates)
        .into_par_iter()
        .filter_map(|k| {
            let h = hash(seed ^ 0xED6E ^ hash(k));
            let x = unit(h) as f64 * perimeter;
            let j = edge_cdf
                .partition_point(|c| *c <= x)
                .min(edge_cdf.len() - 1);
            let (t, e) = (receivers[j / 3], j % 3);
            let v = s.triangles[t as usize];
            let (a, b, c) = (v[e], v[(e + 1) % 3], v[(e + 2) % 3]);
            let on_edge = a + (b - a) * unit(hash(h ^ 4));
            let d = near * 10f32.powf(-2.0 * unit(hash(h ^ 5)));
            // Inwards: towards the opposite corner, perpendicular to the edge.
            let along = (b - a).normalize_or_zero();
            let inward = ((c - a) - along * along.dot(c - a)).normalize_or_zero();
            let p = on_edge + inward * d;
            let (q, _) = closest_point_on_triangle(p, &v);
            if (q - p).length() > d * 1e-3 {
                return None; // the triangle is narrower than d there
            }
            let probe = classify(t, q, h)?;
            matches!(probe.class, Class::Edge | Class::Contact).then_some(probe)
        })
        .collect();
    // Half contacts and half edges where there are enough of each.
    let contacts = edges.iter().filter(|p| p.class == Class::Contact).count();
    let want_contacts = contacts.min(counts.near_edges / 2);
    let want_edges = counts.near_edges - want_contacts;
    let (mut taken_contacts, mut taken_edges) = (0, 0);
    for p in edges {
        let take = match p.class {
            Class::Contact => (taken_contacts < want_contacts).then(|| taken_contacts += 1),
            _ => (taken_edges < want_edges).then(|| taken_edges += 1),
        };
        if take.is_some() {
            out.push(p);
        }
    }
    // Shadows of area lights: candidates by area, kept by class.
    if s.has_emitters() {
        let candidates = ((counts.penumbra + counts.umbra) as u64 * 40).max(1000);
        let shadowed: Vec<Probe> = (0..candidates)
            .into_par_iter()
            .filter_map(|k| {
                let h = hash(seed ^ 0x5AAD ^ hash(k));
                let t = by_area(h);
                let p = point_in_triangle(
                    &s.triangles[t as usize],
                    unit(hash(h ^ 1)),
                    unit(hash(h ^ 2)),
                );
                let probe = classify(t, p, h)?;
                matches!(probe.class, Class::Penumbra | Class::Umbra).then_some(probe)
            })
            .collect();
        let mut penumbra = 0;
        let mut umbra = 0;
        for p in shadowed {
            let keep = match p.class {
                Class::Penumbra => (penumbra < counts.penumbra).then(|| penumbra += 1),
                _ => (umbra < counts.umbra).then(|| umbra += 1),
            };
            if keep.is_some() {
                out.push(p);
            }
        }
    }
    out
}

/// Whether point `p` on the front of triangle `t` is hidden: each of [`HIDDEN_RAYS`]
/// cosine-distributed rays from it meets the back of a single-sided, opaque surface first
/// (the inside of a closed object whose faces point outwards, the floor under a block
/// without a bottom face). Then no light reaches it and no one can see it: its truth is 0
/// by construction, and a solution's light there measures only how much leaks into the
/// object, not what anyone would see (10 of Sponza's first 198 points; the 4 under the
/// Cornell box's blocks).
fn hidden(s: &Surfaces, bvh: &Bvh, t: u32, p: Vec3, h: u64) -> bool {
    let n = s.normal[t as usize];
    let basis = orthonormal_basis(n);
    let from = p + n * s.frame.epsilon();
    (0..HIDDEN_RAYS).all(|k| {
        let hk = hash(h ^ 0x41DE ^ k as u64);
        let d = cosine_direction(n, basis, unit(hk), unit(hash(hk ^ 1)));
        bvh.closest_hit(from, d, 0.0, f32::INFINITY, t)
            .is_some_and(|hit| {
                let j = hit.triangle as usize;
                s.normal[j].dot(d) >= 0.0
                    && !s.double_sided[j]
                    && s.transmittance.get(j).is_none_or(|&tau| tau <= 0.0)
            })
    })
}

/// The class of point `p` on triangle `t`: contact or edge when another object's or the
/// same object's face (not coplanar) is within `near`, else umbra or penumbra by the area
/// lights' visibility, else interior. `None` for a hidden point ([`hidden`]) and for a
/// covered one: a face pressed against it, parallel to it within `near` / 20 (a lamp flush
/// under a ceiling, a box's base on a floor), where nobody can look.
fn classify(s: &Surfaces, bvh: &Bvh, t: u32, p: Vec3, near: f32, h: u64) -> Option<Probe> {
    let n = s.normal[t as usize];
    let point = s.frame.origin + p.as_dvec3();
    let probe = |class| {
        Some(Probe {
            point,
            normal: n.as_dvec3(),
            class,
        })
    };
    if hidden(s, bvh, t, p, h) {
        return None;
    }
    // The nearest other face in front of the point (within `near`).
    let mut nearest: Option<(f32, u32)> = None;
    for (j, tri) in s.triangles.iter().enumerate() {
        if j as u32 == t || s.area[j] <= 0.0 || triangle_area(tri) <= 0.0 {
            continue;
        }
        if s.normal[j].dot(n) > 0.999 && (tri[0] - p).dot(n).abs() < near * 1e-3 {
            continue; // coplanar: the same surface
        }
        let (q, _) = closest_point_on_triangle(p, tri);
        let d = (q - p).length();
        if d <= near && (q - p).dot(n) >= -near * 1e-3 && nearest.is_none_or(|(bd, _)| d < bd) {
            nearest = Some((d, j as u32));
        }
    }
    if let Some((d, j)) = nearest {
        if d <= near / 20.0 && s.normal[j as usize].dot(n).abs() > 0.999 {
            return None;
        }
        let class = if s.object[j as usize] == s.object[t as usize] {
            Class::Edge
        } else {
            Class::Contact
        };
        return probe(class);
    }
    if !s.has_emitters() {
        return probe(Class::Interior);
    }
    let eps = s.frame.epsilon();
    let (mut facing, mut seen) = (0u32, 0u32);
    for k in 0..SHADOW_RAYS {
        let hk = hash(h ^ 0x5EED ^ k as u64);
        let Some(e) = s.sample_emitter(
            (k as f32 + unit(hk)) / SHADOW_RAYS as f32,
            unit(hash(hk ^ 1)),
            unit(hash(hk ^ 2)),
        ) else {
            break;
        };
        let w = e.point - p;
        let ne = s.normal[e.triangle as usize];
        let emits_towards = ne.dot(w) < 0.0 || s.double_sided[e.triangle as usize];
        if n.dot(w) <= 0.0 || !emits_towards {
            continue;
        }
        facing += 1;
        let side = if ne.dot(w) < 0.0 { ne } else { -ne };
        if bvh.transmittance(p + n * eps, e.point + side * eps, [t, e.triangle]) > 0.5 {
            seen += 1;
        }
    }
    let class = match (facing, seen) {
        (0, _) => Class::Interior,
        (f, 0) if f > 0 => Class::Umbra,
        (f, v) if v < f => Class::Penumbra,
        _ => Class::Interior,
    };
    probe(class)
}
