//! Glass: a visual whose material alpha is below 1 tints the colour image
//! with what lies behind it, while depth and segmentation see the glass.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests fail by panicking"
)]
mod common;

use umpnet_sim::camera::{Camera, GlassDepth};
use umpnet_sim::math::{Mat4, Pose3, Vec3};
use umpnet_sim::mesh::TriMesh;
use umpnet_sim::render::{Frame, RenderMesh, RendererKind, Segment, create_renderer, plane_mesh};

const BOX: u32 = 1 << 16;
const NEAR_PANE: u32 = BOX + 1;
const FAR_PANE: u32 = BOX + 2;

fn cuboid(centre: Vec3, size: Vec3) -> TriMesh {
    TriMesh::cuboid(size).transformed(&Pose3::from_translation(centre))
}

/// A red box on the floor at the camera's target, seen through two panes
/// (the near one at y = -0.5, the far one at y = -0.35), each drawn only
/// when its opacity is given.
fn scene(near: Option<f32>, far: Option<f32>) -> Vec<RenderMesh> {
    let mesh = |segment, color, opacity, mesh| RenderMesh {
        part: 0,
        segment,
        color,
        opacity,
        mesh,
    };
    let mut meshes = vec![
        plane_mesh(0),
        mesh(
            BOX,
            [0.8, 0.2, 0.1],
            1.0,
            cuboid(Vec3::new(0.0, 0.0, 0.2), Vec3::splat(0.4)),
        ),
    ];
    let pane = |y: f32| cuboid(Vec3::new(0.0, y, 0.5), Vec3::new(0.8, 0.01, 0.8));
    if let Some(a) = near {
        meshes.push(mesh(NEAR_PANE, [0.6, 0.8, 0.9], a, pane(-0.5)));
    }
    if let Some(a) = far {
        meshes.push(mesh(FAR_PANE, [0.1, 0.9, 0.2], a, pane(-0.35)));
    }
    meshes
}

fn render(kind: RendererKind, meshes: &[RenderMesh]) -> Frame {
    render_reading(kind, meshes, GlassDepth::Surface)
}

fn render_reading(kind: RendererKind, meshes: &[RenderMesh], glass_depth: GlassDepth) -> Frame {
    let mut r = create_renderer(kind).unwrap();
    r.load(meshes).unwrap();
    let camera = Camera {
        glass_depth,
        ..Camera::reference(120, 160)
    };
    r.render(&camera, &[Mat4::IDENTITY]).unwrap()
}

/// A camera that reads through glass: the surface-reading frame's colours,
/// and the depth, segments and normals of the scene without the panes.
fn assert_reads_through(kind: RendererKind, meshes: &[RenderMesh]) {
    let through = render_reading(kind, meshes, GlassDepth::Through);
    let surface = render_reading(kind, meshes, GlassDepth::Surface);
    let bare = render_reading(kind, &scene(None, None), GlassDepth::Surface);
    assert_eq!(
        through.rgb, surface.rgb,
        "{kind:?}: the colour shows the glass"
    );
    assert_eq!(through.segmentation, bare.segmentation, "{kind:?}");
    assert_eq!(through.depth, bare.depth, "{kind:?}");
    assert_eq!(through.normal_in_world, bare.normal_in_world, "{kind:?}");
    let panes = surface
        .segmentation
        .iter()
        .filter(|&&s| s == NEAR_PANE || s == FAR_PANE)
        .count();
    assert!(panes > 1000, "{kind:?}: {panes} pixels see a pane");
}

fn rgb(f: &Frame, i: usize) -> [f32; 3] {
    std::array::from_fn(|c| f32::from(f.rgb[i * 3 + c]))
}

/// Pixels that see the box through the near pane in every frame given.
fn through_the_pane(frames: &[&Frame], behind: &Frame) -> Vec<usize> {
    (0..behind.segmentation.len())
        .filter(|&i| {
            behind.segmentation[i] == BOX && frames.iter().all(|f| f.segmentation[i] == NEAR_PANE)
        })
        .collect()
}

#[test]
fn the_nearest_pane_is_blended_over_the_opaque_surface_behind_it() {
    let a = 0.4;
    let glass = render(RendererKind::Cpu, &scene(Some(a), Some(0.5)));
    let behind = render(RendererKind::Cpu, &scene(None, None));
    let pane_alone = render(RendererKind::Cpu, &scene(Some(1.0), None));
    let pixels = through_the_pane(&[&glass, &pane_alone], &behind);
    assert!(
        pixels.len() > 300,
        "{} pixels see the box through the pane",
        pixels.len()
    );
    for &i in &pixels {
        // Depth and segmentation are the glass's, as if it were opaque.
        assert_eq!(glass.depth[i], pane_alone.depth[i]);
        assert_eq!(glass.normal_in_world[i], pane_alone.normal_in_world[i]);
        let (g, front, back) = (rgb(&glass, i), rgb(&pane_alone, i), rgb(&behind, i));
        for c in 0..3 {
            // The far pane does not show: only the box is behind the near one.
            let want = a * front[c] + (1.0 - a) * back[c];
            assert!(
                (g[c] - want).abs() <= 1.5,
                "pixel {i} channel {c}: {g:?}, want {want}"
            );
        }
    }
    // Where the far pane alone stands in front of the floor, it tints the floor.
    let floor = (0..glass.segmentation.len()).find(|&i| {
        glass.segmentation[i] == FAR_PANE && behind.segmentation[i] == umpnet_sim::render::SEG_PLANE
    });
    assert!(
        floor.is_some(),
        "no pixel sees the floor through the far pane alone"
    );
}

#[test]
fn an_opaque_material_draws_as_before_and_a_clear_one_shows_only_what_is_behind() {
    let opaque = render(RendererKind::Cpu, &scene(Some(1.0), None));
    let clear = render(RendererKind::Cpu, &scene(Some(0.0), None));
    let behind = render(RendererKind::Cpu, &scene(None, None));
    let pixels = through_the_pane(&[&opaque, &clear], &behind);
    assert!(!pixels.is_empty());
    for &i in &pixels {
        assert_eq!(rgb(&clear, i), rgb(&behind, i), "pixel {i}");
        assert_ne!(rgb(&opaque, i), rgb(&behind, i), "pixel {i}");
        assert!(matches!(
            Segment::decode(clear.segmentation[i]),
            Segment::Link { link: 1, .. }
        ));
    }
}

#[test]
fn wgpu_draws_glass_as_the_cpu_ray_caster_does() {
    if !common::wgpu_present() {
        return;
    }
    // The far pane's triangles come first in the buffer: the result must not
    // depend on the order glass is drawn in.
    let mut meshes = scene(Some(0.35), Some(0.6));
    meshes.swap(2, 3);
    let gpu = render(RendererKind::Wgpu, &meshes);
    let cpu = render(RendererKind::Cpu, &meshes);
    let behind = render(RendererKind::Cpu, &scene(None, None));
    let pixels = through_the_pane(&[&gpu, &cpu], &behind);
    assert!(pixels.len() > 300, "{} pixels", pixels.len());
    let worst = pixels
        .iter()
        .flat_map(|&i| {
            let (g, c) = (rgb(&gpu, i), rgb(&cpu, i));
            (0..3).map(move |k| (g[k] - c[k]).abs())
        })
        .fold(0.0f32, f32::max);
    assert!(
        worst <= 3.0,
        "wgpu and CPU colours differ by up to {worst} behind glass"
    );
    for &i in &pixels {
        assert!((gpu.depth[i] - cpu.depth[i]).abs() < 1e-3, "pixel {i}");
    }
}

#[test]
fn a_camera_that_reads_through_glass_sees_depth_and_segments_behind_it() {
    let meshes = scene(Some(0.35), Some(0.6));
    assert_reads_through(RendererKind::Cpu, &meshes);
    // A pane with nothing behind it within range reads as background.
    let mut r = create_renderer(RendererKind::Cpu).unwrap();
    r.load(&[RenderMesh {
        part: 0,
        segment: NEAR_PANE,
        color: [0.6, 0.8, 0.9],
        opacity: 0.5,
        mesh: cuboid(Vec3::ZERO, Vec3::new(0.8, 0.8, 0.01)),
    }])
    .unwrap();
    let camera = Camera {
        glass_depth: GlassDepth::Through,
        ..Camera::reference(120, 160)
    };
    let f = r.render(&camera, &[Mat4::IDENTITY]).unwrap();
    let tinted = (0..f.depth.len()).filter(|&i| f.rgb[i * 3 + 2] > 0).count();
    assert!(tinted > 100, "{tinted} pixels show the pane");
    assert!(f.depth.iter().all(|&d| d == 0.0));
    assert!(
        f.segmentation
            .iter()
            .all(|&s| s == umpnet_sim::render::SEG_BACKGROUND)
    );
}

/// A camera that reads nothing on glass: the surface-reading frame, with
/// every pixel that sees a pane empty in depth, segments and normals.
fn assert_reads_nothing_on_glass(kind: RendererKind, meshes: &[RenderMesh]) {
    let missing = render_reading(kind, meshes, GlassDepth::Missing);
    let surface = render_reading(kind, meshes, GlassDepth::Surface);
    assert_eq!(
        missing.rgb, surface.rgb,
        "{kind:?}: the colour shows the glass"
    );
    let mut panes = 0;
    for (i, &s) in surface.segmentation.iter().enumerate() {
        if s == NEAR_PANE || s == FAR_PANE {
            panes += 1;
            assert_eq!(missing.depth[i], 0.0, "{kind:?} pixel {i}");
            assert_eq!(missing.segmentation[i], umpnet_sim::render::SEG_BACKGROUND);
            assert_eq!(missing.normal_in_world[i], [0.0; 3]);
        } else {
            assert_eq!(missing.depth[i], surface.depth[i], "{kind:?} pixel {i}");
            assert_eq!(missing.segmentation[i], s);
            assert_eq!(missing.normal_in_world[i], surface.normal_in_world[i]);
        }
    }
    assert!(panes > 1000, "{kind:?}: {panes} pixels see a pane");
}

#[test]
fn a_camera_that_reads_nothing_on_glass_leaves_the_panes_empty() {
    assert_reads_nothing_on_glass(RendererKind::Cpu, &scene(Some(0.35), Some(0.6)));
}

#[test]
fn wgpu_reads_nothing_on_glass_too() {
    if !common::wgpu_present() {
        return;
    }
    let mut meshes = scene(Some(0.35), Some(0.6));
    meshes.swap(2, 3);
    assert_reads_nothing_on_glass(RendererKind::Wgpu, &meshes);
}

#[test]
fn wgpu_reads_through_glass_too() {
    if !common::wgpu_present() {
        return;
    }
    let mut meshes = scene(Some(0.35), Some(0.6));
    meshes.swap(2, 3);
    assert_reads_through(RendererKind::Wgpu, &meshes);
}
