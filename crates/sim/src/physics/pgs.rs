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

/// Up to `sweeps` sweeps over the rows pushed since `RowSpace::begin`,
/// updating the velocities `x` in place. It stops early only once a sweep
/// changes no speed measurably, which gives the same answer as running on.
///
/// The sweeps are carried out on each row's unclamped impulse rather than on
/// the velocities. Row `i` of a sweep wants the impulse
/// `u_i = λ_i + (t_i − J_i·x) / A_ii`, where `A = J M⁻¹ Jᵀ`. Changing `λ_k`
/// by `c` changes every other `u_i` by `−c A_ik / A_ii` and leaves `u_k`
/// alone, so a row update is a clamp, a subtraction and a multiply-add for
/// each row it shares a velocity with. On the velocities it is a dot
/// product, the clamp and a scatter back: the sweeps are a chain of
/// dependent row updates, and this one is shorter (a door action 14% faster,
/// docs/physics-and-protocol.md). Same answer in exact arithmetic; in
/// floating point it differs by rounding (see the tests).
pub(crate) fn solve(x: &mut [f64; MAX_DOFS], sweeps: usize, space: &mut RowSpace) {
    let start = space.impulse;
    space.load(x);
    space.sweeps(sweeps);
    let rows = space.rows;
    for ((total, before), response) in space
        .impulse
        .iter()
        .zip(&start)
        .zip(&space.response)
        .take(rows)
    {
        let change = total - before;
        if change != 0.0 {
            for (v, r) in x.iter_mut().zip(response).take(space.dofs) {
                *v += r * change;
            }
        }
    }
}

/// Below this a sweep counts as converged: no speed changes by more.
const CONVERGED: f64 = 1e-7;

/// The most rows a solve holds: the mount's six and three per chain joint
/// (two limits and a brake).
pub(crate) const MAX_ROWS: usize = 6 + 3 * (MAX_DOFS - 3);

/// Slots of the row buffers: a power of two at least `MAX_ROWS`, so that a
/// masked index needs no bounds check in the sweeps.
const ROW_SLOTS: usize = 32;
const _: () = assert!(MAX_ROWS <= ROW_SLOTS && ROW_SLOTS.is_power_of_two());

/// The rows of one solve, each a constraint `lower <= impulse <= upper`
/// while `jacobian · x` is driven to `target`: built in place at every step
/// (`begin`, then `push` per row) into a buffer the caller keeps, so that a
/// step neither allocates nor moves rows around.
#[derive(Clone)]
pub(crate) struct RowSpace {
    rows: usize,
    /// Velocities the rows act on (the first `dofs` of `x`).
    dofs: usize,
    jacobian: [[f64; MAX_DOFS]; ROW_SLOTS],
    /// Inverse mass times the Jacobian: the velocity change per unit impulse.
    response: [[f64; MAX_DOFS]; ROW_SLOTS],
    /// Bit `d` set where the Jacobian (the response) has an entry: two rows
    /// couple only through a velocity both touch.
    jacobian_mask: [u8; ROW_SLOTS],
    response_mask: [u8; ROW_SLOTS],
    target: [f64; ROW_SLOTS],
    effective_mass: [f64; ROW_SLOTS],
    /// Its inverse: the row's own speed change per unit impulse.
    compliance: [f64; ROW_SLOTS],
    lower: [f64; ROW_SLOTS],
    upper: [f64; ROW_SLOTS],
    /// Each row's unclamped impulse.
    wanted: [f64; ROW_SLOTS],
    impulse: [f64; ROW_SLOTS],
    /// Per row `k`, the rows `i` it couples to, with the change of
    /// `wanted[i]` per unit change of `impulse[k]`. Most pairs of rows share
    /// no velocity and are left out; only the first `coupled_count[k]`
    /// entries are meaningful. Nearest rows come first: the next row of a
    /// sweep waits on its own entry only.
    coupled: [[(usize, f64); ROW_SLOTS]; ROW_SLOTS],
    coupled_count: [usize; ROW_SLOTS],
}

impl Default for RowSpace {
    fn default() -> Self {
        RowSpace {
            rows: 0,
            dofs: MAX_DOFS,
            jacobian: [[0.0; MAX_DOFS]; ROW_SLOTS],
            response: [[0.0; MAX_DOFS]; ROW_SLOTS],
            jacobian_mask: [0; ROW_SLOTS],
            response_mask: [0; ROW_SLOTS],
            target: [0.0; ROW_SLOTS],
            effective_mass: [0.0; ROW_SLOTS],
            compliance: [0.0; ROW_SLOTS],
            lower: [0.0; ROW_SLOTS],
            upper: [0.0; ROW_SLOTS],
            wanted: [0.0; ROW_SLOTS],
            impulse: [0.0; ROW_SLOTS],
            coupled: [[(0, 0.0); ROW_SLOTS]; ROW_SLOTS],
            coupled_count: [0; ROW_SLOTS],
        }
    }
}

/// `a · b` over the first `dofs` entries, in index order.
#[inline(always)]
fn dot(a: &[f64; MAX_DOFS], b: &[f64; MAX_DOFS], dofs: usize) -> f64 {
    a.iter().zip(b).take(dofs).map(|(a, b)| a * b).sum()
}

/// The entries of the first `dofs` of `v` that are not zero, as bits.
fn mask(v: &[f64; MAX_DOFS], dofs: usize) -> u8 {
    v.iter()
        .take(dofs)
        .enumerate()
        .fold(0, |m, (d, &e)| if e != 0.0 { m | (1 << d) } else { m })
}

impl RowSpace {
    /// Starts a new set of rows on the first `dofs` velocities.
    pub(crate) fn begin(&mut self, dofs: usize) {
        self.rows = 0;
        self.dofs = dofs.min(MAX_DOFS);
    }

    /// Adds a row (cold: no impulse yet) and whether it was kept: a row
    /// with no mass along it cannot act, and the space holds `MAX_ROWS`.
    pub(crate) fn push(
        &mut self,
        jacobian: &[f64; MAX_DOFS],
        response: &[f64; MAX_DOFS],
        target: f64,
        lower: f64,
        upper: f64,
    ) -> bool {
        debug_assert!(lower <= upper, "row bounds out of order: {lower} > {upper}");
        let d = dot(jacobian, response, self.dofs);
        if d <= 1e-12 || self.rows >= MAX_ROWS {
            return false;
        }
        let k = self.rows;
        self.jacobian[k] = *jacobian;
        self.response[k] = *response;
        self.jacobian_mask[k] = mask(jacobian, self.dofs);
        self.response_mask[k] = mask(response, self.dofs);
        self.target[k] = target;
        self.effective_mass[k] = 1.0 / d;
        self.compliance[k] = d;
        self.lower[k] = lower;
        self.upper[k] = upper;
        self.impulse[k] = 0.0;
        self.rows += 1;
        true
    }

    fn load(&mut self, x: &[f64; MAX_DOFS]) {
        let (rows, dofs) = (self.rows, self.dofs);
        for i in 0..rows {
            self.wanted[i] = self.impulse[i]
                + (self.target[i] - dot(&self.jacobian[i], x, dofs)) * self.effective_mass[i];
        }
        for k in 0..rows {
            let mut count = 0;
            for distance in 1..rows {
                for i in [k.wrapping_sub(distance), k + distance] {
                    let Some(&jacobian_mask) = self.jacobian_mask[..rows].get(i) else {
                        continue;
                    };
                    let shared = jacobian_mask & self.response_mask[k];
                    if shared == 0 {
                        continue;
                    }
                    let c =
                        -dot(&self.jacobian[i], &self.response[k], dofs) * self.effective_mass[i];
                    if c != 0.0 {
                        self.coupled[k][count] = (i, c);
                        count += 1;
                    }
                }
            }
            self.coupled_count[k] = count;
        }
    }

    fn sweeps(&mut self, sweeps: usize) {
        for sweep in 0..sweeps.max(1) {
            // Whether any row changed a speed by CONVERGED or more: a flag
            // rather than the largest change, which would be one more
            // branch per row.
            let mut moved = false;
            if sweep % 2 == 0 {
                for k in (0..self.rows).rev() {
                    moved |= self.update(k);
                }
            } else {
                for k in 0..self.rows {
                    moved |= self.update(k);
                }
            }
            if !moved {
                break;
            }
        }
    }

    /// One row's update; whether it changed a speed measurably.
    #[inline(always)]
    fn update(&mut self, k: usize) -> bool {
        let k = k & (ROW_SLOTS - 1);
        let u = self.wanted[k];
        // Plain comparisons rather than clamp, whose NaN and bound checks
        // lengthen the chain of dependent updates (RowSpace::push asserts
        // lower <= upper in debug builds; every row the reference builds
        // has them in order).
        let next = if u < self.lower[k] { self.lower[k] } else { u };
        let next = if next > self.upper[k] {
            self.upper[k]
        } else {
            next
        };
        let change = next - self.impulse[k];
        // Rows that do not change (an idle limit) break the chain: the next
        // row need not wait for this one.
        if change == 0.0 {
            return false;
        }
        self.impulse[k] = next;
        let count = self.coupled_count[k] & (ROW_SLOTS - 1);
        for &(i, c) in self.coupled[k].iter().take(count) {
            self.wanted[i & (ROW_SLOTS - 1)] += c * change;
        }
        (change * self.compliance[k]).abs() >= CONVERGED
    }
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

    /// One row as the velocity sweeps hold it: the tests' reference.
    #[derive(Clone, Copy)]
    struct Row {
        jacobian: [f64; MAX_DOFS],
        response: [f64; MAX_DOFS],
        effective_mass: f64,
        compliance: f64,
        target: f64,
        lower: f64,
        upper: f64,
        impulse: f64,
    }

    impl Row {
        fn new(
            jacobian: &[f64; MAX_DOFS],
            response: &[f64; MAX_DOFS],
            target: f64,
            lower: f64,
            upper: f64,
        ) -> Option<Row> {
            let d = dot(jacobian, response, MAX_DOFS);
            (d > 1e-12).then_some(Row {
                jacobian: *jacobian,
                response: *response,
                effective_mass: 1.0 / d,
                compliance: d,
                target,
                lower,
                upper,
                impulse: 0.0,
            })
        }
    }

    /// Projected Gauss-Seidel on the velocities, as Bullet runs it.
    fn solve_general(rows: &mut [Row], x: &mut [f64; MAX_DOFS], sweeps: usize) {
        let count = rows.len();
        for sweep in 0..sweeps.max(1) {
            let backward = sweep % 2 == 0;
            let mut largest = 0.0f64;
            for i in 0..count {
                let r = &mut rows[if backward { count - 1 - i } else { i }];
                let jv = dot(&r.jacobian, x, MAX_DOFS);
                let next = (r.impulse + (r.target - jv) * r.effective_mass).clamp(r.lower, r.upper);
                let change = next - r.impulse;
                if change != 0.0 {
                    r.impulse = next;
                    for (v, d) in x.iter_mut().zip(&r.response) {
                        *v += d * change;
                    }
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

    /// `solve` on these rows, from their impulses (a warm start when they
    /// are not zero), writing the impulses back.
    fn solve_rows(rows: &mut [Row], x: &mut [f64; MAX_DOFS], sweeps: usize, space: &mut RowSpace) {
        // The velocities the rows touch: the space's masks see no spare
        // zero entries past them.
        let dofs = rows
            .iter()
            .flat_map(|r| r.jacobian.iter().zip(&r.response).enumerate())
            .filter(|(_, (j, r))| **j != 0.0 || **r != 0.0)
            .map(|(d, _)| d + 1)
            .max()
            .unwrap_or(0);
        space.begin(dofs);
        for r in rows.iter() {
            assert!(space.push(&r.jacobian, &r.response, r.target, r.lower, r.upper));
            space.impulse[space.rows - 1] = r.impulse;
        }
        solve(x, sweeps, space);
        for (r, &total) in rows.iter_mut().zip(&space.impulse) {
            r.impulse = total;
        }
    }

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

    /// A random system on a chain of `n` joints and the mount: an SPD mass
    /// matrix, rows of up to `n + 1` entries (suction-like), one-entry rows
    /// (motors, limits, brakes), and bounds of every kind.
    fn chain_rows(seed: u64, n: usize, count: usize) -> (Vec<Row>, [f64; MAX_DOFS]) {
        let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut uniform = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let dofs = n + 3;
        let mut l = [0.0; 64];
        for v in l.iter_mut().take(n * n) {
            *v = uniform();
        }
        let mut mass = [0.0; 64];
        for r in 0..n {
            for c in 0..n {
                mass[r * n + c] = (0..n).map(|k| l[r * n + k] * l[c * n + k]).sum::<f64>()
                    + if r == c { 0.05 } else { 0.0 };
            }
        }
        let inv = invert(&mass, n).expect("SPD");
        let mut rows = Vec::new();
        while rows.len() < count {
            let mut jac = [0.0; MAX_DOFS];
            if uniform() > 0.0 {
                // A suction row: the chain's joints and one mount axis.
                for j in jac.iter_mut().take(n) {
                    *j = uniform();
                }
                jac[n + rows.len() % 3] = -1.0;
            } else {
                jac[((uniform().abs() * dofs as f64) as usize).min(dofs - 1)] = 1.0;
            }
            let mut response = [0.0; MAX_DOFS];
            for a in 0..n {
                response[a] = (0..n).map(|b| inv[a * n + b] * jac[b]).sum();
            }
            for i in 0..3 {
                response[n + i] = jac[n + i] / 100.0;
            }
            let bound = uniform().abs() * 3.0;
            let (lower, upper) = match rows.len() % 3 {
                0 => (-bound, bound),
                1 => (0.0, f64::INFINITY),
                _ => (f64::NEG_INFINITY, f64::INFINITY),
            };
            rows.extend(Row::new(&jac, &response, uniform(), lower, upper));
        }
        let mut x = [0.0; MAX_DOFS];
        for v in x.iter_mut().take(dofs) {
            *v = uniform() * 0.2;
        }
        (rows, x)
    }

    /// The row-space sweeps against the velocity sweeps they restate: equal
    /// up to rounding, which the sweeps neither amplify nor let drift.
    fn assert_close(rows: &[Row], x0: [f64; MAX_DOFS], scratch: &mut RowSpace, what: &str) {
        let (mut general, mut fast) = (rows.to_vec(), rows.to_vec());
        let (mut xg, mut xf) = (x0, x0);
        solve_general(&mut general, &mut xg, 50);
        solve_rows(&mut fast, &mut xf, 50, scratch);
        let scale = xg.iter().fold(1.0f64, |m, v| m.max(v.abs()));
        for (a, b) in xg.iter().zip(&xf) {
            assert!(
                (a - b).abs() <= 1e-9 * scale,
                "{what}: {xg:?} against {xf:?}"
            );
        }
        for (g, f) in general.iter().zip(&fast) {
            let scale = 1.0f64.max(g.impulse.abs());
            assert!(
                (g.impulse - f.impulse).abs() <= 1e-9 * scale,
                "{what}: impulses"
            );
        }
    }

    #[test]
    fn the_row_space_sweeps_match_the_velocity_sweeps() {
        let mut scratch = RowSpace::default();
        for seed in 0..300 {
            let (rows, x0) = door_rows(seed);
            assert_close(&rows, x0, &mut scratch, &format!("door {seed}"));
        }
        // Chains of up to five joints and up to MAX_ROWS rows, through the
        // same scratch: a larger system's leftovers must not leak into a
        // smaller one.
        for seed in 0..300u64 {
            let n = 1 + seed as usize % 5;
            // Up to 21 rows: all a chain of five joints has (6 + 3 * 5).
            let count = 2 + seed as usize % 20;
            let (rows, x0) = chain_rows(seed, n, count);
            assert_close(&rows, x0, &mut scratch, &format!("chain {seed}"));
        }
        // A space holds MAX_ROWS rows (all a chain of MAX_DOFS - 3 joints
        // can have): one more is refused, not written past the end.
        let (rows, _) = chain_rows(7, 5, 22);
        scratch.begin(MAX_DOFS);
        let kept = rows
            .iter()
            .filter(|r| scratch.push(&r.jacobian, &r.response, r.target, r.lower, r.upper))
            .count();
        assert_eq!(kept, 21);
    }

    #[test]
    fn a_row_on_every_velocity_couples_to_the_rows_it_shares_them_with() {
        // Two velocities: a row on both (no zero entry) and a row on each.
        // The couplings skip only pairs that share no velocity.
        let both = {
            let mut j = [0.0; MAX_DOFS];
            j[0] = 1.0;
            j[1] = -0.5;
            j
        };
        let mut response = both;
        response[0] /= 2.0;
        response[1] /= 3.0;
        let rows = vec![
            Row::new(&unit(0, 1.0), &unit(0, 0.5), 0.7, -10.0, 10.0).unwrap(),
            Row::new(&both, &response, -0.4, -10.0, 10.0).unwrap(),
            Row::new(&unit(1, 1.0), &unit(1, 1.0 / 3.0), 0.2, -0.05, 0.05).unwrap(),
        ];
        let mut scratch = RowSpace::default();
        assert_close(
            &rows,
            [0.1, -0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            &mut scratch,
            "dense",
        );
    }

    #[test]
    fn the_sweeps_stop_once_nothing_moves_and_not_before() {
        // Two free rows on one body converge at once; a third sweep would
        // change nothing, and the answer is the exact solve.
        let mut rows = vec![
            Row::new(&unit(0, 1.0), &unit(0, 0.5), 1.0, -10.0, 10.0).unwrap(),
            Row::new(&unit(1, 1.0), &unit(1, 0.25), -2.0, -10.0, 10.0).unwrap(),
        ];
        let mut x = [0.0; MAX_DOFS];
        solve_rows(&mut rows, &mut x, 50, &mut RowSpace::default());
        assert_eq!((x[0], x[1]), (1.0, -2.0));
        // Started warm from its own answer, a solve stays there: the
        // impulses it starts from are already in the velocities.
        let impulses: Vec<f64> = rows.iter().map(|r| r.impulse).collect();
        assert_eq!(impulses, [2.0, -8.0]);
        solve_rows(&mut rows, &mut x, 50, &mut RowSpace::default());
        assert_eq!((x[0], x[1]), (1.0, -2.0));
        assert_eq!(rows.iter().map(|r| r.impulse).collect::<Vec<_>>(), impulses);
        // The door-like systems never converge in 50 sweeps: cut to fewer,
        // the answer changes, so every sweep ran.
        let (rows, x0) = door_rows(3);
        let (mut a, mut b) = (rows.clone(), rows);
        let (mut xa, mut xb) = (x0, x0);
        solve_rows(&mut a, &mut xa, 50, &mut RowSpace::default());
        solve_rows(&mut b, &mut xb, 49, &mut RowSpace::default());
        assert_ne!(xa, xb);
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
        solve_rows(&mut rows, &mut x, 50, &mut RowSpace::default());
        assert!((x[0] - 0.25).abs() < 1e-12, "{}", x[0]);
        // Pushed the other way, the limit row holds the body at rest.
        let mut rows = vec![
            Row::new(&unit(0, 1.0), &unit(0, 0.5), -1.0, -0.5, 0.5).unwrap(),
            Row::new(&unit(0, 1.0), &unit(0, 0.5), 0.0, 0.0, f64::INFINITY).unwrap(),
        ];
        let mut x = [0.0; MAX_DOFS];
        solve_rows(&mut rows, &mut x, 50, &mut RowSpace::default());
        assert!(x[0].abs() < 1e-9, "{}", x[0]);
        assert!(Row::new(&unit(0, 1.0), &[0.0; MAX_DOFS], 0.0, 0.0, 1.0).is_none());
    }
}
