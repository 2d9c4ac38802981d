//! `umpnet eval merge`: the shards of one evaluation back into its report.
//! Scenes are pure functions of (seed, task, category, index), so the merged
//! report is the unsharded one, byte for byte except `wall_seconds` (here the
//! sum of the shards' wall times). The shards' episodes files are read in
//! step, one line at a time: memory does not grow with their size.
use super::report::{Aggregate, Report, RunInfo};
use super::stream::{self, EpisodeWriter, LineReader, differing_fields};
use crate::{Ctx, usage};
use anyhow::{Context, Result};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use umpnet_eval::benchmark::Shard;

#[derive(clap::Args)]
pub struct MergeArgs {
    /// Shard output directories (each holding the results.json of an
    /// `umpnet eval --shard K/N --out DIR` run), or the results.json files.
    #[arg(required = true, num_args = 1..)]
    pub shards: Vec<PathBuf>,
    /// Write results.csv, results.json, table.txt, curve.png and curve.svg here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace the results a previous run left in --out.
    #[arg(long)]
    pub force: bool,
}

#[derive(serde::Deserialize)]
struct ShardFile {
    summary: ShardSummary,
    #[serde(default)]
    episodes_file: Option<String>,
    #[serde(default)]
    episodes_sha256: Option<String>,
}

#[derive(serde::Deserialize)]
struct ShardSummary {
    #[serde(flatten)]
    run: RunInfo,
    wall_seconds: f64,
    #[serde(default)]
    shard: Option<String>,
}

fn results_path(p: &Path) -> PathBuf {
    if p.is_dir() {
        p.join("results.json")
    } else {
        p.to_path_buf()
    }
}

/// One shard being merged: its episodes file, read in step with the others.
struct Open {
    shard: Shard,
    path: PathBuf,
    lines: LineReader,
    sha256: String,
}

/// The episodes file a shard's results.json names: a plain file beside it.
fn episodes_of(path: &Path, file: &ShardFile) -> Result<(PathBuf, String)> {
    let (Some(name), Some(sha)) = (&file.episodes_file, &file.episodes_sha256) else {
        return Err(usage(format!(
            "{}: names no episodes file (a results.json from before episodes were \
             streamed, or not a shard's); run the shard again",
            path.display()
        )));
    };
    let plain = Path::new(name)
        .file_name()
        .is_some_and(|f| f == std::ffi::OsStr::new(name));
    if !plain {
        return Err(usage(format!(
            "{}: episodes_file `{name}`: expected a file name beside it",
            path.display()
        )));
    }
    let dir = path.parent().unwrap_or(Path::new("."));
    Ok((dir.join(name), sha.clone()))
}

#[expect(
    clippy::too_many_lines,
    reason = "the merge's checks of every shard against the first, in one place"
)]
pub fn run(ctx: &Ctx, a: &MergeArgs) -> Result<()> {
    let mut first: Option<(PathBuf, RunInfo)> = None;
    let mut by_index: BTreeMap<u32, Open> = BTreeMap::new();
    let mut count: Option<u32> = None;
    let mut wall = 0.0;
    if a.shards.len() as u64 + 64 > crate::signals::raise_open_files() {
        return Err(usage(format!(
            "{} shards: more than the open files this system allows (ulimit -n); \
             merge them in groups of shards of a coarser split",
            a.shards.len()
        )));
    }
    for arg in &a.shards {
        let path = results_path(arg);
        let meta =
            std::fs::metadata(&path).with_context(|| format!("reading {}", path.display()))?;
        if !meta.is_file() || meta.len() > 64 << 20 {
            return Err(usage(format!(
                "{}: not the results.json of an `umpnet eval --shard` run",
                path.display()
            )));
        }
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("reading {}", path.display()))?;
        let file: ShardFile = serde_json::from_str(&text).with_context(|| {
            format!(
                "{}: not the results.json of an `umpnet eval --shard` run",
                path.display()
            )
        })?;
        let shard: Shard = match &file.summary.shard {
            Some(s) => s
                .parse()
                .map_err(|e| usage(format!("{}: summary.shard: {e}", path.display())))?,
            None => {
                return Err(usage(format!(
                    "{}: a whole evaluation (no summary.shard), not a shard",
                    path.display()
                )));
            }
        };
        match &first {
            None => first = Some((path.clone(), file.summary.run.clone())),
            Some((p0, run0)) => {
                let diff = differing_fields(&file.summary.run, run0);
                if !diff.is_empty() {
                    return Err(usage(format!(
                        "{} is not a shard of the same evaluation as {}: {}",
                        path.display(),
                        p0.display(),
                        diff.join("; ")
                    )));
                }
            }
        }
        if let Some(n) = count.filter(|n| *n != shard.count) {
            return Err(usage(format!(
                "{}: shard {shard}, but the others are shards of {n}",
                path.display()
            )));
        }
        count = Some(shard.count);
        if let Some(other) = by_index.get(&shard.index) {
            return Err(usage(format!(
                "shard {shard} given twice: {} and {}",
                other.path.display(),
                path.display()
            )));
        }
        let (episodes, sha256) = episodes_of(&path, &file)?;
        wall += file.summary.wall_seconds;
        by_index.insert(
            shard.index,
            Open {
                shard,
                path: path.clone(),
                lines: LineReader::open(&episodes)?,
                sha256,
            },
        );
    }
    let (Some((_, run)), Some(count)) = (first, count) else {
        return Err(usage("no shards given"));
    };
    let missing: Vec<String> = (1..=count)
        .filter(|k| !by_index.contains_key(k))
        .map(|k| format!("{k}/{count}"))
        .collect();
    if !missing.is_empty() {
        return Err(usage(format!("missing shards: {}", missing.join(", "))));
    }
    let _claim = a
        .out
        .as_deref()
        .map(|dir| crate::outdir::claim(dir, a.force, Report::FILES))
        .transpose()?;
    let mut writer = a
        .out
        .as_deref()
        .map(|dir| EpisodeWriter::create(&dir.join(stream::EPISODES)))
        .transpose()?;
    let mut shards: Vec<Open> = by_index.into_values().collect();
    let rows = run.rows();
    let per_scene = run.policies.len() as u64;
    let scenes = Shard::ALL.scene_count(rows.len() as u64, run.episodes_per_category);
    let mut agg = Aggregate::new(run.task);
    let pb = ctx.progress(scenes, "scenes");
    // Scene g of the whole run is scene g / N of shard g mod N (round robin):
    // reading the shards in turn yields the canonical order.
    for g in 0..scenes {
        let Some(open) = shards.get_mut((g % u64::from(count)) as usize) else {
            break;
        };
        for p in 0..per_scene {
            let line = g * per_scene + p;
            let own = open.lines.lines;
            let file = open.lines.path().to_path_buf();
            let Some(text) = open.lines.next_line()? else {
                return Err(usage(format!(
                    "shard {} ({}): {} ends after {own} episodes; the shard has {}",
                    open.shard,
                    open.path.display(),
                    open.lines.path().display(),
                    open.shard
                        .scene_count(rows.len() as u64, run.episodes_per_category)
                        * per_scene
                )));
            };
            let s = run.check_line(&rows, Shard::ALL, line, text).map_err(|e| {
                usage(format!(
                    "shard {} ({}) line {}: {e:#}",
                    open.shard,
                    file.display(),
                    own + 1
                ))
            })?;
            agg.add(&s);
            if let Some(w) = writer.as_mut() {
                w.push(text)?;
            }
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    for open in &mut shards {
        if open.lines.next_line()?.is_some() || open.lines.cut > 0 {
            return Err(usage(format!(
                "shard {} ({}): {} holds more episodes than the shard has",
                open.shard,
                open.path.display(),
                open.lines.path().display()
            )));
        }
        if open.lines.sha256() != open.sha256 {
            return Err(usage(format!(
                "shard {} ({}): {} is not the file its results.json was written with \
                 (its SHA-256 differs)",
                open.shard,
                open.path.display(),
                open.lines.path().display()
            )));
        }
    }
    if let Some(w) = writer.as_mut() {
        w.commit()?;
    }
    let report = Report {
        run,
        shard: Shard::ALL,
        wall_seconds: wall,
        agg,
        episodes_file: writer.as_ref().map(EpisodeWriter::digest),
    };
    super::finish(ctx, &report, a.out.as_deref(), scenes)
}
