use crate::{Ctx, images};
use anyhow::{Context, Result};
use std::path::PathBuf;
use umpnet_sim::env::SimEnv;
use umpnet_sim::render::{RendererKind, create_renderer};

#[derive(clap::Args)]
pub struct RenderArgs {
    #[command(flatten)]
    pub object: crate::ObjectArgs,
    /// Image size as HEIGHTxWIDTH (rows x columns), e.g. 480x640.
    #[arg(long, default_value = "480x640", value_parser = crate::parse_resolution)]
    pub resolution: (u32, u32),
    #[command(flatten)]
    pub sensor: crate::SensorArgs,
    /// Renderer: wgpu (a GPU, or Vulkan's CPU driver), cpu (built in), or auto
    /// (wgpu when an adapter exists, else cpu, with a notice).
    #[arg(long, default_value = "auto", value_parser = crate::choice::<RendererKind>(crate::RENDERERS))]
    pub renderer: RendererKind,
    /// Folder for color.png, depth.png (for viewing), depth.npy (metres),
    /// depth_mm.png, segmentation.png, normals.png and camera.json.
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(ctx: &Ctx, a: &RenderArgs) -> Result<()> {
    let scene = a.object.scene(umpnet_sim::scene::Task::Exploration)?;
    let camera = a.sensor.camera(a.resolution);
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
        "depth_range_m": [lo, hi], "glass_depth": camera.glass_depth,
        "renderer": env.renderer_name(), "scene": scene,
    });
    umpnet_sim::fsio::write_atomic(
        &a.out.join("camera.json"),
        serde_json::to_string_pretty(&cam)?.as_bytes(),
    )?;
    // Raw depth for `infer` and other tools: float32 metres (.npy) and
    // millimetres in a 16-bit PNG (0 = no depth; farther than 65.535 m saturates).
    let depth_m =
        ndarray::Array2::from_shape_vec((f.height as usize, f.width as usize), f.depth.clone())
            .context("depth buffer does not match the frame size")?;
    let mut npy = Vec::new();
    ndarray_npy::WriteNpyExt::write_npy(&depth_m, &mut npy).context("encoding depth.npy")?;
    umpnet_sim::fsio::write_atomic(&a.out.join("depth.npy"), &npy)?;
    let mm =
        image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(f.width, f.height, |c, r| {
            let d = f.depth.get(f.index(r, c)).copied().unwrap_or(0.0);
            image::Luma([(d * 1000.0).round().clamp(0.0, u16::MAX as f32) as u16])
        });
    let mut png = std::io::Cursor::new(Vec::new());
    mm.write_to(&mut png, image::ImageFormat::Png)
        .context("encoding depth_mm.png")?;
    umpnet_sim::fsio::write_atomic(&a.out.join("depth_mm.png"), png.get_ref())?;
    if ctx.json {
        outln!(
            "{}",
            serde_json::json!({"out": a.out, "renderer": env.renderer_name(), "depth_range_m": [lo, hi]})
        );
    } else {
        outln!(
            "wrote color.png depth.png ({lo:.2}-{hi:.2} m) segmentation.png normals.png depth.npy depth_mm.png camera.json to {} ({})",
            a.out.display(),
            env.renderer_name()
        );
    }
    Ok(())
}
