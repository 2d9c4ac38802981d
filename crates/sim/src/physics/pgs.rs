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
    /// The first two entries: all of a row with `len <= 2`.
    #[inline(always)]
    fn pair(&self) -> ([usize; 2], [f64; 2]) {
        (
            [
                self.index[0] as usize & (MAX_DOFS - 1),
                self.index[1] as usize & (MAX_DOFS - 1),
            ],
            [self.value[0], self.value[1]],
        )
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
    if rows
        .iter()
        .all(|r| r.jacobian.len <= 2 && r.response.len <= 2 && r.lower <= r.upper)
    {
        solve_two_entry(rows, x, sweeps);
    } else {
        solve_general(rows, x, sweeps);
    }
}

/// Below this a sweep counts as converged: no speed changes by more.
const CONVERGED: f64 = 1e-7;

fn solve_general(rows: &mut [Row], x: &mut [f64; MAX_DOFS], sweeps: usize) {
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
        if largest < CONVERGED {
            break;
        }
    }
}

/// The sweeps when every row touches at most two velocities: all rows of a
/// one-joint chain, the common case. The sweeps are the reference profile's
/// whole cost, and the general row's length dispatch was much of each
/// update; here every row is the same straight-line arithmetic.
fn solve_two_entry(rows: &mut [Row], x: &mut [f64; MAX_DOFS], sweeps: usize) {
    let mut v = *x;
    let update = |r: &mut Row, v: &mut [f64; MAX_DOFS], largest: &mut f64| {
        let ([a, b], [ja, jb]) = r.jacobian.pair();
        // A second entry only where there is one: a zero-weight read of a
        // slot another row writes would chain the rows together.
        let two = r.jacobian.len == 2;
        let jv = if two {
            ja * v[a] + jb * v[b]
        } else {
            ja * v[a]
        };
        // Plain comparisons rather than clamp or max/min, whose NaN and
        // bound checks lengthen the chain (the bounds were checked above).
        let wanted = r.impulse + (r.target - jv) * r.effective_mass;
        let next = if wanted < r.lower { r.lower } else { wanted };
        let next = if next > r.upper { r.upper } else { next };
        let change = next - r.impulse;
        if change != 0.0 {
            r.impulse = next;
            let ([a, b], [ra, rb]) = r.response.pair();
            v[a] += ra * change;
            if r.response.len == 2 {
                v[b] += rb * change;
            }
            let speed_change = (change * r.compliance).abs();
            if speed_change > *largest {
                *largest = speed_change;
            }
        }
    };
    for sweep in 0..sweeps.max(1) {
        let mut largest = 0.0f64;
        if sweep % 2 == 0 {
            for r in rows.iter_mut().rev() {
                update(r, &mut v, &mut largest);
            }
        } else {
            for r in rows.iter_mut() {
                update(r, &mut v, &mut largest);
            }
        }
        if largest < CONVERGED {
            break;
        }
    }
    *x = v;
}

/// Inverse of a small symmetric positive definite matrix of order `n`
/// (row-major in the first `n * n` entries; Gauss-Jordan with partial
/// pivoting); None when singular or larger than the chain allows.
pub(crate) fn invert<const N: usize>(m: &[f64; N], n: usize) -> Option<[f64; N]> {
    if n * n > N {
        return None;
    }
    let mut a = *m;
    let mut inv = [0.0; N];
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
        assert!(invert(&m, 4).is_none(), "a 3x3 matrix has no order 4");
        for r in 0..3 {
            for c in 0..3 {
                let v: f64 = (0..3).map(|k| m[r * 3 + k] * inv[k * 3 + c]).sum();
                assert!((v - if r == c { 1.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
        assert!(invert(&[1.0, 2.0, 2.0, 4.0], 2).is_none());
        // Zeros below the diagonal, larger entries below it than on it, and
        // elimination that leaves a zero where a careless pivot would look:
        // the pivot must be the largest entry of its column.
        for m in [
            [4.0, 0.0, 1.0, 0.0, 3.0, 0.0, 1.0, 0.0, 2.0],
            [1.0, 2.0, 0.0, 2.0, 5.0, 0.0, 0.0, 0.0, 3.0],
            [5.0, 5.0, -6.0, 5.0, 6.0, -6.0, -6.0, -6.0, 13.0],
            [6.0, 3.0, 0.0, 3.0, 6.0, -6.0, 0.0, -6.0, 14.0],
        ] {
            let inv = invert(&m, 3).expect("invertible");
            for r in 0..3 {
                for c in 0..3 {
                    let v: f64 = (0..3).map(|k| m[r * 3 + k] * inv[k * 3 + c]).sum();
                    assert!((v - if r == c { 1.0 } else { 0.0 }).abs() < 1e-12, "{m:?}");
                }
            }
        }
    }

    fn unit(i: usize, v: f64) -> [f64; MAX_DOFS] {
        let mut a = [0.0; MAX_DOFS];
        a[i] = v;
        a
    }

    /// A door-like system of rows with one or two entries: a light hinge
    /// (index 0) held through a suction point by a 100 kg mount (1..4),
    /// the rows in the reference's order (suction, motors, limits, brake).
    fn door_rows(seed: u64) -> (Vec<Row>, [f64; MAX_DOFS]) {
        let mut state = seed;
        let mut uniform = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let inertia = 0.02 + 0.5 * uniform().abs();
        let h = 1.0 / 240.0;
        let mut rows = Vec::new();
        let mut push = |jac: [f64; MAX_DOFS], target: f64, bound: (f64, f64)| {
            let mut response = jac;
            response[0] /= inertia;
            for r in response.iter_mut().skip(1) {
                *r /= 100.0;
            }
            rows.extend(Row::new(&jac, &response, target, bound.0, bound.1));
        };
        for i in 0..3 {
            let mut jac = [0.0; MAX_DOFS];
            // The lever about a vertical hinge has no vertical part.
            jac[0] = if i == 2 { 0.0 } else { uniform() * 0.8 };
            jac[1 + i] = -1.0;
            push(jac, uniform() * 0.5, (-2000.0 * h, 2000.0 * h));
        }
        for i in 0..3 {
            push(unit(1 + i, 1.0), uniform() * 0.1, (-1500.0 * h, 1500.0 * h));
        }
        push(unit(0, 1.0), uniform() * 2.0 - 1.0, (0.0, f64::INFINITY));
        push(unit(0, -1.0), uniform() * 2.0 - 1.0, (0.0, f64::INFINITY));
        push(unit(0, 1.0), 0.0, (-1.0, 1.0));
        let mut x = [0.0; MAX_DOFS];
        for v in x.iter_mut().take(4) {
            *v = uniform() * 0.2;
        }
        (rows, x)
    }

    #[test]
    fn the_two_entry_sweeps_equal_the_general_ones() {
        for seed in 0..300 {
            let (mut general, x0) = door_rows(seed);
            let mut fast = general.clone();
            assert!(
                fast.iter().any(|r| r.jacobian.len == 1)
                    && fast.iter().any(|r| r.jacobian.len == 2)
            );
            let (mut xg, mut xf) = (x0, x0);
            solve_general(&mut general, &mut xg, 50);
            solve_two_entry(&mut fast, &mut xf, 50);
            assert_eq!(xg, xf, "seed {seed}");
            let impulses = |rows: &[Row]| rows.iter().map(|r| r.impulse).collect::<Vec<_>>();
            assert_eq!(impulses(&general), impulses(&fast), "seed {seed}");
        }
        // Rows the two-entry sweep cannot hold take the general path, with the
        // general path's answer bit for bit: a row of three entries, and a
        // limit on a two-joint chain (one Jacobian entry, a response on both
        // joints and the mount).
        let three_entries = Row::new(
            &[1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            &[0.1, 0.1, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0],
            0.3,
            -1.0,
            1.0,
        );
        let wide_response = Row::new(
            &unit(0, 1.0),
            &[0.5, -0.2, 0.05, 0.0, 0.0, 0.0, 0.0, 0.0],
            0.4,
            0.0,
            f64::INFINITY,
        );
        for extra in [three_entries, wide_response] {
            let (mut rows, x0) = door_rows(1);
            rows.extend(extra);
            let (mut general, mut fast) = (rows.clone(), rows.clone());
            let (mut x, mut xg, mut xf) = (x0, x0, x0);
            solve(&mut rows, &mut x, 50);
            solve_general(&mut general, &mut xg, 50);
            solve_two_entry(&mut fast, &mut xf, 50);
            assert_eq!(x, xg);
            assert_ne!(xf, xg, "this row set needs the general sweep");
        }
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
