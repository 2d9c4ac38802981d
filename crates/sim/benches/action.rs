//! Median physics time of one 0.18 m action on a generated cabinet.
use criterion::{Criterion, criterion_group, criterion_main};
use std::sync::Arc;
use umpnet_sim::math::{Pose3, Vec3};
use umpnet_sim::objects::{Category, generate};
use umpnet_sim::physics::{Articulation, PhysicsConfig};

fn action(c: &mut Criterion) {
    let model = Arc::new(
        generate(Category::StorageFurniture, 0, 0)
            .model()
            .expect("generated cabinet loads"),
    );
    let (j, jm) = model.movable_joints().next().expect("a movable joint");
    let mut art = Articulation::new(
        model.clone(),
        Pose3::from_translation(Vec3::new(0.0, -0.5, 0.0)),
        PhysicsConfig::default(),
    );
    let link = jm.child;
    let centre = {
        let pose = art.world_from_link(link);
        let pts = &model.links[link].visuals[0].mesh_in_link.positions;
        pose.transform_point(pts.iter().copied().sum::<Vec3>() / pts.len() as f32)
    };
    art.attach(centre, link).expect("attach");
    let mut sign = 1.0f32;
    c.bench_function("physics: one 0.18 m action on a cabinet", |b| {
        b.iter(|| {
            let (axis, origin) = art.joint_axis_in_world(j);
            let g = art.gripper_position().unwrap_or(centre);
            let dir = if jm.kind.is_prismatic() {
                axis
            } else {
                axis.cross(g - origin).normalize_or(Vec3::X)
            };
            let o = art.move_gripper(dir * sign, j).expect("action");
            if o.joint_after - o.joint_before == 0.0
                || (o.joint_after - jm.upper).abs() < 1e-3
                || (o.joint_after - jm.lower).abs() < 1e-3
            {
                sign = -sign;
            }
        })
    });
}

criterion_group!(benches, action);
criterion_main!(benches);
