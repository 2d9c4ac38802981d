//! Projected Gauss-Seidel over box-bounded velocity constraints, the way
//! Bullet's multibody solver runs it: from a cold start, a fixed number of
//! sweeps that alternate backward and forward. The reference profile depends
//! on that exact schedule (see reference.rs), not only on its fixed point.
#![allow(
    clippy::indexing_slicing,
    reason = "the solver's matrices and vectors are sized by itself"
)]

/// Velocities a row can touch: the chain's joints and the mount's three axes.
pub(crate) const MAX_DOFS: usize = 8;

/// One constraint row: `lower <= impulse <= upper` while `jacobian · x` is
/// driven to `target`.
#[derive(Clone, Copy, Default)]
pub(crate) struct Row {
    jacobian: Sparse,
    /// Inverse mass times the Jacobian: the velocity change per unit impulse.
    response: Sparse,
    effective_mass: f64,
    /// Its inverse: the row's own speed change per unit impulse.
    compliance: f64,
    target: f64,
    lower: f64,
    upper: f64,
    impulse: f64,
}

impl Row {
    /// None when the row cannot act (no mass along it).
    pub(crate) fn new(
        jacobian: &[f64; MAX_DOFS],
        response: &[f64; MAX_DOFS],
        target: f64,
        lower: f64,
        upper: f64,
    ) -> Option<Row> {
        let d: f64 = jacobian.iter().zip(response).map(|(a, b)| a * b).sum();
        (d > 1e-12).then(|| Row {
            jacobian: Sparse::from_dense(jacobian),
            response: Sparse::from_dense(response),
            effective_mass: 1.0 / d,
            compliance: d,
            target,
            lower,
            upper,
            impulse: 0.0,
        })
    }
}

/// A row vector's non-zero entries: most rows touch one or two velocities,
/// and the solver's sweeps are its whole cost.
#[derive(Clone, Copy, Default)]
struct Sparse {
    index: [u8; MAX_DOFS],
    value: [f64; MAX_DOFS],
    len: usize,
}

impl Sparse {
    fn from_dense(dense: &[f64; MAX_DOFS]) -> Self {
        let mut s = Sparse::default();
        for (i, &v) in dense.iter().enumerate() {
            if v != 0.0 {
                s.index[s.len] = i as u8;
                s.value[s.len] = v;
                s.len += 1;
            }
        }
        s
    }
    #[inline(always)]
    fn dot(&self, x: &[f64; MAX_DOFS]) -> f64 {
        let at = |k: usize| self.value[k] * x[self.index[k] as usize & (MAX_DOFS - 1)];
        match self.len {
            1 => at(0),
            2 => at(0) + at(1),
            n => (0..n).map(at).sum(),
        }
    }
    #[inline(always)]
    fn add_scaled_to(&self, x: &mut [f64; MAX_DOFS], scale: f64) {
        for k in 0..self.len {
            x[self.index[k] as usize & (MAX_DOFS - 1)] += self.value[k] * scale;
        }
    }
}

/// Up to `sweeps` sweeps over `rows`, updating the velocities `x` in place.
/// It stops early only once a sweep changes no speed measurably, which gives
/// the same answer as running on.
pub(crate) fn solve(rows: &mut [Row], x: &mut [f64; MAX_DOFS], sweeps: usize) {
    let count = rows.len();
    for sweep in 0..sweeps.max(1) {
        let backward = sweep % 2 == 0;
        let mut largest = 0.0f64;
        for i in 0..count {
            let r = &mut rows[if backward { count - 1 - i } else { i }];
            let jv = r.jacobian.dot(x);
            let next = (r.impulse + (r.target - jv) * r.effective_mass).clamp(r.lower, r.upper);
            let change = next - r.impulse;
            if change != 0.0 {
                r.impulse = next;
                r.response.add_scaled_to(x, change);
                let speed_change = (change * r.compliance).abs();
                if speed_change > largest {
                    largest = speed_change;
                }
            }
        }
        if largest < 1e-7 {
            break;
        }
    }
}

/// Inverse of a small symmetric positive definite matrix (Gauss-Jordan with
/// partial pivoting); None when singular.
pub(crate) fn invert(m: &[f64], n: usize) -> Option<Vec<f64>> {
    let mut a = m.to_vec();
    let mut inv = vec![0.0; n * n];
    for i in 0..n {
        inv[i * n + i] = 1.0;
    }
    for c in 0..n {
        let p = (c..n).max_by(|&r, &s| a[r * n + c].abs().total_cmp(&a[s * n + c].abs()))?;
        if a[p * n + c].abs() < 1e-15 {
            return None;
        }
        for k in 0..n {
            a.swap(c * n + k, p * n + k);
            inv.swap(c * n + k, p * n + k);
        }
        let d = a[c * n + c];
        for k in 0..n {
            a[c * n + k] /= d;
            inv[c * n + k] /= d;
        }
        for r in 0..n {
            if r != c {
                let f = a[r * n + c];
                if f != 0.0 {
                    for k in 0..n {
                        a[r * n + k] -= f * a[c * n + k];
                        inv[r * n + k] -= f * inv[c * n + k];
                    }
                }
            }
        }
    }
    Some(inv)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invert_gives_the_inverse() {
        let m = [4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0];
        let inv = invert(&m, 3).expect("invertible");
        for r in 0..3 {
            for c in 0..3 {
                let v: f64 = (0..3).map(|k| m[r * 3 + k] * inv[k * 3 + c]).sum();
                assert!((v - if r == c { 1.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
        assert!(invert(&[1.0, 2.0, 2.0, 4.0], 2).is_none());
    }

    fn unit(i: usize, v: f64) -> [f64; MAX_DOFS] {
        let mut a = [0.0; MAX_DOFS];
        a[i] = v;
        a
    }

    #[test]
    fn a_bounded_row_saturates_and_an_unbounded_one_holds() {
        // One body of mass 2: a motor wanting 1 m/s with at most 0.5 N·s gets
        // 0.25 m/s; a limit row that forbids negative speed has no effect.
        let mut rows = vec![
            Row::new(&unit(0, 1.0), &unit(0, 0.5), 1.0, -0.5, 0.5).unwrap(),
            Row::new(&unit(0, 1.0), &unit(0, 0.5), 0.0, 0.0, f64::INFINITY).unwrap(),
        ];
        let mut x = [0.0; MAX_DOFS];
        solve(&mut rows, &mut x, 50);
        assert!((x[0] - 0.25).abs() < 1e-12, "{}", x[0]);
        // Pushed the other way, the limit row holds the body at rest.
        let mut rows = vec![
            Row::new(&unit(0, 1.0), &unit(0, 0.5), -1.0, -0.5, 0.5).unwrap(),
            Row::new(&unit(0, 1.0), &unit(0, 0.5), 0.0, 0.0, f64::INFINITY).unwrap(),
        ];
        let mut x = [0.0; MAX_DOFS];
        solve(&mut rows, &mut x, 50);
        assert!(x[0].abs() < 1e-9, "{}", x[0]);
        assert!(Row::new(&unit(0, 1.0), &[0.0; MAX_DOFS], 0.0, 0.0, 1.0).is_none());
    }
}
