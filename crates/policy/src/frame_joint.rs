//! A joint from one frame (beyond the paper): the grasped part's joint type,
//! axis and origin, voted over the part's pixels from a JointNet's dense
//! predictions (the package's optional `joint.onnx`, FlowBot++'s articulation
//! parameters). The paper infers an axis only after several moves
//! ([`crate::axis`]); this reads it before the first.
#![allow(
    clippy::indexing_slicing,
    reason = "every index is inside the dimensions checked on entry (an H x W x 10 observation, \
              11 x H x W fields, neighbours bounds-checked)"
)]
use crate::CHANNELS;
use crate::axis::JointEstimate;
use crate::observation::point_at as point;
use nalgebra::{Matrix3, Vector3};
use ndarray::{ArrayView3, s};
use std::collections::VecDeque;

/// The JointNet's output channels per pixel, in order: movable logit, hinge
/// logit, scaled flow (3), axis up to sign (3), the vector from the point to
/// the nearest point on a hinge's axis (3, metres).
pub const JOINT_CHANNELS: usize = 11;
/// Neighbouring pixels whose points are farther apart than this (m), or than
/// [`STEP_OVER_SPACING`] times the image's typical spacing of neighbouring
/// points when that is larger (a coarse image), lie on different surfaces:
/// the part stops there.
pub const SURFACE_STEP: f32 = 0.03;
/// See [`SURFACE_STEP`].
pub const STEP_OVER_SPACING: f32 = 3.0;
/// Fewest part pixels a vote needs.
pub const MIN_PART_PIXELS: usize = 3;
/// Where the movable mask leaves fewer than [`MIN_PART_PIXELS`] at the
/// grasp, the grasped surface's pixels within this distance of it (m) are
/// the part: the gripper holds a part there (a grasp given by the caller, or
/// chosen without the mask). On objects unlike the training families the
/// mask is shy while the joint's fields still read the joint: on Meta-World's
/// objects it left 102 of 306 oracle grasps without a vote
/// (`umpnet_train.frame_joint`, docs/training.md).
pub const GRASP_PART_RADIUS: f32 = 0.06;
/// The part's pixels within this distance of the grasp (m) vote: a part
/// the network segments too generously (a door and its cabinet) then votes
/// its own joint. Chosen on the training categories' held-out instances
/// (`umpnet_train.frame_joint`), where 0.1 to 0.3 m do alike.
pub const VOTE_RADIUS: f32 = 0.15;

/// The joint of the part at the grasp, read from one frame.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FrameJoint {
    /// Type, unit axis (world frame) and, for a hinge, a point on its axis.
    /// The axis points so that the part opens by a positive turn about it
    /// (right hand) or, for a slide, in the way the part opens.
    pub estimate: JointEstimate,
    /// The voting pixels' mean predicted probability that the joint is a hinge.
    pub hinge_probability: f32,
    /// How many pixels voted: those of the part connected to the grasp
    /// within [`VOTE_RADIUS`] of it.
    pub voting_pixels: usize,
}

/// A grasp nearer a hinge's axis than this (m) is worth less, in
/// proportion: the force-limited gripper turns the part by too little
/// against the joint's brake so near it: on the test categories' doors the
/// JointNet put the grasps that moved nothing 0.05 to 0.19 m from the
/// axis, the oracle's 0.4 to 0.6 m. 0.09 and 0.18 m did less
/// (docs/decisions.md).
pub const LEVER_M: f32 = 0.3;

/// What the grasp at `(r, c)` is worth for its lever arm, by the JointNet's
/// `fields` (JOINT_CHANNELS x H x W): 1 on a slide and on a hinge
/// [`LEVER_M`] or more from its axis, falling linearly to 0 at the axis,
/// the two blended by the hinge probability.
pub fn lever_weight(fields: &ArrayView3<'_, f32>, (r, c): (usize, usize)) -> f32 {
    let hinge = sigmoid(fields[[1, r, c]]);
    let arm = field(fields, 8, (r, c)).norm();
    1.0 - hinge + hinge * (arm / LEVER_M).min(1.0)
}

pub(crate) fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

fn field(fields: &ArrayView3<'_, f32>, first: usize, (r, c): (usize, usize)) -> Vector3<f32> {
    let f = fields.slice(s![first..first + 3, r, c]);
    Vector3::new(f[0], f[1], f[2])
}

/// The pixels connected to `grasp` that the network calls movable, on one
/// surface (the grasp itself always, when it has depth); with `radius`
/// (m), instead, those within that distance of the grasp, whatever the mask.
pub fn part_pixels(
    observation: &ArrayView3<'_, f32>,
    fields: &ArrayView3<'_, f32>,
    grasp: (usize, usize),
    radius: Option<f32>,
) -> Vec<(usize, usize)> {
    Surface::new(observation, fields)
        .map(|surface| surface.part(grasp, radius))
        .unwrap_or_default()
}

/// An observation and its JointNet fields of matching shapes, with the
/// distance below which neighbouring pixels' points lie on one surface
/// (measured once: it passes over the whole image).
struct Surface<'a, 'o> {
    observation: &'a ArrayView3<'o, f32>,
    fields: &'a ArrayView3<'o, f32>,
    step: f32,
}

impl<'a, 'o> Surface<'a, 'o> {
    fn new(observation: &'a ArrayView3<'o, f32>, fields: &'a ArrayView3<'o, f32>) -> Option<Self> {
        let (h, w, channels) = observation.dim();
        (channels == CHANNELS && fields.dim() == (JOINT_CHANNELS, h, w)).then(|| Surface {
            observation,
            fields,
            step: SURFACE_STEP.max(STEP_OVER_SPACING * median_spacing(observation)),
        })
    }

    /// [`part_pixels`] on this surface.
    fn part(&self, grasp: (usize, usize), radius: Option<f32>) -> Vec<(usize, usize)> {
        let (observation, fields) = (self.observation, self.fields);
        let (h, w, _) = observation.dim();
        let valid = |(r, c): (usize, usize)| observation[[r, c, 9]] > 0.0;
        if grasp.0 >= h || grasp.1 >= w || !valid(grasp) {
            return Vec::new();
        }
        let grasp_point = point(observation, grasp);
        let on_part = |(r, c): (usize, usize), at: Vector3<f32>| match radius {
            None => fields[[0, r, c]] > 0.0,
            Some(radius) => (at - grasp_point).norm() <= radius,
        };
        let mut seen = vec![false; h * w];
        seen[grasp.0 * w + grasp.1] = true;
        let (mut queue, mut part) = (VecDeque::from([grasp]), Vec::new());
        while let Some((r, c)) = queue.pop_front() {
            part.push((r, c));
            let here = point(observation, (r, c));
            let neighbours = [
                (r + 1, c),
                (r.wrapping_sub(1), c),
                (r, c + 1),
                (r, c.wrapping_sub(1)),
            ];
            for n in neighbours {
                if n.0 >= h || n.1 >= w || seen[n.0 * w + n.1] || !valid(n) {
                    continue;
                }
                let at = point(observation, n);
                if on_part(n, at) && (at - here).norm() < self.step {
                    seen[n.0 * w + n.1] = true;
                    queue.push_back(n);
                }
            }
        }
        part
    }
}

/// The median distance between the points of horizontally neighbouring
/// pixels with depth: how far apart one pixel's points are at this camera's
/// resolution and distance.
fn median_spacing(observation: &ArrayView3<'_, f32>) -> f32 {
    let (h, w, _) = observation.dim();
    let mut d = Vec::with_capacity(h * w);
    for r in 0..h {
        for c in 1..w {
            if observation[[r, c, 9]] > 0.0 && observation[[r, c - 1, 9]] > 0.0 {
                d.push((point(observation, (r, c)) - point(observation, (r, c - 1))).norm());
            }
        }
    }
    median(d)
}

fn median(mut v: Vec<f32>) -> f32 {
    v.sort_by(f32::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

/// The principal direction, up to sign, of `vectors` (each counted once,
/// whatever its length; near-zero ones ignored).
fn principal_direction(vectors: impl Iterator<Item = Vector3<f32>>) -> Option<Vector3<f32>> {
    let mut m = Matrix3::zeros();
    for v in vectors {
        if v.norm() > 1e-6 {
            let v = v.normalize();
            m += v * v.transpose();
        }
    }
    let eig = m.symmetric_eigen();
    let (k, _) = eig
        .eigenvalues
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))?;
    let axis: Vector3<f32> = eig.eigenvectors.column(k).into_owned();
    (axis.norm() > 0.5 && axis.iter().all(|v| v.is_finite())).then(|| axis.normalize())
}

/// Votes the joint of the part at `grasp` (row, col of `observation`, an
/// H x W x 10 observation) from `fields` (JOINT_CHANNELS x H x W): the part's
/// pixels within [`VOTE_RADIUS`] of the grasp vote (the grasped surface's
/// pixels near the grasp where the mask misses it, [`GRASP_PART_RADIUS`]).
/// Their mean hinge probability decides the type. A hinge's axis is the
/// principal direction of flow x (the vector to the axis), both
/// perpendicular to it at every point, through the median of the axis
/// points they give; a slide's is their mean flow. None when fewer than
/// [`MIN_PART_PIXELS`] pixels vote or the vote is degenerate.
pub fn joint_from_fields(
    observation: ArrayView3<'_, f32>,
    fields: ArrayView3<'_, f32>,
    grasp: (usize, usize),
) -> Option<FrameJoint> {
    let surface = Surface::new(&observation, &fields)?;
    let mut part = surface.part(grasp, None);
    if part.len() < MIN_PART_PIXELS {
        part = surface.part(grasp, Some(GRASP_PART_RADIUS));
    }
    let at = point(&observation, *part.first()?);
    let voters: Vec<(usize, usize)> = part
        .into_iter()
        .filter(|&px| (point(&observation, px) - at).norm() <= VOTE_RADIUS)
        .collect();
    if voters.len() < MIN_PART_PIXELS {
        return None;
    }
    let n = voters.len() as f32;
    let hinge_probability = voters
        .iter()
        .map(|&(r, c)| sigmoid(fields[[1, r, c]]))
        .sum::<f32>()
        / n;
    let flow: Vector3<f32> = voters.iter().map(|&px| field(&fields, 2, px)).sum();
    let estimate = if hinge_probability > 0.5 {
        let mut axis = principal_direction(
            voters
                .iter()
                .map(|&px| field(&fields, 2, px).cross(&field(&fields, 8, px))),
        )?;
        // Each pixel votes the point of the axis nearest to it.
        let votes: Vec<Vector3<f32>> = voters
            .iter()
            .map(|&px| point(&observation, px) + field(&fields, 8, px))
            .collect();
        let m = Vector3::new(
            median(votes.iter().map(|v| v.x).collect()),
            median(votes.iter().map(|v| v.y).collect()),
            median(votes.iter().map(|v| v.z).collect()),
        );
        let on_axis = m + axis * axis.dot(&(at - m));
        // Opening turns the part by a positive angle about the axis.
        let turn: f32 = voters
            .iter()
            .map(|&px| {
                axis.cross(&(point(&observation, px) - on_axis))
                    .dot(&field(&fields, 2, px))
            })
            .sum();
        if turn < 0.0 {
            axis = -axis;
        }
        JointEstimate::Revolute {
            axis: axis.into(),
            point: on_axis.into(),
        }
    } else {
        // NaN fails this test too: a flow of NaN votes nothing.
        if flow.norm().partial_cmp(&1e-6) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        JointEstimate::Prismatic {
            axis: flow.normalize().into(),
        }
    };
    // The axes above are unit vectors where finite, so this is the finite check.
    estimate.is_usable().then_some(FrameJoint {
        estimate,
        hinge_probability,
        voting_pixels: voters.len(),
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use crate::axis::axis_angle_deg;
    use ndarray::{Array3, Zip};

    /// A flat 0.5 m door in the plane y = 0 (x across, z up) seen on a
    /// 20 x 20 grid, hinged at x = 0 about z, with exact fields.
    fn door(hinge: bool) -> (Array3<f32>, Array3<f32>) {
        let (h, w) = (20, 20);
        let mut obs = Array3::<f32>::zeros((h, w, 10));
        let mut fields = Array3::<f32>::zeros((JOINT_CHANNELS, h, w));
        for r in 0..h {
            for c in 0..w {
                let (x, z) = (c as f32 * 0.025, 1.0 - r as f32 * 0.025);
                obs[[r, c, 0]] = x;
                obs[[r, c, 2]] = z;
                obs[[r, c, 9]] = 2.0;
                // The right quarter is a fixed frame.
                let movable = c < 15;
                fields[[0, r, c]] = if movable { 4.0 } else { -4.0 };
                fields[[1, r, c]] = if hinge { 3.0 } else { -3.0 };
                // Opening swings +x points toward -y about +z.
                let speed = if hinge { x / 0.35 } else { 1.0 };
                fields[[3, r, c]] = -speed;
                fields[[7, r, c]] = if hinge { 1.0 } else { 0.0 };
                fields[[6, r, c]] = if hinge { 0.0 } else { 1.0 };
                fields[[8, r, c]] = -x;
            }
        }
        (obs, fields)
    }

    /// The door's pixels (left of the fixed frame) within the vote's radius
    /// of pixel `grasp` of `obs`.
    fn expected_voters(obs: &Array3<f32>, grasp: (usize, usize)) -> usize {
        let at = point(&obs.view(), grasp);
        (0..20)
            .flat_map(|r| (0..15).map(move |c| (r, c)))
            .filter(|&px| (point(&obs.view(), px) - at).norm() <= VOTE_RADIUS)
            .count()
    }

    #[test]
    fn a_hinge_is_voted_with_its_axis_origin_and_opening_sense() {
        let (obs, fields) = door(true);
        let j = joint_from_fields(obs.view(), fields.view(), (10, 12)).unwrap();
        assert_eq!(
            j.voting_pixels,
            expected_voters(&obs, (10, 12)),
            "the fixed frame does not vote"
        );
        let JointEstimate::Revolute { axis, point } = j.estimate else {
            panic!("not a hinge: {j:?}")
        };
        let axis = Vector3::from(axis);
        assert!(axis_angle_deg(&axis, &Vector3::z()) < 0.1);
        assert!(
            axis.z < 0.0,
            "opening toward -y is a positive turn about -z"
        );
        assert!(point[0].abs() < 1e-4 && point[1].abs() < 1e-4, "{point:?}");
    }

    #[test]
    fn a_slide_follows_the_flow() {
        let (obs, fields) = door(false);
        let j = joint_from_fields(obs.view(), fields.view(), (3, 3)).unwrap();
        let JointEstimate::Prismatic { axis } = j.estimate else {
            panic!("not a slide: {j:?}")
        };
        assert!((Vector3::from(axis) - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-4);
    }

    #[test]
    fn a_coarse_image_keeps_its_part_whole() {
        // The same door seen through a camera with 5 cm between pixels.
        let (mut obs, fields) = door(true);
        obs.slice_mut(s![.., .., 0..3]).mapv_inplace(|v| v * 2.0);
        let j = joint_from_fields(obs.view(), fields.view(), (10, 5)).unwrap();
        assert_eq!(j.voting_pixels, expected_voters(&obs, (10, 5)));
    }

    #[test]
    fn a_shy_mask_leaves_the_grasped_surface_around_the_grasp_to_vote() {
        let (obs, mut fields) = door(true);
        Zip::from(fields.slice_mut(s![0, .., ..])).for_each(|v| *v = -1.0);
        let j = joint_from_fields(obs.view(), fields.view(), (10, 5)).unwrap();
        let at = point(&obs.view(), (10, 5));
        let near = (0..20)
            .flat_map(|r| (0..20).map(move |c| (r, c)))
            .filter(|&px| (point(&obs.view(), px) - at).norm() <= GRASP_PART_RADIUS)
            .count();
        assert!(near >= MIN_PART_PIXELS && near < expected_voters(&obs, (10, 5)));
        assert_eq!(j.voting_pixels, near);
        let JointEstimate::Revolute { axis, .. } = j.estimate else {
            panic!("not a hinge: {j:?}")
        };
        assert!(axis_angle_deg(&Vector3::from(axis), &Vector3::z()) < 0.1);
        // A mask that holds at the grasp keeps its own part, even a small one.
        let (_, mut small) = door(true);
        Zip::from(small.slice_mut(s![0, .., ..])).for_each(|v| *v = -1.0);
        small.slice_mut(s![0, 9..12, 4..7]).fill(1.0);
        let j = joint_from_fields(obs.view(), small.view(), (10, 5)).unwrap();
        assert_eq!(j.voting_pixels, 9);
    }

    #[test]
    fn nothing_is_voted_without_depth_or_a_surface_around_the_grasp() {
        let (mut obs, good) = door(true);
        obs[[10, 5, 9]] = 0.0;
        assert!(joint_from_fields(obs.view(), good.view(), (10, 5)).is_none());
        assert!(joint_from_fields(obs.view(), good.view(), (99, 5)).is_none());
        // A lone point: its neighbours lie on another surface, 0.5 m behind.
        let (mut obs, mut shy) = door(true);
        Zip::from(shy.slice_mut(s![0, .., ..])).for_each(|v| *v = -1.0);
        obs[[10, 5, 1]] = -0.5;
        assert!(joint_from_fields(obs.view(), shy.view(), (10, 5)).is_none());
    }

    #[test]
    fn a_grasp_by_a_hinge_is_worth_less_than_one_far_from_it() {
        // The door's pixels lie x from its axis (column c at 0.025 c m).
        let (_, fields) = door(true);
        let f = fields.view();
        let hinge = sigmoid(3.0);
        for (c, arm) in [(0, 0.0), (6, 0.15), (12, 0.3), (14, 0.35)] {
            let want = 1.0 - hinge + hinge * (arm / LEVER_M).min(1.0);
            let got = lever_weight(&f, (10, c));
            assert!((got - want).abs() < 1e-5, "column {c}: {got} vs {want}");
        }
        assert!(lever_weight(&f, (10, 0)) < 0.1 && lever_weight(&f, (10, 14)) > 0.99);
        // A slide's grasp is worth as much anywhere.
        let (_, slide) = door(false);
        for c in [0, 6, 14] {
            assert!(lever_weight(&slide.view(), (10, c)) > 0.95);
        }
    }
}
