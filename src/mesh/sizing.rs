//! The element size: how long patches may be (longest-edge bisection) and how deep their
//! element quadtrees go for a given size, and the choice of the size itself, either the
//! one asked for or the largest whose element count fits the budget.

use super::build::Source;
use super::{DEFAULT_ELEMENTS, MeshSettings};
use crate::cancel::{Cancelled, check};
use crate::geometry::triangle_area as area;
use glam::Vec3;
use std::sync::atomic::AtomicBool;

/// Patches are at most this many element sizes long (so at most ~16–64 elements each).
pub(super) const PATCH_PER_ELEMENT: f64 = 4.0;

/// The longest edge of `v`: its index `k` (from `v[k]` to `v[k + 1]`) and its length.
fn longest_edge(v: &[Vec3; 3]) -> (usize, f32) {
    let e = [
        (v[1] - v[0]).length_squared(),
        (v[2] - v[1]).length_squared(),
        (v[0] - v[2]).length_squared(),
    ];
    let k = if e[0] >= e[1] && e[0] >= e[2] {
        0
    } else if e[1] >= e[2] {
        1
    } else {
        2
    };
    (k, e[k].sqrt())
}

/// A patch's elements (its quadtree at [`depth_for`] the element size) are at most this
/// many element sizes long. The depth follows the area, and the quadtree's children have
/// their parent's shape, so a needle (a long thin triangle, as a fan triangulates a wall)
/// would keep elements as long as itself: one value along a length over which the light
/// changes, which Gouraud shading then fans out between the needle's corners. A regular
/// triangle's elements are within 1.1 sizes and a right isosceles one's within 1.42, so
/// only needles are cut further.
const ELEMENT_LENGTH_PER_SIZE: f64 = 1.5;

/// Needles narrower than this fraction of the element size (their altitude on the long
/// edge) are left whole: strips along an edge and rounding slivers, whose fan is at most
/// that wide. Cut, their pieces are elements far below the size the solvers resolve (a
/// furnace's 0.1 mm strips, cut into 7 cm pieces, came out up to 7 % off in Gouraud).
const NARROWEST_CUT_PER_SIZE: f64 = 1.0 / 128.0;

/// Longest-edge bisection of `v` into patches for element size `size`: until every edge
/// is at most [`PATCH_PER_ELEMENT`] sizes, and the elements of each patch's quadtree at
/// most [`ELEMENT_LENGTH_PER_SIZE`] sizes long unless narrower than
/// [`NARROWEST_CUT_PER_SIZE`] of a size. Bisection halves a needle's length in three
/// pieces where its quadtree would take four, and it is cut by its length, where the
/// quadtree's depth follows its area.
pub(super) fn split_patches(v: [Vec3; 3], size: f64, out: &mut Vec<[Vec3; 3]>) {
    let max_len = (size * PATCH_PER_ELEMENT) as f32;
    let max_element = size * ELEMENT_LENGTH_PER_SIZE;
    let narrowest = size * NARROWEST_CUT_PER_SIZE;
    let done = |v: &[Vec3; 3], len: f32| {
        let a = area(v);
        len <= max_len
            && (len as f64 <= max_element * f64::from(1u32 << depth_for(a, size))
                || 2.0 * a as f64 / (len as f64) < narrowest)
    };
    // The depth guard bounds the work on absurd inputs (a 1e9:1 sliver); 2^24 pieces
    // would already exceed any sane element budget.
    fn go(
        v: [Vec3; 3],
        done: &dyn Fn(&[Vec3; 3], f32) -> bool,
        out: &mut Vec<[Vec3; 3]>,
        depth: u32,
    ) {
        let (k, len) = longest_edge(&v);
        if done(&v, len) || depth >= 24 {
            out.push(v);
            return;
        }
        let (a, b, c) = (v[k], v[(k + 1) % 3], v[(k + 2) % 3]);
        let m = (a + b) * 0.5;
        for t in [[a, m, c], [m, b, c]] {
            go(t, done, out, depth + 1);
        }
    }
    go(v, &done, out, 0);
}

/// Quadtree depth that brings `sqrt(2·area)` to at most `size` (each level halves it).
pub(super) fn depth_for(area: f32, size: f64) -> u32 {
    let m = (2.0 * area as f64).sqrt();
    if m <= size || size <= 0.0 {
        return 0;
    }
    ((m / size).log2().ceil() as u32).min(12)
}

/// How many elements `sources` get at element size `size`.
fn count_elements(sources: &[Source], size: f64) -> usize {
    let mut pieces = Vec::new();
    let mut total = 0usize;
    for s in sources {
        pieces.clear();
        split_patches(s.verts, size, &mut pieces);
        let sides = if s.double_sided { 2 } else { 1 };
        for p in &pieces {
            total += sides * 4usize.pow(depth_for(area(p), size));
        }
    }
    total
}

/// Patch sides of `sources`: one per single-sided source, two per double-sided one (the
/// fewest elements they can have).
pub(super) fn sides(sources: &[Source]) -> usize {
    sources.iter().map(source_sides).sum()
}

/// Sides of one source: two for a double-sided material, else one.
pub(super) fn source_sides(s: &Source) -> usize {
    if s.double_sided { 2 } else { 1 }
}

/// The fewest elements beyond one per patch side that the default budget leaves to the
/// scene's larger surfaces. Without them, where the labels lying on NegativeScaleTest's
/// background cut it into more pieces than its input triangles' budget, every triangle
/// became one element and the element size that of the largest triangle, 9.6 m, so the
/// hierarchy's smallest element (an eighth of it) was 1.2 m, and the background under
/// its 1 m labels, dark in the path-traced truth (0.04 W/m²), showed the light around them
/// (0.46). Half the default mesh: no scene of `../shared/scenes` but that one comes within
/// it of its budget (the closest, StainedGlassLamp, leaves 3,640), so their meshes do not
/// change.
const SPARE_ELEMENTS: usize = DEFAULT_ELEMENTS / 2;

/// The element budget when none is given: [`DEFAULT_ELEMENTS`], or half as many elements
/// again as there are patch sides for large scenes, so their biggest triangles (floors,
/// walls) are still subdivided.
pub(super) fn default_budget(sides: usize) -> usize {
    DEFAULT_ELEMENTS.max(sides + sides / 2)
}

/// The element size for `sources`: `settings.element_size`, or the largest size whose
/// element count fits the budget (`settings.max_elements`, else `default`, else
/// [`default_budget`] of these sources), never below one element per patch side. Looks
/// at `cancel` before each count of the elements.
pub(super) fn choose_element_size(
    sources: &[Source],
    total_area: f64,
    settings: &MeshSettings,
    default: Option<usize>,
    cancel: &AtomicBool,
) -> Result<f64, Cancelled> {
    if let Some(s) = settings.element_size.filter(|s| *s > 0.0) {
        return Ok(s);
    }
    if sources.is_empty() || total_area <= 0.0 {
        return Ok(1.0);
    }
    // The coarsest mesh has one element per patch side; no budget can go below it. The
    // default budget (the input triangles', see `build`) can be used up by the pieces
    // the contact lines cut: the surfaces left whole then still get at least
    // [`SPARE_ELEMENTS`] more.
    let coarsest = sides(sources);
    let budget = match settings.max_elements {
        Some(given) => given.max(coarsest),
        None => default
            .unwrap_or(default_budget(coarsest))
            .max(coarsest + SPARE_ELEMENTS),
    };
    if budget == coarsest {
        // Every triangle is one patch and one element: the size is that of the largest,
        // by its area or by its length (see `split_patches`).
        return Ok(sources
            .iter()
            .map(|s| {
                (2.0 * area(&s.verts) as f64)
                    .sqrt()
                    .max(longest_edge(&s.verts).1 as f64 / ELEMENT_LENGTH_PER_SIZE)
            })
            .fold(0.0, f64::max));
    }
    let over = |size: f64| -> Result<bool, Cancelled> {
        check(cancel)?;
        Ok(count_elements(sources, size) > budget)
    };
    // Bisection on log(size): count_elements is monotone non-increasing in size. Start
    // from the size that tiles the area with `budget` right isosceles triangles.
    let guess = (2.0 * total_area / budget as f64).sqrt();
    let (mut lo, mut hi) = (guess * 0.25, guess * 64.0);
    while over(hi)? && hi < 1e30 {
        hi *= 4.0;
    }
    for _ in 0..20 {
        let mid = (lo * hi).sqrt();
        if over(mid)? {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok(hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::shortest_altitude;

    /// Per patch, the longest edge of its elements (its quadtree at `depth_for`) and its
    /// width (altitude on its longest edge), over the element size.
    fn element_lengths(v: [Vec3; 3], size: f64) -> Vec<(f64, f64)> {
        let mut pieces = Vec::new();
        split_patches(v, size, &mut pieces);
        pieces
            .iter()
            .map(|p| {
                let depth = depth_for(area(p), size);
                (
                    longest_edge(p).1 as f64 / f64::from(1u32 << depth) / size,
                    shortest_altitude(p) as f64 / size,
                )
            })
            .collect()
    }

    /// A needle 3 m long and 3 cm wide at an element size of 0.5 m: its area alone would
    /// make it one element 6 sizes long; cut by its length, no element is over 1.5 sizes
    /// but the narrowest pieces at its apex, and the pieces cover it (their areas sum to
    /// its own).
    #[test]
    fn needles_are_cut_by_their_length() {
        let v = [
            Vec3::ZERO,
            Vec3::new(3.0, 0.0, 0.02),
            Vec3::new(3.0, 0.0, -0.01),
        ];
        let lengths = element_lengths(v, 0.5);
        assert!(lengths.len() > 1);
        assert!(
            lengths
                .iter()
                .all(|(l, w)| *l <= ELEMENT_LENGTH_PER_SIZE || *w < NARROWEST_CUT_PER_SIZE),
            "{lengths:?}"
        );
        let mut pieces = Vec::new();
        split_patches(v, 0.5, &mut pieces);
        // f32 areas of some twenty pieces, each rounded to about 1e-7 of itself.
        let sum: f32 = pieces.iter().map(area).sum();
        assert!((sum - area(&v)).abs() <= 1e-5 * area(&v));
    }

    /// Regular and right isosceles triangles (the quads of a box) stay one patch up to
    /// the patch length, whatever their size against the element size; a needle narrower
    /// than `NARROWEST_CUT_PER_SIZE` stays whole too.
    #[test]
    fn only_wide_needles_are_cut() {
        let h = 3f32.sqrt() / 2.0;
        for s in [0.3f32, 0.7, 1.0, 2.5] {
            for v in [
                [Vec3::ZERO, Vec3::X * s, Vec3::Y * s],
                [Vec3::ZERO, Vec3::X * s, Vec3::new(0.5, h, 0.0) * s],
            ] {
                assert_eq!(element_lengths(v, 1.0).len(), 1, "{v:?}");
            }
        }
        let strip = [Vec3::ZERO, Vec3::X * 3.0, Vec3::new(3.0, 0.005, 0.0)];
        assert_eq!(element_lengths(strip, 1.0).len(), 1);
    }
}
