//! The paper's benchmark: per category, K fixed scenes (pure functions of
//! seed, task, category and index), every policy on the same scenes, episodes
//! in parallel with results independent of the thread count.
#![allow(
    clippy::indexing_slicing,
    reason = "joint indices come from the model the counts were sized for"
)]
use crate::episode::{Episode, EpisodeConfig, FrameHook, run_episode};
use crate::policy::Policy;
use crate::protocol::Protocol;
pub use crate::shard::Shard;
pub use crate::stats::{Running, mean_ci, wilson};
use crate::{EvalError, Result};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use umpnet_sim::camera::Camera;
use umpnet_sim::env::SimEnv;
use umpnet_sim::objects::{Category, InstanceSplit, nth_instance};
use umpnet_sim::physics::PhysicsProfile;
use umpnet_sim::render::{CpuRenderer, RendererKind, Segment, create_renderer};
use umpnet_sim::scene::{ObjectSource, Scene, Task, sample_scene};

/// Test instances drawn per category (the paper has about ten per category).
pub const INSTANCES_PER_CATEGORY: u32 = 10;

/// Makes a fresh policy for each worker thread.
pub type PolicyFactory = Arc<dyn Fn() -> Result<Box<dyn Policy>> + Send + Sync>;

fn mix(parts: &[u64]) -> u64 {
    // splitmix64 over the parts: stable across platforms and versions.
    let mut h = 0x243F_6A88_85A3_08D3u64;
    for &p in parts {
        h ^= p
            .wrapping_add(0x9E37_79B9_7F4A_7C15)
            .wrapping_add(h << 6)
            .wrapping_add(h >> 2);
        h = (h ^ (h >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h = (h ^ (h >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        h ^= h >> 31;
    }
    h
}

/// What one table row of the benchmark scores: the test instances of a
/// generated category, or one object file (`eval --objects DIR`: a folder's
/// `NAME/mobility.urdf`, placed by its `object_meta_info.json`).
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Row {
    /// A category's generated test instances.
    Category(Category),
    /// One object file (`eval --objects`).
    Object(ObjectRow),
    /// A category's row on object files instead of generated instances
    /// (`eval --partnet`: a local PartNet-Mobility folder).
    Instances(InstanceRow),
}

/// A category scored on given object files: scene `k` uses instance
/// `k % n`, with the category's scene seeds, so it pairs with the generated
/// category's row scene by scene.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct InstanceRow {
    /// The category the row is named after.
    pub category: Category,
    /// Its instances; scene `k` uses instance `k % len`.
    pub instances: Vec<crate::partnet::Instance>,
}

/// An object file scored as its own row, named after its folder.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ObjectRow {
    /// The row's name: the object's folder.
    pub name: String,
    /// The object's URDF.
    pub urdf: PathBuf,
}

impl Row {
    /// The row's name in tables.
    pub fn name(&self) -> &str {
        match self {
            Row::Category(c) => c.name(),
            Row::Object(o) => &o.name,
            Row::Instances(r) => r.category.name(),
        }
    }

    /// The category of a category row (generated or PartNet).
    pub fn category(&self) -> Option<Category> {
        match self {
            Row::Category(c) => Some(*c),
            Row::Object(_) => None,
            Row::Instances(r) => Some(r.category),
        }
    }
}

impl std::fmt::Display for Row {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Every `DIR/NAME/mobility.urdf`, as rows named NAME in name order.
pub fn object_rows(dir: &std::path::Path) -> Result<Vec<Row>> {
    let entries = std::fs::read_dir(dir)
        .map_err(|e| EvalError::Episode(format!("--objects {}: {e}", dir.display())))?;
    let mut rows = Vec::new();
    for entry in entries {
        let entry =
            entry.map_err(|e| EvalError::Episode(format!("--objects {}: {e}", dir.display())))?;
        let urdf = entry.path().join("mobility.urdf");
        if urdf.is_file() {
            rows.push(Row::Object(ObjectRow {
                name: entry.file_name().to_string_lossy().into_owned(),
                urdf,
            }));
        }
    }
    rows.sort();
    if rows.is_empty() {
        return Err(EvalError::Episode(format!(
            "--objects {}: no NAME/mobility.urdf in it (python -m umpnet.objects import-mjcf writes that layout)",
            dir.display()
        )));
    }
    Ok(rows)
}

/// FNV-1a: a name's hash that stays the same across platforms and versions.
fn name_hash(name: &str) -> u64 {
    name.bytes().fold(0xCBF2_9CE4_8422_2325u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01B3)
    })
}

/// The seed of scene `k` of a row. A category's is [`scene_seed`]'s; an
/// object's depends on its name, not on where its folder is.
pub fn row_seed(seed: u64, task: Task, row: &Row, k: u32) -> u64 {
    match row {
        Row::Category(c) => scene_seed(seed, task, *c, k),
        Row::Instances(r) => scene_seed(seed, task, r.category, k),
        Row::Object(o) => mix(&[seed, task as u64, u64::MAX, name_hash(&o.name), k as u64]),
    }
}

/// The seed of the policy's own random choices on scene `k` of a row.
pub fn policy_seed(seed: u64, task: Task, row: &Row, k: u32) -> u64 {
    row_seed(seed ^ 0x5EED, task, row, k)
}

/// Scene `k` of a row: for a category, [`benchmark_scene`]; for an object,
/// its file placed and posed by the protocol, a goal on a joint the camera sees.
pub fn row_scene(
    seed: u64,
    task: Task,
    row: &Row,
    k: u32,
    dataset_seed: u64,
    physics: PhysicsProfile,
) -> Result<Scene> {
    match row {
        Row::Category(c) => benchmark_scene(seed, task, *c, k, dataset_seed, physics),
        Row::Object(o) => sample_visible_scene(
            &mut ChaCha8Rng::seed_from_u64(row_seed(seed, task, row, k)),
            task,
            None,
            ObjectSource::file(o.urdf.clone()),
            physics,
        ),
        Row::Instances(r) => {
            let instance = r
                .instances
                .get(k as usize % r.instances.len().max(1))
                .ok_or_else(|| {
                    EvalError::Episode(format!("{}: no instances", r.category.name()))
                })?;
            sample_visible_scene(
                &mut ChaCha8Rng::seed_from_u64(row_seed(seed, task, row, k)),
                task,
                Some(r.category),
                ObjectSource::file(instance.urdf.clone()),
                physics,
            )
        }
    }
}

/// The seed of scene `k` of a category's row.
pub fn scene_seed(seed: u64, task: Task, category: Category, k: u32) -> u64 {
    let c = Category::ALL
        .iter()
        .position(|x| *x == category)
        .unwrap_or(0) as u64;
    mix(&[seed, task as u64, c, k as u64])
}

/// Scene `k` of a category's benchmark: a test instance, placed and posed by
/// the protocol; goal scenes set their goal on a joint the camera sees.
pub fn benchmark_scene(
    seed: u64,
    task: Task,
    category: Category,
    k: u32,
    dataset_seed: u64,
    physics: PhysicsProfile,
) -> Result<Scene> {
    let index = nth_instance(category, InstanceSplit::Test, k % INSTANCES_PER_CATEGORY);
    let object = ObjectSource::Generated {
        category,
        index,
        dataset_seed,
    };
    sample_visible_scene(
        &mut ChaCha8Rng::seed_from_u64(scene_seed(seed, task, category, k)),
        task,
        Some(category),
        object,
        physics,
    )
}

/// Samples a scene whose (goal) joint's links are visible in a small CPU
/// render, placed as the object's file says (see [`ObjectSource::pose`]).
pub fn sample_visible_scene(
    rng: &mut ChaCha8Rng,
    task: Task,
    category: Option<Category>,
    object: ObjectSource,
    physics: PhysicsProfile,
) -> Result<Scene> {
    let model = object.load_scaled()?;
    let mut last = None;
    // One environment for every try: `reset` keeps the loaded object and its meshes.
    let mut env: Option<SimEnv> = None;
    for _ in 0..20 {
        let mut scene = sample_scene(rng, task, category, object.clone(), &model, None)?;
        scene.physics = physics;
        let env = match env.as_mut() {
            Some(e) => {
                e.reset(scene.clone())?;
                e
            }
            None => env.insert(SimEnv::new(
                scene.clone(),
                Camera::reference(96, 128),
                Box::new(CpuRenderer::default()),
            )?),
        };
        let frame = env.render()?;
        let mut pixels = vec![0usize; model.joints.len()];
        for &s in &frame.segmentation {
            if let Segment::Link { link, .. } = Segment::decode(s)
                && let Some(j) = env.joint_moving_link(link)
            {
                pixels[j] += 1;
            }
        }
        let visible = |j: usize| pixels[j] >= 12;
        let ok = match &scene.goal {
            Some(g) => visible(g.joint),
            None => (0..pixels.len()).any(visible),
        };
        if ok {
            return Ok(scene);
        }
        last = Some(scene);
    }
    last.ok_or_else(|| EvalError::Episode("no scene sampled".into()))
}

/// What one benchmark run evaluates, and how.
#[derive(Clone, Debug)]
pub struct BenchConfig {
    /// Exploration or goal.
    pub task: Task,
    /// The table's rows: categories, object files, or both.
    pub rows: Vec<Row>,
    /// Scenes per row.
    pub episodes_per_category: u32,
    /// The run's seed: scenes and policies' seeds derive from it.
    pub seed: u64,
    /// Seed of the generated objects.
    pub dataset_seed: u64,
    /// The camera of every policy not in `policy_cameras`.
    pub camera: Camera,
    /// Policies that see their own camera (a learned package sees its input
    /// resolution); the scenes are the same for every policy.
    pub policy_cameras: std::collections::BTreeMap<String, Camera>,
    /// The renderer every episode uses.
    pub renderer: RendererKind,
    /// Step budget override (default: the protocol's).
    pub steps: Option<usize>,
    /// The physics every episode runs.
    pub physics: PhysicsProfile,
    /// How episodes end and are scored.
    pub protocol: Protocol,
    /// Which share of the scenes to run (all of them by default).
    pub shard: Shard,
}

impl BenchConfig {
    /// How many scenes this configuration runs (its shard's share). Counted,
    /// never listed: a run of billions of scenes starts at once.
    pub fn scene_count(&self) -> u64 {
        self.shard
            .scene_count(self.rows.len() as u64, self.episodes_per_category)
    }

    /// Scene `i` of this configuration (`i < scene_count()`), as (row,
    /// index), in the canonical order that results are reported in.
    pub fn scene_at(&self, i: u64) -> Option<(&Row, u32)> {
        let (row, k) =
            self.shard
                .scene_at(self.rows.len() as u64, self.episodes_per_category, i)?;
        Some((self.rows.get(usize::try_from(row).ok()?)?, k))
    }

    /// The scenes this configuration runs, as (row, index), in the
    /// canonical order that results are reported in; generated lazily.
    pub fn scenes(&self) -> impl Iterator<Item = (&Row, u32)> + '_ {
        (0..self.scene_count()).filter_map(|i| self.scene_at(i))
    }
}

/// One line of episodes.jsonl: a policy's episode on one scene of a row.
#[derive(Clone, Debug, serde::Serialize)]
pub struct EpisodeOutcome {
    /// The row: a category, or an object file's name (one of the two).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub category: Option<Category>,
    /// The object row's name.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub object: Option<String>,
    /// The scene's index within its row.
    pub index: u32,
    /// The policy's name.
    pub policy: String,
    /// The episode, unless it failed.
    pub episode: Option<Episode>,
    /// Why the episode failed (with its scene), if it did.
    pub error: Option<String>,
}

/// Runs every policy on every scene and returns the outcomes in canonical
/// order. Holds them all in memory: large runs use [`stream_benchmark`].
pub fn run_benchmark(
    cfg: &BenchConfig,
    policies: &[(String, PolicyFactory)],
    progress: &(dyn Fn() + Sync),
) -> Vec<EpisodeOutcome> {
    let mut all = Vec::new();
    let never = AtomicBool::new(false);
    let sink = |_: u64, scene: Vec<EpisodeOutcome>| -> std::result::Result<(), ()> {
        all.extend(scene);
        Ok(())
    };
    let _ = stream_benchmark(cfg, policies, 0, 64, &never, progress, sink);
    all
}

/// Runs scenes `from..scene_count()` in canonical order, `chunk` scenes at a
/// time in parallel, and hands each scene's outcomes (one per policy, in the
/// policies' order) to `sink` in that order, with the scene's number. Memory
/// holds one chunk, whatever the number of scenes. Once `stop` is set no new
/// scene starts; the scenes already finished are still handed over, in
/// order. Returns the number of the first scene not handed over.
pub fn stream_benchmark<E>(
    cfg: &BenchConfig,
    policies: &[(String, PolicyFactory)],
    from: u64,
    chunk: usize,
    stop: &AtomicBool,
    progress: &(dyn Fn() + Sync),
    mut sink: impl FnMut(u64, Vec<EpisodeOutcome>) -> std::result::Result<(), E>,
) -> std::result::Result<u64, E> {
    let total = cfg.scene_count();
    let chunk = chunk.max(1) as u64;
    let mut next = from;
    while next < total {
        if stop.load(Ordering::Relaxed) {
            return Ok(next);
        }
        let end = total.min(next.saturating_add(chunk));
        let done: Vec<Option<Vec<EpisodeOutcome>>> = (next..end)
            .into_par_iter()
            .map(|i| {
                if stop.load(Ordering::Relaxed) {
                    return None;
                }
                let (row, k) = cfg.scene_at(i)?;
                let out = run_scene(cfg, policies, row, k);
                progress();
                Some(out)
            })
            .collect();
        for outcomes in done {
            let Some(outcomes) = outcomes else {
                return Ok(next);
            };
            sink(next, outcomes)?;
            next += 1;
        }
    }
    Ok(next)
}

fn run_scene(
    cfg: &BenchConfig,
    policies: &[(String, PolicyFactory)],
    row: &Row,
    k: u32,
) -> Vec<EpisodeOutcome> {
    policies
        .iter()
        .map(|(name, make)| {
            let (episode, error) = match run_one(cfg, name, make, row, k, None) {
                Ok(ep) => (Some(ep), None),
                Err(e) => (None, Some(e.to_string())),
            };
            EpisodeOutcome {
                category: row.category(),
                object: match row {
                    Row::Object(o) => Some(o.name.clone()),
                    Row::Category(_) | Row::Instances(_) => None,
                },
                index: k,
                policy: name.clone(),
                episode,
                error,
            }
        })
        .collect()
}

/// One episode of the benchmark: `policy` on scene `k` of `row`, exactly
/// as `run_benchmark` runs it (the same scene, seed, camera and budget), with
/// an optional hook. Used to record chosen episodes again after a run.
pub fn run_one(
    cfg: &BenchConfig,
    name: &str,
    make: &PolicyFactory,
    row: &Row,
    k: u32,
    hook: Option<FrameHook<'_>>,
) -> Result<Episode> {
    let scene = row_scene(cfg.seed, cfg.task, row, k, cfg.dataset_seed, cfg.physics)
        .map_err(|e| EvalError::Episode(e.to_string()))?;
    let budget = cfg
        .steps
        .unwrap_or_else(|| cfg.protocol.budget(cfg.task, row.category()));
    let mut policy = make()?;
    let renderer = create_renderer(cfg.renderer)?;
    let seed = policy_seed(cfg.seed, cfg.task, row, k);
    run_episode(
        &scene,
        cfg.policy_cameras.get(name).unwrap_or(&cfg.camera),
        renderer,
        policy.as_mut(),
        EpisodeConfig {
            budget,
            seed,
            protocol: cfg.protocol,
        },
        hook,
    )
    .map_err(|e| EvalError::Episode(format!("{e} (scene: {})", scene.to_json())))
}
