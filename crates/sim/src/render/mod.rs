//! Offscreen RGB-D + segmentation + normal rendering: a wgpu rasteriser and a
//! CPU ray caster with the same output. Meshes are loaded once per scene;
//! a frame only moves part transforms.
#![allow(
    clippy::indexing_slicing,
    reason = "pixel indices are bounded by the frame's own width and height"
)]
mod cpu;
mod gpu;

pub use cpu::CpuRenderer;
pub use gpu::{GpuRenderer, gpu_available};

use crate::camera::{Camera, Intrinsics};
use crate::error::{Result, SimError};
use crate::math::{Mat4, Pose3, Vec3};
use crate::mesh::TriMesh;
use rayon::prelude::*;

/// Segment ids in [`Frame::segmentation`].
pub const SEG_BACKGROUND: u32 = 0;
/// The floor's segment id.
pub const SEG_PLANE: u32 = 1;
/// The gripper's segment id.
pub const SEG_GRIPPER: u32 = 2;
/// Object links: `SEG_OBJECT_BASE * object_id + link_index` (object ids from 1).
pub const SEG_OBJECT_BASE: u32 = 1 << 16;

/// What a segment id stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Segment {
    /// Nothing was hit.
    Background,
    /// The floor.
    Plane,
    /// The suction gripper.
    Gripper,
    /// A link of an object.
    Link {
        /// The object's id (from 1).
        object: u32,
        /// The link's index in the object's model.
        link: usize,
    },
}

impl Segment {
    /// What a segment id stands for.
    pub fn decode(id: u32) -> Segment {
        match id {
            SEG_BACKGROUND => Segment::Background,
            SEG_PLANE => Segment::Plane,
            SEG_GRIPPER => Segment::Gripper,
            _ => Segment::Link {
                object: id / SEG_OBJECT_BASE,
                link: (id % SEG_OBJECT_BASE) as usize,
            },
        }
    }
    /// The segment id of an object's link.
    pub fn link_id(object: u32, link: usize) -> u32 {
        SEG_OBJECT_BASE * object + link as u32
    }
}

/// A mesh to draw: triangles in the frame of transform slot `part`.
#[derive(Clone, Debug)]
pub struct RenderMesh {
    /// The transform slot that poses it.
    pub part: usize,
    /// Its segment id.
    pub segment: u32,
    /// Linear RGB in [0, 1].
    pub color: [f32; 3],
    /// 1 for an opaque surface. Below 1 the mesh is glass: in the colour
    /// image the nearest glass surface in front of the nearest opaque one is
    /// blended over it with this weight (one layer of glass; panes behind it
    /// do not show). Depth, segmentation and normals report the glass surface
    /// itself, the exact geometry a simulator knows and a suction cup can
    /// grasp; or, for a camera that reads glass otherwise
    /// ([`Camera::glass_depth`](crate::camera::Camera::glass_depth)), what
    /// is behind it or nothing.
    pub opacity: f32,
    /// The triangles, in the part's frame.
    pub mesh: TriMesh,
}

impl RenderMesh {
    /// Whether it is drawn as glass: an [`opacity`](RenderMesh::opacity) below 1.
    pub fn is_glass(&self) -> bool {
        self.opacity < 1.0
    }
}

/// One rendered frame. Images are row-major, `height` rows of `width` pixels.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// RGB, 3 bytes per pixel.
    pub rgb: Vec<u8>,
    /// Distance along the optical axis in metres; 0 where nothing was hit.
    pub depth: Vec<f32>,
    /// Segment id of each pixel ([`Segment::decode`]).
    pub segmentation: Vec<u32>,
    /// Geometric surface normal in world frame, facing the camera (zero on background).
    pub normal_in_world: Vec<[f32; 3]>,
    /// The camera's intrinsics.
    pub intrinsics: Intrinsics,
    /// The camera's pose (x right, y down, z forward).
    pub world_from_camera: Pose3,
}

impl Frame {
    /// The index of pixel (row, col) in the row-major buffers.
    pub fn index(&self, row: u32, col: u32) -> usize {
        (row * self.width + col) as usize
    }

    /// Back-projects a pixel centre with its depth into the world frame.
    pub fn point_in_world(&self, row: u32, col: u32) -> Option<Vec3> {
        if row >= self.height || col >= self.width {
            return None;
        }
        let d = self.depth[self.index(row, col)];
        if d <= 0.0 {
            return None;
        }
        let k = &self.intrinsics;
        let p = Vec3::new(
            (col as f32 + 0.5 - k.cx) / k.fx * d,
            (row as f32 + 0.5 - k.cy) / k.fy * d,
            d,
        );
        Some(self.world_from_camera.transform_point(p))
    }
}

/// Which renderer to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RendererKind {
    /// wgpu: a GPU, or Vulkan's CPU driver (lavapipe).
    Wgpu,
    /// The built-in CPU ray caster, the same output.
    Cpu,
    /// wgpu when an adapter exists, else the CPU renderer (with a notice).
    Auto,
}

impl std::str::FromStr for RendererKind {
    type Err = SimError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "wgpu" | "gpu" => Ok(RendererKind::Wgpu),
            "cpu" => Ok(RendererKind::Cpu),
            "auto" => Ok(RendererKind::Auto),
            _ => Err(SimError::Other(format!(
                "unknown renderer `{s}`; expected wgpu, cpu or auto"
            ))),
        }
    }
}

/// Draws a scene's meshes: colour, depth, segmentation and normals.
pub trait Renderer: Send + Sync {
    /// Renderer and adapter, e.g. "wgpu/Vulkan llvmpipe".
    fn name(&self) -> String;
    /// Replaces the scene's meshes (once per scene).
    fn load(&mut self, meshes: &[RenderMesh]) -> Result<()>;
    /// Renders with the given transform per part slot.
    fn render(&mut self, camera: &Camera, part_transforms: &[Mat4]) -> Result<Frame>;
    /// The wgpu renderer behind this one, which [`render_batch`] records into
    /// a shared submission; None for renderers that draw on their own.
    fn as_gpu_mut(&mut self) -> Option<&mut GpuRenderer> {
        None
    }
}

/// One frame to draw in a [`render_batch`]: a scene's renderer, camera and
/// part transforms.
pub struct RenderRequest<'a> {
    /// The scene's renderer (its meshes loaded).
    pub renderer: &'a mut dyn Renderer,
    /// The camera.
    pub camera: &'a Camera,
    /// Each part slot's world transform.
    pub part_transforms: Vec<Mat4>,
}

/// Renders many scenes at once, each frame equal bit for bit to its
/// renderer's own `render`. The wgpu frames go to the device in one
/// submission, with its lock taken once and one wait (see
/// `gpu::render_gpu_batch`); the others (the CPU renderer) render in parallel
/// across scenes. Frames come back in the order of the requests.
pub fn render_batch(requests: Vec<RenderRequest<'_>>) -> Result<Vec<Frame>> {
    let n = requests.len();
    let mut on_gpu = Vec::new();
    let mut on_own = Vec::new();
    for (i, r) in requests.into_iter().enumerate() {
        // Asked twice: a borrow returned from the first call would be held
        // over the `else` branch.
        if r.renderer.as_gpu_mut().is_some() {
            if let Some(g) = r.renderer.as_gpu_mut() {
                on_gpu.push((i, g, r.camera, r.part_transforms));
            }
        } else {
            on_own.push((i, r));
        }
    }
    let mut frames: Vec<Option<Frame>> = (0..n).map(|_| None).collect();
    let gpu_frames = gpu::render_gpu_batch(
        on_gpu
            .iter_mut()
            .map(|(_, g, camera, t)| (&mut **g, *camera, t.as_slice()))
            .collect(),
    )?;
    for ((i, ..), f) in on_gpu.iter().zip(gpu_frames) {
        frames[*i] = Some(f);
    }
    let own_frames = on_own
        .par_iter_mut()
        .map(|(_, r)| r.renderer.render(r.camera, &r.part_transforms))
        .collect::<Result<Vec<_>>>()?;
    for ((i, _), f) in on_own.iter().zip(own_frames) {
        frames[*i] = Some(f);
    }
    frames
        .into_iter()
        .map(|f| f.ok_or_else(|| SimError::Render("a request was not rendered".into())))
        .collect()
}

/// Creates a renderer; `Auto` falls back to the CPU renderer with a one-line notice on stderr.
pub fn create_renderer(kind: RendererKind) -> Result<Box<dyn Renderer>> {
    match kind {
        RendererKind::Cpu => Ok(Box::new(CpuRenderer::default())),
        RendererKind::Wgpu => Ok(Box::new(GpuRenderer::new()?)),
        RendererKind::Auto => match GpuRenderer::new() {
            Ok(r) => Ok(Box::new(r)),
            Err(e) => {
                static ONCE: std::sync::Once = std::sync::Once::new();
                ONCE.call_once(|| {
                    eprintln!("notice: no GPU adapter ({e}); using the CPU renderer")
                });
                Ok(Box::new(CpuRenderer::default()))
            }
        },
    }
}

/// Both renderers accept images of 1..=4096 pixels a side.
pub(crate) fn check_resolution(camera: &Camera) -> Result<(u32, u32)> {
    let (w, h) = (camera.width, camera.height);
    if w == 0 || h == 0 || w > 4096 || h > 4096 {
        return Err(SimError::Render(format!(
            "resolution {h}x{w} out of range 1..=4096"
        )));
    }
    Ok((w, h))
}

/// Flat shading with one light, shared by both renderers.
pub(crate) fn shade(color: [f32; 3], normal: Vec3) -> [u8; 3] {
    shade_unrounded(color, normal).map(|c| c.round().clamp(0.0, 255.0) as u8)
}

/// [`shade`] before rounding, in 0..=255: glass blends this over the
/// opaque pixel behind it, as the rasteriser's blend unit does.
fn shade_unrounded(color: [f32; 3], normal: Vec3) -> [f32; 3] {
    let light = Vec3::new(0.3, -0.6, 0.75).normalize();
    let k = 0.35 + 0.65 * normal.dot(light).max(0.0);
    color.map(|c| c * k * 255.0)
}

/// A glass surface's colour over the opaque pixel `behind` (see
/// [`RenderMesh::opacity`]).
pub(crate) fn shade_glass(color: [f32; 3], normal: Vec3, opacity: f32, behind: [u8; 3]) -> [u8; 3] {
    // The rasteriser reads the opacity from a byte of the vertex colour.
    let a = (opacity.clamp(0.0, 1.0) * 255.0).round() / 255.0;
    let front = shade_unrounded(color, normal).map(|c| c.clamp(0.0, 255.0));
    std::array::from_fn(|i| (front[i] * a + f32::from(behind[i]) * (1.0 - a)).round() as u8)
}

pub(crate) const PLANE_COLOR: [f32; 3] = [0.62, 0.6, 0.58];
pub(crate) const GRIPPER_COLOR: [f32; 3] = [0.15, 0.15, 0.18];

/// Side of the square floor, m: the paper's plane (assets/plane100.obj) is
/// 200 m across, so from the fixed camera the floor fills every pixel that
/// the object does not, and no far edge appears in the image.
pub const FLOOR_SIZE: f32 = 200.0;

/// The floor plane as a mesh in world frame (visual only).
pub fn plane_mesh(part: usize) -> RenderMesh {
    let mut m = TriMesh::cuboid(Vec3::new(FLOOR_SIZE, FLOOR_SIZE, 0.0));
    m.triangles
        .retain(|t| t.iter().all(|&i| m.positions[i as usize].z >= 0.0));
    RenderMesh {
        part,
        segment: SEG_PLANE,
        color: PLANE_COLOR,
        opacity: 1.0,
        mesh: m,
    }
}

/// The suction gripper drawn as a cup and a rod along +z of its frame.
pub fn gripper_mesh(part: usize) -> RenderMesh {
    let mut m = TriMesh::cylinder(0.025, 0.03, 16)
        .transformed(&Pose3::from_translation(Vec3::new(0.0, 0.0, 0.015)));
    m.append(
        &TriMesh::cylinder(0.008, 0.25, 8)
            .transformed(&Pose3::from_translation(Vec3::new(0.0, 0.0, 0.155))),
    );
    RenderMesh {
        part,
        segment: SEG_GRIPPER,
        color: GRIPPER_COLOR,
        opacity: 1.0,
        mesh: m,
    }
}
