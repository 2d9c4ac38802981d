//! The two evaluation protocols: how long an episode runs and how it is scored.
//!
//! `paper` follows the paper's released evaluation code (real-stanford/umpnet,
//! `test_quantitative.py` and `sim.py`), metric by metric:
//!
//! | | paper | strict |
//! |---|---|---|
//! | exploration budget | the category's | the category's |
//! | exploration stops | once the joint is within `thr` of a limit and has moved more than `thr` from its start, `thr = min(0.1 rad or 0.05 m, range / 3.5)` | never |
//! | visited states | `|j_t - j_0|` after each step taken, prismatic ones divided by the object's scale | joint values `j_t` |
//! | unique states | greedy over the sorted values: a value counts when it is more than δ above the last counted one; the first always counts | values at least δ from every earlier one, the start not counted |
//! | novel-state ratio | unique / steps taken | unique / budget |
//! | a wrong grasp | ratio 0 | ratio 0 |
//! | goal budget | the category's | 15 |
//! | goal reached | once the joint is within `thr` of the goal or crosses it: distance 0, episode over | never early |
//! | normalised distance | `|j_end - j_goal| / |j_goal - j_init|`, 1 for a wrong grasp | same |
//! | success | normalised distance < 0.1 | same |
use umpnet_sim::env::DELTA;
use umpnet_sim::objects::Category;
use umpnet_sim::scene::GOAL_STEPS;
use umpnet_sim::scene::Task;

/// Which protocol scores an episode.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Protocol {
    /// The paper's released evaluation code (the default).
    #[default]
    Paper,
    /// Full budgets, no early end, unique states against every earlier one.
    Strict,
}

impl Protocol {
    /// `paper` or `strict`, as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Protocol::Paper => "paper",
            Protocol::Strict => "strict",
        }
    }

    /// Direction actions allowed in an episode of `task` on `category`.
    pub fn budget(self, task: Task, category: Option<Category>) -> usize {
        match (self, task, category) {
            (Protocol::Strict, Task::Goal, _) => GOAL_STEPS,
            (_, _, Some(c)) => c.step_budget(),
            (_, Task::Goal, None) => GOAL_STEPS,
            (_, Task::Exploration, None) => 10,
        }
    }
}

impl std::fmt::Display for Protocol {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Protocol {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "paper" => Ok(Protocol::Paper),
            "strict" => Ok(Protocol::Strict),
            _ => Err(format!("unknown protocol `{s}`; expected paper or strict")),
        }
    }
}

pub use umpnet_sim::labels::{reached_limit, threshold};

/// The paper's end of a goal episode: within the threshold of the goal, or
/// across it since the last step.
pub fn reached_goal(before: f32, after: f32, goal: f32, threshold: f32) -> bool {
    (after - goal).abs() < threshold
        || (before > goal && after < goal + threshold)
        || (before < goal && after > goal - threshold)
}

/// The states the paper's exploration metric visits: after each of `values`
/// (the joint after each step), the reference's signed walk from `start` (a
/// step back toward the start, once more than 0.02 away, counts negative),
/// its absolute value divided by `scale` (the object's for prismatic joints).
pub fn paper_walk(start: f32, values: &[f32], scale: f32) -> Vec<f32> {
    let mut walk = 0.0f32;
    let mut before = start;
    values
        .iter()
        .map(|&now| {
            let from_start = before - start;
            let back = from_start.abs() > 0.02 && from_start * (now - before) < 0.0;
            walk += if back { -1.0 } else { 1.0 } * (now - before).abs();
            before = now;
            walk.abs() / scale
        })
        .collect()
}

/// The paper's count of unique states: over the sorted values, greedily, a
/// value counts when it is more than δ above the last counted one.
pub fn paper_unique_states(visited: &[f32]) -> usize {
    let mut sorted = visited.to_vec();
    sorted.sort_by(f32::total_cmp);
    let mut last = f32::NEG_INFINITY;
    let mut count = 0;
    for v in sorted {
        if v - last > DELTA {
            count += 1;
            last = v;
        }
    }
    count
}

/// The strict count after each step: a value counts when it is at least δ
/// from the start and from every value counted before.
pub fn strict_unique_states(start: f32, values: &[f32]) -> Vec<usize> {
    let mut seen = vec![start];
    values
        .iter()
        .map(|&v| {
            if seen.iter().all(|u| (u - v).abs() >= DELTA) {
                seen.push(v);
            }
            seen.len() - 1
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_walk_counts_returns_negative_and_divides_by_the_scale() {
        let w = paper_walk(0.0, &[0.13, 0.26, 0.13, 0.3], 0.5);
        let expected = [0.26, 0.52, 0.26, 0.6];
        for (a, b) in w.iter().zip(expected) {
            assert!((a - b).abs() < 1e-6, "{w:?}");
        }
        // Within 0.02 of the start every move counts forward.
        let w = paper_walk(0.0, &[0.01, -0.1], 1.0);
        assert!((w[1] - 0.12).abs() < 1e-6, "{w:?}");
    }

    #[test]
    fn paper_unique_states_counts_greedily_over_sorted_values() {
        // Sorted: 0, 0.1, 0.16, 0.2, 0.5 -> counted 0, 0.16, 0.5.
        assert_eq!(paper_unique_states(&[0.5, 0.0, 0.16, 0.1, 0.2]), 3);
        // Nothing moved: the first value still counts.
        assert_eq!(paper_unique_states(&[0.0; 12]), 1);
        // Exactly δ apart is not "more than δ".
        assert_eq!(paper_unique_states(&[0.0, DELTA]), 1);
        assert_eq!(paper_unique_states(&[]), 0);
    }

    #[test]
    fn strict_unique_states_compares_with_every_earlier_state() {
        // Out to 0.3, back to 0.0 (the start), out to 0.16 (0.14 from 0.3), out to 0.5.
        assert_eq!(
            strict_unique_states(0.0, &[0.3, 0.0, 0.16, 0.5]),
            vec![1, 1, 1, 2]
        );
    }

    #[test]
    fn thresholds_and_ends_follow_the_reference() {
        assert_eq!(threshold(false, 0.0, 1.57), 0.1);
        assert_eq!(threshold(true, 0.0, 0.4), 0.05);
        assert!((threshold(false, 0.0, 0.2) - 0.2 / 3.5).abs() < 1e-7);
        // Near the upper limit and moved: done. Near it but never moved: not done.
        assert!(reached_limit(1.5, 0.3, 0.0, 1.57, 0.1));
        assert!(!reached_limit(1.5, 1.45, 0.0, 1.57, 0.1));
        assert!(!reached_limit(0.8, 0.3, 0.0, 1.57, 0.1));
        // Within the threshold, or crossed.
        assert!(reached_goal(0.5, 1.45, 1.5, 0.1));
        assert!(reached_goal(1.2, 1.7, 1.5, 0.1));
        assert!(reached_goal(1.7, 1.3, 1.5, 0.1));
        assert!(!reached_goal(0.5, 1.3, 1.5, 0.1));
    }

    #[test]
    fn goal_ends_at_the_exact_boundaries() {
        // Starting on the goal, only the first clause decides: strictly inside.
        assert!(reached_goal(1.0, 1.125, 1.0, 0.25));
        assert!(!reached_goal(1.0, 1.25, 1.0, 0.25));
        assert!(!reached_goal(1.0, 0.5, 1.0, 0.25));
        assert!(!reached_goal(1.0, 1.5, 1.0, 0.25));
        // Coming from above: "below goal + threshold", strictly.
        assert!(reached_goal(2.0, 0.75, 1.0, 0.25));
        assert!(!reached_goal(2.0, 1.25, 1.0, 0.25));
        // Coming from below: "above goal - threshold", strictly.
        assert!(reached_goal(0.0, 1.25, 1.0, 0.25));
        assert!(!reached_goal(0.0, 0.75, 1.0, 0.25));
    }

    #[test]
    fn paper_walk_is_measured_from_the_start_it_is_given() {
        // From 0.5: out to 0.75, then back to 0.625 counts negative.
        let w = paper_walk(0.5, &[0.75, 0.625], 1.0);
        assert_eq!(w, vec![0.25, 0.125]);
        // Across the start: out, back past it (negative), then further below it
        // (away from the start again: positive).
        let w = paper_walk(0.5, &[0.75, 0.25, 0.0], 1.0);
        assert_eq!(w, vec![0.25, 0.25, 0.0]);
        // Exactly 0.02 from the start is still "near": a move back counts forward.
        let w = paper_walk(0.0, &[0.02, 0.0], 1.0);
        assert!((w[1] - 0.04).abs() < 1e-7, "{w:?}");
        let w = paper_walk(0.0, &[0.03125, 0.0], 1.0);
        assert_eq!(w, vec![0.03125, 0.0]);
    }

    #[test]
    fn protocol_names_round_trip() {
        for p in [Protocol::Paper, Protocol::Strict] {
            assert_eq!(p.name().parse::<Protocol>(), Ok(p));
            assert_eq!(p.to_string(), p.name());
        }
        assert_eq!(Protocol::Paper.name(), "paper");
        assert_eq!(Protocol::Strict.name(), "strict");
        assert!("bullet".parse::<Protocol>().is_err());
    }

    #[test]
    fn budgets() {
        assert_eq!(
            Protocol::Paper.budget(Task::Goal, Some(Category::Kettle)),
            3
        );
        assert_eq!(
            Protocol::Strict.budget(Task::Goal, Some(Category::Kettle)),
            15
        );
        assert_eq!(
            Protocol::Strict.budget(Task::Exploration, Some(Category::Door)),
            10
        );
    }
}
