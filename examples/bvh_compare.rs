//! Three shadow-ray engines on the occlusion workload of `radiosity bench --occlusion`
//! (the same triangles, the same 1,000,000 segments between points drawn uniformly by
//! area, any-hit with early exit, one thread), which must agree on which segments are
//! blocked:
//! - our binary SAH tree (`Bvh::transmittance_binary`);
//! - obvhs's compressed 8-wide BVH with its own traversal (PLOC build, SIMD node test);
//! - our 4-wide tree with four triangles per leaf over obvhs's binary build
//!   (`Bvh::transmittance`, `accel/wide.rs`), which is what the solvers use.
//!
//! On Sponza (release build, 2 cores, 2026-12-01) they traced about 0.95, 3.3 and 5.9 M
//! rays/s.
//!
//! Then closest hits along the same rays, unbounded (what the leaves' rays, the path
//! tracer and the final gather ask), by the binary tree (`Bvh::closest_hit_binary`) and
//! the wide one (`Bvh::closest_hit`), which must find the same triangle or one at the same
//! distance: on Sponza (2026-12-06) 0.71 and 1.48 M rays/s.
//!
//! ```sh
//! cargo run --release --example bvh_compare -- ../shared/scenes/sponza-crytek-converted/sponza.gltf
//! ```

use obvhs::{BvhBuildParams, cwbvh::builder::build_cwbvh_from_tris, ray::Ray, triangle::Triangle};
use radiosity::accel::{Bvh, sample_segments};
use radiosity::mesh::Mesh;
use radiosity::scene::builtin;
use std::time::{Duration, Instant};

fn main() -> anyhow::Result<()> {
    let spec = std::env::args().nth(1).unwrap_or("builtin:cornell".into());
    let n: usize = std::env::args()
        .nth(2)
        .map_or(Ok(1_000_000), |s| s.parse())?;
    let scene = match spec.strip_prefix("builtin:") {
        Some(name) => builtin::by_name(name).ok_or_else(|| anyhow::anyhow!("unknown {name}"))?,
        None => radiosity::scene::gltf::load(std::path::Path::new(&spec))?,
    };
    let mesh = Mesh::build(&scene, &Default::default());
    let tris = &mesh.triangles;
    let segments = sample_segments(tris, n).ok_or_else(|| anyhow::anyhow!("no area"))?;
    println!("{spec}: {} triangles, {n} segments", tris.len());

    let t = Instant::now();
    let ours = Bvh::build(tris, &[]);
    let build_ours = t.elapsed().as_secs_f64();
    let v = |p: glam::Vec3| glam::Vec3A::new(p.x, p.y, p.z);
    let otris: Vec<Triangle> = tris
        .iter()
        .map(|t| Triangle {
            v0: v(t[0]),
            v1: v(t[1]),
            v2: v(t[2]),
        })
        .collect();
    let t = Instant::now();
    let theirs = build_cwbvh_from_tris(
        &otris,
        BvhBuildParams::medium_build(),
        &mut Duration::default(),
    );
    let build_theirs = t.elapsed().as_secs_f64();

    let t = Instant::now();
    let blocked_ours: Vec<bool> = segments
        .iter()
        .map(|(a, b, skip)| ours.transmittance_binary(*a, *b, *skip) < 1.0)
        .collect();
    let trace_ours = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let blocked_theirs: Vec<bool> = segments
        .iter()
        .map(|(a, b, skip)| {
            // Same parametric window as ours: the first and last 1e-4 of the segment.
            let ray = Ray::new(v(*a), v(*b - *a), 1e-4, 1.0 - 1e-4);
            !theirs.ray_traverse_miss(ray, |ray, id| {
                let tri = theirs.primitive_indices[id];
                if tri == skip[0] || tri == skip[1] {
                    f32::INFINITY
                } else {
                    otris[tri as usize].intersect(ray)
                }
            })
        })
        .collect();
    let trace_theirs = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let blocked_wide: Vec<bool> = segments
        .iter()
        .map(|(a, b, skip)| ours.transmittance(*a, *b, *skip) < 1.0)
        .collect();
    let trace_wide = t.elapsed().as_secs_f64();
    // Segments within 0.01 rad of an end triangle's plane graze the surfaces they start
    // or end on (points on one wall): there rounding decides, and the light they carry
    // is weighted by that cosine.
    let grazing = |(a, b, ends): &(glam::Vec3, glam::Vec3, [u32; 2])| {
        let d = (*b - *a).normalize_or_zero();
        ends.iter().any(|&t| {
            let t = &tris[t as usize];
            let n = (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero();
            n.dot(d).abs() < 0.01
        })
    };
    let disagree = |other: &[bool]| {
        (0..n)
            .filter(|&i| blocked_ours[i] != other[i] && !grazing(&segments[i]))
            .count()
    };
    let (disagree, disagree_wide) = (disagree(&blocked_theirs), disagree(&blocked_wide));
    let occluded = blocked_ours.iter().filter(|b| **b).count();
    println!(
        "occluded {:.1} %, disagreements with the binary tree, grazing segments aside: obvhs {disagree}, wide {disagree_wide}",
        100.0 * occluded as f64 / n as f64,
    );
    println!(
        "ours:   build {build_ours:.3} s, {:.2} M rays/s (1 thread)",
        n as f64 / trace_ours / 1e6
    );
    println!(
        "obvhs:  build {build_theirs:.3} s, {:.2} M rays/s (1 thread)",
        n as f64 / trace_theirs / 1e6
    );
    println!(
        "wide:   built with ours, {:.2} M rays/s (1 thread)",
        n as f64 / trace_wide / 1e6
    );

    // Closest hits along the same rays, past their ends (what the leaves' rays, the path
    // tracer and the final gather ask): the first triangle after the start's own.
    let closest = |binary: bool| {
        let t = Instant::now();
        let hits: Vec<Option<(u32, f32)>> = segments
            .iter()
            .map(|(a, b, skip)| {
                let hit = if binary {
                    ours.closest_hit_binary(*a, *b - *a, 0.0, f32::INFINITY, skip[0])
                } else {
                    ours.closest_hit(*a, *b - *a, 0.0, f32::INFINITY, skip[0])
                };
                hit.map(|h| (h.triangle, h.t))
            })
            .collect();
        (hits, t.elapsed().as_secs_f64())
    };
    let (binary, trace_binary) = closest(true);
    let (wide, trace_wide) = closest(false);
    // Sponza holds coplanar copies of some surfaces: a hit on either is the same hit.
    let same = |x: Option<(u32, f32)>, y: Option<(u32, f32)>| match (x, y) {
        (Some((i, s)), Some((j, t))) => i == j || (s - t).abs() <= 1e-6 * s.max(t),
        (x, y) => x.is_none() && y.is_none(),
    };
    let differ = (0..n)
        .filter(|&i| !same(binary[i], wide[i]) && !grazing(&segments[i]))
        .count();
    println!(
        "closest hits: binary {:.2} M rays/s, wide {:.2} M rays/s (1 thread); {differ} differ, grazing rays and ties aside",
        n as f64 / trace_binary / 1e6,
        n as f64 / trace_wide / 1e6
    );
    Ok(())
}
