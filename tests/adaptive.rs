//! A-posteriori adaptive subdivision: refinement keeps the solve
//! exact for the refined mesh (new elements are re-evaluated against everything already
//! shot, so no energy is lost or invented), respects the minimum size, is deterministic,
//! and leaves no T-vertex crack in the Gouraud display.
//!
//! Truth: the dense direct solve of the discrete system on the very mesh refinement
//! produced; brute-force search for T-vertices.

mod common;
use common::{converge, prepared, rms};
use glam::Vec3;
use radiosity::mesh::{AdaptiveSettings, Mesh};
use radiosity::pipeline::Prepared;
use radiosity::scene::builtin;
use radiosity::solver::{Method, Solver, SolverSettings};
use std::sync::Arc;

/// The Cornell box meshed coarsely (at most 500 elements), for refinement to work on.
fn cornell() -> Prepared {
    prepared(&builtin::cornell_box(), 500)
}

fn adaptive(method: Method) -> SolverSettings {
    SolverSettings {
        method,
        tolerance: 1e-6,
        adaptive: Some(AdaptiveSettings {
            max_passes: 2,
            ..Default::default()
        }),
        ..Default::default()
    }
}

/// The direct solve on `mesh` (no refinement).
fn direct_on(p: &Prepared, mesh: &Arc<Mesh>) -> Vec<Vec3> {
    let mut s = Solver::new(
        Arc::clone(mesh),
        Arc::clone(&p.bvh),
        p.external.clone(),
        SolverSettings {
            method: Method::Direct,
            ..Default::default()
        },
    )
    .unwrap();
    converge(&mut s);
    s.radiosity()
}

#[test]
fn refinement_keeps_the_solve_exact_on_the_refined_mesh() {
    let p = cornell();
    for method in [Method::Progressive, Method::GaussSeidel] {
        let mut s = p.solver(adaptive(method)).unwrap();
        converge(&mut s);
        let mesh = Arc::clone(s.mesh());
        assert!(
            mesh.elements.len() > p.mesh.elements.len() + 100,
            "{method}: refinement did little ({} → {} elements)",
            p.mesh.elements.len(),
            mesh.elements.len()
        );
        let exact = direct_on(&p, &mesh);
        // Same bound as tests/solvers.rs: tolerance 1e-6 leaves ≲ 4e-6 of the answer, plus
        // f32 storage. A child that did not gather what was already shot would be off by
        // its share of the whole solution (percent level).
        let err = rms(&s.radiosity(), &exact, &mesh);
        assert!(
            err < 1e-4,
            "{method}: RMS difference to direct on the refined mesh {err:e}"
        );
    }
}

#[test]
fn no_element_is_made_smaller_than_the_minimum() {
    let p = cornell();
    let min_size = p.mesh.element_size / 4.0;
    let mut settings = adaptive(Method::Progressive);
    settings.adaptive = Some(AdaptiveSettings {
        min_size: Some(min_size),
        max_passes: 6,
        ..Default::default()
    });
    let mut s = p.solver(settings).unwrap();
    converge(&mut s);
    let size = |e: &radiosity::mesh::Element| (2.0 * e.area as f64).sqrt();
    let smallest_before = p
        .mesh
        .elements
        .iter()
        .map(size)
        .fold(f64::INFINITY, f64::min);
    let floor = min_size.min(smallest_before);
    // The size is measured by area. A sliver (a piece cut along a contact line) is split
    // below it only by 2:1 balance, to match its neighbour's finer elements along its long
    // edge: that edge still spans the minimum. So an element passes when its size or its
    // longest edge reaches the floor.
    let longest = |e: &radiosity::mesh::Element| {
        (0..3)
            .map(|k| (e.verts[k] - e.verts[(k + 1) % 3]).length() as f64)
            .fold(0.0, f64::max)
    };
    for e in &s.mesh().elements {
        // f32 areas: 1e-3 relative.
        assert!(
            size(e) >= floor * 0.999 || longest(e) >= floor * 0.999,
            "element of {} m (longest edge {} m) below {floor}",
            size(e),
            longest(e)
        );
    }
}

#[test]
fn refinement_is_deterministic() {
    let p = cornell();
    let run = || {
        let mut s = p.solver(adaptive(Method::Progressive)).unwrap();
        converge(&mut s);
        (s.mesh().elements.len(), s.radiosity())
    };
    let (n1, b1) = run();
    let (n2, b2) = run();
    assert_eq!(n1, n2);
    assert!(b1 == b2, "two runs differ");
}

#[test]
fn every_t_vertex_takes_its_value_from_the_coarse_edge() {
    let p = cornell();
    let mut s = p.solver(adaptive(Method::Progressive)).unwrap();
    converge(&mut s);
    let mesh = s.mesh();
    let d = &mesh.display;
    // Brute force: every display vertex at the midpoint of some element's edge that is not
    // one of that element's corners (same surface: normals agree) is a T-vertex; except on
    // a contact line, where only vertices of the element's own side (region) count: the
    // light jumps across the line, so the other side's vertices are not shared.
    let eps = mesh.scale * 1e-6;
    let mut regions: Vec<Vec<u32>> = vec![Vec::new(); d.positions.len()];
    for e in &mesh.elements {
        for &c in &e.corners {
            regions[c as usize].push(mesh.patches[e.patch as usize].region);
        }
    }
    let on_cut = |p: glam::Vec3, patch: &radiosity::mesh::Patch| {
        patch.cuts.clone().any(|c| {
            let [a, b] = mesh.cut_edges[c as usize];
            let t = ((p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
            (a + (b - a) * t - p).length() <= mesh.scale * 1e-5
        })
    };
    let mut expected = std::collections::HashSet::new();
    for e in &mesh.elements {
        let patch = &mesh.patches[e.patch as usize];
        for k in 0..3 {
            let m = (e.verts[k] + e.verts[(k + 1) % 3]) * 0.5;
            for (v, (pos, n)) in d.positions.iter().zip(&d.normals).enumerate() {
                if (*pos - m).length() <= eps
                    && n.dot(e.normal) > 0.86
                    && (!on_cut(m, patch) || regions[v].contains(&patch.region))
                {
                    expected.insert(v as u32);
                }
            }
        }
    }
    assert!(
        !mesh.cut_edges.is_empty(),
        "the Cornell box has contact lines to check"
    );
    assert!(!expected.is_empty(), "refinement left no T-vertex to check");
    let found: std::collections::HashSet<u32> = d
        .hanging
        .iter()
        .filter(|h| h.is_midpoint())
        .map(|h| h.vertex)
        .collect();
    assert_eq!(found, expected);
    // And the Gouraud value there is the coarse edge's.
    let values = d.vertex_values(&mesh.elements, &s.radiosity());
    for h in d.hanging.iter().filter(|h| h.is_midpoint()) {
        let [a, b] = h.edge.map(|v| values[v as usize]);
        let want = (a + b) * 0.5;
        assert!((values[h.vertex as usize] - want).length() <= 1e-5 * want.length().max(1e-6));
    }
}
