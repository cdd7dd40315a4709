//! Our binary BVH (`Bvh::transmittance_binary`) against obvhs (a well-kept Rust BVH crate: PLOC build, compressed 8-wide BVH
//! with SIMD traversal) on the occlusion workload of `radiosity bench --occlusion`: the
//! same triangles, the same 1,000,000 segments between points drawn uniformly by area,
//! any-hit with early exit, one thread. Both must agree on which segments are blocked.
//! (obvhs won, 2× on Sponza, so `Bvh::transmittance` now traces with it.)
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
    let disagree = blocked_ours
        .iter()
        .zip(&blocked_theirs)
        .filter(|(a, b)| a != b)
        .count();
    let occluded = blocked_ours.iter().filter(|b| **b).count();
    println!(
        "occluded {:.1} %, disagreements {disagree} ({:.4} %)",
        100.0 * occluded as f64 / n as f64,
        100.0 * disagree as f64 / n as f64
    );
    println!(
        "ours:   build {build_ours:.3} s, {:.2} M rays/s (1 thread)",
        n as f64 / trace_ours / 1e6
    );
    println!(
        "obvhs:  build {build_theirs:.3} s, {:.2} M rays/s (1 thread)",
        n as f64 / trace_theirs / 1e6
    );
    Ok(())
}
