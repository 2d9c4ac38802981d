//! `umpnet infer`: the next action for frames from a real RGB-D camera.
mod frames;

use crate::{Ctx, usage};
use anyhow::{Context, Result, bail};
use frames::{Camera, load_frame};
use nalgebra::Vector3;
use rand::SeedableRng;
use std::path::PathBuf;
use umpnet_policy::cem::Mode;
use umpnet_policy::observation::{OwnedFrame, resize_nearest};
use umpnet_policy::{CameraFrame, DecisionInput, ModelPackage, UmpnetPolicy, build_observation};

#[derive(clap::Args)]
pub struct InferArgs {
    /// Colour image (PNG or JPEG).
    #[arg(long)]
    pub rgb: PathBuf,
    /// Depth: 16-bit PNG (scaled by --depth-scale) or .npy (float32 metres or uint16 scaled).
    #[arg(long)]
    pub depth: PathBuf,
    /// Metres per depth unit of a 16-bit image (e.g. 0.001 for millimetres).
    #[arg(long, default_value_t = 0.001)]
    pub depth_scale: f32,
    /// fx,fy,cx,cy in pixels.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub intrinsics: Vec<f32>,
    /// world_from_camera, 16 numbers row-major (camera axes: x right, y down, z forward).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub camera_pose: Vec<f32>,
    /// Intrinsics and pose from a camera.json (as `umpnet render` writes it),
    /// instead of --intrinsics and --camera-pose.
    #[arg(long, conflicts_with_all = ["intrinsics", "camera_pose"])]
    pub camera: Option<PathBuf>,
    /// Reference (goal) colour image; with it the goal task is solved.
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Depth of the reference image (same format and scale as --depth).
    #[arg(long)]
    pub reference_depth: Option<PathBuf>,
    /// Exploration: the episode's first colour image, which "forward" (AoT)
    /// is judged against; without it, the current frame is its own reference.
    #[arg(long, conflicts_with = "reference")]
    pub initial: Option<PathBuf>,
    /// Depth of the first image (same format and scale as --depth).
    #[arg(long)]
    pub initial_depth: Option<PathBuf>,
    /// The direction executed last (x,y,z in the world frame), which
    /// `--direction-filter prev90` keeps the next one within 90 degrees of.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub previous: Vec<f32>,
    /// How the gripper itself went over the last move (world x,y,z, metres,
    /// from its own pose), which `--direction-filter goal45` and `onward45`
    /// read; a session reads it from `--gripper` instead.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub motion: Vec<f32>,
    #[command(flatten)]
    pub learned: crate::policies::LearnedArgs,
    /// Pixel (row,col) the gripper holds; without it the position action is chosen.
    #[arg(long, value_delimiter = ',')]
    pub grasp: Vec<usize>,
    /// Model package (default: $UMPNET_MODEL, then models/umpnet-gpu-medium as `explore` finds it).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Seed of the direction sampling (CEM).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// A robot loop's state between calls, kept in this folder: the first
    /// call starts an episode (its frame becomes the exploration's
    /// reference, its grasp is chosen); each later call decides the next
    /// move with the episode's memory. See docs/cli.md.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["initial", "initial_depth", "previous", "motion"])]
    pub session: Option<PathBuf>,
    /// With --session: whether the last move moved the part (`true` or
    /// `false`, as the robot saw it); a move that moved nothing is not tried
    /// again until one does.
    #[arg(long, requires = "session")]
    pub moved: Option<bool>,
    /// With --session, after the first call: where the gripper is now (world
    /// x,y,z), projected into the frame; or give --grasp row,col.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        requires = "session"
    )]
    pub gripper: Vec<f32>,
}

/// What a decision needs, read and checked: the policy, the frames at full
/// and at the model's size, and the other frames (goal or first) if given.
pub(crate) struct Inputs {
    pub model: PathBuf,
    pub policy: UmpnetPolicy,
    pub full: OwnedFrame,
    pub obs: ndarray::Array3<f32>,
    pub reference: Option<ndarray::Array3<f32>>,
    pub initial: Option<ndarray::Array3<f32>>,
    pub grasp: Option<(usize, usize)>,
    pub previous: Option<Vector3<f32>>,
    pub motion: Option<Vector3<f32>>,
}

impl Inputs {
    /// Rows and columns of the full frame per model pixel.
    pub fn scale(&self) -> (f32, f32) {
        let (mh, mw) = self.policy.resolution();
        (
            self.full.height as f32 / mh as f32,
            self.full.width as f32 / mw as f32,
        )
    }

    /// A full-frame pixel at the model's size.
    pub fn to_model(&self, (r, c): (usize, usize)) -> (usize, usize) {
        let (mh, mw) = self.policy.resolution();
        let (sy, sx) = self.scale();
        (
            (((r as f32 + 0.5) / sy) as usize).min(mh - 1),
            (((c as f32 + 0.5) / sx) as usize).min(mw - 1),
        )
    }

    /// A model pixel in the full frame.
    pub fn to_full(&self, (r, c): (usize, usize)) -> (usize, usize) {
        let (sy, sx) = self.scale();
        (
            (((r as f32 + 0.5) * sy) as usize).min(self.full.height.saturating_sub(1)),
            (((c as f32 + 0.5) * sx) as usize).min(self.full.width.saturating_sub(1)),
        )
    }

    /// The grasp at the model's size: `--grasp`, else the policy's position
    /// (masked by the goal, when there is one).
    pub fn grasp_pixel(&self) -> Result<(usize, usize)> {
        Ok(match self.grasp {
            Some(p) => self.to_model(p),
            None => {
                self.policy
                    .position(self.obs.view(), self.reference.as_ref().map(|r| r.view()))?
                    .pixel
            }
        })
    }

    /// Goal mode when a goal frame was given.
    pub fn mode(&self) -> Mode {
        if self.reference.is_some() {
            Mode::Goal
        } else {
            Mode::Explore
        }
    }
}

/// An x,y,z flag's vector: three finite numbers, and not zero where `nonzero`.
fn vector_arg(flag: &str, values: &[f32], nonzero: bool) -> Result<Option<Vector3<f32>>> {
    match values {
        [] => Ok(None),
        &[x, y, z]
            if [x, y, z].iter().all(|v| v.is_finite())
                && (!nonzero || x * x + y * y + z * z > 1e-12) =>
        {
            Ok(Some(Vector3::new(x, y, z)))
        }
        v => Err(usage(format!(
            "{flag} takes x,y,z, three finite numbers{}, got {v:?}",
            if nonzero { " (not all zero)" } else { "" }
        ))),
    }
}

pub(crate) fn read_inputs(a: &InferArgs) -> Result<Inputs> {
    let camera = Camera::from_args(a)?;
    let grasp = match a.grasp.as_slice() {
        [] => None,
        &[r, c] => Some((r, c)),
        other => {
            return Err(usage(format!(
                "--grasp takes row,col (two numbers), got {other:?}"
            )));
        }
    };
    let model = match &a.model {
        Some(m) => m.clone(),
        None => crate::policies::default_model()?,
    };
    let pkg = ModelPackage::load(&model, 1, 1, None)
        .with_context(|| format!("loading {}", model.display()))?;
    let policy = a
        .learned
        .resolve()
        .apply(UmpnetPolicy::new(std::sync::Arc::new(pkg)))?;
    let previous = vector_arg("--previous", &a.previous, true)?.map(|v| v.normalize());
    let motion = vector_arg("--motion", &a.motion, false)?;
    let (mh, mw) = policy.resolution();
    let full = load_frame(&a.rgb, &a.depth, a, &camera)?;
    if let Some((h, w)) = camera.size
        && (h, w) != (full.height, full.width)
    {
        return Err(usage(format!(
            "{} was written for {h}x{w} images (HEIGHTxWIDTH), but {} is {}x{}; its intrinsics would not fit",
            camera.source,
            a.rgb.display(),
            full.height,
            full.width
        )));
    }
    if let Some((r, c)) = grasp
        && (r >= full.height || c >= full.width)
    {
        return Err(usage(format!(
            "--grasp {r},{c} is outside the {}x{} image",
            full.height, full.width
        )));
    }
    let small = resize_nearest(&full.view(), mh, mw)?;
    let obs = build_observation(&small.view())?;
    // A second frame (the goal, or the episode's first) comes as a colour
    // image and its depth, both or neither, seen as the policy sees frames.
    let other_frame = |rgb: &Option<PathBuf>, depth: &Option<PathBuf>, flag: &str| match (
        rgb, depth,
    ) {
        (Some(r), Some(d)) => {
            let frame = load_frame(r, d, a, &camera)?;
            if (frame.height, frame.width) != (full.height, full.width) {
                return Err(usage(format!(
                    "--{flag} {} is {}x{}, but the current frame {} is {}x{}: both come from the same camera",
                    r.display(),
                    frame.height,
                    frame.width,
                    a.rgb.display(),
                    full.height,
                    full.width
                )));
            }
            Ok(Some(build_observation(
                &resize_nearest(&frame.view(), mh, mw)?.view(),
            )?))
        }
        (None, None) => Ok(None),
        _ => Err(usage(format!("--{flag} and --{flag}-depth go together"))),
    };
    let reference = other_frame(&a.reference, &a.reference_depth, "reference")?;
    let initial = other_frame(&a.initial, &a.initial_depth, "initial")?;
    Ok(Inputs {
        model,
        policy,
        full,
        obs,
        reference,
        initial,
        grasp,
        previous,
        motion,
    })
}

pub fn run(_ctx: &Ctx, a: &InferArgs) -> Result<()> {
    let inputs = read_inputs(a)?;
    let pixel_small = inputs.grasp_pixel()?;
    let reference = inputs
        .reference
        .as_ref()
        .or(inputs.initial.as_ref())
        .unwrap_or(&inputs.obs);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(a.seed);
    let known = Known {
        previous: inputs.previous,
        motion: inputs.motion,
        ..Known::default()
    };
    let (out, _) = decide(&inputs, reference, pixel_small, &known, &mut rng)?;
    outln!("{out}");
    Ok(())
}

/// What a decision knows of its episode beyond the frames: the memory's
/// moves ([`umpnet_policy::memory::EpisodeMemory`]) and the grasped part's
/// joint as read at the grasp.
#[derive(Default)]
pub(crate) struct Known<'a> {
    pub banned: &'a [Vector3<f32>],
    pub previous: Option<Vector3<f32>>,
    pub motion: Option<Vector3<f32>>,
    pub long_motion: Option<Vector3<f32>>,
    /// The joint read from the frame the grasp was made on; None: read it
    /// from this frame.
    pub joint: Option<&'a umpnet_policy::frame_joint::FrameJoint>,
}

/// One decision, as infer prints it (JSON): the grasp pixel in the full
/// frame and its world point, the direction (None: stop) with its scores,
/// and the grasped part's joint when the package has a JointNet; with the
/// joint, which a session keeps from its first call.
pub(crate) fn decide(
    inputs: &Inputs,
    reference: &ndarray::Array3<f32>,
    pixel_small: (usize, usize),
    known: &Known<'_>,
    rng: &mut rand_chacha::ChaCha8Rng,
) -> Result<(
    serde_json::Value,
    Option<umpnet_policy::frame_joint::FrameJoint>,
)> {
    let mode = inputs.mode();
    // The joint of the grasped part (a package with a JointNet): as read at
    // the grasp, else from this frame alone; reported, and read by the
    // joint45 and onward45 filters.
    let joint = match known.joint {
        Some(j) => Some(j.clone()),
        None => inputs.policy.frame_joint(inputs.obs.view(), pixel_small)?,
    };
    let input = DecisionInput {
        observation: inputs.obs.view(),
        reference: reference.view(),
        pixel: pixel_small,
        banned: known.banned,
        previous: known.previous,
        mode,
        joint: joint.as_ref().map(|j| &j.estimate),
        motion: known.motion,
        long_motion: known.long_motion,
    };
    let model = &inputs.model;
    let Some(r) = inputs
        .policy
        .directions(std::slice::from_ref(&input), std::slice::from_mut(rng))?
        .pop()
    else {
        bail!("{}: the policy returned no decision", model.display());
    };
    let full = &inputs.full;
    let pixel_full = inputs.to_full(pixel_small);
    let point = CameraFrame::point_in_world(&full.view(), pixel_full.0, pixel_full.1);
    let best = r.direction.and_then(|d| {
        r.candidates
            .iter()
            .position(|c| *c == d)
            .and_then(|i| r.scores.get(i))
            .map(|s| (d, *s))
    });
    // A network that outputs NaN must not yield an action.
    if r.scores.iter().any(|s| !s.distance.is_finite())
        || best.is_some_and(|(d, _)| !d.iter().all(|v| v.is_finite()))
    {
        bail!(
            "{}: the model's predictions are not finite numbers (NaN or infinity); no action",
            model.display()
        );
    }
    let out = serde_json::json!({
        "pixel": [pixel_full.0, pixel_full.1],
        "point_in_world": point.map(|p| [p.x, p.y, p.z]),
        "mode": mode,
        "direction": best.map(|(d, _): (Vector3<f32>, _)| [d.x, d.y, d.z]),
        "predicted_distance": best.map(|(_, s)| s.distance),
        "predicted_aot": best.map(|(_, s)| s.aot),
        "stop": r.direction.is_none(),
        "joint": joint,
        "model": model,
    });
    Ok((out, joint))
}
