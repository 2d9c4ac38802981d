//! The table's rows of an `umpnet eval`: categories (generated, or a
//! PartNet-Mobility folder's instances), then object folders; and the
//! SHA-256 digests that results.json records of the files they read.
use super::report::{ObjectInfo, PartnetInfo};
use crate::usage;
use anyhow::{Context, Result};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use umpnet_eval::benchmark::{Row, object_rows};
use umpnet_sim::objects::Category;

/// What `table_rows` found: the category rows' categories, every row in
/// table order, and what results.json records of the files.
pub struct TableRows {
    pub categories: Vec<Category>,
    pub rows: Vec<Row>,
    pub objects: Vec<ObjectInfo>,
    pub partnet: Option<PartnetInfo>,
}

/// What `eval` asked for: `--categories`, `--split`, `--objects`,
/// `--partnet` and `--split-file`.
pub struct RowRequest<'a> {
    pub categories: &'a [Category],
    pub split: Option<&'a str>,
    pub objects: Option<&'a Path>,
    pub partnet: Option<&'a Path>,
    pub split_file: Option<&'a Path>,
}

/// The rows `--categories`/`--split`, `--partnet` and `--objects` ask for.
pub fn table_rows(a: &RowRequest<'_>) -> Result<TableRows> {
    let split = match (a.split, a.objects) {
        (Some(s), _) => Some(s),
        (None, Some(_)) => None,
        (None, None) => Some("all"),
    };
    let categories: Vec<Category> = if !a.categories.is_empty() {
        a.categories.to_vec()
    } else {
        match split {
            None => Vec::new(),
            Some("train") => Category::ALL
                .iter()
                .copied()
                .filter(|c| c.is_train())
                .collect(),
            Some("test") => Category::ALL
                .iter()
                .copied()
                .filter(|c| !c.is_train())
                .collect(),
            Some("all") => Category::ALL.to_vec(),
            Some(s) => return Err(usage(format!("--split {s}: expected train, test or all"))),
        }
    };
    for (i, c) in categories.iter().enumerate() {
        if categories.get(..i).is_some_and(|before| before.contains(c)) {
            return Err(usage(format!(
                "--categories: {} is listed twice (its row would count its episodes twice)",
                c.name()
            )));
        }
    }
    let object_rows = match a.objects {
        Some(dir) => object_rows(dir).map_err(|e| usage(e.to_string()))?,
        None => Vec::new(),
    };
    let mut objects = Vec::new();
    for row in &object_rows {
        if let Row::Object(o) = row {
            let folder = o.urdf.parent().unwrap_or(Path::new("."));
            objects.push(ObjectInfo {
                name: o.name.clone(),
                urdf: o.urdf.to_string_lossy().into_owned(),
                sha256: folder_digest(folder)?,
            });
        }
    }
    let (categories, category_rows, partnet) = match a.partnet {
        Some(dir) => partnet_rows(dir, a.split_file, &categories, !a.categories.is_empty())?,
        None => {
            let rows = categories.iter().map(|c| Row::Category(*c)).collect();
            (categories, rows, None)
        }
    };
    let rows = category_rows.into_iter().chain(object_rows).collect();
    Ok(TableRows {
        categories,
        rows,
        objects,
        partnet,
    })
}

pub fn package_digest(dir: &Path) -> Result<String> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("reading {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    let mut h = Sha256::new();
    for f in &files {
        let bytes = std::fs::read(f).with_context(|| format!("reading {}", f.display()))?;
        let name = f.file_name().map(|n| n.to_string_lossy().into_owned());
        h.update(name.unwrap_or_default().as_bytes());
        h.update([0]);
        h.update((bytes.len() as u64).to_le_bytes());
        h.update(&bytes);
    }
    Ok(format!("sha256:{:x}", h.finalize()))
}

/// `auto` becomes what this machine runs, so that the report says which
/// renderer made the images (and shards from different renderers do not merge).
/// SHA-256 over every file under an object's folder (relative names, sizes
/// and bytes, in name order).
fn folder_digest(dir: &Path) -> Result<String> {
    fn walk(dir: &Path, root: &Path, h: &mut Sha256, depth: usize) -> Result<()> {
        if depth > 8 {
            anyhow::bail!("{}: folders nested too deep", dir.display());
        }
        let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
            .with_context(|| format!("reading {}", dir.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .collect();
        entries.sort();
        for p in entries {
            let meta = std::fs::symlink_metadata(&p)?;
            if meta.is_dir() {
                walk(&p, root, h, depth + 1)?;
            } else if meta.is_file() {
                let bytes =
                    std::fs::read(&p).with_context(|| format!("reading {}", p.display()))?;
                let rel = p
                    .strip_prefix(root)
                    .unwrap_or(&p)
                    .to_string_lossy()
                    .into_owned();
                h.update(rel.as_bytes());
                h.update([0]);
                h.update((bytes.len() as u64).to_le_bytes());
                h.update(&bytes);
            }
        }
        Ok(())
    }
    let mut h = Sha256::new();
    walk(dir, dir, &mut h, 0)?;
    Ok(format!("sha256:{:x}", h.finalize()))
}

/// The categories' rows on a PartNet-Mobility folder's instances, the
/// categories that have some, and what the run used (for results.json). A
/// category listed by --categories must have instances; one chosen by
/// --split without any is left out, with a notice.
fn partnet_rows(
    dir: &Path,
    split_file: Option<&Path>,
    categories: &[Category],
    listed: bool,
) -> Result<(Vec<Category>, Vec<Row>, Option<PartnetInfo>)> {
    let found =
        umpnet_eval::partnet::read_instances(dir, split_file).map_err(|e| usage(e.to_string()))?;
    let missing: Vec<&str> = categories
        .iter()
        .filter(|c| !found.contains_key(c))
        .map(|c| c.name())
        .collect();
    if !missing.is_empty() {
        let what = format!(
            "--partnet {}: no instances of {}",
            dir.display(),
            missing.join(", ")
        );
        if listed {
            return Err(usage(what));
        }
        eprintln!("notice: {what}; their rows are left out");
    }
    let mut kept = Vec::new();
    let mut rows = Vec::new();
    let mut instances = Vec::new();
    for c in categories {
        let Some(list) = found.get(c) else { continue };
        for i in list {
            let folder = i.urdf.parent().unwrap_or(Path::new("."));
            instances.push(ObjectInfo {
                name: format!("{}/{}", c.name(), i.id),
                urdf: i.urdf.to_string_lossy().into_owned(),
                sha256: folder_digest(folder)?,
            });
        }
        kept.push(*c);
        rows.push(Row::Instances(umpnet_eval::benchmark::InstanceRow {
            category: *c,
            instances: list.clone(),
        }));
    }
    if kept.is_empty() {
        return Err(usage(format!(
            "--partnet {}: none of the chosen categories has instances",
            dir.display()
        )));
    }
    let split = split_file.map(Path::to_path_buf).or_else(|| {
        let default = dir.join("split-full.json");
        default.is_file().then_some(default)
    });
    Ok((
        kept,
        rows,
        Some(PartnetInfo {
            dir: dir.to_string_lossy().into_owned(),
            split_file: split
                .map(|f| -> Result<String> {
                    let bytes =
                        std::fs::read(&f).with_context(|| format!("reading {}", f.display()))?;
                    Ok(format!(
                        "{} sha256:{:x}",
                        f.display(),
                        Sha256::digest(&bytes)
                    ))
                })
                .transpose()?,
            instances,
        }),
    ))
}
