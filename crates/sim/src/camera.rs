//! The pinhole camera of the protocol, OpenCV convention (x right, y down, z forward).
use crate::math::{Mat3, Pose3, Quat, Vec3};

/// The image sides (pixels) the interfaces accept, for the policy's view and
/// for pictures alike: from 8 (the smallest image normals and a U-Net's
/// pooling make sense of) to 4096 (the renderers' limit).
pub const IMAGE_SIDES: std::ops::RangeInclusive<u32> = 8..=4096;

/// `(height, width)` when both are in [`IMAGE_SIDES`]; taken as `i64`, so that
/// a negative or huge value from Python or the command line is None, not an
/// overflow. Callers word the error for their own flag or argument.
pub fn image_size(height: i64, width: i64) -> Option<(u32, u32)> {
    let side = |v: i64| u32::try_from(v).ok().filter(|v| IMAGE_SIDES.contains(v));
    Some((side(height)?, side(width)?))
}

/// A camera looking from `eye` at `target`: the image size, the field of view
/// and the depth range.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Camera {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Horizontal field of view (degrees).
    pub hfov_deg: f32,
    /// Where the camera is (world frame, m).
    pub eye: [f32; 3],
    /// What it looks at.
    pub target: [f32; 3],
    /// The world direction that is up in the image.
    pub up: [f32; 3],
    /// Nearest depth drawn (m).
    pub near: f32,
    /// Farthest depth drawn (m).
    pub far: f32,
    /// What the depth sensor reads where it looks at glass.
    #[serde(default, skip_serializing_if = "GlassDepth::is_surface")]
    pub glass_depth: GlassDepth,
}

/// What a depth camera reads where it looks through glass (a visual with an
/// opacity below 1). The colour image shows the glass either way.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GlassDepth {
    /// The glass surface itself: depth, segmentation and normals are the
    /// pane's, the exact geometry a simulator knows.
    #[default]
    Surface,
    /// The opaque surface behind it, as an active-stereo or time-of-flight
    /// camera often reads clear glass: depth, segmentation and normals are
    /// those of what the glass lets through (background where nothing is),
    /// so a grasp aimed at a pane lands behind it.
    Through,
    /// No reading, as a camera that returns no depth on glass: depth 0,
    /// background segment and zero normal, like a pixel that sees nothing, so
    /// a grasp aimed at a pane finds no surface.
    Missing,
}

impl std::str::FromStr for GlassDepth {
    type Err = crate::error::SimError;
    fn from_str(s: &str) -> crate::error::Result<Self> {
        match s {
            "surface" => Ok(GlassDepth::Surface),
            "through" => Ok(GlassDepth::Through),
            "missing" => Ok(GlassDepth::Missing),
            _ => Err(crate::error::SimError::Other(format!(
                "unknown glass depth `{s}`; expected surface, through or missing"
            ))),
        }
    }
}

impl GlassDepth {
    /// Its name, as `from_str` reads it.
    pub fn name(self) -> &'static str {
        match self {
            GlassDepth::Surface => "surface",
            GlassDepth::Through => "through",
            GlassDepth::Missing => "missing",
        }
    }

    /// Whether it is the default reading, the pane's own surface (for
    /// `skip_serializing_if`).
    pub fn is_surface(&self) -> bool {
        *self == GlassDepth::Surface
    }
}

/// fx, fy, cx, cy in pixels (pixel centres at integer + 0.5).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Intrinsics {
    /// Focal length in pixels, horizontally.
    pub fx: f32,
    /// Focal length in pixels, vertically.
    pub fy: f32,
    /// Principal point, column.
    pub cx: f32,
    /// Principal point, row.
    pub cy: f32,
}

impl Camera {
    /// The reference camera at a given resolution (height, width).
    pub fn reference(height: u32, width: u32) -> Self {
        Self {
            width,
            height,
            hfov_deg: 69.4,
            eye: [0.0, -2.0, 2.0],
            target: [0.0, 0.0, 0.0],
            up: [0.0, 0.0, 1.0],
            near: 0.01,
            far: 10.0,
            glass_depth: GlassDepth::Surface,
        }
    }

    /// Its pinhole intrinsics (square pixels, principal point at the centre).
    pub fn intrinsics(&self) -> Intrinsics {
        let fx = self.width as f32 / 2.0 / (self.hfov_deg.to_radians() / 2.0).tan();
        Intrinsics {
            fx,
            fy: fx,
            cx: self.width as f32 / 2.0,
            cy: self.height as f32 / 2.0,
        }
    }

    /// Camera pose: maps points in the camera frame to the world frame.
    pub fn world_from_camera(&self) -> Pose3 {
        let eye = Vec3::from(self.eye);
        let forward = (Vec3::from(self.target) - eye).normalize();
        let right = forward.cross(Vec3::from(self.up)).normalize();
        let down = forward.cross(right);
        let rot = Mat3::from_cols(right, down, forward);
        Pose3::from_parts(eye, Quat::from_mat3(&rot))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn target_projects_to_image_centre() {
        let cam = Camera::reference(480, 640);
        let p = cam.world_from_camera().inverse_transform_point(Vec3::ZERO);
        let k = cam.intrinsics();
        assert!((k.fx * p.x / p.z + k.cx - 320.0).abs() < 1e-3);
        assert!((k.fy * p.y / p.z + k.cy - 240.0).abs() < 1e-3);
        // World up appears as image up (negative y).
        let q = cam
            .world_from_camera()
            .inverse_transform_point(Vec3::new(0.0, 0.0, 0.5));
        assert!(q.y / q.z < p.y / p.z);
    }

    #[test]
    fn image_sizes_outside_the_sides_are_refused_without_overflow() {
        assert_eq!(image_size(8, 4096), Some((8, 4096)));
        assert_eq!(image_size(480, 640), Some((480, 640)));
        for (h, w) in [(7, 64), (64, 4097), (-1, 64), (64, 1 << 40), (i64::MIN, 8)] {
            assert_eq!(image_size(h, w), None, "{h}x{w}");
        }
    }
}
