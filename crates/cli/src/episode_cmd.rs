use crate::{Ctx, images, pictures, usage};
use anyhow::{Context, Result};
use std::path::PathBuf;
use umpnet_eval::Policy;
use umpnet_eval::episode::{EpisodeConfig, HookFrame, run_episode};
use umpnet_sim::camera::Camera;
use umpnet_sim::render::{RendererKind, create_renderer};
use umpnet_sim::scene::Task;

/// Most direction actions one episode may take: the paper's budgets are 10
/// to 50, and an episode's curves hold one value per step.
pub const MAX_STEPS: usize = 10_000;

/// The camera of scripted policies unless --resolution says otherwise.
const DEFAULT_RESOLUTION: (u32, u32) = (240, 320);

fn parse_steps(s: &str) -> std::result::Result<usize, String> {
    match s.trim().parse::<u64>() {
        Ok(n) if (1..=MAX_STEPS as u64).contains(&n) => Ok(n as usize),
        _ => Err(format!("expected a number of steps from 1 to {MAX_STEPS}")),
    }
}

#[derive(clap::Args)]
pub struct EpisodeArgs {
    #[command(flatten)]
    pub object: crate::ObjectArgs,
    /// Number of direction actions, 1 to 10000 (default: the protocol's budget).
    #[arg(long, value_parser = parse_steps)]
    pub steps: Option<usize>,
    /// Evaluation protocol: paper (the paper's evaluation code) or strict.
    #[arg(long, default_value = "paper", value_parser = crate::choice::<umpnet_eval::Protocol>(crate::PROTOCOLS))]
    pub protocol: umpnet_eval::Protocol,
    /// random, oracle, umpnet (with --model) or NAME=MODEL_DIR.
    #[arg(long, default_value = "oracle")]
    pub policy: String,
    #[command(flatten)]
    pub learned: crate::policies::LearnedArgs,
    /// Model package for --policy umpnet (default: models/umpnet-gpu-medium).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Image size as HEIGHTxWIDTH (rows x columns) of a scripted policy's
    /// camera [default: 240x320]; a learned policy sees its model's input.
    #[arg(long, value_parser = crate::parse_resolution)]
    pub resolution: Option<(u32, u32)>,
    #[command(flatten)]
    pub sensor: crate::SensorArgs,
    /// Renderer: wgpu (a GPU, or Vulkan's CPU driver), cpu (built in), or auto
    /// (wgpu when an adapter exists, else cpu, with a notice).
    #[arg(long, default_value = "auto", value_parser = crate::choice::<RendererKind>(crate::RENDERERS))]
    pub renderer: RendererKind,
    /// Write one PNG per step, a contact sheet and an animated GIF here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Size of the pictures in --out and of the --rrd display view,
    /// HEIGHTxWIDTH, whatever the policy sees (its view is drawn as an inset,
    /// and recorded as `world/camera`).
    #[arg(long, default_value = "480x640", value_parser = crate::parse_resolution)]
    pub picture_size: (u32, u32),
    /// Write a Rerun recording of the episode to this .rrd file (images,
    /// meshes and their poses, gripper, action arrows, joint and predictions
    /// over steps). Needs a build with the `rerun` feature.
    #[arg(long)]
    pub rrd: Option<PathBuf>,
}

pub fn run(ctx: &Ctx, a: &EpisodeArgs, task: Task) -> Result<()> {
    let resolved = crate::policies::resolve(
        std::slice::from_ref(&a.policy),
        a.model.as_deref(),
        1,
        task,
        a.learned.resolve(),
    )?;
    let mut policy: Box<dyn Policy> = match resolved.factories.first() {
        Some((_, make)) => make()?,
        None => return Err(usage("--policy is empty")),
    };
    let resolution = camera_resolution(a, &resolved.resolutions);
    let scene = a.object.scene(task)?;
    let budget = a
        .steps
        .unwrap_or_else(|| a.protocol.budget(task, scene.category));
    let camera = a.sensor.camera(resolution);
    let mut recorder = match &a.rrd {
        Some(path) => Some(crate::rrd::Recorder::create(
            path,
            &format!("{} {:?}, seed {}", a.policy, task, a.object.seed),
            Some((a.picture_size, a.renderer)),
        )?),
        None => None,
    };
    let mut record_error: Option<anyhow::Error> = None;
    let mut display = match &a.out {
        Some(_) => Some(pictures::Display::new(&scene, a.picture_size, a.renderer)?),
        None => None,
    };
    let mut tiles: Vec<pictures::Tile> = Vec::new();
    let mut hook = |h: &HookFrame<'_>| {
        if let Some(d) = display.as_mut()
            && record_error.is_none()
        {
            match d.step(h) {
                Ok(tile) => tiles.push(tile),
                Err(e) => record_error = Some(e.context("drawing the episode's pictures")),
            }
        }
        if let Some(r) = recorder.as_mut()
            && record_error.is_none()
            && let Err(e) = r.log(h)
        {
            record_error = Some(e);
        }
    };
    let ep = run_episode(
        &scene,
        &camera,
        create_renderer(a.renderer)?,
        policy.as_mut(),
        EpisodeConfig {
            budget,
            seed: a.object.seed,
            protocol: a.protocol,
        },
        if a.out.is_some() || a.rrd.is_some() {
            Some(&mut hook)
        } else {
            None
        },
    )?;
    if let Some(e) = record_error {
        return Err(e);
    }
    if let Some(r) = recorder {
        r.finish()?;
    }
    let frame_joint = match (task, resolved.packages.first()) {
        (Task::Exploration, Some((_, dir))) => frame_joint_score(&ep, dir, &camera, a.renderer)?,
        _ => None,
    };
    let (ended, why) = end_reason(&ep, task);
    if let (Some(out), Some(d)) = (&a.out, display.as_mut()) {
        let title = picture_title(&ep, task, a.object.seed, &why);
        write_pictures(out, d, tiles, &title)?;
    }
    if ctx.json {
        let mut value = serde_json::to_value(&ep)?;
        if let Some(map) = value.as_object_mut() {
            map.insert("ended".into(), ended.into());
            if let Some(f) = &frame_joint {
                map.insert("frame_joint".into(), serde_json::to_value(f)?);
            }
        }
        outln!("{value}");
        return Ok(());
    }
    print_episode(&ep, task, a.object.seed, &why)?;
    if let Some(f) = &frame_joint {
        print_frame_joint(f)?;
    }
    if let Some(out) = &a.out {
        outln!("pictures in {}", out.display());
    }
    Ok(())
}

/// The episode as text: the grasp, a row per step, how it ended, the
/// metrics and, exploring, the joint axis the moves imply.
fn print_episode(
    ep: &umpnet_eval::episode::Episode,
    task: Task,
    seed: u64,
    why: &str,
) -> Result<()> {
    let what = ep
        .scene
        .category
        .map(|c| c.name().to_owned())
        .unwrap_or_else(|| "object".into());
    outln!(
        "{} episode, {what}, policy {}, scene seed {}",
        if task == Task::Goal {
            "goal"
        } else {
            "exploration"
        },
        ep.policy,
        seed
    );
    let grasped = match (ep.valid_position, ep.joint) {
        (true, Some(j)) => format!("joint {j} (moves the link under the pixel)"),
        _ => "no valid link: episode ends".into(),
    };
    outln!(
        "position: pixel (row {}, col {}) -> {grasped}",
        ep.pixel.0,
        ep.pixel.1
    );
    outln!(
        "{:>4}  {:>24}  {:>9}  {:>9}  {:>4}",
        "step",
        "direction (world)",
        "joint",
        "change",
        "AoT"
    );
    for (t, s) in ep.steps.iter().enumerate() {
        let d = s.record.direction;
        let l = &s.record.labels;
        outln!(
            "{:>4}  ({:>6.3}, {:>6.3}, {:>6.3})  {:>9.3}  {:>+9.3}  {:>+4}",
            t + 1,
            d[0],
            d[1],
            d[2],
            l.joint_after,
            l.joint_after - l.joint_before,
            l.aot
        );
    }
    outln!("ended: {why}");
    let m = &ep.metrics;
    match task {
        Task::Exploration => outln!(
            "novel-state ratio {:.3}  single action effect {:.3}  unique states {}",
            m.novel_state_ratio,
            m.single_action_effect,
            m.unique_states.last().copied().unwrap_or(0.0)
        ),
        Task::Goal => outln!(
            "normalized distance {:.3}  success {}",
            m.normalized_distance,
            m.success
        ),
    }
    if task == Task::Exploration {
        print_axis_estimate(ep)?;
    }
    Ok(())
}

/// The step PNGs, the contact sheet (the goal first, in the goal task) and the GIF.
fn write_pictures(
    out: &std::path::Path,
    display: &mut pictures::Display,
    tiles: Vec<pictures::Tile>,
    title: &str,
) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let steps: Vec<_> = tiles
        .iter()
        .map(|t| pictures::with_title(&t.at_width(t.img.width()), title))
        .collect();
    for (t, p) in steps.iter().enumerate() {
        images::save(p, &out.join(format!("step_{t:02}.png")))?;
    }
    // The goal task's sheet opens with the goal, so each step can be set beside it.
    let mut sheet = Vec::with_capacity(tiles.len() + 1);
    if let Some(goal) = display.goal()? {
        images::save(&goal.at_width(goal.img.width()), &out.join("goal.png"))?;
        sheet.push(goal);
    }
    sheet.extend(tiles);
    images::save(
        &pictures::contact_sheet(&sheet, title),
        &out.join("episode.png"),
    )?;
    pictures::write_gif(&steps, &out.join("episode.gif"))
}

/// The policy's camera size: a learned policy's model input (with a notice
/// when --resolution asked for another), else --resolution or the default.
fn camera_resolution(
    a: &EpisodeArgs,
    resolutions: &std::collections::BTreeMap<String, (u32, u32)>,
) -> (u32, u32) {
    // One policy: a learned one sees its package's input resolution.
    let learned = resolutions.values().next().copied();
    if let (Some((h, w)), Some(asked)) = (learned, a.resolution)
        && asked != (h, w)
    {
        eprintln!(
            "notice: policy {} sees {h}x{w}, its model's input; --resolution {}x{} is not used (pictures are drawn at --picture-size)",
            a.policy, asked.0, asked.1
        );
    }
    resolutions
        .values()
        .next()
        .copied()
        .unwrap_or(a.resolution.unwrap_or(DEFAULT_RESOLUTION))
}

/// The pictures' title: what ran on what, and how it ended.
fn picture_title(ep: &umpnet_eval::episode::Episode, task: Task, seed: u64, why: &str) -> String {
    use umpnet_sim::scene::ObjectSource;
    let object = match &ep.scene.object {
        ObjectSource::Generated {
            category, index, ..
        } => format!("{} #{index}", category.name()),
        ObjectSource::File { path, .. } => path.parent().and_then(|p| p.file_name()).map_or_else(
            || path.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        ),
    };
    let what = match task {
        Task::Exploration => format!(
            "exploration, novel-state ratio {:.2}",
            ep.metrics.novel_state_ratio
        ),
        Task::Goal => format!(
            "goal {}, distance {:.2}",
            if ep.metrics.success {
                "reached"
            } else {
                "not reached"
            },
            ep.metrics.normalized_distance
        ),
    };
    format!(
        "{object} | policy {} | seed {seed} | {what} | {why}",
        ep.policy
    )
}

/// How an episode ended, as a code (`--json`'s `ended`) and in words.
fn end_reason(ep: &umpnet_eval::episode::Episode, task: Task) -> (&'static str, String) {
    let n = ep.steps.len();
    let steps = |k: usize| {
        if k == 1 {
            "1 step".to_owned()
        } else {
            format!("{k} steps")
        }
    };
    if !ep.valid_position {
        (
            "missed",
            "the grasp is not on a movable part, so no move was made".into(),
        )
    } else if ep.stopped_early {
        (
            "policy_stopped",
            format!("the policy stopped after {}", steps(n)),
        )
    } else if ep.ended_by_protocol && task == Task::Goal {
        (
            "goal_reached",
            format!("the goal was reached in {n} of {}", steps(ep.budget)),
        )
    } else if ep.ended_by_protocol {
        (
            "joint_limit",
            format!(
                "the part reached a joint limit after {} (the paper's protocol ends exploration there)",
                steps(n)
            ),
        )
    } else if !ep.steps.iter().any(|s| s.record.labels.moved) {
        (
            "no_effect",
            format!(
                "all {} spent, none of them moved the part",
                steps(ep.budget)
            ),
        )
    } else {
        ("budget", format!("all {} spent", steps(ep.budget)))
    }
}

/// The joint a package's JointNet reads from the scene's first frame at the
/// episode's grasp, scored against the simulator; None without a JointNet,
/// a valid grasp or a vote.
fn frame_joint_score(
    ep: &umpnet_eval::episode::Episode,
    package: &std::path::Path,
    camera: &Camera,
    renderer: RendererKind,
) -> Result<Option<umpnet_eval::frame_joint::FrameJointScore>> {
    let Some(joint) = ep.joint.filter(|_| ep.valid_position) else {
        return Ok(None);
    };
    let pkg = umpnet_policy::ModelPackage::load(package, 1, 1, None)
        .with_context(|| format!("loading {}", package.display()))?;
    if !pkg.has_joint() {
        return Ok(None);
    }
    let policy = umpnet_policy::UmpnetPolicy::new(std::sync::Arc::new(pkg));
    let pixel = (ep.pixel.0 as usize, ep.pixel.1 as usize);
    Ok(umpnet_eval::frame_joint::score_first_frame(
        &ep.scene,
        camera,
        create_renderer(renderer)?,
        &policy,
        pixel,
        joint,
    )?)
}

fn print_frame_joint(f: &umpnet_eval::frame_joint::FrameJointScore) -> Result<()> {
    use umpnet_policy::axis::JointEstimate;
    let v = |a: &[f32; 3]| format!("({:.3}, {:.3}, {:.3})", a[0], a[1], a[2]);
    let estimate = match &f.estimate.estimate {
        JointEstimate::Prismatic { axis } => format!("prismatic, axis {}", v(axis)),
        JointEstimate::Revolute { axis, point } => {
            format!("revolute, axis {} through {}", v(axis), v(point))
        }
    };
    let truth = if f.true_prismatic {
        format!("prismatic, axis {}", v(&f.true_axis))
    } else {
        format!(
            "revolute, axis {} through {}",
            v(&f.true_axis),
            v(&f.true_point)
        )
    };
    let origin = f
        .origin_error_m
        .map(|m| format!(", the axis passes {m:.3} m from the true one"))
        .unwrap_or_default();
    outln!(
        "joint from the first frame (JointNet, {} voting pixels, hinge probability {:.2}): {estimate}",
        f.estimate.voting_pixels,
        f.estimate.hinge_probability
    );
    outln!(
        "  true: {truth}; {:.1} deg apart{origin}{}",
        f.axis_error_deg,
        if f.type_right { "" } else { "; the wrong type" }
    );
    Ok(())
}

/// The paper's joint-axis inference from the executed directions, for a
/// joint of the grasped joint's kind, against the truth.
fn print_axis_estimate(ep: &umpnet_eval::episode::Episode) -> Result<()> {
    use nalgebra::Vector3;
    use umpnet_policy::axis::axis_of_known_kind;
    let (Some(err), Some(j)) = (ep.metrics.axis, ep.joint) else {
        outln!("joint axis: fewer than two moves of the part; nothing to infer it from");
        return Ok(());
    };
    let dirs: Vec<Vector3<f32>> = ep
        .steps
        .iter()
        .filter(|s| s.record.labels.moved)
        .map(|s| Vector3::from(s.record.direction))
        .collect();
    let axis = axis_of_known_kind(&dirs, err.prismatic).unwrap_or_default();
    // At the scene's scale: its joint values (prismatic ones scale) are the scaled object's.
    let model = std::sync::Arc::new(ep.scene.load_model()?);
    let mut art = umpnet_sim::physics::Articulation::new(
        model,
        ep.scene.world_from_base(),
        Default::default(),
    );
    art.set_joint_positions(&ep.scene.joints)?;
    let (truth, _) = art.joint_axis_in_world(j);
    let kind = if err.prismatic {
        "prismatic"
    } else {
        "revolute"
    };
    let looks = match (err.prismatic, err.looks_prismatic) {
        (false, true) => " (the moves alone look like a slide's: the hinge turned little)",
        (true, false) => " (the moves alone do not line up as a slide's)",
        _ => "",
    };
    outln!(
        "joint axis ({kind}, from {} moves): inferred ({:.3}, {:.3}, {:.3}), true ({:.3}, {:.3}, {:.3}), {:.1} deg apart{looks}",
        dirs.len(),
        axis.x,
        axis.y,
        axis.z,
        truth.x,
        truth.y,
        truth.z,
        err.degrees
    );
    Ok(())
}
