//! Policies by name: `random`, `oracle`, or a learned package (`umpnet` with
//! --model DIR, or `NAME=DIR` for any package, e.g. a baseline).
use crate::usage;
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use umpnet_eval::benchmark::PolicyFactory;
use umpnet_eval::learned::LearnedPolicy;
use umpnet_policy::UmpnetPolicy;
use umpnet_policy::cem::Sampler;
use umpnet_policy::policy::{DirectionFilter, GraspRule};
use umpnet_sim::scene::Task;

/// The default model package's directory name, under `models/`: the shipped
/// package with the best test-category figures (README's table).
pub const SHIPPED_MODEL: &str = "umpnet-gpu-medium";

/// Where the shipped model is looked for, in order: $UMPNET_MODEL (a package
/// directory), `models/umpnet-gpu-medium` under the working directory, under
/// $XDG_DATA_HOME/umpnet (or ~/.local/share/umpnet), and beside the binary
/// or any directory above it (a build in the repository, or an install
/// prefix's `share/umpnet`).
pub fn default_model_candidates() -> Vec<PathBuf> {
    let rel = Path::new("models").join(SHIPPED_MODEL);
    let mut candidates: Vec<PathBuf> = Vec::new();
    if let Some(p) = std::env::var_os("UMPNET_MODEL") {
        candidates.push(PathBuf::from(p));
    }
    candidates.push(rel.clone());
    let data = std::env::var_os("XDG_DATA_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| Path::new(&h).join(".local/share")));
    if let Some(d) = data {
        candidates.push(d.join("umpnet").join(&rel));
    }
    if let Ok(exe) = std::env::current_exe() {
        for dir in exe.ancestors().skip(1) {
            candidates.push(dir.join(&rel));
            candidates.push(dir.join("share").join("umpnet").join(&rel));
        }
    }
    candidates
}

/// The shipped model package, or an error that lists where it was looked for.
pub fn default_model() -> Result<PathBuf> {
    let candidates = default_model_candidates();
    if let Some(found) = candidates.iter().find(|p| p.join("model.json").is_file()) {
        return Ok(found.clone());
    }
    let listed: Vec<String> = candidates.iter().map(|p| p.display().to_string()).collect();
    Err(usage(format!(
        "no model package found (pass --model DIR or set UMPNET_MODEL); looked in: {}",
        listed.join(", ")
    )))
}

pub struct Resolved {
    pub factories: Vec<(String, PolicyFactory)>,
    /// Each learned package's input resolution, by policy name.
    pub resolutions: std::collections::BTreeMap<String, (u32, u32)>,
    /// Each learned policy's package directory, by policy name.
    pub packages: Vec<(String, PathBuf)>,
}

/// What replaces every learned package's own choices: its direction filter
/// and grasp rule, how it draws candidate directions (the sampler ablations
/// of the paper's appendix) and how it scores them (`--mirror-average`).
/// One set of flags for `episode`, `eval`, `explore`, `goal` and `infer`.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct LearnedArgs {
    /// A learned policy's direction filter instead of its package's: none,
    /// normal90 (within 90 degrees of the surface normal), prev90 (within 90
    /// degrees of the previous action, the paper's +HP; exploration only),
    /// joint45 (along the JointNet's joint), goal45 (toward where the goal
    /// frame shows the part; goal only) or onward45 (onward where the
    /// gripper went; exploration only).
    #[arg(long, value_parser = crate::choice::<DirectionFilter>(crate::DIRECTION_FILTERS))]
    pub direction_filter: Option<DirectionFilter>,
    /// A learned policy's grasp rule instead of its package's (model.json
    /// `grasp`): affordance (the paper: the PositionNet's best pixel),
    /// affordance_times_movable (weighted by the JointNet's movable mask) or
    /// affordance_times_movable_lever (and by the lever arm about a hinge).
    #[arg(long, value_parser = crate::choice::<GraspRule>(crate::GRASP_RULES))]
    pub grasp_rule: Option<GraspRule>,
    /// How a learned policy draws candidate directions: cem (the paper: two
    /// rounds, the second resampled around the best of the first) or uniform
    /// (one round of twice --cem-samples, the same number of evaluations)
    #[arg(long, value_parser = ["cem", "uniform"])]
    pub sampler: Option<String>,
    /// Candidate directions per CEM round (the paper: 64)
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=umpnet_policy::cem::MAX_CANDIDATES as i64))]
    pub cem_samples: Option<u32>,
    /// Beyond the paper: a learned policy scores every candidate direction
    /// also on the scene mirrored left-right (the camera's plane of
    /// symmetry) and acts on the average of the two; twice the direction
    /// networks' time
    #[arg(long)]
    pub mirror_average: bool,
}

/// The choices [`LearnedArgs`] asked for; None keeps the package's own.
#[derive(Clone, Copy, Debug, Default)]
pub struct Overrides {
    /// `--direction-filter`.
    pub filter: Option<DirectionFilter>,
    /// `--grasp-rule`.
    pub grasp: Option<GraspRule>,
    /// The sampler asked for, or None for the package's default (CEM, 64).
    pub sampler: Option<Sampler>,
    /// `--mirror-average`.
    pub mirror_average: bool,
}

impl LearnedArgs {
    /// The choices asked for.
    pub fn resolve(&self) -> Overrides {
        Overrides {
            filter: self.direction_filter,
            grasp: self.grasp_rule,
            sampler: self.sampler(),
            mirror_average: self.mirror_average,
        }
    }

    /// The sampler asked for, or None for the package's default (CEM, 64).
    pub fn sampler(&self) -> Option<Sampler> {
        if self.sampler.is_none() && self.cem_samples.is_none() {
            return None;
        }
        let n = self
            .cem_samples
            .map_or(umpnet_policy::cem::CANDIDATES, |n| n as usize);
        Some(match self.sampler.as_deref() {
            Some("uniform") => Sampler::Uniform { n },
            _ => Sampler::Cem { n },
        })
    }
}

impl Overrides {
    /// `policy` with these choices in place of its package's.
    pub fn apply(self, mut policy: UmpnetPolicy) -> umpnet_policy::Result<UmpnetPolicy> {
        if let Some(f) = self.filter {
            policy = policy.with_direction_filter(f);
        }
        if let Some(s) = self.sampler {
            policy = policy.with_sampler(s);
        }
        if let Some(g) = self.grasp {
            policy = policy.with_grasp(g)?;
        }
        Ok(policy.with_mirror_average(self.mirror_average))
    }
}

/// Packages are checked against `task`: an Inverse package has no exploration
/// behaviour. `overrides` replace every learned package's own choices.
pub fn resolve(
    specs: &[String],
    model: Option<&Path>,
    sessions: usize,
    task: Task,
    overrides: Overrides,
) -> Result<Resolved> {
    if overrides.filter == Some(DirectionFilter::Prev90) && task == Task::Goal {
        return Err(usage(
            "--direction-filter prev90 serves exploration only (the paper's +HP baselines): \
             in the goal task the way to the goal may lie behind the last move",
        ));
    }
    let mut factories: Vec<(String, PolicyFactory)> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for spec in specs {
        let name = spec.split_once('=').map_or(spec.as_str(), |(n, _)| n);
        if let Some((n, d)) = spec.split_once('=')
            && (n.trim().is_empty() || d.trim().is_empty())
        {
            return Err(usage(format!(
                "policy `{spec}`: expected NAME=MODEL_DIR with both parts"
            )));
        }
        if !seen.insert(name) {
            return Err(usage(format!(
                "policy `{name}` is listed twice; give each policy its own name (NAME=MODEL_DIR)"
            )));
        }
    }
    let mut resolutions = std::collections::BTreeMap::new();
    let mut packages = Vec::new();
    for spec in specs {
        let (name, dir) = match spec.split_once('=') {
            Some((n, d)) => (n.to_string(), Some(PathBuf::from(d))),
            None if spec == "umpnet" => (
                spec.clone(),
                Some(match model {
                    Some(m) => m.to_path_buf(),
                    None => default_model()?,
                }),
            ),
            None => (spec.clone(), None),
        };
        match dir {
            None => {
                if umpnet_eval::scripted_policy(&name).is_none() {
                    return Err(usage(format!(
                        "policy `{name}`: unknown; expected random, oracle, umpnet or NAME=MODEL_DIR"
                    )));
                }
                let n = name.clone();
                let f: PolicyFactory = Arc::new(move || {
                    umpnet_eval::scripted_policy(&n).ok_or_else(|| {
                        umpnet_eval::EvalError::Episode(format!("unknown policy {n}"))
                    })
                });
                factories.push((name, f));
            }
            Some(dir) => {
                if !dir.join("model.json").is_file() {
                    return Err(usage(format!(
                        "policy `{name}`: {} is not a model package (no model.json)",
                        dir.display()
                    )));
                }
                let pkg = LearnedPolicy::load(&dir, sessions)
                    .with_context(|| format!("loading policy `{name}`"))?;
                if pkg.branches.goal_only() && task != Task::Goal {
                    return Err(usage(format!(
                        "policy `{name}`: {} is an Inverse package, which serves only the goal task",
                        dir.display()
                    )));
                }
                if let Some(Err(why)) = overrides.grasp.map(|g| g.check_joint(pkg.has_joint())) {
                    return Err(usage(format!(
                        "policy `{name}`: --grasp-rule: {}: {why}",
                        dir.display()
                    )));
                }
                let r = (pkg.meta.input.height as u32, pkg.meta.input.width as u32);
                resolutions.insert(name.clone(), r);
                packages.push((name.clone(), dir.clone()));
                let n = name.clone();
                let f: PolicyFactory = Arc::new(move || {
                    let policy = overrides.apply(UmpnetPolicy::new(pkg.clone()))?;
                    Ok(Box::new(LearnedPolicy::from_policy(&n, policy))
                        as Box<dyn umpnet_eval::Policy>)
                });
                factories.push((name, f));
            }
        }
    }
    Ok(Resolved {
        factories,
        resolutions,
        packages,
    })
}
