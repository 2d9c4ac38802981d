//! What one executed direction is labelled with. Two definitions live here,
//! on purpose side by side:
//! - [`labels`]: the paper's text (DESIGN.md), with δ as the threshold. The
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
    pub joint_before: f32,
    pub joint_after: f32,
    /// |j_t - j_{t-1}|
    pub r_dist: f32,
    /// Arrow of Time: 0 (no effective change), +1 (away from the start), -1 (back).
    pub aot: i8,
    pub moved: bool,
    pub reached_limit: bool,
    pub back_at_start: bool,
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
}
