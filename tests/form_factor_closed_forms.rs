//! Point-to-polygon form factors against closed forms from the radiation literature.
//!
//! Closed forms are cited from J. R. Howell, *A Catalog of Radiation Heat Transfer
//! Configuration Factors* (3rd ed., thermalradiation.net; also Siegel & Howell, *Thermal
//! Radiation Heat Transfer*, appendix C), by catalogue number. Where a formula is
//! transcribed, it is first checked against a brute-force quadrature of the defining integral
//! F = ∫ cosθ_i cosθ_j / (π s²) dA or against a value printed in the literature, so that a
//! transcription error cannot pass for a bug (or hide one).
//!
//! Tolerances: see `common::F32_REL` and `common::contour_slack`. Vertices are given in f32, but every closed form here
//! is evaluated from the same f32 values, so input rounding does not count.
//!
//! The estimators on meshes (conservation laws, the hemicube, contact) are in
//! `form_factors.rs`.

mod common;
use common::{F32_REL, contour_slack, ptp};
use glam::{DVec3, Vec3};
use std::f64::consts::PI;

/// The quad corner, corner + u, corner + u + v, corner + v.
fn quad(corner: Vec3, u: Vec3, v: Vec3) -> [Vec3; 4] {
    [corner, corner + u, corner + u + v, corner + v]
}

/// Form factor to a quad given as two triangles (their sum: disjoint pieces add).
fn ptp_two_triangles(p: Vec3, n: Vec3, q: &[Vec3; 4]) -> f64 {
    ptp(p, n, &[q[0], q[1], q[2]]) + ptp(p, n, &[q[0], q[2], q[3]])
}

/// The f32 error bound of [`ptp_two_triangles`]: the sum of its triangles' slacks.
fn two_triangles_slack(p: Vec3, q: &[Vec3; 4]) -> f64 {
    contour_slack(p, &[q[0], q[1], q[2]]) + contour_slack(p, &[q[0], q[2], q[3]])
}

/// Form factor to a regular `sides`-gon of circumradius `radius` centred at `centre` in the
/// plane z = centre.z, as a fan of triangles (`point_to_polygon` takes at most six vertices).
fn ptp_ngon(p: Vec3, n: Vec3, centre: Vec3, radius: f64, sides: usize) -> f64 {
    let vertex = |k: usize| {
        let a = 2.0 * PI * k as f64 / sides as f64;
        centre + Vec3::new((radius * a.cos()) as f32, (radius * a.sin()) as f32, 0.0)
    };
    (0..sides)
        .map(|k| ptp(p, n, &[centre, vertex(k), vertex(k + 1)]))
        .sum()
}

/// Brute-force midpoint quadrature of F = ∫ cosθ_i cosθ_j / (π s²) dA over the
/// parallelogram corner + [0,1]u + [0,1]v (both sides count as its front when facing p),
/// `m × m` cells, f64. Used only to check the transcription of closed forms.
fn quadrature(p: DVec3, n: DVec3, corner: DVec3, u: DVec3, v: DVec3, m: usize) -> f64 {
    let nq = u.cross(v);
    let da = nq.length() / (m * m) as f64;
    let nq = nq.normalize();
    let mut sum = 0.0;
    for i in 0..m {
        for j in 0..m {
            let y = corner + u * ((i as f64 + 0.5) / m as f64) + v * ((j as f64 + 0.5) / m as f64);
            let d = y - p;
            let s2 = d.length_squared();
            let s = s2.sqrt();
            let ci = n.dot(d) / s;
            let cj = (nq.dot(d) / s).abs();
            if ci > 0.0 {
                sum += ci * cj / (PI * s2) * da;
            }
        }
    }
    sum
}

/// `got` within `rel` of `want` relative, plus `slack` absolute.
fn assert_close(got: f64, want: f64, rel: f64, slack: f64, what: &str) {
    assert!(
        got.is_finite() && (got - want).abs() <= rel * want.abs() + slack + 1e-12,
        "{what}: got {got:.9e}, want {want:.9e} (relative error {:.2e} > {rel:.0e})",
        (got - want).abs() / want.abs()
    );
}

// ---------------------------------------------------------------------------------------
// Differential area to finite area (Howell section B)
// ---------------------------------------------------------------------------------------

/// Howell B-3: plane element dA parallel to a rectangle a × b at distance c, on the normal
/// through one of its corners. A = a/c, B = b/c:
/// F = 1/(2π) [A/√(1+A²) atan(B/√(1+A²)) + B/√(1+B²) atan(A/√(1+B²))].
fn howell_b3(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / c, b / c);
    let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * PI)
}

/// Plane element dA perpendicular to a rectangle (Howell B-8 with the planes at Φ = π/2;
/// Hamilton & Morgan 1952): the rectangle spans a along the line where the element's plane
/// meets the rectangle's plane and b away from the element's plane; the element lies at
/// distance d from the rectangle's plane, on the normal to that line through a corner.
/// With X = b/a, Y = d/a: F = 1/(2π) [atan(1/Y) − Y/√(X²+Y²) · atan(1/√(X²+Y²))].
/// (Also Lambert's contour integral by hand: the edge in the element's plane gives
/// atan(a/d), the far edge −d/√(b²+d²) · atan(a/√(b²+d²)), the other two nothing.)
fn perpendicular_corner(a: f64, b: f64, d: f64) -> f64 {
    let (x, y) = (b / a, d / a);
    let r = (x * x + y * y).sqrt();
    ((1.0 / y).atan() - y / r * (1.0 / r).atan()) / (2.0 * PI)
}

#[test]
fn closed_forms_for_points_match_brute_force_quadrature() {
    // 1000² midpoint cells: relative error O((cell/distance)²) ≈ 1e-6 for these unit-scale
    // cases; 1e-4 is a loose bound that still catches any transcription slip.
    let m = 1000;
    for (a, b, c) in [(1.0, 1.0, 1.0), (2.0, 0.5, 0.7)] {
        let q = quadrature(
            DVec3::ZERO,
            DVec3::Z,
            DVec3::new(0.0, 0.0, c),
            DVec3::X * a,
            DVec3::Y * b,
            m,
        );
        assert_close(howell_b3(a, b, c), q, 1e-4, 0.0, "B-3 vs quadrature");
    }
    for (a, b, d) in [(1.0, 1.0, 1.0), (2.0, 0.5, 0.3)] {
        let q = quadrature(
            DVec3::ZERO,
            DVec3::Z,
            DVec3::new(0.0, d, 0.0),
            DVec3::X * a,
            DVec3::Z * b,
            m,
        );
        assert_close(
            perpendicular_corner(a, b, d),
            q,
            1e-4,
            0.0,
            "perpendicular vs quadrature",
        );
    }
}

#[test]
fn point_to_parallel_rectangle_matches_howell_b3() {
    // Includes near-contact (c → 0: F → 1/4, the corner's quarter hemisphere) and far field
    // (c = 10⁴: F ≈ ab/(πc²) ≈ 3e-9, where the contour terms cancel to (a/c)² and
    // `point_to_polygon` takes the point formula instead, good to (a/c)² relative).
    let cases = [
        (1.0, 1.0, 1.0),
        (2.0, 0.5, 1.0),
        (0.3, 3.0, 0.7),
        (1.0, 1.0, 1e-3),
        (1.0, 1.0, 1e-6),
        (5.0, 2.0, 1e-9),
        (1.0, 1.0, 1e3),
        (0.5, 2.0, 1e4),
    ];
    for (a, b, c) in cases {
        let (a32, b32, c32) = (a as f32, b as f32, c as f32);
        let rect = quad(Vec3::new(0.0, 0.0, c32), Vec3::X * a32, Vec3::Y * b32);
        let want = howell_b3(a32 as f64, b32 as f64, c32 as f64);
        let what = format!("B-3 a={a} b={b} c={c}");
        let slack = contour_slack(Vec3::ZERO, &rect);
        assert_close(
            ptp(Vec3::ZERO, Vec3::Z, &rect),
            want,
            F32_REL,
            slack,
            &format!("{what}, quad"),
        );
        assert_close(
            ptp_two_triangles(Vec3::ZERO, Vec3::Z, &rect),
            want,
            F32_REL,
            two_triangles_slack(Vec3::ZERO, &rect),
            &format!("{what}, two triangles"),
        );
        // Either winding.
        let mut rev = rect;
        rev.reverse();
        assert_close(
            ptp(Vec3::ZERO, Vec3::Z, &rev),
            want,
            F32_REL,
            slack,
            &format!("{what}, reversed"),
        );
    }
    // Touching: the point in the rectangle's plane (inside, at a corner, on an edge) or
    // behind it. Any value must be finite and in [0, 1]; behind must be 0.
    let rect = quad(Vec3::new(-1.0, -1.0, 0.0), Vec3::X * 2.0, Vec3::Y * 2.0);
    for p in [
        Vec3::ZERO,
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(0.0, -1.0, 0.0),
        Vec3::new(0.0, 0.0, -1e-9),
    ] {
        for f in [ptp(p, Vec3::Z, &rect), ptp_two_triangles(p, Vec3::Z, &rect)] {
            assert!(
                f.is_finite() && (0.0..=1.0).contains(&f),
                "touching at {p}: {f}"
            );
        }
    }
    assert_eq!(
        ptp(Vec3::new(0.0, 0.0, 1e-3), Vec3::Z, &rect),
        0.0,
        "a rectangle behind the point"
    );
}

#[test]
fn point_to_perpendicular_rectangle_matches_closed_form() {
    for (a, b, d) in [
        (1.0, 1.0, 1.0),
        (2.0, 0.5, 0.3),
        (0.2, 3.0, 1.0),
        (1.0, 1.0, 1e-6),
        (1.0, 1.0, 1e3),
    ] {
        let (a32, b32, d32) = (a as f32, b as f32, d as f32);
        let rect = quad(Vec3::new(0.0, d32, 0.0), Vec3::X * a32, Vec3::Z * b32);
        let want = perpendicular_corner(a32 as f64, b32 as f64, d32 as f64);
        let what = format!("perpendicular a={a} b={b} d={d}");
        let slack = contour_slack(Vec3::ZERO, &rect);
        assert_close(ptp(Vec3::ZERO, Vec3::Z, &rect), want, F32_REL, slack, &what);
        assert_close(
            ptp_two_triangles(Vec3::ZERO, Vec3::Z, &rect),
            want,
            F32_REL,
            two_triangles_slack(Vec3::ZERO, &rect),
            &what,
        );
    }
}

/// Howell B-13 (plane element to a parallel coaxial disc of radius r at height h):
/// F = r² / (h² + r²).
fn point_to_disc(r: f64, h: f64) -> f64 {
    r * r / (h * h + r * r)
}

#[test]
fn point_to_coaxial_disc_is_bracketed_by_polygons() {
    // The disc is approximated by regular N-gons: the inscribed one (circumradius r) lies
    // inside it and the circumscribed one (circumradius r / cos(π/N)) contains it. The kernel
    // cosθ_i cosθ_j/(π s²) is positive, so F(inscribed) ≤ F(disc) ≤ F(circumscribed): a
    // rigorous bracket. Its width is the area between them, N r² (tan(π/N) − sin(2π/N)/2)
    // ≈ π r² (π/N)², times the largest kernel over that annulus, h²/(π (h² + (r cos π/N)²)²)
    // for a point on the axis: ~1.5e-4 relative at N = 256.
    let sides = 256;
    let half = PI / sides as f64;
    for (r, h) in [(1.0, 1.0), (0.5, 2.0), (3.0, 0.1), (1.0, 1e-4), (1e-3, 1.0)] {
        let centre = Vec3::new(0.0, 0.0, h as f32);
        let want = point_to_disc(r, h as f32 as f64);
        let inner = ptp_ngon(Vec3::ZERO, Vec3::Z, centre, r, sides);
        let outer = ptp_ngon(Vec3::ZERO, Vec3::Z, centre, r / half.cos(), sides);
        let slack = F32_REL * want;
        assert!(
            inner <= want + slack && want <= outer + slack,
            "r={r} h={h}: {inner} ≤ {want} ≤ {outer} fails"
        );
        let gap_area = sides as f64 * r * r * (half.tan() - (2.0 * half).sin() / 2.0);
        let hh = h * h;
        let kernel = hh / (PI * (hh + (r * half.cos()).powi(2)).powi(2));
        assert!(
            outer - inner <= gap_area * kernel + 2.0 * slack,
            "r={r} h={h}: bracket {} wider than {}",
            outer - inner,
            gap_area * kernel
        );
    }
}

// ---------------------------------------------------------------------------------------
// Finite area to finite area (Howell section C): area averages of point values
// ---------------------------------------------------------------------------------------

/// Howell C-11: identical parallel directly opposed rectangles a × b at distance c.
/// X = a/c, Y = b/c:
/// F = 2/(πXY) { ln √[(1+X²)(1+Y²)/(1+X²+Y²)] + X√(1+Y²) atan(X/√(1+Y²))
///               + Y√(1+X²) atan(Y/√(1+X²)) − X atan X − Y atan Y }.
fn howell_c11(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / c, b / c);
    let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    let log = (((1.0 + x * x) * (1.0 + y * y)) / (1.0 + x * x + y * y))
        .sqrt()
        .ln();
    2.0 / (PI * x * y)
        * (log + x * sy * (x / sy).atan() + y * sx * (y / sx).atan() - x * x.atan() - y * y.atan())
}

/// Howell C-14: rectangles at 90° sharing an edge of length l; A₁ is l × w, A₂ is l × h.
/// H = h/l, W = w/l:
/// ```text
/// F₁₂ = 1/(πW) ( W atan(1/W) + H atan(1/H) − √(H²+W²) atan(1/√(H²+W²))
///   + ¼ ln{ (1+W²)(1+H²)/(1+W²+H²) · [W²(1+W²+H²)/((1+W²)(W²+H²))]^{W²}
///           · [H²(1+H²+W²)/((1+H²)(H²+W²))]^{H²} } ).
/// ```
fn howell_c14(l: f64, w: f64, h: f64) -> f64 {
    let (hh, ww) = (h / l, w / l);
    let (h2, w2) = (hh * hh, ww * ww);
    let r = (h2 + w2).sqrt();
    let log = ((1.0 + w2) * (1.0 + h2) / (1.0 + w2 + h2)).ln()
        + w2 * (w2 * (1.0 + w2 + h2) / ((1.0 + w2) * (w2 + h2))).ln()
        + h2 * (h2 * (1.0 + h2 + w2) / ((1.0 + h2) * (h2 + w2))).ln();
    (ww * (1.0 / ww).atan() + hh * (1.0 / hh).atan() - r * (1.0 / r).atan() + 0.25 * log)
        / (PI * ww)
}

/// Howell C-41: coaxial parallel discs, r₁ receiving, r₂ at distance h. R_i = r_i/h,
/// X = 1 + (1 + R₂²)/R₁²: F₁₂ = ½ [X − √(X² − 4 (R₂/R₁)²)].
fn howell_c41(r1: f64, r2: f64, h: f64) -> f64 {
    let (a, b) = (r1 / h, r2 / h);
    let x = 1.0 + (1.0 + b * b) / (a * a);
    0.5 * (x - (x * x - 4.0 * (b / a).powi(2)).sqrt())
}

#[test]
fn area_closed_forms_match_published_values() {
    // Printed values: Siegel & Howell's example for C-11 (a = 1, b = 1.5, c = 0.5: 0.4756, as
    // reproduced in EES's view factor library); the classic 0.2000 for perpendicular unit
    // squares (C-14); 0.382 = (3 − √5)/2 for equal discs one radius apart (C-41).
    assert!((howell_c11(1.0, 1.5, 0.5) - 0.4756).abs() < 5e-5);
    assert!((howell_c14(1.0, 1.0, 1.0) - 0.200_044).abs() < 1e-6);
    assert!((howell_c41(1.0, 1.0, 1.0) - (3.0 - 5f64.sqrt()) / 2.0).abs() < 1e-12);
}

/// Midpoint-rule average of `f` over the rectangle corner + [0,1]u + [0,1]v, `n × n` cells.
fn average_over_rectangle(
    corner: Vec3,
    u: Vec3,
    v: Vec3,
    n: usize,
    f: impl Fn(Vec3) -> f64,
) -> f64 {
    let mut sum = 0.0;
    for i in 0..n {
        for j in 0..n {
            let (s, t) = ((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
            sum += f(corner + u * s + v * t);
        }
    }
    sum / (n * n) as f64
}

/// Checks a midpoint-rule area average against a closed form. The midpoint rule converges as
/// O(1/n²) for these integrands (smooth inside the receiver, mild corner singularities at
/// shared edges), so the n-grid's error is about (F_n − F_2n)·4/3 and the 2n-grid's about a
/// third of |F_n − F_2n|: the 2n value must lie within |F_n − F_2n| of the closed form (a
/// factor 3 of margin) plus f32 rounding, and the errors must shrink with n.
fn check_convergence(coarse: f64, fine: f64, want: f64, what: &str) {
    let step = (coarse - fine).abs();
    let err_fine = (fine - want).abs();
    let err_coarse = (coarse - want).abs();
    assert!(
        err_fine <= step + F32_REL * want,
        "{what}: fine grid error {err_fine:.3e} > step {step:.3e}"
    );
    assert!(
        err_fine <= err_coarse + F32_REL * want,
        "{what}: error grew with n ({err_coarse:.3e} → {err_fine:.3e})"
    );
}

#[test]
fn parallel_rectangles_match_howell_c11() {
    for (a, b, c) in [
        (1.0f32, 1.0f32, 1.0f32),
        (1.0, 1.5, 0.5),
        (2.0, 0.5, 0.25),
        (0.5, 0.5, 2.0),
    ] {
        let emitter = quad(Vec3::new(0.0, 0.0, c), Vec3::X * a, Vec3::Y * b);
        let point = |x: Vec3| ptp(x, Vec3::Z, &emitter);
        let avg = |n| average_over_rectangle(Vec3::ZERO, Vec3::X * a, Vec3::Y * b, n, point);
        let want = howell_c11(a as f64, b as f64, c as f64);
        check_convergence(avg(32), avg(64), want, &format!("C-11 a={a} b={b} c={c}"));
    }
}

#[test]
fn perpendicular_rectangles_match_howell_c14() {
    for (l, w, h) in [(1.0f32, 1.0f32, 1.0f32), (1.0, 0.5, 2.0), (2.0, 1.0, 0.3)] {
        // A₁ in z = 0 (normal +z), A₂ in y = 0 (normal +y), common edge along x.
        let emitter = quad(Vec3::ZERO, Vec3::X * l, Vec3::Z * h);
        let point = |x: Vec3| ptp(x, Vec3::Z, &emitter);
        let avg = |n| average_over_rectangle(Vec3::ZERO, Vec3::X * l, Vec3::Y * w, n, point);
        let want = howell_c14(l as f64, w as f64, h as f64);
        check_convergence(avg(32), avg(64), want, &format!("C-14 l={l} w={w} h={h}"));
    }
}

#[test]
fn coaxial_discs_match_howell_c41() {
    // Receiver: the exact disc r₁, integrated over its radius by the midpoint rule with
    // weight 2ρ/r₁² (the true disc is symmetric, so one radial line suffices: along it the
    // polygon bracket below holds point by point). Emitter: inscribed and circumscribed
    // 256-gons, which bracket the disc's value as in `point_to_coaxial_disc_...`.
    let sides = 256;
    let half = PI / sides as f64;
    for (r1, r2, h) in [
        (1.0, 1.0, 1.0),
        (0.5, 1.0, 1.0),
        (1.0, 0.5, 0.2),
        (2.0, 1.0, 3.0),
    ] {
        let centre = Vec3::new(0.0, 0.0, h as f32);
        let average = |radius: f64, n: usize| {
            (0..n)
                .map(|k| {
                    let rho = r1 * (k as f64 + 0.5) / n as f64;
                    let f = ptp_ngon(
                        Vec3::new(rho as f32, 0.0, 0.0),
                        Vec3::Z,
                        centre,
                        radius,
                        sides,
                    );
                    f * 2.0 * rho / (r1 * r1) * (r1 / n as f64)
                })
                .sum::<f64>()
        };
        let want = howell_c41(r1, r2, h);
        let (inner, inner_fine) = (average(r2, 64), average(r2, 128));
        let (outer, outer_fine) = (average(r2 / half.cos(), 64), average(r2 / half.cos(), 128));
        let quad_err = (inner - inner_fine).abs().max((outer - outer_fine).abs()) + F32_REL * want;
        assert!(
            inner_fine - quad_err <= want && want <= outer_fine + quad_err,
            "C-41 r1={r1} r2={r2} h={h}: {inner_fine} ≤ {want} ≤ {outer_fine} (± {quad_err:.1e}) fails"
        );
        // The bracket is tight: polygons within ~2e-4 relative of the disc (see above).
        assert!(
            outer_fine - inner_fine <= 1e-3 * want,
            "C-41 bracket too wide: {inner_fine} .. {outer_fine}"
        );
    }
}
