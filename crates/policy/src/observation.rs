//! The 10-channel observation built from what a real RGB-D camera gives:
//! colour, depth, intrinsics and the camera pose. Channels: world xyz (3),
//! rgb in [0, 1] (3), surface normal facing the camera (3), depth in metres (1).
#![allow(
    clippy::indexing_slicing,
    reason = "the observation is built at the frame's own width and height"
)]
use crate::error::{PolicyError, Result};
use nalgebra::Vector3;
use ndarray::{Array3, Array4, ArrayView4, Axis};
use rayon::prelude::*;

/// Channels of an observation: xyz, rgb, normal, depth.
pub const CHANNELS: usize = 10;

/// A camera frame as plain data; images row-major.
#[derive(Clone, Copy, Debug)]
pub struct CameraFrame<'a> {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// 3 bytes per pixel.
    pub rgb: &'a [u8],
    /// Metres along the optical axis; 0 (or non-finite) = no measurement.
    pub depth: &'a [f32],
    /// fx, fy, cx, cy (OpenCV convention, pixel centres at +0.5).
    pub intrinsics: [f32; 4],
    /// Camera pose, row-major 4x4, camera frame x right, y down, z forward.
    pub world_from_camera: [[f32; 4]; 4],
}

impl CameraFrame<'_> {
    /// Checks sizes, intrinsics and pose: an error names what is wrong.
    pub fn validate(&self) -> Result<()> {
        let n = self.width * self.height;
        if n == 0 {
            return Err(PolicyError::Input("image has zero pixels".into()));
        }
        if self.rgb.len() != n * 3 {
            return Err(PolicyError::Input(format!(
                "rgb has {} bytes, expected {} ({}x{}x3)",
                self.rgb.len(),
                n * 3,
                self.height,
                self.width
            )));
        }
        if self.depth.len() != n {
            return Err(PolicyError::Input(format!(
                "depth has {} values, expected {} ({}x{})",
                self.depth.len(),
                n,
                self.height,
                self.width
            )));
        }
        let [fx, fy, ..] = self.intrinsics;
        if !(fx > 0.0 && fy > 0.0 && self.intrinsics.iter().all(|v| v.is_finite())) {
            return Err(PolicyError::Input(format!(
                "intrinsics {:?} must be finite with fx, fy > 0",
                self.intrinsics
            )));
        }
        if !self
            .world_from_camera
            .iter()
            .flatten()
            .all(|v| v.is_finite())
        {
            return Err(PolicyError::Input(
                "camera pose has non-finite entries".into(),
            ));
        }
        Ok(())
    }

    fn valid_depth(&self, i: usize) -> Option<f32> {
        let d = self.depth[i];
        (d.is_finite() && d > 0.0).then_some(d)
    }

    /// Pixel centre at depth `d`, in the world frame.
    fn back_project(&self, row: usize, col: usize, d: f32) -> [f32; 3] {
        let m = &self.world_from_camera;
        let [fx, fy, cx, cy] = self.intrinsics;
        let x = (col as f32 + 0.5 - cx) * (1.0 / fx) * d;
        let y = (row as f32 + 0.5 - cy) * (1.0 / fy) * d;
        [0, 1, 2].map(|k| m[k][0] * x + m[k][1] * y + m[k][2] * d + m[k][3])
    }

    /// Pixel centre back-projected to the world frame.
    pub fn point_in_world(&self, row: usize, col: usize) -> Option<Vector3<f32>> {
        let d = self.valid_depth(row * self.width + col)?;
        Some(Vector3::from(self.back_project(row, col, d)))
    }

    /// The camera's centre in the world frame.
    pub fn camera_position(&self) -> Vector3<f32> {
        let m = &self.world_from_camera;
        Vector3::new(m[0][3], m[1][3], m[2][3])
    }
}

/// Rows per parallel task: each band back-projects its rows plus one above
/// and one below, so bands share nothing and the overlap costs 2/BAND.
const BAND: usize = 16;

/// The world point (channels 0 to 2) of pixel (row, col) of an H x W x 10
/// observation; the caller keeps the pixel inside it.
pub(crate) fn point_at(
    observation: &ndarray::ArrayView3<'_, f32>,
    (r, c): (usize, usize),
) -> Vector3<f32> {
    Vector3::new(
        observation[[r, c, 0]],
        observation[[r, c, 1]],
        observation[[r, c, 2]],
    )
}

/// The channels that hold a world x (the point's and the normal's): the ones
/// a left-right mirror negates.
pub const MIRRORED_CHANNELS: [usize; 2] = [0, 6];

/// A batch of observations (B x H x W x 10) mirrored left-right: columns
/// reversed, and the world's x (position and normal) negated. The benchmark
/// camera sits in the plane x = 0, so this is the same scene mirrored. It is
/// the one mirror: the runtime's `--mirror-average` calls it here, and
/// training (`train --mirror`, the fine-tune's `--mirror`) through the Python
/// binding, so the two cannot disagree on which channels flip.
pub fn mirrored_observations(obs: ArrayView4<'_, f32>) -> Result<Array4<f32>> {
    if obs.dim().3 != CHANNELS {
        return Err(PolicyError::Input(format!(
            "observations {:?}: expected (N, H, W, {CHANNELS})",
            obs.shape()
        )));
    }
    // In standard (row-major) layout: `to_owned` of the reversed view would
    // keep its memory order, and callers read the raw buffer.
    let mut m = obs
        .slice(ndarray::s![.., .., ..;-1, ..])
        .as_standard_layout()
        .into_owned();
    for ch in MIRRORED_CHANNELS {
        m.index_axis_mut(Axis(3), ch).mapv_inplace(|v| -v);
    }
    Ok(m)
}

/// Builds the H x W x 10 observation. Normals come from the depth image: the
/// cross product of the horizontal and vertical differences, each taken
/// toward the neighbour closer in depth so that edges do not bleed.
pub fn build_observation(frame: &CameraFrame<'_>) -> Result<Array3<f32>> {
    let mut out = vec![0f32; frame.height * frame.width * CHANNELS];
    build_observation_into(frame, &mut out)?;
    Array3::from_shape_vec((frame.height, frame.width, CHANNELS), out)
        .map_err(|e| PolicyError::Input(format!("observation shape: {e}")))
}

/// [`build_observation`] into a caller's buffer (H x W x 10, row-major), so
/// that a control loop reuses one allocation; every element is overwritten.
pub fn build_observation_into(frame: &CameraFrame<'_>, out: &mut [f32]) -> Result<()> {
    frame.validate()?;
    let (h, w) = (frame.height, frame.width);
    if out.len() != h * w * CHANNELS {
        return Err(PolicyError::Input(format!(
            "output buffer has {} values, expected {} ({h}x{w}x{CHANNELS})",
            out.len(),
            h * w * CHANNELS
        )));
    }
    out.par_chunks_mut(BAND * w * CHANNELS)
        .enumerate()
        .for_each(|(b, band)| observation_band(frame, b * BAND, band));
    Ok(())
}

/// World points (None without depth) of rows `rows`, row-major.
fn points_in_world(frame: &CameraFrame<'_>, rows: std::ops::Range<usize>) -> Vec<Option<[f32; 3]>> {
    let w = frame.width;
    let mut pts = Vec::with_capacity(rows.len() * w);
    for r in rows {
        for c in 0..w {
            pts.push(
                frame
                    .valid_depth(r * w + c)
                    .map(|d| frame.back_project(r, c, d)),
            );
        }
    }
    pts
}

fn observation_band(frame: &CameraFrame<'_>, r0: usize, band: &mut [f32]) {
    let (h, w) = (frame.height, frame.width);
    let rows = band.len() / (w * CHANNELS);
    let p0 = r0.saturating_sub(1);
    let pts = points_in_world(frame, p0..(r0 + rows + 1).min(h));
    let eye: [f32; 3] = frame.camera_position().into();
    let sub = |a: [f32; 3], b: [f32; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let depth = frame.depth;
    for (k, out_row) in band.chunks_exact_mut(w * CHANNELS).enumerate() {
        let r = r0 + k;
        let pr = r - p0; // this row in `pts`
        for (c, o) in out_row.chunks_exact_mut(CHANNELS).enumerate() {
            let i = r * w + c;
            let rgb = &frame.rgb[i * 3..i * 3 + 3];
            o[3] = rgb[0] as f32 * (1.0 / 255.0);
            o[4] = rgb[1] as f32 * (1.0 / 255.0);
            o[5] = rgb[2] as f32 * (1.0 / 255.0);
            let Some(p) = pts[pr * w + c] else {
                o[..3].fill(0.0);
                o[6..].fill(0.0);
                continue;
            };
            o[..3].copy_from_slice(&p);
            o[9] = depth[i];
            let d0 = depth[i];
            // Difference toward the neighbour closer in depth, signed as "after minus before".
            let diff = |before: Option<(usize, usize)>, after: Option<(usize, usize)>| {
                let at = |(j, q): (usize, usize)| pts[q].map(|pt| (depth[j], pt));
                match (before.and_then(at), after.and_then(at)) {
                    (Some((db, pb)), Some((da, _))) if (db - d0).abs() <= (da - d0).abs() => {
                        Some(sub(p, pb))
                    }
                    (_, Some((_, pa))) => Some(sub(pa, p)),
                    (Some((_, pb)), None) => Some(sub(p, pb)),
                    (None, None) => None,
                }
            };
            let q = pr * w + c;
            let dx = diff(
                (c > 0).then(|| (i - 1, q - 1)),
                (c + 1 < w).then(|| (i + 1, q + 1)),
            );
            let dy = diff(
                (r > 0).then(|| (i - w, q - w)),
                (r + 1 < h).then(|| (i + w, q + w)),
            );
            o[6..9].fill(0.0);
            let (Some(a), Some(b)) = (dx, dy) else {
                continue;
            };
            let n = [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ];
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if len > 0.0 {
                let to_eye = sub(eye, p);
                let facing = n[0] * to_eye[0] + n[1] * to_eye[1] + n[2] * to_eye[2];
                let scale = if facing < 0.0 { -1.0 } else { 1.0 } / len;
                o[6] = n[0] * scale;
                o[7] = n[1] * scale;
                o[8] = n[2] * scale;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mirror_image_reverses_columns_and_negates_the_worlds_x() {
        let obs = ndarray::Array4::from_shape_fn((2, 3, 4, 10), |(b, r, c, ch)| {
            (b * 1000 + r * 100 + c * 10 + ch) as f32
        });
        let m = mirrored_observations(obs.view()).unwrap();
        for ((b, r, c, ch), &v) in m.indexed_iter() {
            let was = obs[[b, r, 3 - c, ch]];
            let want = if ch == 0 || ch == 6 { -was } else { was };
            assert_eq!(v, want, "{b} {r} {c} {ch}");
        }
        assert!(m.is_standard_layout());
        assert_eq!(mirrored_observations(m.view()).unwrap(), obs);
        let nine = ndarray::Array4::<f32>::zeros((1, 3, 4, 9));
        let err = mirrored_observations(nine.view()).unwrap_err().to_string();
        assert!(
            err.contains("[1, 3, 4, 9]") && err.contains("(N, H, W, 10)"),
            "{err}"
        );
    }

    #[test]
    fn plane_facing_camera_gives_its_normal() {
        // Camera at the origin looking down +z at a wall 2 m away.
        let (w, h) = (8, 6);
        let rgb = vec![128u8; w * h * 3];
        let depth = vec![2.0f32; w * h];
        let frame = CameraFrame {
            width: w,
            height: h,
            rgb: &rgb,
            depth: &depth,
            intrinsics: [10.0, 10.0, 4.0, 3.0],
            world_from_camera: [
                [1.0, 0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0, 0.0],
                [0.0, 0.0, 1.0, 0.0],
                [0.0, 0.0, 0.0, 1.0],
            ],
        };
        let obs = build_observation(&frame).unwrap();
        assert_eq!(obs.shape(), &[6, 8, 10]);
        for r in 0..h {
            for c in 0..w {
                assert!(
                    (obs[[r, c, 8]] + 1.0).abs() < 1e-5,
                    "normal should face the camera (-z)"
                );
                assert!((obs[[r, c, 2]] - 2.0).abs() < 1e-5 && (obs[[r, c, 9]] - 2.0).abs() < 1e-6);
                assert!((obs[[r, c, 3]] - 128.0 / 255.0).abs() < 1e-6);
            }
        }
        // Reusing a dirty buffer gives the same tensor, holes included: every element is written.
        let mut holed = depth.clone();
        holed[3] = 0.0;
        holed[w * 2 + 5] = f32::NAN;
        let frame_holed = CameraFrame {
            depth: &holed,
            ..frame
        };
        let fresh = build_observation(&frame_holed).unwrap();
        assert_eq!(fresh[[0, 3, 9]], 0.0);
        let mut reused = vec![f32::NAN; h * w * CHANNELS];
        build_observation_into(&frame_holed, &mut reused).unwrap();
        assert_eq!(reused.as_slice(), fresh.as_slice().unwrap());
        let err = build_observation_into(&frame, &mut reused[..5]).unwrap_err();
        assert!(
            err.to_string()
                .contains("output buffer has 5 values, expected 480")
        );
        let bad = CameraFrame {
            rgb: &rgb[..10],
            ..frame
        };
        assert!(
            build_observation(&bad)
                .unwrap_err()
                .to_string()
                .contains("rgb has 10 bytes")
        );
    }
}

/// A frame resized (nearest neighbour) to the model's resolution, with the
/// intrinsics scaled to match; owns its buffers.
#[derive(Clone, Debug)]
pub struct OwnedFrame {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// 3 bytes per pixel.
    pub rgb: Vec<u8>,
    /// Metres along the optical axis; 0 = no measurement.
    pub depth: Vec<f32>,
    /// fx, fy, cx, cy, scaled with the image.
    pub intrinsics: [f32; 4],
    /// Camera pose, row-major 4x4 (unchanged by resizing).
    pub world_from_camera: [[f32; 4]; 4],
}

impl OwnedFrame {
    /// The frame as a [`CameraFrame`] borrowing these buffers.
    pub fn view(&self) -> CameraFrame<'_> {
        CameraFrame {
            width: self.width,
            height: self.height,
            rgb: &self.rgb,
            depth: &self.depth,
            intrinsics: self.intrinsics,
            world_from_camera: self.world_from_camera,
        }
    }
}

/// `frame` at `height` x `width` (nearest neighbour, so depths are never
/// blended across an edge), its intrinsics scaled to match.
pub fn resize_nearest(frame: &CameraFrame<'_>, height: usize, width: usize) -> Result<OwnedFrame> {
    frame.validate()?;
    let (sx, sy) = (
        frame.width as f32 / width as f32,
        frame.height as f32 / height as f32,
    );
    let mut rgb = Vec::with_capacity(width * height * 3);
    let mut depth = Vec::with_capacity(width * height);
    for r in 0..height {
        let sr = (((r as f32 + 0.5) * sy) as usize).min(frame.height - 1);
        for c in 0..width {
            let sc = (((c as f32 + 0.5) * sx) as usize).min(frame.width - 1);
            let i = sr * frame.width + sc;
            rgb.extend_from_slice(&frame.rgb[i * 3..i * 3 + 3]);
            depth.push(frame.depth[i]);
        }
    }
    let [fx, fy, cx, cy] = frame.intrinsics;
    Ok(OwnedFrame {
        width,
        height,
        rgb,
        depth,
        intrinsics: [fx / sx, fy / sy, cx / sx, cy / sy],
        world_from_camera: frame.world_from_camera,
    })
}
