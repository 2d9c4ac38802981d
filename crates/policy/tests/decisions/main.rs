//! What `UmpnetPolicy` decides, on the fixture's packages (made by
//! `python -m umpnet_train.fixture DIR`; make test sets UMPNET_FIXTURE):
//! - the untrained package, for the grasp: the test reads its affordance map
//!   and works out the pixel the policy must pick;
//! - `steer`, whose decoder ignores the image: distance 0.3 - 0.2 x, AoT +1
//!   along +x and -1 along -x, so the largest distance is a backward move;
//! - `steer-normal90`, the same with the Where2Act pulling filter;
//! - `inverse`, an Inverse baseline that always regresses (1.2, 1.6, 0),
//!   which its package normalises to (0.6, 0.8, 0).
//!
//! One module per kind of decision (`grasp`, `directions`, `filters`,
//! `onward45`); the helpers here load the packages and build their inputs.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests fail by panicking"
)]
use nalgebra::Vector3;
use ndarray::{Array3, Axis};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;
use umpnet_policy::cem::Mode;
use umpnet_policy::policy::GOAL_DIFF_M;
use umpnet_policy::{CHANNELS, DecisionInput, ModelPackage, UmpnetPolicy};

#[path = "../common/mod.rs"]
mod common;

mod directions;
mod filters;
mod grasp;
mod onward45;

/// The fixture's package `name` ("" for the untrained one), or None (skipped;
/// see `common::fixture`).
fn policy(name: &str) -> Option<UmpnetPolicy> {
    let dir = common::fixture()?.join(name);
    let package = ModelPackage::load(&dir, 1, 1, None)
        .unwrap_or_else(|e| panic!("{}: {e} (rebuild the fixture)", dir.display()));
    Some(UmpnetPolicy::new(Arc::new(package)))
}

/// A random observation at the policy's resolution, every pixel with depth.
fn observation(policy: &UmpnetPolicy, seed: u64) -> Array3<f32> {
    use rand::Rng;
    let (h, w) = policy.resolution();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut obs = Array3::from_shape_fn((h, w, CHANNELS), |_| rng.random_range(-1.0f32..1.0));
    obs.index_axis_mut(Axis(2), 9).fill(2.0);
    obs
}

/// The affordance map the policy's package gives for `obs`.
fn affordance(policy: &UmpnetPolicy, obs: &Array3<f32>) -> ndarray::Array2<f32> {
    policy
        .package
        .position(obs.view().insert_axis(Axis(0)))
        .unwrap()
        .index_axis_move(Axis(0), 0)
}

/// The pixel of largest affordance among those `allowed` (first in raster order on ties).
fn best(aff: &ndarray::Array2<f32>, allowed: impl Fn(usize, usize) -> bool) -> (usize, usize) {
    let mut out: Option<((usize, usize), f32)> = None;
    for ((r, c), &a) in aff.indexed_iter() {
        if allowed(r, c) && out.is_none_or(|(_, b)| a > b) {
            out = Some(((r, c), a));
        }
    }
    out.unwrap().0
}

fn decide(
    policy: &UmpnetPolicy,
    obs: &[Array3<f32>],
    modes: &[Mode],
    banned: &[Vector3<f32>],
    seed: u64,
) -> Vec<umpnet_policy::cem::CemResult> {
    let (h, w) = policy.resolution();
    decide_at(policy, obs, modes, banned, seed, (h / 2, w / 2))
}

fn decide_at(
    policy: &UmpnetPolicy,
    obs: &[Array3<f32>],
    modes: &[Mode],
    banned: &[Vector3<f32>],
    seed: u64,
    pixel: (usize, usize),
) -> Vec<umpnet_policy::cem::CemResult> {
    let inputs: Vec<DecisionInput<'_>> = obs
        .iter()
        .zip(modes)
        .map(|(o, &mode)| DecisionInput {
            observation: o.view(),
            reference: o.view(),
            pixel,
            banned,
            previous: None,
            mode,
            joint: None,
            motion: None,
            long_motion: None,
        })
        .collect();
    let mut rngs: Vec<ChaCha8Rng> = (0..obs.len())
        .map(|i| ChaCha8Rng::seed_from_u64(seed + i as u64))
        .collect();
    policy.directions(&inputs, &mut rngs).unwrap()
}

fn explore<'a>(
    observation: &'a Array3<f32>,
    reference: &'a Array3<f32>,
    pixel: (usize, usize),
) -> DecisionInput<'a> {
    DecisionInput {
        observation: observation.view(),
        reference: reference.view(),
        pixel,
        banned: &[],
        previous: None,
        mode: Mode::Explore,
        joint: None,
        motion: None,
        long_motion: None,
    }
}

/// An H x W observation through a pinhole at the origin looking down +z of
/// a wall at z = 2 with a 0.4 m panel in front of it at depth `z`, centred
/// at (`x`, 0).
fn panel(policy: &UmpnetPolicy, x: f32, z: f32) -> Array3<f32> {
    let (h, w) = policy.resolution();
    let f = w as f32;
    let mut obs = Array3::<f32>::zeros((h, w, CHANNELS));
    for r in 0..h {
        for c in 0..w {
            let u = (c as f32 + 0.5 - w as f32 / 2.0) / f;
            let v = (r as f32 + 0.5 - h as f32 / 2.0) / f;
            let depth = if (u * z - x).abs() < 0.2 && (v * z).abs() < 0.2 {
                z
            } else {
                2.0
            };
            obs[[r, c, 0]] = u * depth;
            obs[[r, c, 1]] = v * depth;
            obs[[r, c, 2]] = depth;
            obs[[r, c, 9]] = depth;
        }
    }
    obs
}
