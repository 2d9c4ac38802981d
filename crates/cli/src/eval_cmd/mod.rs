//! `umpnet eval`: the paper's benchmark over categories, scenes and
//! policies, whole or in shards, and `umpnet eval merge` to join shards.
mod merge;
mod plot;
mod report;
mod rows;
mod stream;
mod tables;

use crate::{Ctx, usage};
use anyhow::{Context, Result};
use report::{Aggregate, Report, RunInfo, Scored};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use stream::{EpisodeWriter, RunState};
use umpnet_eval::Protocol;
use umpnet_eval::benchmark::{BenchConfig, PolicyFactory, Row, Shard, stream_benchmark};
use umpnet_sim::objects::Category;
use umpnet_sim::physics::PhysicsProfile;
use umpnet_sim::render::{RendererKind, create_renderer};
use umpnet_sim::scene::Task;

#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct EvalCmd {
    #[command(subcommand)]
    pub action: Option<EvalAction>,
    #[command(flatten)]
    pub run: EvalArgs,
}

#[derive(clap::Subcommand)]
pub enum EvalAction {
    /// Join the results.json of `eval --shard K/N` runs into the report of one
    /// whole run (the same tables, CSV, JSON and plot, byte for byte).
    Merge(merge::MergeArgs),
}

#[derive(clap::Args)]
pub struct EvalArgs {
    /// Exploration (novel-state ratio, single action effect, joint-axis error)
    /// or goal (success, normalised distance).
    #[arg(long, default_value = "exploration", value_parser = crate::choice::<Task>(crate::TASKS))]
    pub task: Task,
    /// Comma-separated categories (overrides --split).
    #[arg(long, value_delimiter = ',', value_parser = crate::parse_category)]
    pub categories: Vec<Category>,
    /// train (held-out instances of training categories), test (test categories) or all
    /// (the default, unless --objects is given alone).
    #[arg(long)]
    pub split: Option<String>,
    /// Also score every DIR/NAME/mobility.urdf, one row per object (NAME), on
    /// the same protocol; alone, only the objects. `python -m umpnet.objects`
    /// writes this layout from MJCF files.
    #[arg(long, value_name = "DIR")]
    pub objects: Option<PathBuf>,
    /// Score the categories on a local PartNet-Mobility folder instead of the
    /// generated objects: UMPNet's mobility_dataset (<Category>/<id>/) or
    /// PartNet's own layout (<id>/ with meta.json), each object with its
    /// object_meta_info.json. Instances come from --split-file.
    #[arg(long, value_name = "DIR")]
    pub partnet: Option<PathBuf>,
    /// The released split (split-full.json; default: DIR/split-full.json when
    /// present, else every instance found): a training category's held-out
    /// instances, every instance of a test category.
    #[arg(long, value_name = "FILE", requires = "partnet")]
    pub split_file: Option<PathBuf>,
    /// Scenes per row (category or object); every policy runs each scene.
    #[arg(long, default_value_t = 100)]
    pub episodes_per_category: u32,
    /// Comma-separated policies: random, oracle, umpnet (with --model) or NAME=MODEL_DIR.
    #[arg(long, value_delimiter = ',', default_value = "oracle,random")]
    pub policies: Vec<String>,
    #[command(flatten)]
    pub learned: crate::policies::LearnedArgs,
    /// Model package for `umpnet` (default: models/umpnet-gpu-medium).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Benchmark seed: the scenes, and each policy's seed per scene, derive from it.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Camera images (HEIGHTxWIDTH) of oracle and random; a learned policy
    /// sees its package's input resolution. All see the same scenes.
    #[arg(long, default_value = "120x160", value_parser = crate::parse_resolution)]
    pub resolution: (u32, u32),
    #[command(flatten)]
    pub sensor: crate::SensorArgs,
    /// Renderer: wgpu (a GPU, or Vulkan's CPU driver), cpu (built in), or auto
    /// (wgpu when an adapter exists, else cpu, with a notice).
    #[arg(long, default_value = "auto", value_parser = crate::choice::<RendererKind>(crate::RENDERERS))]
    pub renderer: RendererKind,
    /// Physics profile: reference (the paper's simulator) or ideal.
    #[arg(long, default_value = "reference", value_parser = crate::choice::<PhysicsProfile>(crate::PHYSICS))]
    pub physics: PhysicsProfile,
    /// Evaluation protocol: paper (the paper's evaluation code) or strict.
    #[arg(long, default_value = "paper", value_parser = crate::choice::<Protocol>(crate::PROTOCOLS))]
    pub protocol: Protocol,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=1024))]
    pub threads: Option<u16>,
    /// Run only shard K of N (1-based, e.g. 2/4): every N-th scene, starting
    /// at the K-th. `umpnet eval merge` joins the shards' --out directories.
    #[arg(long, value_parser = parse_shard)]
    pub shard: Option<Shard>,
    /// Write episodes.jsonl as episodes finish, then results.json, results.csv,
    /// table.txt, curve.png and curve.svg, here (a shard: episodes.jsonl and results.json).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace the results a previous run left in --out.
    #[arg(long, conflicts_with = "resume")]
    pub force: bool,
    /// Continue the interrupted run in --out (the same command, plus
    /// --resume): its whole scenes are kept, the rest are run, and the report
    /// is the one an uninterrupted run writes.
    #[arg(long, requires = "out")]
    pub resume: bool,
    /// Write Rerun recordings of chosen episodes here, one .rrd per episode
    /// (`{category}_{index}_{policy}.rrd`), replayed after the run and
    /// checked to be the episodes evaluated. Needs the `rerun` feature.
    #[arg(long)]
    pub rrd: Option<PathBuf>,
    /// With --rrd: record scenes 0..N of each category (of this shard), for every policy.
    #[arg(long, default_value_t = 1, requires = "rrd")]
    pub rrd_per_category: u32,
    /// With --rrd: the size of the recordings' display view (`world/display`),
    /// HEIGHTxWIDTH, whatever the policies see (`world/camera`).
    #[arg(long, default_value = "480x640", value_parser = crate::parse_resolution, requires = "rrd")]
    pub picture_size: (u32, u32),
}

fn parse_shard(s: &str) -> std::result::Result<Shard, String> {
    s.parse::<Shard>().map_err(|e| e.to_string())
}

/// SHA-256 over a package's files (names, sizes and bytes, in name order):
/// shards that loaded different packages under one name must not merge.
fn resolve_renderer(kind: RendererKind) -> Result<RendererKind> {
    if kind != RendererKind::Auto {
        return Ok(kind);
    }
    let probe = create_renderer(kind)?;
    Ok(if probe.name().starts_with("wgpu") {
        RendererKind::Wgpu
    } else {
        RendererKind::Cpu
    })
}

pub fn run(ctx: &Ctx, cmd: &EvalCmd) -> Result<()> {
    match &cmd.action {
        Some(EvalAction::Merge(m)) => merge::run(ctx, m),
        None => run_eval(ctx, &cmd.run),
    }
}

#[expect(
    clippy::too_many_lines,
    reason = "the eval command's setup, run and report in order; the next to split"
)]
fn run_eval(ctx: &Ctx, a: &EvalArgs) -> Result<()> {
    if a.episodes_per_category == 0 {
        return Err(usage("--episodes-per-category must be at least 1"));
    }
    let rows::TableRows {
        categories,
        rows,
        objects,
        partnet,
    } = rows::table_rows(&rows::RowRequest {
        categories: &a.categories,
        split: a.split.as_deref(),
        objects: a.objects.as_deref(),
        partnet: a.partnet.as_deref(),
        split_file: a.split_file.as_deref(),
    })?;

    let threads = a
        .threads
        .map_or_else(rayon::current_num_threads, usize::from)
        .max(1);
    // The oracle is the ceiling of every table, under the same protocol and physics.
    let mut listed = a.policies.clone();
    if !listed.iter().any(|p| p == "oracle") {
        listed.push("oracle".into());
    }
    let resolved = crate::policies::resolve(
        &listed,
        a.model.as_deref(),
        threads,
        a.task,
        a.learned.resolve(),
    )?;
    let mut models = BTreeMap::new();
    for (name, dir) in &resolved.packages {
        models.insert(name.clone(), rows::package_digest(dir)?);
    }
    let policies: Vec<(String, PolicyFactory)> = resolved.factories;
    let names: Vec<String> = policies.iter().map(|(n, _)| n.clone()).collect();
    // Scripted policies see --resolution, learned ones their package's input
    // resolution; every policy sees the same scenes. A policy's results thus
    // never depend on which others are listed beside it.
    let resolution = a.resolution;
    let resolutions: BTreeMap<String, [u32; 2]> = names
        .iter()
        .map(|n| {
            let (h, w) = resolved.resolutions.get(n).copied().unwrap_or(resolution);
            (n.clone(), [h, w])
        })
        .collect();
    let renderer = resolve_renderer(a.renderer)?;
    let shard = a.shard.unwrap_or_default();
    let cfg = BenchConfig {
        task: a.task,
        rows,
        episodes_per_category: a.episodes_per_category,
        seed: a.seed,
        dataset_seed: 0,
        camera: a.sensor.camera(resolution),
        policy_cameras: resolved
            .resolutions
            .iter()
            .map(|(n, size)| (n.clone(), a.sensor.camera(*size)))
            .collect(),
        renderer,
        steps: None,
        physics: a.physics,
        protocol: a.protocol,
        shard,
    };
    let run = RunInfo {
        umpnet_version: env!("CARGO_PKG_VERSION").into(),
        task: a.task,
        seed: a.seed,
        episodes_per_category: a.episodes_per_category,
        physics: a.physics,
        protocol: a.protocol,
        resolution: [resolution.0, resolution.1],
        resolutions,
        renderer: match renderer {
            RendererKind::Wgpu => "wgpu",
            _ => "cpu",
        }
        .into(),
        policies: names,
        models,
        categories,
        objects,
        partnet,
        direction_filter: a.learned.direction_filter.map(|f| f.name().to_owned()),
        grasp_rule: a.learned.grasp_rule.map(|g| g.name().to_owned()),
        sampler: a
            .learned
            .sampler()
            .map(|s| format!("{} {}", s.name(), s.samples())),
        mirror_average: a.learned.mirror_average,
        glass_depth: a.sensor.glass_depth,
    };
    if let Some(dir) = &a.out
        && !a.force
        && !a.resume
        && dir.join(stream::RUN).exists()
        && !dir.join("results.json").exists()
    {
        return Err(usage(format!(
            "{} holds an interrupted evaluation ({}); the same command with --resume \
             continues it, --force starts over",
            dir.display(),
            stream::RUN
        )));
    }
    // Claimed before the long run, so a conflict is known at once.
    let _claim = a
        .out
        .as_deref()
        .map(|dir| crate::outdir::claim(dir, a.force || a.resume, Report::FILES))
        .transpose()?;
    if let Some(dir) = &a.rrd {
        crate::rrd::check(dir)?;
    }
    let mut agg = Aggregate::new(a.task);
    // The evaluated episodes that --rrd records again, to check the replays.
    let mut evaluated: Vec<(Scored, String)> = Vec::new();
    let recorded = |s: &Scored| a.rrd.is_some() && s.index < a.rrd_per_category;
    let mut wall_before = 0.0;
    let mut start = 0;
    let mut writer = match &a.out {
        Some(dir) if a.resume => {
            let r = stream::resume(dir, &run, shard, &mut agg, |s, text| {
                if recorded(&s) {
                    evaluated.push((s, text));
                }
            })?;
            wall_before = r.wall_seconds;
            start = r.scenes;
            Some(r.writer)
        }
        Some(dir) => {
            // A forced run replaces the whole previous report at once: the
            // folder never mixes an old summary with new episodes.
            for f in Report::FILES {
                let p = dir.join(f);
                if p.exists() {
                    std::fs::remove_file(&p)
                        .with_context(|| format!("{}: cannot replace", p.display()))?;
                }
            }
            Some(EpisodeWriter::create(&dir.join(stream::EPISODES))?)
        }
        None => None,
    };
    let save_state = |wall: f64| -> Result<()> {
        match &a.out {
            Some(dir) => RunState {
                run: run.clone(),
                shard: shard.to_string(),
                wall_seconds: wall,
            }
            .write(dir),
            None => Ok(()),
        }
    };
    save_state(wall_before)?;
    let scenes = cfg.scene_count();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads.map_or(0, usize::from))
        .build()?;
    let pb = ctx.progress(scenes, "scenes");
    pb.set_position(start);
    pb.reset_eta();
    let stop = crate::signals::stop_flag();
    let t0 = std::time::Instant::now();
    // Enough scenes per chunk that waiting for its slowest costs little; a chunk's episodes
    // are written (and committed) in canonical order before the next starts.
    let chunk = pool.current_num_threads().max(1) * 32;
    let sink = |i: u64, outcomes: Vec<umpnet_eval::benchmark::EpisodeOutcome>| -> Result<()> {
        for o in &outcomes {
            let text = serde_json::to_string(o)?;
            let s = Scored::parse(&text).context("an episode outcome that does not read back")?;
            agg.add(&s);
            if let Some(w) = writer.as_mut() {
                w.push(&text)?;
            }
            if recorded(&s) {
                evaluated.push((s, text));
            }
        }
        // Whole chunks only: commit once the chunk's last scene is in.
        if (i + 1 - start).is_multiple_of(chunk as u64) || i + 1 == scenes {
            if let Some(w) = writer.as_mut() {
                w.commit()?;
            }
            save_state(wall_before + t0.elapsed().as_secs_f64())?;
        }
        Ok(())
    };
    let done = pool
        .install(|| stream_benchmark(&cfg, &policies, start, chunk, stop, &|| pb.inc(1), sink))?;
    pb.finish_and_clear();
    let wall = wall_before + t0.elapsed().as_secs_f64();
    if let Some(w) = writer.as_mut() {
        w.commit()?;
    }
    save_state(wall)?;
    if done < scenes {
        let how = match &a.out {
            Some(dir) => format!(
                "{} holds them; the same command with --resume continues",
                dir.display()
            ),
            None => "nothing was written (no --out)".into(),
        };
        return Err(crate::signals::Interrupted(format!(
            "interrupted after {done} of {scenes} scenes; {how}"
        ))
        .into());
    }
    for f in &agg.failures {
        eprintln!("episode failed: {f}");
    }
    let report = Report {
        run,
        shard,
        wall_seconds: wall,
        agg,
        episodes_file: writer.as_ref().map(EpisodeWriter::digest),
    };
    finish(ctx, &report, a.out.as_deref(), scenes)?;
    if let Some(dir) = &a.rrd {
        let n = record(
            &cfg,
            &policies,
            &evaluated,
            dir,
            (a.rrd_per_category, a.picture_size),
        )?;
        if !ctx.json {
            outln!("recorded {n} episodes to {}", dir.display());
        }
    }
    Ok(())
}

/// Replays the chosen episodes with a Rerun recorder; each must be the
/// episode the run evaluated, step for step.
fn record(
    cfg: &BenchConfig,
    policies: &[(String, PolicyFactory)],
    evaluated: &[(Scored, String)],
    dir: &Path,
    (per_category, picture_size): (u32, (u32, u32)),
) -> Result<usize> {
    let mut n = 0;
    let per_row = per_category.min(cfg.episodes_per_category);
    let mine = cfg.rows.iter().enumerate().flat_map(|(r, row)| {
        (0..per_row).filter_map(move |k| {
            let position = r as u64 * u64::from(cfg.episodes_per_category) + u64::from(k);
            cfg.shard.holds(position).then_some((row, k))
        })
    });
    for (row, k) in mine {
        for (name, make) in policies {
            let path = dir.join(format!("{row}_{k}_{name}.rrd"));
            let mut recorder = crate::rrd::Recorder::create(
                &path,
                &format!("{name}: {row} #{k}"),
                Some((picture_size, cfg.renderer)),
            )?;
            let mut failed: Option<anyhow::Error> = None;
            let mut hook = |h: &umpnet_eval::episode::HookFrame<'_>| {
                if failed.is_none()
                    && let Err(e) = recorder.log(h)
                {
                    failed = Some(e);
                }
            };
            let replayed =
                umpnet_eval::benchmark::run_one(cfg, name, make, row, k, Some(&mut hook));
            if let Some(e) = failed {
                return Err(e);
            }
            recorder.finish()?;
            let evaluated = evaluated
                .iter()
                .find(|(o, _)| {
                    o.category == row.category()
                        && o.object.as_deref() == matches!(row, Row::Object(_)).then(|| row.name())
                        && o.index == k
                        && &o.policy == name
                })
                .map(|(_, text)| serde_json::from_str::<serde_json::Value>(text))
                .transpose()?;
            if let (Ok(ep), Some(evaluated)) = (&replayed, evaluated)
                // Both through the same text: the evaluated episode was read
                // back from its JSON line, f32 as written there.
                && Some(&serde_json::from_str::<serde_json::Value>(&serde_json::to_string(ep)?)?)
                    != evaluated.get("episode")
            {
                anyhow::bail!(
                    "{}: the replayed episode differs from the evaluated one (a determinism bug)",
                    path.display()
                );
            }
            n += 1;
        }
    }
    Ok(n)
}

/// Prints the report (a table, or the summary with --json) and writes its files.
fn finish(ctx: &Ctx, report: &Report, out: Option<&Path>, scenes: u64) -> Result<()> {
    let written = match out {
        Some(dir) => report.write(dir)?,
        None => Vec::new(),
    };
    if ctx.json {
        outln!("{}", report.summary()?);
        return Ok(());
    }
    if !report.shard.is_all() {
        outln!(
            "shard {}: its share of the scenes only; `umpnet eval merge` joins the shards",
            report.shard
        );
    }
    out!("{}", report.table());
    // Which images each policy saw (learned packages see their input resolution).
    let mut groups: BTreeMap<[u32; 2], Vec<&str>> = BTreeMap::new();
    for (name, res) in &report.run.resolutions {
        groups.entry(*res).or_default().push(name);
    }
    let seen: Vec<String> = groups
        .iter()
        .rev()
        .map(|([h, w], names)| format!("{} at {h}x{w}", names.join(", ")))
        .collect();
    if !seen.is_empty() {
        outln!("images: {} (same scenes for all)", seen.join("; "));
    }
    outln!(
        "{} episodes ({} scenes x {} policies) in {:.1} s; {} failed",
        report.agg.episodes,
        scenes,
        report.run.policies.len(),
        report.wall_seconds,
        report.agg.failed
    );
    if let Some(dir) = out {
        let mut files = written;
        if report.episodes_file.is_some() {
            files.insert(0, stream::EPISODES);
        }
        outln!("wrote {} to {}", files.join(", "), dir.display());
    }
    Ok(())
}
