//! Procedural articulated objects for the paper's 22 categories, written as
//! URDF + OBJ in the PartNet-Mobility layout (`<Category>/<id>/mobility.urdf`).
mod builder;
mod families;

use crate::error::{Result, SimError};
use crate::mesh::TriMesh;
use crate::model::ObjectModel;
use crate::urdf::parse_urdf_with;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

macro_rules! categories {
    ($($name:ident = $steps:expr, $train:expr;)*) => {
        /// The paper's object categories (12 for training, 10 held out).
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
        #[expect(missing_docs, reason = "each variant is the category it names")]
        pub enum Category { $($name),* }
        impl Category {
            /// Every category: the training ones, then the test ones.
            pub const ALL: &'static [Category] = &[$(Category::$name),*];
            /// The paper's name, e.g. `StorageFurniture`.
            pub fn name(self) -> &'static str {
                match self { $(Category::$name => stringify!($name)),* }
            }
            /// Step budget of the exploration benchmark (paper, appendix table).
            pub fn step_budget(self) -> usize {
                match self { $(Category::$name => $steps),* }
            }
            /// True for the 12 training categories.
            pub fn is_train(self) -> bool {
                match self { $(Category::$name => $train),* }
            }
        }
    };
}

categories! {
    Refrigerator = 12, true; FoldingChair = 8, true; Laptop = 12, true; Stapler = 15, true;
    TrashCan = 9, true; Microwave = 8, true; Toilet = 7, true; Window = 6, true;
    StorageFurniture = 9, true; Switch = 7, true; Kettle = 3, true; Toy = 10, true;
    Box = 10, false; Phone = 12, false; Dishwasher = 10, false; Safe = 10, false;
    Oven = 9, false; WashingMachine = 9, false; Table = 7, false; KitchenPot = 3, false;
    Bucket = 13, false; Door = 10, false;
}

impl std::fmt::Display for Category {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Category {
    type Err = SimError;
    fn from_str(s: &str) -> Result<Self> {
        let key = s.to_ascii_lowercase().replace(['_', '-'], "");
        let alias = match key.as_str() {
            "fridge" => "refrigerator",
            "cabinet" => "storagefurniture",
            other => other,
        };
        Category::ALL
            .iter()
            .copied()
            .find(|c| c.name().to_ascii_lowercase() == alias)
            .ok_or_else(|| {
                let names = |train: bool| {
                    Category::ALL
                        .iter()
                        .filter(|c| c.is_train() == train)
                        .map(|c| c.name())
                        .collect::<Vec<_>>()
                        .join(", ")
                };
                SimError::Other(format!(
                    "unknown category `{s}`{}; expected a training category ({}) or a test category ({})",
                    category_hint(&key),
                    names(true),
                    names(false)
                ))
            })
    }
}

/// Parts people ask for by name, and the categories that have them.
const PART_HINTS: &[(&str, &str)] = &[
    ("drawer", "StorageFurniture (drawers and cabinets)"),
    ("cabinet", "StorageFurniture (drawers and cabinets)"),
    ("cupboard", "StorageFurniture (drawers and cabinets)"),
    ("wardrobe", "StorageFurniture (drawers and cabinets)"),
    ("lid", "Box, Kettle, KitchenPot, TrashCan or Toilet (lids)"),
];

/// "(did you mean `X`?)" for a near miss of a name (at most a third of its
/// letters wrong) or a part that lives in a category; empty otherwise.
fn category_hint(key: &str) -> String {
    if let Some((_, category)) = PART_HINTS.iter().find(|(part, _)| key.contains(part)) {
        return format!(" (did you mean {category}?)");
    }
    let best = Category::ALL
        .iter()
        .map(|c| (edit_distance(key, &c.name().to_ascii_lowercase()), c.name()))
        .min();
    match best {
        Some((d, name)) if d * 3 <= name.len().max(3) => format!(" (did you mean {name}?)"),
        _ => String::new(),
    }
}

/// Levenshtein distance over bytes (category names are ASCII).
fn edit_distance(a: &str, b: &str) -> usize {
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.bytes().enumerate() {
        let mut cur = Vec::with_capacity(prev.len());
        cur.push(i + 1);
        for ((cb, &diagonal), &up) in b.bytes().zip(&prev).zip(prev.iter().skip(1)) {
            let left = cur.last().copied().unwrap_or(0);
            cur.push((diagonal + usize::from(ca != cb)).min(up + 1).min(left + 1));
        }
        prev = cur;
    }
    prev.last().copied().unwrap_or(0)
}

/// Instance split: training categories have train and test instances; test
/// categories only test instances.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum InstanceSplit {
    /// Instances trained on.
    Train,
    /// Held-out instances (every instance of a test category).
    Test,
}

/// Which instances of a category belong to a split: every fifth instance of a
/// training category is held out for testing.
pub fn instance_split(category: Category, index: u32) -> InstanceSplit {
    if category.is_train() && index % 5 != 4 {
        InstanceSplit::Train
    } else {
        InstanceSplit::Test
    }
}

/// The `k`-th instance index of a category within a split.
pub fn nth_instance(category: Category, split: InstanceSplit, k: u32) -> u32 {
    match (category.is_train(), split) {
        (false, _) => k,
        (true, InstanceSplit::Test) => 5 * k + 4,
        (true, InstanceSplit::Train) => k / 4 * 5 + k % 4,
    }
}

/// A generated object: URDF text plus its meshes, not yet on disk.
pub struct GeneratedObject {
    /// Its category.
    pub category: Category,
    /// Its instance index.
    pub index: u32,
    /// The URDF text.
    pub urdf: String,
    /// Each mesh with its path relative to the URDF.
    pub meshes: Vec<(String, TriMesh)>,
}

fn instance_seed(dataset_seed: u64, category: Category, index: u32) -> u64 {
    let c = Category::ALL
        .iter()
        .position(|x| *x == category)
        .unwrap_or(0) as u64;
    dataset_seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (c << 40) ^ index as u64
}

/// The global scale the paper's code gives every PartNet-Mobility object.
/// Generated files are written at PartNet's size (the scene size divided by
/// it) with an `object_meta_info.json` that carries it, so they load, scale
/// and score (prismatic values are divided by it) as PartNet objects do.
pub const PARTNET_SCALE: f32 = 0.55;

/// The pose of every generated object: upright as written, PartNet's scale.
pub fn generated_pose() -> crate::model::ObjectPose {
    crate::model::ObjectPose {
        scale: PARTNET_SCALE,
        ..Default::default()
    }
}

/// Which instances draw glass panels (`families::glass`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GlassDraw {
    /// A share of the training instances of the categories that have glass
    /// (the benchmark's objects: held-out instances and test categories never).
    #[default]
    Training,
    /// Every instance of a category that has glass, held-out and test
    /// categories' too: a probe of how a policy meets glass it never saw.
    All,
    /// No instance.
    None,
}

impl std::str::FromStr for GlassDraw {
    type Err = SimError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "training" => Ok(GlassDraw::Training),
            "all" => Ok(GlassDraw::All),
            "none" => Ok(GlassDraw::None),
            _ => Err(SimError::Other(format!(
                "unknown glass draw `{s}`; expected training, all or none"
            ))),
        }
    }
}

/// Generates instance `index` of `category`; a pure function of its arguments.
pub fn generate(category: Category, index: u32, dataset_seed: u64) -> GeneratedObject {
    generate_with(category, index, dataset_seed, GlassDraw::Training)
}

/// [`generate`] with another choice of which instances draw glass; with
/// [`GlassDraw::Training`] the same object.
pub fn generate_with(
    category: Category,
    index: u32,
    dataset_seed: u64,
    glass: GlassDraw,
) -> GeneratedObject {
    let mut rng = ChaCha8Rng::seed_from_u64(instance_seed(dataset_seed, category, index));
    let test = instance_split(category, index) == InstanceSplit::Test;
    let mut parts = families::build(category, &mut rng, test, glass);
    // The families are designed at scene size; files are at PartNet's.
    parts.scale(1.0 / PARTNET_SCALE);
    let files = parts.meshes();
    let urdf = parts.urdf(&format!("{}_{index}", category.name()), &files);
    let meshes = files
        .into_iter()
        .flatten()
        .map(|(file, mesh, _)| (file, mesh))
        .collect();
    GeneratedObject {
        category,
        index,
        urdf,
        meshes,
    }
}

impl GeneratedObject {
    /// The instance id used as its folder name.
    pub fn id(&self) -> String {
        format!("{}", self.index)
    }

    /// Where this object lives under a dataset root.
    pub fn urdf_path(&self, root: &Path) -> PathBuf {
        root.join(self.category.name())
            .join(self.id())
            .join("mobility.urdf")
    }

    /// The object at scene size (the file scaled by [`PARTNET_SCALE`]).
    pub fn model(&self) -> Result<ObjectModel> {
        self.file_model()?.scaled(PARTNET_SCALE)
    }

    /// The object as the file has it (PartNet's size), without touching the disk.
    pub fn file_model(&self) -> Result<ObjectModel> {
        let dir = PathBuf::from(format!("generated/{}/{}", self.category.name(), self.index));
        let meshes: HashMap<PathBuf, &TriMesh> = self
            .meshes
            .iter()
            .map(|(rel, m)| (dir.join(rel), m))
            .collect();
        parse_urdf_with(&self.urdf, &dir.join("mobility.urdf"), &|p| {
            meshes.get(p).map(|m| (*m).clone())
        })
    }

    /// Writes `mobility.urdf` and `textured_objs/*.obj` under `root`.
    pub fn write(&self, root: &Path) -> Result<PathBuf> {
        let urdf = self.urdf_path(root);
        let dir = urdf.parent().unwrap_or(root).to_path_buf();
        let io = |file: &Path, e: std::io::Error| SimError::Write {
            file: file.to_path_buf(),
            source: e,
        };
        std::fs::create_dir_all(dir.join("textured_objs")).map_err(|e| io(&dir, e))?;
        for (rel, mesh) in &self.meshes {
            let p = dir.join(rel);
            crate::fsio::write_atomic(&p, mesh.to_obj().as_bytes())?;
        }
        crate::fsio::write_atomic(&urdf, self.urdf.as_bytes())?;
        let pose = generated_pose();
        let meta = serde_json::json!({
            "orientation": pose.orientation,
            "offset_z": pose.offset_z,
            "scale": pose.scale,
        });
        let meta_path = dir.join("object_meta_info.json");
        crate::fsio::write_atomic(&meta_path, meta.to_string().as_bytes())?;
        Ok(urdf)
    }
}

/// Writes `per_category` instances of each category and `split.json` under
/// `root`, glass drawn as `glass` says.
pub fn write_dataset(
    root: &Path,
    categories: &[Category],
    per_category: u32,
    dataset_seed: u64,
    glass: GlassDraw,
) -> Result<serde_json::Value> {
    let mut split = serde_json::Map::new();
    for &c in categories {
        let mut train = Vec::new();
        let mut test = Vec::new();
        for i in 0..per_category {
            let obj = generate_with(c, i, dataset_seed, glass);
            obj.write(root)?;
            match instance_split(c, i) {
                InstanceSplit::Train => train.push(obj.id()),
                InstanceSplit::Test => test.push(obj.id()),
            }
        }
        split.insert(
            c.name().to_owned(),
            serde_json::json!({"role": if c.is_train() { "train" } else { "test" }, "train": train, "test": test}),
        );
    }
    let value = serde_json::json!({"dataset_seed": dataset_seed, "categories": split});
    let path = root.join("split.json");
    let text = serde_json::to_string_pretty(&value).map_err(|e| SimError::Other(e.to_string()))?;
    crate::fsio::write_atomic(&path, text.as_bytes())?;
    Ok(value)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refusal(name: &str) -> String {
        match name.parse::<Category>() {
            Ok(c) => panic!("{name} parsed as {c}"),
            Err(e) => e.to_string(),
        }
    }

    /// Whether a generated object has the mechanism `families::variants`
    /// gives its category (none of the category's own recipes has it).
    fn has_variant_mechanism(category: Category, model: &ObjectModel) -> bool {
        let revolute_with = |axis_x: fn(f32) -> bool| {
            model
                .joints
                .iter()
                .any(|j| j.kind == crate::model::JointKind::Revolute && axis_x(j.axis_in_joint.x))
        };
        match category {
            // Flaps hinged at the top or bottom edge; the recipes hinge doors at a side.
            Category::StorageFurniture | Category::Window => revolute_with(|x| x.abs() > 0.9),
            // A bail handle turns about +x; the recipe's lid turns about -x.
            Category::Kettle => revolute_with(|x| x > 0.9),
            // A flap hinged on the lid.
            Category::TrashCan => model.joints.iter().any(|j| j.parent != model.root),
            _ => false,
        }
    }

    #[test]
    fn only_training_instances_draw_the_variant_mechanisms() {
        for category in [
            Category::StorageFurniture,
            Category::Window,
            Category::Kettle,
            Category::TrashCan,
        ] {
            let (mut train, mut train_variants) = (0, 0);
            for index in 0..60 {
                let model = generate(category, index, 0).file_model().unwrap();
                let variant = has_variant_mechanism(category, &model);
                match instance_split(category, index) {
                    InstanceSplit::Train => {
                        train += 1;
                        train_variants += usize::from(variant);
                    }
                    InstanceSplit::Test => {
                        assert!(
                            !variant,
                            "{category} {index}: a held-out instance drew a variant"
                        );
                    }
                }
            }
            let share = train_variants as f64 / train as f64;
            assert!(
                (0.2..0.6).contains(&share),
                "{category}: {train_variants} of {train} training instances are variants"
            );
        }
    }

    #[test]
    fn only_training_instances_draw_glass_and_it_covers_panels_not_handles() {
        for category in [
            Category::Window,
            Category::Microwave,
            Category::Refrigerator,
            Category::StorageFurniture,
        ] {
            let (mut train, mut glazed) = (0, 0);
            for index in 0..60 {
                let object = generate(category, index, 0);
                let model = object.file_model().unwrap();
                let glass: Vec<&crate::model::VisualModel> = model
                    .links
                    .iter()
                    .flat_map(|l| &l.visuals)
                    .filter(|v| v.opacity < 1.0)
                    .collect();
                if instance_split(category, index) == InstanceSplit::Test {
                    assert!(glass.is_empty(), "{category} {index}: held out, with glass");
                    continue;
                }
                train += 1;
                glazed += usize::from(!glass.is_empty());
                for v in glass {
                    assert!((0.2..=0.6).contains(&v.opacity), "{category} {index}");
                    // Panels only: the glass is thin, and no handle stands on it.
                    let (lo, hi) = v.mesh_in_link.bounds().unwrap();
                    let thin = (hi - lo).min_element() * PARTNET_SCALE;
                    assert!(
                        thin <= 0.045 + 1e-4,
                        "{category} {index}: glass {thin} m thick"
                    );
                }
                // A glazed link keeps its frame or handle opaque.
                for l in &model.links {
                    let glazed = l.visuals.iter().any(|v| v.opacity < 1.0);
                    let opaque = l.visuals.iter().any(|v| v.opacity >= 1.0);
                    assert!(
                        !glazed || opaque,
                        "{category} {index}: {} is all glass",
                        l.name
                    );
                }
            }
            let share = glazed as f64 / train as f64;
            assert!(
                (0.15..0.6).contains(&share),
                "{category}: {glazed} of {train} training instances have glass"
            );
        }
        // The other categories never do.
        for index in 0..20 {
            let model = generate(Category::Oven, index, 0).file_model().unwrap();
            assert!(
                model
                    .links
                    .iter()
                    .flat_map(|l| &l.visuals)
                    .all(|v| v.opacity >= 1.0)
            );
        }
    }

    #[test]
    fn an_unknown_category_suggests_the_nearest_name_or_the_category_of_a_part() {
        assert!(refusal("Microwav").contains("(did you mean Microwave?)"));
        assert!(refusal("washing_machne").contains("(did you mean WashingMachine?)"));
        assert!(refusal("drawer").contains("(did you mean StorageFurniture"));
        assert!(refusal("kitchen cabinet").contains("StorageFurniture"));
        assert!(refusal("pot lid").contains("KitchenPot"));
        let far = refusal("Spaceship");
        assert!(!far.contains("did you mean"), "{far}");
        // The categories listed by split, each in its own list.
        assert!(
            far.contains("a training category (Refrigerator, FoldingChair"),
            "{far}"
        );
        assert!(far.contains("or a test category (Box, Phone"), "{far}");
        assert_eq!(
            "fridge".parse::<Category>().ok(),
            Some(Category::Refrigerator)
        );
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
    }
}
