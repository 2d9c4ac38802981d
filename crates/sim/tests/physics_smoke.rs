use std::path::Path;
use std::sync::Arc;
use umpnet_sim::math::{Pose3, Vec3};
use umpnet_sim::physics::{Articulation, PhysicsConfig};
use umpnet_sim::urdf::parse_urdf;

const DOOR: &str = r#"<robot name="cab">
<link name="base"><inertial><mass value="5"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>
<visual><geometry><box size="0.5 0.5 0.8"/></geometry></visual></link>
<link name="door"><inertial><origin xyz="-0.25 0 0"/><mass value="1"/><inertia ixx="0.05" iyy="0.05" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial>
<visual><origin xyz="-0.25 0 0"/><geometry><box size="0.5 0.02 0.8"/></geometry></visual></link>
<link name="drawer"><inertial><mass value="1"/><inertia ixx="0.02" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial>
<visual><geometry><box size="0.4 0.4 0.1"/></geometry></visual></link>
<joint name="hinge" type="revolute"><origin xyz="0.25 -0.26 0"/><axis xyz="0 0 1"/>
<parent link="base"/><child link="door"/><limit lower="0" upper="1.57" effort="10" velocity="1"/></joint>
<joint name="slide" type="prismatic"><origin xyz="0 -0.05 0.5"/><axis xyz="0 -1 0"/>
<parent link="base"/><child link="drawer"/><limit lower="0" upper="0.5" effort="10" velocity="1"/></joint>
</robot>"#;

#[test]
fn door_and_drawer_respond_to_pulls() {
    let model = Arc::new(parse_urdf(DOOR, Path::new("door.urdf")).unwrap());
    let mut art = Articulation::new(model.clone(), Pose3::from_translation(Vec3::new(0.0, 0.0, 0.4)), PhysicsConfig::default());
    let hinge = model.joint_by_name("hinge").unwrap();
    let slide = model.joint_by_name("slide").unwrap();
    let door_link = model.joints[hinge].child;
    // Door handle point: far edge of the door, front face.
    let p = art.world_from_link(door_link).transform_point(Vec3::new(-0.45, -0.01, 0.0));
    art.attach(p, door_link).unwrap();
    let t0 = std::time::Instant::now();
    for k in 0..12 {
        let g = art.gripper_position().unwrap();
        let (axis, origin) = art.joint_axis_in_world(hinge);
        let r = g - origin;
        let tangent = axis.cross(r).normalize();
        let o = art.move_gripper(tangent, hinge).unwrap();
        eprintln!("door {k}: {:.3} -> {:.3} moved {:.3} steps {} lost {}", o.joint_before, o.joint_after, o.gripper_moved, o.steps, o.suction_lost);
    }
    eprintln!("12 actions {:?}", t0.elapsed());
    art.release();
    let d = model.joints[slide].child;
    let p = art.world_from_link(d).transform_point(Vec3::new(0.0, -0.2, 0.0));
    art.attach(p, d).unwrap();
    for k in 0..4 {
        let (axis, _) = art.joint_axis_in_world(slide);
        let o = art.move_gripper(axis, slide).unwrap();
        eprintln!("drawer {k}: {:.3} -> {:.3} moved {:.3} steps {}", o.joint_before, o.joint_after, o.gripper_moved, o.steps);
    }
    art.set_joint_positions(&[0.3, 0.1]).unwrap();
    eprintln!("reset: {:?}", art.joint_positions());
}
