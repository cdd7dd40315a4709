//! The display mesh: element corners welded into shared vertices on smooth surfaces, and
//! reconstruction of a continuous radiosity from per-element values.
//!
//! Vertices are shared between elements of the same patch side and material whose normals
//! differ by less than [`SMOOTH_ANGLE_DEG`], so Gouraud shading (area-weighted vertex
//! averages, Cohen & Wallace, "Radiosity and Realistic Image Synthesis" §9.2) blends across
//! a smooth surface but never across a crease or a material boundary.

use super::{Element, Hanging, Patch};
use crate::geometry::orthonormal_basis;
use crate::geometry::sampling::FastMap;
use glam::Vec3;
use std::collections::hash_map::Entry;

/// Rec. 709 luminance: the brightness that vertex values are fitted in (see
/// `DisplayMesh::fit`), also what adaptive subdivision and auto exposure compare.
pub fn luminance(v: Vec3) -> f32 {
    v.dot(LUMINANCE)
}

const LUMINANCE: Vec3 = Vec3::new(0.2126, 0.7152, 0.0722);

/// Normals within this angle are one smooth surface (the usual 30° crease angle of
/// modelling tools).
pub const SMOOTH_ANGLE_DEG: f32 = 30.0;

/// How a continuous radiosity is reconstructed from element values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Reconstruction {
    /// Each element's value, constant over it.
    Flat,
    /// Linear interpolation of area-weighted vertex averages.
    #[default]
    Gouraud,
    /// A cubic Bézier triangle per element through the vertex values, with tangents from
    /// vertex gradients fitted to the neighbouring elements (see [`Hermite`]): no kinks at
    /// vertices, so no Mach bands along the element edges of smooth light.
    Hermite,
}

impl std::str::FromStr for Reconstruction {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "flat" => Ok(Reconstruction::Flat),
            "gouraud" => Ok(Reconstruction::Gouraud),
            "hermite" => Ok(Reconstruction::Hermite),
            _ => Err(format!(
                "unknown reconstruction '{s}' (expected flat, gouraud or hermite)"
            )),
        }
    }
}

/// Shared vertices of the elements, in the mesh frame.
#[derive(Clone, Debug, Default)]
pub struct DisplayMesh {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    /// T-vertices (see `hanging`): a vertex inside the edge of a coarser element that does
    /// not use it, at the edge's midpoint where subdivision left it, anywhere where the
    /// input did. Its value is taken from that edge, so the shading has no crack there.
    /// Ordered coarse edges first, so chains of T-vertices resolve in one pass.
    pub hanging: Vec<Hanging>,
    /// Which side of hard shadow edges vertices and elements are on (set by
    /// `solver::mark_hard_shadows`; `None`: no hard shadow edges).
    pub shadow_sides: Option<ShadowSides>,
}

/// Sides of hard shadow edges: the shadows of point, spot and directional lights and the
/// sun, across which the light jumps. A vertex of an element such an edge crosses takes
/// the area-weighted mean of the elements around it that see the same lights as it does,
/// and no slope: vertex values do not average the two sides, so the reconstruction goes
/// from one side's light to the other's within the crossed elements (no blur beyond them),
/// and no slope is fitted across the jump (Hermite would ring beside the shadow).
#[derive(Clone, Debug, Default)]
pub struct ShadowSides {
    /// Per display vertex on a crossed element: which sources it sees (a bit per source),
    /// if some element around it sees the same; `None` elsewhere.
    pub vertex: Vec<Option<u64>>,
    /// Per element: which sources its centroid sees (0 where no corner is on an edge).
    pub element: Vec<u64>,
}

impl DisplayMesh {
    /// Welds the corners of `elements` into shared vertices and records them in
    /// `Element::corners`. Positions closer than `scale × 1e-6` are the same point; points
    /// on a contact line (`cut_edges`, the ranges in `Patch::cuts`) are shared only by
    /// patches of the same region, so the light may jump across the line.
    pub fn build(
        elements: &mut [Element],
        patches: &[Patch],
        cut_edges: &[[Vec3; 2]],
        scale: f32,
    ) -> DisplayMesh {
        let cos_smooth = SMOOTH_ANGLE_DEG.to_radians().cos();
        let quantum = (scale * 1e-6).max(f32::MIN_POSITIVE);
        let on_line = (scale * 1e-5).max(f32::MIN_POSITIVE);
        let mut mesh = DisplayMesh::default();
        // Key: quantised position, material, side, region on a contact line (else MAX)
        // → candidate vertices. A point is on a contact line when it lies on any contact
        // segment of its triangle (a piece may touch the line at only one corner).
        let key = |p: Vec3, patch: &Patch| {
            let q = (p / quantum).round();
            let on_cut = patch.cuts.clone().any(|c| {
                let [a, b] = cut_edges[c as usize];
                let ab = b - a;
                let t =
                    ((p - a).dot(ab) / ab.length_squared().max(f32::MIN_POSITIVE)).clamp(0.0, 1.0);
                (a + ab * t - p).length() <= on_line
            });
            (
                [q.x as i64, q.y as i64, q.z as i64],
                patch.material,
                patch.back,
                if on_cut { patch.region } else { u32::MAX },
            )
        };
        // Key → the first vertex made for it. Other vertices of the same key (other
        // normals) follow it in a chain through `next`, in the order they were made.
        let mut welded: FastMap<([i64; 3], u32, bool, u32), u32> =
            FastMap::with_capacity_and_hasher(elements.len(), Default::default());
        let mut next: Vec<u32> = Vec::with_capacity(elements.len());
        let mut keys = Vec::with_capacity(elements.len());
        for e in elements.iter_mut() {
            let patch = &patches[e.patch as usize];
            for k in 0..3 {
                let p = e.verts[k];
                let key = key(p, patch);
                let new = mesh.positions.len() as u32;
                let found = match welded.entry(key) {
                    Entry::Vacant(slot) => {
                        slot.insert(new);
                        None
                    }
                    Entry::Occupied(slot) => {
                        let mut v = *slot.get();
                        loop {
                            if mesh.normals[v as usize].dot(e.normal) >= cos_smooth {
                                break Some(v);
                            }
                            match next[v as usize] {
                                u32::MAX => {
                                    next[v as usize] = new;
                                    break None;
                                }
                                w => v = w,
                            }
                        }
                    }
                };
                e.corners[k] = found.unwrap_or_else(|| {
                    mesh.positions.push(p);
                    mesh.normals.push(e.normal);
                    keys.push(key);
                    next.push(u32::MAX);
                    new
                });
            }
        }
        // T-vertices: a vertex inside an element's edge that the element would have
        // welded had it been its corner (same surface, same side of a contact line).
        let same_surface = |v: u32, e: &Element| {
            let v = v as usize;
            mesh.normals[v].dot(e.normal) >= cos_smooth
                && key(mesh.positions[v], &patches[e.patch as usize]) == keys[v]
        };
        mesh.hanging = super::hanging::find(elements, &mesh.positions, on_line, same_surface);
        mesh
    }

    /// Gouraud vertex values: for each vertex the value at the vertex of the least-squares
    /// plane through the values of the elements that use it (see `fit`); T-vertices take
    /// their coarse edge's value at their parameter on it.
    pub fn vertex_values(&self, elements: &[Element], values: &[Vec3]) -> Vec<Vec3> {
        self.gouraud(self.fit(elements, values).values)
    }

    /// Both smooth reconstructions' vertex data from one fit: the Gouraud vertex values
    /// ([`DisplayMesh::vertex_values`]) and the Hermite data ([`DisplayMesh::hermite`]),
    /// what the viewer's snapshots carry.
    pub fn smooth_values(&self, elements: &[Element], values: &[Vec3]) -> (Vec<Vec3>, Hermite) {
        let fit = self.fit(elements, values);
        let gouraud = self.gouraud(fit.values.clone());
        (gouraud, self.hermite_from(elements, fit))
    }

    /// The fit's values with each T-vertex on its coarse edge's line.
    fn gouraud(&self, mut values: Vec<Vec3>) -> Vec<Vec3> {
        self.resolve_hanging(|h| {
            let [a, b] = h.edge.map(|i| values[i as usize]);
            let value = a + (b - a) * h.t;
            let change = (value - values[h.vertex as usize]).abs().max_element();
            values[h.vertex as usize] = value;
            (change, value.abs().max_element())
        });
        values
    }

    /// Per display vertex, whether it is a T-vertex.
    fn hanging_flags(&self) -> Vec<bool> {
        let mut is_hanging = vec![false; self.positions.len()];
        for h in &self.hanging {
            is_hanging[h.vertex as usize] = true;
        }
        is_hanging
    }

    /// Sets every T-vertex from its edge with `set(hanging)`, which returns how much the
    /// vertex changed and its size; passes in coarse-edge order until no vertex changes by
    /// more than 10⁻⁶ of the largest (at most 64). One pass is exact unless T-vertices
    /// hang on each other, which they do where two elements' edges overlap along a line
    /// from opposite sides, each with a corner inside the other's edge (an input's
    /// T-junctions): then the passes are a fixed-point iteration that converges, each
    /// vertex's dependence on itself through the other being a product of parameters
    /// below 1, slowly where that product is near 1 (on Sponza, all 64 passes). Passes
    /// after the first go only through the T-vertices with a T-vertex at an end of their
    /// edge: the others are set for good by the first.
    fn resolve_hanging(&self, mut set: impl FnMut(&Hanging) -> (f32, f32)) {
        let is_hanging = self.hanging_flags();
        let depends = |h: &&Hanging| h.edge.iter().any(|&v| is_hanging[v as usize]);
        let dependent: Vec<&Hanging> = self.hanging.iter().filter(depends).collect();
        // The largest size among the T-vertices set for good.
        let mut settled = 0.0f32;
        for h in &self.hanging {
            let (_, s) = set(h);
            if !depends(&h) {
                settled = settled.max(s);
            }
        }
        for _ in 1..64 {
            let (mut change, mut size) = (0.0f32, settled);
            for h in &dependent {
                let (c, s) = set(h);
                change = change.max(c);
                size = size.max(s);
            }
            if change <= 1e-6 * size {
                break;
            }
        }
    }

    /// The reconstructed value at barycentric point `bary` of element `e`, given element
    /// values and (for Gouraud) the vertex values from [`DisplayMesh::vertex_values`].
    pub fn value_at(
        mode: Reconstruction,
        elements: &[Element],
        element_values: &[Vec3],
        vertex_values: &[Vec3],
        e: u32,
        bary: [f32; 3],
    ) -> Vec3 {
        match mode {
            Reconstruction::Flat => element_values[e as usize],
            // Hermite needs gradients: use `Reconstructor`. Here it falls back to Gouraud.
            Reconstruction::Gouraud | Reconstruction::Hermite => {
                let c = elements[e as usize].corners;
                vertex_values[c[0] as usize] * bary[0]
                    + vertex_values[c[1] as usize] * bary[1]
                    + vertex_values[c[2] as usize] * bary[2]
            }
        }
    }
}

/// What `DisplayMesh::fit` finds per display vertex: the value, the gradient of each RGB
/// channel in the surface's tangent plane (all three along the luminance's), and the range
/// (least, greatest) of the values of the elements around it.
struct Fit {
    values: Vec<Vec3>,
    gradients: Vec<[Vec3; 3]>,
    range: Vec<(Vec3, Vec3)>,
}

/// Data for [`Reconstruction::Hermite`]: per display vertex a value and the gradient of
/// each RGB channel in the surface's tangent plane.
///
/// Each element is a Clough–Tocher macro-element (Farin, "Triangular Bernstein–Bézier
/// patches", CAGD 3, 1986, §4): split at its centroid into three cubic Bézier triangles,
/// 19 control points in all. Corner points are the vertex values; the two edge points
/// next to a corner are the value plus a third of the gradient along the edge, so along
/// each edge the surface is the cubic Hermite curve of the end values and end slopes, the
/// same from both sides (C⁰). The derivative across each edge (along its normal in the
/// element's plane) is made linear along the edge, between the end gradients' values, so
/// both elements sharing an edge have the same cross-edge slope: C¹ across edges where
/// they share their vertices (a smooth surface), not only at vertices. The inner points
/// follow from C¹ between the three sub-triangles, the three of them next to the edges
/// held within the edges' control points (no new extremum inside an element; a sliver's
/// would otherwise swing far, see `bezier`). Linear light of one colour is reproduced
/// exactly. The vertex gradient is the luminance's least-squares plane through
/// the centroids' values of the elements around it, weighted by area, times the vertex's
/// chromaticity (see `DisplayMesh::fit`). T-vertices take the
/// coarse edge's cubic (value and slope along the edge at their parameter on it) and its
/// ends' cross-edge slopes interpolated linearly, so refinement leaves no crack, and no
/// crease except where that cross-edge slope is held to the limiter's bounds (see
/// `hermite_from`). Across a contact line vertices are not shared, and the surface jumps.
#[derive(Clone, Debug, Default)]
pub struct Hermite {
    pub values: Vec<Vec3>,
    pub gradients: Vec<[Vec3; 3]>,
}

/// Flat, Gouraud or Hermite reconstruction of one set of element values, ready to
/// evaluate anywhere on the mesh.
pub struct Reconstructor {
    mode: Reconstruction,
    vertex: Vec<Vec3>,
    hermite: Hermite,
}

impl Reconstructor {
    pub fn new(
        mode: Reconstruction,
        mesh: &DisplayMesh,
        elements: &[Element],
        values: &[Vec3],
    ) -> Reconstructor {
        let (vertex, hermite) = match mode {
            Reconstruction::Flat => (Vec::new(), Hermite::default()),
            Reconstruction::Gouraud => (mesh.vertex_values(elements, values), Hermite::default()),
            Reconstruction::Hermite => (Vec::new(), mesh.hermite(elements, values)),
        };
        Reconstructor {
            mode,
            vertex,
            hermite,
        }
    }

    /// The value at barycentric point `bary` of element `e`.
    pub fn at(&self, elements: &[Element], values: &[Vec3], e: u32, bary: [f32; 3]) -> Vec3 {
        match self.mode {
            Reconstruction::Flat | Reconstruction::Gouraud => {
                DisplayMesh::value_at(self.mode, elements, values, &self.vertex, e, bary)
            }
            Reconstruction::Hermite => {
                let b = DisplayMesh::bezier(elements, &self.hermite, e);
                eval_bezier(&b, bary)
            }
        }
    }
}

/// The 19 control points of a Clough–Tocher macro-element over corners 1, 2, 3 (our 0,
/// 1, 2) and the centroid 4, named by their powers of the four (extended) barycentrics:
/// c3000, c0300, c0030, c2100, c2010, c1200, c0210, c1020, c0120, c2001, c0201, c0021,
/// c1101, c1011, c0111, c1002, c0102, c0012, c0003.
pub type Bezier = [Vec3; 19];

/// Evaluates a Clough–Tocher element at barycentric `bary` (of its corners): with
/// m = min(bary), the point has extended barycentrics (b − m, 3m) in the sub-triangle
/// opposite the corner with the smallest coordinate, where the cubic is a sum over the
/// control points of that sub-triangle (the terms of the other two vanish).
pub fn eval_bezier(c: &Bezier, bary: [f32; 3]) -> Vec3 {
    let m = bary[0].min(bary[1]).min(bary[2]);
    let (b1, b2, b3, b4) = (bary[0] - m, bary[1] - m, bary[2] - m, 3.0 * m);
    c[0] * (b1 * b1 * b1)
        + c[1] * (b2 * b2 * b2)
        + c[2] * (b3 * b3 * b3)
        + c[3] * (3.0 * b1 * b1 * b2)
        + c[4] * (3.0 * b1 * b1 * b3)
        + c[5] * (3.0 * b1 * b2 * b2)
        + c[6] * (3.0 * b2 * b2 * b3)
        + c[7] * (3.0 * b1 * b3 * b3)
        + c[8] * (3.0 * b2 * b3 * b3)
        + c[9] * (3.0 * b1 * b1 * b4)
        + c[10] * (3.0 * b2 * b2 * b4)
        + c[11] * (3.0 * b3 * b3 * b4)
        + c[12] * (6.0 * b1 * b2 * b4)
        + c[13] * (6.0 * b1 * b3 * b4)
        + c[14] * (6.0 * b2 * b3 * b4)
        + c[15] * (3.0 * b1 * b4 * b4)
        + c[16] * (3.0 * b2 * b4 * b4)
        + c[17] * (3.0 * b3 * b4 * b4)
        + c[18] * (b4 * b4 * b4)
}

/// The slope across a T-vertex's coarse edge, per channel, that keeps its cubics within
/// `bounds` (each: the value without it, its rate of change with the slope, least and
/// greatest value): `preferred` where it meets every bound, else the nearest that does;
/// where they conflict, whichever of `preferred` and the two conflicting bounds' slopes
/// oversteps the bounds least.
fn slope_within(bounds: &[(Vec3, f32, Vec3, Vec3)], preferred: Vec3) -> Vec3 {
    Vec3::from_array(std::array::from_fn(|ch| {
        let (mut least, mut most) = (f32::NEG_INFINITY, f32::INFINITY);
        for &(base, rate, lo, hi) in bounds {
            if rate != 0.0 {
                let (x, y) = ((lo[ch] - base[ch]) / rate, (hi[ch] - base[ch]) / rate);
                least = least.max(x.min(y));
                most = most.min(x.max(y));
            }
        }
        if least <= most {
            return preferred[ch].clamp(least, most);
        }
        let overstep = |n: f32| {
            bounds.iter().fold(0.0f32, |worst, &(base, rate, lo, hi)| {
                let value = base[ch] + rate * n;
                worst.max(lo[ch] - value).max(value - hi[ch])
            })
        };
        [least, most].into_iter().fold(preferred[ch], |best, n| {
            if overstep(n) < overstep(best) {
                n
            } else {
                best
            }
        })
    }))
}

/// The least-squares plane through values at the centroids of the elements around a
/// vertex, weighted by area, evaluated at the vertex: from the weighted moments of the
/// centroids' offsets (d1, d2) from the vertex in its tangent plane, `[Σw, Σw·d1, Σw·d2,
/// Σw·d1², Σw·d1·d2, Σw·d2²]`.
///
/// In the principal axes of the centroids' spread about their mean the normal equations
/// decouple: the slope along axis i is cov(f, x_i)/λ_i, and the value at the vertex is the
/// mean plus each slope times the vertex's offset d_i from the mean along its axis. An
/// axis along which the vertex lies more than [`PlaneFit::MAX_LEVERAGE`]^½ standard
/// deviations of the centroids' spread away (d_i² > 16 λ_i) gets no slope: there the fit
/// extrapolates its data's noise that many times over. Slivers along an edge have
/// centroids almost on a line, and the plane across that line then swings with any
/// difference between them (on Sponza's roof, three elements lit 0.20–0.42 W/m² put the
/// vertex's plane at −0.34, shown as 0 where the truth is 0.46; d_i²/λ_i = 142 there, 47
/// at another, against 7.6 for the outer axis at a boundary vertex of a regular grid of
/// right triangles). Linear light is still reproduced wherever the kept axes span the
/// plane; with no axis kept, the weighted mean.
struct PlaneFit {
    /// The weights' sum.
    weight: f64,
    /// The centroids' weighted mean offset from the vertex.
    mean: [f64; 2],
    /// The principal axes that keep their slope.
    axes: [Option<Axis>; 2],
}

/// A principal axis of the centroids' spread (see [`PlaneFit`]).
#[derive(Clone, Copy)]
struct Axis {
    /// Unit direction in the tangent plane.
    direction: [f64; 2],
    /// The centroids' weighted variance along it, λ.
    variance: f64,
    /// The vertex's offset from the centroids' mean along it, d.
    offset: f64,
}

impl PlaneFit {
    /// The most d_i²/λ_i an axis may have and keep its slope (see [`PlaneFit`]): about
    /// twice a regular grid's boundary vertex (7.6).
    const MAX_LEVERAGE: f64 = 16.0;

    fn new([s00, s01, s02, s11, s12, s22]: [f64; 6]) -> Option<PlaneFit> {
        if s00.is_nan() || s00 <= 0.0 {
            return None;
        }
        let mean = [s01 / s00, s02 / s00];
        let (a, b, c) = (
            s11 / s00 - mean[0] * mean[0],
            s12 / s00 - mean[0] * mean[1],
            s22 / s00 - mean[1] * mean[1],
        );
        // Eigenvalues of [[a, b], [b, c]], largest first, and their unit eigenvectors.
        let half = 0.5 * (a - c);
        let root = (half * half + b * b).sqrt();
        let lambdas = [0.5 * (a + c) + root, 0.5 * (a + c) - root];
        // Of the two forms of the first eigenvector, the one away from zero.
        let v = if root == 0.0 {
            [1.0, 0.0]
        } else if half >= 0.0 {
            [half + root, b]
        } else {
            [b, root - half]
        };
        let n = (v[0] * v[0] + v[1] * v[1]).sqrt();
        let first = [v[0] / n, v[1] / n];
        let directions = [first, [-first[1], first[0]]];
        // Below this a variance is rounding (the offsets are f32).
        let floor = 1e-10 * lambdas[0].max(0.0);
        let axes = std::array::from_fn(|i| {
            let (direction, variance) = (directions[i], lambdas[i]);
            let offset = -(direction[0] * mean[0] + direction[1] * mean[1]);
            (variance > floor && offset * offset <= Self::MAX_LEVERAGE * variance).then_some(Axis {
                direction,
                variance,
                offset,
            })
        });
        Some(PlaneFit {
            weight: s00,
            mean,
            axes,
        })
    }

    /// The plane's value at the vertex and its slopes along the tangent axes, from the
    /// weighted sums of the values `[Σw·f, Σw·f·d1, Σw·f·d2]`.
    fn at_vertex(&self, [r0, r1, r2]: [f64; 3]) -> [f64; 3] {
        let f = r0 / self.weight;
        let cov = [
            r1 / self.weight - f * self.mean[0],
            r2 / self.weight - f * self.mean[1],
        ];
        let mut out = [f, 0.0, 0.0];
        for axis in self.axes.iter().flatten() {
            let e = axis.direction;
            let slope = (e[0] * cov[0] + e[1] * cov[1]) / axis.variance;
            out[0] += slope * axis.offset;
            out[1] += slope * e[0];
            out[2] += slope * e[1];
        }
        out
    }
}

fn along(g: &[Vec3; 3], d: Vec3) -> Vec3 {
    Vec3::new(g[0].dot(d), g[1].dot(d), g[2].dot(d))
}

impl DisplayMesh {
    /// Per vertex, the area-weighted least-squares plane through the luminance at the
    /// centroids of the elements around it, and the chromaticity (value over luminance)
    /// of the channels' planes there. The vertex's value is the luminance plane's value
    /// (within the luminances around the vertex widened by their spread, and at least 0)
    /// times that chromaticity, drawn towards the mean's until it is within the
    /// chromaticities of the elements around it widened by their spread; each channel's
    /// gradient is the luminance's times the chromaticity. Unlike the plain area-weighted
    /// mean, this is exact for linear light (the slopes for light of one colour, the
    /// values also where the colour varies within that range) and extrapolates at a
    /// surface's boundary instead of flattening it. Fitted channel by
    /// channel, a small channel's plane could reach 0 at a boundary where the others stay
    /// lit: under Sponza's cornice blue did, and the wall showed yellow there. Along a
    /// direction in which the elements' centroids barely spread, seen from the vertex, no
    /// slope ([`PlaneFit`]); where they spread in neither, the mean. On a
    /// hard shadow edge, the mean of the elements on the vertex's side and no slope (see
    /// [`ShadowSides`]). The range of the values around each vertex comes with them.
    fn fit(&self, elements: &[Element], values: &[Vec3]) -> Fit {
        let nv = self.positions.len();
        // Fallback values: area-weighted means (where the plane fit is not determined);
        // the range of the values around each vertex, of their luminances and of the
        // chromaticities of those that are lit.
        let mut sum = vec![Vec3::ZERO; nv];
        let mut weight = vec![0.0f32; nv];
        let mut range = vec![(Vec3::INFINITY, Vec3::NEG_INFINITY); nv];
        let mut bright = vec![(f32::INFINITY, f32::NEG_INFINITY); nv];
        let mut colour = vec![(Vec3::INFINITY, Vec3::NEG_INFINITY); nv];
        for (i, (e, v)) in elements.iter().zip(values).enumerate() {
            let l = luminance(*v);
            for &c in &e.corners {
                let c = c as usize;
                if !self.counts(i, c) {
                    continue;
                }
                range[c] = (range[c].0.min(*v), range[c].1.max(*v));
                bright[c] = (bright[c].0.min(l), bright[c].1.max(l));
                if l > 0.0 {
                    colour[c] = (colour[c].0.min(*v / l), colour[c].1.max(*v / l));
                }
                sum[c] += *v * e.area;
                weight[c] += e.area;
            }
        }
        let mut vals: Vec<Vec3> = sum
            .iter()
            .zip(&weight)
            .map(|(s, w)| if *w > 0.0 { *s / *w } else { Vec3::ZERO })
            .collect();
        // The area-weighted least-squares plane of each channel through the centroids'
        // values of the elements around the vertex, f_e ≈ a + g · (c_e − p_v) in the
        // vertex's tangent plane, evaluated at the vertex (see `PlaneFit`: no slope along a
        // direction the centroids barely spread in); the luminance's plane is the same
        // weighted sum of the channels' (least squares is linear in the data).
        let mut m = vec![[0.0f64; 6]; nv]; // s00 s01 s02 s11 s12 s22
        let mut r = vec![[[0.0f64; 3]; 3]; nv];
        let basis: Vec<(Vec3, Vec3)> = self.normals.iter().map(|n| orthonormal_basis(*n)).collect();
        for (i, (e, v)) in elements.iter().zip(values).enumerate() {
            let c = e.centroid();
            for &k in &e.corners {
                let k = k as usize;
                if !self.counts(i, k) {
                    continue;
                }
                let d = c - self.positions[k];
                let (t1, t2) = basis[k];
                let (d1, d2) = (d.dot(t1) as f64, d.dot(t2) as f64);
                let w = e.area as f64;
                let q = &mut m[k];
                q[0] += w;
                q[1] += w * d1;
                q[2] += w * d2;
                q[3] += w * d1 * d1;
                q[4] += w * d1 * d2;
                q[5] += w * d2 * d2;
                for ch in 0..3 {
                    let f = v[ch] as f64;
                    r[k][ch][0] += w * f;
                    r[k][ch][1] += w * f * d1;
                    r[k][ch][2] += w * f * d2;
                }
            }
        }
        let mut grads = vec![[Vec3::ZERO; 3]; nv];
        // Widened by its spread: room for a ramp's extrapolation to a boundary.
        let widen = |lo: f32, hi: f32| (lo - (hi - lo), hi + (hi - lo));
        for k in 0..nv {
            if self.on_shadow_edge(k) {
                // A plane fitted to one side's elements extrapolates to the vertex from
                // beside it (to black, where noisy values tilt it): the side's mean, flat.
                continue;
            }
            let Some(plane) = PlaneFit::new(m[k]) else {
                continue;
            };
            let plane = |data: [f64; 3]| plane.at_vertex(data);
            let channels = r[k].map(plane);
            let lum = plane(std::array::from_fn(|j| {
                (0..3).map(|ch| LUMINANCE[ch] as f64 * r[k][ch][j]).sum()
            }));
            // An ill-conditioned fit (a sliver beside the vertex) can put the plane's value
            // far outside the data: keep it within the luminances around the vertex.
            let (lo, hi) = widen(bright[k].0, bright[k].1);
            let brightness = (lum[0] as f32).min(hi).max(lo).max(0.0);
            // The chromaticity: the fitted one, or where it leaves the widened range of
            // those around the vertex, the point where the way to it from the mean's (which
            // is within the range: a weighted mean of them) leaves the range.
            let (clo, chi) = colour[k];
            let mean = vals[k] / luminance(vals[k]).max(f32::MIN_POSITIVE);
            let chroma = if brightness == 0.0 || clo.x > chi.x {
                Vec3::ZERO
            } else if lum[0] <= 0.0 {
                mean
            } else {
                let fitted = Vec3::from_array(channels.map(|c| (c[0] / lum[0]) as f32));
                let mut t = 1.0f32;
                for ch in 0..3 {
                    let (lo, hi) = widen(clo[ch], chi[ch]);
                    let d = fitted[ch] - mean[ch];
                    if fitted[ch] > hi {
                        t = t.min((hi - mean[ch]) / d);
                    } else if fitted[ch] < lo.max(0.0) {
                        t = t.min((lo.max(0.0) - mean[ch]) / d);
                    }
                }
                mean + (fitted - mean) * t.max(0.0)
            };
            let (t1, t2) = basis[k];
            let g = t1 * lum[1] as f32 + t2 * lum[2] as f32;
            vals[k] = chroma * brightness;
            grads[k] = [g * chroma.x, g * chroma.y, g * chroma.z];
        }
        Fit {
            values: vals,
            gradients: grads,
            range,
        }
    }

    /// Whether element `i` counts for vertex `k`: on a hard shadow edge, only the elements
    /// on the vertex's side of it.
    fn counts(&self, i: usize, k: usize) -> bool {
        match &self.shadow_sides {
            Some(s) => match s.vertex.get(k).copied().flatten() {
                Some(side) => s.element.get(i) == Some(&side),
                None => true,
            },
            None => true,
        }
    }

    /// Scales each vertex's gradient, per channel, by the largest φ ≤ 1 that keeps the
    /// plane from the vertex's value (`vertex`, the fit's) to the centroid of every element
    /// around it within the range of those elements' values and the vertex's, and to the
    /// third points of those elements' edges from it within that range and the far end's
    /// value (where the edge's cubic has its inner control points): Barth and Jespersen's
    /// limiter ("The design and application of upwind schemes on unstructured meshes",
    /// AIAA 89-0366, 1989). A fit beside a sliver or across a shadow edge not marked
    /// hard can tilt steeply where the values around the vertex are nearly equal: the
    /// cubics then swing far beyond the light around them (on Sponza, 0.15 W/m² on a
    /// point that is black in truth). Linear light keeps its gradient (the plane meets
    /// every centroid's value), and since the Clough–Tocher elements are C¹ for any
    /// vertex gradients, limiting leaves no kink.
    fn limit_gradients(
        &self,
        elements: &[Element],
        vertex: &[Vec3],
        range: &[(Vec3, Vec3)],
        grads: &mut [[Vec3; 3]],
    ) {
        let mut phi = vec![Vec3::ONE; vertex.len()];
        for (i, e) in elements.iter().enumerate() {
            for (n, &k) in e.corners.iter().enumerate() {
                let k = k as usize;
                if !self.counts(i, k) {
                    continue;
                }
                let (a, phi) = (vertex[k], &mut phi[k]);
                // The largest φ that keeps a + φ·δ within [lo, hi], per channel.
                self.limits_in(e, n, vertex, range[k], |d, lo, hi| {
                    let delta = along(&grads[k], d);
                    for ch in 0..3 {
                        let room = if delta[ch] > 0.0 {
                            hi[ch] - a[ch]
                        } else {
                            lo[ch] - a[ch]
                        };
                        if delta[ch] != 0.0 {
                            phi[ch] = phi[ch].min((room / delta[ch]).clamp(0.0, 1.0));
                        }
                    }
                });
            }
        }
        for (g, f) in grads.iter_mut().zip(phi) {
            for ch in 0..3 {
                g[ch] *= f[ch];
            }
        }
    }

    /// What the limiter holds the cubic of element `e` from its corner `n` (vertex k) to:
    /// calls `bound(d, lo, hi)` for each offset d from the vertex at which the plane of
    /// the vertex's value and gradient must stay within [lo, hi]: the element's centroid,
    /// within `range` (the values of the elements around the vertex) and the vertex's
    /// value; and the third points of its two edges from the vertex (where the edge's
    /// cubic has its inner control points), within that and the far end's value.
    fn limits_in(
        &self,
        e: &Element,
        n: usize,
        vertex: &[Vec3],
        range: (Vec3, Vec3),
        mut bound: impl FnMut(Vec3, Vec3, Vec3),
    ) {
        let k = e.corners[n] as usize;
        let a = vertex[k];
        let (lo, hi) = (range.0.min(a), range.1.max(a));
        bound(e.centroid() - self.positions[k], lo, hi);
        for j in [e.corners[(n + 1) % 3], e.corners[(n + 2) % 3]] {
            let j = j as usize;
            let far = vertex[j];
            bound(
                (self.positions[j] - self.positions[k]) / 3.0,
                lo.min(far),
                hi.max(far),
            );
        }
    }

    /// Whether vertex `k` is a corner of an element a hard shadow edge crosses.
    fn on_shadow_edge(&self, k: usize) -> bool {
        self.shadow_sides
            .as_ref()
            .is_some_and(|s| s.vertex.get(k).copied().flatten().is_some())
    }

    /// Vertex values and gradients for [`Reconstruction::Hermite`]: the fit's, with the
    /// gradients limited (see `limit_gradients`; Gouraud uses no gradient).
    pub fn hermite(&self, elements: &[Element], values: &[Vec3]) -> Hermite {
        self.hermite_from(elements, self.fit(elements, values))
    }

    fn hermite_from(&self, elements: &[Element], fit: Fit) -> Hermite {
        let Fit {
            values: mut vals,
            gradients: mut grads,
            range,
        } = fit;
        self.limit_gradients(elements, &vals, &range, &mut grads);
        // Each T-vertex's elements (the vertex, the element, its corner there), for the
        // limiter below.
        let is_hanging = self.hanging_flags();
        let mut around: Vec<(u32, u32, u8)> = Vec::new();
        for (i, e) in elements.iter().enumerate() {
            for (n, &k) in e.corners.iter().enumerate() {
                if is_hanging[k as usize] && self.counts(i, k as usize) {
                    around.push((k, i as u32, n as u8));
                }
            }
        }
        around.sort_unstable();
        let mut bounds: Vec<(Vec3, f32, Vec3, Vec3)> = Vec::new();
        // T-vertices: the coarse edge's cubic at their parameter t on it (value, and slope
        // along it; the cubic Hermite basis), and across the edge the ends' slopes
        // interpolated linearly, since the coarse element's cross-edge slope is linear
        // along the edge. The value and the slope along the edge must stay the coarse
        // edge's (the surface is continuous along it), but the slope across is free: it
        // is held to the limiter's bounds in the T-vertex's own elements. Their other
        // edges leave the coarse edge at an angle, so the slope along it enters their
        // cubics too: on Sponza, 4.5 W/m² per metre along a 1 cm edge under the cornice
        // (between a fan's black apex and its lit neighbour) sent a 0.6 m sliver's cubic
        // from that edge to −0.25 W/m², between values of 0.016 and 0.043: a black line
        // along the sliver. A slope across that meets the bounds cancels it there.
        self.resolve_hanging(|h| {
            let (v, [a, b], t) = (h.vertex as usize, h.edge.map(|i| i as usize), h.t);
            let d = self.positions[b] - self.positions[a];
            let len2 = d.length_squared().max(f32::MIN_POSITIVE);
            let m0 = along(&grads[a], d);
            let m1 = along(&grads[b], d);
            let (t2, t3) = (t * t, t * t * t);
            let value = vals[a] * (2.0 * t3 - 3.0 * t2 + 1.0)
                + m0 * (t3 - 2.0 * t2 + t)
                + vals[b] * (3.0 * t2 - 2.0 * t3)
                + m1 * (t3 - t2);
            let slope = (vals[b] - vals[a]) * (6.0 * t - 6.0 * t2)
                + m0 * (3.0 * t2 - 4.0 * t + 1.0)
                + m1 * (3.0 * t2 - 2.0 * t); // d/dt over the edge
            let across = self.normals[v].cross(d).normalize_or_zero();
            let change = (value - vals[v]).abs().max_element();
            vals[v] = value;
            let interpolated = Vec3::from_array(std::array::from_fn(|ch| {
                grads[a][ch].dot(across) * (1.0 - t) + grads[b][ch].dot(across) * t
            }));
            let on_edge = d * (1.0 / len2);
            // T-vertices on an edge with a T-vertex at an end are set again and again, until
            // they settle (`resolve_hanging`): they keep the interpolated slope, which
            // settles. Held to bounds, slopes fed back through each other can grow without
            // end.
            let mut across_slope = interpolated;
            if !h.edge.iter().any(|&e| is_hanging[e as usize]) {
                // Each bound: the value at d without the slope across, how fast the slope
                // across changes it, and its least and greatest value.
                bounds.clear();
                let start = around.partition_point(|&(k, _, _)| (k as usize) < v);
                for &(_, i, n) in around[start..]
                    .iter()
                    .take_while(|&&(k, _, _)| k as usize == v)
                {
                    let e = &elements[i as usize];
                    self.limits_in(e, n as usize, &vals, range[v], |d, lo, hi| {
                        // Along the coarse edge (within 11.5° of it) the slope across
                        // cannot help without growing huge: not a bound on it.
                        let rate = across.dot(d);
                        if rate.abs() >= 0.2 * d.length() {
                            bounds.push((value + slope * on_edge.dot(d), rate, lo, hi));
                        }
                    });
                }
                across_slope = slope_within(&bounds, interpolated);
            }
            for ch in 0..3 {
                grads[v][ch] = on_edge * slope[ch] + across * across_slope[ch];
            }
            (change, value.abs().max_element())
        });
        Hermite {
            values: vals,
            gradients: grads,
        }
    }

    /// The control points of element `e`'s Clough–Tocher element (see [`Bezier`]).
    pub fn bezier(elements: &[Element], h: &Hermite, e: u32) -> Bezier {
        let el = &elements[e as usize];
        let [i1, i2, i3] = el.corners.map(|c| c as usize);
        let [p1, p2, p3] = el.verts;
        let (f1, f2, f3) = (h.values[i1], h.values[i2], h.values[i3]);
        let (g1, g2, g3) = (&h.gradients[i1], &h.gradients[i2], &h.gradients[i3]);
        let (e12, e23, e31) = (p2 - p1, p3 - p2, p1 - p3);
        // Edges: the Hermite cubic of the end values and slopes.
        let c3000 = f1;
        let c0300 = f2;
        let c0030 = f3;
        let c2100 = f1 + along(g1, e12) / 3.0;
        let c2010 = f1 - along(g1, e31) / 3.0;
        let c1200 = f2 - along(g2, e12) / 3.0;
        let c0210 = f2 + along(g2, e23) / 3.0;
        let c1020 = f3 + along(g3, e31) / 3.0;
        let c0120 = f3 - along(g3, e23) / 3.0;
        // Next to each corner towards the centroid: the corner's tangent plane.
        let c2001 = (c2100 + c2010 + c3000) / 3.0;
        let c0201 = (c1200 + c0300 + c0210) / 3.0;
        let c0021 = (c1020 + c0120 + c0030) / 3.0;
        // Cross-edge slopes linear along each edge, along the edge's normal in the plane:
        // the centroid direction E_k4 = w + γ·(edge) with w normal to the edge, γ below.
        let (e14, e24, e34) = ((e12 - e31) / 3.0, (e23 - e12) / 3.0, (e31 - e23) / 3.0);
        let gamma =
            |e: Vec3, edge: Vec3| -e.dot(edge) / edge.length_squared().max(f32::MIN_POSITIVE);
        let (q1, q2, q3) = (gamma(e24, e23), gamma(e34, e31), gamma(e14, e12));
        let c0111 = (((c0210 - c0120) * 3.0 - c0300 + c0030) * q1
            + (c0210 * 2.0 - c0300 - c0120 + c0021 + c0201))
            * 0.5;
        let c1011 = (((c1020 - c2010) * 3.0 - c0030 + c3000) * q2
            + (c1020 * 2.0 - c0030 - c2010 + c2001 + c0021))
            * 0.5;
        let c1101 = (((c2100 - c1200) * 3.0 - c3000 + c0300) * q3
            + (c2100 * 2.0 - c3000 - c1200 + c2001 + c0201))
            * 0.5;
        // No new extremum inside: those three within the edges' control points, and with
        // them every point inside (a Bézier triangle lies within its control points). In
        // a sliver the centroid's direction from a short edge runs mostly along it (γ up
        // to tens), so corner data that disagree along the short edge (values 5 mm apart
        // fitted from different fans, slopes that do not see the step) swing the inside
        // far past the light around it: on Sponza to −0.12 W/m² between corners of 0.016
        // to 0.043. Clamped, the element keeps C⁰ with its neighbours (the edges are
        // untouched) and loses C¹ across an edge only where a clamp acts.
        let (lo, hi) = [c2100, c2010, c1200, c0210, c1020, c0120, c0300, c0030]
            .iter()
            .fold((c3000, c3000), |(lo, hi), c| (lo.min(*c), hi.max(*c)));
        let (c0111, c1011, c1101) = (
            c0111.clamp(lo, hi),
            c1011.clamp(lo, hi),
            c1101.clamp(lo, hi),
        );
        // Inner points: C¹ between the three sub-triangles.
        let c1002 = (c1101 + c1011 + c2001) / 3.0;
        let c0102 = (c1101 + c0111 + c0201) / 3.0;
        let c0012 = (c1011 + c0111 + c0021) / 3.0;
        let c0003 = (c1002 + c0102 + c0012) / 3.0;
        [
            c3000, c0300, c0030, c2100, c2010, c1200, c0210, c1020, c0120, c2001, c0201, c0021,
            c1101, c1011, c0111, c1002, c0102, c0012, c0003,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::PlaneFit;

    /// The moments and value sums `PlaneFit` takes, from centroid offsets (in the tangent
    /// plane, from the vertex), weights and values.
    fn sums(points: &[([f64; 2], f64, f64)]) -> ([f64; 6], [f64; 3]) {
        let (mut m, mut r) = ([0.0; 6], [0.0; 3]);
        for &([x, y], w, f) in points {
            m = [
                m[0] + w,
                m[1] + w * x,
                m[2] + w * y,
                m[3] + w * x * x,
                m[4] + w * x * y,
                m[5] + w * y * y,
            ];
            r = [r[0] + w * f, r[1] + w * f * x, r[2] + w * f * y];
        }
        (m, r)
    }

    /// At a boundary vertex of a regular grid of right triangles (three elements on one
    /// side of it), a linear light is reproduced exactly: value and both slopes.
    #[test]
    fn a_linear_light_is_reproduced_at_a_boundary_vertex() {
        let light = |[x, y]: [f64; 2]| 0.4 + 0.3 * x - 0.2 * y;
        let centroids = [
            [1.0 / 3.0, 1.0 / 3.0],
            [-1.0 / 3.0, 2.0 / 3.0],
            [-2.0 / 3.0, 1.0 / 3.0],
        ];
        let points: Vec<_> = centroids.iter().map(|&c| (c, 0.5, light(c))).collect();
        let (m, r) = sums(&points);
        let [value, gx, gy] = PlaneFit::new(m).expect("fit").at_vertex(r);
        for (got, want) in [(value, 0.4), (gx, 0.3), (gy, -0.2)] {
            assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        }
    }

    /// Slivers: centroids 0.2–0.4 m from the vertex along the edge and 6 cm beside it,
    /// within 8 mm of each other across it (Sponza's roof had such), under a light that
    /// rises along the edge (truth at the vertex: 0.5), one value 0.05 low (the noise of a
    /// few shadow rays). The full plane reads that 0.05 across millimetres as a slope of
    /// −8 per metre and puts the vertex at 0.95; with no slope across (d²/λ = 408 there),
    /// the vertex is off by no more than the noise.
    #[test]
    fn slivers_along_an_edge_do_not_tilt_the_plane_across_it() {
        let light = |[x, _]: [f64; 2]| 0.5 + 0.5 * x;
        let centroids = [[-0.4, 0.06], [-0.38, 0.066], [-0.2, 0.058]];
        let noise = [0.0, -0.05, 0.0];
        let points: Vec<_> = centroids
            .iter()
            .zip(noise)
            .map(|(&c, n)| (c, 1.0, light(c) + n))
            .collect();
        let (m, r) = sums(&points);
        let [value, _, _] = PlaneFit::new(m).expect("fit").at_vertex(r);
        assert!((value - 0.5).abs() <= 0.05, "{value}");
        // The full least-squares plane, through the three points exactly, is far off at
        // the vertex (so the test can fail): its value a + b·0 + c·0, by Cramer's rule.
        let [(p, _, f), (q, _, g), (t, _, h)] = [points[0], points[1], points[2]];
        let det3 = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| {
            a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0])
        };
        let rows = [[1.0, p[0], p[1]], [1.0, q[0], q[1]], [1.0, t[0], t[1]]];
        let with_values = [[f, p[0], p[1]], [g, q[0], q[1]], [h, t[0], t[1]]];
        let through_all =
            det3(with_values[0], with_values[1], with_values[2]) / det3(rows[0], rows[1], rows[2]);
        assert!((through_all - 0.5).abs() > 0.3, "{through_all}");
    }
}
