//! What a learned policy carries from one move to the next within an
//! episode: the moves that moved nothing (not tried again until a move
//! does), the previous move (for the `prev90` filter), how far the
//! gripper itself went over it (for `goal45` and `onward45`) and over the
//! last move that carried it (for `goal45` after a stall). One rule for
//! the benchmark's policy, `umpnet infer --session` and the Python
//! `Policy.act`.
use crate::axis::JointEstimate;
use crate::cem::Mode;
use crate::policy::{DecisionInput, MOTION_MIN_M};
use nalgebra::Vector3;
use ndarray::ArrayView3;

/// The memory of one episode; `clear` at its start.
#[derive(Clone, Debug, Default)]
pub struct EpisodeMemory {
    banned: Vec<Vector3<f32>>,
    previous: Option<Vector3<f32>>,
    /// Where the gripper was at the last decision (world frame).
    gripper: Option<Vector3<f32>>,
    /// Where it is now less where it was then.
    motion: Option<Vector3<f32>>,
    /// The last `motion` longer than [`MOTION_MIN_M`].
    long_motion: Option<Vector3<f32>>,
}

impl EpisodeMemory {
    /// A new episode: nothing banned, no previous move.
    pub fn clear(&mut self) {
        self.banned.clear();
        self.previous = None;
        self.gripper = None;
        self.motion = None;
        self.long_motion = None;
    }

    /// After a move along `direction`: one that moved the part lifts every
    /// ban; one that did not is banned.
    pub fn record(&mut self, direction: Vector3<f32>, moved: bool) {
        if moved {
            self.banned.clear();
        } else {
            self.banned.push(direction);
        }
        self.previous = Some(direction);
    }

    /// A memory as saved elsewhere (`banned`, `previous` and
    /// [`Self::long_motion`] as they were): a robot loop's session between
    /// calls.
    pub fn from_parts(
        banned: Vec<Vector3<f32>>,
        previous: Option<Vector3<f32>>,
        long_motion: Option<Vector3<f32>>,
    ) -> Self {
        Self {
            banned,
            previous,
            gripper: None,
            motion: None,
            long_motion: long_motion.filter(|m| m.iter().all(|v| v.is_finite())),
        }
    }

    /// Where the gripper is (world frame, from its own pose) as the next move
    /// is chosen: from the second call on, [`Self::motion`] is how far it
    /// went since the last. A point that is not finite forgets the motion.
    pub fn gripper_at(&mut self, point: Vector3<f32>) {
        if !point.iter().all(|v| v.is_finite()) {
            self.gripper = None;
            self.motion = None;
            self.long_motion = None;
            return;
        }
        self.motion = self.gripper.map(|before| point - before);
        if let Some(m) = self.motion.filter(|m| m.norm() > MOTION_MIN_M) {
            self.long_motion = Some(m);
        }
        self.gripper = Some(point);
    }

    /// Where the gripper was at the last decision ([`Self::gripper_at`]).
    pub fn gripper(&self) -> Option<Vector3<f32>> {
        self.gripper
    }

    /// How the gripper went between the last two [`Self::gripper_at`] calls
    /// (world frame, metres); None before the second.
    pub fn motion(&self) -> Option<Vector3<f32>> {
        self.motion
    }

    /// How the gripper went over the last move that carried it more than
    /// [`MOTION_MIN_M`]: [`Self::motion`] when the last move did, else the
    /// move's before the ones that stalled; None before any did.
    pub fn long_motion(&self) -> Option<Vector3<f32>> {
        self.long_motion
    }

    /// The directions not to choose again.
    pub fn banned(&self) -> &[Vector3<f32>] {
        &self.banned
    }

    /// The last move, if any.
    pub fn previous(&self) -> Option<Vector3<f32>> {
        self.previous
    }

    /// The next decision's input, with what this memory holds (bans, the
    /// previous move, the gripper's motions) filled in, so that every caller
    /// hands the filters the same memory.
    pub fn decision_input<'a>(
        &'a self,
        observation: ArrayView3<'a, f32>,
        reference: ArrayView3<'a, f32>,
        pixel: (usize, usize),
        mode: Mode,
        joint: Option<&'a JointEstimate>,
    ) -> DecisionInput<'a> {
        DecisionInput {
            observation,
            reference,
            pixel,
            banned: self.banned(),
            previous: self.previous(),
            mode,
            joint,
            motion: self.motion(),
            long_motion: self.long_motion(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_move_that_moved_nothing_is_banned_until_one_moves() {
        let mut m = EpisodeMemory::default();
        let (x, y) = (Vector3::x(), Vector3::y());
        assert!(m.banned().is_empty() && m.previous().is_none());
        m.record(x, false);
        m.record(y, false);
        assert_eq!(m.banned(), &[x, y]);
        assert_eq!(m.previous(), Some(y));
        m.record(x, true);
        assert!(m.banned().is_empty());
        assert_eq!(m.previous(), Some(x));
        m.record(y, false);
        m.clear();
        assert!(m.banned().is_empty() && m.previous().is_none());
    }

    #[test]
    fn the_motion_is_where_the_gripper_went_between_two_decisions() {
        let mut m = EpisodeMemory::default();
        m.gripper_at(Vector3::new(0.1, 0.2, 0.3));
        assert_eq!(m.motion(), None);
        m.gripper_at(Vector3::new(0.2, 0.2, 0.1));
        let went = m.motion().expect("a motion after two positions");
        assert!(
            (went - Vector3::new(0.1, 0.0, -0.2)).norm() < 1e-6,
            "{went}"
        );
        m.gripper_at(Vector3::new(f32::NAN, 0.0, 0.0));
        assert_eq!((m.motion(), m.gripper()), (None, None));
        m.gripper_at(Vector3::new(0.2, 0.2, 0.1));
        m.clear();
        assert_eq!((m.motion(), m.gripper()), (None, None));
    }

    #[test]
    fn the_long_motion_outlasts_moves_that_stalled() {
        let mut m = EpisodeMemory::default();
        m.gripper_at(Vector3::zeros());
        m.gripper_at(Vector3::new(0.01, 0.0, 0.0));
        assert_eq!(m.long_motion(), None, "a 1 cm motion is no long one");
        m.gripper_at(Vector3::new(0.11, 0.0, 0.0));
        let went = Vector3::new(0.1, 0.0, 0.0);
        assert!((m.long_motion().unwrap() - went).norm() < 1e-6);
        // Two moves that stalled: the motion is short, the long one stays.
        m.gripper_at(Vector3::new(0.115, 0.0, 0.0));
        m.gripper_at(Vector3::new(0.115, 0.005, 0.0));
        assert!(m.motion().unwrap().norm() < MOTION_MIN_M);
        assert!((m.long_motion().unwrap() - went).norm() < 1e-6);
        m.gripper_at(Vector3::new(0.115, 0.105, 0.0));
        assert!((m.long_motion().unwrap() - Vector3::new(0.0, 0.1, 0.0)).norm() < 1e-6);
        // A pose that is not finite forgets it, and so does a new episode
        // or a saved one that is not finite.
        m.gripper_at(Vector3::new(f32::NAN, 0.0, 0.0));
        assert_eq!(m.long_motion(), None);
        m.gripper_at(Vector3::zeros());
        m.gripper_at(Vector3::new(0.0, 0.0, 0.1));
        m.clear();
        assert_eq!(m.long_motion(), None);
        let saved = EpisodeMemory::from_parts(vec![], None, Some(went));
        assert_eq!(saved.long_motion(), Some(went));
        let bad = Vector3::new(f32::INFINITY, 0.0, 0.0);
        assert_eq!(
            EpisodeMemory::from_parts(vec![], None, Some(bad)).long_motion(),
            None
        );
    }

    #[test]
    fn a_decision_input_carries_the_whole_memory() {
        let mut m = EpisodeMemory::default();
        m.gripper_at(Vector3::zeros());
        m.record(Vector3::x(), false);
        m.gripper_at(Vector3::new(0.0, 0.1, 0.0));
        let image = ndarray::Array3::<f32>::zeros((2, 3, 10));
        let input = m.decision_input(image.view(), image.view(), (1, 2), Mode::Goal, None);
        assert_eq!(input.banned, &[Vector3::x()]);
        assert_eq!(input.previous, Some(Vector3::x()));
        assert_eq!(input.motion, m.motion());
        assert_eq!(input.long_motion, m.long_motion());
        assert!(input.motion.is_some() && input.long_motion.is_some());
        assert_eq!((input.pixel, input.mode), ((1, 2), Mode::Goal));
    }
}
