//! The UMPNet policy on observation tensors: position from the affordance
//! map, directions from batched two-round CEM over the direction networks.
#![allow(
    clippy::indexing_slicing,
    reason = "arrays are indexed within shapes checked against the package at the public entry points"
)]
use crate::cem::{CemResult, Mode, Sampler, Score, first_round, second_round, select};
use crate::error::{PolicyError, Result};
use crate::filters::{self, Keep};
use crate::observation::{CHANNELS, mirrored_observations};
use crate::package::{Branches, ModelPackage};
use nalgebra::Vector3;
use ndarray::{Array2, Array4, ArrayView3, Axis};
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;

/// Goal task: pixels whose world position differs by more than this between
/// the current and the goal observation are where the change must happen.
pub const GOAL_DIFF_M: f32 = 0.02;

/// One environment's direction decision.
pub struct DecisionInput<'a> {
    /// The current observation, H x W x 10.
    pub observation: ArrayView3<'a, f32>,
    /// The reference observation: the episode's first (exploring) or the goal.
    pub reference: ArrayView3<'a, f32>,
    /// Where the gripper holds the object, in image coordinates (row, col).
    pub pixel: (usize, usize),
    /// Directions that just failed to move anything.
    pub banned: &'a [Vector3<f32>],
    /// The direction executed last in this episode (world frame), which the
    /// `prev90` filter reads; None before the first.
    pub previous: Option<Vector3<f32>>,
    /// Exploring or seeking the reference state.
    pub mode: Mode,
    /// The grasped part's joint as the package's JointNet read it from the
    /// episode's first frame ([`UmpnetPolicy::frame_joint`]), which the
    /// `joint45` filter reads; None without one.
    pub joint: Option<&'a crate::axis::JointEstimate>,
    /// How the gripper itself went over the last move (world frame,
    /// metres), from its own pose ([`crate::memory::EpisodeMemory::motion`]),
    /// which `goal45` and `onward45` read; None before the second decision
    /// or where the caller does not know its gripper's pose.
    pub motion: Option<Vector3<f32>>,
    /// How the gripper went over the last move that carried it more than
    /// [`MOTION_MIN_M`] ([`crate::memory::EpisodeMemory::long_motion`]):
    /// `motion` itself, or after moves that stalled, the one before them,
    /// which `goal45` reads; None before one or where the caller does not
    /// know its gripper's pose.
    pub long_motion: Option<Vector3<f32>>,
}

/// A gripper motion over one move shorter than this says nothing about
/// which way the part gives (a 0.18 m move that the part stopped).
pub const MOTION_MIN_M: f32 = 0.02;

// The filter is one of model.json's closed sets; it is named here too,
// where callers choose it.
pub use crate::package::{DirectionFilter, GraspRule};

/// Where to grasp, and the map it was chosen from.
#[derive(Clone, Debug)]
pub struct PositionChoice {
    /// (row, col) of the grasp.
    pub pixel: (usize, usize),
    /// H x W: the probability that acting at each pixel moves the object.
    pub affordance: Array2<f32>,
    /// The JointNet's fields on this frame, where the grasp rule read them,
    /// so that [`UmpnetPolicy::joint_at_grasp`] need not run it again.
    pub joint_fields: Option<ndarray::Array3<f32>>,
}

/// The learned policy: a package's networks, the CEM over directions and
/// the selection rules; no simulator.
#[derive(Clone)]
pub struct UmpnetPolicy {
    /// The networks.
    pub package: Arc<ModelPackage>,
    /// The package's `direction_filter`, unless overridden.
    pub direction_filter: DirectionFilter,
    /// The package's `grasp` rule, unless overridden.
    pub grasp: GraspRule,
    /// How candidates are drawn: the paper's CEM unless overridden (ablations).
    pub sampler: Sampler,
    /// Score each candidate also on the scene mirrored left-right (x -> -x,
    /// the benchmark camera's plane of symmetry) and average the two.
    pub mirror_average: bool,
}

impl UmpnetPolicy {
    /// The policy of `package`, with its own direction filter and the paper's CEM.
    pub fn new(package: Arc<ModelPackage>) -> Self {
        // The loader has checked the name.
        let direction_filter = package.meta.direction_filter;
        let grasp = package.meta.grasp;
        Self {
            package,
            direction_filter,
            grasp,
            sampler: Sampler::default(),
            mirror_average: false,
        }
    }

    /// Averages each candidate's scores with those of the mirrored scene.
    pub fn with_mirror_average(mut self, on: bool) -> Self {
        self.mirror_average = on;
        self
    }

    /// Draws candidates with `sampler` instead of the paper's CEM with 64 per
    /// round (the sampler ablations of the paper's appendix).
    pub fn with_sampler(mut self, sampler: Sampler) -> Self {
        self.sampler = sampler;
        self
    }

    /// The same package under another direction filter.
    pub fn with_direction_filter(mut self, filter: DirectionFilter) -> Self {
        self.direction_filter = filter;
        self
    }

    /// The same package under another grasp rule (`Affordance` is the
    /// paper's; the movable weighting needs the package's JointNet).
    pub fn with_grasp(mut self, grasp: GraspRule) -> Result<Self> {
        grasp
            .check_joint(self.package.has_joint())
            .map_err(|why| PolicyError::Input(format!("{}: {why}", self.package.dir.display())))?;
        self.grasp = grasp;
        Ok(self)
    }

    /// (height, width) of the observations the package takes.
    pub fn resolution(&self) -> (usize, usize) {
        (
            self.package.meta.input.height,
            self.package.meta.input.width,
        )
    }

    /// The joint of the part at `pixel` (row, col of `observation`, an
    /// H x W x 10 observation), read from this one frame by the package's
    /// JointNet; None when the package has none or the vote has too few
    /// pixels ([`crate::frame_joint`]).
    pub fn frame_joint(
        &self,
        observation: ArrayView3<'_, f32>,
        pixel: (usize, usize),
    ) -> Result<Option<crate::frame_joint::FrameJoint>> {
        let Some(fields) = self
            .package
            .joint_fields(observation.insert_axis(Axis(0)))?
        else {
            return Ok(None);
        };
        Ok(crate::frame_joint::joint_from_fields(
            observation,
            fields.index_axis(Axis(0), 0),
            pixel,
        ))
    }

    /// [`Self::frame_joint`] at the grasp `choice` made on `observation`,
    /// from the JointNet fields the grasp rule already read where it did.
    pub fn joint_at_grasp(
        &self,
        observation: ArrayView3<'_, f32>,
        choice: &PositionChoice,
    ) -> Result<Option<crate::frame_joint::FrameJoint>> {
        match &choice.joint_fields {
            Some(fields) => Ok(crate::frame_joint::joint_from_fields(
                observation,
                fields.view(),
                choice.pixel,
            )),
            None => self.frame_joint(observation, choice.pixel),
        }
    }

    /// Best pixel of the affordance map among pixels with depth; with a goal
    /// observation, only where current and goal differ (the paper's mask).
    /// Under [`GraspRule::AffordanceTimesMovable`] the map is the
    /// PositionNet's probability times the JointNet's probability that the
    /// pixel lies on a movable part: the JointNet learned that mask densely,
    /// from every pixel of many more frames, and it keeps the grasp off the
    /// static parts of objects unlike the training ones. Under
    /// [`GraspRule::AffordanceTimesMovableLever`] it is also weighed by the
    /// grasp's lever arm about a hinge ([`crate::frame_joint::lever_weight`]):
    /// a grasp by the hinge moves nothing.
    pub fn position(
        &self,
        observation: ArrayView3<'_, f32>,
        goal: Option<ArrayView3<'_, f32>>,
    ) -> Result<PositionChoice> {
        if let Some(g) = &goal
            && g.shape() != observation.shape()
        {
            return Err(PolicyError::Input(format!(
                "goal observation has shape {:?}, expected the observation's {:?}",
                g.shape(),
                observation.shape()
            )));
        }
        let obs4 = observation.insert_axis(Axis(0));
        let mut aff = self.package.position(obs4)?.index_axis_move(Axis(0), 0);
        let joint_fields = if self.grasp.reads_joint() {
            self.package
                .joint_fields(obs4)?
                .map(|f| f.index_axis_move(Axis(0), 0))
        } else {
            None
        };
        if let Some(fields) = &joint_fields {
            let lever = self.grasp == GraspRule::AffordanceTimesMovableLever;
            let fields = fields.view();
            for ((r, c), a) in aff.indexed_iter_mut() {
                *a *= crate::frame_joint::sigmoid(fields[[0, r, c]]);
                if lever {
                    *a *= crate::frame_joint::lever_weight(&fields, (r, c));
                }
            }
        }
        let (h, w) = (aff.shape()[0], aff.shape()[1]);
        let allowed = |r: usize, c: usize| -> bool {
            if observation[[r, c, 9]] <= 0.0 {
                return false;
            }
            match &goal {
                Some(g) => {
                    let d: f32 = (0..3)
                        .map(|k| (observation[[r, c, k]] - g[[r, c, k]]).powi(2))
                        .sum::<f32>()
                        .sqrt();
                    d > GOAL_DIFF_M || g[[r, c, 9]] <= 0.0
                }
                None => true,
            }
        };
        let mut best: Option<(f32, (usize, usize))> = None;
        let mut fallback: Option<(f32, (usize, usize))> = None;
        for r in 0..h {
            for c in 0..w {
                let a = aff[[r, c]];
                if observation[[r, c, 9]] > 0.0 && fallback.is_none_or(|(b, _)| a > b) {
                    fallback = Some((a, (r, c)));
                }
                if allowed(r, c) && best.is_none_or(|(b, _)| a > b) {
                    best = Some((a, (r, c)));
                }
            }
        }
        let (_, pixel) = best
            .or(fallback)
            .ok_or_else(|| PolicyError::Input(
                "no pixel with depth in the observation: its depth channel (the last) is 0 everywhere, so no surface is in view to grasp".into(),
            ))?;
        Ok(PositionChoice {
            pixel,
            affordance: aff,
            joint_fields,
        })
    }

    /// Refuses a direction filter or a model the inputs' tasks cannot use.
    fn check_filter_and_task(&self, inputs: &[DecisionInput<'_>]) -> Result<()> {
        if self.direction_filter == DirectionFilter::Prev90
            && inputs.iter().any(|i| i.mode == Mode::Goal)
        {
            return Err(PolicyError::Input(
                "the prev90 direction filter serves exploration only: in the goal task the \
                 way to the goal may lie behind the last move"
                    .into(),
            ));
        }
        if self.direction_filter == DirectionFilter::Joint45 && !self.package.has_joint() {
            return Err(PolicyError::Input(format!(
                "{}: the joint45 direction filter reads the package's JointNet, and it has none \
                 (model.json `files.joint`)",
                self.package.dir.display()
            )));
        }
        if self.direction_filter == DirectionFilter::Goal45
            && inputs.iter().any(|i| i.mode != Mode::Goal)
        {
            return Err(PolicyError::Input(
                "the goal45 direction filter serves the goal task only: exploring, there is no \
                 goal frame to read the way from"
                    .into(),
            ));
        }
        if self.direction_filter == DirectionFilter::Onward45
            && inputs.iter().any(|i| i.mode == Mode::Goal)
        {
            return Err(PolicyError::Input(
                "the onward45 direction filter serves exploration only: toward a goal, onward may \
                 be past it (goal45 reads the way there)"
                    .into(),
            ));
        }
        if self.package.branches.goal_only() && inputs.iter().any(|i| i.mode != Mode::Goal) {
            return Err(PolicyError::Input(format!(
                "{}: the Inverse model needs a goal to invert toward; it serves only the goal task",
                self.package.dir.display()
            )));
        }
        Ok(())
    }

    /// Decides directions for several environments: one encoder call for all,
    /// one decoder call per CEM round for all candidates of all environments.
    pub fn directions(
        &self,
        inputs: &[DecisionInput<'_>],
        rngs: &mut [ChaCha8Rng],
    ) -> Result<Vec<CemResult>> {
        if inputs.len() != rngs.len() {
            return Err(PolicyError::Input(format!(
                "{} inputs but {} random generators",
                inputs.len(),
                rngs.len()
            )));
        }
        if inputs.is_empty() {
            return Ok(Vec::new());
        }
        self.check_filter_and_task(inputs)?;
        let (h, w) = self.resolution();
        let b = inputs.len();
        let mut obs = Array4::<f32>::zeros((b, h, w, CHANNELS));
        let mut refs = Array4::<f32>::zeros((b, h, w, CHANNELS));
        let mut pix = Array2::<i64>::zeros((b, 2));
        for (i, inp) in inputs.iter().enumerate() {
            if inp.observation.shape() != [h, w, CHANNELS]
                || inp.reference.shape() != [h, w, CHANNELS]
            {
                return Err(PolicyError::Input(format!(
                    "observation {:?} / reference {:?}: the model takes [{h}, {w}, {CHANNELS}]",
                    inp.observation.shape(),
                    inp.reference.shape()
                )));
            }
            obs.index_axis_mut(Axis(0), i).assign(&inp.observation);
            refs.index_axis_mut(Axis(0), i).assign(&inp.reference);
            let (r, c) = on_image(inp.pixel, (h, w));
            pix[[i, 0]] = r as i64;
            pix[[i, 1]] = c as i64;
        }
        let (de, ae) = self.package.encode(obs.view(), refs.view(), pix.view())?;
        if self.package.branches == Branches::Inverse {
            return self.inverse(&de, &ae);
        }
        let mirrored = if self.mirror_average {
            let (mo, mr, mp) = (
                mirrored_observations(obs.view())?,
                mirrored_observations(refs.view())?,
                {
                    let mut p = pix.clone();
                    p.column_mut(1).mapv_inplace(|c| w as i64 - 1 - c);
                    p
                },
            );
            Some(self.package.encode(mo.view(), mr.view(), mp.view())?)
        } else {
            None
        };
        let emb = Embeddings {
            de: &de,
            ae: &ae,
            mirrored: mirrored.as_ref().map(|(d, a)| (d, a)),
        };
        let (n, uniform) = match self.sampler {
            Sampler::Cem { n } => (n, false),
            Sampler::Uniform { n } => (2 * n, true),
        };
        let mut first: Vec<Vec<Vector3<f32>>> = inputs
            .iter()
            .zip(rngs.iter_mut())
            .map(|(inp, rng)| first_round(rng, inp.banned, n))
            .collect();
        let rules = filters::rules(self.direction_filter, inputs, self.resolution());
        if uniform {
            Keep::add_exact_ways(&rules, &mut first);
        }
        let mut s1 = self.score(&emb, &first)?;
        filters::apply(&rules, &first, &mut s1);
        if uniform {
            return Ok((0..b)
                .map(|i| CemResult {
                    direction: rules[i].settle(select(&first[i], &s1[i], inputs[i].mode)),
                    candidates: first[i].clone(),
                    scores: s1[i].clone(),
                })
                .collect());
        }
        let mut second: Vec<Vec<Vector3<f32>>> = inputs
            .iter()
            .zip(rngs.iter_mut())
            .enumerate()
            .map(|(i, (inp, rng))| second_round(rng, &first[i], &s1[i], inp.mode, inp.banned, n))
            .collect();
        Keep::add_exact_ways(&rules, &mut second);
        let mut s2 = self.score(&emb, &second)?;
        filters::apply(&rules, &second, &mut s2);
        Ok((0..b)
            .map(|i| {
                let candidates: Vec<Vector3<f32>> =
                    first[i].iter().chain(&second[i]).copied().collect();
                let scores: Vec<Score> = s1[i].iter().chain(&s2[i]).copied().collect();
                CemResult {
                    direction: rules[i].settle(select(&candidates, &scores, inputs[i].mode)),
                    candidates,
                    scores,
                }
            })
            .collect())
    }

    /// The Inverse baseline acts on its regressed direction as it is: it has
    /// no scores to search over and no notion of having arrived, so it never stops.
    fn inverse(&self, de: &Array2<f32>, ae: &Array2<f32>) -> Result<Vec<CemResult>> {
        let pred = self.package.predict_direction(de.view(), ae.view())?;
        Ok(pred
            .rows()
            .into_iter()
            .map(|r| {
                let v = Vector3::new(r[0], r[1], r[2]);
                let d = v.try_normalize(1e-6).unwrap_or_else(Vector3::z);
                CemResult {
                    direction: Some(d),
                    candidates: vec![d],
                    scores: vec![Score {
                        distance: v.norm(),
                        aot: -1,
                    }],
                }
            })
            .collect())
    }

    /// Scores each environment's candidates in one decoder call (two with
    /// the mirrored scene, averaged).
    fn score(&self, emb: &Embeddings<'_>, cands: &[Vec<Vector3<f32>>]) -> Result<Vec<Vec<Score>>> {
        let mut s = self.decode(emb.de, emb.ae, cands, 1.0)?;
        if let Some((dm, am)) = emb.mirrored {
            let m = self.decode(dm, am, cands, -1.0)?;
            s.distance = (&s.distance + &m.distance) * 0.5;
            s.aot_probs = (&s.aot_probs + &m.aot_probs) * 0.5;
        }
        let mut out = Vec::with_capacity(cands.len());
        let mut row = 0;
        for c in cands {
            out.push(
                (0..c.len())
                    .map(|k| Score {
                        distance: s.distance[row + k],
                        aot: most_likely_aot(s.aot_probs.row(row + k)),
                    })
                    .collect(),
            );
            row += c.len();
        }
        Ok(out)
    }

    /// The decoder's scores of every candidate, its x scaled by `x_sign`.
    fn decode(
        &self,
        de: &Array2<f32>,
        ae: &Array2<f32>,
        cands: &[Vec<Vector3<f32>>],
        x_sign: f32,
    ) -> Result<crate::package::DirectionScores> {
        let n: usize = cands.iter().map(Vec::len).sum();
        let e = de.shape()[1];
        let mut d = Array2::<f32>::zeros((n, e));
        let mut a = Array2::<f32>::zeros((n, e));
        let mut dirs = Array2::<f32>::zeros((n, 3));
        let mut row = 0;
        for (i, c) in cands.iter().enumerate() {
            for v in c {
                d.row_mut(row).assign(&de.row(i));
                a.row_mut(row).assign(&ae.row(i));
                dirs.row_mut(row)
                    .assign(&ndarray::arr1(&[x_sign * v.x, v.y, v.z]));
                row += 1;
            }
        }
        self.package.decode(d.view(), a.view(), dirs.view())
    }
}

/// The encoders' embeddings of a batch, and of its mirror image.
struct Embeddings<'a> {
    de: &'a Array2<f32>,
    ae: &'a Array2<f32>,
    mirrored: Option<(&'a Array2<f32>, &'a Array2<f32>)>,
}

/// The most probable class of a row of AoT probabilities in the canonical
/// order (-1, 0, +1), as the AoT value.
fn most_likely_aot(p: ndarray::ArrayView1<'_, f32>) -> i8 {
    let cls = (0..3).max_by(|x, y| p[*x].total_cmp(&p[*y])).unwrap_or(1);
    cls as i8 - 1
}

/// The grasp pixel clamped onto an image of `(h, w)`: a gripper given past
/// the edge is read at the nearest pixel. The encoders of packages made by
/// this project clamp again, but a package made elsewhere need not, so the
/// runtime never hands an encoder a pixel outside its image.
pub(crate) fn on_image(pixel: (usize, usize), (h, w): (usize, usize)) -> (usize, usize) {
    (
        pixel.0.min(h.saturating_sub(1)),
        pixel.1.min(w.saturating_sub(1)),
    )
}

#[cfg(test)]
mod tests {
    use super::{most_likely_aot, on_image};

    #[test]
    fn a_grasp_pixel_past_the_image_is_read_at_the_nearest_edge_pixel() {
        assert_eq!(on_image((0, 0), (96, 128)), (0, 0));
        assert_eq!(on_image((95, 127), (96, 128)), (95, 127));
        assert_eq!(on_image((96, 128), (96, 128)), (95, 127));
        assert_eq!(on_image((500, 3), (96, 128)), (95, 3));
        assert_eq!(on_image((7, usize::MAX), (96, 128)), (7, 127));
    }

    #[test]
    fn aot_probabilities_are_read_in_the_order_minus_one_zero_plus_one() {
        let aot = |p: [f32; 3]| most_likely_aot(ndarray::aview1(&p));
        assert_eq!(aot([0.7, 0.2, 0.1]), -1);
        assert_eq!(aot([0.2, 0.7, 0.1]), 0);
        assert_eq!(aot([0.1, 0.2, 0.7]), 1);
    }
}
