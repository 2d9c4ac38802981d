//! Normals estimated from depth (what a real camera allows) against the
//! renderer's exact ones, on every category: the measurement behind the choice.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests and benchmarks fail by panicking"
)]
use rand::SeedableRng;
use umpnet_eval::benchmark::benchmark_scene;
use umpnet_eval::learned::observation_tensor;
use umpnet_sim::camera::Camera;
use umpnet_sim::env::SimEnv;
use umpnet_sim::objects::Category;
use umpnet_sim::render::{CpuRenderer, SEG_OBJECT_BASE};
use umpnet_sim::scene::Task;

#[test]
fn estimated_normals_agree_with_exact_ones() {
    let _ = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let mut angles = Vec::new();
    for &c in Category::ALL {
        let scene = benchmark_scene(0, Task::Exploration, c, 0, 0, Default::default()).unwrap();
        let mut env = SimEnv::new(
            scene,
            Camera::reference(120, 160),
            Box::new(CpuRenderer::default()),
        )
        .unwrap();
        let f = env.render().unwrap();
        let obs = observation_tensor(&f).unwrap();
        for r in 0..f.height as usize {
            for col in 0..f.width as usize {
                let i = r * f.width as usize + col;
                if f.segmentation[i] < SEG_OBJECT_BASE {
                    continue;
                }
                let exact = f.normal_in_world[i];
                let est = [obs[[r, col, 6]], obs[[r, col, 7]], obs[[r, col, 8]]];
                let dot: f32 = exact.iter().zip(est).map(|(a, b)| a * b).sum();
                angles.push(dot.clamp(-1.0, 1.0).acos().to_degrees());
            }
        }
    }
    angles.sort_by(f32::total_cmp);
    let median = angles[angles.len() / 2];
    let p90 = angles[angles.len() * 9 / 10];
    eprintln!(
        "normals from depth vs exact, {} object pixels: median {median:.2} deg, p90 {p90:.2} deg",
        angles.len()
    );
    assert!(median < 2.0, "median angle {median} deg");
    assert!(p90 < 30.0, "90th percentile {p90} deg");
}

/// Every channel of the network input against the renderer's ground truth on a
/// coloured scene: xyz are the frame's world points, then r, g, b in that
/// order, then depth. A swapped channel (RGB read as BGR, y for z) fails here.
#[test]
fn observation_channels_are_the_frames_world_points_colours_and_depth() {
    let mut checked = 0;
    let mut coloured = 0;
    for c in [Category::Microwave, Category::Door, Category::Toy] {
        let scene = benchmark_scene(1, Task::Exploration, c, 0, 0, Default::default()).unwrap();
        let mut env = SimEnv::new(
            scene,
            Camera::reference(60, 80),
            Box::new(CpuRenderer::default()),
        )
        .unwrap();
        let f = env.render().unwrap();
        let obs = observation_tensor(&f).unwrap();
        for r in 0..f.height {
            for col in 0..f.width {
                let i = f.index(r, col);
                let (ru, cu) = (r as usize, col as usize);
                let rgb = &f.rgb[i * 3..i * 3 + 3];
                for k in 0..3 {
                    let want = rgb[k] as f32 / 255.0;
                    let got = obs[[ru, cu, 3 + k]];
                    assert!(
                        (got - want).abs() < 1e-6,
                        "{c} ({r},{col}) colour {k}: {got} vs {want}"
                    );
                }
                let Some(p) = f.point_in_world(r, col) else {
                    assert_eq!(
                        obs[[ru, cu, 9]],
                        0.0,
                        "{c} ({r},{col}) depth without a point"
                    );
                    continue;
                };
                assert_eq!(obs[[ru, cu, 9]], f.depth[i], "{c} ({r},{col}) depth");
                for (k, want) in [p.x, p.y, p.z].into_iter().enumerate() {
                    let got = obs[[ru, cu, k]];
                    assert!(
                        (got - want).abs() < 1e-4,
                        "{c} ({r},{col}) xyz[{k}]: {got} vs {want}"
                    );
                }
                checked += 1;
                coloured += usize::from((rgb[0] as i32 - rgb[2] as i32).abs() > 20);
            }
        }
    }
    // The scene must be able to tell R from B, or an R/B swap would pass unseen.
    assert!(checked > 1000, "{checked} pixels with depth");
    assert!(
        coloured > 200,
        "{coloured} of {checked} pixels with |R - B| > 20"
    );
}

/// The zero-copy path (`observe_into`, what the Python environments use)
/// writes the same observation as the allocating one, bit for bit, through a
/// goal episode: reset, grasp, moves; and the reference it writes is the one
/// `reference()` holds.
#[test]
fn observe_into_equals_the_allocating_observation_bit_for_bit() {
    use umpnet_eval::train_env::{EnvConfig, ScriptedAction, TrainEnv};
    use umpnet_sim::objects::InstanceSplit;
    use umpnet_sim::render::RendererKind;
    let mut cfg = EnvConfig::new(Task::Goal, InstanceSplit::Train);
    cfg.resolution = (48, 64);
    cfg.renderer = RendererKind::Cpu;
    let mut env = TrainEnv::new(cfg, 3).unwrap();
    let (h, w) = (48usize, 64usize);
    // Poisoned buffers: every value must be overwritten.
    let mut image = vec![f32::NAN; h * w * 10];
    let mut seg = vec![-7i64; h * w];
    let mut reference = vec![f32::NAN; h * w * 10];
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let mut compared = 0;
    for episode in 0..2 {
        env.reset_in_place(None).unwrap();
        env.reference_into(&mut reference).unwrap();
        let held = env.reference().unwrap();
        assert_eq!(
            bits(&reference),
            bits(held.as_slice().unwrap()),
            "episode {episode}"
        );
        for step in 0..6 {
            let meta = env.observe_into(&mut image, &mut seg).unwrap();
            let fresh = env.reset_observation().unwrap();
            assert_eq!(
                bits(&image),
                bits(fresh.image.as_slice().unwrap()),
                "step {step}"
            );
            let fresh_seg: Vec<i64> = fresh.segmentation.iter().map(|&s| i64::from(s)).collect();
            assert_eq!(seg, fresh_seg);
            assert_eq!(meta.intrinsics, fresh.intrinsics);
            assert_eq!(meta.world_from_camera, fresh.world_from_camera);
            assert_eq!(meta.gripper_pixel, fresh.gripper_pixel);
            compared += 1;
            match env.scripted_action("oracle").unwrap() {
                ScriptedAction::Pixel(r, c) => {
                    env.step_position_in_place(r, c).unwrap();
                }
                ScriptedAction::Direction(d) => {
                    env.step_direction_in_place(d).unwrap();
                }
                ScriptedAction::Stop => break,
            }
        }
    }
    assert!(compared >= 6, "{compared} observations compared");
    // Buffers of the wrong size are errors, not panics.
    assert!(env.observe_into(&mut image[1..], &mut seg).is_err());
    assert!(env.observe_into(&mut image, &mut seg[1..]).is_err());
    assert!(env.reference_into(&mut reference[1..]).is_err());
}

/// Deferred steps drawn together by `render_pending` (what `VecEnv` does)
/// give the observations of immediate steps, bit for bit, with wgpu when it
/// is here and with the CPU renderer; an environment that did not step keeps
/// its frame; observing before the draw is an error, not a stale frame.
#[test]
fn deferred_steps_drawn_in_one_batch_equal_immediate_steps() {
    use umpnet_eval::train_env::{EnvConfig, ScriptedAction, TrainEnv, render_pending};
    use umpnet_sim::objects::InstanceSplit;
    use umpnet_sim::render::{RendererKind, gpu_available};
    let mut kinds = vec![RendererKind::Cpu];
    if gpu_available() {
        kinds.push(RendererKind::Wgpu);
    }
    let (h, w) = (48usize, 64usize);
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let observe = |e: &TrainEnv| {
        let mut image = vec![f32::NAN; h * w * 10];
        let mut seg = vec![-7i64; h * w];
        e.observe_into(&mut image, &mut seg)
            .map(|_| (bits(&image), seg))
    };
    for kind in kinds {
        let mut cfg = EnvConfig::new(Task::Goal, InstanceSplit::Train);
        cfg.resolution = (h as u32, w as u32);
        cfg.renderer = kind;
        let seeds = [11, 12, 13];
        let mut immediate: Vec<TrainEnv> = seeds
            .iter()
            .map(|&s| TrainEnv::new(cfg.clone(), s).unwrap())
            .collect();
        let mut deferred: Vec<TrainEnv> = seeds
            .iter()
            .map(|&s| TrainEnv::new(cfg.clone(), s).unwrap())
            .collect();
        for e in immediate.iter_mut().chain(deferred.iter_mut()) {
            e.reset_in_place(None).unwrap();
        }
        let mut drawn = 0;
        for step in 0..8 {
            // Environment 2 sits out odd steps: its frame must stay as it was.
            let mut stepped = 0;
            for (i, (a, b)) in immediate.iter_mut().zip(deferred.iter_mut()).enumerate() {
                if i == 2 && step % 2 == 1 {
                    continue;
                }
                let action = a.scripted_action("oracle").unwrap();
                assert_eq!(action, b.scripted_action("oracle").unwrap());
                match action {
                    ScriptedAction::Pixel(r, c) => {
                        assert_eq!(
                            a.step_position_in_place(r, c).unwrap(),
                            b.step_position_deferred(r, c).unwrap()
                        );
                    }
                    ScriptedAction::Direction(d) => {
                        a.step_direction_in_place(d).unwrap();
                        b.step_direction_deferred(d).unwrap();
                    }
                    ScriptedAction::Stop => continue,
                }
                stepped += 1;
                let err = observe(b).unwrap_err().to_string();
                assert!(err.contains("render_pending"), "{err}");
            }
            render_pending(&mut deferred).unwrap();
            for (i, (a, b)) in immediate.iter().zip(&deferred).enumerate() {
                assert_eq!(
                    observe(a).unwrap(),
                    observe(b).unwrap(),
                    "{kind:?} step {step} env {i}"
                );
            }
            drawn += stepped;
        }
        assert!(drawn >= 12, "{kind:?}: only {drawn} deferred steps drawn");
    }
}
