//! `umpnet eval merge`: the shards of one evaluation back into its report.
//! Scenes are pure functions of (seed, task, category, index), so the merged
//! report is the unsharded one, byte for byte except `wall_seconds` (here the
//! sum of the shards' wall times).
use super::report::{Report, RunInfo, Scored};
use crate::{Ctx, usage};
use anyhow::{Context, Result};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use umpnet_eval::bench::Shard;

#[derive(clap::Args)]
pub struct MergeArgs {
    /// Shard output directories (each holding the results.json of an
    /// `umpnet eval --shard K/N --out DIR` run), or the results.json files.
    #[arg(required = true, num_args = 1..)]
    pub shards: Vec<PathBuf>,
    /// Write results.csv, results.json, table.txt and curve.png here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace the results a previous run left in --out.
    #[arg(long)]
    pub force: bool,
}

#[derive(serde::Deserialize)]
struct ShardFile {
    summary: ShardSummary,
    episodes: Vec<serde_json::Value>,
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

/// The fields of two runs' information that differ, by name.
fn differing_fields(a: &RunInfo, b: &RunInfo) -> Vec<String> {
    let (Ok(serde_json::Value::Object(a)), Ok(serde_json::Value::Object(b))) =
        (serde_json::to_value(a), serde_json::to_value(b))
    else {
        return vec!["(unreadable)".into()];
    };
    a.iter()
        .filter(|(k, v)| b.get(*k) != Some(v))
        .map(|(k, v)| {
            let other = b.get(k).map(|x| x.to_string()).unwrap_or_default();
            format!("{k} ({v} against {other})")
        })
        .collect()
}

pub fn run(ctx: &Ctx, a: &MergeArgs) -> Result<()> {
    let mut first: Option<(PathBuf, RunInfo)> = None;
    let mut by_index: BTreeMap<u32, PathBuf> = BTreeMap::new();
    let mut count: Option<u32> = None;
    let mut wall = 0.0;
    let mut episodes = Vec::new();
    for arg in &a.shards {
        let path = results_path(arg);
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
        if let Some(other) = by_index.insert(shard.index, path.clone()) {
            return Err(usage(format!(
                "shard {shard} given twice: {} and {}",
                other.display(),
                path.display()
            )));
        }
        wall += file.summary.wall_seconds;
        episodes.extend(file.episodes);
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
    let mut report = Report {
        run,
        shard: Shard::ALL,
        wall_seconds: wall,
        episodes,
    };
    sort_canonically(&mut report)?;
    let scenes = report.run.rows().len() * report.run.episodes_per_category as usize;
    let _claim = a
        .out
        .as_deref()
        .map(|dir| crate::outdir::claim(dir, a.force, Report::FILES))
        .transpose()?;
    super::finish(ctx, &report, a.out.as_deref(), scenes)
}

/// Puts the episodes in the order a single run reports them (category as
/// listed, scene index, policy as listed) and checks that each is there once.
fn sort_canonically(report: &mut Report) -> Result<()> {
    let scored: Vec<Scored> = report.scored()?;
    let run = &report.run;
    let rows = run.rows();
    let mut keyed = Vec::with_capacity(scored.len());
    for (o, value) in scored.iter().zip(std::mem::take(&mut report.episodes)) {
        let row = o.row();
        let name = row.as_ref().map_or("?", |r| r.name()).to_owned();
        let c = row.and_then(|row| rows.iter().position(|r| *r == row));
        let p = run.policies.iter().position(|p| *p == o.policy);
        let (Some(c), Some(p)) = (c, p) else {
            return Err(usage(format!(
                "episode {name} #{} of policy `{}` is outside the evaluation's rows or policies",
                o.index, o.policy
            )));
        };
        if o.index >= run.episodes_per_category {
            return Err(usage(format!(
                "episode {name} #{} is beyond episodes_per_category {}",
                o.index, run.episodes_per_category
            )));
        }
        keyed.push(((c, o.index, p), value));
    }
    keyed.sort_by_key(|(k, _)| *k);
    let twice = keyed.windows(2).find_map(|w| match w {
        [a, b] if a.0 == b.0 => Some(a.0),
        _ => None,
    });
    if let Some((c, k, p)) = twice {
        return Err(usage(format!(
            "episode {} #{k} of policy `{}` appears in more than one shard",
            rows.get(c).map_or("?", |c| c.name()),
            run.policies.get(p).map_or("?", String::as_str)
        )));
    }
    let expected = rows.len() * run.episodes_per_category as usize * run.policies.len();
    if keyed.len() != expected {
        return Err(usage(format!(
            "the shards hold {} episodes; the evaluation has {expected}",
            keyed.len()
        )));
    }
    report.episodes = keyed.into_iter().map(|(_, v)| v).collect();
    Ok(())
}
