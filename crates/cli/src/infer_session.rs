//! `umpnet infer --session DIR`: a robot loop's episode across calls. The
//! first call starts it: the frame becomes the exploration's reference and
//! the grasp is chosen. Each later call decides the next move with the
//! episode's memory (umpnet_policy::memory, the benchmark's rule), told by
//! `--moved` whether the last move moved the part. The state is
//! `DIR/session.json` and, exploring, `DIR/reference.f32` (the first frame
//! at the model's size), each replaced whole.
use crate::infer_cmd::{InferArgs, Inputs, Known, decide, read_inputs};
use crate::{Ctx, usage};
use anyhow::{Context, Result, bail};
use nalgebra::Vector3;
use rand::SeedableRng;
use std::path::Path;
use umpnet_policy::cem::Mode;
use umpnet_policy::frame_joint::FrameJoint;
use umpnet_policy::memory::EpisodeMemory;

const FORMAT: &str = "umpnet-infer-session";

#[derive(serde::Serialize, serde::Deserialize)]
struct State {
    format: String,
    version: u32,
    /// The model package the session decides with.
    model: String,
    seed: u64,
    mode: Mode,
    /// Calls so far.
    steps: u64,
    /// Full frame size (height, width): every frame comes from one camera.
    size: [usize; 2],
    /// The model's input (height, width, channels) of reference.f32.
    reference_shape: Option<[usize; 3]>,
    banned: Vec<[f32; 3]>,
    previous: Option<[f32; 3]>,
    /// The move the last call returned, which --moved reports on.
    last: Option<[f32; 3]>,
    /// Where the gripper was at the last call (world frame): the grasp's
    /// point at the first, then `--gripper` or the point at `--grasp`.
    /// Sessions written before it read as unknown.
    #[serde(default)]
    gripper: Option<[f32; 3]>,
    /// How the gripper went over the last move that carried it more than
    /// 2 cm (world frame), which goal45 reads after moves that stalled.
    /// Sessions written before it read as none.
    #[serde(default)]
    long_motion: Option<[f32; 3]>,
    /// The grasped part's joint as the package's JointNet read it on the
    /// first call's frame, where the grasp was made: later frames show the
    /// gripper over it. Sessions written before it read it from each frame.
    #[serde(default)]
    joint: Option<FrameJoint>,
}

fn state_error(dir: &Path, what: impl std::fmt::Display) -> anyhow::Error {
    usage(format!("--session {}: {what}", dir.display()))
}

/// The gripper's world position projected into the current frame.
fn project(inputs: &Inputs, p: Vector3<f32>, dir: &Path) -> Result<(usize, usize)> {
    let m = inputs.full.world_from_camera;
    let rot = nalgebra::Matrix3::new(
        m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2], m[2][0], m[2][1], m[2][2],
    );
    let t = Vector3::new(m[0][3], m[1][3], m[2][3]);
    let c = rot.transpose() * (p - t);
    let [fx, fy, cx, cy] = inputs.full.intrinsics;
    let (col, row) = (fx * c.x / c.z + cx, fy * c.y / c.z + cy);
    let (h, w) = (inputs.full.height as f32, inputs.full.width as f32);
    if !(c.z > 1e-3 && (0.0..w).contains(&col) && (0.0..h).contains(&row)) {
        return Err(state_error(
            dir,
            format!(
                "--gripper {:?} is not in front of the camera, inside the image",
                [p.x, p.y, p.z]
            ),
        ));
    }
    Ok((row as usize, col as usize))
}

fn save(dir: &Path, state: &State) -> Result<()> {
    let text = serde_json::to_string_pretty(state)?;
    umpnet_sim::fsio::write_atomic(&dir.join("session.json"), text.as_bytes())?;
    Ok(())
}

/// One call of the loop (`infer --session DIR`): start the session, or
/// take its next step.
pub fn run(_ctx: &Ctx, a: &InferArgs, dir: &Path) -> Result<()> {
    let inputs = read_inputs(a)?;
    if dir.join("session.json").exists() {
        next(dir, a, &inputs)
    } else {
        start(dir, a, &inputs)
    }
}

fn start(dir: &Path, a: &InferArgs, inputs: &Inputs) -> Result<()> {
    let size = [inputs.full.height, inputs.full.width];
    let model = inputs.model.to_string_lossy().into_owned();
    {
        if a.moved.is_some() || !a.gripper.is_empty() {
            return Err(state_error(
                dir,
                "no session yet: its first call takes the first frame (and --grasp, if the gripper already holds the part), not --moved or --gripper",
            ));
        }
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let pixel = inputs.grasp_pixel()?;
        let mode = inputs.mode();
        let reference_shape = (mode == Mode::Explore).then(|| {
            let (h, w, c) = inputs.obs.dim();
            [h, w, c]
        });
        if reference_shape.is_some() {
            let bytes: Vec<u8> = inputs.obs.iter().flat_map(|v| v.to_le_bytes()).collect();
            umpnet_sim::fsio::write_atomic(&dir.join("reference.f32"), &bytes)?;
        }
        let reference = inputs.reference.as_ref().unwrap_or(&inputs.obs);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(a.seed);
        let (out, joint) = decide(inputs, reference, pixel, &Known::default(), &mut rng)?;
        let (r, c) = inputs.to_full(pixel);
        let gripper = inputs.full.view().point_in_world(r, c);
        let state = State {
            format: FORMAT.into(),
            version: 1,
            model,
            seed: a.seed,
            mode,
            steps: 1,
            size,
            reference_shape,
            banned: Vec::new(),
            previous: None,
            last: direction_of(&out),
            gripper: gripper.map(|g| [g.x, g.y, g.z]),
            long_motion: None,
            joint,
        };
        save(dir, &state)?;
        print(out, dir, &state)
    }
}

/// The session's state, checked against this call's model, camera and task.
fn load_state(dir: &Path, inputs: &Inputs) -> Result<State> {
    let path = dir.join("session.json");
    let size = [inputs.full.height, inputs.full.width];
    let model = inputs.model.to_string_lossy().into_owned();
    let text = umpnet_sim::fsio::read_text(&path, 1 << 20)?;
    let state: State =
        serde_json::from_str(&text).map_err(|e| state_error(dir, format!("session.json: {e}")))?;
    if state.format != FORMAT || state.version != 1 {
        return Err(state_error(
            dir,
            "session.json is not an umpnet infer session (version 1)",
        ));
    }
    if state
        .joint
        .as_ref()
        .is_some_and(|j| !j.estimate.is_usable())
    {
        return Err(state_error(
            dir,
            "session.json: joint needs a nonzero axis and finite numbers",
        ));
    }
    if state.model != model {
        return Err(state_error(
            dir,
            format!(
                "the session decides with {}, not {model}: start a new session for another model",
                state.model
            ),
        ));
    }
    if state.size != size {
        return Err(state_error(
            dir,
            format!(
                "frames of this session are {}x{}, this one is {}x{}: one camera per session",
                state.size[0], state.size[1], size[0], size[1]
            ),
        ));
    }
    if (state.mode == Mode::Goal) != inputs.reference.is_some() {
        return Err(state_error(
            dir,
            match state.mode {
                Mode::Goal => {
                    "the session seeks a goal: give --reference and --reference-depth at every call"
                }
                Mode::Explore => {
                    "the session explores: --reference starts a goal session in a new folder"
                }
            },
        ));
    }
    Ok(state)
}

/// The gripper's pixel at the model's size, and its world point.
type GripperNow = ((usize, usize), Option<Vector3<f32>>);

/// Where the gripper holds the part now: `--gripper` projected, or
/// `--grasp` with the surface the frame shows there (None where it shows
/// none).
fn gripper_now(dir: &Path, a: &InferArgs, inputs: &Inputs) -> Result<GripperNow> {
    Ok(match (inputs.grasp, a.gripper.as_slice()) {
        (Some((r, c)), []) => (
            inputs.to_model((r, c)),
            inputs.full.view().point_in_world(r, c),
        ),
        (None, &[x, y, z]) if [x, y, z].iter().all(|v| v.is_finite()) => {
            let point = Vector3::new(x, y, z);
            (inputs.to_model(project(inputs, point, dir)?), Some(point))
        }
        (None, []) => {
            return Err(state_error(
                dir,
                "where is the gripper now? give --grasp row,col or --gripper x,y,z (world frame)",
            ));
        }
        _ => {
            return Err(state_error(
                dir,
                "give one of --grasp row,col and --gripper x,y,z (three finite numbers)",
            ));
        }
    })
}

/// The next step: the memory told whether the last move moved the part.
fn next(dir: &Path, a: &InferArgs, inputs: &Inputs) -> Result<()> {
    let mut state = load_state(dir, inputs)?;
    let (pixel, gripper) = gripper_now(dir, a, inputs)?;
    let mut memory = EpisodeMemory::from_parts(
        state.banned.iter().map(|d| Vector3::from(*d)).collect(),
        state.previous.map(Vector3::from),
        state.long_motion.map(Vector3::from),
    );
    if let (Some(last), Some(moved)) = (state.last, a.moved) {
        memory.record(Vector3::from(last), moved);
    }
    // The memory takes how the gripper went since the last call.
    if let Some(g) = state.gripper {
        memory.gripper_at(Vector3::from(g));
    }
    if let Some(g) = gripper {
        memory.gripper_at(g);
    }
    let stored;
    let reference = match (state.mode, state.reference_shape) {
        (Mode::Explore, Some(shape)) => {
            let bytes = std::fs::read(dir.join("reference.f32"))
                .with_context(|| format!("reading {}", dir.join("reference.f32").display()))?;
            let values: Vec<f32> = bytes
                .chunks_exact(4)
                .filter_map(|b| <[u8; 4]>::try_from(b).ok().map(f32::from_le_bytes))
                .collect();
            stored = ndarray::Array3::from_shape_vec((shape[0], shape[1], shape[2]), values)
                .map_err(|_| {
                    state_error(dir, "reference.f32 does not hold the session's first frame")
                })?;
            &stored
        }
        (Mode::Explore, None) => bail!(
            "--session {}: session.json lost its reference",
            dir.display()
        ),
        (Mode::Goal, _) => inputs.reference.as_ref().unwrap_or(&inputs.obs),
    };
    // Each step its own stream, so a step replayed decides the same.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(
        state.seed ^ state.steps.wrapping_mul(0x9E37_79B9_7F4A_7C15),
    );
    let known = Known {
        banned: memory.banned(),
        previous: memory.previous(),
        motion: memory.motion(),
        long_motion: memory.long_motion(),
        joint: state.joint.as_ref(),
    };
    let (out, _) = decide(inputs, reference, pixel, &known, &mut rng)?;
    state.steps += 1;
    state.banned = memory.banned().iter().map(|d| [d.x, d.y, d.z]).collect();
    state.previous = memory.previous().map(|d| [d.x, d.y, d.z]);
    state.last = direction_of(&out);
    state.gripper = gripper.map(|g| [g.x, g.y, g.z]);
    state.long_motion = memory.long_motion().map(|m| [m.x, m.y, m.z]);
    save(dir, &state)?;
    print(out, dir, &state)
}

fn direction_of(out: &serde_json::Value) -> Option<[f32; 3]> {
    let d = out.get("direction")?.as_array()?;
    let v: Vec<f32> = d
        .iter()
        .filter_map(|x| x.as_f64().map(|x| x as f32))
        .collect();
    <[f32; 3]>::try_from(v.as_slice()).ok()
}

fn print(mut out: serde_json::Value, dir: &Path, state: &State) -> Result<()> {
    if let Some(map) = out.as_object_mut() {
        map.insert(
            "session".into(),
            serde_json::json!({"dir": dir, "step": state.steps, "banned": state.banned.len()}),
        );
    }
    outln!("{out}");
    Ok(())
}
