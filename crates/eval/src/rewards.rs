//! The reward of one direction step, for reinforcement-learning interfaces
//! (gymnasium): the paper's protocol turned into a dense signal, in units of
//! δ. The ends are the protocol's own ([`protocol::reached_limit`],
//! [`protocol::reached_goal`]), so an episode a gym user sees succeed is one
//! `umpnet eval` counts as a success.
use crate::protocol;
use umpnet_sim::env::DELTA;
use umpnet_sim::scene::Task;

/// Where an episode stands after a direction step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepScore {
    /// Exploration: how far the step takes the joint beyond the farthest it
    /// has been from its start (new states only). Goal: the step's progress
    /// toward the goal (negative when it moves away). Both in units of δ.
    pub reward: f32,
    /// The protocol's end in success: the joint near a limit after moving
    /// (exploration), or at or across the goal (goal).
    pub success: bool,
    /// The farthest the joint has been from its start, this step included.
    pub farthest: f32,
}

/// The score of a step from `before` to `after` of a joint that started the
/// episode at `start` within `[lower, upper]`; `threshold` is the protocol's
/// (labels::threshold), `goal` the goal value (unused when exploring).
#[expect(
    clippy::too_many_arguments,
    reason = "the values a step is scored on, each a plain number"
)]
pub fn score_step(
    task: Task,
    before: f32,
    after: f32,
    start: f32,
    farthest: f32,
    (lower, upper): (f32, f32),
    threshold: f32,
    goal: f32,
) -> StepScore {
    match task {
        Task::Exploration => {
            let distance = (after - start).abs();
            StepScore {
                reward: (distance - farthest).max(0.0) / DELTA,
                success: protocol::reached_limit(after, start, lower, upper, threshold),
                farthest: farthest.max(distance),
            }
        }
        Task::Goal => StepScore {
            reward: ((before - goal).abs() - (after - goal).abs()) / DELTA,
            success: protocol::reached_goal(before, after, goal, threshold),
            farthest,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exploration_pays_new_distance_once_and_ends_at_a_limit() {
        let limits = (0.0, 1.5);
        let s = score_step(Task::Exploration, 0.3, 0.6, 0.3, 0.0, limits, 0.1, f32::NAN);
        assert!((s.reward - 2.0).abs() < 1e-5 && !s.success && (s.farthest - 0.3).abs() < 1e-6);
        // Back toward the start: no new distance, no reward.
        let back = score_step(
            Task::Exploration,
            0.6,
            0.45,
            0.3,
            s.farthest,
            limits,
            0.1,
            f32::NAN,
        );
        assert_eq!(back.reward, 0.0);
        assert_eq!(back.farthest, s.farthest);
        let end = score_step(
            Task::Exploration,
            0.6,
            1.45,
            0.3,
            s.farthest,
            limits,
            0.1,
            f32::NAN,
        );
        assert!(end.success && end.reward > 0.0);
        // Starting at the limit does not count as reaching it.
        assert!(
            !score_step(
                Task::Exploration,
                1.45,
                1.46,
                1.45,
                0.0,
                limits,
                0.1,
                f32::NAN
            )
            .success
        );
    }

    #[test]
    fn goal_pays_progress_both_ways_and_ends_at_or_across_the_goal() {
        let limits = (0.0, 1.5);
        let toward = score_step(Task::Goal, 0.2, 0.5, 0.2, 0.0, limits, 0.05, 1.0);
        assert!((toward.reward - 2.0).abs() < 1e-5 && !toward.success);
        let away = score_step(Task::Goal, 0.5, 0.35, 0.2, 0.0, limits, 0.05, 1.0);
        assert!((away.reward + 1.0).abs() < 1e-5);
        assert!(score_step(Task::Goal, 0.8, 0.98, 0.2, 0.0, limits, 0.05, 1.0).success);
        assert!(score_step(Task::Goal, 0.8, 1.3, 0.2, 0.0, limits, 0.05, 1.0).success);
    }
}
