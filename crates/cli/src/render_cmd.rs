use crate::{Ctx, images};
use anyhow::{Context, Result};
use std::path::PathBuf;
use umpnet_sim::env::SimEnv;
use umpnet_sim::render::{RendererKind, create_renderer};

#[derive(clap::Args)]
pub struct RenderArgs {
    #[command(flatten)]
    pub object: crate::ObjectArgs,
    #[arg(long, default_value = "480x640", value_parser = crate::parse_resolution)]
    pub resolution: (u32, u32),
    #[arg(long, default_value = "auto")]
    pub renderer: RendererKind,
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(ctx: &Ctx, a: &RenderArgs) -> Result<()> {
    let scene = a.object.scene(umpnet_sim::scene::Task::Exploration)?;
    let camera = umpnet_sim::camera::Camera::reference(a.resolution.0, a.resolution.1);
    let mut env = SimEnv::new(scene.clone(), camera.clone(), create_renderer(a.renderer)?)?;
    let f = env.render()?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    images::save(&images::color_image(&f), &a.out.join("color.png"))?;
    let (depth, lo, hi) = images::depth_image(&f);
    images::save(&depth, &a.out.join("depth.png"))?;
    images::save(
        &images::segmentation_image(&f),
        &a.out.join("segmentation.png"),
    )?;
    images::save(&images::normal_image(&f), &a.out.join("normals.png"))?;
    let cam = serde_json::json!({
        "width": f.width, "height": f.height,
        "intrinsics": {"fx": f.intrinsics.fx, "fy": f.intrinsics.fy, "cx": f.intrinsics.cx, "cy": f.intrinsics.cy},
        "world_from_camera": f.world_from_camera.to_mat4().transpose().to_cols_array_2d(),
        "depth_range_m": [lo, hi], "renderer": env.renderer_name(), "scene": scene,
    });
    umpnet_sim::fsio::write_atomic(
        &a.out.join("camera.json"),
        serde_json::to_string_pretty(&cam)?.as_bytes(),
    )?;
    let depth_bytes: Vec<u8> = f.depth.iter().flat_map(|d| d.to_le_bytes()).collect();
    write_npy_f32(
        &a.out.join("depth.npy"),
        &[f.height as usize, f.width as usize],
        &depth_bytes,
    )?;
    if ctx.json {
        println!(
            "{}",
            serde_json::json!({"out": a.out, "renderer": env.renderer_name(), "depth_range_m": [lo, hi]})
        );
    } else {
        println!(
            "wrote color.png depth.png ({lo:.2}-{hi:.2} m) segmentation.png normals.png depth.npy camera.json to {} ({})",
            a.out.display(),
            env.renderer_name()
        );
    }
    Ok(())
}

/// Minimal .npy (v1.0) writer for little-endian f32 arrays.
pub fn write_npy_f32(path: &std::path::Path, shape: &[usize], data: &[u8]) -> Result<()> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape_s = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape_s}, }}");
    let total = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - total % 64) % 64));
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend_from_slice(data);
    Ok(umpnet_sim::fsio::write_atomic(path, &out)?)
}
