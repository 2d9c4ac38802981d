//! Frames for n environments at 120x160, drawn one by one (a device wait and
//! a lock per frame) and as one batch (`render_batch`: one submission, one
//! wait, parallel readback): the lever a `VecEnv` step pulls.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests and benchmarks fail by panicking"
)]
use criterion::{Criterion, criterion_group, criterion_main};
use rand::SeedableRng;
use umpnet_sim::camera::Camera;
use umpnet_sim::env::SimEnv;
use umpnet_sim::objects::{Category, InstanceSplit, nth_instance};
use umpnet_sim::render::{RendererKind, create_renderer, gpu_available, render_batch};
use umpnet_sim::scene::{ObjectSource, Task, sample_scene};

fn envs(n: u32, kind: RendererKind, (h, w): (u32, u32)) -> Vec<SimEnv> {
    (0..n)
        .map(|k| {
            let c = Category::Refrigerator;
            let object = ObjectSource::Generated {
                category: c,
                index: nth_instance(c, InstanceSplit::Train, k),
                dataset_seed: 0,
            };
            let model = object.load_scaled().unwrap();
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(u64::from(k));
            let scene =
                sample_scene(&mut rng, Task::Exploration, Some(c), object, &model, None).unwrap();
            SimEnv::new(
                scene,
                Camera::reference(h, w),
                create_renderer(kind).unwrap(),
            )
            .unwrap()
        })
        .collect()
}

fn render(c: &mut Criterion) {
    let mut kinds = vec![(RendererKind::Cpu, "cpu")];
    if gpu_available() {
        kinds.insert(0, (RendererKind::Wgpu, "wgpu"));
    }
    for (kind, name) in kinds {
        for n in [1, 2, 4, 8] {
            let mut envs = envs(n, kind, (120, 160));
            c.bench_function(
                &format!("render {name}: {n} frames 120x160, one by one"),
                |b| {
                    b.iter(|| {
                        for e in &mut envs {
                            e.render().unwrap();
                        }
                    })
                },
            );
            c.bench_function(
                &format!("render {name}: {n} frames 120x160, one batch"),
                |b| b.iter(|| render_batch(envs.iter_mut().map(|e| e.render_request()).collect())),
            );
        }
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = render
}
criterion_main!(benches);
