//! What an evaluation reports, from its episodes as JSON: the summary, the
//! tables, results.csv/json, table.txt and curve.png. A single run and a
//! merge of shards go through this same code from the same JSON, which is
//! what makes a merged report byte-identical to an unsharded one.
use anyhow::{Context, Result, bail};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;
use umpnet_eval::Protocol;
use umpnet_eval::bench::Shard;
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

use super::tables::{self, Cells, RowKey, metrics_of};

impl Scored {
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
        _ => return None,
    })
}

impl Report {
    pub fn scored(&self) -> Result<Vec<Scored>> {
        self.episodes
            .iter()
            .enumerate()
            .map(|(i, e)| {
                let s = Scored::deserialize(e)
                    .with_context(|| format!("episode {i}: not an episode outcome"))?;
                if s.row().is_none() {
                    bail!("episode {i}: expected one of `category` or `object`");
                }
                Ok(s)
            })
            .collect()
    }

    fn cells(&self, scored: &[Scored]) -> Cells {
        let mut cells = Cells::new();
        for o in scored {
            let (Some(ep), Some(row)) = (&o.episode, o.row()) else {
                continue;
            };
            for (m, _) in metrics_of(self.run.task) {
                if let Some(v) = value(&ep.metrics, m) {
                    cells
                        .entry((o.policy.clone(), row.clone(), m))
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

    pub fn table(&self, scored: &[Scored]) -> String {
        tables::screen(
            self.run.task,
            &self.run.policies,
            &self.run.rows(),
            &self.cells(scored),
        )
    }

    /// Every file [`Report::write`] may write: what `--out` must not already hold.
    pub const FILES: &'static [&'static str] = &[
        "results.json",
        "results.csv",
        "results.md",
        "results.tex",
        "table.txt",
        "curve.png",
    ];

    /// results.json always; a whole evaluation also gets results.csv,
    /// results.md, results.tex, table.txt and curve.png (a shard's share of the tables would mislead).
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
        let rows = self.run.rows();
        let (task, policies, categories) = (self.run.task, &self.run.policies, &rows);
        let files: [(&'static str, String); 4] = [
            (
                "results.csv",
                tables::csv(task, policies, categories, &cells),
            ),
            (
                "results.md",
                tables::markdown(task, policies, categories, &cells),
            ),
            (
                "results.tex",
                tables::latex(task, policies, categories, &cells),
            ),
            (
                "table.txt",
                tables::screen(task, policies, categories, &cells),
            ),
        ];
        let mut written = vec!["results.json"];
        for (name, text) in files {
            write_atomic(&out.join(name), text.as_bytes())?;
            written.push(name);
        }
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
