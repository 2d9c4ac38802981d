//! `umpnet infer`: the next action for frames from a real RGB-D camera.
use crate::{Ctx, usage};
use anyhow::{Context, Result, bail};
use nalgebra::Vector3;
use rand::SeedableRng;
use std::path::{Path, PathBuf};
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
    /// Reference (goal) colour image; with it the goal task is solved.
    #[arg(long)]
    pub reference: Option<PathBuf>,
    #[arg(long)]
    pub reference_depth: Option<PathBuf>,
    /// Pixel (row,col) the gripper holds; without it the position action is chosen.
    #[arg(long, value_delimiter = ',')]
    pub grasp: Vec<usize>,
    #[arg(long)]
    pub model: Option<PathBuf>,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

fn read_npy(path: &Path, scale: f32) -> Result<(usize, usize, Vec<f32>)> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        bail!("{}: not a .npy file", path.display());
    }
    // Version 1 has a 2-byte header length at 8; versions 2 and 3 a 4-byte one.
    let (hlen, start): (usize, usize) = match (bytes[6], bytes.get(8..12)) {
        (1, _) => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        (2 | 3, Some(&[a, b, c, d])) => (u32::from_le_bytes([a, b, c, d]) as usize, 12),
        (v, _) => bail!(
            "{}: unsupported or truncated .npy header (version {v}); expected version 1, 2 or 3",
            path.display()
        ),
    };
    let Some(header_bytes) = start
        .checked_add(hlen)
        .and_then(|end| bytes.get(start..end))
    else {
        bail!(
            "{}: truncated .npy file: the header says {hlen} bytes, the file has {}",
            path.display(),
            bytes.len().saturating_sub(start)
        );
    };
    let header = String::from_utf8_lossy(header_bytes);
    let shape_txt = header
        .split("'shape':")
        .nth(1)
        .and_then(|s| s.split(')').next())
        .unwrap_or("");
    let dims: Vec<usize> = shape_txt
        .trim_start_matches([' ', '('])
        .split(',')
        .filter_map(|t| t.trim().parse().ok())
        .collect();
    if dims.len() != 2 || header.contains("'fortran_order': True") {
        bail!(
            "{}: expected a 2-D C-order array, header {header}",
            path.display()
        );
    }
    let data = &bytes[start + hlen..];
    let values: Vec<f32> = if header.contains("<f4") {
        data.chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    } else if header.contains("<u2") {
        data.chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]) as f32 * scale)
            .collect()
    } else {
        bail!(
            "{}: dtype must be <f4 (metres) or <u2 (scaled), header {header}",
            path.display()
        );
    };
    if Some(values.len()) != dims[0].checked_mul(dims[1]) {
        bail!(
            "{}: {} values for shape {dims:?}",
            path.display(),
            values.len()
        );
    }
    Ok((dims[0], dims[1], values))
}

fn load_frame(rgb: &Path, depth: &Path, a: &InferArgs) -> Result<OwnedFrame> {
    let img = image::open(rgb)
        .with_context(|| format!("reading {}", rgb.display()))?
        .to_rgb8();
    let (h, w, d) = if depth.extension().is_some_and(|e| e == "npy") {
        read_npy(depth, a.depth_scale)?
    } else {
        let di = image::open(depth)
            .with_context(|| format!("reading {}", depth.display()))?
            .to_luma16();
        (
            di.height() as usize,
            di.width() as usize,
            di.pixels().map(|p| p.0[0] as f32 * a.depth_scale).collect(),
        )
    };
    if (h, w) != (img.height() as usize, img.width() as usize) {
        return Err(usage(format!(
            "{} is {}x{} but {} is {h}x{w}",
            rgb.display(),
            img.height(),
            img.width(),
            depth.display()
        )));
    }
    let p = &a.camera_pose;
    Ok(OwnedFrame {
        width: w,
        height: h,
        rgb: img.into_raw(),
        depth: d,
        intrinsics: [
            a.intrinsics[0],
            a.intrinsics[1],
            a.intrinsics[2],
            a.intrinsics[3],
        ],
        world_from_camera: [
            [p[0], p[1], p[2], p[3]],
            [p[4], p[5], p[6], p[7]],
            [p[8], p[9], p[10], p[11]],
            [p[12], p[13], p[14], p[15]],
        ],
    })
}

pub fn run(_ctx: &Ctx, a: &InferArgs) -> Result<()> {
    if a.intrinsics.len() != 4 || a.camera_pose.len() != 16 {
        return Err(usage(
            "--intrinsics takes fx,fy,cx,cy and --camera-pose 16 numbers",
        ));
    }
    let model = match &a.model {
        Some(m) => m.clone(),
        None => crate::policies::default_model()?,
    };
    let pkg = ModelPackage::load(&model, 1, 1, None)
        .with_context(|| format!("loading {}", model.display()))?;
    let policy = UmpnetPolicy::new(std::sync::Arc::new(pkg));
    let (mh, mw) = policy.resolution();
    let full = load_frame(&a.rgb, &a.depth, a)?;
    let small = resize_nearest(&full.view(), mh, mw)?;
    let obs = build_observation(&small.view())?;
    let reference = match (&a.reference, &a.reference_depth) {
        (Some(r), Some(d)) => Some(build_observation(
            &resize_nearest(&load_frame(r, d, a)?.view(), mh, mw)?.view(),
        )?),
        (None, None) => None,
        _ => return Err(usage("--reference and --reference-depth go together")),
    };
    let (sy, sx) = (
        full.height as f32 / mh as f32,
        full.width as f32 / mw as f32,
    );
    let pixel_small = if a.grasp.len() == 2 {
        (
            ((a.grasp[0] as f32 + 0.5) / sy) as usize,
            ((a.grasp[1] as f32 + 0.5) / sx) as usize,
        )
    } else {
        policy
            .position(obs.view(), reference.as_ref().map(|r| r.view()))?
            .pixel
    };
    let mode = if reference.is_some() {
        Mode::Goal
    } else {
        Mode::Explore
    };
    let refv = reference.as_ref().unwrap_or(&obs);
    let input = DecisionInput {
        observation: obs.view(),
        reference: refv.view(),
        pixel: pixel_small,
        banned: &[],
        mode,
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(a.seed);
    let r = policy
        .directions(std::slice::from_ref(&input), std::slice::from_mut(&mut rng))?
        .remove(0);
    let pixel_full = (
        ((pixel_small.0 as f32 + 0.5) * sy) as usize,
        ((pixel_small.1 as f32 + 0.5) * sx) as usize,
    );
    let point = CameraFrame::point_in_world(
        &full.view(),
        pixel_full.0.min(full.height - 1),
        pixel_full.1.min(full.width - 1),
    );
    let best = r.direction.and_then(|d| {
        r.candidates
            .iter()
            .position(|c| *c == d)
            .map(|i| (d, r.scores[i]))
    });
    let out = serde_json::json!({
        "pixel": [pixel_full.0, pixel_full.1],
        "point_in_world": point.map(|p| [p.x, p.y, p.z]),
        "mode": mode,
        "direction": best.map(|(d, _): (Vector3<f32>, _)| [d.x, d.y, d.z]),
        "predicted_distance": best.map(|(_, s)| s.distance),
        "predicted_aot": best.map(|(_, s)| s.aot),
        "stop": r.direction.is_none(),
        "model": model,
    });
    println!("{out}");
    Ok(())
}
