//! The wgpu rasteriser. One device per process (creating one costs far more
//! than a frame), used by one thread at a time: parallel lavapipe devices were
//! seen to corrupt memory under load.
#![allow(
    clippy::indexing_slicing,
    reason = "buffers are sized from the frame and mesh sizes this renderer allocated"
)]
use super::{Frame, RenderMesh, Renderer};
use crate::camera::{Camera, GlassDepth};
use crate::error::{Result, SimError};
use crate::math::{Mat4, Vec3};
use rayon::prelude::*;
use std::sync::{Arc, Mutex, OnceLock};
use wgpu::util::DeviceExt;

/// Part slots: every link an object may have, the floor and the gripper.
/// shader.wgsl holds the same number (checked by a test).
const MAX_PARTS: usize = crate::urdf::MAX_LINKS + 2;
const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DATA_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Uint;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
    /// Opaque meshes, glass depth, then glass colour with the glass's data,
    /// with the opaque surface's data, or with none (see `pipelines`).
    pipelines: [wgpu::RenderPipeline; 5],
    layout: wgpu::BindGroupLayout,
    adapter_name: String,
    /// Serialises all use of the device.
    lock: Mutex<()>,
}

static GPU: OnceLock<std::result::Result<Arc<Gpu>, String>> = OnceLock::new();

fn gpu() -> Result<Arc<Gpu>> {
    GPU.get_or_init(|| init().map(Arc::new))
        .clone()
        .map_err(SimError::Render)
}

/// True when a wgpu adapter can be created here.
pub fn gpu_available() -> bool {
    gpu().is_ok()
}

fn init() -> std::result::Result<Gpu, String> {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
    // Vulkan only, unless WGPU_BACKEND says otherwise (`gl`, `vulkan,gl`): an
    // enabled GL backend initialises EGL in this process, and another EGL
    // user beside us (PyBullet's renderer) then reads stale frames.
    desc.backends = wgpu::Backends::from_env().unwrap_or(wgpu::Backends::VULKAN);
    let instance = wgpu::Instance::new(desc);
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        force_fallback_adapter: false,
        compatible_surface: None,
        ..Default::default()
    }))
    .map_err(|e| format!("no adapter: {e}"))?;
    let info = adapter.get_info();
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("umpnet"),
        required_features: wgpu::Features::empty(),
        required_limits: wgpu::Limits::downlevel_defaults().using_resolution(adapter.limits()),
        ..Default::default()
    }))
    .map_err(|e| format!("no device: {e}"))?;
    let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("umpnet shader"),
        source: wgpu::ShaderSource::Wgsl(include_str!("shader.wgsl").into()),
    });
    let uniform = |binding| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    };
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: None,
        entries: &[uniform(0), uniform(1)],
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: None,
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let pipelines = pipelines(&device, &shader, &pipeline_layout);
    Ok(Gpu {
        adapter_name: format!("{:?} {}", info.backend, info.name),
        device,
        queue,
        pipelines,
        layout,
        lock: Mutex::new(()),
    })
}

/// The opaque pipeline, then those that draw glass over it.
fn pipelines(
    device: &wgpu::Device,
    shader: &wgpu::ShaderModule,
    pipeline_layout: &wgpu::PipelineLayout,
) -> [wgpu::RenderPipeline; 5] {
    // Opaque meshes; then glass in two draws: its nearest depth first (no
    // colour), then its colour blended where the depth is that nearest
    // glass's, so one layer of glass shows whatever order its triangles come in.
    let pipeline = |label,
                    fragment: &str,
                    targets: &[Option<wgpu::ColorTargetState>],
                    depth_write,
                    compare| {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(label),
            layout: Some(pipeline_layout),
            vertex: wgpu::VertexState {
                module: shader,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<Vertex>() as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Uint32, 2 => Uint32, 3 => Uint32],
                })],
            },
            fragment: Some(wgpu::FragmentState {
                module: shader,
                entry_point: Some(fragment),
                compilation_options: Default::default(),
                targets,
            }),
            primitive: wgpu::PrimitiveState { cull_mode: None, ..Default::default() },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(depth_write),
                depth_compare: Some(compare),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            multiview_mask: None,
            cache: None,
        })
    };
    let target = |format: wgpu::TextureFormat, blend, write_mask| {
        Some(wgpu::ColorTargetState {
            format,
            blend,
            write_mask,
        })
    };
    let (all, none) = (wgpu::ColorWrites::ALL, wgpu::ColorWrites::empty());
    let opaque = pipeline(
        "umpnet opaque",
        "fs_main",
        &[
            target(COLOR_FORMAT, None, all),
            target(DATA_FORMAT, None, all),
        ],
        true,
        wgpu::CompareFunction::Less,
    );
    let glass_depth = pipeline(
        "umpnet glass depth",
        "fs_main",
        &[
            target(COLOR_FORMAT, None, none),
            target(DATA_FORMAT, None, none),
        ],
        true,
        wgpu::CompareFunction::Less,
    );
    let glass = |label, fragment, data_writes| {
        pipeline(
            label,
            fragment,
            &[
                target(COLOR_FORMAT, Some(wgpu::BlendState::ALPHA_BLENDING), all),
                target(DATA_FORMAT, None, data_writes),
            ],
            false,
            wgpu::CompareFunction::Equal,
        )
    };
    // The data target (depth, segment, normal) is the glass's own; left as
    // the opaque pass wrote it, for a camera that reads through glass; or
    // cleared (`fs_no_reading`), for one that reads nothing there.
    [
        opaque,
        glass_depth,
        glass("umpnet glass", "fs_main", all),
        glass("umpnet glass colour", "fs_main", none),
        glass("umpnet glass no reading", "fs_no_reading", all),
    ]
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Vertex {
    position: [f32; 3],
    part: u32,
    color: u32,
    segment: u32,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct CameraUniform {
    clip_from_camera: [[f32; 4]; 4],
    camera_from_world: [[f32; 4]; 4],
    eye: [f32; 4],
    light: [f32; 4],
}

struct Targets {
    size: (u32, u32),
    color: wgpu::Texture,
    data: wgpu::Texture,
    depth: wgpu::Texture,
    color_buf: wgpu::Buffer,
    data_buf: wgpu::Buffer,
}

/// A scene's vertex buffer: the opaque meshes' vertices, then the glass's.
#[derive(Clone)]
struct Vertices {
    buffer: wgpu::Buffer,
    opaque: std::ops::Range<u32>,
    glass: std::ops::Range<u32>,
}

/// The wgpu renderer: each frame draws the opaque meshes, then any glass
/// over them, into colour, depth, segment and normal targets, read back to a
/// [`Frame`].
pub struct GpuRenderer {
    gpu: Arc<Gpu>,
    vertices: Option<Vertices>,
    camera_buf: wgpu::Buffer,
    parts_buf: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    targets: Option<Targets>,
}

fn padded(bytes_per_row: u32) -> u32 {
    bytes_per_row.div_ceil(256) * 256
}

impl GpuRenderer {
    /// A renderer on the process's wgpu device (made on first use), or an
    /// error when no adapter exists.
    pub fn new() -> Result<Self> {
        let gpu = gpu()?;
        let device = &gpu.device;
        let camera_buf = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("camera"),
            size: std::mem::size_of::<CameraUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let parts_buf = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("parts"),
            size: (MAX_PARTS * 64) as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &gpu.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: camera_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: parts_buf.as_entire_binding(),
                },
            ],
        });
        Ok(Self {
            gpu,
            vertices: None,
            camera_buf,
            parts_buf,
            bind_group,
            targets: None,
        })
    }

    fn targets(&mut self, width: u32, height: u32) -> &Targets {
        if self.targets.as_ref().map(|t| t.size) != Some((width, height)) {
            let device = &self.gpu.device;
            let tex = |format, usage| {
                device.create_texture(&wgpu::TextureDescriptor {
                    label: None,
                    size: wgpu::Extent3d {
                        width,
                        height,
                        depth_or_array_layers: 1,
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format,
                    usage,
                    view_formats: &[],
                })
            };
            let rt = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
            let buf = |bpp: u32| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: None,
                    size: (padded(width * bpp) * height) as u64,
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            };
            self.targets = Some(Targets {
                size: (width, height),
                color: tex(COLOR_FORMAT, rt),
                data: tex(DATA_FORMAT, rt),
                depth: tex(DEPTH_FORMAT, wgpu::TextureUsages::RENDER_ATTACHMENT),
                color_buf: buf(4),
                data_buf: buf(16),
            });
        }
        match &self.targets {
            Some(t) => t,
            None => unreachable!("the branch above creates the targets"),
        }
    }
}

fn pack_color(c: [f32; 3], opacity: f32) -> u32 {
    let [r, g, b, a] =
        [c[0], c[1], c[2], opacity].map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u32);
    r | (g << 8) | (b << 16) | (a << 24)
}

fn unpack_snorm(v: u32) -> (f32, f32) {
    let lo = (v & 0xFFFF) as u16 as i16;
    let hi = (v >> 16) as u16 as i16;
    (
        (lo as f32 / 32767.0).max(-1.0),
        (hi as f32 / 32767.0).max(-1.0),
    )
}

impl Renderer for GpuRenderer {
    fn name(&self) -> String {
        format!("wgpu/{}", self.gpu.adapter_name)
    }

    fn load(&mut self, meshes: &[RenderMesh]) -> Result<()> {
        let mut verts = Vec::new();
        // Opaque meshes first: glass is drawn over them.
        let opaque = meshes.iter().filter(|m| !m.is_glass());
        let glass = meshes.iter().filter(|m| m.is_glass());
        let mut opaque_vertices = 0;
        for m in opaque.chain(glass) {
            if m.part >= MAX_PARTS {
                return Err(SimError::Render(format!(
                    "part slot {} exceeds the {MAX_PARTS} supported",
                    m.part
                )));
            }
            let color = pack_color(m.color, m.opacity);
            for t in &m.mesh.triangles {
                for &i in t {
                    let p = m.mesh.positions[i as usize];
                    verts.push(Vertex {
                        position: p.to_array(),
                        part: m.part as u32,
                        color,
                        segment: m.segment,
                    });
                }
            }
            if !m.is_glass() {
                opaque_vertices = verts.len() as u32;
            }
        }
        // wgpu panics on a buffer over the device's limit: refuse it here.
        let bytes = (verts.len() as u64).saturating_mul(std::mem::size_of::<Vertex>() as u64);
        let limit = self.gpu.device.limits().max_buffer_size;
        if bytes > limit {
            return Err(SimError::Render(format!(
                "the scene's meshes need {bytes} bytes of vertices ({} triangles); this GPU takes at most {limit} in one buffer (simplify the meshes)",
                verts.len() / 3
            )));
        }
        let _guard = self
            .gpu
            .lock
            .lock()
            .map_err(|_| SimError::Render("renderer lock poisoned".into()))?;
        let buf = self
            .gpu
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("vertices"),
                contents: bytemuck::cast_slice(&verts),
                usage: wgpu::BufferUsages::VERTEX,
            });
        self.vertices = Some(Vertices {
            buffer: buf,
            opaque: 0..opaque_vertices,
            glass: opaque_vertices..verts.len() as u32,
        });
        Ok(())
    }

    fn render(&mut self, camera: &Camera, part_transforms: &[Mat4]) -> Result<Frame> {
        let mut frames = render_gpu_batch(vec![(self, camera, part_transforms)])?;
        frames
            .pop()
            .ok_or_else(|| SimError::Render("the batch returned no frame".into()))
    }

    fn as_gpu_mut(&mut self) -> Option<&mut GpuRenderer> {
        Some(self)
    }
}

/// What a frame recorded into a batch needs to be read back.
struct Recorded {
    width: u32,
    height: u32,
    intrinsics: crate::camera::Intrinsics,
    world_from_camera: crate::math::Pose3,
}

impl GpuRenderer {
    /// Stages this renderer's uniforms and records its render pass and the
    /// copies to its readback buffers into `enc`. The caller holds the device
    /// lock and submits. Each renderer owns its uniforms, targets and
    /// buffers, so frames recorded side by side cannot see each other's.
    fn record(
        &mut self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        camera: &Camera,
        part_transforms: &[Mat4],
    ) -> Result<Recorded> {
        let (w, h) = super::check_resolution(camera)?;
        let k = camera.intrinsics();
        let world_from_camera = camera.world_from_camera();
        let (n, f) = (camera.near, camera.far);
        // OpenCV pinhole to wgpu clip space (y up, depth 0..1).
        let clip_from_camera = Mat4::from_cols_array_2d(&[
            [2.0 * k.fx / w as f32, 0.0, 0.0, 0.0],
            [0.0, -2.0 * k.fy / h as f32, 0.0, 0.0],
            [
                (2.0 * k.cx - w as f32) / w as f32,
                1.0 - 2.0 * k.cy / h as f32,
                f / (f - n),
                1.0,
            ],
            [0.0, 0.0, -f * n / (f - n), 0.0],
        ]);
        let light = Vec3::new(0.3, -0.6, 0.75).normalize();
        let uniform = CameraUniform {
            clip_from_camera: clip_from_camera.to_cols_array_2d(),
            camera_from_world: world_from_camera.inverse().to_mat4().to_cols_array_2d(),
            eye: [camera.eye[0], camera.eye[1], camera.eye[2], 1.0],
            light: [light.x, light.y, light.z, 0.0],
        };
        let mut parts = [[[0f32; 4]; 4]; MAX_PARTS];
        for (slot, t) in parts.iter_mut().zip(part_transforms) {
            *slot = t.to_cols_array_2d();
        }
        gpu.queue
            .write_buffer(&self.camera_buf, 0, bytemuck::bytes_of(&uniform));
        gpu.queue
            .write_buffer(&self.parts_buf, 0, bytemuck::cast_slice(&parts));
        let bind_group = self.bind_group.clone();
        let vertices = self.vertices.clone();
        let t = self.targets(w, h);
        let color_view = t.color.create_view(&Default::default());
        let data_view = t.data.create_view(&Default::default());
        let depth_view = t.depth.create_view(&Default::default());
        {
            let attach = |view| {
                Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })
            };
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: None,
                color_attachments: &[attach(&color_view), attach(&data_view)],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            if let Some(v) = &vertices {
                draw(&mut pass, gpu, v, &bind_group, camera.glass_depth);
            }
        }
        let copy =
            |enc: &mut wgpu::CommandEncoder, tex: &wgpu::Texture, buf: &wgpu::Buffer, bpp: u32| {
                enc.copy_texture_to_buffer(
                    tex.as_image_copy(),
                    wgpu::TexelCopyBufferInfo {
                        buffer: buf,
                        layout: wgpu::TexelCopyBufferLayout {
                            offset: 0,
                            bytes_per_row: Some(padded(w * bpp)),
                            rows_per_image: Some(h),
                        },
                    },
                    wgpu::Extent3d {
                        width: w,
                        height: h,
                        depth_or_array_layers: 1,
                    },
                );
            };
        copy(enc, &t.color, &t.color_buf, 4);
        copy(enc, &t.data, &t.data_buf, 16);
        Ok(Recorded {
            width: w,
            height: h,
            intrinsics: k,
            world_from_camera,
        })
    }

    /// The frame from this renderer's mapped readback buffers.
    fn read_back(&self, r: &Recorded) -> Result<Frame> {
        let t = self
            .targets
            .as_ref()
            .ok_or_else(|| SimError::Render("no frame was recorded".into()))?;
        let (w, h) = (r.width, r.height);
        let npix = (w * h) as usize;
        let mut frame = Frame {
            width: w,
            height: h,
            rgb: vec![0; npix * 3],
            depth: vec![0.0; npix],
            segmentation: vec![0; npix],
            normal_in_world: vec![[0.0; 3]; npix],
            intrinsics: r.intrinsics,
            world_from_camera: r.world_from_camera,
        };
        let mapped = |b: &wgpu::Buffer| {
            b.slice(..)
                .get_mapped_range()
                .map_err(|e| SimError::Render(format!("reading the frame back: {e:?}")))
        };
        let color = mapped(&t.color_buf)?;
        let data = mapped(&t.data_buf)?;
        let (cp, dp, wu) = (padded(w * 4) as usize, padded(w * 16) as usize, w as usize);
        // Rows unpack independently; on lavapipe this copy is a large share of a frame.
        frame
            .rgb
            .par_chunks_mut(wu * 3)
            .zip(frame.depth.par_chunks_mut(wu))
            .zip(frame.segmentation.par_chunks_mut(wu))
            .zip(frame.normal_in_world.par_chunks_mut(wu))
            .enumerate()
            .for_each(|(row, (((rgb, depth), seg), normal))| {
                let crow = &color[row * cp..row * cp + wu * 4];
                let drow: &[u32] = bytemuck::cast_slice(&data[row * dp..row * dp + wu * 16]);
                for col in 0..wu {
                    rgb[col * 3..col * 3 + 3].copy_from_slice(&crow[col * 4..col * 4 + 3]);
                    let d = &drow[col * 4..col * 4 + 4];
                    if d[1] == super::SEG_BACKGROUND {
                        continue;
                    }
                    depth[col] = f32::from_bits(d[0]);
                    seg[col] = d[1];
                    let (nx, ny) = unpack_snorm(d[2]);
                    let (nz, _) = unpack_snorm(d[3]);
                    normal[col] = Vec3::new(nx, ny, nz).normalize_or_zero().to_array();
                }
            });
        Ok(frame)
    }
}

/// Draws the opaque vertices, then the glass over them.
fn draw(
    pass: &mut wgpu::RenderPass<'_>,
    gpu: &Gpu,
    v: &Vertices,
    bind_group: &wgpu::BindGroup,
    glass_depth_read: GlassDepth,
) {
    let [opaque, glass_depth, surface, through, missing] = &gpu.pipelines;
    let glass = match glass_depth_read {
        GlassDepth::Surface => surface,
        GlassDepth::Through => through,
        GlassDepth::Missing => missing,
    };
    pass.set_bind_group(0, bind_group, &[]);
    pass.set_vertex_buffer(0, v.buffer.slice(..));
    pass.set_pipeline(opaque);
    pass.draw(v.opaque.clone(), 0..1);
    if !v.glass.is_empty() {
        pass.set_pipeline(glass_depth);
        pass.draw(v.glass.clone(), 0..1);
        pass.set_pipeline(glass);
        pass.draw(v.glass.clone(), 0..1);
    }
}

/// Renders several scenes, each with its own renderer, in one submission:
/// the device lock is taken once to record and submit them all, the device
/// is waited on once, and the frames are read back in parallel without the
/// lock. A frame is the same, bit for bit, as the renderer's own `render`,
/// which is this function with one item.
pub(super) fn render_gpu_batch(
    mut items: Vec<(&mut GpuRenderer, &Camera, &[Mat4])>,
) -> Result<Vec<Frame>> {
    let Some(gpu) = items.first().map(|(r, _, _)| r.gpu.clone()) else {
        return Ok(Vec::new());
    };
    let recorded = {
        let guard = lock(&gpu)?;
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        let recorded = items
            .iter_mut()
            .map(|(r, camera, transforms)| r.record(&gpu, &mut enc, camera, transforms))
            .collect::<Result<Vec<_>>>()?;
        gpu.queue.submit([enc.finish()]);
        for (r, _, _) in &items {
            if let Some(t) = &r.targets {
                t.color_buf.slice(..).map_async(wgpu::MapMode::Read, |_| {});
                t.data_buf.slice(..).map_async(wgpu::MapMode::Read, |_| {});
            }
        }
        gpu.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| SimError::Render(format!("waiting for the frame: {e}")))?;
        // The device is free once the frames are mapped. Releasing the lock
        // also keeps the parallel unpack below from deadlocking: a rayon
        // worker waiting here may steal another renderer's frame.
        drop(guard);
        recorded
    };
    let frames = items
        .par_iter()
        .zip(&recorded)
        .map(|((r, _, _), rec)| r.read_back(rec))
        .collect::<Result<Vec<_>>>();
    let _guard = lock(&gpu)?;
    for (r, _, _) in &items {
        if let Some(t) = &r.targets {
            t.color_buf.unmap();
            t.data_buf.unmap();
        }
    }
    frames
}

fn lock(gpu: &Gpu) -> Result<std::sync::MutexGuard<'_, ()>> {
    gpu.lock
        .lock()
        .map_err(|_| SimError::Render("renderer lock poisoned".into()))
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_shader_has_a_slot_for_every_part() {
        let shader = include_str!("shader.wgsl");
        let n = super::MAX_PARTS;
        assert!(
            shader.contains(&format!("const MAX_PARTS: u32 = {n}u;")),
            "{n}"
        );
        assert!(shader.contains(&format!("array<mat4x4<f32>, {n}>")), "{n}");
    }
}
