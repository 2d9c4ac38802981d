//! `umpnet`: the command line of the UMPNet simulator and policy runtime.
/// `println!` that returns a failed write (a full disk or device behind
/// stdout) as an error with `?`, where `println!` would panic.
macro_rules! outln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout(), $($t)*)
            .map_err(|e| anyhow::anyhow!("writing to standard output: {e}"))?
    }};
}

/// `print!` that returns a failed write as an error (see [`outln!`]).
macro_rules! out {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        write!(std::io::stdout(), $($t)*)
            .map_err(|e| anyhow::anyhow!("writing to standard output: {e}"))?
    }};
}

mod bench_cmd;
mod episode_cmd;
mod eval_cmd;
mod images;
mod infer_cmd;
mod infer_session;
mod objects_cmd;
mod outdir;
mod pictures;
mod policies;
mod render_cmd;
#[cfg(feature = "rerun")]
mod rrd;
#[cfg(not(feature = "rerun"))]
#[path = "rrd_disabled.rs"]
mod rrd;
mod signals;
mod text;

use anyhow::Result;
use clap::{Parser, Subcommand};
use rand::SeedableRng;
use std::path::PathBuf;
use umpnet_sim::camera::{Camera, GlassDepth};
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
    let p = |v: &str| v.trim().parse::<i64>().unwrap_or(-1);
    match umpnet_sim::camera::image_size(p(h), p(w)) {
        Some((h, w)) => {
            if w < h {
                // Cameras are wider than tall; 640x480 here is a portrait image.
                eprintln!(
                    "warning: resolution `{s}` is HEIGHTxWIDTH: {h} rows by {w} columns, \
                     taller than wide (did you mean {w}x{h}?)"
                );
            }
            Ok((h, w))
        }
        None => Err(format!(
            "`{s}`: height and width must be integers in {:?}",
            umpnet_sim::camera::IMAGE_SIDES
        )),
    }
}

pub fn parse_category(s: &str) -> std::result::Result<Category, String> {
    s.parse::<Category>().map_err(|e| e.to_string())
}

/// A flag over a fixed set of names (`name` or `name|alias`): `--help` lists
/// them, a wrong one is refused with the list, and the name is then parsed
/// into the library's type (which knows no clap).
pub fn choice<T>(names: &'static [&'static str]) -> impl clap::builder::TypedValueParser<Value = T>
where
    T: std::str::FromStr + Clone + Send + Sync + 'static,
    T::Err: Into<Box<dyn std::error::Error + Send + Sync + 'static>>,
{
    let values = names.iter().map(|n| {
        let mut parts = n.split('|');
        let name = parts.next().unwrap_or(n);
        clap::builder::PossibleValue::new(name).aliases(parts)
    });
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(values).try_map(|s| s.parse::<T>())
}

pub const PHYSICS: &[&str] = &["reference", "ideal"];
pub const PROTOCOLS: &[&str] = &["paper", "strict"];
pub const TASKS: &[&str] = &["exploration|explore", "goal"];
pub const RENDERERS: &[&str] = &["auto", "wgpu|gpu", "cpu"];
pub const GLASS_DRAWS: &[&str] = &["training", "all", "none"];
pub const GLASS_DEPTHS: &[&str] = &["surface", "through", "missing"];

/// What the camera's depth sensor does, beside the image size.
#[derive(clap::Args, Clone, Copy)]
pub struct SensorArgs {
    /// What depth, segmentation and normals read where the camera looks
    /// through glass: surface (the pane itself), through (what is behind it,
    /// as active-stereo and time-of-flight cameras often read clear glass) or
    /// missing (no reading: depth 0, background). The colour image shows the
    /// glass whatever the reading.
    #[arg(long, default_value = "surface", value_parser = crate::choice::<GlassDepth>(crate::GLASS_DEPTHS))]
    pub glass_depth: GlassDepth,
}

impl SensorArgs {
    /// The reference camera at (height, width), with this sensor.
    pub fn camera(self, (height, width): (u32, u32)) -> Camera {
        Camera {
            glass_depth: self.glass_depth,
            ..Camera::reference(height, width)
        }
    }
}
pub const GRASP_RULES: &[&str] = &[
    "affordance",
    "affordance_times_movable",
    "affordance_times_movable_lever",
];
pub const DIRECTION_FILTERS: &[&str] = &[
    "none", "normal90", "prev90", "joint45", "goal45", "onward45",
];

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
    #[arg(long, default_value = "reference", value_parser = choice::<PhysicsProfile>(PHYSICS))]
    pub physics: PhysicsProfile,
    /// With --object: uniform scale of the object file (as PyBullet's
    /// globalScaling; PartNet-Mobility's is 0.55), instead of its
    /// object_meta_info.json's.
    #[arg(long, requires = "object", value_parser = parse_scale, allow_hyphen_values = true)]
    pub scale: Option<f32>,
    /// With --object: the file's orientation as a quaternion, and optionally
    /// its lift off the floor in the file's units: `QX,QY,QZ,QW[,OFFSET_Z]`
    /// (e.g. `0.7071,0,0,0.7071` stands a Y-up model upright). Applied before
    /// the scene's random yaw; instead of object_meta_info.json's.
    #[arg(long, requires = "object", value_parser = parse_pose, allow_hyphen_values = true)]
    pub pose: Option<([f32; 4], Option<f32>)>,
}

fn parse_scale(s: &str) -> std::result::Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 && v <= 1000.0 => Ok(v),
        _ => Err(format!("`{s}`: expected a scale in (0, 1000], e.g. 0.55")),
    }
}

fn parse_pose(s: &str) -> std::result::Result<([f32; 4], Option<f32>), String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| format!("`{s}`: expected QX,QY,QZ,QW or QX,QY,QZ,QW,OFFSET_Z (numbers)"))?;
    let (q, offset) = match v.as_slice() {
        [x, y, z, w] => ([*x, *y, *z, *w], None),
        [x, y, z, w, o] => ([*x, *y, *z, *w], Some(*o)),
        _ => {
            return Err(format!(
                "`{s}`: expected 4 numbers (QX,QY,QZ,QW) or 5 (and OFFSET_Z), got {}",
                v.len()
            ));
        }
    };
    let pose = umpnet_sim::model::ObjectPose {
        orientation: q,
        offset_z: offset.unwrap_or(0.0),
        scale: 1.0,
    };
    pose.validate().map_err(|e| format!("`{s}`: {e}"))?;
    Ok((q, offset))
}

impl ObjectArgs {
    /// The object file's source with --scale and --pose over its own placement.
    fn file_source(&self, path: &std::path::Path) -> Result<ObjectSource> {
        let source = ObjectSource::file(path);
        if self.scale.is_none() && self.pose.is_none() {
            return Ok(source);
        }
        let mut pose = source.pose()?;
        if let Some(s) = self.scale {
            pose.scale = s;
        }
        if let Some((q, offset)) = self.pose {
            pose.orientation = q;
            pose.offset_z = offset.unwrap_or(pose.offset_z);
        }
        Ok(ObjectSource::File {
            path: path.to_path_buf(),
            pose: Some(pose),
        })
    }

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
                (self.file_source(path)?, c)
            }
            (None, Some(c)) => {
                let index = self.instance.unwrap_or_else(|| {
                    nth_instance(
                        c,
                        InstanceSplit::Test,
                        (self.seed % umpnet_eval::benchmark::INSTANCES_PER_CATEGORY as u64) as u32,
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
        Ok(umpnet_eval::benchmark::sample_visible_scene(
            &mut rng,
            task,
            category,
            object,
            self.physics,
        )?)
    }
}

#[expect(
    unsafe_code,
    reason = "SIGPIPE's default and XDG_RUNTIME_DIR, set before any thread exists"
)]
fn main() {
    // As Unix tools do: `umpnet objects list | head -1` ends quietly when the
    // reader goes away, instead of panicking in println! on EPIPE.
    // SAFETY: called first, before any thread exists; SIG_DFL is always valid.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        // Silences a harmless warning of the Vulkan loader on headless
        // machines. Here, not in the library: setting the environment is
        // only sound before any thread exists.
        // SAFETY: still single-threaded (see above).
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir()) };
    }
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        // A usage error under --json is one JSON line, as any other error.
        Err(e) if json_requested() && e.use_stderr() => {
            let text = e.render().to_string();
            let first = text.lines().next().unwrap_or_default();
            let message = first.trim_start_matches("error: ");
            report_json_error(message, &[message.to_owned()], 2)
        }
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
        Command::Infer(a) => match &a.session {
            Some(dir) => infer_session::run(&ctx, a, dir),
            None => infer_cmd::run(&ctx, a),
        },
    };
    if let Err(e) = result {
        let code = if e.downcast_ref::<Usage>().is_some() {
            2
        } else if e.downcast_ref::<signals::Interrupted>().is_some() {
            signals::INTERRUPTED
        } else {
            1
        };
        // An error that quotes its source (`cannot write: File too large`)
        // would otherwise say the cause twice.
        let mut msg: Vec<String> = Vec::new();
        for cause in e.chain().map(|c| c.to_string()) {
            if !msg.last().is_some_and(|m| m.ends_with(&cause)) {
                msg.push(cause);
            }
        }
        if ctx.json {
            report_json_error(&msg.join(": "), &msg, code);
        }
        eprintln!("error: {}", msg.join(": "));
        std::process::exit(code);
    }
}

/// `--json` anywhere on the command line, before clap has parsed it.
fn json_requested() -> bool {
    std::env::args_os().any(|a| a == "--json")
}

/// An error under `--json`: one line of JSON on stderr, `{"error": message,
/// "causes": [outermost .. innermost], "exit_code": code}`, then exit.
fn report_json_error(message: &str, causes: &[String], code: i32) -> ! {
    let line = serde_json::json!({"error": message, "causes": causes, "exit_code": code});
    eprintln!("{line}");
    std::process::exit(code)
}

#[cfg(test)]
mod choice_tests {
    use super::*;

    fn all_parse<T: std::str::FromStr>(names: &[&str]) {
        for n in names.iter().flat_map(|n| n.split('|')) {
            assert!(n.parse::<T>().is_ok(), "listed value `{n}` does not parse");
        }
    }

    #[test]
    fn every_listed_value_parses_and_every_profile_is_listed() {
        all_parse::<PhysicsProfile>(PHYSICS);
        all_parse::<umpnet_eval::Protocol>(PROTOCOLS);
        all_parse::<Task>(TASKS);
        all_parse::<umpnet_sim::render::RendererKind>(RENDERERS);
        all_parse::<umpnet_policy::policy::DirectionFilter>(DIRECTION_FILTERS);
        for f in umpnet_policy::policy::DirectionFilter::ALL {
            assert!(
                DIRECTION_FILTERS.contains(&f.name()),
                "{} is not offered",
                f.name()
            );
        }
        all_parse::<umpnet_policy::policy::GraspRule>(GRASP_RULES);
        for g in umpnet_policy::policy::GraspRule::ALL {
            assert!(
                GRASP_RULES.contains(&g.name()),
                "{} is not offered",
                g.name()
            );
        }
        for p in PhysicsProfile::ALL {
            assert!(PHYSICS.contains(&p.name()), "{} is not offered", p.name());
        }
    }

    fn undocumented(cmd: &clap::Command, path: &str, out: &mut Vec<String>) {
        let path = format!("{path} {}", cmd.get_name());
        for a in cmd.get_arguments() {
            let builtin = matches!(a.get_id().as_str(), "help" | "version");
            if !builtin && a.get_help().is_none() && a.get_long_help().is_none() {
                out.push(format!("{path} --{}", a.get_id()));
            }
        }
        for sub in cmd.get_subcommands() {
            if sub.get_about().is_none() && sub.get_name() != "help" {
                out.push(format!("{path} {} (no description)", sub.get_name()));
            }
            undocumented(sub, &path, out);
        }
    }

    #[test]
    fn every_option_and_command_has_help_text() {
        use clap::CommandFactory;
        let mut missing = Vec::new();
        undocumented(&Cli::command(), "", &mut missing);
        assert!(missing.is_empty(), "no help text: {missing:#?}");
    }

    #[test]
    fn help_lists_the_values_and_a_wrong_one_is_refused_with_them() {
        use clap::CommandFactory;
        let mut cmd = Cli::command();
        let help = cmd
            .find_subcommand_mut("eval")
            .map(|c| c.render_long_help().to_string())
            .unwrap_or_default();
        for v in [
            "[possible values: exploration, goal]",
            "[possible values: auto, wgpu, cpu]",
            "[possible values: reference, ideal]",
            "[possible values: paper, strict]",
        ] {
            assert!(help.contains(v), "eval --help lacks {v}");
        }
        let err = Cli::try_parse_from(["umpnet", "eval", "--physics", "bullet"])
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(err.contains("reference, ideal"), "{err}");
        assert!(
            Cli::try_parse_from(["umpnet", "eval", "--task", "explore", "--renderer", "gpu"])
                .is_ok()
        );
    }
}
