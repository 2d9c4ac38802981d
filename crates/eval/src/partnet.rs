//! A local PartNet-Mobility folder as the benchmark's objects, for users who
//! have the dataset (it cannot be downloaded here). Two layouts are read:
//! UMPNet's released `mobility_dataset` (`DIR/<Category>/<id>/mobility.urdf`)
//! and PartNet-Mobility's own (`DIR/<id>/mobility.urdf`, the category in
//! `meta.json`'s `model_cat`). Each object needs the `object_meta_info.json`
//! UMPNet ships beside it: PartNet's files are Y-up and unscaled, and that
//! file says how the object stands (see `ObjectSource::pose`).
//!
//! The released split (`split-full.json`: `{"train"|"test": {Category:
//! {"train": [ids], "test": [ids]}}}`) picks the instances: a training
//! category's held-out (`test`) instances, every instance of a test category.
//! Without a split file, every instance found is scored.
use crate::{EvalError, Result};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use umpnet_sim::objects::Category;

/// One object of the dataset: its id and its URDF.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Instance {
    /// The dataset's id (its folder's name).
    pub id: String,
    /// Its mobility.urdf.
    pub urdf: PathBuf,
}

fn err(what: impl std::fmt::Display) -> EvalError {
    EvalError::Episode(format!("--partnet: {what}"))
}

/// Largest JSON file read (a split file or a meta.json): far above the
/// released split's 60 kB.
const MAX_JSON_BYTES: u64 = 16 << 20;

fn read_json(path: &Path) -> Result<serde_json::Value> {
    let text = umpnet_sim::fsio::read_text(path, MAX_JSON_BYTES)
        .map_err(|e| err(format!("{}: {e}", path.display())))?;
    serde_json::from_str(&text).map_err(|e| err(format!("{}: {e}", path.display())))
}

/// The instances to score, by category, in id order.
pub fn read_instances(
    dir: &Path,
    split_file: Option<&Path>,
) -> Result<BTreeMap<Category, Vec<Instance>>> {
    if !dir.is_dir() {
        return Err(err(format!("{} is not a folder", dir.display())));
    }
    let default_split = dir.join("split-full.json");
    let split_file = split_file
        .map(Path::to_path_buf)
        .or_else(|| default_split.is_file().then_some(default_split));
    let wanted: BTreeMap<Category, Vec<String>> = match &split_file {
        Some(f) => split_ids(f)?,
        None => found_ids(dir)?,
    };
    let mut out = BTreeMap::new();
    for (category, ids) in wanted {
        let mut instances = Vec::with_capacity(ids.len());
        for id in ids {
            instances.push(locate(dir, category, &id)?);
        }
        instances.sort();
        instances.dedup();
        if !instances.is_empty() {
            out.insert(category, instances);
        }
    }
    if out.is_empty() {
        return Err(err(format!(
            "{}: no objects ({}); expected <Category>/<id>/mobility.urdf or <id>/mobility.urdf with meta.json",
            dir.display(),
            split_file.map_or("no split file".to_owned(), |f| format!(
                "split {}",
                f.display()
            ))
        )));
    }
    Ok(out)
}

/// The ids a split file lists for the benchmark, by category.
fn split_ids(file: &Path) -> Result<BTreeMap<Category, Vec<String>>> {
    let value = read_json(file)?;
    let shape = || {
        err(format!(
            "{}: expected {{\"train\"|\"test\": {{Category: {{\"train\": [ids], \"test\": [ids]}}}}}}",
            file.display()
        ))
    };
    let top = value.as_object().ok_or_else(shape)?;
    let mut out: BTreeMap<Category, Vec<String>> = BTreeMap::new();
    for (kind, categories) in top {
        let lists: &[&str] = match kind.as_str() {
            // A training category's trained-on instances are not scored.
            "train" => &["test"],
            "test" => &["train", "test"],
            other => {
                return Err(err(format!(
                    "{}: unknown key {other:?}; expected \"train\" and \"test\" (category splits)",
                    file.display()
                )));
            }
        };
        for (name, split) in categories.as_object().ok_or_else(shape)? {
            let category: Category = name
                .parse()
                .map_err(|e| err(format!("{}: {kind}.{name}: {e}", file.display())))?;
            let split = split.as_object().ok_or_else(shape)?;
            for list in lists {
                for id in split
                    .get(*list)
                    .and_then(|v| v.as_array())
                    .into_iter()
                    .flatten()
                {
                    let id = match id {
                        serde_json::Value::String(s) => s.clone(),
                        serde_json::Value::Number(n) => n.to_string(),
                        other => {
                            return Err(err(format!(
                                "{}: {kind}.{name}.{list}: id {other} is not a string or number",
                                file.display()
                            )));
                        }
                    };
                    if id.is_empty() || id.contains(['/', '\\']) || id == ".." {
                        return Err(err(format!(
                            "{}: {kind}.{name}.{list}: bad id {id:?}",
                            file.display()
                        )));
                    }
                    out.entry(category).or_default().push(id);
                }
            }
        }
    }
    Ok(out)
}

/// Every object in the folder, by category: `<Category>/<id>/` folders, and
/// `<id>/` folders whose meta.json names a category.
fn found_ids(dir: &Path) -> Result<BTreeMap<Category, Vec<String>>> {
    let mut out: BTreeMap<Category, Vec<String>> = BTreeMap::new();
    let entries = std::fs::read_dir(dir).map_err(|e| err(format!("{}: {e}", dir.display())))?;
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name().to_string_lossy().into_owned();
        if !path.is_dir() {
            continue;
        }
        if let Ok(category) = name.parse::<Category>() {
            let objects =
                std::fs::read_dir(&path).map_err(|e| err(format!("{}: {e}", path.display())))?;
            for object in objects.flatten() {
                if object.path().join("mobility.urdf").is_file() {
                    out.entry(category)
                        .or_default()
                        .push(object.file_name().to_string_lossy().into_owned());
                }
            }
        } else if path.join("mobility.urdf").is_file() {
            let meta = path.join("meta.json");
            let Some(category) = meta
                .is_file()
                .then(|| read_json(&meta))
                .transpose()?
                .and_then(|m| {
                    m.get("model_cat")
                        .and_then(|c| c.as_str())
                        .map(str::to_owned)
                })
            else {
                continue;
            };
            // PartNet-Mobility has categories UMPNet does not use (Faucet, Lamp...).
            if let Ok(category) = category.parse::<Category>() {
                out.entry(category).or_default().push(name);
            }
        }
    }
    Ok(out)
}

/// Where object `id` of `category` is, in either layout, with its placement.
fn locate(dir: &Path, category: Category, id: &str) -> Result<Instance> {
    let (nested, flat) = (dir.join(category.name()).join(id), dir.join(id));
    let Some(folder) = [&nested, &flat]
        .into_iter()
        .find(|c| c.join("mobility.urdf").is_file())
    else {
        return Err(err(format!(
            "{} {id}: no mobility.urdf at {} or {}",
            category.name(),
            nested.display(),
            flat.display()
        )));
    };
    if !folder.join("object_meta_info.json").is_file() {
        return Err(err(format!(
            "{} {id}: no object_meta_info.json in {} (UMPNet's mobility_dataset has one per object: \
             PartNet's files are Y-up and unscaled, and it says how the object stands)",
            category.name(),
            folder.display()
        )));
    }
    Ok(Instance {
        id: id.to_owned(),
        urdf: folder.join("mobility.urdf"),
    })
}
