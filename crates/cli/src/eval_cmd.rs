use crate::{Ctx, usage};
use anyhow::{Context, Result};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use umpnet_eval::Protocol;
use umpnet_eval::bench::{BenchConfig, EpisodeOutcome, PolicyFactory, mean_ci, run_benchmark};
use umpnet_sim::camera::Camera;
use umpnet_sim::objects::Category;
use umpnet_sim::physics::PhysicsProfile;
use umpnet_sim::render::RendererKind;
use umpnet_sim::scene::Task;

#[derive(clap::Args)]
pub struct EvalArgs {
    #[arg(long, default_value = "exploration")]
    pub task: Task,
    /// Comma-separated categories (overrides --split).
    #[arg(long, value_delimiter = ',', value_parser = crate::parse_category)]
    pub categories: Vec<Category>,
    /// train (held-out instances of training categories), test (test categories) or all.
    #[arg(long, default_value = "all")]
    pub split: String,
    #[arg(long, default_value_t = 100)]
    pub episodes_per_category: u32,
    /// Comma-separated policies: random, oracle, umpnet (with --model) or NAME=MODEL_DIR.
    #[arg(long, value_delimiter = ',', default_value = "oracle,random")]
    pub policies: Vec<String>,
    /// Model package for `umpnet` (default: models/umpnet-small).
    #[arg(long)]
    pub model: Option<PathBuf>,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[arg(long, default_value = "120x160", value_parser = crate::parse_resolution)]
    pub resolution: (u32, u32),
    #[arg(long, default_value = "auto")]
    pub renderer: RendererKind,
    /// Physics profile: reference (the paper's simulator) or ideal.
    #[arg(long, default_value = "reference", value_parser = crate::parse_physics)]
    pub physics: PhysicsProfile,
    /// Evaluation protocol: paper (the paper's evaluation code) or strict.
    #[arg(long, default_value = "paper", value_parser = crate::parse_protocol)]
    pub protocol: Protocol,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Write results.csv, results.json and curve.png here.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

fn metrics_of(task: Task) -> &'static [(&'static str, &'static str)] {
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

fn value(o: &EpisodeOutcome, metric: &str) -> Option<f64> {
    let m = &o.episode.as_ref()?.metrics;
    Some(match metric {
        "novel_state_ratio" => m.novel_state_ratio as f64,
        "single_action_effect" => m.single_action_effect as f64,
        "normalized_distance" => m.normalized_distance as f64,
        "success_rate" => m.success as u8 as f64,
        _ => return None,
    })
}

pub fn run(ctx: &Ctx, a: &EvalArgs) -> Result<()> {
    let categories: Vec<Category> = if !a.categories.is_empty() {
        a.categories.clone()
    } else {
        match a.split.as_str() {
            "train" => Category::ALL
                .iter()
                .copied()
                .filter(|c| c.is_train())
                .collect(),
            "test" => Category::ALL
                .iter()
                .copied()
                .filter(|c| !c.is_train())
                .collect(),
            "all" => Category::ALL.to_vec(),
            s => return Err(usage(format!("--split {s}: expected train, test or all"))),
        }
    };
    if a.episodes_per_category == 0 {
        return Err(usage("--episodes-per-category must be at least 1"));
    }
    let threads = a.threads.unwrap_or_else(rayon::current_num_threads).max(1);
    // The oracle is the ceiling of every table, under the same protocol and physics.
    let mut listed = a.policies.clone();
    if !listed.iter().any(|p| p == "oracle") {
        listed.push("oracle".into());
    }
    let resolved = crate::policies::resolve(&listed, a.model.as_deref(), threads, a.task)?;
    let policies: Vec<(String, PolicyFactory)> = resolved.factories;
    let names: Vec<String> = policies.iter().map(|(n, _)| n.clone()).collect();
    let resolution = resolved.resolution.unwrap_or(a.resolution);
    let cfg = BenchConfig {
        task: a.task,
        categories: categories.clone(),
        episodes_per_category: a.episodes_per_category,
        seed: a.seed,
        dataset_seed: 0,
        camera: Camera::reference(resolution.0, resolution.1),
        renderer: a.renderer,
        steps: None,
        physics: a.physics,
        protocol: a.protocol,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads.unwrap_or(0))
        .build()?;
    let pb = ctx.progress(
        categories.len() as u64 * a.episodes_per_category as u64,
        "scenes",
    );
    let t0 = std::time::Instant::now();
    let outcomes = pool.install(|| run_benchmark(&cfg, &policies, &|| pb.inc(1)));
    pb.finish_and_clear();
    let wall = t0.elapsed().as_secs_f64();
    let failures: Vec<&EpisodeOutcome> = outcomes.iter().filter(|o| o.error.is_some()).collect();
    for f in failures.iter().take(5) {
        eprintln!(
            "episode failed: {} #{} {}: {}",
            f.category,
            f.index,
            f.policy,
            f.error.as_deref().unwrap_or("")
        );
    }
    // (policy, category, metric) -> values
    let mut cells: BTreeMap<(String, Category, &str), Vec<f64>> = BTreeMap::new();
    for o in &outcomes {
        for (m, _) in metrics_of(a.task) {
            if let Some(v) = value(o, m) {
                cells
                    .entry((o.policy.clone(), o.category, m))
                    .or_default()
                    .push(v);
            }
        }
    }
    let table = render_table(a.task, &names, &categories, &cells);
    let summary = serde_json::json!({
        "task": a.task, "seed": a.seed, "episodes_per_category": a.episodes_per_category,
        "physics": a.physics, "protocol": a.protocol,
        "resolution": [resolution.0, resolution.1], "policies": names, "wall_seconds": wall, "failed_episodes": failures.len(),
        "cells": cells.iter().map(|((p, c, m), v)| { let (mean, ci) = mean_ci(v); serde_json::json!({"policy": p, "category": c.name(), "metric": m, "mean": mean, "ci95": ci, "n": v.len()}) }).collect::<Vec<_>>(),
    });
    if let Some(out) = &a.out {
        std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
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
        std::fs::write(out.join("results.csv"), csv)?;
        let full = serde_json::json!({"summary": summary, "episodes": outcomes});
        std::fs::write(out.join("results.json"), serde_json::to_string(&full)?)?;
        std::fs::write(out.join("table.txt"), &table)?;
        if let Err(e) = plot_curves(a.task, &names, &outcomes, &out.join("curve.png")) {
            eprintln!("warning: no plot: {e:#}");
        }
    }
    if ctx.json {
        println!("{summary}");
    } else {
        print!("{table}");
        println!(
            "{} episodes ({} scenes x {} policies) in {wall:.1} s; {} failed",
            outcomes.len(),
            categories.len() as u32 * a.episodes_per_category,
            listed.len(),
            failures.len()
        );
        if let Some(out) = &a.out {
            println!(
                "wrote results.csv, results.json, table.txt, curve.png to {}",
                out.display()
            );
        }
    }
    Ok(())
}

fn render_table(
    task: Task,
    policies: &[String],
    categories: &[Category],
    cells: &BTreeMap<(String, Category, &str), Vec<f64>>,
) -> String {
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

fn register_font() -> Result<()> {
    use std::sync::OnceLock;
    static FONT: OnceLock<std::result::Result<(), String>> = OnceLock::new();
    FONT.get_or_init(|| {
        let paths = [
            "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
            "/usr/share/fonts/TTF/DejaVuSans.ttf",
            "/usr/share/fonts/dejavu/DejaVuSans.ttf",
        ];
        let bytes = paths
            .iter()
            .find_map(|p| std::fs::read(p).ok())
            .ok_or("no DejaVuSans.ttf found (apt-get install fonts-dejavu-core)")?;
        let leaked: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, leaked)
            .map_err(|_| "invalid font file".to_string())
    })
    .clone()
    .map_err(|e| anyhow::anyhow!(e))
}

/// Mean curve per policy: unique states (exploration) or normalized distance (goal) vs step.
pub fn plot_curves(
    task: Task,
    policies: &[String],
    outcomes: &[EpisodeOutcome],
    path: &Path,
) -> Result<()> {
    use plotters::prelude::*;
    register_font()?;
    let mut curves: Vec<(String, Vec<f64>)> = Vec::new();
    let mut max_len = 0;
    for p in policies {
        let series: Vec<&Vec<f32>> = outcomes
            .iter()
            .filter(|o| &o.policy == p)
            .filter_map(|o| o.episode.as_ref())
            .map(|e| {
                if task == Task::Goal {
                    &e.metrics.normalized_distance_curve
                } else {
                    &e.metrics.unique_states
                }
            })
            .collect();
        let len = series.iter().map(|s| s.len()).max().unwrap_or(0);
        max_len = max_len.max(len);
        let mean: Vec<f64> = (0..len)
            .map(|t| {
                let v: Vec<f64> = series
                    .iter()
                    .map(|s| *s.get(t).or(s.last()).unwrap_or(&0.0) as f64)
                    .collect();
                v.iter().sum::<f64>() / v.len().max(1) as f64
            })
            .collect();
        curves.push((p.clone(), mean));
    }
    let ymax = curves
        .iter()
        .flat_map(|(_, c)| c.iter().copied())
        .fold(1.0, f64::max)
        * 1.05;
    let root = BitMapBackend::new(path, (720, 480)).into_drawing_area();
    root.fill(&WHITE)?;
    let (title, ylabel) = match task {
        Task::Exploration => ("Exploration: unique states discovered", "unique states"),
        Task::Goal => (
            "Goal: normalized distance to the goal",
            "normalized distance",
        ),
    };
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(56)
        .build_cartesian_2d(1f64..max_len.max(2) as f64, 0f64..ymax)?;
    chart
        .configure_mesh()
        .x_desc("step")
        .y_desc(ylabel)
        .draw()?;
    let palette = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
        RGBColor(255, 127, 14),
    ];
    for (k, (name, c)) in curves.iter().enumerate() {
        let color = palette[k % palette.len()];
        chart
            .draw_series(LineSeries::new(
                c.iter().enumerate().map(|(t, v)| ((t + 1) as f64, *v)),
                color.stroke_width(3),
            ))?
            .label(name.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(3))
            });
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}
