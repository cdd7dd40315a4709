//! Bicubic Hermite reconstruction: it interpolates the vertex values,
//! is continuous across element edges (no cracks, also at T-vertices after refinement),
//! removes the first-derivative jumps of Gouraud shading along edges (Mach bands) on
//! smooth light, and is more accurate than Gouraud against the closed form of
//! `builtin:penumbra`.

use glam::{DVec3, Vec3};
use radiosity::analytic::penumbra_errors;
use radiosity::mesh::{
    AdaptiveSettings, DisplayMesh, Element, Mesh, MeshSettings, Reconstruction, Reconstructor,
    eval_bezier,
};
use radiosity::pipeline::Prepared;
use radiosity::pipeline::probe_values;
use radiosity::scene::builtin;
use radiosity::solver::{Method, Solver, SolverSettings};
use std::sync::atomic::AtomicBool;

fn penumbra(element_size: f64, adaptive: bool) -> (Prepared, Solver) {
    let p = Prepared::new(
        &builtin::penumbra(),
        &MeshSettings {
            element_size: Some(element_size),
            ..Default::default()
        },
    );
    let mut s = p
        .solver(SolverSettings {
            method: Method::GaussSeidel,
            tolerance: 1e-6,
            adaptive: adaptive.then(|| AdaptiveSettings {
                min_size: Some(element_size / 4.0),
                ..Default::default()
            }),
            ..Default::default()
        })
        .unwrap();
    s.run(None, &AtomicBool::new(false)).unwrap();
    (p, s)
}

#[test]
fn hermite_interpolates_vertex_values_and_is_continuous_across_edges() {
    let (_, s) = penumbra(0.1, true);
    let mesh: &Mesh = s.mesh();
    let b = s.radiosity();
    let h = mesh.display.hermite(&mesh.elements, &b);
    let scale = b.iter().map(|v| v.max_element()).fold(0.0f32, f32::max);
    // Corners: exactly the vertex values.
    for (i, e) in mesh.elements.iter().enumerate() {
        let bz = DisplayMesh::bezier(&mesh.elements, &h, i as u32);
        for (k, bary) in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
            .iter()
            .enumerate()
        {
            let got = eval_bezier(&bz, *bary);
            assert_eq!(got, h.values[e.corners[k] as usize]);
        }
    }
    // Edges: wherever a point lies on the edges of two elements (shared edges and T-vertex
    // edges alike), both evaluate to the same value. Points at quarter, half and
    // three-quarters of every element edge, found in the other element by position.
    let r = Reconstructor::new(Reconstruction::Hermite, &mesh.display, &mesh.elements, &b);
    let mut checked = 0;
    for (i, e) in mesh.elements.iter().enumerate() {
        for k in 0..3 {
            for t in [0.25f32, 0.5, 0.75] {
                let mut bary = [0.0f32; 3];
                bary[k] = 1.0 - t;
                bary[(k + 1) % 3] = t;
                let p = e.verts[k] * (1.0 - t) + e.verts[(k + 1) % 3] * t;
                let mine = r.at(&mesh.elements, &b, i as u32, bary);
                // The neighbour across this edge: another element of the floor containing p.
                for (j, f) in mesh.elements.iter().enumerate() {
                    if j == i || f.normal.dot(e.normal) < 0.99 {
                        continue;
                    }
                    let (q, fb) = radiosity::geometry::closest_point_on_triangle(p, &f.verts);
                    if (q - p).length() > 1e-6 {
                        continue;
                    }
                    let theirs = r.at(&mesh.elements, &b, j as u32, fb);
                    // f32 evaluation of cubics: 1e-4 of the scene's brightest value.
                    assert!(
                        (mine - theirs).abs().max_element() <= 1e-4 * scale,
                        "crack at {p}: {mine} vs {theirs}"
                    );
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 1000, "only {checked} edge points checked");
}

/// Mean jump of the first derivative across element edges along a line on the lit floor,
/// relative to the mean |derivative|.
fn derivative_jumps(mode: Reconstruction, mesh: &Mesh, b: &[Vec3]) -> f64 {
    let n = 4000;
    let (x0, x1, z) = (-0.95f64, -0.35f64, -0.75f64); // fully lit, light falling off
    let pts: Vec<(DVec3, DVec3)> = (0..n)
        .map(|i| {
            (
                DVec3::new(x0 + (x1 - x0) * i as f64 / (n - 1) as f64, 0.0, z),
                DVec3::Y,
            )
        })
        .collect();
    let vals = probe_values(mesh, b, &pts, mode);
    let owner: Vec<u32> = pts
        .iter()
        .map(|(p, nrm)| mesh.locate(mesh.to_local(*p), nrm.as_vec3()).unwrap().0)
        .collect();
    let h = (x1 - x0) / (n - 1) as f64;
    let d: Vec<f64> = (0..n - 1)
        .map(|i| (vals[i + 1].x - vals[i].x) as f64 / h)
        .collect();
    let mean_abs = d.iter().map(|v| v.abs()).sum::<f64>() / d.len() as f64;
    let mut jumps = Vec::new();
    for i in 2..n - 3 {
        // An edge between samples i and i+1; derivatives from two samples on each side.
        if owner[i] != owner[i + 1]
            && owner[i - 2] == owner[i]
            && owner[i - 1] == owner[i]
            && owner[i + 2] == owner[i + 1]
            && owner[i + 3] == owner[i + 1]
        {
            jumps.push((d[i + 2] - d[i - 2]).abs());
        }
    }
    assert!(jumps.len() > 5, "{} edge crossings", jumps.len());
    jumps.iter().sum::<f64>() / jumps.len() as f64 / mean_abs
}

#[test]
fn hermite_removes_mach_bands_on_smooth_light() {
    let (_, s) = penumbra(0.1, false);
    let b = s.radiosity();
    let gouraud = derivative_jumps(Reconstruction::Gouraud, s.mesh(), &b);
    let hermite = derivative_jumps(Reconstruction::Hermite, s.mesh(), &b);
    println!(
        "mean derivative jump across edges / mean |derivative|: Gouraud {gouraud:.3}, Hermite {hermite:.1e}"
    );
    // Gouraud's slope changes at every edge by about the curvature × element size; the
    // cubic's slope is continuous at vertices and nearly so along edges.
    assert!(
        hermite < 0.5 * gouraud,
        "Hermite {hermite} vs Gouraud {gouraud}"
    );
}

#[test]
fn hermite_is_closer_to_the_closed_form_than_gouraud() {
    for adaptive in [false, true] {
        let (_, s) = penumbra(0.1, adaptive);
        let rms = |mode| penumbra_errors(&s, mode).0;
        let (g, h) = (rms(Reconstruction::Gouraud), rms(Reconstruction::Hermite));
        println!("adaptive {adaptive}: RMS error Gouraud {g:.4}, Hermite {h:.4}");
        assert!(
            h < g,
            "adaptive {adaptive}: Hermite {h} not below Gouraud {g}"
        );
    }
}

/// Worst jump of the derivative across shared edges (along the edge's normal in the
/// plane), relative to the mean gradient magnitude, sampled at a quarter, half and
/// three-quarters of every edge shared by two floor elements; one-sided second-order
/// differences with a step of 0.5 % of the edge on each side.
fn cross_edge_jump(mode: Reconstruction, mesh: &Mesh, b: &[Vec3]) -> f64 {
    use std::collections::HashMap;
    let r = Reconstructor::new(mode, &mesh.display, &mesh.elements, b);
    let mut by_edge: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (i, e) in mesh.elements.iter().enumerate() {
        for k in 0..3 {
            let (a, c) = (e.corners[k], e.corners[(k + 1) % 3]);
            by_edge.entry((a.min(c), a.max(c))).or_default().push(i);
        }
    }
    let value = |i: usize, p: Vec3| -> f64 {
        let (_, bary) = radiosity::geometry::closest_point_on_triangle(p, &mesh.elements[i].verts);
        r.at(&mesh.elements, b, i as u32, bary).x as f64
    };
    let (mut worst, mut grad_sum, mut n) = (0.0f64, 0.0f64, 0usize);
    for ((a, c), users) in &by_edge {
        let [i, j] = users[..] else { continue };
        let (ei, ej) = (&mesh.elements[i], &mesh.elements[j]);
        // The floor only (the emitter is flat and bright: its f32 rounding would be all
        // that is measured there).
        let on_floor = |e: &radiosity::mesh::Element| mesh.patches[e.patch as usize].object == 0;
        if !on_floor(ei) || !on_floor(ej) {
            continue;
        }
        let (pa, pc) = (
            mesh.display.positions[*a as usize],
            mesh.display.positions[*c as usize],
        );
        let d = pc - pa;
        // In-plane normal of the edge, pointing into element j.
        let mut nrm = ei.normal.cross(d).normalize();
        if nrm.dot(ej.centroid() - pa) < 0.0 {
            nrm = -nrm;
        }
        let h = d.length() * 0.005;
        for t in [0.25f32, 0.5, 0.75] {
            let p = pa + d * t;
            let into_j = (-3.0 * value(j, p) + 4.0 * value(j, p + nrm * h)
                - value(j, p + nrm * 2.0 * h))
                / (2.0 * h as f64);
            let from_i = (3.0 * value(i, p) - 4.0 * value(i, p - nrm * h)
                + value(i, p - nrm * 2.0 * h))
                / (2.0 * h as f64);
            worst = worst.max((into_j - from_i).abs());
            grad_sum += 0.5 * (into_j.abs() + from_i.abs());
            n += 1;
        }
    }
    assert!(n > 100, "only {n} edge points");
    worst / (grad_sum / n as f64)
}

#[test]
fn hermite_is_c1_across_edges() {
    // A smoothly lit, uniformly meshed floor: every shared edge, not only the vertices.
    let (_, s) = penumbra(0.1, false);
    let b = s.radiosity();
    let gouraud = cross_edge_jump(Reconstruction::Gouraud, s.mesh(), &b);
    let hermite = cross_edge_jump(Reconstruction::Hermite, s.mesh(), &b);
    println!(
        "worst cross-edge derivative jump / mean |derivative|: Gouraud {gouraud:.4}, Hermite {hermite:.2e}"
    );
    // Clough–Tocher elements share the cross-edge slope (linear along each edge between
    // the shared vertex gradients): what is left is the differences' truncation (measured:
    // 2.5e-3 of the slope with a 2 % step, 2.4e-4 with 0.5 %, so O(step²) and not a jump)
    // and f32 rounding, about 4e-3 of the mean slope at worst with this step, against
    // Gouraud's kinks of several times the mean slope.
    assert!(
        hermite < 1e-2,
        "Hermite jumps by {hermite} of the mean slope"
    );
    assert!(
        gouraud > 0.1,
        "Gouraud shows no kinks ({gouraud}): the test is blind"
    );
}

/// The farthest the reconstruction of `b` goes beyond [0, 1] over `elements`, sampled at
/// the (n + 1)(n + 2)/2 barycentric points of a triangle cut n times along each edge.
fn swing_beyond_unit_range(
    mode: Reconstruction,
    display: &DisplayMesh,
    elements: &[Element],
    b: &[Vec3],
    n: u32,
) -> f32 {
    let r = Reconstructor::new(mode, display, elements, b);
    let mut worst = 0.0f32;
    for i in 0..elements.len() as u32 {
        for u in 0..=n {
            for v in 0..=n - u {
                let bary = [u, v, n - u - v].map(|k| k as f32 / n as f32);
                let x = r.at(elements, b, i, bary).x;
                worst = worst.max(x - 1.0).max(-x);
            }
        }
    }
    worst
}

#[test]
fn hermite_stays_within_the_light_around_it_across_a_step() {
    // Element values that jump from 1 to 0 along an oblique line across the refined
    // floor (a shadow edge the mesh does not know of): the truth is within [0, 1]. The
    // vertex values are (Gouraud stays within it), so what a cubic adds beyond it is its
    // swing between the vertices: with the vertex slopes unlimited, 0.148 at a corner of
    // the floor, where the edge's slope is not seen by the centroids. The limit keeps the
    // plane from each vertex to the centroids and to the third points of its edges within
    // the values there, which bounds every edge's cubic; what is left (measured 0.0011)
    // is the inner control points' cross-edge extrapolation.
    let (_, s) = penumbra(0.1, true);
    let mesh: &Mesh = s.mesh();
    let b: Vec<Vec3> = mesh
        .elements
        .iter()
        .map(|e| {
            let p = e.centroid();
            Vec3::splat(if p.x + 0.37 * p.z < 0.13 { 1.0 } else { 0.0 })
        })
        .collect();
    // 28 points per element.
    let swing = |mode| swing_beyond_unit_range(mode, &mesh.display, &mesh.elements, &b, 6);
    let gouraud = swing(Reconstruction::Gouraud);
    let hermite = swing(Reconstruction::Hermite);
    println!("swing beyond [0, 1]: Gouraud {gouraud:.4}, Hermite {hermite:.4}");
    // f32 rounding of the least-squares fits: 4e-6 measured.
    assert!(
        gouraud <= 1e-5,
        "the vertex values leave [0, 1] by {gouraud}"
    );
    assert!(
        hermite < 0.01,
        "Hermite swings {hermite} beyond the light around it"
    );
}

/// The Cornell box meshed to at most 1,500 elements, and one colour per element, each
/// channel drawn uniformly from [0, 1) (a fixed hash, so every run draws the same).
fn cornell_with_random_colours() -> (Prepared, Vec<Vec3>) {
    use radiosity::geometry::sampling::{hash, unit};
    let prepared = Prepared::new(
        &builtin::cornell_box(),
        &MeshSettings {
            max_elements: Some(1500),
            ..Default::default()
        },
    );
    let colours = (0..prepared.mesh.elements.len() as u64)
        .map(|i| {
            Vec3::new(
                unit(hash(3 * i)),
                unit(hash(3 * i + 1)),
                unit(hash(3 * i + 2)),
            )
        })
        .collect();
    (prepared, colours)
}

#[test]
fn the_viewer_draws_the_hermite_surface_the_cpu_evaluates() {
    // The shader builds each element's Clough–Tocher control points from the vertex
    // values and slopes (`shader.wgsl`, `hermite`); the CPU builds them in
    // `DisplayMesh::bezier`. Every pixel of a rendered Cornell box must show the CPU's
    // value at the surface point its centre's ray meets, through the same exposure and
    // tone map. The irradiance is drawn at random per element, so the slopes are steep
    // and every control point shapes the picture.
    use radiosity::mesh::barycentric;
    use radiosity::view::render::{Display, Solution, ToneMap, headless_device, render_image};
    let scene = builtin::cornell_box();
    let (prepared, colours) = cornell_with_random_colours();
    let solver = prepared.solver(SolverSettings::default()).unwrap();
    let mesh = &prepared.mesh;
    let (reflectance, emission) = (solver.reflectance(), solver.emission());
    let irradiance: Vec<Vec3> = colours.iter().map(|c| *c * 2.0).collect();
    let radiosity: Vec<Vec3> = (irradiance
        .iter()
        .zip(reflectance.iter())
        .zip(emission.iter()))
    .map(|((h, r), e)| *r * *h + *e)
    .collect();
    let camera = radiosity::view::default_camera(mesh, &prepared.bvh);
    let display = Display {
        reconstruction: Reconstruction::Hermite,
        ev: 0.0,
        tonemap: ToneMap::Reinhard,
        textures: false,
        ..Default::default()
    };
    let size = [200u32, 150];
    let image = render_image(
        &headless_device().unwrap(),
        mesh,
        &Solution {
            radiosity: &radiosity,
            reflectance: &reflectance,
            emission: &emission,
        },
        &scene.materials,
        &scene.images,
        &camera,
        &display,
        size,
    )
    .unwrap();
    // The irradiance as the renderer recovers it from B, E and ρ.
    let irradiance = radiosity::solver::irradiance(&radiosity, &reflectance, &emission);
    let hermite = Reconstructor::new(
        Reconstruction::Hermite,
        &mesh.display,
        &mesh.elements,
        &irradiance,
    );
    let exposure = 1.0 / std::f32::consts::PI;
    let encode = |c: f32| {
        (radiosity::scene::textures::linear_to_srgb(c.clamp(0.0, 1.0)) * 255.0).round() as i32
    };
    let mut errors = Vec::new();
    for y in 0..size[1] {
        for x in 0..size[0] {
            let (w, h) = (size[0] as f32, size[1] as f32);
            let (o, d) = camera.ray(x as f32 + 0.5, y as f32 + 0.5, w, h);
            let Some(hit) = prepared.bvh.closest_hit(o, d, 0.0, f32::INFINITY, u32::MAX) else {
                continue;
            };
            let Some(e) = mesh.element_at(hit.triangle, o + d * hit.t, -d) else {
                continue;
            };
            let el = &mesh.elements[e as usize];
            let bary = barycentric(&el.verts, el.project(o + d * hit.t));
            let h = hermite
                .at(&mesh.elements, &irradiance, e, bary)
                .max(Vec3::ZERO);
            let b = reflectance[e as usize] * h + emission[e as usize];
            let want = display.tonemap.apply(b * exposure);
            let got = image.get_pixel(x, y).0;
            for c in 0..3 {
                errors.push((encode(want[c]) - got[c] as i32).abs());
            }
        }
    }
    errors.sort();
    let mean = errors.iter().sum::<i32>() as f64 / errors.len() as f64;
    let p99 = errors[errors.len() * 99 / 100];
    println!(
        "GPU Hermite against the CPU's, {} channels of pixels: mean {mean:.3} levels, \
         99th percentile {p99}, max {}",
        errors.len(),
        errors[errors.len() - 1]
    );
    assert!(errors.len() > 20_000, "{} channels seen", errors.len());
    // Both evaluate the same cubic in f32, so most pixels agree to the level. Pixels
    // differ where the centre's ray and the rasteriser land on two sides of a contact
    // line (the light jumps there) or of a crease, and by a level where rounding does.
    assert!(mean <= 0.2 && p99 <= 2, "mean {mean}, p99 {p99}");
}

#[test]
fn vertex_values_keep_to_the_colours_around_them() {
    // Light whose colour varies from element to element (every channel of every element
    // between 0.2 and 1, drawn at random on the Cornell box's surfaces): a vertex value
    // is the luminance's plane at the vertex times a chromaticity (value over luminance)
    // kept within those of the elements around it, widened by their spread. A channel's
    // own plane, extrapolated to a surface's edge, could put it at 0 while the others
    // stay lit: a colour the light around the vertex does not have (under Sponza's
    // cornice the wall went yellow where blue fell to 0).
    use radiosity::mesh::luminance;
    let (prepared, colours) = cornell_with_random_colours();
    let mesh = &prepared.mesh;
    let values: Vec<Vec3> = colours
        .iter()
        .map(|v| Vec3::splat(0.2) + *v * 0.8)
        .collect();
    let mut around = vec![(Vec3::INFINITY, Vec3::NEG_INFINITY); mesh.display.positions.len()];
    for (e, v) in mesh.elements.iter().zip(&values) {
        for &c in &e.corners {
            let r = &mut around[c as usize];
            *r = (r.0.min(*v / luminance(*v)), r.1.max(*v / luminance(*v)));
        }
    }
    let hanging: std::collections::HashSet<u32> =
        mesh.display.hanging.iter().map(|h| h.vertex).collect();
    let gouraud = mesh.display.vertex_values(&mesh.elements, &values);
    let hermite = mesh.display.hermite(&mesh.elements, &values).values;
    let (mut checked, mut worst) = (0, 0.0f32);
    for (k, (lo, hi)) in around.iter().enumerate() {
        // T-vertices take their coarse edge's value, not a fit of their own.
        if hanging.contains(&(k as u32)) || lo.x > hi.x {
            continue;
        }
        for v in [gouraud[k], hermite[k]] {
            let l = luminance(v);
            if l <= 0.0 {
                continue;
            }
            let c = v / l;
            // Outside the widened range, as a share of the range's top.
            let outside = (*lo - (*hi - *lo) - c)
                .max(c - (*hi + (*hi - *lo)))
                .max(Vec3::ZERO);
            worst = worst.max((outside / *hi).max_element());
            checked += 1;
        }
    }
    println!("{checked} vertex values; worst chromaticity outside the widened range: {worst:.2e}");
    assert!(checked > 1000, "{checked} vertex values");
    // f32 rounding of the value over its luminance.
    assert!(
        worst <= 1e-5,
        "a vertex's colour {worst} beyond those around it"
    );
}

/// A T-vertex at the middle of a short edge whose light steps along it, at the top of a
/// long sliver, as at the foot of Sponza's cornice (where a fan's black apex sits 1 cm from
/// its lit neighbour, and a 0.6 m sliver hangs from between them). The T-vertex takes the
/// edge's cubic, and with it the edge's steep slope; the sliver's long edges leave the
/// short one at an angle, so with the slope across the edge interpolated from the ends the
/// slope along it ran down the sliver, below 0 (measured: −0.014 here; −0.25 W/m² on
/// Sponza, a black line there). The element values are within [0, 1], and so are the
/// vertex values (checked: Gouraud stays within it), so a cubic that leaves [0, 1] swings
/// beyond the light around it; allowed: f32 rounding. Hand-built: the short edge A–E
/// under a coarse element K, the sliver patch A–P–E below it cut into four (its corner C
/// at the middle of A–E hangs on K's edge), dark elements left of A and lit ones right of
/// E.
#[test]
fn a_sliver_below_a_t_vertex_keeps_within_the_light_around_it() {
    use radiosity::mesh::Hanging;
    let p = |x: f32, z: f32| Vec3::new(x, 0.0, z);
    let positions = vec![
        p(0.0, 0.0),       // 0 A
        p(0.01, 0.0),      // 1 E
        p(0.005, 0.0),     // 2 C, on A–E
        p(-0.356, -1.118), // 3 P
        p(-0.178, -0.559), // 4 middle of A–P
        p(-0.173, -0.559), // 5 middle of P–E
        p(0.005, 0.5),     // 6 K's apex
        p(-0.3, 0.0),      // 7 left
        p(0.31, 0.0),      // 8 right
    ];
    let triangles: [([u32; 3], f32); 9] = [
        ([0, 1, 6], 0.5), // K, the coarse element over A–E
        ([7, 0, 6], 0.0), // dark, left of A
        ([7, 4, 0], 0.0),
        ([1, 8, 6], 1.0), // lit, right of E
        ([1, 5, 8], 1.0),
        ([0, 4, 2], 0.3), // the sliver patch A–P–E, cut into four
        ([4, 3, 5], 0.5),
        ([2, 5, 1], 0.6),
        ([4, 5, 2], 0.5),
    ];
    let mut elements = Vec::new();
    let mut values = Vec::new();
    for (corners, value) in triangles {
        let element = Element::over(&positions, corners);
        // All wound the same way (the test's own check on its data).
        assert!(element.normal.y < 0.0, "{corners:?} is wound the other way");
        elements.push(element);
        values.push(Vec3::splat(value));
    }
    let display = DisplayMesh {
        normals: vec![elements[0].normal; positions.len()],
        positions,
        hanging: vec![Hanging {
            vertex: 2,
            edge: [0, 1],
            t: 0.5,
        }],
        shadow_sides: None,
    };
    // 91 points per element, over all nine.
    let swing = |mode| swing_beyond_unit_range(mode, &display, &elements, &values, 12);
    let gouraud = swing(Reconstruction::Gouraud);
    let hermite = swing(Reconstruction::Hermite);
    println!("swing beyond [0, 1]: Gouraud {gouraud:.2e}, Hermite {hermite:.2e}");
    assert!(
        gouraud <= 1e-5,
        "the vertex values leave [0, 1] by {gouraud}"
    );
    assert!(
        hermite <= 1e-5,
        "the sliver's light goes {hermite} beyond [0, 1]"
    );
}

/// A sliver of Sponza's wall under the cornice (0.6 m long, 5 mm across its short edge),
/// with the corner values and slopes the reconstruction gave it there (one channel; the
/// wall in the mesh frame, its normal along −x). Its corners' light is 0.016 to 0.043
/// W/m², and light is never negative, but its Clough–Tocher element went to −0.017
/// inside: seen from the short edge the centroid lies mostly along it (γ ≈ 11), so the
/// step between the short edge's ends, which the corners' slopes do not see, was
/// extrapolated into the element. The inner control points are held within the edges'
/// (no new extremum inside), and the whole element with them.
#[test]
fn a_sliver_s_cubic_makes_no_extremum_inside() {
    use radiosity::mesh::Hermite;
    let p = |y: f32, z: f32| Vec3::new(9.2987, y, z);
    let corners = [
        p(-2.1441948, -0.1637601),
        p(-2.1441948, -0.15853384),
        p(-1.5850648, 0.019391172),
    ];
    let elements = [Element::over(&corners, [0, 1, 2])];
    let slope = |y: f32, z: f32| [Vec3::new(0.0, y, z); 3];
    let h = Hermite {
        values: [0.043269485f32, 0.029726284, 0.016326763]
            .map(Vec3::splat)
            .to_vec(),
        gradients: vec![
            slope(0.016372088, -0.12591152),
            slope(0.0018906817, 0.23768489),
            slope(-1.518141, 4.5060487),
        ],
    };
    let c = DisplayMesh::bezier(&elements, &h, 0);
    let mut least = f32::INFINITY;
    for u in 0..=30 {
        for v in 0..=30 - u {
            let bary = [u as f32 / 30.0, v as f32 / 30.0, (30 - u - v) as f32 / 30.0];
            least = least.min(eval_bezier(&c, bary).x);
        }
    }
    println!("least inside the sliver: {least}");
    assert!(least >= 0.0, "the sliver's light goes down to {least}");
}
