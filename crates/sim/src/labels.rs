//! What one executed direction is labelled with. Two definitions live here,
//! on purpose side by side:
//! - [`labels`]: the paper's task definition, with δ as the threshold. The
//!   evaluation metrics and the scripted policies read these.
//! - [`train_labels`]: what the paper's released training code records
//!   (sim.py `get_reward` / `get_init_boundary`): thresholds of 0.1 rad or
//!   0.05 m (a 3.5th of a short range), a sign that ignores the first 0.02
//!   from the start, and the limit and start events its contradictory policy
//!   turns on. Training reads these by default.

/// δ: the smallest joint change that counts as a state change — 0.15 m for
/// prismatic joints, 8.6° = 0.15 rad for revolute ones.
pub const DELTA: f32 = 0.15;

/// How far from its start a joint must be before the reference signs a move
/// as forward or back.
const SIGN_DEADBAND: f32 = 0.02;

/// Labels of one executed direction.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StepLabels {
    /// The grasped joint's value before the move.
    pub joint_before: f32,
    /// Its value after.
    pub joint_after: f32,
    /// |j_t - j_{t-1}|
    pub r_dist: f32,
    /// Arrow of Time: 0 (no effective change), +1 (away from the start), -1 (back).
    pub aot: i8,
    /// The joint changed by more than the protocol's threshold.
    pub moved: bool,
    /// The joint is now at a limit.
    pub reached_limit: bool,
    /// The joint is back where it was grasped.
    pub back_at_start: bool,
    /// `ideal` only: the suction let go.
    pub suction_lost: bool,
    /// The reference training code's labels for the same step.
    #[serde(default)]
    pub train: TrainLabels,
}

/// The labels the paper's released training code records for one step.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrainLabels {
    /// |Δj| above 0.1 rad / 0.05 m, or above a 3.5th of the range.
    pub moved: bool,
    /// 0 when not moved; -1 when the move heads back towards the start (from
    /// more than 0.02 away); else +1.
    pub aot: i8,
    /// Moved more than the threshold from the start and now within it of a
    /// limit: where the contradictory policy turns back.
    pub reached_boundary: bool,
    /// Within the threshold of the start, or across it: where the
    /// contradictory policy's return ends.
    pub reached_init: bool,
}

/// The reference's closeness threshold for a joint: 0.1 rad or 0.05 m, at
/// most a 3.5th of the range.
pub fn threshold(prismatic: bool, lower: f32, upper: f32) -> f32 {
    let base: f32 = if prismatic { 0.05 } else { 0.1 };
    let range = upper - lower;
    if range.is_finite() {
        base.min(range / 3.5)
    } else {
        base
    }
}

/// The reference's boundary event: moved more than `threshold` from the
/// start and now within it of a limit.
pub fn reached_limit(value: f32, start: f32, lower: f32, upper: f32, threshold: f32) -> bool {
    (value - start).abs() > threshold && (value < lower + threshold || value > upper - threshold)
}

/// The paper's labels for one action (pure function, tested on its own).
pub fn labels(
    before: f32,
    after: f32,
    j0: f32,
    lower: f32,
    upper: f32,
    prismatic: bool,
    suction_lost: bool,
) -> StepLabels {
    let r_dist = (after - before).abs();
    // A move from (numerically) the start is forward by definition.
    let from_start = if (before - j0).abs() < 1e-3 {
        0.0
    } else {
        before - j0
    };
    let gamma = (after - before) * from_start;
    let aot = if r_dist <= DELTA {
        0
    } else if gamma >= 0.0 {
        1
    } else {
        -1
    };
    let tol = 1e-3 + 1e-3 * (upper - lower).abs().min(10.0);
    StepLabels {
        joint_before: before,
        joint_after: after,
        r_dist,
        aot,
        moved: r_dist > DELTA / 10.0,
        reached_limit: (after - lower).abs() < tol || (after - upper).abs() < tol,
        back_at_start: (after - j0).abs() <= DELTA,
        suction_lost,
        train: train_labels(before, after, j0, lower, upper, prismatic),
    }
}

/// The reference training code's labels for a step from `before` to `after`
/// of a joint that started the sequence at `j0`.
pub fn train_labels(
    before: f32,
    after: f32,
    j0: f32,
    lower: f32,
    upper: f32,
    prismatic: bool,
) -> TrainLabels {
    let step = after - before;
    let r = step.abs();
    let base: f32 = if prismatic { 0.05 } else { 0.1 };
    let range = upper - lower;
    let moved = r > base || (range.is_finite() && r * 3.5 > range);
    let from_start = before - j0;
    let back = from_start.abs() > SIGN_DEADBAND && from_start * step < 0.0;
    let aot = match (moved, back) {
        (false, _) => 0,
        (true, true) => -1,
        (true, false) => 1,
    };
    let thr = threshold(prismatic, lower, upper);
    let reached_init = (before > j0 && after < j0 + thr)
        || (before < j0 && after > j0 - thr)
        || (after - j0).abs() < thr;
    TrainLabels {
        moved,
        aot,
        reached_boundary: reached_limit(after, j0, lower, upper, thr),
        reached_init,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aot_labels_follow_the_definition() {
        // Forward from the start, forward again, back, no change.
        assert_eq!(labels(0.0, 0.3, 0.0, 0.0, 1.5, false, false).aot, 1);
        assert_eq!(labels(0.3, 0.6, 0.0, 0.0, 1.5, false, false).aot, 1);
        assert_eq!(labels(0.6, 0.3, 0.0, 0.0, 1.5, false, false).aot, -1);
        assert_eq!(labels(0.6, 0.7, 0.0, 0.0, 1.5, false, false).aot, 0);
        // Starting mid-range and going down first is also "forward".
        assert_eq!(labels(0.8, 0.5, 0.8, 0.0, 1.5, false, false).aot, 1);
        assert_eq!(labels(0.5, 0.8, 0.8, 0.0, 1.5, false, false).aot, -1);
        let l = labels(1.2, 1.5, 0.0, 0.0, 1.5, false, false);
        assert!(l.reached_limit && !l.back_at_start);
        assert!(labels(0.3, 0.1, 0.0, 0.0, 1.5, false, false).back_at_start);
    }

    #[test]
    fn training_labels_follow_the_reference_code() {
        // Revolute [0, 1.57]: 0.1 rad counts as moved, δ would not.
        let t = train_labels(0.0, 0.12, 0.0, 0.0, 1.57, false);
        assert!(t.moved && t.aot == 1 && !t.reached_boundary);
        assert!(!train_labels(0.0, 0.09, 0.0, 0.0, 1.57, false).moved);
        // Prismatic [0, 0.4]: 0.05 m, so a 0.13 m pull is a move (δ: not).
        let t = train_labels(0.13, 0.26, 0.0, 0.0, 0.4, true);
        assert_eq!((t.moved, t.aot), (true, 1));
        assert!(!train_labels(0.13, 0.17, 0.0, 0.0, 0.4, true).moved);
        // Back towards the start is -1, but only from more than 0.02 away.
        assert_eq!(train_labels(0.26, 0.13, 0.0, 0.0, 0.4, true).aot, -1);
        assert_eq!(train_labels(0.8, 0.5, 0.8, 0.0, 1.57, false).aot, 1);
        assert_eq!(train_labels(0.81, 0.5, 0.8, 0.0, 1.57, false).aot, 1);
        assert_eq!(train_labels(0.9, 0.5, 0.8, 0.0, 1.57, false).aot, -1);
        // A short range moves when a step spans a 3.5th of it.
        let t = train_labels(0.0, 0.03, 0.0, 0.0, 0.1, true);
        assert!(t.moved);
        // Boundary: near a limit and away from the start; init: back within thr.
        assert!(train_labels(0.3, 0.37, 0.0, 0.0, 0.4, true).reached_boundary);
        assert!(!train_labels(0.0, 0.005, 0.0, 0.0, 0.03, true).reached_boundary);
        assert!(train_labels(0.0, 0.03, 0.0, 0.0, 0.03, true).reached_boundary);
        assert!(train_labels(0.13, 0.04, 0.0, 0.0, 0.4, true).reached_init);
        assert!(train_labels(0.5, -0.2, 0.3, -1.0, 1.0, false).reached_init);
        assert!(!train_labels(0.13, 0.26, 0.0, 0.0, 0.4, true).reached_init);
    }

    #[test]
    fn step_labels_at_their_boundaries() {
        // Range [0.5, 2]: a limit is reached within 1e-3 + 1e-3 x 1.5 = 2.5e-3.
        let at = |after: f32| labels(1.0, after, 1.0, 0.5, 2.0, false, false);
        assert!(at(2.0 - 0.002).reached_limit && at(0.5 + 0.002).reached_limit);
        assert!(!at(2.0 - 0.003).reached_limit && !at(0.5 + 0.003).reached_limit);
        assert!(!at(1.2).reached_limit);
        // Ranges [0, 1] and [-1, 0]: the tolerance is exactly 0.002, and a
        // joint exactly that far from a limit has not reached it.
        let tol = 0.002f32;
        assert!(!labels(0.5, tol, 0.5, 0.0, 1.0, false, false).reached_limit);
        assert!(!labels(-0.5, -tol, -0.5, -1.0, 0.0, false, false).reached_limit);
        // Moved: more than δ/10.
        let moved = |r: f32| labels(0.0, r, 0.0, -2.0, 2.0, false, false).moved;
        assert!(moved(0.02) && !moved(0.01) && !moved(DELTA / 10.0));
        // Back at the start: within δ of it, wherever the start is.
        assert!(labels(1.2, 0.75, 0.8, 0.0, 1.5, false, false).back_at_start);
        assert!(!labels(1.2, 0.6, 0.8, 0.0, 1.5, false, false).back_at_start);
        // Within 1e-3 of the start counts as at the start: any move is forward.
        assert_eq!(labels(0.8005, 0.5, 0.8, 0.0, 1.5, false, false).aot, 1);
        assert_eq!(labels(0.0005, -0.3, 0.0, -1.0, 1.5, false, false).aot, 1);
        // 1e-3 away no longer is: going back down is backward.
        assert_eq!(
            labels(1e-3, 1e-3 - 0.3, 0.0, -1.0, 1.5, false, false).aot,
            -1
        );
    }

    #[test]
    fn training_labels_at_their_boundaries() {
        // A short prismatic range, 7/64 m, so that the threshold is
        // range / 3.5 = 1/32 exactly and every boundary below is exact.
        let (lower, upper) = (0.0f32, 0.109375f32);
        let thr = 0.03125f32;
        assert_eq!(threshold(true, lower, upper), thr);
        assert_eq!(threshold(true, 0.2, 0.3), (0.3f32 - 0.2) / 3.5);
        assert_eq!(threshold(false, -1.0, 1.0), 0.1);
        assert_eq!(threshold(true, 0.0, f32::INFINITY), 0.05);
        let t =
            |before: f32, after: f32, j0: f32| train_labels(before, after, j0, lower, upper, true);
        // Moved: a step of exactly a 3.5th of the range is not yet a move.
        assert!(!t(0.0, thr, 0.0).moved);
        assert!(t(0.0, thr + 1e-4, 0.0).moved);
        // Exactly 0.1 rad on a long revolute range is not a move either.
        assert!(!train_labels(0.0, 0.1, 0.0, -3.0, 3.0, false).moved);
        // The range is measured from the lower limit, not from 0.
        assert!(train_labels(0.2, 0.23, 0.2, 0.2, 0.3, true).moved);
        // The sign: exactly 0.02 from the start is still inside the dead band.
        assert_eq!(train_labels(0.02, -0.2, 0.0, -1.0, 1.0, false).aot, 1);
        // Back at the start, with j0 in the middle of the range.
        let j0 = 0.0625f32;
        assert!(
            t(0.1, j0 - thr, j0).reached_init,
            "from above, crossed to exactly thr below"
        );
        assert!(
            !t(0.1, j0 + thr, j0).reached_init,
            "from above, exactly thr above: not yet"
        );
        assert!(
            t(0.0, 0.1, j0).reached_init,
            "from below, crossed well above"
        );
        assert!(
            t(0.0, j0 + thr, j0).reached_init,
            "from below, crossed to exactly thr above"
        );
        assert!(
            !t(0.0, j0 - thr, j0).reached_init,
            "from below, exactly thr below: not yet"
        );
        assert!(
            t(j0, 0.07, j0).reached_init,
            "at the start and within thr of it"
        );
        assert!(!t(j0, 0.0, j0).reached_init, "from the start, away below");
        assert!(!t(j0, upper, j0).reached_init, "from the start, away above");
        assert!(
            !t(j0, j0 + thr, j0).reached_init,
            "from the start, exactly thr away"
        );
    }

    #[test]
    fn the_boundary_event_at_its_edges() {
        // Threshold 1/4, range [0, 2], so every value below is exact.
        let thr = 0.25f32;
        let at = |value: f32, start: f32| reached_limit(value, start, 0.0, 2.0, thr);
        assert!(at(0.1, 1.0) && at(1.9, 1.0));
        assert!(
            !at(0.25, 1.0) && !at(1.75, 1.0),
            "exactly thr from a limit is not within it"
        );
        assert!(at(1.8, 1.0));
        // Near a limit, but only exactly thr from the start: not yet.
        assert!(!at(0.125, 0.375));
        assert!(at(0.125, 0.5));
        assert!(!at(1.0, 0.0), "far from both limits");
    }
}
