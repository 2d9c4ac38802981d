//! What an evaluation reports, from its episodes as JSON: the summary, the
//! tables, results.csv/json, table.txt and curve.png. A single run and a
//! merge of shards go through this same code from the same JSON, which is
//! what makes a merged report byte-identical to an unsharded one.
use anyhow::{Context, Result, bail};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;
use umpnet_eval::Protocol;
use umpnet_eval::bench::{Shard, mean_ci};
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
    /// (height, width) of the camera images.
    pub resolution: [u32; 2],
    /// The renderer that ran (`wgpu` or `cpu`, `auto` resolved).
    pub renderer: String,
    pub policies: Vec<String>,
    /// Learned policies' packages by policy name: SHA-256 of their files.
    pub models: BTreeMap<String, String>,
    pub categories: Vec<Category>,
}

/// One evaluation's (or one shard's) episodes, in canonical order.
pub struct Report {
    pub run: RunInfo,
    pub shard: Shard,
    pub wall_seconds: f64,
    /// Each an `EpisodeOutcome` as JSON.
    pub episodes: Vec<serde_json::Value>,
}

/// The part of an episode outcome that the tables read.
#[derive(serde::Deserialize)]
pub struct Scored {
    pub category: Category,
    pub index: u32,
    pub policy: String,
    pub episode: Option<ScoredEpisode>,
    pub error: Option<String>,
}

#[derive(serde::Deserialize)]
pub struct ScoredEpisode {
    pub metrics: Metrics,
}

type Cells = BTreeMap<(String, Category, &'static str), Vec<f64>>;

pub fn metrics_of(task: Task) -> &'static [(&'static str, &'static str)] {
    match task {
        Task::Exploration => &[
            ("novel_state_ratio", "novel-state ratio (higher is better)"),
            (
                "single_action_effect",
                "single action effect (higher is better)",
            ),
        ],
        Task::Goal => &[
            (
                "normalized_distance",
                "normalized distance (lower is better)",
            ),
            ("success_rate", "success rate (higher is better)"),
        ],
    }
}

fn value(m: &Metrics, metric: &str) -> Option<f64> {
    Some(match metric {
        "novel_state_ratio" => m.novel_state_ratio as f64,
        "single_action_effect" => m.single_action_effect as f64,
        "normalized_distance" => m.normalized_distance as f64,
        "success_rate" => m.success as u8 as f64,
        _ => return None,
    })
}

impl Report {
    pub fn scored(&self) -> Result<Vec<Scored>> {
        self.episodes
            .iter()
            .enumerate()
            .map(|(i, e)| {
                serde_json::from_value(e.clone())
                    .with_context(|| format!("episode {i}: not an episode outcome"))
            })
            .collect()
    }

    fn cells(&self, scored: &[Scored]) -> Cells {
        let mut cells = Cells::new();
        for o in scored {
            let Some(ep) = &o.episode else { continue };
            for (m, _) in metrics_of(self.run.task) {
                if let Some(v) = value(&ep.metrics, m) {
                    cells
                        .entry((o.policy.clone(), o.category, m))
                        .or_default()
                        .push(v);
                }
            }
        }
        cells
    }

    /// The summary printed with --json and stored in results.json.
    pub fn summary(&self, scored: &[Scored]) -> Result<serde_json::Value> {
        let cells = self.cells(scored);
        let mut summary = serde_json::to_value(&self.run)?;
        let Some(map) = summary.as_object_mut() else {
            bail!("run information is not an object");
        };
        map.insert("wall_seconds".into(), self.wall_seconds.into());
        map.insert(
            "failed_episodes".into(),
            scored.iter().filter(|o| o.error.is_some()).count().into(),
        );
        map.insert(
            "cells".into(),
            cells
                .iter()
                .map(|((p, c, m), v)| {
                    let (mean, ci) = mean_ci(v);
                    serde_json::json!({"policy": p, "category": c.name(), "metric": m, "mean": mean, "ci95": ci, "n": v.len()})
                })
                .collect(),
        );
        if !self.shard.is_all() {
            map.insert("shard".into(), self.shard.to_string().into());
        }
        Ok(summary)
    }

    pub fn table(&self, scored: &[Scored]) -> String {
        render_table(
            self.run.task,
            &self.run.policies,
            &self.run.categories,
            &self.cells(scored),
        )
    }

    /// results.json always; a whole evaluation also gets results.csv,
    /// table.txt and curve.png (a shard's share of the tables would mislead).
    /// Each file is written beside and renamed, so a crash never leaves a
    /// half-written one in place of a good one.
    pub fn write(&self, scored: &[Scored], out: &Path) -> Result<Vec<&'static str>> {
        std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
        let full = serde_json::json!({"summary": self.summary(scored)?, "episodes": self.episodes});
        write_atomic(
            &out.join("results.json"),
            serde_json::to_string(&full)?.as_bytes(),
        )?;
        if !self.shard.is_all() {
            return Ok(vec!["results.json"]);
        }
        let cells = self.cells(scored);
        let mut csv = String::from("policy,category,split,metric,mean,ci95,n\n");
        for ((p, c, m), v) in &cells {
            let (mean, ci) = mean_ci(v);
            let _ = writeln!(
                csv,
                "{p},{},{},{m},{mean:.6},{ci:.6},{}",
                c.name(),
                if c.is_train() { "train" } else { "test" },
                v.len()
            );
        }
        write_atomic(&out.join("results.csv"), csv.as_bytes())?;
        write_atomic(&out.join("table.txt"), self.table(scored).as_bytes())?;
        let mut written = vec!["results.json", "results.csv", "table.txt"];
        match crate::eval_cmd::plot::plot_curves(
            self.run.task,
            &self.run.policies,
            scored,
            &out.join("curve.png"),
        ) {
            Ok(()) => written.push("curve.png"),
            Err(e) => eprintln!("warning: no plot: {e:#}"),
        }
        Ok(written)
    }
}

fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    Ok(umpnet_sim::fsio::write_atomic(path, bytes)?)
}

fn render_table(task: Task, policies: &[String], categories: &[Category], cells: &Cells) -> String {
    let mut s = String::from("(oracle: the ceiling, privileged policy under the same protocol)\n");
    let short = |c: &Category| c.name().chars().take(7).collect::<String>();
    let width = policies
        .iter()
        .map(|p| p.chars().count())
        .max()
        .unwrap_or(0)
        .max(10);
    for (metric, title) in metrics_of(task) {
        let _ = writeln!(s, "\n{title}");
        for (split_name, train) in [
            ("train categories (held-out instances)", true),
            ("test categories", false),
        ] {
            let cats: Vec<&Category> = categories
                .iter()
                .filter(|c| c.is_train() == train)
                .collect();
            if cats.is_empty() {
                continue;
            }
            let _ = write!(s, "  {split_name}\n  {:<width$}", "method");
            for c in &cats {
                let _ = write!(s, " {:>7}", short(c));
            }
            let _ = writeln!(s, " {:>7}", "avg");
            for p in policies {
                let _ = write!(s, "  {p:<width$}");
                let mut means = Vec::new();
                for c in &cats {
                    match cells.get(&(p.clone(), **c, *metric)) {
                        Some(v) => {
                            let (m, _) = mean_ci(v);
                            means.push(m);
                            let _ = write!(s, " {m:>7.2}");
                        }
                        None => {
                            let _ = write!(s, " {:>7}", "-");
                        }
                    }
                }
                let avg = if means.is_empty() {
                    f64::NAN
                } else {
                    means.iter().sum::<f64>() / means.len() as f64
                };
                let _ = writeln!(s, " {avg:>7.2}");
            }
        }
    }
    s
}
