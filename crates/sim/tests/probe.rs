//! Dense labels: probing directions from a state leaves the episode as it was
//! and gives what executing them gives.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests and benchmarks fail by panicking"
)]
use rand::SeedableRng;
use umpnet_sim::camera::Camera;
use umpnet_sim::env::{Pick, SimEnv};
use umpnet_sim::math::Vec3;
use umpnet_sim::objects::{Category, InstanceSplit, nth_instance};
use umpnet_sim::render::CpuRenderer;
use umpnet_sim::scene::{ObjectSource, Task, sample_scene};

fn grasped_env(c: Category, seed: u64) -> SimEnv {
    let object = ObjectSource::Generated {
        category: c,
        index: nth_instance(c, InstanceSplit::Test, 0),
        dataset_seed: 0,
    };
    let model = object.load_scaled().unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let scene = sample_scene(&mut rng, Task::Exploration, Some(c), object, &model, None).unwrap();
    let mut env = SimEnv::new(
        scene,
        Camera::reference(48, 64),
        Box::new(CpuRenderer::default()),
    )
    .unwrap();
    let frame = env.render().unwrap();
    // The movable pixel farthest from its joint's axis: a long lever.
    let (w, h) = (frame.width, frame.height);
    let mut best: Option<(f32, u32)> = None;
    for i in 0..(w * h) {
        if let Pick::Movable {
            point_in_world,
            joint,
            ..
        } = env.pick(&frame, i / w, i % w).unwrap()
        {
            let (axis, origin) = env.articulation().joint_axis_in_world(joint);
            let r = point_in_world - origin;
            let lever = (r - axis * r.dot(axis)).length();
            if best.is_none_or(|(l, _)| lever > l) {
                best = Some((lever, i));
            }
        }
    }
    let (_, i) = best.unwrap_or_else(|| panic!("{c}: nothing movable in view"));
    env.step_position(&frame, i / w, i % w).unwrap();
    env
}

#[test]
fn probing_leaves_the_state_and_predicts_the_executed_step() {
    let mut env = grasped_env(Category::Microwave, 3);
    let directions: Vec<Vec3> = (0..8)
        .map(|k| {
            let a = k as f32 * 0.8;
            Vec3::new(a.cos(), -1.0, a.sin()).normalize()
        })
        .collect();
    let before = env.joint_positions();
    let gripper = env.articulation().gripper_position();
    let probed = env.probe_directions(&directions).unwrap();
    assert_eq!(env.joint_positions(), before);
    assert_eq!(env.articulation().gripper_position(), gripper);
    assert_eq!(env.probe_directions(&directions).unwrap(), probed);
    assert!(
        probed.iter().any(|l| l.r_dist > 0.05),
        "no probe moved the part: {probed:?}"
    );
    let executed = env.step_direction(directions[5]).unwrap();
    assert_eq!(executed, probed[5]);
    assert!(env.probe_directions(&[Vec3::ZERO]).is_err());
}
