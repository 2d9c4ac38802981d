//! Physics of the action primitive on generated objects of every category.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests and benchmarks fail by panicking"
)]
use rand::{Rng, SeedableRng};
use std::sync::Arc;
use umpnet_sim::env::{DELTA, labels};
use umpnet_sim::math::{Pose3, Quat, Vec3};
use umpnet_sim::objects::{Category, generate};
use umpnet_sim::physics::{Articulation, PhysicsConfig, PhysicsProfile};
use umpnet_sim::urdf::{JointKind, ObjectModel};

fn model(c: Category, i: u32) -> Arc<ObjectModel> {
    Arc::new(generate(c, i, 0).model().unwrap())
}

fn articulation(m: &Arc<ObjectModel>, yaw: f32) -> Articulation {
    Articulation::new(
        m.clone(),
        Pose3::from_parts(Vec3::new(0.0, -0.5, 0.0), Quat::from_rotation_z(yaw)),
        PhysicsConfig::with_profile(PhysicsProfile::Ideal),
    )
}

/// A grasp point on the joint's child link: the vertex farthest from a revolute
/// axis (pulled slightly inward), or the link's centre for a prismatic joint.
fn grasp_point(art: &Articulation, m: &ObjectModel, j: usize) -> (Vec3, f32) {
    let link = m.joints[j].child;
    let pose = art.world_from_link(link);
    let pts: Vec<Vec3> = m.links[link]
        .visuals
        .iter()
        .flat_map(|v| {
            v.mesh_in_link
                .positions
                .iter()
                .map(|p| pose.transform_point(*p))
        })
        .collect();
    let (axis, origin) = art.joint_axis_in_world(j);
    if m.joints[j].kind == JointKind::Prismatic {
        let c = pts.iter().copied().sum::<Vec3>() / pts.len() as f32;
        return (c, 0.0);
    }
    let radial = |p: Vec3| {
        let r = p - origin;
        r - axis * r.dot(axis)
    };
    let far = pts
        .iter()
        .copied()
        .max_by(|a, b| radial(*a).length().total_cmp(&radial(*b).length()))
        .unwrap();
    let p = far - radial(far) * 0.1;
    (p, radial(p).length())
}

#[test]
fn every_joint_of_every_category_opens_step_by_step_and_stops_at_its_limit() {
    let mut checked = 0;
    for &c in Category::ALL {
        for i in 0..3 {
            let m = model(c, i);
            for (j, jm) in m.movable_joints() {
                let mut art = articulation(&m, 0.3);
                let mut q: Vec<f32> = art.joint_positions();
                q[j] = jm.lower;
                art.set_joint_positions(&q).unwrap();
                let (p, radius) = grasp_point(&art, &m, j);
                art.attach(p, jm.child).unwrap();
                let range = jm.upper - jm.lower;
                let expected = if jm.kind == JointKind::Prismatic {
                    0.18
                } else {
                    0.18 / radius
                };
                let mut reached = false;
                for step in 0..60 {
                    let (axis, origin) = art.joint_axis_in_world(j);
                    let dir = if jm.kind == JointKind::Prismatic {
                        axis
                    } else {
                        axis.cross(art.gripper_position().unwrap() - origin)
                            .normalize()
                    };
                    let o = art.move_gripper(dir, j).unwrap();
                    assert!(
                        !o.suction_lost,
                        "{c}#{i} joint {j}: suction lost on a tangent pull"
                    );
                    let gained = o.joint_after - o.joint_before;
                    let left = jm.upper - o.joint_before;
                    if left > 1.2 * expected {
                        assert!(
                            gained > 0.75 * expected && gained < 1.1 * expected,
                            "{c}#{i} joint {j} step {step}: gained {gained:.3}, expected about {expected:.3}"
                        );
                    }
                    if (o.joint_after - jm.upper).abs() < 0.01 * range.max(0.1) {
                        // At the limit: pulling again changes nothing.
                        let again = art.move_gripper(dir, j).unwrap();
                        assert!(
                            again.joint_after <= jm.upper + 0.005
                                && (again.joint_after - again.joint_before).abs() < 0.02,
                            "{c}#{i} joint {j}: moved past its limit: {} -> {} (upper {})",
                            again.joint_before,
                            again.joint_after,
                            jm.upper
                        );
                        reached = true;
                        break;
                    }
                }
                assert!(
                    reached,
                    "{c}#{i} joint {j}: never reached its upper limit {}",
                    jm.upper
                );
                checked += 1;
            }
        }
    }
    assert!(checked >= 66, "checked only {checked} joints");
}

#[test]
fn door_opens_by_the_action_length_over_its_lever() {
    // The ideal profile: a door of about half a metre (PartNet's at the paper's
    // 0.55 scale) pulled at its far edge gains 0.18 m / r per action.
    let m = model(Category::Door, 0);
    let (j, jm) = m.movable_joints().next().unwrap();
    let mut art = articulation(&m, 0.0);
    let (p, r) = grasp_point(&art, &m, j);
    art.attach(p, jm.child).unwrap();
    let (axis, origin) = art.joint_axis_in_world(j);
    let o = art
        .move_gripper(
            axis.cross(art.gripper_position().unwrap() - origin)
                .normalize(),
            j,
        )
        .unwrap();
    let gained = o.joint_after - o.joint_before;
    assert!((0.35..0.65).contains(&r), "lever {r}");
    let expected = 0.18 / r;
    assert!(
        (gained - expected).abs() < 0.1 * expected,
        "gained {gained} rad with lever {r} m, expected {expected}"
    );
}

#[test]
fn a_thousand_random_actions_never_explode() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let mut actions = 0;
    while actions < 1000 {
        let c = Category::ALL[rng.random_range(0..Category::ALL.len())];
        let m = model(c, rng.random_range(0..5));
        let mut art = articulation(&m, rng.random_range(-0.7..0.7));
        let movable: Vec<usize> = m.movable_joints().map(|(j, _)| j).collect();
        let j = movable[rng.random_range(0..movable.len())];
        let (p, _) = grasp_point(&art, &m, j);
        art.attach(p, m.joints[j].child).unwrap();
        for _ in 0..20 {
            let d = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize();
            let o = art.move_gripper(d, j).unwrap();
            actions += 1;
            for (k, jm) in m.joints.iter().enumerate() {
                let v = art.joint_position(k);
                assert!(v.is_finite(), "{c}: joint {k} became {v}");
                if jm.kind.is_movable() && jm.lower.is_finite() {
                    assert!(
                        v >= jm.lower - 0.05 && v <= jm.upper + 0.05,
                        "{c}: joint {k} = {v} outside [{}, {}]",
                        jm.lower,
                        jm.upper
                    );
                }
                assert!(
                    art.joint_velocity(k).abs() < 1e-3,
                    "velocities are zeroed after each action"
                );
            }
            assert!(
                o.gripper_moved <= 0.25,
                "{c}: gripper moved {} m in one 0.18 m action",
                o.gripper_moved
            );
        }
    }
}

#[test]
fn reset_restores_joint_values_and_the_same_actions_replay_bit_identically() {
    let m = model(Category::StorageFurniture, 3);
    let run = || {
        let mut art = articulation(&m, 0.2);
        let q: Vec<f32> = m
            .joints
            .iter()
            .map(|j| {
                if j.kind.is_movable() {
                    (j.lower + j.upper) * 0.37
                } else {
                    0.0
                }
            })
            .collect();
        art.set_joint_positions(&q).unwrap();
        for (k, v) in art.joint_positions().iter().enumerate() {
            assert!(
                (v - q[k]).abs() < 1e-5,
                "reset: joint {k} is {v}, expected {}",
                q[k]
            );
        }
        let (j, jm) = m.movable_joints().next().unwrap();
        let (p, _) = grasp_point(&art, &m, j);
        art.attach(p, jm.child).unwrap();
        let mut trace = Vec::new();
        for k in 0..8 {
            let a = k as f32 * 0.7;
            let o = art
                .move_gripper(Vec3::new(a.cos(), -0.8, a.sin()).normalize(), j)
                .unwrap();
            trace.push(o.joint_after.to_bits());
        }
        trace.extend(art.joint_positions().iter().map(|v| v.to_bits()));
        trace
    };
    assert_eq!(run(), run());
}

#[test]
fn scripted_back_and_forth_gives_the_defined_aot_labels() {
    // Drawer out, out, in, in: +1, +1, -1, -1 (relative to the grasp state).
    // A slide long enough for two effective pulls (> 2 x 0.15 m plus margin).
    let m = Category::ALL
        .iter()
        .flat_map(|&c| (0..10).map(move |i| model(c, i)))
        .find(|m| {
            m.movable_joints()
                .any(|(_, jm)| jm.kind == JointKind::Prismatic && jm.upper - jm.lower > 0.4)
        })
        .expect("some generated object has a slide longer than 0.4 m");
    let (j, jm) = m
        .movable_joints()
        .find(|(_, jm)| jm.kind == JointKind::Prismatic && jm.upper - jm.lower > 0.4)
        .unwrap();
    let mut art = articulation(&m, 0.0);
    let (p, _) = grasp_point(&art, &m, j);
    art.attach(p, jm.child).unwrap();
    let j0 = art.joint_position(j);
    let (axis, _) = art.joint_axis_in_world(j);
    let mut aots = Vec::new();
    for sign in [1.0, 1.0, -1.0, -1.0] {
        let o = art.move_gripper(axis * sign, j).unwrap();
        let l = labels(
            o.joint_before,
            o.joint_after,
            j0,
            jm.lower,
            jm.upper,
            true,
            o.suction_lost,
        );
        assert!((l.r_dist - (o.joint_after - o.joint_before).abs()).abs() < 1e-6);
        aots.push(if l.r_dist > DELTA {
            l.aot
        } else {
            2 * sign as i8
        });
    }
    assert_eq!(
        aots,
        vec![1, 1, -1, -1],
        "drawer range {}",
        jm.upper - jm.lower
    );
}

#[test]
fn generated_files_are_plain_urdf_that_urdf_rs_reads_without_mending() {
    let dir = tempfile::tempdir().unwrap();
    for &c in Category::ALL {
        let obj = generate(c, 1, 0);
        let path = obj.write(dir.path()).unwrap();
        let robot = urdf_rs::read_file(&path).unwrap_or_else(|e| panic!("{c}: {e}"));
        assert!(robot.joints.iter().any(|j| matches!(
            j.joint_type,
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Prismatic
        )));
        assert!(
            robot.links.iter().all(|l| l.inertial.mass.value > 0.0),
            "{c}: every link has an inertial"
        );
        // And it loads back through our loader from disk, meshes included.
        let m = umpnet_sim::urdf::load_urdf(&path).unwrap();
        assert_eq!(m.links.len(), robot.links.len());
    }
}

/// The test cabinet (door, drawer, lid) 0.5 m in front of the camera's side.
fn cabinet(profile: PhysicsProfile) -> (Arc<ObjectModel>, Articulation) {
    let urdf = include_str!("data/cabinet.urdf");
    let model =
        Arc::new(umpnet_sim::urdf::parse_urdf(urdf, std::path::Path::new("cabinet.urdf")).unwrap());
    let art = Articulation::new(
        model.clone(),
        Pose3::from_translation(Vec3::new(0.0, -0.5, 0.0)),
        PhysicsConfig::with_profile(profile),
    );
    (model, art)
}

#[test]
fn both_profiles_hold_a_grasp_until_released_and_set_joints_to_absolute_values() {
    for profile in PhysicsProfile::ALL {
        let (m, mut art) = cabinet(*profile);
        let j = m.joint_by_name("drawer_slide").unwrap();
        let drawer = m.links.iter().position(|l| l.name == "drawer").unwrap();
        assert!(
            drawer > 1,
            "the drawer's index must tell it from links 0 and 1"
        );
        assert_eq!((art.grasped_link(), art.gripper_position()), (None, None));
        assert!(art.move_gripper(Vec3::new(0.0, -1.0, 0.0), j).is_err());
        art.attach(Vec3::new(0.0, -0.76, 0.25), drawer).unwrap();
        assert_eq!(art.grasped_link(), Some(drawer), "{profile:?}");
        art.move_gripper(Vec3::new(0.0, -1.0, 0.0), j).unwrap();
        assert_eq!(
            art.grasped_link(),
            Some(drawer),
            "{profile:?}: an action keeps the grasp"
        );
        art.release();
        assert_eq!(
            (art.grasped_link(), art.gripper_position()),
            (None, None),
            "{profile:?}"
        );
        assert!(
            art.move_gripper(Vec3::new(0.0, -1.0, 0.0), j).is_err(),
            "{profile:?}"
        );
        // Joints are set to the values given, wherever they were: twice, from
        // a state that is not the rest state.
        art.attach(Vec3::new(0.0, -0.9, 0.25), drawer).unwrap();
        for values in [[0.3, 0.2, 0.5], [0.1, 0.05, 0.2]] {
            art.set_joint_positions(&values).unwrap();
            for (k, v) in values.iter().enumerate() {
                let now = art.joint_position(k);
                assert!(
                    (now - v).abs() < 1e-4,
                    "{profile:?}: joint {k} at {now}, set to {v}"
                );
                assert_eq!(art.joint_velocity(k), 0.0, "{profile:?}");
            }
            assert_eq!(
                art.grasped_link(),
                None,
                "{profile:?}: setting the joints lets go"
            );
        }
    }
}

#[test]
fn the_ideal_set_point_travels_the_action_at_the_action_speed() {
    let cfg = PhysicsConfig::with_profile(PhysicsProfile::Ideal);
    let (m, mut art) = cabinet(PhysicsProfile::Ideal);
    let j = m.joint_by_name("drawer_slide").unwrap();
    let drawer = m.links.iter().position(|l| l.name == "drawer").unwrap();
    art.attach(Vec3::new(0.0, -0.76, 0.25), drawer).unwrap();
    let o = art.move_gripper(Vec3::new(0.0, -1.0, 0.0), j).unwrap();
    // A set-point that jumped ahead would end the action in fewer steps.
    let travelled = o.steps as f32 * cfg.dt * cfg.action_speed;
    assert!(
        travelled >= cfg.action_length - 1e-4,
        "{} steps of {} s at {} m/s cover {travelled} m, short of the {} m action",
        o.steps,
        cfg.dt,
        cfg.action_speed,
        cfg.action_length
    );
    assert!(o.joint_after - o.joint_before > 0.1, "{o:?}");
}

/// The drawer of the test cabinet at `q`, grasped at the middle of its
/// front, on the ideal profile under `cfg`.
fn grasped_drawer(cfg: PhysicsConfig, q: f32) -> (Articulation, usize, usize) {
    let (m, _) = cabinet(PhysicsProfile::Ideal);
    let mut art = Articulation::new(
        m.clone(),
        Pose3::from_translation(Vec3::new(0.0, -0.5, 0.0)),
        cfg,
    );
    let j = m.joint_by_name("drawer_slide").unwrap();
    let drawer = m.links.iter().position(|l| l.name == "drawer").unwrap();
    art.set_joint_positions(&[0.0, q, 0.0]).unwrap();
    let front = art.world_from_link(drawer).transform_point(Vec3::ZERO);
    art.attach(front, drawer).unwrap();
    (art, j, drawer)
}

#[test]
fn an_ideal_pull_moves_a_free_drawer_the_action_length_along_the_pull_and_rests_on_the_grasp() {
    let cfg = PhysicsConfig::with_profile(PhysicsProfile::Ideal);
    let travel = (cfg.action_length / (cfg.action_speed * cfg.dt)).ceil() as usize;
    let (mut art, j, drawer) = grasped_drawer(cfg.clone(), 0.1);
    let on_grasp = |art: &Articulation| {
        let held = art.world_from_link(drawer).transform_point(Vec3::ZERO);
        (art.gripper_position().unwrap() - held).length()
    };
    for (d, sign) in [
        (Vec3::new(0.0, -1.0, 0.0), 1.0),
        (Vec3::new(0.0, 1.0, 0.0), -1.0),
    ] {
        let before = art.gripper_position().unwrap();
        let o = art.move_gripper(d, j).unwrap();
        let moved = art.gripper_position().unwrap() - before;
        // A free part follows the whole action, along it.
        assert!(
            (o.joint_after - o.joint_before - sign * cfg.action_length).abs() < 0.005,
            "{d}: {o:?}"
        );
        assert!(
            (moved - d * cfg.action_length).length() < 0.005,
            "{d}: moved {moved}"
        );
        // The set-point takes `travel` steps; the gripper then settles behind it.
        assert!(o.steps > travel && o.steps <= travel + 15, "{d}: {o:?}");
        assert!(on_grasp(&art) < 1e-4, "{d}: the gripper is off its grasp");
    }
    // Stopped by the limit, the gripper rests on the grasp, not where the
    // drive's spring had stretched to.
    art.set_joint_positions(&[0.0, 0.35, 0.0]).unwrap();
    let front = art.world_from_link(drawer).transform_point(Vec3::ZERO);
    art.attach(front, drawer).unwrap();
    let o = art.move_gripper(Vec3::new(0.0, -1.0, 0.0), j).unwrap();
    assert!((o.joint_after - 0.4).abs() < 0.005, "{o:?}");
    assert!(
        on_grasp(&art) < 1e-4,
        "the gripper is off its grasp at the limit"
    );
}

#[test]
fn the_ideal_suction_lets_go_past_its_force_limit() {
    let weak = PhysicsConfig {
        suction_max_force: 100.0,
        ..PhysicsConfig::with_profile(PhysicsProfile::Ideal)
    };
    // Pulling a drawer against its limit loads the suction up to the drive's
    // 1500 N: a 100 N suction lets go, the default 2000 N one holds.
    let (mut art, j, drawer) = grasped_drawer(weak.clone(), 0.35);
    let before = art.gripper_position().unwrap();
    let pull = Vec3::new(0.0, -1.0, 0.0);
    let o = art.move_gripper(pull, j).unwrap();
    assert!(o.suction_lost && art.grasped_link().is_none(), "{o:?}");
    // Let go, the gripper ends where its drive took it, off the part.
    let after = art.gripper_position().unwrap();
    assert!(
        (after - (before + pull * weak.action_length)).length() < 0.02,
        "{after}"
    );
    let held = art.world_from_link(drawer).transform_point(Vec3::ZERO);
    assert!((after - held).length() > 0.05);
    let (mut strong, j, drawer) =
        grasped_drawer(PhysicsConfig::with_profile(PhysicsProfile::Ideal), 0.35);
    let o = strong.move_gripper(pull, j).unwrap();
    assert!(
        !o.suction_lost && strong.grasped_link() == Some(drawer),
        "{o:?}"
    );
}
