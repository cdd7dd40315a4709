//! Dense direct solve: LU factorisation with partial pivoting (Golub & Van Loan, "Matrix
//! Computations", Alg. 3.4.1), in f64. Used as the exact discrete reference; O(n³).

use super::{Phase, Solver, SolverError, Stop};
use crate::cancel::{Cancelled, check};
use glam::DVec3;
use rayon::prelude::*;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

/// Solves `a · x = b` for a dense row-major `n × n` matrix `a` (consumed). Returns `None`
/// if the matrix is singular to working precision.
pub fn solve_dense(a: Vec<f64>, b: Vec<f64>, n: usize) -> Option<Vec<f64>> {
    solve_dense_cancellable(a, b, n, crate::cancel::never()).unwrap_or(None)
}

/// [`solve_dense`], checking `cancel` before each elimination step (O(n²) work each, so a
/// raised flag stops a 6000-patch solve within milliseconds).
pub fn solve_dense_cancellable(
    mut a: Vec<f64>,
    mut b: Vec<f64>,
    n: usize,
    cancel: &AtomicBool,
) -> Result<Option<Vec<f64>>, Cancelled> {
    assert_eq!(a.len(), n * n);
    assert_eq!(b.len(), n);
    for k in 0..n {
        check(cancel)?;
        // Pivot: the largest magnitude in column k at or below the diagonal.
        let (piv, max) = (k..n)
            .map(|r| (r, a[r * n + k].abs()))
            .fold((k, -1.0), |best, c| if c.1 > best.1 { c } else { best });
        if max.is_nan() || max <= 0.0 || !max.is_finite() {
            return Ok(None);
        }
        if piv != k {
            for c in 0..n {
                a.swap(k * n + c, piv * n + c);
            }
            b.swap(k, piv);
        }
        let (head, tail) = a.split_at_mut((k + 1) * n);
        let pivot_row = &head[k * n..(k + 1) * n];
        let pivot = pivot_row[k];
        let bk = b[k];
        let (_, b_tail) = b.split_at_mut(k + 1);
        // Row updates are independent; each row's arithmetic is the same whatever the
        // thread count, so the result is deterministic.
        tail.par_chunks_mut(n)
            .zip(b_tail.par_iter_mut())
            .for_each(|(row, bi)| {
                let f = row[k] / pivot;
                if f != 0.0 {
                    for c in k..n {
                        row[c] -= f * pivot_row[c];
                    }
                    *bi -= f * bk;
                }
            });
    }
    let mut x = vec![0.0; n];
    for k in (0..n).rev() {
        let row = &a[k * n..(k + 1) * n];
        let s: f64 = (k + 1..n).map(|c| row[c] * x[c]).sum();
        x[k] = (b[k] - s) / row[k];
    }
    Ok(x.iter().all(|v| v.is_finite()).then_some(x))
}

impl Solver {
    /// The direct method's one step: LU of the reduced patch system, then every element
    /// gathers from the exact patch radiosities. `Err(Cancelled)` leaves the solve as it was.
    pub(super) fn direct_solve(&mut self, cancel: &AtomicBool) -> Result<(), Stop> {
        let m = self.mesh.patches.len();
        let mesh = Arc::clone(&self.mesh);
        let source_means = self.patch_means(&self.source);
        let mut means = vec![DVec3::ZERO; m];
        for c in 0..3 {
            // Reduced system: (I − P ρ F) B̄ = P E'.
            let mut a = vec![0.0f64; m * m];
            for q in 0..m {
                a[q * m + q] = 1.0;
            }
            for (q, patch) in mesh.patches.iter().enumerate() {
                for i in patch.elements.clone() {
                    let i = i as usize;
                    let w =
                        (mesh.elements[i].area / patch.area) as f64 * self.reflectance[i][c] as f64;
                    if w == 0.0 {
                        continue;
                    }
                    for &(p, f) in self.rows[i].iter() {
                        a[q * m + p as usize] -= w * f as f64;
                    }
                }
            }
            let b: Vec<f64> = source_means.iter().map(|s| s[c]).collect();
            let x = solve_dense_cancellable(a, b, m, cancel)?.ok_or(SolverError::Singular)?;
            for (mean, v) in means.iter_mut().zip(x) {
                mean[c] = v;
            }
        }
        self.radiosity = (0..self.radiosity.len())
            .into_par_iter()
            .map(|i| self.gather(i, &means))
            .collect();
        self.stats.iterations = 1;
        self.stats.residual = Some(0.0);
        self.stats.energy_balance = Some(self.gathered_balance());
        self.phase = Phase::Done;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    pub(super) fn solves_a_system_needing_pivoting() {
        // [[0, 2, 1], [1, 1, 1], [2, 1, 0]] x = [5, 4, 4] has x = (1, 2, 1): 0+4+1, 1+2+1, 2+2+0.
        let a = vec![0.0, 2.0, 1.0, 1.0, 1.0, 1.0, 2.0, 1.0, 0.0];
        let x = solve_dense(a, vec![5.0, 4.0, 4.0], 3).unwrap();
        for (got, want) in x.iter().zip([1.0, 2.0, 1.0]) {
            assert!((got - want).abs() < 1e-12);
        }
        assert!(solve_dense(vec![1.0, 2.0, 2.0, 4.0], vec![1.0, 2.0], 2).is_none());
    }
}
