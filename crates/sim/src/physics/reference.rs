//! The `reference` profile: the paper's released simulator (PyBullet,
//! real-stanford/umpnet `sim.py`) re-derived as a small velocity-level
//! solver in reduced coordinates, so that it is both faithful and fast.
//!
//! What it models, as the reference does (checked against PyBullet by
//! `tests/reference` and `tests/pybullet_golden.rs`):
//! - The gripper is a mount of mass ~100 kg on three world-aligned prismatic
//!   axes, each a velocity motor whose target is `gain * error / dt`
//!   (PyBullet's POSITION_CONTROL) with at most 1500 N.
//! - The suction is a point-to-point constraint between the mount and a point
//!   fixed on the link, at most 2000 N per world axis: past that it slips,
//!   it never lets go.
//! - Every object joint keeps PyBullet's default velocity motor (target 0,
//!   1 N·s per 1/240 s step): a dry brake of about 240 N or N·m.
//! - An action drives the mount's target 0.18 m along the direction and steps
//!   until three steps (counted cumulatively) moved the mount less than
//!   1e-4 m, or 8 s pass; then a faster drive re-aligns the mount onto the
//!   suction point.
//!
//! How it solves: each update builds the constraint rows (mount motors,
//! suction, brakes, joint limits) on the grasped link's chain of movable
//! joints and solves them by projected Gauss-Seidel with box bounds, as
//! Bullet does; the velocities it converges to are unique, so the answer does
//! not depend on the row order. Joints off the chain carry no load and keep
//! still. One update may cover several reference steps (`steps_per_update`):
//! gains and bounds are rescaled so a free pull follows the same exponential
//! approach.
#![allow(
    clippy::indexing_slicing,
    reason = "vectors are sized from the validated model's joints and links"
)]
use super::kinematics::{forward_kinematics, joint_motion, movable_chain, moved_links};
use super::pgs::{MAX_DOFS, RowSpace, invert, solve};
pub use super::reference_rows::MAX_CHAIN;
use super::reference_rows::{
    ChainMatrix, Responses, WorldAxis, linear, push_limit_rows, push_suction_rows, unit,
};
use super::{ActionOutcome, PhysicsConfig};
use crate::error::{Result, SimError};
use crate::math::{Pose3, Vec3};
use crate::model::{JointKind, ObjectModel};
use std::sync::Arc;

/// Constants of the reference simulator (defaults: the paper's code).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct ReferenceParams {
    /// The reference time step (PyBullet's 1/240 s).
    pub reference_dt: f32,
    /// Reference steps covered by one solver update: 1 (the default) replays
    /// the reference step by step; more is faster but loses the reference's
    /// behaviour on light parts, which comes from its per-step solve.
    pub steps_per_update: usize,
    /// Projected Gauss-Seidel sweeps per update (PyBullet: 50).
    pub solver_iterations: usize,
    /// Mass moved by each mount axis (the reference mount: 100 kg + tip parts).
    pub mount_mass: f32,
    /// Position gain of the mount during an action (0.002 per step).
    pub mount_gain: f32,
    /// Position gain of the approach and the re-alignment (speed ratio 10).
    pub realign_gain: f32,
    /// Impulse of each object joint's default velocity motor per reference step.
    pub brake_impulse: f32,
    /// Error reduction of the suction and joint limits per reference step.
    pub erp: f32,
    /// A step "did not move" when the mount moved less than this (m).
    pub still_displacement: f32,
    /// ... and the drive stops after this many such steps (cumulative).
    pub still_steps: usize,
    /// At most this many reference steps per drive (8 s).
    pub max_steps: usize,
    /// Joint speeds are clamped to this after each solve (Bullet: 100).
    pub max_joint_speed: f32,
    /// Where the mount waits before a grasp (its base in the reference).
    pub mount_home: [f32; 3],
}

impl Default for ReferenceParams {
    fn default() -> Self {
        Self {
            reference_dt: 1.0 / 240.0,
            steps_per_update: 1,
            solver_iterations: 50,
            mount_mass: 100.5,
            mount_gain: 0.002,
            realign_gain: 0.02,
            brake_impulse: 1.0,
            erp: 0.2,
            still_displacement: 1e-4,
            still_steps: 3,
            max_steps: 240 * 8,
            max_joint_speed: 100.0,
            mount_home: [0.0, -2.0, 2.0],
        }
    }
}

#[derive(Clone)]
struct Suction {
    link: usize,
    point_in_link: Vec3,
    /// Movable joints from the root to `link`: the only ones that carry load.
    chain: Vec<usize>,
    /// For each chain joint, the links it moves.
    moved: Vec<Vec<usize>>,
    /// The joints whose child the chain moves, parent first: all that an
    /// update re-poses (a sibling part does not move).
    reposed: Vec<usize>,
    /// The chain's inverse mass matrix when it cannot change: one joint, on
    /// a parent that stays still, turns (or slides) its links about (along)
    /// its own axis, which keeps their inertia about it. Longer chains
    /// change theirs as they move and compute it at every update.
    fixed_inverse_mass: Option<ChainMatrix>,
}

#[derive(Clone)]
struct Mount {
    position: Vec3,
    velocity: Vec3,
    suction: Option<Suction>,
}

#[derive(Clone)]
pub(crate) struct ReferenceArticulation {
    model: Arc<ObjectModel>,
    params: ReferenceParams,
    gripper_max_force: f32,
    suction_max_force: f32,
    action_length: f32,
    world_from_base: Pose3,
    q: Vec<f32>,
    qd: Vec<f32>,
    world_from_link: Vec<Pose3>,
    mount: Option<Mount>,
    /// The solver's rows, kept so that a step neither allocates nor clears them.
    row_space: Box<RowSpace>,
}

impl ReferenceArticulation {
    pub(crate) fn new(
        model: Arc<ObjectModel>,
        world_from_base: Pose3,
        config: &PhysicsConfig,
    ) -> Self {
        let n = model.joints.len();
        let mut art = Self {
            params: config.reference.clone(),
            gripper_max_force: config.gripper_max_force,
            suction_max_force: config.suction_max_force,
            action_length: config.action_length,
            world_from_base,
            q: vec![0.0; n],
            qd: vec![0.0; n],
            world_from_link: vec![Pose3::IDENTITY; model.links.len()],
            mount: None,
            row_space: Box::default(),
            model,
        };
        art.refresh_kinematics();
        art
    }

    fn refresh_kinematics(&mut self) {
        forward_kinematics(
            &self.model,
            self.world_from_base,
            &self.q,
            &mut self.world_from_link,
        );
    }

    pub(crate) fn joint_position(&self, joint: usize) -> f32 {
        self.q.get(joint).copied().unwrap_or(0.0)
    }

    pub(crate) fn joint_velocity(&self, joint: usize) -> f32 {
        self.qd.get(joint).copied().unwrap_or(0.0)
    }

    pub(crate) fn set_joint_positions(&mut self, values: &[f32]) {
        self.release();
        for (j, joint) in self.model.joints.iter().enumerate() {
            self.q[j] = if joint.kind.is_movable() {
                values[j].clamp(joint.lower, joint.upper)
            } else {
                0.0
            };
        }
        self.qd.fill(0.0);
        self.refresh_kinematics();
    }

    pub(crate) fn world_from_link(&self, link: usize) -> Pose3 {
        self.world_from_link
            .get(link)
            .copied()
            .unwrap_or(Pose3::IDENTITY)
    }

    pub(crate) fn gripper_position(&self) -> Option<Vec3> {
        self.mount.as_ref().map(|m| m.position)
    }

    pub(crate) fn grasped_link(&self) -> Option<usize> {
        self.mount
            .as_ref()
            .and_then(|m| m.suction.as_ref())
            .map(|s| s.link)
    }

    pub(crate) fn release(&mut self) {
        self.mount = None;
    }

    /// The reference's position action: a fresh mount at its home drives to
    /// the point (nothing attached yet, so it does not touch the object), then
    /// the suction joins the mount to the point on the link. The drive stops
    /// a few millimetres short, as the reference's does; the suction pulls
    /// that gap closed during the first action.
    pub(crate) fn attach(&mut self, point_in_world: Vec3, link: usize) -> Result<()> {
        self.mount = Some(Mount {
            position: Vec3::from(self.params.mount_home),
            velocity: Vec3::ZERO,
            suction: None,
        });
        self.drive(point_in_world, self.params.realign_gain);
        let mut chain = movable_chain(&self.model, link);
        if chain.len() > MAX_CHAIN {
            chain.drain(..chain.len() - MAX_CHAIN);
        }
        let moved: Vec<Vec<usize>> = chain.iter().map(|&j| moved_links(&self.model, j)).collect();
        let reposed = match moved.first() {
            Some(links) => (0..self.model.joints.len())
                .filter(|&j| links.contains(&self.model.joints[j].child))
                .collect(),
            None => Vec::new(),
        };
        let point_in_link = self.world_from_link[link].inverse_transform_point(point_in_world);
        let fixed_inverse_mass = match chain.len() {
            1 => chain_inverse_mass(&self.model, &self.world_from_link, &chain, &moved),
            _ => None,
        };
        if let Some(m) = self.mount.as_mut() {
            m.suction = Some(Suction {
                link,
                point_in_link,
                chain,
                moved,
                reposed,
                fixed_inverse_mass,
            });
        }
        Ok(())
    }

    fn suction_point(&self) -> Option<Vec3> {
        let s = self.mount.as_ref()?.suction.as_ref()?;
        Some(self.world_from_link[s.link].transform_point(s.point_in_link))
    }

    pub(crate) fn move_gripper(&mut self, direction: Vec3, joint: usize) -> Result<ActionOutcome> {
        let (Some(start_point), Some(start)) = (self.suction_point(), self.gripper_position())
        else {
            return Err(SimError::InvalidAction(
                "no grasp: a position action must come first".into(),
            ));
        };
        let joint_before = self.joint_position(joint);
        let mut steps = self.drive(
            start_point + direction * self.action_length,
            self.params.mount_gain,
        );
        if let Some(p) = self.suction_point() {
            steps += self.drive(p, self.params.realign_gain);
        }
        let end = self.gripper_position().unwrap_or(start);
        Ok(ActionOutcome {
            joint_before,
            joint_after: self.joint_position(joint),
            gripper_moved: (end - start).length(),
            suction_lost: false,
            steps,
        })
    }

    /// Drives the mount toward `target` until it stops (the reference's
    /// `_move_to`); returns the reference steps taken.
    fn drive(&mut self, target: Vec3, gain: f32) -> usize {
        let p = &self.params;
        let k = p.steps_per_update.max(1);
        let h = p.reference_dt * k as f32;
        // k reference steps of gain g close the same share of a free error.
        let gain = 1.0 - (1.0 - gain).powi(k as i32);
        let (max_steps, still_needed, still_disp) =
            (p.max_steps, p.still_steps, p.still_displacement);
        let mut still = 0;
        let mut steps = 0;
        while steps < max_steps {
            let Some(before) = self.gripper_position() else {
                break;
            };
            self.update(target, gain, h, k);
            steps += k;
            let after = self.gripper_position().unwrap_or(before);
            // The reference measures its first step from a far-away sentinel,
            // so that step never counts as still: a stalled drive takes 4
            // steps there, not 3.
            if steps > k && (after - before).length() / (k as f32) < still_disp {
                still += k;
                if still >= still_needed {
                    break;
                }
            }
        }
        steps
    }

    /// One solver update of length `h` covering `k` reference steps, in
    /// Bullet's stages: the rows of the constraints, the sweeps that solve
    /// them, then the velocities integrated into positions.
    fn update(&mut self, target: Vec3, gain: f32, h: f32, k: usize) {
        let Some(mount) = self.mount.as_ref() else {
            return;
        };
        let desired = (target - mount.position) * (gain / h);
        if mount.suction.is_none() {
            self.move_free_mount(desired, h);
            return;
        }
        let Some(s) = mount.suction.as_ref() else {
            return;
        };
        let n = s.chain.len();
        let erp = 1.0 - (1.0 - self.params.erp as f64).powi(k as i32);
        let inverse_mass = s
            .fixed_inverse_mass
            .or_else(|| chain_inverse_mass(&self.model, &self.world_from_link, &s.chain, &s.moved));
        let Some(inv_mass) = inverse_mass else {
            return;
        };
        let responses = Responses {
            n,
            inv_mass: &inv_mass,
            mount_mass: self.params.mount_mass as f64,
        };
        let mut x = [0.0f64; MAX_DOFS];
        for (a, &j) in s.chain.iter().enumerate() {
            x[a] = self.qd[j] as f64;
        }
        for i in 0..3 {
            x[n + i] = mount.velocity[i] as f64;
        }

        // The rows in the order Bullet's solver holds them (measured against
        // PyBullet by the differential suite): the suction, the mount's
        // motors, the object's limits, its default motors. It sweeps them
        // backward and forward in turn, from cold, a fixed number of times: a
        // light part held by the heavy mount does not converge in that many,
        // and the reference's light parts (switches, knobs) barely move
        // because of it.
        let space = &mut *self.row_space;
        space.begin(n + 3);
        let point = self.world_from_link[s.link].transform_point(s.point_in_link);
        // Fixed-size: this runs at every 1/240 s step, hundreds of times per action.
        let axes = chain_axes(&self.model, &self.world_from_link, &s.chain);
        let suction_bound = (self.suction_max_force * h) as f64;
        let hk = h as f64;
        push_suction_rows(
            space,
            &responses,
            &axes,
            (point, point - mount.position),
            (erp, hk),
            suction_bound,
        );
        let motor_bound = (self.gripper_max_force * h) as f64;
        for i in 0..3 {
            space.push(
                &unit(n + i, 1.0),
                &responses.unit(n + i, 1.0),
                desired[i] as f64,
                -motor_bound,
                motor_bound,
            );
        }
        push_limit_rows(
            space,
            &responses,
            &self.model,
            &self.q,
            &s.chain,
            &x,
            hk,
            erp,
        );
        // The default velocity motor of each chain joint: a dry brake.
        let brake = (self.params.brake_impulse * k as f32) as f64;
        for a in 0..n {
            space.push(&unit(a, 1.0), &responses.unit(a, 1.0), 0.0, -brake, brake);
        }

        solve(&mut x, self.params.solver_iterations, &mut self.row_space);
        self.integrate(&x, h);
    }

    /// The mount alone: three independent force-limited velocity motors.
    fn move_free_mount(&mut self, desired: Vec3, h: f32) {
        let dv = self.gripper_max_force * h / self.params.mount_mass;
        if let Some(m) = self.mount.as_mut() {
            let v = m.velocity;
            let v = Vec3::new(
                desired.x.clamp(v.x - dv, v.x + dv),
                desired.y.clamp(v.y - dv, v.y + dv),
                desired.z.clamp(v.z - dv, v.z + dv),
            );
            m.velocity = v;
            m.position += v * h;
        }
    }

    /// The solved velocities (the chain's joints, then the mount's three)
    /// into speeds and positions, and the moved links reposed.
    fn integrate(&mut self, x: &[f64; MAX_DOFS], h: f32) {
        let Some(s) = self.mount.as_ref().and_then(|m| m.suction.as_ref()) else {
            return;
        };
        let n = s.chain.len();
        let max_speed = self.params.max_joint_speed as f64;
        let mut chain_buf = [0usize; MAX_CHAIN];
        chain_buf[..n].copy_from_slice(&s.chain);
        let chain = &chain_buf[..n];
        for (a, &j) in chain.iter().enumerate() {
            let v = x[a].clamp(-max_speed, max_speed) as f32;
            self.qd[j] = v;
            self.q[j] += v * h;
        }
        if let Some(m) = self.mount.as_mut() {
            m.velocity = Vec3::new(x[n] as f32, x[n + 1] as f32, x[n + 2] as f32);
            m.position += m.velocity * h;
        }
        if let Some(s) = self.mount.as_ref().and_then(|m| m.suction.as_ref()) {
            repose(&self.model, &self.q, &mut self.world_from_link, &s.reposed);
        }
    }
}

/// Each chain joint's axis and origin in world (unused slots: fixed).
fn chain_axes(
    model: &ObjectModel,
    world_from_link: &[Pose3],
    chain: &[usize],
) -> [WorldAxis; MAX_CHAIN] {
    let mut axes = [(JointKind::Fixed, Vec3::ZERO, Vec3::ZERO); MAX_CHAIN];
    for (slot, &j) in axes.iter_mut().zip(chain) {
        let jm = &model.joints[j];
        let pose = world_from_link[jm.parent] * jm.parent_from_joint;
        *slot = (jm.kind, pose.rotation * jm.axis_in_joint, pose.translation);
    }
    axes
}

/// The angular velocity per unit speed of the joint.
fn angular(&(kind, axis, _): &WorldAxis) -> Vec3 {
    if kind.is_prismatic() {
        Vec3::ZERO
    } else {
        axis
    }
}

/// The inverse of the chain's mass matrix; None when it is singular.
fn chain_inverse_mass(
    model: &ObjectModel,
    world_from_link: &[Pose3],
    chain: &[usize],
    moved: &[Vec<usize>],
) -> Option<ChainMatrix> {
    let n = chain.len();
    let axes = chain_axes(model, world_from_link, chain);
    let mut mass = chain_mass(model, world_from_link, &axes[..n], moved);
    for a in 0..n {
        // Guards a massless chain; far below any real link's inertia.
        mass[a * n + a] += 1e-9;
    }
    invert(&mass, n)
}

/// The chain's joint-space mass matrix (n x n, row-major, n = `axes.len()`):
/// `qd' M qd / 2` is the kinetic energy of every link the chain moves. A
/// deeper joint's moved links are a subset of a shallower one's, so link `l`
/// moved by joint `b` is moved by every `a <= b`.
fn chain_mass(
    model: &ObjectModel,
    world_from_link: &[Pose3],
    axes: &[WorldAxis],
    moved: &[Vec<usize>],
) -> ChainMatrix {
    let n = axes.len();
    let mut mass = [0.0f64; MAX_CHAIN * MAX_CHAIN];
    for b in 0..n {
        for &l in &moved[b] {
            let link = &model.links[l];
            let pose = world_from_link[l];
            let com = pose.transform_point(link.com_in_link);
            let rot = crate::math::Mat3::from_quat(pose.rotation);
            let inertia = rot * link.inertia_in_link * rot.transpose();
            for a in 0..=b {
                let (va, vb) = (linear(&axes[a], com), linear(&axes[b], com));
                let (wa, wb) = (angular(&axes[a]), angular(&axes[b]));
                let m = (link.mass * va.dot(vb) + wa.dot(inertia * wb)) as f64;
                mass[a * n + b] += m;
                if a != b {
                    mass[b * n + a] += m;
                }
            }
        }
    }
    mass
}

/// Re-poses the children of `joints` (parent first): the links the grasped
/// chain moves; the rest did not move.
fn repose(model: &ObjectModel, q: &[f32], world_from_link: &mut [Pose3], joints: &[usize]) {
    for &j in joints {
        let (Some(joint), Some(&qj)) = (model.joints.get(j), q.get(j)) else {
            continue;
        };
        let parent = world_from_link[joint.parent];
        world_from_link[joint.child] =
            parent * joint.parent_from_joint * joint_motion(joint.kind, joint.axis_in_joint, qj);
    }
}

#[cfg(test)]
mod tests {
    #![allow(
        clippy::unwrap_used,
        clippy::expect_used,
        reason = "tests fail by panicking"
    )]
    use super::*;
    use crate::urdf::parse_urdf;

    /// A hinge about z, a slider along its link's x, and a hinge about that
    /// link's y: every pair of joints couples, with offset centres of mass.
    const CHAIN: &str = r#"<?xml version="1.0"?>
<robot name="chain">
  <link name="base"/>
  <link name="a"><inertial><origin xyz="0.2 0.05 0"/><mass value="2"/><inertia ixx="0.02" ixy="0.001" ixz="0" iyy="0.05" iyz="0" izz="0.06"/></inertial></link>
  <link name="b"><inertial><origin xyz="0.1 0 0.03"/><mass value="0.7"/><inertia ixx="0.004" ixy="0" ixz="0.0005" iyy="0.003" iyz="0" izz="0.005"/></inertial></link>
  <link name="c"><inertial><origin xyz="0 0.04 -0.15"/><mass value="1.3"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.012" iyz="0.001" izz="0.003"/></inertial></link>
  <joint name="hinge" type="revolute"><parent link="base"/><child link="a"/><origin xyz="0.1 -0.2 0.5"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="slide" type="prismatic"><parent link="a"/><child link="b"/><origin xyz="0.3 0 0" rpy="0 0 0.3"/><axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="tilt" type="revolute"><parent link="b"/><child link="c"/><origin xyz="0.2 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>"#;

    fn poses(model: &ObjectModel, q: &[f32]) -> Vec<Pose3> {
        let mut out = vec![Pose3::IDENTITY; model.links.len()];
        forward_kinematics(model, Pose3::IDENTITY, q, &mut out);
        out
    }

    /// The kinetic energy of every link at joint speeds `qd`, from finite
    /// differences of the link poses alone (no Jacobians).
    fn kinetic_energy(model: &ObjectModel, q: &[f32], qd: &[f32]) -> f64 {
        let eps = 1e-3f32;
        let moved: Vec<f32> = q.iter().zip(qd).map(|(q, v)| q + eps * v).collect();
        let (now, next) = (poses(model, q), poses(model, &moved));
        let mut energy = 0.0;
        for (l, link) in model.links.iter().enumerate() {
            let v = (next[l].transform_point(link.com_in_link)
                - now[l].transform_point(link.com_in_link))
                / eps;
            let (axis, angle) = (next[l].rotation * now[l].rotation.inverse()).to_axis_angle();
            let w = axis * angle / eps;
            let rot = crate::math::Mat3::from_quat(now[l].rotation);
            let inertia = rot * link.inertia_in_link * rot.transpose();
            energy += 0.5 * f64::from(link.mass * v.dot(v) + w.dot(inertia * w));
        }
        energy
    }

    #[test]
    fn the_chain_mass_matrix_gives_the_links_kinetic_energy() {
        let model = parse_urdf(CHAIN, std::path::Path::new("chain.urdf")).unwrap();
        let tip = model.links.iter().position(|l| l.name == "c").unwrap();
        let chain = movable_chain(&model, tip);
        assert_eq!(chain.len(), 3);
        let moved: Vec<Vec<usize>> = chain.iter().map(|&j| moved_links(&model, j)).collect();
        let mut q = vec![0.0; model.joints.len()];
        for (&j, v) in chain.iter().zip([0.7, 0.15, -0.4]) {
            q[j] = v;
        }
        let world_from_link = poses(&model, &q);
        let axes = chain_axes(&model, &world_from_link, &chain);
        let mass = chain_mass(&model, &world_from_link, &axes[..3], &moved);
        for speeds in [
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.8, -0.5, 1.2],
            [-0.3, 0.9, 0.6],
        ] {
            let mut qd = vec![0.0; model.joints.len()];
            for (&j, v) in chain.iter().zip(speeds) {
                qd[j] = v;
            }
            let mut from_matrix = 0.0;
            for a in 0..3 {
                for b in 0..3 {
                    from_matrix +=
                        0.5 * f64::from(speeds[a]) * mass[a * 3 + b] * f64::from(speeds[b]);
                }
            }
            let expected = kinetic_energy(&model, &q, &qd);
            assert!(
                (from_matrix - expected).abs() < 2e-3 * expected,
                "speeds {speeds:?}: {from_matrix} from the matrix, {expected} from the poses"
            );
        }
        for a in 0..3 {
            for b in 0..3 {
                assert_eq!(
                    mass[a * 3 + b],
                    mass[b * 3 + a],
                    "not symmetric at ({a}, {b})"
                );
            }
        }
    }
}
