//! `umpnet`: the command line of the UMPNet simulator and policy runtime.
mod bench_cmd;
mod episode_cmd;
mod eval_cmd;
mod images;
mod infer_cmd;
mod objects_cmd;
mod outdir;
mod policies;
mod render_cmd;

use anyhow::Result;
use clap::{Parser, Subcommand};
use rand::SeedableRng;
use std::path::PathBuf;
use umpnet_sim::objects::{Category, InstanceSplit, nth_instance};
use umpnet_sim::physics::PhysicsProfile;
use umpnet_sim::scene::{ObjectSource, Scene, Task};

#[derive(Parser)]
#[command(
    name = "umpnet",
    version,
    about = "UMPNet: simulator, policies and benchmark for articulated-object manipulation"
)]
struct Cli {
    /// Machine-readable JSON on stdout; no progress bars.
    #[arg(long, global = true)]
    json: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Generate or list procedural articulated objects.
    #[command(subcommand)]
    Objects(objects_cmd::ObjectsCmd),
    /// Render one scene: colour, depth, segmentation and normal PNGs.
    Render(render_cmd::RenderArgs),
    /// One exploration episode.
    Explore(episode_cmd::EpisodeArgs),
    /// One goal-conditioned episode.
    Goal(episode_cmd::EpisodeArgs),
    /// The benchmark: policies x categories, tables, CSV, JSON and plots.
    Eval(eval_cmd::EvalCmd),
    /// Simulator and renderer speed figures.
    Bench(bench_cmd::BenchArgs),
    /// The next action for real RGB-D frames (JSON).
    Infer(infer_cmd::InferArgs),
}

pub struct Ctx {
    pub json: bool,
}

impl Ctx {
    /// Progress bars only on a terminal and without --json.
    pub fn progress(&self, len: u64, what: &str) -> indicatif::ProgressBar {
        use std::io::IsTerminal;
        if self.json || !std::io::stderr().is_terminal() {
            return indicatif::ProgressBar::hidden();
        }
        let pb = indicatif::ProgressBar::new(len);
        pb.set_style(
            indicatif::ProgressStyle::with_template(
                "{msg} [{bar:30}] {pos}/{len} {elapsed} (eta {eta})",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        pb.set_message(what.to_owned());
        pb
    }
}

/// A usage error: exit code 2.
#[derive(Debug)]
pub struct Usage(pub String);
impl std::fmt::Display for Usage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}
impl std::error::Error for Usage {}

pub fn usage(msg: impl Into<String>) -> anyhow::Error {
    Usage(msg.into()).into()
}

pub fn parse_resolution(s: &str) -> std::result::Result<(u32, u32), String> {
    let (h, w) = s
        .split_once('x')
        .ok_or_else(|| format!("`{s}`: expected HEIGHTxWIDTH, e.g. 480x640"))?;
    let p = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|v| (8..=4096).contains(v))
    };
    match (p(h), p(w)) {
        (Some(h), Some(w)) => Ok((h, w)),
        _ => Err(format!(
            "`{s}`: height and width must be integers in 8..=4096"
        )),
    }
}

pub fn parse_category(s: &str) -> std::result::Result<Category, String> {
    s.parse::<Category>().map_err(|e| e.to_string())
}

pub fn parse_physics(s: &str) -> std::result::Result<PhysicsProfile, String> {
    s.parse::<PhysicsProfile>().map_err(|e| e.to_string())
}

pub fn parse_protocol(s: &str) -> std::result::Result<umpnet_eval::Protocol, String> {
    s.parse::<umpnet_eval::Protocol>()
}

/// Which object and scene: a generated instance of a category, or a URDF file.
#[derive(clap::Args, Clone)]
pub struct ObjectArgs {
    /// Object category (e.g. Microwave, StorageFurniture).
    #[arg(long, value_parser = parse_category)]
    pub category: Option<Category>,
    /// A URDF file (PartNet-Mobility `mobility.urdf` or generated) instead of a generated instance.
    #[arg(long)]
    pub object: Option<PathBuf>,
    /// Scene seed: placement, joint state and, without --instance, the instance.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Instance index within the category (default: chosen by the seed among test instances).
    #[arg(long)]
    pub instance: Option<u32>,
    /// Seed of the generated dataset.
    #[arg(long, default_value_t = 0)]
    pub dataset_seed: u64,
    /// Physics profile: reference (the paper's simulator) or ideal (every pull
    /// follows the joint's path).
    #[arg(long, default_value = "reference", value_parser = parse_physics)]
    pub physics: PhysicsProfile,
}

impl ObjectArgs {
    pub fn scene(&self, task: Task) -> Result<Scene> {
        let (object, category) = match (&self.object, self.category) {
            (Some(path), c) => {
                let what = match std::fs::metadata(path) {
                    Err(_) => Some("no such file".to_owned()),
                    Ok(m) if m.is_dir() => Some(format!(
                        "is a directory; expected a URDF file such as {}",
                        path.join("mobility.urdf").display()
                    )),
                    Ok(m) if !m.is_file() => Some(
                        "is not a regular file (a FIFO or device?); expected a URDF file"
                            .to_owned(),
                    ),
                    Ok(_) => None,
                };
                if let Some(what) = what {
                    return Err(usage(format!("--object {}: {what}", path.display())));
                }
                (ObjectSource::File { path: path.clone() }, c)
            }
            (None, Some(c)) => {
                let index = self.instance.unwrap_or_else(|| {
                    nth_instance(
                        c,
                        InstanceSplit::Test,
                        (self.seed % umpnet_eval::bench::INSTANCES_PER_CATEGORY as u64) as u32,
                    )
                });
                (
                    ObjectSource::Generated {
                        category: c,
                        index,
                        dataset_seed: self.dataset_seed,
                    },
                    Some(c),
                )
            }
            (None, None) => return Err(usage("give --category C or --object DIR/mobility.urdf")),
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(self.seed);
        Ok(umpnet_eval::bench::sample_visible_scene(
            &mut rng,
            task,
            category,
            object,
            self.physics,
        )?)
    }
}

fn main() {
    // As Unix tools do: `umpnet objects list | head -1` ends quietly when the
    // reader goes away, instead of panicking in println! on EPIPE.
    // SAFETY: called first, before any thread exists; SIG_DFL is always valid.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => e.exit(), // clap: usage errors exit with 2, --help/--version with 0
    };
    let ctx = Ctx { json: cli.json };
    let result = match &cli.command {
        Command::Objects(c) => objects_cmd::run(&ctx, c),
        Command::Render(a) => render_cmd::run(&ctx, a),
        Command::Explore(a) => episode_cmd::run(&ctx, a, Task::Exploration),
        Command::Goal(a) => episode_cmd::run(&ctx, a, Task::Goal),
        Command::Eval(a) => eval_cmd::run(&ctx, a),
        Command::Bench(a) => bench_cmd::run(&ctx, a),
        Command::Infer(a) => infer_cmd::run(&ctx, a),
    };
    if let Err(e) = result {
        let code = if e.downcast_ref::<Usage>().is_some() {
            2
        } else {
            1
        };
        let msg: Vec<String> = e.chain().map(|c| c.to_string()).collect();
        eprintln!("error: {}", msg.join(": "));
        std::process::exit(code);
    }
}
