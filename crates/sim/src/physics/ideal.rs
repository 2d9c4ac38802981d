//! The `ideal` profile: the articulated object as a rapier3d multibody, a
//! suction gripper on a stiff drive that follows the commanded line as far as
//! the joint's path allows (the ideal projection onto that path). No contacts.
#![allow(
    clippy::indexing_slicing,
    reason = "body and joint handles are indexed by the validated model's own indices"
)]
use super::{ActionOutcome, PhysicsConfig};
use crate::error::{Result, SimError};
use crate::math::{Pose3, Vec3, rotation_x_to};
use crate::urdf::{JointKind, ObjectModel};
use rapier3d::prelude::*;
use std::sync::Arc;

/// Steps an action may take to settle once its set-point has arrived: a cap
/// for a gripper that never comes to rest (every measured pull settles
/// within 10).
const MAX_SETTLE_STEPS: usize = 60;

/// A gripper that moves less than this in a step has come to rest, m.
const AT_REST_M: f32 = 2e-4;

/// How far along the action the drive's set-point is after step `i`: one
/// `per_step` further each step, from the first, up to `length`.
fn set_point_distance(i: usize, per_step: f32, length: f32) -> f32 {
    ((i + 1) as f32 * per_step).min(length)
}

/// An action is over once its set-point has arrived (after `travel` steps)
/// and the gripper moved less than [`AT_REST_M`] in the last step.
fn action_over(i: usize, travel: usize, moved: f32) -> bool {
    i + 1 >= travel && moved < AT_REST_M
}

#[derive(Clone)]
struct Gripper {
    body: RigidBodyHandle,
    target: RigidBodyHandle,
    suction: Option<ImpulseJointHandle>,
    link: usize,
    point_in_link: Vec3,
}

/// One articulated object (fixed base) plus the gripper, in its own rapier world.
pub(crate) struct IdealArticulation {
    model: Arc<ObjectModel>,
    config: PhysicsConfig,
    bodies: RigidBodySet,
    colliders: ColliderSet,
    impulse_joints: ImpulseJointSet,
    multibody_joints: MultibodyJointSet,
    soft_bodies: SoftBodySet,
    islands: IslandManager,
    broad_phase: BroadPhaseBvh,
    narrow_phase: NarrowPhase,
    ccd: CCDSolver,
    pipeline: PhysicsPipeline,
    params: IntegrationParameters,
    link_bodies: Vec<RigidBodyHandle>,
    joint_handles: Vec<Option<MultibodyJointHandle>>,
    gripper: Option<Gripper>,
}

impl IdealArticulation {
    pub(crate) fn new(
        model: Arc<ObjectModel>,
        world_from_base: Pose3,
        config: PhysicsConfig,
    ) -> Self {
        let mut bodies = RigidBodySet::new();
        let mut multibody_joints = MultibodyJointSet::new();
        let mut link_bodies = vec![RigidBodyHandle::invalid(); model.links.len()];
        let mut world_from_link = vec![Pose3::IDENTITY; model.links.len()];
        world_from_link[model.root] = world_from_base;
        let mprops = |l: usize| {
            let link = &model.links[l];
            let m = MassProperties::with_inertia_matrix(
                link.com_in_link,
                link.mass,
                link.inertia_in_link,
            );
            // A principal moment near zero (a thin rod's, 1e-30) inverts to a
            // number the solver overflows into NaN; a floor a millionth of the
            // largest moment changes no real object's motion.
            let principal = m.principal_inertia();
            let floor = (principal.max_element() * 1e-6).max(1e-12);
            MassProperties::with_principal_inertia_frame(
                m.local_com,
                link.mass,
                principal.max(Vec3::splat(floor)),
                m.principal_inertia_local_frame,
            )
        };
        link_bodies[model.root] = bodies.insert(
            RigidBodyBuilder::fixed()
                .pose(world_from_base)
                .additional_mass_properties(mprops(model.root)),
        );
        let mut joint_handles = Vec::with_capacity(model.joints.len());
        for j in &model.joints {
            let frame_rot = Pose3::from_rotation(rotation_x_to(j.axis_in_joint));
            let pose = world_from_link[j.parent] * j.parent_from_joint;
            world_from_link[j.child] = pose;
            link_bodies[j.child] = bodies.insert(
                RigidBodyBuilder::dynamic()
                    .pose(pose)
                    .gravity_scale(0.0)
                    .additional_mass_properties(mprops(j.child)),
            );
            let axes = match j.kind {
                JointKind::Fixed => JointAxesMask::LOCKED_FIXED_AXES,
                JointKind::Revolute | JointKind::Continuous => JointAxesMask::LOCKED_REVOLUTE_AXES,
                JointKind::Prismatic => JointAxesMask::LOCKED_PRISMATIC_AXES,
            };
            let mut builder = GenericJointBuilder::new(axes)
                .local_frame1(j.parent_from_joint * frame_rot)
                .local_frame2(frame_rot)
                .contacts_enabled(false);
            match j.kind {
                JointKind::Revolute => {
                    builder = builder.limits(JointAxis::AngX, [j.lower, j.upper])
                }
                JointKind::Prismatic => {
                    builder = builder.limits(JointAxis::LinX, [j.lower, j.upper])
                }
                _ => {}
            }
            let handle = multibody_joints.insert(
                link_bodies[j.parent],
                link_bodies[j.child],
                builder.build(),
                true,
            );
            joint_handles.push(handle);
        }
        let params = IntegrationParameters {
            dt: config.dt,
            num_solver_iterations: config.substeps,
            ..IntegrationParameters::default()
        };
        let mut art = Self {
            model,
            config,
            bodies,
            colliders: ColliderSet::new(),
            impulse_joints: ImpulseJointSet::new(),
            multibody_joints,
            soft_bodies: SoftBodySet::new(),
            islands: IslandManager::new(),
            broad_phase: BroadPhaseBvh::new(),
            narrow_phase: NarrowPhase::new(),
            ccd: CCDSolver::new(),
            pipeline: PhysicsPipeline::new(),
            params,
            link_bodies,
            joint_handles,
            gripper: None,
        };
        art.configure_joint_dynamics();
        art.refresh_kinematics();
        art
    }

    fn configure_joint_dynamics(&mut self) {
        for (j, joint) in self.model.joints.iter().enumerate() {
            let Some(handle) = self.joint_handles[j] else {
                continue;
            };
            let Some((mb, link_id)) = self.multibody_joints.get_mut(handle) else {
                continue;
            };
            mb.set_self_contacts_enabled(false);
            if !joint.kind.is_movable() {
                continue;
            }
            let Some(dof) = mb.link(link_id).map(|l| l.assembly_id()) else {
                continue;
            };
            mb.damping_mut()[dof] = joint.damping.max(self.config.min_joint_damping);
            mb.frictions_mut()[dof] = joint.friction.max(self.config.joint_friction);
        }
    }

    /// The one multibody of the object (None for an object without joints).
    fn multibody(&self) -> Option<MultibodyIndex> {
        self.multibody_joints
            .rigid_body_link(self.link_bodies[self.model.root])
            .map(|l| l.multibody)
    }

    /// Recomputes link poses from the joint coordinates (after building or a reset).
    fn refresh_kinematics(&mut self) {
        if let Some(mb) = self
            .multibody()
            .and_then(|i| self.multibody_joints.get_multibody_mut(i))
        {
            // `true`: the fixed root takes the base pose from its rigid body.
            mb.forward_kinematics(&self.bodies, true);
            mb.update_rigid_bodies(&mut self.bodies, true);
        }
    }

    /// An independent copy of the whole world (the pipeline's scratch state
    /// is made anew).
    pub(crate) fn duplicate(&self) -> Self {
        Self {
            model: self.model.clone(),
            config: self.config.clone(),
            bodies: self.bodies.clone(),
            colliders: self.colliders.clone(),
            impulse_joints: self.impulse_joints.clone(),
            multibody_joints: self.multibody_joints.clone(),
            soft_bodies: self.soft_bodies.clone(),
            islands: self.islands.clone(),
            broad_phase: self.broad_phase.clone(),
            narrow_phase: self.narrow_phase.clone(),
            ccd: self.ccd.clone(),
            pipeline: PhysicsPipeline::new(),
            params: self.params,
            link_bodies: self.link_bodies.clone(),
            joint_handles: self.joint_handles.clone(),
            gripper: self.gripper.clone(),
        }
    }

    /// (multibody, dof index) of a movable joint.
    fn dof_of(&self, joint: usize) -> Option<(MultibodyIndex, usize, usize)> {
        let handle = (*self.joint_handles.get(joint)?)?;
        let (mb, link_id) = self.multibody_joints.get(handle)?;
        let dof = mb.link(link_id)?.assembly_id();
        Some((self.multibody()?, link_id, dof))
    }

    /// Current value of a joint (rad or m); 0 for fixed joints.
    pub(crate) fn joint_position(&self, joint: usize) -> f32 {
        let Some(kind) = self.model.joints.get(joint).map(|j| j.kind) else {
            return 0.0;
        };
        let Some((idx, link_id, _)) = self.dof_of(joint) else {
            return 0.0;
        };
        let Some(link) = self
            .multibody_joints
            .get_multibody(idx)
            .and_then(|mb| mb.link(link_id))
        else {
            return 0.0;
        };
        let c = link.joint().coords();
        match kind {
            JointKind::Revolute | JointKind::Continuous => c[3],
            JointKind::Prismatic => c[0],
            JointKind::Fixed => 0.0,
        }
    }

    pub(crate) fn joint_velocity(&self, joint: usize) -> f32 {
        let Some((idx, _, dof)) = self.dof_of(joint) else {
            return 0.0;
        };
        if !self.model.joints[joint].kind.is_movable() {
            return 0.0;
        }
        self.multibody_joints
            .get_multibody(idx)
            .map(|mb| mb.generalized_velocity()[dof])
            .unwrap_or(0.0)
    }

    /// Sets every joint to the given values (clamped into its limits), zeroes
    /// velocities and lets go of anything the gripper holds.
    pub(crate) fn set_joint_positions(&mut self, values: &[f32]) {
        self.release();
        for (j, &v) in values.iter().enumerate() {
            let joint = &self.model.joints[j];
            if !joint.kind.is_movable() {
                continue;
            }
            let target = v.clamp(joint.lower, joint.upper);
            let delta = target - self.joint_position(j);
            if let Some((idx, _, dof)) = self.dof_of(j)
                && let Some(mb) = self.multibody_joints.get_multibody_mut(idx)
            {
                let mut disp = vec![0.0; mb.ndofs()];
                disp[dof] = delta;
                mb.apply_displacements(&disp);
            }
        }
        self.zero_velocities();
        self.refresh_kinematics();
    }

    fn zero_velocities(&mut self) {
        if let Some(mb) = self
            .multibody()
            .and_then(|i| self.multibody_joints.get_multibody_mut(i))
        {
            mb.generalized_velocity_mut().fill(0.0);
        }
        let handles: Vec<RigidBodyHandle> = self.bodies.iter().map(|(h, _)| h).collect();
        for h in handles {
            if let Some(b) = self.bodies.get_mut(h)
                && b.is_dynamic()
            {
                b.set_linvel(Vec3::ZERO, false);
                b.set_angvel(Vec3::ZERO, false);
            }
        }
    }

    pub(crate) fn world_from_link(&self, link: usize) -> Pose3 {
        self.bodies
            .get(self.link_bodies[link])
            .map(|b| *b.position())
            .unwrap_or(Pose3::IDENTITY)
    }

    pub(crate) fn gripper_position(&self) -> Option<Vec3> {
        let g = self.gripper.as_ref()?;
        self.bodies.get(g.body).map(|b| b.translation())
    }

    pub(crate) fn grasped_link(&self) -> Option<usize> {
        self.gripper
            .as_ref()
            .filter(|g| g.suction.is_some())
            .map(|g| g.link)
    }

    /// Attaches the suction gripper at `point_in_world` on `link`.
    pub(crate) fn attach(&mut self, point_in_world: Vec3, link: usize) -> Result<()> {
        self.release();
        let cfg = &self.config;
        let target = self
            .bodies
            .insert(RigidBodyBuilder::kinematic_position_based().translation(point_in_world));
        let body = self.bodies.insert(
            RigidBodyBuilder::dynamic()
                .translation(point_in_world)
                .gravity_scale(0.0)
                .additional_mass_properties(MassProperties::new(Vec3::ZERO, 0.5, Vec3::splat(0.01)))
                .lock_rotations(),
        );
        // Force-based springs so that the limit is in newtons.
        let (stiffness, damping) = (20_000.0, 600.0);
        let mut drive = GenericJointBuilder::new(JointAxesMask::empty()).contacts_enabled(false);
        for axis in [JointAxis::LinX, JointAxis::LinY, JointAxis::LinZ] {
            drive = drive
                .motor_model(axis, MotorModel::ForceBased)
                .motor_position(axis, 0.0, stiffness, damping)
                .motor_max_force(axis, cfg.gripper_max_force);
        }
        self.impulse_joints
            .insert(target, body, drive.build(), true);
        let world_from_link = self.world_from_link(link);
        let point_in_link = world_from_link.inverse_transform_point(point_in_world);
        let suction = GenericJointBuilder::new(JointAxesMask::LOCKED_SPHERICAL_AXES)
            .local_anchor1(Vec3::ZERO)
            .local_anchor2(point_in_link)
            .contacts_enabled(false)
            .build();
        let suction = self
            .impulse_joints
            .insert(body, self.link_bodies[link], suction, true);
        self.gripper = Some(Gripper {
            body,
            target,
            suction: Some(suction),
            link,
            point_in_link,
        });
        Ok(())
    }

    /// Removes the gripper from the world.
    pub(crate) fn release(&mut self) {
        if let Some(g) = self.gripper.take() {
            for h in [g.body, g.target] {
                self.bodies.remove(
                    h,
                    &mut self.islands,
                    &mut self.colliders,
                    &mut self.impulse_joints,
                    &mut self.multibody_joints,
                    &mut self.soft_bodies,
                    true,
                );
            }
        }
    }

    fn step(&mut self) {
        self.pipeline.step(
            Vec3::ZERO,
            &self.params,
            &mut self.islands,
            &mut self.broad_phase,
            &mut self.narrow_phase,
            &mut self.bodies,
            &mut self.colliders,
            &mut self.impulse_joints,
            &mut self.multibody_joints,
            &mut self.soft_bodies,
            &mut self.ccd,
            &(),
            &(),
        );
    }

    /// Moves the gripper `action_length` along `direction` (unit, world frame),
    /// force-limited, until it stops moving. `joint` is the joint whose value is reported.
    pub(crate) fn move_gripper(&mut self, direction: Vec3, joint: usize) -> Result<ActionOutcome> {
        let Some(g) = self.gripper.as_ref() else {
            return Err(SimError::InvalidAction(
                "no grasp: a position action must come first".into(),
            ));
        };
        let (body, target) = (g.body, g.target);
        let start = self.bodies[body].translation();
        let joint_before = self.joint_position(joint);
        let per_step = self.config.action_speed * self.config.dt;
        let travel_steps = (self.config.action_length / per_step).ceil() as usize;
        let mut suction_lost = self.gripper.as_ref().is_some_and(|g| g.suction.is_none());
        let mut steps = 0;
        let mut last = start;
        for i in 0..travel_steps + MAX_SETTLE_STEPS {
            let s = set_point_distance(i, per_step, self.config.action_length);
            if let Some(t) = self.bodies.get_mut(target) {
                t.set_next_kinematic_translation(start + direction * s);
            }
            self.step();
            steps += 1;
            if !suction_lost && self.check_suction() {
                suction_lost = true;
            }
            let now = self.bodies[body].translation();
            let moved = (now - last).length();
            last = now;
            if action_over(i, travel_steps, moved) {
                break;
            }
        }
        self.zero_velocities();
        // Quasi-static primitive: the gripper and its set-point come to rest on
        // the suction point (as the reference re-aligns its mount). Left where
        // the drive's spring held them, a pull against a limit would cost the
        // next action the stretch of that spring.
        let end = match self.gripper.as_ref() {
            Some(g) if g.suction.is_some() => self
                .world_from_link(g.link)
                .transform_point(g.point_in_link),
            _ => self.bodies[body].translation(),
        };
        for h in [body, target] {
            if let Some(b) = self.bodies.get_mut(h) {
                b.set_translation(end, false);
                if h == target {
                    b.set_next_kinematic_translation(end);
                }
            }
        }
        Ok(ActionOutcome {
            joint_before,
            joint_after: self.joint_position(joint),
            gripper_moved: (end - start).length(),
            suction_lost,
            steps,
        })
    }

    /// Breaks the suction when its force passed the limit; true when it did now.
    fn check_suction(&mut self) -> bool {
        let Some(g) = self.gripper.as_mut() else {
            return false;
        };
        let Some(h) = g.suction else { return false };
        let Some(j) = self.impulse_joints.get(h) else {
            return false;
        };
        let force =
            Vec3::new(j.impulses[0], j.impulses[1], j.impulses[2]).length() / self.params.dt;
        if force > self.config.suction_max_force {
            self.impulse_joints.remove(h, true);
            g.suction = None;
            return true;
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::{AT_REST_M, action_over, set_point_distance};

    #[test]
    fn the_set_point_advances_one_step_at_a_time_from_the_first_and_stops_at_the_end() {
        let (per_step, length) = (0.01, 0.18);
        let at = |i| set_point_distance(i, per_step, length);
        for (i, expected) in [(0, 0.01), (8, 0.09), (16, 0.17), (17, 0.18), (400, 0.18)] {
            assert!((at(i) - expected).abs() < 1e-6, "step {i}: {}", at(i));
        }
        assert!(at(400) <= length, "never past the end: {}", at(400));
    }

    #[test]
    fn an_action_ends_only_at_rest_after_the_set_point_arrived() {
        let travel = 18;
        // Still during the travel: the set-point is on its way.
        assert!(!action_over(16, travel, 0.0));
        assert!(action_over(17, travel, 0.0));
        assert!(action_over(30, travel, AT_REST_M * 0.99));
        assert!(!action_over(30, travel, AT_REST_M));
        assert!(!action_over(30, travel, 0.01));
    }
}
