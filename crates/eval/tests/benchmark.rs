//! The benchmark engine: a failing episode is reported with its scene and the run goes on.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests and benchmarks fail by panicking"
)]
use std::sync::Arc;
use umpnet_eval::benchmark::{
    BenchConfig, PolicyFactory, Row, Shard, object_rows, run_benchmark, stream_benchmark,
};
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
    fn position(&mut self, _: &Observation<'_>, _: &SimEnv) -> Result<(u32, u32)> {
        Err(EvalError::Episode("policy failed on purpose".into()))
    }
    fn direction(&mut self, _: &Observation<'_>, _: &SimEnv, _: &[StepRecord]) -> Result<Decision> {
        Ok(Decision::Stop)
    }
}

/// A small CPU-rendered benchmark over all scenes.
fn config(task: Task, categories: Vec<Category>, episodes_per_category: u32) -> BenchConfig {
    BenchConfig {
        task,
        rows: categories.into_iter().map(Row::Category).collect(),
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
fn streamed_scenes_arrive_in_order_and_a_stop_keeps_a_whole_prefix() {
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
    let cfg = config(Task::Goal, vec![Category::Door, Category::Laptop], 5);
    let oracle: PolicyFactory =
        Arc::new(|| Ok(umpnet_eval::scripted_policy("oracle").expect("oracle exists")));
    let policies = [("oracle".to_string(), oracle)];
    let whole = run_benchmark(&cfg, &policies, &|| {});
    let key = |o: &umpnet_eval::benchmark::EpisodeOutcome| (o.category, o.index);
    let mut from_three = Vec::new();
    let never = AtomicBool::new(false);
    let end = stream_benchmark(&cfg, &policies, 3, 2, &never, &|| {}, |i, out| {
        from_three.push((i, out));
        Ok::<(), ()>(())
    })
    .unwrap();
    assert_eq!(end, 10);
    for (n, (i, out)) in from_three.iter().enumerate() {
        assert_eq!(*i, 3 + n as u64);
        assert_eq!(key(&out[0]), key(&whole[*i as usize]));
        assert_eq!(
            serde_json::to_string(&out[0]).unwrap(),
            serde_json::to_string(&whole[*i as usize]).unwrap()
        );
    }
    // Stopped after four scenes have started: what arrives is a prefix.
    let stop = AtomicBool::new(false);
    let started = AtomicUsize::new(0);
    let mut got = Vec::new();
    let end = stream_benchmark(
        &cfg,
        &policies,
        0,
        3,
        &stop,
        &|| {
            if started.fetch_add(1, Ordering::SeqCst) >= 3 {
                stop.store(true, Ordering::SeqCst);
            }
        },
        |i, _| {
            got.push(i);
            Ok::<(), ()>(())
        },
    )
    .unwrap();
    assert!((4..10).contains(&end), "{end}");
    assert_eq!(got, (0..end).collect::<Vec<_>>());
}

#[test]
fn shards_partition_the_scenes_in_canonical_order() {
    let categories = vec![Category::Door, Category::Laptop, Category::Microwave];
    let mut cfg = config(Task::Exploration, categories, 5);
    let all: Vec<(Row, u32)> = cfg.scenes().map(|(r, k)| (r.clone(), k)).collect();
    assert_eq!(all.len(), 15);
    assert_eq!(all[0], (Row::Category(Category::Door), 0));
    assert_eq!(all[5], (Row::Category(Category::Laptop), 0));
    for count in [1u32, 2, 4, 15, 16] {
        let mut seen = Vec::new();
        let mut sizes = Vec::new();
        for index in 1..=count {
            cfg.shard = Shard::new(index, count).expect("valid shard");
            let part: Vec<(Row, u32)> = cfg.scenes().map(|(r, k)| (r.clone(), k)).collect();
            sizes.push(part.len());
            seen.extend(part);
        }
        // Round-robin: shard sizes differ by at most one.
        let (lo, hi) = (sizes.iter().min(), sizes.iter().max());
        assert!(
            hi.zip(lo).is_some_and(|(h, l)| h - l <= 1),
            "{count}: {sizes:?}"
        );
        seen.sort_by_key(|s| all.iter().position(|a| a == s));
        assert_eq!(seen, all, "{count} shards");
    }
    // Counted, not listed: a run of 22 x 4e9 scenes is known at once.
    let mut huge = config(Task::Exploration, Category::ALL.to_vec(), u32::MAX);
    huge.shard = Shard::new(3, 7).unwrap();
    let total = Category::ALL.len() as u64 * u64::from(u32::MAX);
    assert_eq!(huge.scene_count(), (total - 2).div_ceil(7));
    let last = huge.scene_count() - 1;
    let position = 2 + last * 7;
    let (row, k) = huge.scene_at(last).unwrap();
    assert_eq!(
        (row.clone(), u64::from(k)),
        (
            Row::Category(Category::ALL[(position / u64::from(u32::MAX)) as usize]),
            position % u64::from(u32::MAX)
        )
    );
    assert!(huge.scene_at(last + 1).is_none());
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

/// Generated instances written as files under `dir/NAME/`, placed by an
/// `object_meta_info.json` as an imported object is.
fn object_folder(dir: &std::path::Path, names: &[(&str, u32)]) {
    for (name, index) in names {
        let tmp = tempfile::tempdir().unwrap();
        let urdf = umpnet_sim::objects::generate(Category::Microwave, *index, 0)
            .write(tmp.path())
            .unwrap();
        let dest = dir.join(name);
        std::fs::create_dir_all(dest.join("textured_objs")).unwrap();
        let src = urdf.parent().unwrap();
        std::fs::copy(&urdf, dest.join("mobility.urdf")).unwrap();
        for f in std::fs::read_dir(src.join("textured_objs")).unwrap() {
            let f = f.unwrap().path();
            std::fs::copy(&f, dest.join("textured_objs").join(f.file_name().unwrap())).unwrap();
        }
        std::fs::write(
            dest.join("object_meta_info.json"),
            r#"{"orientation":[0,0,0,1],"offset_z":0,"scale":0.55}"#,
        )
        .unwrap();
    }
}

#[test]
fn object_folders_are_rows_named_by_folder_with_scenes_that_do_not_depend_on_the_path() {
    let a = tempfile::tempdir().unwrap();
    object_folder(a.path(), &[("oven_b", 1), ("oven_a", 0)]);
    std::fs::create_dir_all(a.path().join("not_an_object")).unwrap();
    let rows = object_rows(a.path()).unwrap();
    let names: Vec<&str> = rows.iter().map(Row::name).collect();
    assert_eq!(names, ["oven_a", "oven_b"]);
    let mut cfg = config(Task::Goal, vec![], 2);
    cfg.rows = rows;
    let oracle: PolicyFactory =
        Arc::new(|| Ok(umpnet_eval::scripted_policy("oracle").expect("oracle exists")));
    let out = run_benchmark(&cfg, &[("oracle".into(), oracle.clone())], &|| {});
    assert_eq!(out.len(), 4);
    for o in &out {
        assert!(o.category.is_none(), "{o:?}");
        assert!(o.error.is_none(), "{:?}", o.error);
        let ep = o.episode.as_ref().unwrap();
        assert!(
            ep.metrics.success,
            "the oracle reaches the goal on {:?}",
            o.object
        );
        assert!(ep.scene.category.is_none());
    }
    let json = serde_json::to_value(&out[0]).unwrap();
    assert_eq!(json["object"], "oven_a");
    assert!(json.get("category").is_none(), "{json}");
    // The same objects in another folder: the same scenes, bar the file's path.
    let b = tempfile::tempdir().unwrap();
    object_folder(b.path(), &[("oven_a", 0), ("oven_b", 1)]);
    cfg.rows = object_rows(b.path()).unwrap();
    let again = run_benchmark(&cfg, &[("oracle".into(), oracle)], &|| {});
    for (x, y) in out.iter().zip(&again) {
        let (x, y) = (x.episode.as_ref().unwrap(), y.episode.as_ref().unwrap());
        assert_eq!(
            (x.scene.joints.clone(), x.scene.base_yaw),
            (y.scene.joints.clone(), y.scene.base_yaw)
        );
        assert_eq!(x.metrics, y.metrics);
    }
    let empty = tempfile::tempdir().unwrap();
    let e = object_rows(empty.path()).unwrap_err().to_string();
    assert!(e.contains("no NAME/mobility.urdf"), "{e}");
}
