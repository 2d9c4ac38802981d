//! The reference solver's constraint rows, in the order Bullet holds them
//! (reference.rs's `update` pushes them, then solves): the suction per world
//! axis, the joint limits, and the helpers for a row's response.
#![allow(
    clippy::indexing_slicing,
    reason = "indices run below the chain length n <= MAX_CHAIN and the row's MAX_DOFS slots"
)]
use super::pgs::{MAX_DOFS, RowSpace};
use crate::math::Vec3;
use crate::model::{JointKind, ObjectModel};

/// At most this many movable joints above the grasped link carry load; the
/// ones farther up stay still (no generated or PartNet object has more).
pub const MAX_CHAIN: usize = MAX_DOFS - 3;

/// A chain's joint-space matrix, row-major in the first n x n entries.
pub(super) type ChainMatrix = [f64; MAX_CHAIN * MAX_CHAIN];

/// A chain joint in world: its kind, axis and origin.
pub(super) type WorldAxis = (JointKind, Vec3, Vec3);

/// The velocity of the point `at` per unit speed of the joint (its motion
/// subspace): axis x (at - origin) for a hinge, the axis for a slider.
pub(super) fn linear(&(kind, axis, origin): &WorldAxis, at: Vec3) -> Vec3 {
    if kind.is_prismatic() {
        axis
    } else {
        axis.cross(at - origin)
    }
}

/// How a row's impulse changes the velocities: through the chain's inverse
/// mass for the object's joints, the mount's mass for the mount's three.
pub(super) struct Responses<'a> {
    pub(super) n: usize,
    pub(super) inv_mass: &'a ChainMatrix,
    pub(super) mount_mass: f64,
}

impl Responses<'_> {
    /// A row's response: the chain's inverse mass on the chain's part of
    /// its Jacobian, the mount's on the mount's.
    pub(super) fn of(&self, jacobian: &[f64; MAX_DOFS]) -> [f64; MAX_DOFS] {
        let n = self.n;
        let mut response = [0.0; MAX_DOFS];
        for (a, r) in response.iter_mut().enumerate().take(n) {
            *r = (0..n).map(|b| self.inv_mass[a * n + b] * jacobian[b]).sum();
        }
        for i in 0..3 {
            response[n + i] = jacobian[n + i] / self.mount_mass;
        }
        response
    }

    /// A row on one velocity (a motor, a limit, a brake): its response is a
    /// column of the inverse mass.
    pub(super) fn unit(&self, i: usize, sign: f64) -> [f64; MAX_DOFS] {
        let n = self.n;
        let mut response = [0.0; MAX_DOFS];
        if i < n {
            for (a, r) in response.iter_mut().enumerate().take(n) {
                *r = self.inv_mass[a * n + i] * sign;
            }
        } else {
            response[i] = sign / self.mount_mass;
        }
        response
    }
}

/// The Jacobian of a row on velocity `i` alone.
pub(super) fn unit(i: usize, sign: f64) -> [f64; MAX_DOFS] {
    let mut j = [0.0; MAX_DOFS];
    j[i] = sign;
    j
}

/// The suction, per world axis: the grasped `point`'s velocity minus the
/// mount's, closing `gap` (point minus mount) at the `erp` rate.
pub(super) fn push_suction_rows(
    space: &mut RowSpace,
    responses: &Responses<'_>,
    axes: &[WorldAxis; MAX_CHAIN],
    (point, gap): (Vec3, Vec3),
    (erp, hk): (f64, f64),
    bound: f64,
) {
    let n = responses.n;
    let mut point_velocity = [Vec3::ZERO; MAX_CHAIN];
    for (a, v) in point_velocity.iter_mut().enumerate().take(n) {
        *v = linear(&axes[a], point);
    }
    for i in 0..3 {
        let mut jac = [0.0; MAX_DOFS];
        for (ja, v) in jac.iter_mut().zip(&point_velocity).take(n) {
            *ja = v[i] as f64;
        }
        jac[n + i] = -1.0;
        space.push(
            &jac,
            &responses.of(&jac),
            -(gap[i] as f64) * erp / hk,
            -bound,
            bound,
        );
    }
}

/// Joint limits. Bullet's rule: while clear of a limit, the solve may change
/// the joint's speed toward it by at most gap/h (its speed before the solve,
/// `x`, is not counted); past it, the error is closed at the erp rate.
#[expect(
    clippy::too_many_arguments,
    reason = "one stage of the solver's step: what it reads, named"
)]
pub(super) fn push_limit_rows(
    space: &mut RowSpace,
    responses: &Responses<'_>,
    model: &ObjectModel,
    q: &[f32],
    chain: &[usize],
    x: &[f64; MAX_DOFS],
    hk: f64,
    erp: f64,
) {
    for (a, &j) in chain.iter().enumerate() {
        let jm = &model.joints[j];
        if jm.kind == JointKind::Continuous || !jm.lower.is_finite() {
            continue;
        }
        let q = q[j] as f64;
        for (sign, gap) in [(1.0, q - jm.lower as f64), (-1.0, jm.upper as f64 - q)] {
            let target = if gap > 0.0 {
                sign * x[a] - gap / hk
            } else {
                -gap * erp / hk
            };
            space.push(
                &unit(a, sign),
                &responses.unit(a, sign),
                target,
                0.0,
                f64::INFINITY,
            );
        }
    }
}
