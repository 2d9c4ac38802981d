//! What an evaluation reports: running aggregates of its episodes (read
//! back as JSON lines, in canonical order), then the summary, the tables,
//! results.csv/json, table.txt and curve.png/svg. A single run, a resumed run and
//! a merge of shards feed this same code the same lines in the same order,
//! which is what makes their reports byte-identical. Memory holds one
//! running statistic per cell and one sum per curve step, whatever the
//! number of episodes.
use anyhow::{Context, Result, bail};
use std::collections::BTreeMap;
use std::path::Path;
use umpnet_eval::Protocol;
use umpnet_eval::benchmark::Shard;
use umpnet_eval::episode::Metrics;
use umpnet_sim::objects::Category;
use umpnet_sim::physics::PhysicsProfile;
use umpnet_sim::scene::Task;

/// Everything that decides an evaluation's episodes. Shards merge only when
/// theirs are equal.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunInfo {
    /// The umpnet that ran (the crate version).
    pub umpnet_version: String,
    pub task: Task,
    pub seed: u64,
    pub episodes_per_category: u32,
    pub physics: PhysicsProfile,
    pub protocol: Protocol,
    /// (height, width) of the scripted policies' camera images.
    pub resolution: [u32; 2],
    /// (height, width) each policy saw: learned packages see their input resolution.
    #[serde(default)]
    pub resolutions: BTreeMap<String, [u32; 2]>,
    /// The renderer that ran (`wgpu` or `cpu`, `auto` resolved).
    pub renderer: String,
    pub policies: Vec<String>,
    /// Learned policies' packages by policy name: SHA-256 of their files.
    pub models: BTreeMap<String, String>,
    pub categories: Vec<Category>,
    /// Object files scored as rows (`eval --objects`), after the categories.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub objects: Vec<ObjectInfo>,
    /// `eval --partnet`: the categories' instances came from this folder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub partnet: Option<PartnetInfo>,
    /// `--direction-filter`: the filter every learned policy ran under, when
    /// not its package's own.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub direction_filter: Option<String>,
    /// The grasp rule that replaced the packages' (`--grasp-rule`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grasp_rule: Option<String>,
    /// `--sampler`/`--cem-samples`: how every learned policy drew its
    /// candidates (`cem 32`, `uniform 64`), when not the paper's CEM with 64.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sampler: Option<String>,
    /// `--mirror-average`: every learned policy averaged its scores with
    /// the mirrored scene's.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub mirror_average: bool,
    /// `--glass-depth`: what every camera's depth read through glass, when
    /// not the pane's own surface.
    #[serde(
        default,
        skip_serializing_if = "umpnet_sim::camera::GlassDepth::is_surface"
    )]
    pub glass_depth: umpnet_sim::camera::GlassDepth,
}

/// The PartNet-Mobility folder a run's categories were scored on: the
/// folder, the split file and its SHA-256, and each instance (`Category/id`)
/// with its folder's SHA-256.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PartnetInfo {
    pub dir: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub split_file: Option<String>,
    pub instances: Vec<ObjectInfo>,
}

/// One object row: its name, its file and the SHA-256 of its folder (shards
/// that scored different files under one name must not merge).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ObjectInfo {
    pub name: String,
    pub urdf: String,
    pub sha256: String,
}

impl RunInfo {
    /// The table's rows in canonical order: categories as listed, then objects.
    pub fn rows(&self) -> Vec<RowKey> {
        self.categories
            .iter()
            .map(|c| RowKey::Category(*c))
            .chain(self.objects.iter().map(|o| RowKey::Object(o.name.clone())))
            .collect()
    }
}

/// The episodes file of an evaluation's `--out` folder.
pub const EPISODES: &str = "episodes.jsonl";
/// What the run is and how long it has run, rewritten as it goes.
pub const RUN: &str = "run.json";

/// The episodes file a report stands for: its name beside results.json and
/// its SHA-256.
#[derive(Clone, Debug)]
pub struct EpisodesDigest {
    pub name: String,
    pub sha256: String,
}

/// One evaluation's (or one shard's) report: what ran, and its episodes'
/// aggregates.
pub struct Report {
    pub run: RunInfo,
    pub shard: Shard,
    pub wall_seconds: f64,
    pub agg: Aggregate,
    /// The episodes file beside results.json, when the run wrote one.
    pub episodes_file: Option<EpisodesDigest>,
}

/// The part of an episode outcome that the tables read.
#[derive(serde::Deserialize)]
pub struct Scored {
    #[serde(default)]
    pub category: Option<Category>,
    #[serde(default)]
    pub object: Option<String>,
    pub index: u32,
    pub policy: String,
    pub episode: Option<ScoredEpisode>,
    pub error: Option<String>,
}

#[derive(serde::Deserialize)]
pub struct ScoredEpisode {
    pub metrics: Metrics,
}

use super::plot::Curve;
use super::tables::{self, Cells, RowKey, metrics_of};

impl Scored {
    /// One line of an episodes file.
    pub fn parse(line: &str) -> Result<Scored> {
        let s: Scored = serde_json::from_str(line).context("not an episode outcome")?;
        if s.row().is_none() {
            bail!("expected one of `category` or `object`");
        }
        Ok(s)
    }

    pub fn row(&self) -> Option<RowKey> {
        match (&self.category, &self.object) {
            (Some(c), None) => Some(RowKey::Category(*c)),
            (None, Some(o)) => Some(RowKey::Object(o.clone())),
            _ => None,
        }
    }
}

fn value(m: &Metrics, metric: &str) -> Option<f64> {
    Some(match metric {
        "novel_state_ratio" => m.novel_state_ratio as f64,
        "single_action_effect" => m.single_action_effect as f64,
        "normalized_distance" => m.normalized_distance as f64,
        "success_rate" => m.success as u8 as f64,
        "revolute_axis_error" => f64::from(m.axis.filter(|a| !a.prismatic)?.degrees),
        "prismatic_axis_error" => f64::from(m.axis.filter(|a| a.prismatic)?.degrees),
        _ => return None,
    })
}

/// The mean curve of one policy, kept as sums: `at[t]` adds the episodes
/// that reached step t, `ended[l]` the last values of those that ended after
/// l steps (a shorter episode holds its last value, as a plot of it would);
/// the same for the squares, for the interval.
#[derive(Default)]
struct CurveSum {
    n: usize,
    at: Vec<(f64, f64)>,
    ended: Vec<(f64, f64)>,
}

impl CurveSum {
    fn push(&mut self, series: &[f32]) {
        self.n += 1;
        if self.at.len() < series.len() {
            self.at.resize(series.len(), (0.0, 0.0));
        }
        for (sum, v) in self.at.iter_mut().zip(series) {
            let v = f64::from(*v);
            sum.0 += v;
            sum.1 += v * v;
        }
        if let Some(last) = series.last() {
            if self.ended.len() <= series.len() {
                self.ended.resize(series.len() + 1, (0.0, 0.0));
            }
            if let Some(e) = self.ended.get_mut(series.len()) {
                let v = f64::from(*last);
                e.0 += v;
                e.1 += v * v;
            }
        }
    }

    fn curve(&self, policy: &str) -> Curve {
        let n = self.n.max(1) as f64;
        let mut held = (0.0, 0.0);
        let (mut mean, mut half) = (Vec::new(), Vec::new());
        for (t, sum) in self.at.iter().enumerate() {
            let e = self.ended.get(t).copied().unwrap_or((0.0, 0.0));
            held = (held.0 + e.0, held.1 + e.1);
            let (s, s2) = (sum.0 + held.0, sum.1 + held.1);
            let m = s / n;
            let var = if self.n > 1 {
                ((s2 - n * m * m) / (n - 1.0)).max(0.0)
            } else {
                0.0
            };
            mean.push(m);
            half.push(1.96 * (var / n).sqrt());
        }
        Curve {
            policy: policy.to_owned(),
            episodes: self.n,
            mean,
            half,
        }
    }
}

/// Running aggregates of an evaluation's episodes.
pub struct Aggregate {
    task: Task,
    cells: Cells,
    curves: BTreeMap<String, CurveSum>,
    pub episodes: u64,
    pub failed: u64,
    /// The first few failures, for the screen: `row #k policy: error`.
    pub failures: Vec<String>,
}

impl Aggregate {
    pub fn new(task: Task) -> Aggregate {
        Aggregate {
            task,
            cells: Cells::new(),
            curves: BTreeMap::new(),
            episodes: 0,
            failed: 0,
            failures: Vec::new(),
        }
    }

    pub fn add(&mut self, o: &Scored) {
        self.episodes += 1;
        if let Some(e) = &o.error {
            self.failed += 1;
            if self.failures.len() < 5 {
                let row = o.row().map(|r| r.name().to_owned()).unwrap_or_default();
                self.failures
                    .push(format!("{row} #{} {}: {e}", o.index, o.policy));
            }
        }
        let (Some(ep), Some(row)) = (&o.episode, o.row()) else {
            return;
        };
        for (m, _) in metrics_of(self.task) {
            if let Some(v) = value(&ep.metrics, m) {
                self.cells
                    .entry((o.policy.clone(), row.clone(), m))
                    .or_default()
                    .push(v);
            }
        }
        let series = if self.task == Task::Goal {
            &ep.metrics.normalized_distance_curve
        } else {
            &ep.metrics.unique_states
        };
        self.curves
            .entry(o.policy.clone())
            .or_default()
            .push(series);
    }

    /// Each listed policy's mean curve (empty for a policy without episodes).
    pub fn mean_curves(&self, policies: &[String]) -> Vec<Curve> {
        policies
            .iter()
            .map(|p| match self.curves.get(p) {
                Some(c) => c.curve(p),
                None => CurveSum::default().curve(p),
            })
            .collect()
    }
}

impl Report {
    /// The summary printed with --json and stored in results.json.
    pub fn summary(&self) -> Result<serde_json::Value> {
        let mut summary = serde_json::to_value(&self.run)?;
        let Some(map) = summary.as_object_mut() else {
            bail!("run information is not an object");
        };
        map.insert("wall_seconds".into(), self.wall_seconds.into());
        map.insert("episodes".into(), self.agg.episodes.into());
        map.insert("failed_episodes".into(), self.agg.failed.into());
        map.insert(
            "cells".into(),
            self.agg
                .cells
                .iter()
                .map(|((p, c, m), v)| {
                    let st = tables::stat(m, v);
                    let key = if matches!(c, RowKey::Object(_)) { "object" } else { "category" };
                    serde_json::json!({"policy": p, (key): c.name(), "metric": m, "mean": st.mean,
                        "ci95": (st.hi - st.lo) / 2.0, "ci_low": st.lo, "ci_high": st.hi, "n": st.n})
                })
                .collect(),
        );
        if !self.shard.is_all() {
            map.insert("shard".into(), self.shard.to_string().into());
        }
        Ok(summary)
    }

    pub fn table(&self) -> String {
        tables::screen(
            self.run.task,
            &self.run.policies,
            &self.run.rows(),
            &self.agg.cells,
        )
    }

    /// Every file [`Report::write`] and the run itself may write: what `--out`
    /// must not already hold.
    pub const FILES: &'static [&'static str] = &[
        RUN,
        EPISODES,
        "results.json",
        "results.csv",
        "results.md",
        "results.tex",
        "table.txt",
        "curve.png",
        "curve.svg",
    ];

    /// results.json always (the summary, and the episodes file it stands
    /// for); a whole evaluation also gets results.csv, results.md,
    /// results.tex, table.txt and curve.png/svg (a shard's share of the tables
    /// would mislead). Each file is written beside and renamed, so a crash
    /// never leaves a half-written one in place of a good one.
    pub fn write(&self, out: &Path) -> Result<Vec<&'static str>> {
        std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
        let mut full = serde_json::json!({"summary": self.summary()?});
        if let (Some(f), Some(map)) = (&self.episodes_file, full.as_object_mut()) {
            map.insert("episodes_file".into(), f.name.clone().into());
            map.insert("episodes_sha256".into(), f.sha256.clone().into());
        }
        write_atomic(
            &out.join("results.json"),
            serde_json::to_string(&full)?.as_bytes(),
        )?;
        if !self.shard.is_all() {
            return Ok(vec!["results.json"]);
        }
        let cells = &self.agg.cells;
        let rows = self.run.rows();
        let (task, policies, categories) = (self.run.task, &self.run.policies, &rows);
        let files: [(&'static str, String); 4] = [
            (
                "results.csv",
                tables::csv(task, policies, categories, cells),
            ),
            (
                "results.md",
                tables::markdown(task, policies, categories, cells),
            ),
            (
                "results.tex",
                tables::latex(task, policies, categories, cells),
            ),
            (
                "table.txt",
                tables::screen(task, policies, categories, cells),
            ),
        ];
        let mut written = vec!["results.json"];
        for (name, text) in files {
            write_atomic(&out.join(name), text.as_bytes())?;
            written.push(name);
        }
        let curves = self.agg.mean_curves(&self.run.policies);
        let splits: Vec<&str> = tables::splits_of(&rows);
        let about = format!(
            "{} ({})",
            splits.join(" and "),
            crate::eval_cmd::plot::episodes_text(&curves)
        );
        match crate::eval_cmd::plot::plot_curves(self.run.task, &curves, &about, out) {
            Ok(files) => written.extend(files),
            Err(e) => eprintln!("warning: no plot: {e:#}"),
        }
        Ok(written)
    }
}

pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    Ok(umpnet_sim::fsio::write_atomic(path, bytes)?)
}
