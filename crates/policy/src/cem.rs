//! The paper's direction sampler: 64 candidates on a Fibonacci sphere under a
//! random rotation, scored; a second round resampled with probability
//! proportional to exp(20 x score) plus noise, re-scored; then the pick.
#![allow(
    clippy::indexing_slicing,
    reason = "indices stay below the lengths of the candidate lists it built"
)]
use nalgebra::{Rotation3, Unit, Vector3};
use rand::Rng;
use rand_distr::StandardNormal;

/// Candidates per CEM round: the paper's 64.
pub const CANDIDATES: usize = 64;
/// Most candidates per round a caller may ask for (`--cem-samples`).
pub const MAX_CANDIDATES: usize = 1024;

/// How candidate directions are drawn and scored for one decision.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sampler {
    /// The paper's cross-entropy method: `n` evenly spread directions, then
    /// `n` resampled around the best of them; the best of all is chosen.
    Cem {
        /// Candidates per round.
        n: usize,
    },
    /// The paper's ablation: one round of `2n` evenly spread directions (the
    /// same number of network evaluations as CEM with `n`).
    Uniform {
        /// Half the round's candidates.
        n: usize,
    },
}

impl Default for Sampler {
    fn default() -> Self {
        Sampler::Cem { n: CANDIDATES }
    }
}

impl Sampler {
    /// Candidates per round (CEM) or half the single round (uniform).
    pub fn samples(self) -> usize {
        match self {
            Sampler::Cem { n } | Sampler::Uniform { n } => n,
        }
    }
    /// `cem` or `uniform`, as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Sampler::Cem { .. } => "cem",
            Sampler::Uniform { .. } => "uniform",
        }
    }
}
/// Temperature of the resampling weights (paper: exp(20 x score)).
pub const RESAMPLE_SHARPNESS: f32 = 20.0;
/// Standard deviation of the noise added to resampled directions.
pub const RESAMPLE_NOISE: f32 = 0.1;
/// Directions closer than this angle to a banned one are not proposed.
pub const BAN_COS: f32 = 0.94; // about 20 degrees

/// What a decision is for: which candidates count and when to stop.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Largest predicted distance among directions predicted to move forward (AoT +1).
    Explore,
    /// Largest predicted distance among directions predicted to move back (AoT -1); stop when none.
    Goal,
}

/// What the networks say about one candidate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Score {
    /// Predicted joint change |j_t - j_{t-1}| (rad or m).
    pub distance: f32,
    /// argmax class: -1, 0 or +1.
    pub aot: i8,
}

/// One decision: the chosen direction, and every candidate scored on the way.
#[derive(Clone, Debug)]
pub struct CemResult {
    /// None: goal mode found no direction predicted to move toward the goal.
    pub direction: Option<Vector3<f32>>,
    /// Every candidate scored, both rounds (unit, world frame).
    pub candidates: Vec<Vector3<f32>>,
    /// The networks' scores of `candidates`, in the same order.
    pub scores: Vec<Score>,
}

/// `n` unit directions spread evenly over the sphere (a Fibonacci lattice).
pub fn fibonacci_sphere(n: usize) -> Vec<Vector3<f32>> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let t = golden * i as f32;
            Vector3::new(r * t.cos(), r * t.sin(), z)
        })
        .collect()
}

/// A rotation about a uniformly random axis by a uniformly random angle:
/// turns the lattice so that no direction is favoured across decisions.
pub fn random_rotation(rng: &mut impl Rng) -> Rotation3<f32> {
    loop {
        let v = Vector3::new(
            rng.sample::<f32, _>(StandardNormal),
            rng.sample(StandardNormal),
            rng.sample(StandardNormal),
        );
        if let Some(axis) = Unit::try_new(v, 1e-6) {
            return Rotation3::from_axis_angle(&axis, rng.random_range(0.0..std::f32::consts::TAU));
        }
    }
}

fn is_banned(d: &Vector3<f32>, banned: &[Vector3<f32>]) -> bool {
    banned.iter().any(|b| d.dot(b) > BAN_COS)
}

/// The value CEM concentrates on: predicted distance where the predicted AoT
/// is the wanted one, zero elsewhere.
pub fn objective(s: &Score, mode: Mode) -> f32 {
    let wanted = if mode == Mode::Explore { 1 } else { -1 };
    if s.aot == wanted {
        s.distance.max(0.0)
    } else {
        0.0
    }
}

/// The first round's `n` candidates for one decision: an evenly spread
/// sphere of directions, randomly turned.
pub fn first_round(rng: &mut impl Rng, banned: &[Vector3<f32>], n: usize) -> Vec<Vector3<f32>> {
    let rot = random_rotation(rng);
    let all: Vec<Vector3<f32>> = fibonacci_sphere(n).into_iter().map(|d| rot * d).collect();
    let kept: Vec<Vector3<f32>> = all
        .iter()
        .copied()
        .filter(|d| !is_banned(d, banned))
        .collect();
    if kept.is_empty() { all } else { kept }
}

/// The index whose share of the weights' running sum holds `u` (drawn in
/// `[0, total)`). Rounding can make `u` reach the sum of the weights before
/// the last one is passed; the walk then stops at the last index instead of
/// running off the end.
pub fn roulette(weights: &[f32], mut u: f32) -> usize {
    let mut k = 0;
    while k + 1 < weights.len() && u >= weights[k] {
        u -= weights[k];
        k += 1;
    }
    k
}

/// The second round: `n` candidates resampled around the good ones of the first.
pub fn second_round(
    rng: &mut impl Rng,
    first: &[Vector3<f32>],
    scores: &[Score],
    mode: Mode,
    banned: &[Vector3<f32>],
    n: usize,
) -> Vec<Vector3<f32>> {
    let obj: Vec<f32> = scores.iter().map(|s| objective(s, mode)).collect();
    let top = obj.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let weights: Vec<f32> = obj
        .iter()
        .map(|o| (RESAMPLE_SHARPNESS * (o - top)).exp())
        .collect();
    let total: f32 = weights.iter().sum();
    let mut out = Vec::with_capacity(n);
    let mut tries = 0;
    while out.len() < n && tries < n * 20 {
        tries += 1;
        let k = roulette(
            &weights,
            rng.random_range(0.0..total.max(f32::MIN_POSITIVE)),
        );
        let noise = Vector3::new(
            rng.sample::<f32, _>(StandardNormal),
            rng.sample(StandardNormal),
            rng.sample(StandardNormal),
        ) * RESAMPLE_NOISE;
        let Some(d) = (first[k] + noise).try_normalize(1e-6) else {
            continue;
        };
        if !is_banned(&d, banned) {
            out.push(d);
        }
    }
    out
}

/// Picks from all scored candidates (both rounds).
pub fn select(candidates: &[Vector3<f32>], scores: &[Score], mode: Mode) -> Option<Vector3<f32>> {
    let wanted = if mode == Mode::Explore { 1 } else { -1 };
    let best = |filter: &dyn Fn(&Score) -> bool| {
        candidates
            .iter()
            .zip(scores)
            .filter(|(_, s)| filter(s))
            .max_by(|a, b| a.1.distance.total_cmp(&b.1.distance))
            .map(|(d, _)| *d)
    };
    match mode {
        Mode::Goal => best(&|s| s.aot == wanted),
        // Exploration never stops: with no forward candidate, the largest distance.
        Mode::Explore => best(&|s| s.aot == wanted).or_else(|| best(&|_| true)),
    }
}

/// Both rounds for one decision with a scoring function (used by tests and
/// single-environment callers; the batched policy drives the rounds itself).
pub fn cem(
    rng: &mut impl Rng,
    mode: Mode,
    banned: &[Vector3<f32>],
    score: &mut dyn FnMut(&[Vector3<f32>]) -> Vec<Score>,
) -> CemResult {
    let first = first_round(rng, banned, CANDIDATES);
    let s1 = score(&first);
    let second = second_round(rng, &first, &s1, mode, banned, CANDIDATES);
    let s2 = score(&second);
    let candidates: Vec<Vector3<f32>> = first.into_iter().chain(second).collect();
    let scores: Vec<Score> = s1.into_iter().chain(s2).collect();
    CemResult {
        direction: select(&candidates, &scores, mode),
        candidates,
        scores,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn roulette_picks_the_share_that_holds_u_and_stops_at_the_last_index() {
        let w = [0.25f32, 0.5, 0.25];
        assert_eq!(roulette(&w, 0.0), 0);
        assert_eq!(roulette(&w, 0.2499), 0);
        assert_eq!(roulette(&w, 0.25), 1);
        assert_eq!(roulette(&w, 0.7499), 1);
        assert_eq!(roulette(&w, 0.75), 2);
        // u at or past the whole sum (rounding in the draw or the sum): the last
        // index, never one past it.
        assert_eq!(roulette(&w, 1.0), 2);
        assert_eq!(roulette(&w, 1.5), 2);
        assert_eq!(roulette(&[1.0], 3.0), 0);
    }

    fn peak(target: Vector3<f32>) -> impl FnMut(&[Vector3<f32>]) -> Vec<Score> {
        move |ds: &[Vector3<f32>]| {
            ds.iter()
                .map(|d| {
                    let c = d.dot(&target);
                    Score {
                        distance: 0.18 * c.max(0.0),
                        aot: if c > 0.2 {
                            1
                        } else if c < -0.2 {
                            -1
                        } else {
                            0
                        },
                    }
                })
                .collect()
        }
    }

    #[test]
    fn concentrates_near_the_maximum() {
        let target = Vector3::new(0.3, -0.8, 0.5).normalize();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let mut worst: f32 = 1.0;
        for _ in 0..50 {
            let r = cem(&mut rng, Mode::Explore, &[], &mut peak(target));
            let d = r.direction.unwrap();
            worst = worst.min(d.dot(&target));
            // The second round sits closer to the peak than the uniform first round.
            let mean =
                |s: &[Vector3<f32>]| s.iter().map(|d| d.dot(&target)).sum::<f32>() / s.len() as f32;
            assert!(mean(&r.candidates[CANDIDATES..]) > mean(&r.candidates[..CANDIDATES]) + 0.5);
        }
        assert!(
            worst > 0.97,
            "best direction only {:.1} degrees from the peak",
            worst.acos().to_degrees()
        );
    }

    #[test]
    fn honours_bans() {
        let target = Vector3::new(0.0, 0.0, 1.0);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let banned = [target];
        for _ in 0..20 {
            let r = cem(&mut rng, Mode::Explore, &banned, &mut peak(target));
            assert!(r.candidates.iter().all(|d| d.dot(&target) <= BAN_COS));
            assert!(r.direction.unwrap().dot(&target) <= BAN_COS);
        }
    }

    #[test]
    fn goal_mode_stops_when_no_aot_is_negative() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut all_forward = |ds: &[Vector3<f32>]| {
            ds.iter()
                .map(|_| Score {
                    distance: 0.2,
                    aot: 1,
                })
                .collect()
        };
        assert!(
            cem(&mut rng, Mode::Goal, &[], &mut all_forward)
                .direction
                .is_none()
        );
        let target = Vector3::new(1.0, 0.0, 0.0);
        let r = cem(&mut rng, Mode::Goal, &[], &mut peak(target));
        assert!(
            r.direction.unwrap().dot(&target) < -0.2,
            "goal mode picks a negative-AoT direction"
        );
    }

    #[test]
    fn selection_follows_the_wanted_arrow_of_time_before_distance() {
        let dirs = [
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(-1.0, 0.0, 0.0),
            Vector3::new(0.0, 1.0, 0.0),
            Vector3::new(0.0, 0.0, 1.0),
        ];
        let score = |distance, aot| Score { distance, aot };
        // The largest distance is backward (-x), a smaller one forward (+x).
        let scores = [score(0.2, 1), score(0.9, -1), score(0.5, 0), score(0.1, 1)];
        assert_eq!(select(&dirs, &scores, Mode::Explore), Some(dirs[0]));
        assert_eq!(select(&dirs, &scores, Mode::Goal), Some(dirs[1]));
        // Nothing forward: exploration still moves (largest distance); the goal mode
        // with nothing backward stops.
        let none_forward = [score(0.2, 0), score(0.9, -1), score(0.5, 0), score(0.1, 0)];
        assert_eq!(select(&dirs, &none_forward, Mode::Explore), Some(dirs[1]));
        let none_back = [score(0.2, 1), score(0.9, 0), score(0.5, 1), score(0.1, 0)];
        assert_eq!(select(&dirs, &none_back, Mode::Goal), None);
        // The objective CEM resamples around counts only the wanted class.
        assert_eq!(objective(&scores[1], Mode::Explore), 0.0);
        assert_eq!(objective(&scores[0], Mode::Explore), 0.2);
        assert_eq!(objective(&scores[1], Mode::Goal), 0.9);
    }

    #[test]
    fn fibonacci_directions_are_unit_and_spread_over_the_sphere() {
        let dirs = fibonacci_sphere(CANDIDATES);
        assert_eq!(dirs.len(), CANDIDATES);
        for d in &dirs {
            assert!((d.norm() - 1.0).abs() < 1e-5, "{d:?} is not a unit vector");
        }
        // Heights are evenly spaced strips, pole to pole.
        let n = CANDIDATES as f32;
        for (i, d) in dirs.iter().enumerate() {
            assert!((d.z - (1.0 - (2 * i + 1) as f32 / n)).abs() < 1e-6);
        }
        // The golden-angle turn keeps every pair of directions apart: an even
        // cover of 64 points has neighbours about 25 degrees apart; a wrong
        // turn per step brings some within 17 degrees of each other.
        let closest = dirs
            .iter()
            .enumerate()
            .flat_map(|(i, a)| dirs[i + 1..].iter().map(move |b| a.dot(b)))
            .fold(f32::NEG_INFINITY, f32::max);
        assert!(
            closest.acos() > 0.35,
            "two directions only {:.1} degrees apart",
            closest.acos().to_degrees()
        );
    }

    #[test]
    fn a_ban_covers_directions_strictly_within_its_angle() {
        let banned = [Vector3::new(1.0, 0.0, 0.0)];
        let on_the_edge = Vector3::new(BAN_COS, (1.0 - BAN_COS * BAN_COS).sqrt(), 0.0);
        assert!(!is_banned(&on_the_edge, &banned));
        let inside = Vector3::new(BAN_COS + 0.01, (1.0 - (BAN_COS + 0.01).powi(2)).sqrt(), 0.0);
        assert!(is_banned(&inside, &banned));
    }

    /// Share of `second_round`'s draws near `a` rather than `b` (orthogonal),
    /// given their objectives.
    fn share_near_first(objectives: [f32; 2], seed: u64) -> f32 {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let first = [Vector3::x(), Vector3::y()];
        let scores = objectives.map(|distance| Score { distance, aot: 1 });
        let mut near = 0;
        let mut all = 0;
        for _ in 0..40 {
            let drawn = second_round(&mut rng, &first, &scores, Mode::Explore, &[], CANDIDATES);
            assert_eq!(
                drawn.len(),
                CANDIDATES,
                "the second round has as many candidates as the first"
            );
            near += drawn.iter().filter(|d| d.x > d.y).count();
            all += drawn.len();
        }
        near as f32 / all as f32
    }

    #[test]
    fn resampling_weights_are_exp_of_twenty_times_the_score() {
        // Objectives 0.1 and 0: weights e^2 : 1, so 88% of draws come from the first.
        let expected = (RESAMPLE_SHARPNESS * 0.1).exp() / ((RESAMPLE_SHARPNESS * 0.1).exp() + 1.0);
        let share = share_near_first([0.1, 0.0], 4);
        assert!(
            (share - expected).abs() < 0.03,
            "{share} of draws near the better candidate, expected {expected}"
        );
        // Only differences count: large predicted distances give the same split
        // and do not overflow.
        let share = share_near_first([10.1, 10.0], 5);
        assert!(
            (share - expected).abs() < 0.03,
            "{share} at large distances, expected {expected}"
        );
    }

    #[test]
    fn resampling_tries_past_bans_and_stops_when_everything_is_banned() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(6);
        let first = [Vector3::z()];
        let scores = [Score {
            distance: 0.2,
            aot: 1,
        }];
        // A ban whose cone edge passes through the only good candidate turns
        // away about half the draws; the round still fills up.
        let tilt = BAN_COS.acos();
        let half = [Vector3::new(tilt.sin(), 0.0, tilt.cos())];
        for _ in 0..10 {
            let drawn = second_round(&mut rng, &first, &scores, Mode::Explore, &half, CANDIDATES);
            assert_eq!(drawn.len(), CANDIDATES);
        }
        // Everything banned: the round gives up with no candidate instead of spinning.
        let everywhere = fibonacci_sphere(400);
        assert!(
            second_round(
                &mut rng,
                &first,
                &scores,
                Mode::Explore,
                &everywhere,
                CANDIDATES
            )
            .is_empty()
        );
    }
}
