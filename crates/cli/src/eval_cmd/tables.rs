//! The tables of an evaluation: on screen (table.txt), CSV, Markdown and
//! LaTeX, from the per-cell values. Success rates get Wilson intervals,
//! continuous metrics the normal approximation.
use std::collections::BTreeMap;
use std::fmt::Write as _;
use umpnet_eval::benchmark::{Running, wilson};
use umpnet_sim::objects::Category;
use umpnet_sim::scene::Task;

/// A table row: a category, or an object file (`eval --objects`). Categories
/// order as before objects existed, so their files stay byte for byte the same.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum RowKey {
    Category(Category),
    Object(String),
}

impl RowKey {
    pub fn name(&self) -> &str {
        match self {
            RowKey::Category(c) => c.name(),
            RowKey::Object(o) => o,
        }
    }

    /// The group the row is averaged in: `train`, `test` or `objects`.
    pub fn split(&self) -> &'static str {
        match self {
            RowKey::Category(c) if c.is_train() => "train",
            RowKey::Category(_) => "test",
            RowKey::Object(_) => "objects",
        }
    }
}

/// (policy, row, metric) -> the running statistics of its episodes' values.
pub type Cells = BTreeMap<(String, RowKey, &'static str), Running>;

pub fn metrics_of(task: Task) -> &'static [(&'static str, &'static str)] {
    match task {
        Task::Exploration => &[
            ("novel_state_ratio", "novel-state ratio (higher is better)"),
            (
                "single_action_effect",
                "single action effect (higher is better)",
            ),
            // The paper's structure inference: episodes with two or more
            // moving steps, by the grasped joint's kind.
            (
                "revolute_axis_error",
                "joint-axis error on revolute joints, degrees (lower is better)",
            ),
            (
                "prismatic_axis_error",
                "joint-axis error on prismatic joints, degrees (lower is better)",
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

/// Mean and 95% interval of one cell.
pub struct Stat {
    pub mean: f64,
    pub lo: f64,
    pub hi: f64,
    pub n: usize,
}

pub fn stat(metric: &str, values: &Running) -> Stat {
    let (mean, half) = values.mean_ci();
    let (lo, hi) = if metric == "success_rate" {
        wilson(values.successes, values.n)
    } else {
        (mean - half, mean + half)
    };
    Stat {
        mean,
        lo,
        hi,
        n: values.n,
    }
}

const SPLITS: [(&str, &str); 3] = [
    ("train categories (held-out instances)", "train"),
    ("test categories", "test"),
    ("objects", "objects"),
];

/// The labels of the splits `rows` cover, in the tables' order.
pub fn splits_of(rows: &[RowKey]) -> Vec<&'static str> {
    SPLITS
        .iter()
        .filter(|(_, split)| rows.iter().any(|r| r.split() == *split))
        .map(|(label, _)| *label)
        .collect()
}

/// The rows of one split, in the evaluation's order.
fn of_split<'a>(rows: &'a [RowKey], split: &str) -> Vec<&'a RowKey> {
    rows.iter().filter(|r| r.split() == split).collect()
}

fn cell<'a>(cells: &'a Cells, p: &str, row: &RowKey, metric: &'static str) -> Option<&'a Running> {
    cells.get(&(p.to_string(), row.clone(), metric))
}

fn mean_of_means(cells: &Cells, p: &str, cats: &[&RowKey], metric: &'static str) -> Option<f64> {
    let means: Vec<f64> = cats
        .iter()
        .filter_map(|c| cell(cells, p, c, metric))
        .map(Running::mean)
        .collect();
    (!means.is_empty()).then(|| means.iter().sum::<f64>() / means.len() as f64)
}

/// Objects where the oracle (the ceiling) succeeds in under 95% of goal
/// episodes: those objects' rows then measure the object as much as the
/// policy (a part too small or hidden, a range under the success threshold).
const ORACLE_FLOOR: f64 = 0.95;

fn oracle_shortfalls(rows: &[&RowKey], cells: &Cells) -> Vec<String> {
    rows.iter()
        .filter(|r| matches!(r, RowKey::Object(_)))
        .filter_map(|r| {
            let v = cell(cells, "oracle", r, "success_rate")?;
            let mean = v.mean();
            (mean < ORACLE_FLOOR).then(|| format!("{} {mean:.2}", r.name()))
        })
        .collect()
}

fn shortfall_note(rows: &[&RowKey], cells: &Cells) -> Option<String> {
    let short = oracle_shortfalls(rows, cells);
    (!short.is_empty()).then(|| {
        format!(
            "the oracle succeeds in under {ORACLE_FLOOR:.2} of goal episodes on: {}; \
             those rows measure the object as much as the policy",
            short.join(", ")
        )
    })
}

/// The screen table: per metric and split, a row of means per policy with
/// the 95% interval's half-width below it.
pub fn screen(task: Task, policies: &[String], categories: &[RowKey], cells: &Cells) -> String {
    let mut s = String::from("(oracle: the ceiling, privileged policy under the same protocol)\n");
    let width = policies
        .iter()
        .map(|p| p.chars().count())
        .max()
        .unwrap_or(0)
        .max(10);
    for (metric, title) in metrics_of(task) {
        let _ = writeln!(s, "\n{title}; below each row, +- the 95% interval");
        for (split_label, split) in SPLITS {
            let cats = of_split(categories, split);
            if cats.is_empty() {
                continue;
            }
            let col = |c: &RowKey| c.name().chars().count().max(6);
            let _ = write!(s, "  {split_label}\n  {:<width$}", "method");
            for c in &cats {
                let _ = write!(s, " {:>w$}", c.name(), w = col(c));
            }
            let _ = writeln!(s, " {:>7}", "avg");
            for p in policies {
                let mut means = format!("  {p:<width$}");
                let mut halves = format!("  {:<width$}", "");
                for c in &cats {
                    match cell(cells, p, c, metric) {
                        Some(v) => {
                            let st = stat(metric, v);
                            let _ = write!(means, " {:>w$.2}", st.mean, w = col(c));
                            let half = format!("+-{:.2}", (st.hi - st.lo) / 2.0);
                            let _ = write!(halves, " {half:>w$}", w = col(c));
                        }
                        None => {
                            let _ = write!(means, " {:>w$}", "-", w = col(c));
                            let _ = write!(halves, " {:>w$}", "", w = col(c));
                        }
                    }
                }
                let avg = mean_of_means(cells, p, &cats, metric).unwrap_or(f64::NAN);
                let _ = writeln!(s, "{means} {avg:>7.2}\n{}", halves.trim_end());
            }
            if *metric == "success_rate"
                && let Some(note) = shortfall_note(&cats, cells)
            {
                let _ = writeln!(s, "  note: {note}");
            }
        }
    }
    s
}

/// results.csv: one row per cell with its interval, then one average row per
/// (policy, split, metric): the mean over that split's categories.
pub fn csv(task: Task, policies: &[String], categories: &[RowKey], cells: &Cells) -> String {
    let mut out = String::from("policy,category,split,metric,mean,ci95,ci_low,ci_high,n\n");
    for ((p, c, m), v) in cells {
        let st = stat(m, v);
        let _ = writeln!(
            out,
            "{p},{},{},{m},{:.6},{:.6},{:.6},{:.6},{}",
            c.name(),
            c.split(),
            st.mean,
            (st.hi - st.lo) / 2.0,
            st.lo,
            st.hi,
            st.n
        );
    }
    for p in policies {
        for (metric, _) in metrics_of(task) {
            for (_, split) in SPLITS {
                let cats = of_split(categories, split);
                let n: usize = cats
                    .iter()
                    .filter_map(|c| cell(cells, p, c, metric))
                    .map(|r| r.n)
                    .sum();
                if let Some(avg) = mean_of_means(cells, p, &cats, metric) {
                    let _ = writeln!(out, "{p},average,{split},{metric},{avg:.6},,,,{n}");
                }
            }
        }
    }
    out
}

/// results.md: per metric and split, categories as rows and policies as
/// columns, each cell "mean [low, high]".
pub fn markdown(task: Task, policies: &[String], categories: &[RowKey], cells: &Cells) -> String {
    let mut s = String::new();
    for (metric, title) in metrics_of(task) {
        for (split_label, split) in SPLITS {
            let cats = of_split(categories, split);
            if cats.is_empty() {
                continue;
            }
            let _ = writeln!(s, "### {title}, {split_label}\n");
            let head = if split == "objects" {
                "object"
            } else {
                "category"
            };
            let _ = writeln!(s, "| {head} | {} |", policies.join(" | "));
            let _ = writeln!(s, "|---|{}", "---|".repeat(policies.len()));
            for c in &cats {
                let _ = write!(s, "| {} |", c.name());
                for p in policies {
                    match cell(cells, p, c, metric) {
                        Some(v) => {
                            let st = stat(metric, v);
                            let _ = write!(s, " {:.2} [{:.2}, {:.2}] |", st.mean, st.lo, st.hi);
                        }
                        None => s.push_str(" - |"),
                    }
                }
                s.push('\n');
            }
            s.push_str("| **average** |");
            for p in policies {
                match mean_of_means(cells, p, &cats, metric) {
                    Some(a) => {
                        let _ = write!(s, " **{a:.2}** |");
                    }
                    None => s.push_str(" - |"),
                }
            }
            s.push_str("\n\n");
            if *metric == "success_rate"
                && let Some(note) = shortfall_note(&cats, cells)
            {
                let _ = writeln!(s, "Note: {note}.\n");
            }
        }
    }
    s
}

fn tex_escape(s: &str) -> String {
    s.replace('\\', "\\textbackslash{}")
        .replace('_', "\\_")
        .replace('&', "\\&")
        .replace('%', "\\%")
        .replace('#', "\\#")
}

/// results.tex: the paper's layout (methods as rows, categories as columns,
/// then the average), means only, one tabular per metric and split.
pub fn latex(task: Task, policies: &[String], categories: &[RowKey], cells: &Cells) -> String {
    let mut s = String::from("% umpnet eval: means over episodes; intervals in results.md/csv\n");
    for (metric, title) in metrics_of(task) {
        for (split_label, split) in SPLITS {
            let cats = of_split(categories, split);
            if cats.is_empty() {
                continue;
            }
            let _ = writeln!(s, "% {title}, {split_label}");
            let _ = writeln!(s, "\\begin{{tabular}}{{l{}c}}", "c".repeat(cats.len()));
            s.push_str("\\hline\nmethod");
            for c in &cats {
                let _ = write!(s, " & {}", tex_escape(c.name()));
            }
            s.push_str(" & avg \\\\\n\\hline\n");
            for p in policies {
                s.push_str(&tex_escape(p));
                for c in &cats {
                    match cell(cells, p, c, metric) {
                        Some(v) => {
                            let _ = write!(s, " & {:.2}", v.mean());
                        }
                        None => s.push_str(" & -"),
                    }
                }
                match mean_of_means(cells, p, &cats, metric) {
                    Some(a) => {
                        let _ = writeln!(s, " & {a:.2} \\\\");
                    }
                    None => s.push_str(" & - \\\\\n"),
                }
            }
            s.push_str("\\hline\n\\end{tabular}\n\n");
        }
    }
    s
}
