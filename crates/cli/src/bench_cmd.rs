use crate::Ctx;
use anyhow::Result;
use std::time::Instant;
use umpnet_eval::learned::camera_frame;
use umpnet_eval::scripted::OraclePolicy;
use umpnet_eval::{Decision, Observation, Policy};
use umpnet_policy::build_observation;
use umpnet_sim::camera::Camera;
use umpnet_sim::env::{Pick, SimEnv};
use umpnet_sim::objects::Category;
use umpnet_sim::physics::PhysicsProfile;
use umpnet_sim::render::{RendererKind, create_renderer};
use umpnet_sim::scene::Task;

/// A count of timed repetitions: a median needs at least one.
fn at_least_one(s: &str) -> std::result::Result<usize, String> {
    match s.trim().parse::<u64>() {
        Ok(n) if (1..=100_000).contains(&n) => Ok(n as usize),
        _ => Err("expected a count from 1 to 100000".into()),
    }
}

#[derive(clap::Args)]
pub struct BenchArgs {
    /// Frames per renderer figure (1 to 100000).
    #[arg(long, default_value_t = 40, value_parser = at_least_one)]
    pub frames: usize,
    /// Actions per physics figure (1 to 100000).
    #[arg(long, default_value_t = 300, value_parser = at_least_one)]
    pub actions: usize,
    /// Measure this URDF only (physics in both profiles, observations at both
    /// resolutions): the figures benches/compare_pybullet.py sets beside PyBullet's.
    #[arg(long)]
    pub object: Option<std::path::PathBuf>,
}

fn object_args(
    category: Option<Category>,
    instance: Option<u32>,
    object: Option<&std::path::Path>,
    physics: PhysicsProfile,
) -> crate::ObjectArgs {
    crate::ObjectArgs {
        category,
        object: object.map(std::path::Path::to_path_buf),
        seed: 1,
        instance,
        dataset_seed: 0,
        physics,
        scale: None,
        pose: None,
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// Physics: median time of one 0.18 m action with the oracle's directions (re-grasping after each episode).
fn physics_ms(args: &crate::ObjectArgs, actions: usize) -> Result<f64> {
    let label = args.category.map_or_else(
        || {
            args.object
                .as_ref()
                .map_or(String::new(), |p| p.display().to_string())
        },
        |c| c.name().to_string(),
    );
    let scene = args.scene(Task::Exploration)?;
    let mut env = SimEnv::new(
        scene.clone(),
        Camera::reference(96, 128),
        create_renderer(RendererKind::Cpu)?,
    )?;
    // A fixed action: the pull along the joint's motion, never planned.
    let mut oracle = OraclePolicy::plain();
    let mut times = Vec::with_capacity(actions);
    while times.len() < actions {
        env.reset(scene.clone())?;
        let f = env.render()?;
        let obs = Observation {
            frame: &f,
            reference: &f,
            gripper_in_world: None,
        };
        let px = oracle.position(&obs, &env)?;
        if let Pick::NoMovableLink = env.step_position(&f, px.0, px.1)? {
            anyhow::bail!("oracle found no movable link on the benchmark object {label}");
        }
        for _ in 0..10 {
            let Decision::Move { direction, .. } = oracle.direction(&obs, &env, &[])? else {
                break;
            };
            let t = Instant::now();
            env.step_direction(direction)?;
            times.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    Ok(median(times))
}

/// Largest generated object by triangle count among 20 instances of each category.
fn largest_object() -> (Category, u32, usize) {
    let mut best = (Category::StorageFurniture, 0, 0);
    for &c in Category::ALL {
        for i in 0..20 {
            if let Ok(m) = umpnet_sim::objects::generate(c, i, 0).model() {
                let n: usize = m
                    .links
                    .iter()
                    .flat_map(|l| &l.visuals)
                    .map(|v| v.mesh_in_link.triangles.len())
                    .sum();
                if n > best.2 {
                    best = (c, i, n);
                }
            }
        }
    }
    best
}

/// Median (render + readback, 10-channel tensor, both) in ms.
fn observation_ms(
    args: &crate::ObjectArgs,
    res: (u32, u32),
    kind: RendererKind,
    frames: usize,
) -> Result<((f64, f64, f64), String)> {
    let scene = args.scene(Task::Exploration)?;
    let mut env = SimEnv::new(
        scene,
        Camera::reference(res.0, res.1),
        create_renderer(kind)?,
    )?;
    let _ = env.render()?; // warm-up
    let (mut render, mut tensor, mut total) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..frames {
        let t = Instant::now();
        let f = env.render()?;
        let t1 = Instant::now();
        let obs = build_observation(&camera_frame(&f))?;
        std::hint::black_box(obs);
        render.push((t1 - t).as_secs_f64() * 1e3);
        tensor.push(t1.elapsed().as_secs_f64() * 1e3);
        total.push(t.elapsed().as_secs_f64() * 1e3);
    }
    Ok((
        (median(render), median(tensor), median(total)),
        env.renderer_name(),
    ))
}

pub fn run(ctx: &Ctx, a: &BenchArgs) -> Result<()> {
    let mut rows = Vec::new();
    let physics_objects: Vec<(String, Option<Category>)> = match &a.object {
        Some(p) => vec![(p.display().to_string(), None)],
        None => [
            Category::StorageFurniture,
            Category::Refrigerator,
            Category::Microwave,
        ]
        .iter()
        .map(|c| (c.name().to_string(), Some(*c)))
        .collect(),
    };
    for (label, c) in &physics_objects {
        for (physics, target) in [
            (PhysicsProfile::Reference, 1.0),
            (PhysicsProfile::Ideal, 1.5),
        ] {
            let ms = physics_ms(
                &object_args(*c, None, a.object.as_deref(), physics),
                a.actions,
            )?;
            rows.push(serde_json::json!({"figure": format!("physics per 0.18 m action ({physics})"), "object": label, "renderer": match physics { PhysicsProfile::Reference => "PGS (Bullet's schedule)", PhysicsProfile::Ideal => "rapier3d multibody" }, "median_ms": ms, "target_ms": target}));
        }
    }
    let views: Vec<(crate::ObjectArgs, String)> = match &a.object {
        Some(p) => vec![(
            object_args(None, None, Some(p), PhysicsProfile::default()),
            p.display().to_string(),
        )],
        None => {
            let (big, big_i, tris) = largest_object();
            let cab_i = umpnet_sim::objects::nth_instance(
                Category::StorageFurniture,
                umpnet_sim::objects::InstanceSplit::Test,
                0,
            );
            vec![
                (
                    object_args(
                        Some(Category::StorageFurniture),
                        Some(cab_i),
                        None,
                        PhysicsProfile::default(),
                    ),
                    "cabinet".to_string(),
                ),
                (
                    object_args(Some(big), Some(big_i), None, PhysicsProfile::default()),
                    format!("largest ({big}, {tris} triangles)"),
                ),
            ]
        }
    };
    let gpu = umpnet_sim::render::gpu_available();
    for (kind, frames) in [
        (RendererKind::Wgpu, a.frames),
        (RendererKind::Cpu, a.frames.div_ceil(4)),
    ] {
        if kind == RendererKind::Wgpu && !gpu {
            eprintln!("notice: no wgpu adapter; skipping wgpu figures");
            continue;
        }
        for res in [(480, 640), (120, 160)] {
            for (args, label) in &views {
                let ((render_ms, tensor_ms, ms), name) = observation_ms(args, res, kind, frames)?;
                let target = match (kind, res.0) {
                    (RendererKind::Wgpu, 480) => Some(15.0),
                    (RendererKind::Wgpu, _) => Some(3.0),
                    _ => None,
                };
                rows.push(serde_json::json!({"figure": format!("observation {}x{}", res.0, res.1), "object": label, "renderer": name, "median_ms": ms, "render_ms": render_ms, "tensor_ms": tensor_ms, "target_ms": target}));
            }
        }
    }
    if ctx.json {
        outln!("{}", serde_json::Value::Array(rows));
    } else {
        out!("{}", table(&rows));
    }
    Ok(())
}

/// The figures as a table for the terminal.
fn table(rows: &[serde_json::Value]) -> String {
    // Columns as wide as their longest entry: figure names and
    // renderer strings vary with the profile, the device and the driver.
    let text = |r: &serde_json::Value, k: &str| r[k].as_str().unwrap_or("-").to_string();
    let width = |k: &str, header: &str| {
        rows.iter()
            .map(|r| text(r, k).chars().count())
            .fold(header.len(), usize::max)
    };
    let (wf, wo, wr) = (
        width("figure", "figure"),
        width("object", "object"),
        width("renderer", "renderer"),
    );
    let mut out = format!(
        "{:<wf$} {:<wo$} {:<wr$} {:>9} {:>8} {:>8} {:>7}\n",
        "figure", "object", "renderer", "median ms", "render", "tensor", "target"
    );
    let ms = |r: &serde_json::Value, k: &str| {
        r[k].as_f64()
            .map(|t| format!("{t:.2}"))
            .unwrap_or_else(|| "-".into())
    };
    for r in rows {
        out += &format!(
            "{:<wf$} {:<wo$} {:<wr$} {:>9.3} {:>8} {:>8} {:>7}\n",
            text(r, "figure"),
            text(r, "object"),
            text(r, "renderer"),
            r["median_ms"].as_f64().unwrap_or(f64::NAN),
            ms(r, "render_ms"),
            ms(r, "tensor_ms"),
            ms(r, "target_ms"),
        );
    }
    out
}

#[cfg(test)]
mod tests {
    #![allow(clippy::indexing_slicing, reason = "tests fail by panicking")]
    use super::*;

    #[test]
    fn the_table_keeps_its_columns_whatever_the_lengths() {
        let rows = [
            serde_json::json!({"figure": "physics per 0.18 m action (reference)", "object": "StorageFurniture", "renderer": "PGS (Bullet's schedule)", "median_ms": 0.141, "target_ms": 1.0}),
            serde_json::json!({"figure": "observation 120x160", "object": "largest (Toy, 240 triangles)", "renderer": "wgpu/Vulkan llvmpipe (LLVM 15.0.6, 256 bits) and more", "median_ms": 1.947, "render_ms": 1.52, "tensor_ms": 0.44, "target_ms": 3.0}),
        ];
        let t = table(&rows);
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines.len(), 3, "{t}");
        // Every column starts where its header does.
        for header in ["object", "renderer", "median ms"] {
            let at = lines[0].find(header).expect("header");
            for line in &lines[1..] {
                assert_eq!(
                    line.as_bytes()[at - 1],
                    b' ',
                    "column {header} shifted:\n{t}"
                );
            }
        }
        let end = lines[0].find("median ms").expect("header") + "median ms".len();
        assert!(lines[1][..end].ends_with("0.141"), "{t}");
        assert!(lines[2][..end].ends_with("1.947"), "{t}");
        assert!(
            lines[1].ends_with("1.00") && lines[2].ends_with("3.00"),
            "{t}"
        );
    }
}
