//! The wgpu rasteriser against the independent CPU ray caster, on every category.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests and benchmarks fail by panicking"
)]
mod common;

use rand::SeedableRng;
use umpnet_sim::camera::Camera;
use umpnet_sim::env::SimEnv;
use umpnet_sim::objects::{Category, InstanceSplit, nth_instance};
use umpnet_sim::render::{RendererKind, SEG_OBJECT_BASE, create_renderer, gpu_available};
use umpnet_sim::scene::{ObjectSource, Task, sample_scene};

fn scene(c: Category, k: u32) -> umpnet_sim::scene::Scene {
    let split = if c.is_train() {
        InstanceSplit::Train
    } else {
        InstanceSplit::Test
    };
    let object = ObjectSource::Generated {
        category: c,
        index: nth_instance(c, split, k),
        dataset_seed: 0,
    };
    let model = object.load_scaled().unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(k as u64);
    sample_scene(&mut rng, Task::Exploration, Some(c), object, &model, None).unwrap()
}

#[test]
fn wgpu_matches_cpu_reference_on_every_category() {
    if !common::wgpu_present() {
        return;
    }
    let camera = Camera::reference(120, 160);
    let (mut worst_depth, mut worst_seg) = (1.0f64, 0.0f64);
    for &c in Category::ALL {
        for k in 0..2 {
            let s = scene(c, k);
            let mut gpu = SimEnv::new(
                s.clone(),
                camera.clone(),
                create_renderer(RendererKind::Wgpu).unwrap(),
            )
            .unwrap();
            let mut cpu = SimEnv::new(
                s,
                camera.clone(),
                create_renderer(RendererKind::Cpu).unwrap(),
            )
            .unwrap();
            let (a, b) = (gpu.render().unwrap(), cpu.render().unwrap());
            let object = |s: u32| s >= SEG_OBJECT_BASE;
            let (mut obj, mut depth_ok, mut seg_diff) = (0usize, 0usize, 0usize);
            for i in 0..a.depth.len() {
                if a.segmentation[i] != b.segmentation[i] {
                    seg_diff += 1;
                }
                if object(a.segmentation[i]) && a.segmentation[i] == b.segmentation[i] {
                    obj += 1;
                    if (a.depth[i] - b.depth[i]).abs() <= 1e-3 {
                        depth_ok += 1;
                    }
                }
            }
            assert!(obj > 100, "{c}: only {obj} object pixels in view");
            // The paper's floor is 200 m across: from its camera every pixel
            // sees the floor or the object, and no far edge or background.
            for f in [&a, &b] {
                let empty = f.depth.iter().filter(|&&d| d <= 0.0).count();
                assert_eq!(empty, 0, "{c} scene {k}: {empty} pixels see no floor");
            }
            let depth_frac = depth_ok as f64 / obj as f64;
            let seg_frac = seg_diff as f64 / a.depth.len() as f64;
            worst_depth = worst_depth.min(depth_frac);
            worst_seg = worst_seg.max(seg_frac);
            assert!(
                depth_frac >= 0.99,
                "{c} scene {k}: depth within 1 mm on {:.2}% of object pixels",
                depth_frac * 100.0
            );
            assert!(
                seg_frac <= 0.01,
                "{c} scene {k}: segmentation differs on {:.2}% of pixels",
                seg_frac * 100.0
            );
        }
    }
    eprintln!(
        "worst: depth within 1 mm on {:.2}% of object pixels; segmentation differs on {:.3}%",
        worst_depth * 100.0,
        worst_seg * 100.0
    );
}

/// The batch path (one wgpu submission for many scenes, or the CPU renderer
/// in parallel across scenes) draws what each renderer draws on its own, bit
/// for bit, in the order asked, with wgpu and CPU renderers mixed in one batch.
#[test]
fn a_batch_renders_what_each_renderer_renders_alone() {
    use umpnet_sim::render::{Frame, render_batch};
    let gpu = gpu_available();
    if !gpu {
        assert!(
            std::env::var_os("UMPNET_REQUIRE_WGPU").is_none()
                && std::env::var("CI").as_deref() != Ok("true"),
            "no wgpu adapter, under UMPNET_REQUIRE_WGPU or CI=true (install mesa-vulkan-drivers)"
        );
        eprintln!("no wgpu adapter: the batch is checked with the CPU renderer only");
    }
    let camera = Camera::reference(60, 80);
    let kinds = [
        RendererKind::Wgpu,
        RendererKind::Cpu,
        RendererKind::Wgpu,
        RendererKind::Wgpu,
        RendererKind::Cpu,
    ];
    let categories = [
        Category::Refrigerator,
        Category::Microwave,
        Category::StorageFurniture,
        Category::Door,
        Category::Box,
    ];
    let mut envs: Vec<SimEnv> = kinds
        .iter()
        .zip(categories)
        .enumerate()
        .filter(|(_, (k, _))| gpu || **k == RendererKind::Cpu)
        .map(|(i, (k, c))| {
            SimEnv::new(
                scene(c, i as u32),
                camera.clone(),
                create_renderer(*k).unwrap(),
            )
            .unwrap()
        })
        .collect();
    let alone: Vec<Frame> = envs.iter_mut().map(|e| e.render().unwrap()).collect();
    // Twice: the second batch reuses every renderer's targets and buffers.
    for round in 0..2 {
        let batch = render_batch(envs.iter_mut().map(|e| e.render_request()).collect()).unwrap();
        assert_eq!(batch.len(), alone.len());
        for (i, (a, b)) in alone.iter().zip(&batch).enumerate() {
            let what = format!("round {round}, scene {i}");
            assert_eq!(a.rgb, b.rgb, "{what}: colour");
            let bits = |f: &Frame| f.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(a), bits(b), "{what}: depth");
            assert_eq!(a.segmentation, b.segmentation, "{what}: segmentation");
            assert_eq!(a.normal_in_world, b.normal_in_world, "{what}: normals");
            assert!(
                b.segmentation.iter().any(|&s| s >= SEG_OBJECT_BASE),
                "{what}: the object is in view"
            );
        }
        // Scenes differ, so a frame read from a neighbour's buffer would show.
        assert_ne!(batch[0].segmentation, batch[1].segmentation);
    }
    assert!(render_batch(Vec::new()).unwrap().is_empty());
}

/// An object with as many links as the loader allows draws every one of them
/// on the GPU: the renderer has a part slot for each link, the floor and the
/// gripper, and its picture matches the CPU ray caster's.
#[test]
fn an_object_with_the_most_links_allowed_renders_on_both_renderers() {
    if !gpu_available() {
        eprintln!("skipped: no wgpu adapter");
        return;
    }
    let n = umpnet_sim::urdf::MAX_LINKS - 1;
    let mut urdf = String::from(
        r#"<robot name="many"><link name="base"><visual><geometry><box size="0.6 0.6 0.05"/></geometry></visual></link>"#,
    );
    for i in 0..n {
        // A staircase of plates, each one a link on its own hinge.
        urdf += &format!(
            r#"<link name="l{i}"><visual><origin xyz="{:.3} 0 {:.3}"/><geometry><box size="0.05 0.4 0.01"/></geometry></visual></link>"#,
            -0.3 + 0.6 * i as f32 / n as f32,
            0.05 + 0.01 * i as f32
        );
    }
    for i in 0..n {
        urdf += &format!(
            r#"<joint name="j{i}" type="revolute"><parent link="base"/><child link="l{i}"/><axis xyz="0 0 1"/><limit lower="0" upper="1"/></joint>"#
        );
    }
    urdf += "</robot>";
    let dir = std::env::temp_dir().join(format!("umpnet-many-links-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("many.urdf");
    std::fs::write(&path, urdf).unwrap();
    let object = ObjectSource::file(path);
    let model = object.load_scaled().unwrap();
    assert_eq!(model.links.len(), umpnet_sim::urdf::MAX_LINKS);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let s = sample_scene(&mut rng, Task::Exploration, None, object, &model, None).unwrap();
    let camera = Camera::reference(120, 160);
    let mut frames = [RendererKind::Wgpu, RendererKind::Cpu].map(|kind| {
        SimEnv::new(s.clone(), camera.clone(), create_renderer(kind).unwrap())
            .unwrap()
            .render()
            .unwrap()
    });
    let [a, b] = &mut frames;
    let seen = |f: &umpnet_sim::render::Frame| {
        let mut ids: Vec<u32> = f
            .segmentation
            .iter()
            .copied()
            .filter(|s| *s >= SEG_OBJECT_BASE)
            .collect();
        ids.sort_unstable();
        ids.dedup();
        ids
    };
    let (ga, gb) = (seen(a), seen(b));
    assert!(ga.len() >= n / 2, "the GPU drew {} of {n} links", ga.len());
    let same = a
        .segmentation
        .iter()
        .zip(&b.segmentation)
        .filter(|(x, y)| x == y)
        .count();
    assert!(
        same as f64 >= 0.99 * a.segmentation.len() as f64,
        "segmentation agrees on {same} of {} pixels; links seen {ga:?} against {gb:?}",
        a.segmentation.len()
    );
    std::fs::remove_dir_all(&dir).ok();
}
