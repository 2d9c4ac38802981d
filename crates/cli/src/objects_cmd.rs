use crate::Ctx;
use anyhow::{Context, Result};
use std::path::PathBuf;
use umpnet_sim::objects::{Category, GlassDraw, write_dataset};

#[derive(clap::Subcommand)]
pub enum ObjectsCmd {
    /// Write URDF + OBJ instances in the PartNet-Mobility layout, plus split.json.
    Generate {
        /// Folder to write CATEGORY/INSTANCE/mobility.urdf (and meshes) into.
        #[arg(long)]
        out: PathBuf,
        /// Instances per category; split.json says which are train and which test instances.
        #[arg(long, default_value_t = 20)]
        per_category: u32,
        /// Dataset seed: the same seed writes the same objects.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Comma-separated categories (default: all 22).
        #[arg(long, value_delimiter = ',', value_parser = crate::parse_category)]
        categories: Vec<Category>,
        /// Which instances draw glass panels: training (a share of the training instances of
        /// Window, Microwave, Refrigerator and StorageFurniture; the benchmark's objects), all
        /// (every instance of those and of Oven, WashingMachine and Door: a probe) or none.
        #[arg(long, default_value = "training", value_parser = crate::choice::<GlassDraw>(crate::GLASS_DRAWS))]
        glass: GlassDraw,
        /// Write into a folder that is not empty (files of the same instances are replaced).
        #[arg(long)]
        force: bool,
    },
    /// List the categories with their split, step budget and joint types.
    List,
}

pub fn run(ctx: &Ctx, cmd: &ObjectsCmd) -> Result<()> {
    match cmd {
        ObjectsCmd::Generate {
            out,
            per_category,
            seed,
            categories,
            glass,
            force,
        } => {
            let _claim = crate::outdir::claim(out, *force, &[])?;
            let cats = if categories.is_empty() {
                Category::ALL.to_vec()
            } else {
                categories.clone()
            };
            let t0 = std::time::Instant::now();
            let pb = ctx.progress(cats.len() as u64, "generating");
            let mut split = serde_json::Map::new();
            for c in &cats {
                let v = write_dataset(out, &[*c], *per_category, *seed, *glass)
                    .with_context(|| format!("generating {c}"))?;
                if let Some(m) = v.get("categories").and_then(|c| c.as_object()) {
                    split.extend(m.clone());
                }
                pb.inc(1);
            }
            pb.finish_and_clear();
            let mut value = serde_json::Map::new();
            value.insert("dataset_seed".into(), (*seed).into());
            value.insert("categories".into(), split.into());
            // Said only when not the default, so default datasets keep their files.
            if *glass != GlassDraw::Training {
                value.insert("glass".into(), serde_json::to_value(glass)?);
            }
            umpnet_sim::fsio::write_atomic(
                &out.join("split.json"),
                serde_json::to_string_pretty(&value)?.as_bytes(),
            )?;
            let secs = t0.elapsed().as_secs_f64();
            if ctx.json {
                outln!(
                    "{}",
                    serde_json::json!({"out": out, "objects": cats.len() as u32 * per_category, "seconds": secs})
                );
            } else {
                outln!(
                    "wrote {} objects ({} categories x {per_category}) to {} in {secs:.2} s",
                    cats.len() as u32 * per_category,
                    cats.len(),
                    out.display()
                );
            }
        }
        ObjectsCmd::List => {
            let rows: Vec<serde_json::Value> = Category::ALL
                .iter()
                .map(|c| {
                    let m = umpnet_sim::objects::generate(*c, 0, 0).model();
                    let kinds: std::collections::BTreeSet<String> = (0..10)
                        .filter_map(|i| umpnet_sim::objects::generate(*c, i, 0).model().ok())
                        .flat_map(|m| m.joints.iter().filter(|j| j.kind.is_movable()).map(|j| format!("{:?}", j.kind).to_lowercase()).collect::<Vec<_>>())
                        .collect();
                    serde_json::json!({"category": c.name(), "split": if c.is_train() {"train"} else {"test"},
                        "steps": c.step_budget(), "joints": kinds, "ok": m.is_ok()})
                })
                .collect();
            if ctx.json {
                outln!("{}", serde_json::to_string(&rows)?);
            } else {
                outln!(
                    "{:<18} {:<6} {:>5}  joint types",
                    "category",
                    "split",
                    "steps"
                );
                for r in rows {
                    let kinds: Vec<&str> = r
                        .get("joints")
                        .and_then(|j| j.as_array())
                        .map(|a| a.iter().filter_map(|v| v.as_str()).collect())
                        .unwrap_or_default();
                    outln!(
                        "{:<18} {:<6} {:>5}  {}",
                        r.get("category").and_then(|v| v.as_str()).unwrap_or(""),
                        r.get("split").and_then(|v| v.as_str()).unwrap_or(""),
                        r.get("steps").and_then(|v| v.as_u64()).unwrap_or(0),
                        kinds.join(", ")
                    );
                }
            }
        }
    }
    Ok(())
}
