//! The benchmark engine: a failing episode is reported with its scene and the run goes on.
use std::sync::Arc;
use umpnet_eval::bench::{BenchConfig, PolicyFactory, run_benchmark};
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

#[test]
fn failed_episodes_are_reported_with_their_scene_and_the_run_goes_on() {
    let cfg = BenchConfig {
        task: Task::Goal,
        categories: vec![Category::Door, Category::Laptop],
        episodes_per_category: 2,
        seed: 0,
        dataset_seed: 0,
        camera: Camera::reference(48, 64),
        renderer: RendererKind::Cpu,
        steps: None,
        physics: Default::default(),
        protocol: Default::default(),
    };
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
