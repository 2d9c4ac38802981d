//! The loader fuzzer: mutated generated URDFs and OBJ meshes, plus a corpus of
//! hand-made bad files, must each load into a finite, usable model or fail
//! with a typed error. A panic, a NaN in a loaded model or a NaN out of the
//! physics fails the test (proptest shrinks it to a small reproduction).
//!
//! Fixed seeds: the same cases run everywhere, in about half a minute in
//! release builds. Raise `UMPNET_FUZZ_CASES` for a longer hunt.
//!
//! `text` mutates files' contents, `folders` the files themselves; the checks
//! of what "loaded" promises and the seeded runner are here.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests and benchmarks fail by panicking"
)]
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, RngSeed, TestCaseError, TestRunner};
use std::cell::Cell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use umpnet_sim::SimError;
use umpnet_sim::math::{Pose3, Vec3};
use umpnet_sim::mesh::TriMesh;
use umpnet_sim::objects::{Category, GeneratedObject, PARTNET_SCALE, generate};
use umpnet_sim::physics::{Articulation, PhysicsConfig, PhysicsProfile};
use umpnet_sim::urdf::{ObjectModel, parse_urdf_with};

mod folders;
mod text;

fn finite3(v: Vec3) -> bool {
    v.is_finite()
}

/// What "loaded" promises: every number the physics and renderer read is
/// finite (limits may be infinite only on continuous joints) and sane.
fn check_model(m: &ObjectModel) -> Result<(), TestCaseError> {
    prop_assert!(!m.links.is_empty(), "a model without links loaded");
    prop_assert!(m.root < m.links.len());
    for l in &m.links {
        prop_assert!(
            l.mass.is_finite() && l.mass > 0.0,
            "link {} mass {}",
            l.name,
            l.mass
        );
        prop_assert!(
            finite3(l.com_in_link),
            "link {} com {:?}",
            l.name,
            l.com_in_link
        );
        prop_assert!(
            l.inertia_in_link
                .to_cols_array()
                .iter()
                .all(|x| x.is_finite()),
            "link {} inertia {:?}",
            l.name,
            l.inertia_in_link
        );
        for v in &l.visuals {
            prop_assert!(v.color.iter().all(|c| c.is_finite()));
            prop_assert!(v.mesh_in_link.positions.iter().all(|p| finite3(*p)));
            let n = v.mesh_in_link.positions.len() as u32;
            prop_assert!(
                v.mesh_in_link.triangles.iter().flatten().all(|i| *i < n),
                "index out of range"
            );
        }
    }
    for j in &m.joints {
        prop_assert!(j.parent < m.links.len() && j.child < m.links.len());
        prop_assert!(finite3(j.parent_from_joint.translation));
        prop_assert!(j.parent_from_joint.rotation.is_finite());
        prop_assert!(
            finite3(j.axis_in_joint) && (j.axis_in_joint.length() - 1.0).abs() < 1e-3,
            "joint {} axis {:?}",
            j.name,
            j.axis_in_joint
        );
        prop_assert!(!j.lower.is_nan() && !j.upper.is_nan() && j.lower <= j.upper);
        if j.kind.is_movable() && j.kind != umpnet_sim::urdf::JointKind::Continuous {
            prop_assert!(
                j.lower.is_finite() && j.upper.is_finite(),
                "joint {} limits",
                j.name
            );
        }
        prop_assert!(j.damping.is_finite() && j.friction.is_finite());
    }
    Ok(())
}

/// Grasps each movable joint's child at its centre of mass and pulls it two
/// ways: the joint values must stay finite and within the limits.
fn check_physics(m: ObjectModel, profile: PhysicsProfile) -> Result<(), TestCaseError> {
    let m = Arc::new(m);
    for (j, joint) in m.movable_joints().take(2) {
        let mut art = Articulation::new(
            m.clone(),
            Pose3::IDENTITY,
            PhysicsConfig::with_profile(profile),
        );
        let q0 = art.joint_position(j);
        prop_assert!(
            q0 >= joint.lower && q0 <= joint.upper,
            "joint {} starts at {q0}, outside [{}, {}]",
            joint.name,
            joint.lower,
            joint.upper
        );
        let link = joint.child;
        let at = art
            .world_from_link(link)
            .transform_point(m.links[link].com_in_link);
        if art.attach(at, link).is_err() {
            continue;
        }
        for dir in [Vec3::X, -Vec3::Y, Vec3::Z] {
            match art.move_gripper(dir, j) {
                Ok(_) => {}
                Err(SimError::InvalidAction(_)) => break,
                Err(e) => return Err(TestCaseError::fail(format!("move_gripper: {e}"))),
            }
            let q = art.joint_position(j);
            prop_assert!(q.is_finite(), "joint {} became {q}", joint.name);
            prop_assert!(
                q >= joint.lower - 1e-2 && q <= joint.upper + 1e-2,
                "joint {} at {q} outside [{}, {}]",
                joint.name,
                joint.lower,
                joint.upper
            );
        }
    }
    Ok(())
}

fn cases(default: u32) -> u32 {
    std::env::var("UMPNET_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn runner(cases: u32, seed: u64) -> TestRunner {
    TestRunner::new(Config {
        cases,
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        max_shrink_iters: 2000,
        ..Config::default()
    })
}

/// One generated object per category, with the in-memory meshes it refers to.
fn seeds() -> Vec<GeneratedObject> {
    Category::ALL.iter().map(|&c| generate(c, 1, 7)).collect()
}

fn load(obj: &GeneratedObject, text: &str) -> umpnet_sim::Result<ObjectModel> {
    let dir = PathBuf::from(format!("fuzz/{}/{}", obj.category.name(), obj.index));
    let meshes: HashMap<PathBuf, &TriMesh> = obj
        .meshes
        .iter()
        .map(|(rel, m)| (dir.join(rel), m))
        .collect();
    parse_urdf_with(text, &dir.join("mobility.urdf"), &|p| {
        meshes.get(p).map(|m| (*m).clone())
    })
}
