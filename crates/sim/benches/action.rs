//! Physics time of one 0.18 m action (reference profile) on a generated
//! drawer and a generated door: the figures `umpnet bench` reports, without
//! the renderer and the episode around them.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests and benchmarks fail by panicking"
)]
use criterion::{Criterion, criterion_group, criterion_main};
use std::sync::Arc;
use umpnet_sim::math::{Pose3, Vec3};
use umpnet_sim::model::JointKind;
use umpnet_sim::objects::{Category, generate};
use umpnet_sim::physics::{Articulation, PhysicsConfig};

fn bench_category(c: &mut Criterion, category: Category, kind: JointKind, label: &str) {
    let model = Arc::new(
        generate(category, 0, 0)
            .model()
            .expect("generated object loads"),
    );
    let (j, jm) = model
        .movable_joints()
        .find(|(_, jm)| jm.kind == kind)
        .expect("a joint of the wanted kind");
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
    c.bench_function(&format!("physics: one 0.18 m action on {label}"), |b| {
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

fn action(c: &mut Criterion) {
    bench_category(
        c,
        Category::StorageFurniture,
        JointKind::Prismatic,
        "a drawer",
    );
    bench_category(c, Category::Refrigerator, JointKind::Revolute, "a door");
}

criterion_group!(benches, action);
criterion_main!(benches);
