//! The 10-channel observation built from what a real RGB-D camera gives:
//! colour, depth, intrinsics and the camera pose. Channels: world xyz (3),
//! rgb in [0, 1] (3), surface normal facing the camera (3), depth in metres (1).
use crate::error::{PolicyError, Result};
use nalgebra::{Matrix4, Point3, Vector3};
use ndarray::Array3;
use rayon::prelude::*;

pub const CHANNELS: usize = 10;

/// A camera frame as plain data; images row-major.
#[derive(Clone, Copy, Debug)]
pub struct CameraFrame<'a> {
    pub width: usize,
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

    fn pose(&self) -> Matrix4<f32> {
        let m = &self.world_from_camera;
        Matrix4::from_fn(|r, c| m[r][c])
    }

    fn valid_depth(&self, i: usize) -> Option<f32> {
        let d = self.depth[i];
        (d.is_finite() && d > 0.0).then_some(d)
    }

    /// Pixel centre back-projected to the world frame.
    pub fn point_in_world(&self, row: usize, col: usize) -> Option<Vector3<f32>> {
        let d = self.valid_depth(row * self.width + col)?;
        let [fx, fy, cx, cy] = self.intrinsics;
        let p = Point3::new(
            (col as f32 + 0.5 - cx) / fx * d,
            (row as f32 + 0.5 - cy) / fy * d,
            d,
        );
        Some(self.pose().transform_point(&p).coords)
    }

    pub fn camera_position(&self) -> Vector3<f32> {
        let m = &self.world_from_camera;
        Vector3::new(m[0][3], m[1][3], m[2][3])
    }
}

/// Builds the H x W x 10 observation. Normals come from the depth image: the
/// cross product of the horizontal and vertical differences, each taken
/// toward the neighbour closer in depth so that edges do not bleed.
pub fn build_observation(frame: &CameraFrame) -> Result<Array3<f32>> {
    frame.validate()?;
    let (h, w) = (frame.height, frame.width);
    let m = &frame.world_from_camera;
    let [fx, fy, cx, cy] = frame.intrinsics;
    let (ifx, ify) = (1.0 / fx, 1.0 / fy);
    let eye = [m[0][3], m[1][3], m[2][3]];
    // Pass 1: world points, colour and depth; rows in parallel.
    let mut out = vec![0f32; h * w * CHANNELS];
    let mut points = vec![[0f32; 3]; h * w];
    let mut valid = vec![false; h * w];
    out.par_chunks_mut(w * CHANNELS)
        .zip(points.par_chunks_mut(w))
        .zip(valid.par_chunks_mut(w))
        .enumerate()
        .for_each(|(r, ((out_row, points_row), valid_row))| {
            let yc = (r as f32 + 0.5 - cy) * ify;
            for c in 0..w {
                let i = r * w + c;
                let o = &mut out_row[c * CHANNELS..(c + 1) * CHANNELS];
                for k in 0..3 {
                    o[3 + k] = frame.rgb[i * 3 + k] as f32 * (1.0 / 255.0);
                }
                let d = frame.depth[i];
                if !(d.is_finite() && d > 0.0) {
                    continue;
                }
                let p_cam = [(c as f32 + 0.5 - cx) * ifx * d, yc * d, d];
                let mut p = [0f32; 3];
                for (k, pk) in p.iter_mut().enumerate() {
                    *pk = m[k][0] * p_cam[0] + m[k][1] * p_cam[1] + m[k][2] * p_cam[2] + m[k][3];
                }
                o[..3].copy_from_slice(&p);
                o[9] = d;
                points_row[c] = p;
                valid_row[c] = true;
            }
        });
    // Pass 2: normals from neighbouring points; rows in parallel.
    let sub = |a: [f32; 3], b: [f32; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let (points, valid) = (&points, &valid);
    out.par_chunks_mut(w * CHANNELS)
        .enumerate()
        .for_each(|(r, out_row)| {
            for c in 0..w {
                let i = r * w + c;
                if !valid[i] {
                    continue;
                }
                let (p, d0) = (points[i], frame.depth[i]);
                // Difference toward the neighbour closer in depth, signed as "after minus before".
                let diff = |before: Option<usize>, after: Option<usize>| -> Option<[f32; 3]> {
                    let b = before.filter(|&j| valid[j]);
                    let a = after.filter(|&j| valid[j]);
                    match (b, a) {
                        (Some(j), Some(k))
                            if (frame.depth[j] - d0).abs() <= (frame.depth[k] - d0).abs() =>
                        {
                            Some(sub(p, points[j]))
                        }
                        (_, Some(k)) => Some(sub(points[k], p)),
                        (Some(j), None) => Some(sub(p, points[j])),
                        (None, None) => None,
                    }
                };
                let dx = diff((c > 0).then(|| i - 1), (c + 1 < w).then(|| i + 1));
                let dy = diff((r > 0).then(|| i - w), (r + 1 < h).then(|| i + w));
                let (Some(a), Some(b)) = (dx, dy) else {
                    continue;
                };
                let mut n = [
                    a[1] * b[2] - a[2] * b[1],
                    a[2] * b[0] - a[0] * b[2],
                    a[0] * b[1] - a[1] * b[0],
                ];
                let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                if len <= 0.0 {
                    continue;
                }
                let to_eye = sub(eye, p);
                let sign = if n[0] * to_eye[0] + n[1] * to_eye[1] + n[2] * to_eye[2] < 0.0 {
                    -1.0
                } else {
                    1.0
                };
                for v in &mut n {
                    *v *= sign / len;
                }
                out_row[c * CHANNELS + 6..c * CHANNELS + 9].copy_from_slice(&n);
            }
        });
    Array3::from_shape_vec((h, w, CHANNELS), out)
        .map_err(|e| PolicyError::Input(format!("observation shape: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

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
    pub width: usize,
    pub height: usize,
    pub rgb: Vec<u8>,
    pub depth: Vec<f32>,
    pub intrinsics: [f32; 4],
    pub world_from_camera: [[f32; 4]; 4],
}

impl OwnedFrame {
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

pub fn resize_nearest(frame: &CameraFrame, height: usize, width: usize) -> Result<OwnedFrame> {
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
