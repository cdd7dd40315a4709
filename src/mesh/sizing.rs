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

/// Longest-edge bisection until every edge is at most `max_len`.
pub(super) fn split_patches(v: [Vec3; 3], max_len: f32, out: &mut Vec<[Vec3; 3]>) {
    let (k, len) = longest_edge(&v);
    // The depth guard bounds the work on absurd inputs (a 1e9:1 sliver); 2^24 pieces
    // would already exceed any sane element budget.
    fn go(v: [Vec3; 3], max_len: f32, out: &mut Vec<[Vec3; 3]>, k: usize, len: f32, depth: u32) {
        if len <= max_len || depth >= 24 {
            out.push(v);
            return;
        }
        let (a, b, c) = (v[k], v[(k + 1) % 3], v[(k + 2) % 3]);
        let m = (a + b) * 0.5;
        for t in [[a, m, c], [m, b, c]] {
            let (k2, l2) = longest_edge(&t);
            go(t, max_len, out, k2, l2, depth + 1);
        }
    }
    go(v, max_len, out, k, len, 0);
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
    let patch_len = (size * PATCH_PER_ELEMENT) as f32;
    let mut pieces = Vec::new();
    let mut total = 0usize;
    for s in sources {
        pieces.clear();
        split_patches(s.verts, patch_len, &mut pieces);
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
    sources
        .iter()
        .map(|s| if s.double_sided { 2 } else { 1 })
        .sum()
}

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
    // The coarsest mesh has one element per patch side; no budget can go below it.
    let coarsest = sides(sources);
    let budget = settings
        .max_elements
        .unwrap_or(default.unwrap_or(default_budget(coarsest)))
        .max(coarsest);
    if budget == coarsest {
        // Every triangle is one patch and one element: the size is that of the largest.
        return Ok(sources
            .iter()
            .map(|s| {
                (2.0 * area(&s.verts) as f64)
                    .sqrt()
                    .max(longest_edge(&s.verts).1 as f64 / PATCH_PER_ELEMENT)
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
