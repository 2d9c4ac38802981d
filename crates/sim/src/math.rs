//! The one place where geometry types are chosen: rapier's glam types.
pub use rapier3d::glamx::{Mat3, Mat4, Pose3, Quat, Vec3};

/// Rotation taking +X onto `axis` (unit); rapier's revolute and prismatic
/// joints move along their local X axis.
pub fn rotation_x_to(axis: Vec3) -> Quat {
    Quat::from_rotation_arc(Vec3::X, axis.normalize())
}
