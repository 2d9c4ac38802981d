//! The benchmark engine: a failing episode is reported with its scene and the run goes on.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests and benchmarks fail by panicking"
)]
use std::sync::Arc;
use umpnet_eval::bench::{BenchConfig, PolicyFactory, Shard, run_benchmark};
use umpnet_eval::policy::{Decision, Observation, Policy, StepRecord};
use umpnet_eval::{EvalError, Result};
use umpnet_sim::camera::Camera;
use umpnet_sim::env::SimEnv;
use umpnet_sim::objects::Category;
use umpnet_sim::render::RendererKind;
use umpnet_sim::scene::Task;

struct Broken;
impl Policy for Broken {
    fn name(&self) -> String {
        "broken".into()
    }
    fn reset(&mut self, _: u64) {}
    fn position(&mut self, _: &Observation, _: &SimEnv) -> Result<(u32, u32)> {
        Err(EvalError::Episode("policy failed on purpose".into()))
    }
    fn direction(&mut self, _: &Observation, _: &SimEnv, _: &[StepRecord]) -> Result<Decision> {
        Ok(Decision::Stop)
    }
}

/// A small CPU-rendered benchmark over all scenes.
fn config(task: Task, categories: Vec<Category>, episodes_per_category: u32) -> BenchConfig {
    BenchConfig {
        task,
        categories,
        episodes_per_category,
        seed: 0,
        dataset_seed: 0,
        camera: Camera::reference(48, 64),
        policy_cameras: Default::default(),
        renderer: RendererKind::Cpu,
        steps: None,
        physics: Default::default(),
        protocol: Default::default(),
        shard: Shard::ALL,
    }
}

#[test]
fn failed_episodes_are_reported_with_their_scene_and_the_run_goes_on() {
    let cfg = config(Task::Goal, vec![Category::Door, Category::Laptop], 2);
    let broken: PolicyFactory = Arc::new(|| Ok(Box::new(Broken) as Box<dyn Policy>));
    let oracle: PolicyFactory =
        Arc::new(|| Ok(umpnet_eval::scripted_policy("oracle").expect("oracle exists")));
    let out = run_benchmark(
        &cfg,
        &[("broken".into(), broken), ("oracle".into(), oracle)],
        &|| {},
    );
    assert_eq!(out.len(), 8);
    for o in &out {
        if o.policy == "broken" {
            let e = o.error.as_deref().unwrap_or_default();
            assert!(
                e.contains("policy failed on purpose") && e.contains("\"task\":\"goal\""),
                "{e}"
            );
        } else {
            assert!(o.error.is_none() && o.episode.as_ref().is_some_and(|e| e.metrics.success));
        }
    }
}

#[test]
fn shards_partition_the_scenes_in_canonical_order() {
    let categories = vec![Category::Door, Category::Laptop, Category::Microwave];
    let mut cfg = config(Task::Exploration, categories, 5);
    let all = cfg.scenes();
    assert_eq!(all.len(), 15);
    assert_eq!(all[0], (Category::Door, 0));
    assert_eq!(all[5], (Category::Laptop, 0));
    for count in [1u32, 2, 4, 15, 16] {
        let mut seen = Vec::new();
        let mut sizes = Vec::new();
        for index in 1..=count {
            cfg.shard = Shard::new(index, count).expect("valid shard");
            let part = cfg.scenes();
            sizes.push(part.len());
            seen.extend(part);
        }
        // Round-robin: shard sizes differ by at most one.
        let (lo, hi) = (sizes.iter().min(), sizes.iter().max());
        assert!(
            hi.zip(lo).is_some_and(|(h, l)| h - l <= 1),
            "{count}: {sizes:?}"
        );
        seen.sort_by_key(|&(c, k)| (all.iter().position(|s| *s == (c, k)), k));
        assert_eq!(seen, all, "{count} shards");
    }
    assert_eq!(
        "2/4".parse::<Shard>().ok(),
        Some(Shard { index: 2, count: 4 })
    );
    for bad in ["0/4", "5/4", "1/0", "2", "a/b", "-1/3"] {
        let e = bad.parse::<Shard>().err().map(|e| e.to_string());
        assert!(
            e.as_deref().is_some_and(|m| m.contains("K/N")),
            "{bad}: {e:?}"
        );
    }
}
