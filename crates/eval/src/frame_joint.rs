//! A joint read from one frame (beyond the paper) against the simulator's
//! truth: what `umpnet explore` reports for a package with a JointNet.
use crate::Result;
use crate::learned::observation_tensor;
use nalgebra::Vector3;
use umpnet_policy::UmpnetPolicy;
use umpnet_policy::axis::{JointEstimate, axis_angle_deg};
use umpnet_policy::frame_joint::FrameJoint;
use umpnet_sim::camera::Camera;
use umpnet_sim::env::SimEnv;
use umpnet_sim::model::JointKind;
use umpnet_sim::render::Renderer;
use umpnet_sim::scene::Scene;

/// A one-frame joint estimate and how far it is from the simulator's joint.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FrameJointScore {
    /// What the JointNet's vote gave.
    pub estimate: FrameJoint,
    /// The true joint is a slide.
    pub true_prismatic: bool,
    /// The true joint's unit axis (world frame).
    pub true_axis: [f32; 3],
    /// A point on the true axis (world frame).
    pub true_point: [f32; 3],
    /// Whether the estimate has the true joint's type.
    pub type_right: bool,
    /// Angle between the estimated and the true axis, ignoring sign (0 to 90).
    pub axis_error_deg: f32,
    /// For a hinge estimated as a hinge: how far the estimated axis passes
    /// from the true one, measured at the estimate's point (m).
    pub origin_error_m: Option<f32>,
}

/// Reads the joint of `joint` from the scene's first frame (before any
/// grasp), at `pixel` of `camera`'s image, with `policy`'s JointNet, and
/// scores it. None when the package has no JointNet or the vote gave nothing.
pub fn score_first_frame(
    scene: &Scene,
    camera: &Camera,
    renderer: Box<dyn Renderer>,
    policy: &UmpnetPolicy,
    pixel: (usize, usize),
    joint: usize,
) -> Result<Option<FrameJointScore>> {
    let mut env = SimEnv::new(scene.clone(), camera.clone(), renderer)?;
    let frame = env.render()?;
    let observation = observation_tensor(&frame)?;
    let Some(estimate) = policy.frame_joint(observation.view(), pixel)? else {
        return Ok(None);
    };
    let (true_axis, true_point) = env.articulation().joint_axis_in_world(joint);
    let true_prismatic = env
        .model()
        .joints
        .get(joint)
        .is_some_and(|j| j.kind == JointKind::Prismatic);
    let true_axis = Vector3::new(true_axis.x, true_axis.y, true_axis.z);
    let true_point = Vector3::new(true_point.x, true_point.y, true_point.z);
    let (axis, point, prismatic) = match &estimate.estimate {
        JointEstimate::Prismatic { axis } => (Vector3::from(*axis), None, true),
        JointEstimate::Revolute { axis, point } => {
            (Vector3::from(*axis), Some(Vector3::from(*point)), false)
        }
    };
    let origin_error_m = match (point, true_prismatic) {
        (Some(p), false) => {
            let u = true_axis.normalize();
            let d = p - true_point;
            Some((d - u * u.dot(&d)).norm())
        }
        _ => None,
    };
    Ok(Some(FrameJointScore {
        axis_error_deg: axis_angle_deg(&axis, &true_axis),
        type_right: prismatic == true_prismatic,
        true_prismatic,
        true_axis: true_axis.into(),
        true_point: true_point.into(),
        origin_error_m,
        estimate,
    }))
}
