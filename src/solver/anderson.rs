//! Anderson acceleration of a sweep's fixed-point iteration B ← G(B) = E' + ρ K B
//! (D. G. Anderson, "Iterative procedures for nonlinear integral equations", J. ACM 12(4),
//! 1965; in the form of H. F. Walker & P. Ni, "Anderson acceleration for fixed-point
//! iterations", SIAM J. Numer. Anal. 49(4), 2011, with a window of m columns).
//!
//! A Jacobi sweep shrinks the error by the spectral radius of ρK. In a closed scene that is
//! about the mean reflectance ρ̄ (light bounces until it is absorbed, and the slowest mode
//! is the nearly uniform one), so reaching a relative change τ takes ln τ / ln ρ̄ sweeps:
//! 14,000 at ρ̄ = 0.999 and τ = 10⁻⁶. Anderson's step combines the last sweeps: with the
//! residuals f_i = G(x_i) − x_i and the columns ΔF = [f_{i+1} − f_i], ΔG = [G(x_{i+1}) −
//! G(x_i)] over the window, it takes
//!
//! γ = argmin_γ ‖f_k − ΔF γ‖,   x_{k+1} = G(x_k) − ΔG γ.
//!
//! For a linear G and an unlimited window this is GMRES (Walker & Ni, Theorem 2.2); with
//! a window of a few columns it stays close to it, and the slow modes go in a few sweeps.
//!
//! The norm weighs each element's residual relative to its own radiosity (floored at
//! [`DARK_FLOOR`] of the area-weighted mean, so that black elements do not take it over):
//! ‖f‖² = Σ_e |f_e|² / max(b_e, b_floor)², with b_e the sum of the image's channels. One
//! γ serves every element, and fitted to area-weighted residuals it answers only to the
//! large surfaces: where small elements go their own way it may throw them far off, and
//! nothing sees it. The foot of nvpro's white sphere (ρ = 0.999, elements of 3·10⁻⁹ m² in
//! an 18° wedge of the floor) swung between 0 and 2.3 W/m², with a period of about ten
//! sweeps, through the 90 sweeps the area-weighted norm took to stop, and stopped at 0;
//! plain sweeps from there settle at 0.17 in a few. Weighed relative to its own light,
//! such an element's residual counts as much as any other's, and the window restarts when
//! it grows.
//!
//! The least squares are solved through the normal equations in f64 with a relative ridge
//! of 10⁻¹⁰ (m ≤ 5 columns), and the window restarts whenever the residual grows, so a
//! step never does worse for long than the plain sweep would. Values below zero (a step
//! may overshoot where B is near 0) are cut off: B is a radiosity.

use super::{ELEMENT_CHUNK, ordered_sum};
use glam::{DVec2, DVec3, Vec3};
use rayon::prelude::*;
use std::collections::VecDeque;

/// Columns kept (Walker & Ni find 3–5 enough for linear problems).
const WINDOW: usize = 5;

/// The residual may grow by this factor before the window restarts.
const GROWTH: f64 = 1.0;

/// The radiosity below which the norm weighs an element's residual as if it had this
/// much, relative to the area-weighted mean radiosity: a twentieth, so that an element
/// in deep shadow counts at most twenty times as much per unit of residual as one at
/// the mean, and a black one (a sealed inside) does not divide by zero.
const DARK_FLOOR: f64 = 0.05;

/// The iteration's history: see the module documentation.
#[derive(Default)]
pub(super) struct Anderson {
    /// The last iterate's residual and image.
    last: Option<(Vec<DVec3>, Vec<DVec3>)>,
    /// (Δf, Δg) columns, oldest first.
    columns: VecDeque<(Vec<Vec3>, Vec<Vec3>)>,
}

impl Anderson {
    /// Forgets the history: the map G changed (new links, elements or materials).
    pub fn restart(&mut self) {
        self.last = None;
        self.columns.clear();
    }

    /// The next iterate from the current one, `x`, and its sweep's image `g` = G(x);
    /// `scales`: [`LightScales::of`] `g`, what each element's residual is weighed against.
    pub fn next(&mut self, x: &[DVec3], g: Vec<DVec3>, scales: &LightScales) -> Vec<DVec3> {
        if self
            .last
            .as_ref()
            .is_some_and(|(f0, _)| f0.len() != x.len())
        {
            self.restart(); // another set of elements: the history does not apply
        }
        let f: Vec<DVec3> = g
            .par_iter()
            .zip(x)
            .with_min_len(ELEMENT_CHUNK)
            .map(|(g, x)| *g - *x)
            .collect();
        let weights = scales.weights();
        let weight = |e: usize| weights[e];
        let norm = |f: &[DVec3]| dot(|e| f[e], |e| f[e], &weight, f.len()).sqrt();
        match self.last.take() {
            // The last residual in this sweep's weights.
            Some((f0, _)) if norm(&f) > GROWTH * norm(&f0) => self.columns.clear(),
            Some((f0, g0)) => {
                let delta = |a: &[DVec3], b: &[DVec3]| -> Vec<Vec3> {
                    a.iter().zip(b).map(|(a, b)| (*a - *b).as_vec3()).collect()
                };
                if self.columns.len() == WINDOW {
                    self.columns.pop_front();
                }
                self.columns.push_back((delta(&f, &f0), delta(&g, &g0)));
            }
            None => {}
        }
        let gamma = self.coefficients(&f, &weight);
        let mut next = g.clone();
        if let Some(gamma) = gamma {
            next.par_iter_mut()
                .enumerate()
                .with_min_len(ELEMENT_CHUNK)
                .for_each(|(e, v)| {
                    for (c, (_, dg)) in gamma.iter().zip(&self.columns) {
                        *v -= dg[e].as_dvec3() * *c;
                    }
                    *v = v.max(DVec3::ZERO);
                });
        }
        self.last = Some((f, g));
        next
    }

    /// γ minimising ‖f − ΔF γ‖ (normal equations, Cholesky with a ridge); `None` without
    /// columns or when they are degenerate.
    fn coefficients(
        &self,
        f: &[DVec3],
        weight: &(impl Fn(usize) -> f32 + Sync),
    ) -> Option<Vec<f64>> {
        let m = self.columns.len();
        if m == 0 {
            return None;
        }
        let mut a = vec![vec![0.0f64; m]; m];
        let mut b = vec![0.0f64; m];
        for (i, (di, _)) in self.columns.iter().enumerate() {
            b[i] = dot(|e| di[e].as_dvec3(), |e| f[e], weight, f.len());
            for (j, (dj, _)) in self.columns.iter().enumerate().take(i + 1) {
                let v = dot(|e| di[e].as_dvec3(), |e| dj[e].as_dvec3(), weight, f.len());
                a[i][j] = v;
                a[j][i] = v;
            }
        }
        let ridge = 1e-10 * (0..m).map(|i| a[i][i]).sum::<f64>();
        // Also false for NaN.
        if !(ridge.is_finite() && ridge > 0.0) {
            return None;
        }
        for (i, row) in a.iter_mut().enumerate() {
            row[i] += ridge;
        }
        let gamma = cholesky_solve(a, b)?;
        gamma.iter().all(|g| g.is_finite()).then_some(gamma)
    }
}

/// The light each element's residual is measured against (see the module
/// documentation): `per_element[e]` = max(b_e, b_floor), with b_e the sum of element e's
/// channels and `floor` = b_floor, [`DARK_FLOOR`] times their area-weighted mean (0 where
/// everything is black). Made once per sweep, for Anderson's norm and for the sweep's
/// worst element residual.
pub(super) struct LightScales {
    pub per_element: Vec<f64>,
    pub floor: f64,
}

impl LightScales {
    /// The scales of radiosities `b` over elements of areas `area(e)`.
    pub fn of(b: &[DVec3], area: impl Fn(usize) -> f32 + Sync) -> LightScales {
        let sums = ordered_sum(b.len(), |e| {
            DVec2::new(b[e].element_sum(), 1.0) * area(e) as f64
        });
        let floor = if sums.y > 0.0 {
            DARK_FLOOR * sums.x / sums.y
        } else {
            0.0
        };
        let per_element = b
            .par_iter()
            .with_min_len(ELEMENT_CHUNK)
            .map(|v| v.element_sum().max(floor))
            .collect();
        LightScales { per_element, floor }
    }

    /// Each element's weight in the norm, 1 / scale_e² scaled into (0, 1] by the floor
    /// (γ does not depend on the scale). All 1 where everything is black.
    fn weights(&self) -> Vec<f32> {
        let floor = self.floor;
        self.per_element
            .par_iter()
            .with_min_len(ELEMENT_CHUNK)
            .map(|scale| {
                if floor > 0.0 {
                    (floor / scale).powi(2) as f32
                } else {
                    1.0
                }
            })
            .collect()
    }
}

/// Solves A x = b for symmetric positive definite A; `None` if it is not.
fn cholesky_solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let n = b.len();
    for j in 0..n {
        let d = a[j][j] - (0..j).map(|k| a[j][k] * a[j][k]).sum::<f64>();
        // Not positive, or NaN.
        if d.is_nan() || d <= 0.0 {
            return None;
        }
        let d = d.sqrt();
        a[j][j] = d;
        for i in j + 1..n {
            a[i][j] = (a[i][j] - (0..j).map(|k| a[i][k] * a[j][k]).sum::<f64>()) / d;
        }
    }
    for i in 0..n {
        b[i] = (b[i] - (0..i).map(|k| a[i][k] * b[k]).sum::<f64>()) / a[i][i];
    }
    for i in (0..n).rev() {
        b[i] = (b[i] - (i + 1..n).map(|k| a[k][i] * b[k]).sum::<f64>()) / a[i][i];
    }
    Some(b)
}

/// Area-weighted inner product Σ_e w(e) u(e) · v(e) over `n` elements, summed in a
/// fixed order ([`ordered_sum`]).
fn dot(
    u: impl Fn(usize) -> DVec3 + Sync,
    v: impl Fn(usize) -> DVec3 + Sync,
    w: &(impl Fn(usize) -> f32 + Sync),
    n: usize,
) -> f64 {
    ordered_sum(n, |e| u(e).dot(v(e)) * w(e) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A linear map with one slow mode, G(x) = c + T x: T scales the uniform direction by
    /// 0.999 and the others by 0.3. Jacobi needs about 14,000 steps to reach 10⁻⁶; the
    /// accelerated iteration must reach the exact fixed point x* = (I − T)⁻¹ c to 10⁻⁶
    /// within 10 (GMRES on a matrix with two distinct eigenvalues converges in two steps,
    /// Walker & Ni §2; the f32 columns and the ridge may cost a few more: it takes 4).
    #[test]
    fn a_slow_uniform_mode_goes_in_a_few_steps() {
        let n = 1000;
        let weight: Vec<f32> = (0..n).map(|i| 1.0 + (i % 7) as f32).collect();
        let total: f64 = weight.iter().map(|w| *w as f64).sum();
        let c: Vec<DVec3> = (0..n)
            .map(|i| DVec3::new(i as f64 % 3.0, 1.0, (i * 7 % 11) as f64))
            .collect();
        // T x = 0.3 x + (0.999 − 0.3) · (weighted mean of x), per channel.
        let apply = |x: &[DVec3]| -> Vec<DVec3> {
            let mean = x
                .iter()
                .zip(&weight)
                .map(|(v, w)| *v * *w as f64)
                .sum::<DVec3>()
                / total;
            x.iter()
                .zip(&c)
                .map(|(v, c)| *c + *v * 0.3 + mean * (0.999 - 0.3))
                .collect()
        };
        // The fixed point: the mean m satisfies m = c̄ + 0.999 m → m = c̄ / 0.001; then
        // x = (c + 0.699 m) / 0.7.
        let c_mean = c
            .iter()
            .zip(&weight)
            .map(|(v, w)| *v * *w as f64)
            .sum::<DVec3>()
            / total;
        let m = c_mean / 0.001;
        let exact: Vec<DVec3> = c.iter().map(|c| (*c + m * 0.699) / 0.7).collect();
        let mut acc = Anderson::default();
        let mut x = vec![DVec3::ZERO; n];
        let mut steps = 0;
        let error = |x: &[DVec3]| {
            x.iter()
                .zip(&exact)
                .map(|(a, b)| ((*a - *b).abs() / b.abs()).max_element())
                .fold(0.0, f64::max)
        };
        while error(&x) > 1e-6 {
            steps += 1;
            assert!(steps <= 10, "still {} off after 10 steps", error(&x));
            let g = apply(&x);
            let scales = LightScales::of(&g, |e| weight[e]);
            x = acc.next(&x, g, &scales);
        }
    }

    #[test]
    fn cholesky_solves_a_small_system() {
        let a = vec![vec![4.0, 2.0], vec![2.0, 3.0]];
        let x = cholesky_solve(a, vec![2.0, 1.0]).unwrap();
        // 4x + 2y = 2, 2x + 3y = 1 → x = 0.5, y = 0.
        assert!((x[0] - 0.5).abs() < 1e-12 && x[1].abs() < 1e-12, "{x:?}");
        assert!(cholesky_solve(vec![vec![0.0]], vec![1.0]).is_none());
    }
}
