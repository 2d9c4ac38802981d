//! The direction filters (model.json `direction_filter`): what each keeps
//! of one decision's CEM candidates, read from the frames, the package's
//! JointNet and how the gripper went. The heads score every candidate; a
//! filter marks the ones it rules out as "no effect" and, for the rules
//! that follow a way exactly, settles the heads' choice onto that way.
#![allow(
    clippy::indexing_slicing,
    reason = "frames are indexed at pixels clamped onto their checked shapes"
)]
use crate::cem::{Mode, Score};
use crate::observation::point_at;
use crate::policy::{DecisionInput, DirectionFilter, MOTION_MIN_M, on_image};
use nalgebra::Vector3;

impl DecisionInput<'_> {
    /// The direction the gripper went over the last move, where it went
    /// more than [`MOTION_MIN_M`].
    fn went(&self) -> Option<Vector3<f32>> {
        long_direction(self.motion)
    }

    /// [`Self::went`] where the last move moved the grasped part. A move
    /// that carried the gripper but left the part's joint where it was
    /// moved something else: the part's parent (a door that swings when its
    /// latch is pulled), and onward along it the part stays as it is.
    fn went_with_part(&self) -> Option<Vector3<f32>> {
        self.went()
            .filter(|_| self.previous.is_none_or(|p| !self.banned.contains(&p)))
    }

    /// [`Self::went`], or after moves that stalled, the direction of the
    /// last one that carried the gripper.
    fn went_last(&self) -> Option<Vector3<f32>> {
        self.went().or_else(|| long_direction(self.long_motion))
    }
}

/// The direction of a gripper motion longer than [`MOTION_MIN_M`].
fn long_direction(motion: Option<Vector3<f32>>) -> Option<Vector3<f32>> {
    motion
        .filter(|m| m.norm() > MOTION_MIN_M)
        .and_then(|m| m.try_normalize(1e-6))
}

/// What [`DirectionFilter`] keeps of each environment's candidates,
/// decided once per decision (the `goal45` filter compares frames).
pub(crate) fn rules(
    filter: DirectionFilter,
    inputs: &[DecisionInput<'_>],
    (h, w): (usize, usize),
) -> Vec<Keep> {
    inputs
        .iter()
        .map(|inp| {
            let held = Held::new(inp, (h, w));
            let gripper = held.point_in_world;
            match filter {
                DirectionFilter::None => Keep::All,
                DirectionFilter::Normal90 => Keep::HalfSpace(face_normal(inp, held.pixel)),
                DirectionFilter::Prev90 => inp.previous.map_or(Keep::All, Keep::HalfSpace),
                DirectionFilter::Joint45 => joint_line(inp, gripper),
                DirectionFilter::Goal45 => goal_way(inp, gripper),
                DirectionFilter::Onward45 => inp.went_with_part().map_or_else(
                    || onward_after_stall(inp, held),
                    |went| Keep::Way {
                        way: along_joint(inp, gripper).unwrap_or(went),
                        aot: 1,
                        exact: true,
                    },
                ),
            }
        })
        .collect()
}

/// Scores the directions each rule rules out as "no effect", so that CEM
/// neither resamples around them nor picks them; the `goal45` filter also
/// sets the Arrow of Time of the directions it keeps: toward the goal.
pub(crate) fn apply(rules: &[Keep], cands: &[Vec<Vector3<f32>>], scores: &mut [Vec<Score>]) {
    let no_effect = Score {
        distance: -1.0,
        aot: 0,
    };
    for ((rule, cands), scores) in rules.iter().zip(cands).zip(scores.iter_mut()) {
        for (d, s) in cands.iter().zip(scores.iter_mut()) {
            match rule {
                Keep::All => {}
                Keep::HalfSpace(v) if d.dot(v) < 0.0 => *s = no_effect,
                Keep::HalfSpace(_) => {}
                Keep::Line(v) if d.dot(v).abs() < std::f32::consts::FRAC_1_SQRT_2 => *s = no_effect,
                Keep::Line(_) => {}
                Keep::Way { way, aot, .. } => {
                    if d.dot(way) < std::f32::consts::FRAC_1_SQRT_2 {
                        *s = no_effect;
                    } else {
                        s.aot = *aot;
                    }
                }
            }
        }
    }
}

/// Where the gripper holds the part in one decision's frame: its pixel
/// (clamped onto the image) and the point the frame shows there, one read
/// for every rule.
#[derive(Clone, Copy)]
pub(crate) struct Held {
    pixel: (usize, usize),
    point_in_world: Vector3<f32>,
}

impl Held {
    fn new(inp: &DecisionInput<'_>, (h, w): (usize, usize)) -> Self {
        let pixel = on_image(inp.pixel, (h, w));
        Self {
            pixel,
            point_in_world: point_at(&inp.observation, pixel),
        }
    }
}

/// What a direction filter keeps of one decision's candidates.
pub(crate) enum Keep {
    All,
    /// Within 90 degrees of this direction.
    HalfSpace(Vector3<f32>),
    /// Within 45 degrees of this line, either way.
    Line(Vector3<f32>),
    /// Within 45 degrees of `way`, with this Arrow of Time; `exact`: a
    /// choice within the cone moves along `way` itself.
    Way {
        way: Vector3<f32>,
        aot: i8,
        exact: bool,
    },
}

impl Keep {
    /// Adds each exact rule's way to its candidates, so that the move it
    /// settles on is scored by the heads like any other (front ends report
    /// the chosen candidate's predictions).
    pub(crate) fn add_exact_ways(rules: &[Keep], cands: &mut [Vec<Vector3<f32>>]) {
        for (rule, c) in rules.iter().zip(cands) {
            if let &Keep::Way {
                way, exact: true, ..
            } = rule
            {
                c.push(way);
            }
        }
    }

    /// The direction to execute for the heads' choice. `onward45` keeps to
    /// the gripper's own last motion exactly: the part's constraint turned
    /// that motion onto the joint's path, while a choice up to 45 degrees
    /// off it pushes into the constraint, and the force-limited move stalls
    /// after a fraction of its 0.18 m (and of delta).
    pub(crate) fn settle(&self, chosen: Option<Vector3<f32>>) -> Option<Vector3<f32>> {
        match (self, chosen) {
            (
                &Self::Way {
                    way, exact: true, ..
                },
                Some(d),
            ) if d.dot(&way) >= std::f32::consts::FRAC_1_SQRT_2 => Some(way),
            _ => chosen,
        }
    }
}

/// The `joint45` filter's rule: along the line the JointNet's joint moves
/// the gripper's point, either way; without a joint, the heads choose.
fn joint_line(inp: &DecisionInput<'_>, gripper: Vector3<f32>) -> Keep {
    inp.joint
        .and_then(|j| j.motion_at(gripper))
        .map_or(Keep::All, Keep::Line)
}

/// The way on after the gripper's last motion brought it to `gripper`:
/// that motion carried along with the JointNet's joint
/// ([`crate::axis::JointEstimate::onward`]); None without a JointNet.
fn along_joint(inp: &DecisionInput<'_>, gripper: Vector3<f32>) -> Option<Vector3<f32>> {
    inp.joint?.onward(gripper, inp.motion?)
}

/// The `onward45` filter's rule where the last move did not carry the
/// gripper. Each line in turn, the JointNet's, then the grasped surface's
/// normal (a lid or a handle turns out of its own face): its unstalled
/// side, where moves since the last that moved the part stalled on one
/// (a limit, or a line read backwards); the next line where they stalled
/// on both; the heads choose where every line has, and before any stall
/// where the JointNet read no joint.
fn onward_after_stall(inp: &DecisionInput<'_>, held: Held) -> Keep {
    let stalled = |v: Vector3<f32>| {
        inp.banned
            .iter()
            .any(|b| b.dot(&v) >= std::f32::consts::FRAC_1_SQRT_2)
    };
    let line = joint_line(inp, held.point_in_world);
    if inp.banned.is_empty() {
        return line;
    }
    if let Keep::Line(v) = line {
        match (stalled(v), stalled(-v)) {
            (false, false) => return Keep::Line(v),
            (true, true) => {}
            (plus, _) => {
                return Keep::Way {
                    way: if plus { -v } else { v },
                    aot: 1,
                    exact: false,
                };
            }
        }
    }
    // Pulling off the face first: what suction does best.
    if let Some(n) = face_normal(inp, held.pixel).try_normalize(1e-6) {
        for way in [n, -n] {
            if !stalled(way) {
                return Keep::Way {
                    way,
                    aot: 1,
                    exact: true,
                };
            }
        }
    }
    Keep::All
}

/// The grasped face's normal at the gripper's pixel `(r, c)`. The current
/// frame shows the gripper itself there, so exploring it is read from the
/// reference, the frame the grasp was chosen on; toward a goal the
/// reference shows the goal state, and the current frame is all there is.
fn face_normal(inp: &DecisionInput<'_>, (r, c): (usize, usize)) -> Vector3<f32> {
    let frame = match inp.mode {
        Mode::Explore => &inp.reference,
        Mode::Goal => &inp.observation,
    };
    Vector3::new(frame[[r, c, 6]], frame[[r, c, 7]], frame[[r, c, 8]])
}

/// The `goal45` filter's rule: toward where the goal frame shows the part
/// that the current frame does not ([`crate::goal_shift::change`]), along
/// the gripper's own last motion where that agrees (the frames' shift is a
/// hinge's chord; the gripper's motion follows its arc). After moves that
/// stalled, the last motion that carried the gripper still stands: the
/// chord runs up to half the angle left off the arc, and a part far from
/// its goal stalled again and again in a cone about it. Where the goal
/// frame does not show the part's new place, onward along the last move if
/// it moved the part, else deeper along the goal camera's rays through the
/// part (where hidden places lie); with nothing changed, the heads choose.
fn goal_way(inp: &DecisionInput<'_>, gripper: Vector3<f32>) -> Keep {
    // The change's unit shift, and whether it reads a hidden goal.
    let change = crate::goal_shift::change(&inp.observation, &inp.reference, gripper)
        .and_then(|c| Some((c.shift.try_normalize(1e-6)?, c.hidden)));
    let went = inp.went_last();
    let seen = change
        .filter(|&(_, hidden)| !hidden)
        .map(|(way, _)| went.filter(|g| g.dot(&way) > 0.0).unwrap_or(way));
    let moved = went.or(inp.previous.filter(|p| !inp.banned.contains(p)));
    let hidden = change.filter(|&(_, hidden)| hidden).map(|(way, _)| way);
    seen.or(moved)
        .or(hidden)
        .map_or(Keep::All, |way| Keep::Way {
            way,
            aot: -1,
            exact: false,
        })
}
