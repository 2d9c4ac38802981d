//! Pure-CPU renderer: one ray per pixel centre against a BVH (parry3d) of the
//! scene's triangles in world frame. Independent of the rasteriser, so tests
//! use it as a reference; also the fallback when no GPU adapter exists.
#![allow(
    clippy::indexing_slicing,
    reason = "pixel and triangle indices are bounded by the buffers this renderer allocated"
)]
use super::{Frame, RenderMesh, Renderer, SEG_BACKGROUND, shade, shade_glass};
use crate::camera::{Camera, GlassDepth};
use crate::error::{Result, SimError};
use crate::math::{Mat4, Vec3};
use rapier3d::parry::query::{Ray, RayCast};
use rapier3d::parry::shape::{TriMesh as ParryMesh, Triangle};

/// The built-in renderer: a ray per pixel against the meshes (parry), in
/// parallel rows; the same frames as the wgpu renderer's, within a pixel on
/// silhouettes.
#[derive(Default)]
pub struct CpuRenderer {
    meshes: Vec<RenderMesh>,
}

impl Renderer for CpuRenderer {
    fn name(&self) -> String {
        "cpu/parry3d ray casting".into()
    }

    fn load(&mut self, meshes: &[RenderMesh]) -> Result<()> {
        self.meshes = meshes.to_vec();
        Ok(())
    }

    fn render(&mut self, camera: &Camera, part_transforms: &[Mat4]) -> Result<Frame> {
        let (w, h) = super::check_resolution(camera)?;
        let has_glass = self.meshes.iter().any(RenderMesh::is_glass);
        let WorldTriangles {
            positions,
            triangles,
            owner,
            opaque,
            opaque_owner,
        } = self.world_triangles(part_transforms, has_glass);
        let k = camera.intrinsics();
        let world_from_camera = camera.world_from_camera();
        let eye = Vec3::from(camera.eye);
        let npix = (w * h) as usize;
        let mut frame = Frame {
            width: w,
            height: h,
            rgb: vec![0; npix * 3],
            depth: vec![0.0; npix],
            segmentation: vec![SEG_BACKGROUND; npix],
            normal_in_world: vec![[0.0; 3]; npix],
            intrinsics: k,
            world_from_camera,
        };
        if triangles.is_empty() {
            return Ok(frame);
        }
        let ntri = triangles.len() as u32;
        let bvh_of = |positions, triangles| {
            ParryMesh::new(positions, triangles)
                .map_err(|e| SimError::Render(format!("building the ray-casting BVH: {e:?}")))
        };
        let behind_glass = match (has_glass, opaque.is_empty()) {
            (true, false) => Some(bvh_of(positions.clone(), opaque)?),
            _ => None,
        };
        let bvh = bvh_of(positions, triangles)?;
        let forward = world_from_camera.rotation * Vec3::Z;
        for row in 0..h {
            for col in 0..w {
                let dir_cam = Vec3::new(
                    (col as f32 + 0.5 - k.cx) / k.fx,
                    (row as f32 + 0.5 - k.cy) / k.fy,
                    1.0,
                );
                let dir = world_from_camera.rotation * dir_cam;
                let ray = Ray::new(eye, dir);
                let Some(hit) = bvh.cast_local_ray_and_get_normal(&ray, camera.far, true) else {
                    continue;
                };
                let tri = hit.subshape;
                if tri >= ntri {
                    continue;
                }
                let point = eye + dir * hit.time_of_impact;
                let z = (point - eye).dot(forward);
                if z < camera.near {
                    continue;
                }
                let n = facing_normal(&bvh.triangle(tri), point, eye);
                let m = &self.meshes[owner[tri as usize]];
                let i = (row * w + col) as usize;
                if !m.is_glass() {
                    frame.depth[i] = z;
                    frame.segmentation[i] = m.segment;
                    frame.normal_in_world[i] = n.to_array();
                    frame.rgb[i * 3..i * 3 + 3].copy_from_slice(&shade(m.color, n));
                    continue;
                }
                let behind = behind_glass
                    .as_ref()
                    .and_then(|b| self.opaque_hit(b, &opaque_owner, &ray, camera.far));
                let rgb = shade_glass(
                    m.color,
                    n,
                    m.opacity,
                    behind.as_ref().map_or([0; 3], |b| b.rgb),
                );
                frame.rgb[i * 3..i * 3 + 3].copy_from_slice(&rgb);
                match camera.glass_depth {
                    GlassDepth::Surface => {
                        frame.depth[i] = z;
                        frame.segmentation[i] = m.segment;
                        frame.normal_in_world[i] = n.to_array();
                    }
                    GlassDepth::Through => {
                        if let Some(b) = behind {
                            frame.depth[i] = (b.point - eye).dot(forward);
                            frame.segmentation[i] = b.segment;
                            frame.normal_in_world[i] = b.normal.to_array();
                        }
                    }
                    // The frame's own "nothing here": depth 0, background.
                    GlassDepth::Missing => {}
                }
            }
        }
        Ok(frame)
    }
}

/// A frame's triangles in world frame, each remembering its mesh; and, in a
/// scene with glass, the opaque ones alone (what glass lets through).
struct WorldTriangles {
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    owner: Vec<usize>,
    opaque: Vec<[u32; 3]>,
    opaque_owner: Vec<usize>,
}

/// The nearest opaque surface behind glass along a ray.
struct OpaqueHit {
    point: Vec3,
    normal: Vec3,
    segment: u32,
    rgb: [u8; 3],
}

impl CpuRenderer {
    /// The scene's triangles in world space; with `has_glass`, the opaque
    /// ones again apart, for the ray cast behind a pane.
    fn world_triangles(&self, part_transforms: &[Mat4], has_glass: bool) -> WorldTriangles {
        let mut out = WorldTriangles {
            positions: Vec::new(),
            triangles: Vec::new(),
            owner: Vec::new(),
            opaque: Vec::new(),
            opaque_owner: Vec::new(),
        };
        for (mi, m) in self.meshes.iter().enumerate() {
            let t = part_transforms
                .get(m.part)
                .copied()
                .unwrap_or(Mat4::IDENTITY);
            if t.determinant().abs() < 1e-9 {
                continue; // hidden part
            }
            let positions = &mut out.positions;
            let base = positions.len() as u32;
            positions.extend(m.mesh.positions.iter().map(|p| t.transform_point3(*p)));
            for tri in &m.mesh.triangles {
                let [a, b, c] = tri.map(|i| positions[(base + i) as usize]);
                if (b - a).cross(c - a).length_squared() > 1e-14 {
                    let t = [base + tri[0], base + tri[1], base + tri[2]];
                    out.triangles.push(t);
                    out.owner.push(mi);
                    if has_glass && !m.is_glass() {
                        out.opaque.push(t);
                        out.opaque_owner.push(mi);
                    }
                }
            }
        }
        out
    }

    /// The nearest opaque surface along `ray`, from the BVH of the opaque
    /// triangles and each one's mesh.
    fn opaque_hit(
        &self,
        opaque: &ParryMesh,
        owner: &[usize],
        ray: &Ray,
        far: f32,
    ) -> Option<OpaqueHit> {
        let hit = opaque.cast_local_ray_and_get_normal(ray, far, true)?;
        let m = self.meshes.get(*owner.get(hit.subshape as usize)?)?;
        let point = ray.origin + ray.dir * hit.time_of_impact;
        let normal = facing_normal(&opaque.triangle(hit.subshape), point, ray.origin);
        Some(OpaqueHit {
            point,
            normal,
            segment: m.segment,
            rgb: shade(m.color, normal),
        })
    }
}

/// A triangle's geometric normal, turned to face `eye` from `point` on it.
fn facing_normal(t: &Triangle, point: Vec3, eye: Vec3) -> Vec3 {
    let n = (t.b - t.a).cross(t.c - t.a).normalize();
    if n.dot(eye - point) < 0.0 { -n } else { n }
}
