use crate::{Ctx, images, usage};
use anyhow::{Context, Result};
use image::RgbImage;
use std::path::PathBuf;
use umpnet_eval::Policy;
use umpnet_eval::episode::{EpisodeConfig, Step, run_episode};
use umpnet_sim::camera::Camera;
use umpnet_sim::math::Vec3;
use umpnet_sim::render::{Frame, RendererKind, create_renderer};
use umpnet_sim::scene::Task;

#[derive(clap::Args)]
pub struct EpisodeArgs {
    #[command(flatten)]
    pub object: crate::ObjectArgs,
    /// Number of direction actions (default: the protocol's budget).
    #[arg(long)]
    pub steps: Option<usize>,
    /// Evaluation protocol: paper (the paper's evaluation code) or strict.
    #[arg(long, default_value = "paper", value_parser = crate::choice::<umpnet_eval::Protocol>(crate::PROTOCOLS))]
    pub protocol: umpnet_eval::Protocol,
    /// random, oracle, umpnet (with --model) or NAME=MODEL_DIR.
    #[arg(long, default_value = "oracle")]
    pub policy: String,
    /// Model package for --policy umpnet (default: models/umpnet-small).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Image size; a learned policy uses its model's.
    #[arg(long, default_value = "240x320", value_parser = crate::parse_resolution)]
    pub resolution: (u32, u32),
    #[arg(long, default_value = "auto", value_parser = crate::choice::<RendererKind>(crate::RENDERERS))]
    pub renderer: RendererKind,
    /// Write one PNG per step, a contact sheet and an animated GIF here.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run(ctx: &Ctx, a: &EpisodeArgs, task: Task) -> Result<()> {
    let resolved =
        crate::policies::resolve(std::slice::from_ref(&a.policy), a.model.as_deref(), 1, task)?;
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
    let mut pictures: Vec<RgbImage> = Vec::new();
    let mut hook = |t: usize, f: &Frame, step: Option<&Step>, pixel: (u32, u32)| {
        pictures.push(step_picture(f, t, step, pixel));
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
        if a.out.is_some() {
            Some(&mut hook)
        } else {
            None
        },
    )?;
    if let Some(out) = &a.out {
        std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
        for (t, p) in pictures.iter().enumerate() {
            images::save(p, &out.join(format!("step_{t:02}.png")))?;
        }
        images::save(&contact_sheet(&pictures), &out.join("episode.png"))?;
        write_gif(&pictures, &out.join("episode.gif"))?;
    }
    if ctx.json {
        println!("{}", serde_json::to_string(&ep)?);
        return Ok(());
    }
    let what = scene
        .category
        .map(|c| c.name().to_owned())
        .unwrap_or_else(|| "object".into());
    println!(
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
    println!(
        "position: pixel (row {}, col {}) -> {grasped}",
        ep.pixel.0, ep.pixel.1
    );
    println!(
        "{:>4}  {:>24}  {:>9}  {:>9}  {:>4}",
        "step", "direction (world)", "joint", "change", "AoT"
    );
    for (t, s) in ep.steps.iter().enumerate() {
        let d = s.record.direction;
        let l = &s.record.labels;
        println!(
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
    if ep.stopped_early {
        println!("policy stopped after {} steps", ep.steps.len());
    }
    let m = &ep.metrics;
    match task {
        Task::Exploration => println!(
            "novel-state ratio {:.3}  single action effect {:.3}  unique states {}",
            m.novel_state_ratio,
            m.single_action_effect,
            m.unique_states.last().copied().unwrap_or(0.0)
        ),
        Task::Goal => println!(
            "normalized distance {:.3}  success {}",
            m.normalized_distance, m.success
        ),
    }
    if task == Task::Exploration {
        print_axis_estimate(&ep)?;
    }
    if let Some(out) = &a.out {
        println!("pictures in {}", out.display());
    }
    Ok(())
}

/// The paper's joint-axis inference from the executed directions, against the truth.
fn print_axis_estimate(ep: &umpnet_eval::episode::Episode) -> Result<()> {
    use nalgebra::Vector3;
    use umpnet_policy::axis::{JointEstimate, axis_angle_deg, infer_joint};
    let moved: Vec<&Step> = ep.steps.iter().filter(|s| s.record.labels.moved).collect();
    let dirs: Vec<Vector3<f32>> = moved
        .iter()
        .map(|s| Vector3::from(s.record.direction))
        .collect();
    let pts: Vec<Vector3<f32>> = moved
        .iter()
        .map(|s| Vector3::from(s.gripper_in_world))
        .collect();
    let (Some(est), Some(j)) = (infer_joint(&dirs, &pts), ep.joint) else {
        println!("joint axis: too few effective actions to infer");
        return Ok(());
    };
    let model = std::sync::Arc::new(ep.scene.object.load()?);
    let mut art = umpnet_sim::physics::Articulation::new(
        model.clone(),
        ep.scene.world_from_base(),
        Default::default(),
    );
    art.set_joint_positions(&ep.scene.joints)?;
    let (true_axis, _) = art.joint_axis_in_world(j);
    let truth = Vector3::new(true_axis.x, true_axis.y, true_axis.z);
    let (kind, axis) = match &est {
        JointEstimate::Prismatic { axis } => ("prismatic", axis),
        JointEstimate::Revolute { axis, .. } => ("revolute", axis),
    };
    let true_kind = if model.joints.get(j).is_some_and(|jm| jm.kind.is_prismatic()) {
        "prismatic"
    } else {
        "revolute"
    };
    println!(
        "joint axis: inferred {kind} ({:.3}, {:.3}, {:.3}); true {true_kind} ({:.3}, {:.3}, {:.3}); angle error {:.1} deg",
        axis[0],
        axis[1],
        axis[2],
        truth.x,
        truth.y,
        truth.z,
        axis_angle_deg(&Vector3::from(*axis), &truth)
    );
    Ok(())
}

fn step_picture(f: &Frame, t: usize, step: Option<&Step>, pixel: (u32, u32)) -> RgbImage {
    let mut img = images::color_image(f);
    let scale = f.width as f32 / 320.0;
    let thick = (2.0 * scale).round().max(1.0) as i32;
    images::draw_disc(
        &mut img,
        (pixel.1 as f32 + 0.5, pixel.0 as f32 + 0.5),
        4.0 * scale.max(0.5),
        [255, 40, 40],
    );
    if let Some(s) = step {
        // Arrows start where the gripper was when the action began.
        let from = Vec3::from(s.gripper_in_world);
        if let Some(c) = &s.candidates {
            let maxd = c.distance.iter().copied().fold(1e-6f32, f32::max);
            for (k, d) in c.directions.iter().enumerate() {
                let color = match c.aot.get(k) {
                    Some(1) => [40, 200, 60],
                    Some(-1) => [230, 60, 200],
                    _ => [160, 160, 160],
                };
                let length = 0.2 * c.distance.get(k).copied().unwrap_or(0.0).max(0.0) / maxd;
                images::draw_arrow(&mut img, f, from, Vec3::from(*d), length, color, 1);
            }
        }
        images::draw_arrow(
            &mut img,
            f,
            from,
            Vec3::from(s.record.direction),
            0.25,
            [255, 220, 0],
            thick + 1,
        );
    }
    let _ = t;
    images::enlarge(&img, 320)
}

fn contact_sheet(pics: &[RgbImage]) -> RgbImage {
    let Some(first) = pics.first() else {
        return RgbImage::new(1, 1);
    };
    let cols = (pics.len() as f32).sqrt().ceil() as u32;
    let rows = (pics.len() as u32).div_ceil(cols);
    let (w, h) = (first.width(), first.height());
    let mut sheet = RgbImage::from_pixel(cols * w, rows * h, image::Rgb([255, 255, 255]));
    for (i, p) in pics.iter().enumerate() {
        image::imageops::overlay(
            &mut sheet,
            p,
            ((i as u32 % cols) * w) as i64,
            ((i as u32 / cols) * h) as i64,
        );
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
