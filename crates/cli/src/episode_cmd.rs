use crate::{Ctx, images, usage};
use anyhow::{Context, Result};
use image::RgbImage;
use std::path::PathBuf;
use umpnet_eval::Policy;
use umpnet_eval::episode::{EpisodeConfig, HookFrame, Step, run_episode};
use umpnet_policy::policy::DirectionFilter;
use umpnet_sim::camera::Camera;
use umpnet_sim::math::Vec3;
use umpnet_sim::render::{Frame, RendererKind, create_renderer};
use umpnet_sim::scene::Task;

/// Most direction actions one episode may take: the paper's budgets are 10
/// to 50, and an episode's curves hold one value per step.
pub const MAX_STEPS: usize = 10_000;

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
    /// A learned policy's direction filter instead of its package's: none,
    /// normal90 (within 90 degrees of the surface normal) or prev90 (within
    /// 90 degrees of the previous action, the paper's +HP; exploration only).
    #[arg(long, value_parser = crate::choice::<DirectionFilter>(crate::DIRECTION_FILTERS))]
    pub direction_filter: Option<DirectionFilter>,
    #[command(flatten)]
    pub sampler: crate::policies::SamplerArgs,
    /// Model package for --policy umpnet (default: models/umpnet-small).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Image size as HEIGHTxWIDTH (rows x columns); a learned policy uses its
    /// model's.
    #[arg(long, default_value = "240x320", value_parser = crate::parse_resolution)]
    pub resolution: (u32, u32),
    /// Renderer: wgpu (a GPU, or Vulkan's CPU driver), cpu (built in), or auto
    /// (wgpu when an adapter exists, else cpu, with a notice).
    #[arg(long, default_value = "auto", value_parser = crate::choice::<RendererKind>(crate::RENDERERS))]
    pub renderer: RendererKind,
    /// Write one PNG per step, a contact sheet and an animated GIF here.
    #[arg(long)]
    pub out: Option<PathBuf>,
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
        a.direction_filter,
        a.sampler.sampler(),
    )?;
    let mut policy: Box<dyn Policy> = match resolved.factories.first() {
        Some((_, make)) => make()?,
        None => return Err(usage("--policy is empty")),
    };
    // One policy: a learned one sees its package's input resolution.
    let resolution = resolved
        .resolutions
        .values()
        .next()
        .copied()
        .unwrap_or(a.resolution);
    let scene = a.object.scene(task)?;
    let budget = a
        .steps
        .unwrap_or_else(|| a.protocol.budget(task, scene.category));
    let camera = Camera::reference(resolution.0, resolution.1);
    let mut recorder = match &a.rrd {
        Some(path) => Some(crate::rrd::Recorder::create(
            path,
            &format!("{} {:?}, seed {}", a.policy, task, a.object.seed),
        )?),
        None => None,
    };
    let mut record_error: Option<anyhow::Error> = None;
    let mut pictures: Vec<RgbImage> = Vec::new();
    let mut hook = |h: &HookFrame<'_>| {
        if a.out.is_some() {
            pictures.push(step_picture(h.frame, h.t, h.step, h.pixel));
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
    if let Some(out) = &a.out {
        std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
        for (t, p) in pictures.iter().enumerate() {
            images::save(p, &out.join(format!("step_{t:02}.png")))?;
        }
        // The goal task's sheet opens with the goal, so each step can be set beside it.
        let mut tiles = Vec::with_capacity(pictures.len() + 1);
        if let Some(goal) = &scene.goal {
            let mut env = umpnet_sim::env::SimEnv::new(
                scene.clone(),
                camera.clone(),
                create_renderer(a.renderer)?,
            )?;
            if let Some(f) = env.render_goal()? {
                let value = goal.joints.get(goal.joint).copied();
                let tile = goal_picture(&f, value);
                images::save(&tile, &out.join("goal.png"))?;
                tiles.push(tile);
            }
        }
        tiles.extend(pictures.iter().cloned());
        images::save(&contact_sheet(&tiles), &out.join("episode.png"))?;
        write_gif(&pictures, &out.join("episode.gif"))?;
    }
    let (ended, why) = end_reason(&ep, task);
    if ctx.json {
        let mut value = serde_json::to_value(&ep)?;
        if let Some(map) = value.as_object_mut() {
            map.insert("ended".into(), ended.into());
        }
        outln!("{value}");
        return Ok(());
    }
    let what = scene
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
        a.object.seed
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
        print_axis_estimate(&ep)?;
    }
    if let Some(out) = &a.out {
        outln!("pictures in {}", out.display());
    }
    Ok(())
}

/// How an episode ended, as a code (`--json`'s `ended`) and in words.
fn end_reason(ep: &umpnet_eval::episode::Episode, task: Task) -> (&'static str, String) {
    let n = ep.steps.len();
    if !ep.valid_position {
        (
            "missed",
            "the grasp is not on a movable part, so no move was made".into(),
        )
    } else if ep.stopped_early {
        (
            "policy_stopped",
            format!("the policy stopped after {n} steps"),
        )
    } else if ep.ended_by_protocol && task == Task::Goal {
        (
            "goal_reached",
            format!("the goal was reached in {n} of {} steps", ep.budget),
        )
    } else if ep.ended_by_protocol {
        (
            "joint_limit",
            format!(
                "the part reached a joint limit after {n} steps (the paper's protocol ends exploration there)"
            ),
        )
    } else if !ep.steps.iter().any(|s| s.record.labels.moved) {
        (
            "no_effect",
            format!("all {} steps spent, none of them moved the part", ep.budget),
        )
    } else {
        ("budget", format!("all {} steps spent", ep.budget))
    }
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
    let model = std::sync::Arc::new(ep.scene.object.load()?);
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

/// Candidate arrows drawn per step: the most promising ones, not a blur of all.
const SHOWN_CANDIDATES: usize = 8;
const GRASP: [u8; 3] = [255, 40, 40];
const EXECUTED: [u8; 3] = [255, 220, 0];
const FORWARD: [u8; 3] = [40, 200, 60];
const BACKWARD: [u8; 3] = [230, 60, 200];
const NO_MOVE: [u8; 3] = [160, 160, 160];

fn aot_color(aot: Option<&i8>) -> [u8; 3] {
    match aot {
        Some(1) => FORWARD,
        Some(-1) => BACKWARD,
        _ => NO_MOVE,
    }
}

/// One tile: the frame, the grasp, the executed direction and the top
/// candidates, with a caption saying what happened and what was predicted.
fn step_picture(f: &Frame, t: usize, step: Option<&Step>, pixel: (u32, u32)) -> RgbImage {
    let mut img = images::color_image(f);
    let scale = f.width as f32 / 320.0;
    let thick = (2.0 * scale).round().max(1.0) as i32;
    images::draw_disc(
        &mut img,
        (pixel.1 as f32 + 0.5, pixel.0 as f32 + 0.5),
        4.0 * scale.max(0.5),
        GRASP,
    );
    let mut caption = vec![match step {
        None => format!("start: grasp at pixel ({}, {})", pixel.0, pixel.1),
        Some(s) => format!(
            "step {t}: joint {:.2} -> {:.2}",
            s.record.labels.joint_before, s.record.labels.joint_after
        ),
    }];
    if let Some(s) = step {
        // Arrows start where the gripper was when the action began.
        let from = Vec3::from(s.gripper_in_world);
        let mut predicted = None;
        if let Some(c) = &s.candidates {
            let maxd = c.distance.iter().copied().fold(1e-6f32, f32::max);
            let mut order: Vec<usize> = (0..c.directions.len()).collect();
            order.sort_by(|&a, &b| {
                let d = |k: usize| c.distance.get(k).copied().unwrap_or(0.0);
                d(b).total_cmp(&d(a))
            });
            for &k in order.iter().take(SHOWN_CANDIDATES) {
                let (Some(d), Some(dist)) = (c.directions.get(k), c.distance.get(k)) else {
                    continue;
                };
                let length = 0.2 * dist.max(0.0) / maxd;
                images::draw_arrow(
                    &mut img,
                    f,
                    from,
                    Vec3::from(*d),
                    length,
                    aot_color(c.aot.get(k)),
                    1,
                );
            }
            // The executed direction's own prediction, if it is a candidate.
            predicted = c
                .index_of(Vec3::from(s.record.direction))
                .and_then(|k| Some((*c.distance.get(k)?, *c.aot.get(k)?)));
        }
        images::draw_arrow(
            &mut img,
            f,
            from,
            Vec3::from(s.record.direction),
            0.25,
            EXECUTED,
            thick + 1,
        );
        // The network's AoT is relative to its reference image (the goal, in
        // the goal task); the simulator's labels to the episode's start.
        caption.push(match predicted {
            Some((d, aot)) => format!("predicted d {d:.2}, AoT {aot:+} vs reference"),
            None => "predicted: -".to_owned(),
        });
        caption.push(format!(
            "actual d {:.2}, AoT {:+} vs start",
            s.record.labels.r_dist, s.record.labels.aot
        ));
    } else {
        caption.extend([String::new(), String::new()]);
    }
    crate::text::with_caption(&images::enlarge(&img, 320), &caption)
}

/// The goal observation as a tile, captioned like the steps.
fn goal_picture(f: &Frame, goal_value: Option<f32>) -> RgbImage {
    let img = images::enlarge(&images::color_image(f), 320);
    let line = goal_value.map_or(String::new(), |v| format!("joint at the goal {v:.2}"));
    crate::text::with_caption(&img, &["goal".to_owned(), line, String::new()])
}

/// The tiles in a grid, then a legend of the marks.
fn contact_sheet(pics: &[RgbImage]) -> RgbImage {
    let Some(first) = pics.first() else {
        return RgbImage::new(1, 1);
    };
    let cols = (pics.len() as f32).sqrt().ceil() as u32;
    let rows = (pics.len() as u32).div_ceil(cols);
    let (w, h) = (first.width(), first.height());
    let legend_h = 28;
    let mut sheet = RgbImage::from_pixel(
        (cols * w).max(640),
        rows * h + legend_h,
        image::Rgb([255, 255, 255]),
    );
    for (i, p) in pics.iter().enumerate() {
        image::imageops::overlay(
            &mut sheet,
            p,
            ((i as u32 % cols) * w) as i64,
            ((i as u32 / cols) * h) as i64,
        );
    }
    let y = (rows * h) as f32 + 14.0;
    let mut x = 8.0;
    for (color, label, arrow) in [
        (GRASP, "grasp", false),
        (EXECUTED, "executed", true),
        (FORWARD, "candidate: forward", true),
        (BACKWARD, "backward", true),
        (NO_MOVE, "no change", true),
    ] {
        if arrow {
            images::draw_line(&mut sheet, (x, y), (x + 18.0, y), color, 3);
        } else {
            images::draw_disc(&mut sheet, (x + 8.0, y), 5.0, color);
        }
        x += 24.0;
        crate::text::draw(&mut sheet, x, y - 8.0, 14.0, label, [30, 30, 30]);
        x += crate::text::width(label, 14.0) + 16.0;
    }
    sheet
}

fn write_gif(pics: &[RgbImage], path: &std::path::Path) -> Result<()> {
    let mut bytes = Vec::new();
    let mut enc = image::codecs::gif::GifEncoder::new_with_speed(&mut bytes, 10);
    enc.set_repeat(image::codecs::gif::Repeat::Infinite)?;
    for p in pics {
        let rgba = image::DynamicImage::ImageRgb8(p.clone()).to_rgba8();
        enc.encode_frame(image::Frame::from_parts(
            rgba,
            0,
            0,
            image::Delay::from_numer_denom_ms(600, 1),
        ))?;
    }
    drop(enc);
    Ok(umpnet_sim::fsio::write_atomic(path, &bytes)?)
}
