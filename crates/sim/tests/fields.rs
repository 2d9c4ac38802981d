//! Articulation fields: each pixel's flow is the way its point moves when its
//! joint opens (checked against the kinematics by finite differences), and a
//! goal scene's displacement takes each point to its place in the goal state.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests and benchmarks fail by panicking"
)]
use rand::SeedableRng;
use umpnet_sim::camera::Camera;
use umpnet_sim::env::SimEnv;
use umpnet_sim::math::Vec3;
use umpnet_sim::objects::{Category, InstanceSplit, nth_instance};
use umpnet_sim::physics::{Articulation, PhysicsConfig};
use umpnet_sim::render::{CpuRenderer, Segment};
use umpnet_sim::scene::{ObjectSource, Task, sample_scene};

fn env(c: Category, task: Task, seed: u64) -> SimEnv {
    let object = ObjectSource::Generated {
        category: c,
        index: nth_instance(c, InstanceSplit::Test, 0),
        dataset_seed: 0,
    };
    let model = object.load_scaled().unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let scene = sample_scene(&mut rng, task, Some(c), object, &model, None).unwrap();
    SimEnv::new(
        scene,
        Camera::reference(60, 80),
        Box::new(CpuRenderer::default()),
    )
    .unwrap()
}

/// Where a world point on `link` goes when joint `j` moves by `dq`, by the
/// articulation's own forward kinematics.
fn moved(env: &SimEnv, link: usize, j: usize, dq: f32, p: Vec3) -> Vec3 {
    let mut q = env.joint_positions();
    q[j] += dq;
    let mut other = Articulation::new(
        env.model().clone(),
        env.scene().world_from_base(),
        PhysicsConfig::with_profile(env.scene().physics),
    );
    other.set_joint_positions(&q).unwrap();
    let p_in_link = env
        .articulation()
        .world_from_link(link)
        .inverse()
        .transform_point(p);
    other.world_from_link(link).transform_point(p_in_link)
}

fn link_of(segment: u32) -> Option<usize> {
    match Segment::decode(segment) {
        Segment::Link { link, .. } => Some(link),
        _ => None,
    }
}

#[test]
fn flow_is_the_opening_direction_of_each_point_and_zero_on_fixed_parts() {
    for (c, seed) in [
        (Category::Microwave, 3),
        (Category::StorageFurniture, 1),
        (Category::Laptop, 2),
    ] {
        let mut env = env(c, Task::Exploration, seed);
        let frame = env.render().unwrap();
        let fields = env.articulation_fields(&frame).unwrap();
        assert!(fields.goal_displacement_in_world.is_none());
        let (mut moving, mut fixed) = (0, 0);
        // Per joint: (speed label, how far the point moved for dq).
        let mut speeds: std::collections::BTreeMap<i32, Vec<(f32, f32)>> = Default::default();
        for i in 0..fields.joint.len() {
            let flow = Vec3::from(fields.flow_in_world[i]);
            let j = fields.joint[i];
            if j < 0 {
                assert_eq!(flow, Vec3::ZERO, "{c}: pixel {i}");
                assert_eq!(fields.speed[i], 0.0, "{c}: pixel {i}");
                fixed += usize::from(link_of(frame.segmentation[i]).is_some());
                continue;
            }
            moving += 1;
            let j = j as usize;
            let link = link_of(frame.segmentation[i]).unwrap();
            let p = frame
                .point_in_world(i as u32 / frame.width, i as u32 % frame.width)
                .unwrap();
            let dq = 1e-3;
            let step = moved(&env, link, j, dq, p) - p;
            speeds
                .entry(j as i32)
                .or_default()
                .push((fields.speed[i], step.length()));
            if step.length() < 1e-7 {
                continue; // on a hinge's axis
            }
            let cos = step.normalize().dot(flow);
            assert!(cos > 0.999, "{c}: pixel {i}: flow {flow} against {step}");
            assert!((flow.length() - 1.0).abs() < 1e-4);
        }
        assert!(
            moving > 20 && fixed > 5,
            "{c}: {moving} moving, {fixed} fixed pixels"
        );
        // Speed: each point's step over its part's largest step.
        for (j, pairs) in speeds {
            let fastest = pairs.iter().map(|p| p.1).fold(0.0f32, f32::max);
            for (speed, step) in pairs {
                assert!(
                    (speed - step / fastest).abs() < 0.02,
                    "{c}: joint {j}: speed {speed} against {}",
                    step / fastest
                );
            }
        }
    }
}

#[test]
fn goal_displacement_takes_the_goal_part_to_its_goal_place_and_nothing_else() {
    for (c, seed) in [(Category::Door, 0), (Category::StorageFurniture, 2)] {
        let mut env = env(c, Task::Goal, seed);
        let frame = env.render().unwrap();
        let fields = env.articulation_fields(&frame).unwrap();
        let disp = fields.goal_displacement_in_world.as_ref().unwrap();
        let goal = env.scene().goal.clone().unwrap();
        let j = goal.joint;
        let dq = goal.joints[j] - env.joint_positions()[j];
        assert!(dq.abs() > 0.05, "{c}: a goal {dq} from the start");
        let jm = &env.model().joints[j];
        let (axis, origin) = env.articulation().joint_axis_in_world(j);
        let mut on_goal_part = 0;
        for (i, d) in disp.iter().enumerate() {
            let d = Vec3::from(*d);
            let Some(link) = link_of(frame.segmentation[i]) else {
                assert_eq!(d, Vec3::ZERO);
                continue;
            };
            if fields.joint[i] != j as i32 {
                assert!(
                    d.length() < 1e-5,
                    "{c}: pixel {i} off the goal part moves {d}"
                );
                continue;
            }
            on_goal_part += 1;
            let p = frame
                .point_in_world(i as u32 / frame.width, i as u32 % frame.width)
                .unwrap();
            let want = if jm.kind.is_prismatic() {
                dq.abs()
            } else {
                let r = p - origin;
                2.0 * (r - axis * r.dot(axis)).length() * (dq.abs() / 2.0).sin()
            };
            assert!(
                (d.length() - want).abs() < 1e-3,
                "{c}: |{d}| against {want}"
            );
            // The same place the kinematics give for the whole move.
            let there = moved(&env, link, j, dq, p);
            assert!(
                (p + d - there).length() < 1e-3,
                "{c}: {} against {there}",
                p + d
            );
        }
        assert!(
            on_goal_part > 20,
            "{c}: {on_goal_part} pixels on the goal part"
        );
    }
}
